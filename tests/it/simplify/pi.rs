//! The exact constant π: parsing, printing, the exact trigonometric values at its rational
//! multiples (checked against the float functions, an independent implementation), the shifts
//! of an argument by multiples of π/2, the compiled value, and the refusal of `pi` as a
//! declared name (it would otherwise be silently shadowed by the constant).

use std::f64::consts::PI;

use lagrangian::eval::eval_with;
use lagrangian::mechanics::{MechanicsError, System};
use lagrangian::parse::parse;
use lagrangian::print::{render as to_string, Format};
use lagrangian::simulate::{self, MethodId, RunOptions, Sampling};
use lagrangian::{Expr, Func, Symbol};

fn value(e: &Expr, x: f64) -> f64 {
    eval_with(e, &|s: &Symbol| (s.name() == "x").then_some(x)).unwrap_or_else(|err| panic!("{e}: {err}"))
}

fn has_call(e: &Expr) -> bool {
    let mut found = matches!(e.node(), lagrangian::expr::Node::Call(..));
    e.for_each_child(|c| found |= has_call(c));
    found
}

/// Every multiple n π/d with d in {1, 2, 3, 4, 6} folds sin and cos to an exact algebraic
/// number equal to the float value; tan folds too, and is undefined exactly at its poles.
#[test]
fn trigonometric_values_at_rational_multiples_of_pi_are_exact() {
    for d in [1i64, 2, 3, 4, 6] {
        for n in -25i64..=25 {
            let arg = Expr::frac(n, d).times(&Expr::pi());
            let x = n as f64 / d as f64 * PI;
            for (f, want) in [(Func::Sin, x.sin()), (Func::Cos, x.cos()), (Func::Tan, x.tan())] {
                let e = Expr::call(f, vec![arg.clone()]);
                // A pole of tan: n/d an odd multiple of 1/2.
                let pole = f == Func::Tan && (2 * n) % d == 0 && ((2 * n) / d) % 2 != 0;
                if pole {
                    assert!(e.is_undefined(), "tan({n}π/{d}) = {e}, a pole");
                    continue;
                }
                assert!(!has_call(&e) && !e.to_string().contains("pi"), "{f:?}({n}π/{d}) not folded: {e}");
                let got = value(&e, 0.0);
                assert!((got - want).abs() < 1e-14 * (1.0 + want.abs()), "{f:?}({n}π/{d}) = {e} = {got}, float {want}");
            }
        }
    }
}

/// sec and csc fold at the same multiples as 1/cos and 1/sin (the float reciprocals), and
/// are undefined exactly at the zeros of cos and sin.
#[test]
fn secant_and_cosecant_at_rational_multiples_of_pi_are_exact() {
    for d in [1i64, 2, 3, 4, 6] {
        for n in -25i64..=25 {
            let arg = Expr::frac(n, d).times(&Expr::pi());
            let x = n as f64 / d as f64 * PI;
            for (f, of) in [(Func::Sec, x.cos()), (Func::Csc, x.sin())] {
                let e = Expr::call(f, vec![arg.clone()]);
                // A zero of cos or sin: sin at n/d an integer, cos at an odd multiple of 1/2.
                let pole = match f {
                    Func::Sec => (2 * n) % d == 0 && ((2 * n) / d) % 2 != 0,
                    _ => n % d == 0,
                };
                if pole {
                    assert!(e.is_undefined(), "{f:?}({n}π/{d}) = {e}, a pole");
                    continue;
                }
                assert!(!has_call(&e) && !e.to_string().contains("pi"), "{f:?}({n}π/{d}) not folded: {e}");
                let (got, want) = (value(&e, 0.0), 1.0 / of);
                assert!((got - want).abs() < 1e-14 * (1.0 + want.abs()), "{f:?}({n}π/{d}) = {e} = {got}, float {want}");
            }
        }
    }
    assert_eq!(Expr::call(Func::Sec, vec![Expr::pi()]), Expr::int(-1));
    assert_eq!(Expr::call(Func::Csc, vec![Expr::frac(1, 6).times(&Expr::pi())]), Expr::int(2));
}

/// `sin(x + n π/2)`, `cos(…)`, `tan(…)` drop the multiple of π from the argument (a quarter
/// turn swaps sin and cos), and the result has the float value at sample points.
#[test]
fn shifts_by_multiples_of_half_pi_leave_the_argument() {
    for n in -9i64..=9 {
        for (f, g) in [(Func::Sin, f64::sin as fn(f64) -> f64), (Func::Cos, f64::cos), (Func::Tan, f64::tan)] {
            let e = Expr::call(f, vec![Expr::var("x").plus(&Expr::frac(n, 2).times(&Expr::pi()))]);
            assert!(!e.to_string().contains("pi"), "{f:?}(x + {n}π/2) = {e}");
            for x in [0.31, -1.2, 2.9] {
                let want = g(x + n as f64 * PI / 2.0);
                let got = value(&e, x);
                assert!(
                    (got - want).abs() < 1e-12 * (1.0 + want.abs()),
                    "{f:?}(x + {n}π/2) at {x}: {e} = {got}, float {want}"
                );
            }
        }
    }
    // Other multiples stay in the argument.
    let e = parse("sin(x + pi/3)").unwrap();
    assert!(e.to_string().contains("pi"), "{e}");
}

/// The inverse functions give π's multiples at their tabulated points.
#[test]
fn inverse_trigonometric_values_are_multiples_of_pi() {
    for (text, want) in [
        ("asin(1)", PI / 2.0),
        ("asin(-1/2)", -PI / 6.0),
        ("acos(-1)", PI),
        ("acos(0)", PI / 2.0),
        ("acos(-1/2)", 2.0 * PI / 3.0),
        ("atan(-1)", -PI / 4.0),
    ] {
        let e = parse(text).unwrap();
        assert!(!has_call(&e), "{text} = {e}");
        assert!((value(&e, 0.0) - want).abs() < 1e-15, "{text} = {e}");
    }
    assert_eq!(parse("cos(acos(-1/2))").unwrap(), parse("-1/2").unwrap());
}

/// `pi` and `π` parse to the constant; it prints as `pi`, `π` and `\pi`, the plain form
/// re-parses, it differentiates to 0, and it is no symbol of the expression.
#[test]
fn pi_parses_prints_and_differentiates_as_a_number() {
    assert_eq!(parse("pi").unwrap(), Expr::pi());
    assert_eq!(parse("π").unwrap(), Expr::pi());
    let e = parse("2 pi x/3 + pi^2").unwrap();
    assert_eq!(to_string(&parse("2 pi x").unwrap(), Format::Plain), "2 pi x");
    assert_eq!(to_string(&parse("2 pi x").unwrap(), Format::Unicode), "2 π x");
    assert_eq!(to_string(&parse("2 pi x").unwrap(), Format::Latex), "2 \\pi x");
    assert_eq!(parse(&to_string(&e, Format::Plain)).unwrap(), e);
    assert_eq!(e.free_symbols().len(), 1);
    assert_eq!(lagrangian::diff::diff(&e, &Symbol::new("x")), parse("2 pi/3").unwrap());
    assert!((value(&e, 1.5) - (PI + PI * PI)).abs() < 1e-14);
    let err = parse("pi'").unwrap_err();
    assert!(err.message.contains("constant π"), "{}", err.message);
}

/// An oscillator of period T written with π compiles with π's float value: after one period
/// it is back at its start (closed form x = cos(2π t/T)).
#[test]
fn a_lagrangian_with_pi_compiles_and_runs() {
    let t = 1.5;
    let sys =
        System::from_lagrangian("1/2 x'^2 - 1/2 (2 pi/T)^2 x^2", &["x"]).unwrap().with_params(&[("T", t)]).unwrap();
    assert_eq!(sys.parameters().len(), 1, "π is not a parameter");
    let c = simulate::compile_system(&sys, MethodId::Taylor, &[]).unwrap();
    let mut o = RunOptions::new(MethodId::Taylor, 0.0, t);
    o.sampling = Sampling::Final;
    let y = simulate::integrate(&c, &[1.0, 0.0], &o, &mut |_| {}).unwrap().last_state().unwrap().to_vec();
    assert!((y[0] - 1.0).abs() < 1e-10 && y[1].abs() < 1e-9, "{y:?}");
}

/// `pi` as a declared name is refused where it is declared, in the library and in scenes.
#[test]
fn pi_cannot_name_a_coordinate_or_parameter() {
    assert!(matches!(
        System::from_lagrangian("1/2 x'^2 - x^2", &["π"]),
        Err(MechanicsError::ConstantName(n)) if n == "π"
    ));
    let sys = System::from_lagrangian("1/2 x'^2 - pi x^2", &["x"]).unwrap();
    assert!(matches!(sys.with_params(&[("pi", 3.0)]), Err(MechanicsError::ConstantName(_))));
    for scene in [
        "coordinates x\nparameters pi = 3\n",
        "coordinates π\n",
        "coordinates x\npi = 3\n",
        "coordinates x\nfunctions pi\n",
    ] {
        let dir = tempfile::tempdir().unwrap();
        let (code, _, err) = crate::support::run_scene_in(dir.path(), scene, &[]);
        assert_eq!(code, 2, "{scene}: {err}");
        assert!(
            err.contains("is the constant π and cannot be declared") && err.contains("delete the declaration"),
            "{scene}: {err}"
        );
    }
}
