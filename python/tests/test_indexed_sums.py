"""Indexed sums and names (``sum(i = 0..4, …)``, ``sum(i < j in 0..4, …)``, ``x[i]``) reach
Python through the engine's parser: an N-body Hamiltonian written with them is the system its
written-out text gives."""

import pytest

import lagrangian as lg

COORDS = ["x0", "x1", "x2", "y0", "y1", "y2"]
PARAMS = {"G": 1.0, "m0": 1.0, "m1": 2.0, "m2": 3.0}
SUMMED = (
    "sum(i = 0..2, (p_x[i]^2 + p_y[i]^2)/(2 m[i]))"
    " - G sum(i < j in 0..2, m[i] m[j]/sqrt((x[i] - x[j])^2 + (y[i] - y[j])^2))"
)
WRITTEN = (
    "(p_x0^2 + p_y0^2)/(2 m0) + (p_x1^2 + p_y1^2)/(2 m1) + (p_x2^2 + p_y2^2)/(2 m2)"
    " - G (m0 m1/sqrt((x0 - x1)^2 + (y0 - y1)^2) + m0 m2/sqrt((x0 - x2)^2 + (y0 - y2)^2)"
    " + m1 m2/sqrt((x1 - x2)^2 + (y1 - y2)^2))"
)


def test_the_sum_form_is_the_written_out_system():
    positive = list(PARAMS)
    a = lg.System.from_hamiltonian(SUMMED, COORDS, params=PARAMS, positive=positive)
    b = lg.System.from_hamiltonian(WRITTEN, COORDS, params=PARAMS, positive=positive)
    assert lg.Expr(SUMMED) == lg.Expr(WRITTEN)
    assert repr(a) == repr(b)  # the system shows the expanded terms, as written out
    assert a.hamiltonian() == b.hamiltonian()
    assert str(a.hamiltonian()) == str(b.hamiltonian())
    assert "sum(" not in str(a.hamiltonian())
    y0 = {"x0": 1, "y0": 0, "x1": 0, "y1": 1, "x2": -1, "y2": 0,
          "p_x0": 0, "p_y0": 0.2, "p_x1": -0.1, "p_y1": 0, "p_x2": 0, "p_y2": -0.1}
    ra = a.integrate((0.0, 3.0), y0, "taylor", tol=1e-12)
    rb = b.integrate((0.0, 3.0), y0, "taylor", tol=1e-12)
    assert (ra.y == rb.y).all() and (ra.t == rb.t).all()


@pytest.mark.parametrize(
    "text, says",
    [
        ("x[i]", "not an index bound"),
        ("sum(i = 3..1, x[i])", "is empty"),
        ("sum(i = 0..2, sum(i = 0..2, x[i]))", "already bound"),
        ("sum(i = 0..100000, x[i])", "more than 10000 terms"),
    ],
)
def test_mistakes_are_refused_with_their_place(text, says):
    with pytest.raises(lg.ParseError) as e:
        lg.Expr(text)
    assert says in str(e.value)
