"""One exception hierarchy: every error is a `LagrangianError`; every argument error is also a
`ValueError` (what NumPy and SciPy code catches), raised by real calls; only a run that was
asked for correctly and failed along the way (`IntegrationError`) is not."""

import ast
import pickle

import numpy as np
import pytest

import lagrangian as lg
from conftest import STUB_PATH

ARGUMENT_ERRORS = [
    "ArgumentError",
    "ParseError",
    "MechanicsError",
    "CompileError",
    "RhsError",
    "EvalError",
    "TransformError",
    "SolveError",
    "PhaseSpaceError",
    "LieError",
    "ActionAngleError",
    "AverageError",
    "EnsembleError",
]


def test_the_hierarchy():
    for name in ARGUMENT_ERRORS:
        cls = getattr(lg, name)
        assert issubclass(cls, lg.LagrangianError) and issubclass(cls, ValueError), name
    assert issubclass(lg.IntegrationError, lg.LagrangianError)
    assert not issubclass(lg.IntegrationError, ValueError)
    # The native module raises the package's classes, not copies of them.
    assert lg._core.ParseError is lg.ParseError
    assert lg.ParseError.__module__ == "lagrangian"


def test_the_stubs_say_which_are_value_errors():
    tree = ast.parse(STUB_PATH.read_text(encoding="utf-8"))
    bases = {
        n.name: [b.id for b in n.bases if isinstance(b, ast.Name)] for n in tree.body if isinstance(n, ast.ClassDef)
    }
    for name in ARGUMENT_ERRORS:
        assert bases[name] == ["LagrangianError", "ValueError"], name
    assert bases["IntegrationError"] == ["LagrangianError"]


def raised(f):
    with pytest.raises(lg.LagrangianError) as e:
        f()
    return e.value


def test_argument_errors_from_real_calls(oscillator):
    singular = lg.System.from_lagrangian("1/2 x'^2 + 1/2 x^2 y'^2 - 1/2 y^2", ["x", "y"])
    cases = {
        "ParseError": lambda: lg.Expr("x +"),
        "MechanicsError": lambda: lg.System.from_lagrangian("x' y", ["x", "y"]).accelerations(),
        "CompileError": lambda: lg.System.from_lagrangian("1/2 m x'^2", ["x"]).integrate((0, 1), [0.0, 1.0]),
        "EvalError": lambda: lg.Expr("x").evaluate(),
        "RhsError": lambda: singular.compile()(0.0, np.array([0.0, 1.0, 0.0, 0.0])),
        "ArgumentError": lambda: oscillator.integrate((0, 1), [1.0, 0.0], "rk5"),
    }
    for name, f in cases.items():
        e = raised(f)
        assert type(e).__name__ == name, (name, type(e), e)
        assert isinstance(e, ValueError), name


@pytest.mark.parametrize(
    "call",
    [
        lambda s: s.integrate((0, 1), [1.0, 0.0], "gauss6"),  # no dt
        lambda s: s.integrate((0, 1), [1.0, 0.0], "dop853", dt=0.1),  # dt to an adaptive method
        lambda s: s.integrate((0, 1), [1.0, 0.0], rtol=1e-30),  # below f64
        lambda s: s.integrate((0, 0), [1.0, 0.0]),  # empty span
        lambda s: s.integrate((0, 1), [1.0, 0.0], t_eval=[2.0]),  # outside the span
        lambda s: s.integrate((0, 1e12), [1.0, 0.0], "rk4", dt=1e-3),  # too many steps
        lambda s: s.integrate("ab", [1.0, 0.0]),
        lambda s: s.integrate((0, 1), [1.0, 0.0, 2.0]),
        lambda s: s.ensemble((0, 1), [[1.0, 0.0]], "rk4"),
        lambda s: s.state_names("rk5"),
        lambda s: s.with_params({"k": float("nan")}).integrate((0, 1), [1.0, 0.0]),
    ],
)
def test_refused_requests_are_argument_errors(oscillator, call):
    e = raised(lambda: call(oscillator))
    assert isinstance(e, ValueError) and not isinstance(e, lg.IntegrationError), (type(e), e)


def test_hints_speak_python(oscillator):
    # The engine's hints are written for scenes (`dt = 0.01`, `steps = 1000`, `tol = 1e-10`);
    # a Python caller is told the keyword arguments that exist here.
    e = raised(lambda: oscillator.integrate((0, 1), [1.0, 0.0], "gauss6"))
    assert "dt=0.01" in str(e) and "steps" not in str(e)
    e = raised(lambda: oscillator.integrate((0, 1), [1.0, 0.0], "dop853", dt=0.1))
    assert "rtol=" in str(e) and "tol =" not in str(e)
    e = raised(lambda: oscillator.integrate((0, 1), [1.0, 0.0], rtol=1e-30))
    assert "rtol=1e-14" in str(e) and "tol =" not in str(e)
    e = raised(lambda: oscillator.integrate((0, 1), [1.0, 0.0], "rk5"))
    assert "help simulate" not in str(e) and "`rk4`" in str(e)


def test_a_start_where_the_equations_have_no_value_is_an_argument_error():
    # W = diag(1, x²) is singular at x = 0: y0 is the bad argument, so it is an RhsError (a
    # ValueError) naming the start, not an IntegrationError of a run that "stopped" at t0.
    s = lg.System.from_lagrangian("1/2 x'^2 + 1/2 x^2 y'^2 - 1/2 y^2", ["x", "y"])
    for method, kw in (("rk4", {"dt": 0.01}), ("dop853", {}), ("gauss6", {"dt": 0.01})):
        e = raised(lambda: s.integrate((0, 1), [0.0, 1.0, 0.0, 0.0], method, **kw))
        assert isinstance(e, lg.RhsError) and isinstance(e, ValueError), (method, type(e))
        assert "initial state" in str(e) and "singular" in str(e), str(e)
    # Starting off the singular set integrates.
    assert s.integrate((0, 0.1), [1.0, 1.0, 0.0, 0.0], "rk4", dt=0.01).success


def test_a_run_that_fails_along_the_way_is_an_integration_error(oscillator):
    e = raised(lambda: oscillator.integrate((0, 100), [1.0, 0.0], max_steps=3))
    assert type(e) is lg.IntegrationError and not isinstance(e, ValueError)
    assert e.steps == 3 and len(e.state) == 2 and 0 < e.t < 100
    # The message names the state variables.
    assert "x = " in str(e) and "x' = " in str(e), str(e)


def test_errors_pickle_as_their_class(oscillator):
    for f in (lambda: lg.Expr("x +"), lambda: oscillator.integrate((0, 1), [1.0, 0.0], "rk5")):
        e = raised(f)
        back = pickle.loads(pickle.dumps(e))
        assert type(back) is type(e) and str(back) == str(e)
