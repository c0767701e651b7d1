"""Python's ``**`` in expression text: the expression language writes powers as ``^``, and
text with ``**`` is refused with a hint saying so (not a bare "expected a name")."""

import pytest

import lagrangian as lg


@pytest.mark.parametrize("text", ["x**2", "1/2 m x'**2 - k x ** 2", "x**-2"])
def test_double_star_is_refused_with_a_hint_to_write_a_caret(text):
    with pytest.raises(lg.ParseError, match=r"hint: write `\^` for a power") as e:
        lg.Expr(text)
    assert isinstance(e.value, lg.LagrangianError)


def test_the_hint_reaches_every_place_text_is_read():
    with pytest.raises(lg.ParseError, match=r"write `\^`"):
        lg.System.from_lagrangian("1/2 m x'**2", ["x"])
    s = lg.System.from_lagrangian("1/2 m x'^2", ["x"])
    with pytest.raises(lg.ParseError, match=r"write `\^`"):
        s.with_force("x", "-c x'**3")
    # Written with `^`, the same text parses: x^2 is x·x.
    assert lg.Expr("x^2") == lg.Expr("x x")


def test_a_lone_star_error_gets_no_power_hint():
    with pytest.raises(lg.ParseError) as e:
        lg.Expr("x * * 2")
    assert "write `^`" not in str(e.value)
