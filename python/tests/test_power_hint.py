"""Python's ``**`` in expression text is the power operator, as ``^`` (the engine's grammar
reads both; it used to take the first ``*`` as a product and fail on the second)."""

import pytest

import lagrangian as lg


@pytest.mark.parametrize(
    "text,caret",
    [("x**2", "x^2"), ("1/2 m x'**2 - k x ** 2", "1/2 m x'^2 - k x^2"), ("x**-2", "x^-2"), ("2**3**2", "512")],
)
def test_double_star_is_a_power(text, caret):
    assert lg.Expr(text) == lg.Expr(caret)


def test_double_star_reaches_every_place_text_is_read():
    s = lg.System.from_lagrangian("1/2 m x'**2", ["x"])
    assert s.lagrangian == lg.Expr("1/2 m x'^2")
    s.with_force("x", "-c x'**3")


def test_a_lone_star_is_still_an_error():
    with pytest.raises(lg.ParseError):
        lg.Expr("x * * 2")
