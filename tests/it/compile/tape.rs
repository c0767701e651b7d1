//! The register tape: sharing, dead outputs, code generation choices, accuracy, errors.

use crate::support::compile as compile_common;

use std::collections::HashMap;

use compile_common::{benchmark_systems, mass_matrix_split, ulps, Rng};
use lagrangian::compile::{CompileError, CompileOptions, Instr, Tape};
use lagrangian::eval::rational_to_f64;
use lagrangian::{parse, Expr, Func, Node, Rational, Symbol};

fn compile(src: &str, inputs: &[&str], params: &[(&str, f64)]) -> Tape {
    Tape::compile(&[parse(src).unwrap()], inputs, params).unwrap()
}

fn eval1(tape: &Tape, inputs: &[f64]) -> f64 {
    let mut out = [0.0];
    tape.eval(inputs, &mut out);
    out[0]
}

#[test]
fn shared_subexpressions_are_computed_once() {
    // `sin(x)^2 + sin(x)`: one sine, one square (a multiplication), one addition.
    let tape = compile("sin(x)^2 + sin(x)", &["x"], &[]);
    let c = tape.op_counts();
    assert_eq!((c.call, c.mul, c.add, c.powf), (1, 1, 1, 0), "{tape}");
    assert_eq!(tape.op_count(), 3);
    let x: f64 = 0.7;
    assert_eq!(eval1(&tape, &[x]), x.sin() * x.sin() + x.sin());
}

#[test]
fn work_shared_between_outputs_is_done_once() {
    // Two outputs both using exp(x y): the exponential appears once in the joint tape.
    let a = parse("exp(x y) + x").unwrap();
    let b = parse("exp(x y) * y").unwrap();
    let joint = Tape::compile(&[a.clone(), b.clone()], &["x", "y"], &[]).unwrap();
    let sep_a = Tape::compile(&[a], &["x", "y"], &[]).unwrap();
    let sep_b = Tape::compile(&[b], &["x", "y"], &[]).unwrap();
    assert_eq!(joint.op_counts().call, 1);
    assert_eq!(joint.op_count(), sep_a.op_count() + sep_b.op_count() - 2, "exp and x·y shared:\n{joint}");
}

#[test]
fn dead_outputs_are_not_computed() {
    // Asking for the cheap output only must not compile the expensive one.
    let cheap = parse("x + y").unwrap();
    let costly = parse("atan(sinh(x) cosh(y)) / log(2 + x^4)").unwrap();
    let both = Tape::compile(&[cheap.clone(), costly], &["x", "y"], &[]).unwrap();
    let only = Tape::compile(&[cheap], &["x", "y"], &[]).unwrap();
    assert_eq!(only.op_count(), 1);
    assert_eq!(only.op_counts().call, 0);
    assert!(both.op_count() > 5);
}

#[test]
fn powers_become_multiplications_roots_and_divisions() {
    // x^2 → one mul; x^5 → x^4 = (x^2)^2 then ·x: three muls, no powf.
    let t = compile("x^5", &["x"], &[]);
    assert_eq!((t.op_counts().mul, t.op_counts().powf), (3, 0), "{t}");
    let t = compile("x^2", &["x"], &[]);
    assert_eq!(t.instrs(), &[Instr::Mul { d: 1, a: 0, b: 0 }]);
    // sqrt(x) is x^(1/2): one sqrt; x^(3/2) = x·sqrt(x).
    let t = compile("sqrt(x)", &["x"], &[]);
    assert_eq!(t.op_counts().sqrt, 1);
    assert_eq!(t.op_count(), 1);
    let t = compile("x^(3/2)", &["x"], &[]);
    assert_eq!((t.op_counts().sqrt, t.op_counts().mul, t.op_count()), (1, 1, 2));
    assert_eq!(eval1(&t, &[2.0]), 2.0 * 2f64.sqrt());
    // y/x is one division, not a reciprocal and a product.
    let t = compile("y / x", &["x", "y"], &[]);
    assert_eq!((t.op_counts().div, t.op_count()), (1, 1));
    assert_eq!(eval1(&t, &[3.0, 1.0]), 1.0 / 3.0);
    let t = compile("x y / (z^2 w)", &["x", "y", "z", "w"], &[]);
    assert_eq!((t.op_counts().div, t.op_count()), (1, 4), "{t}");
    // A general exponent keeps powf.
    let t = compile("x^(1/3)", &["x"], &[]);
    assert_eq!(t.op_counts().powf, 1);
}

#[test]
fn a_shared_reciprocal_is_computed_once() {
    // r is divided by in three products: one reciprocal, then multiplications.
    let t = compile("a/r + b/r^2 + c/r^3", &["a", "b", "c", "r"], &[]);
    assert_eq!(t.op_counts().div, 1, "{t}");
    let (a, b, c, r) = (1.5, -2.0, 0.25, 1.75);
    let v = eval1(&t, &[a, b, c, r]);
    let want = a / r + b / (r * r) + c / (r * r * r);
    assert!(ulps(v, want) <= 4, "{v} vs {want}");
}

#[test]
fn sine_and_cosine_of_one_argument_are_one_instruction() {
    let t = compile("sin(a - b) x + cos(a - b) y", &["a", "b", "x", "y"], &[]);
    let c = t.op_counts();
    assert_eq!((c.sin_cos, c.call), (1, 0), "{t}");
    let (a, b, x, y) = (0.3, -1.2, 2.0, 5.0);
    let v = eval1(&t, &[a, b, x, y]);
    let want = (a - b).sin() * x + (a - b).cos() * y;
    assert!(ulps(v, want) <= 2);
    // Only a sine: a plain call.
    let t = compile("sin(a) + a", &["a"], &[]);
    assert_eq!((t.op_counts().sin_cos, t.op_counts().call), (0, 1));
}

#[test]
fn bound_parameters_fold_at_compile_time() {
    // m g l sin θ with m, g, l bound: the constant m·g·l is folded, leaving one sin and
    // one multiplication.
    let params = [("m", 2.0), ("g", 9.81), ("l", 0.5)];
    let t = compile("m g l sin(θ)", &["θ"], &params);
    assert_eq!((t.op_counts().call, t.op_counts().mul, t.op_count()), (1, 1, 2), "{t}");
    assert_eq!(eval1(&t, &[0.4]), 2.0 * 9.81 * 0.5 * 0.4f64.sin());
    // Whole parameter subexpressions fold, including calls: sqrt(g/l) x → one mul.
    let t = compile("sqrt(g/l) x + cos(g)", &["x"], &params);
    assert_eq!(t.op_count(), 2, "{t}");
    // A negative coefficient becomes a subtraction, not a negation and an addition.
    let t = compile("x - 3 y", &["x", "y"], &[]);
    assert_eq!((t.op_counts().neg, t.op_count()), (0, 2), "{t}");
}

use crate::support::snapshot;

#[test]
fn double_pendulum_tape_listing() {
    // The listing is checked numerically against the hand-written W and F (see
    // compile_common::double_pendulum) before it is compared with the snapshot.
    let sys = compile_common::double_pendulum();
    let (w, f) = mass_matrix_split(&sys.lagrangian, &sys.coords());
    let rhs = lagrangian::compile::LagrangianRhs::new(&w, &f, &sys.coords(), &sys.params).unwrap();
    let tape = rhs.tape();
    let y = [2.0, 2.5, 0.3, -0.7, 0.0];
    let mut out = vec![0.0; tape.n_outputs()];
    tape.eval(&y, &mut out);
    let (s, c) = (2.0f64 - 2.5).sin_cos();
    let hand = [2.0, c, c, 1.0, -s * 0.7 * 0.7 - 2.0 * 9.81 * 2f64.sin(), s * 0.3 * 0.3 - 9.81 * 2.5f64.sin()];
    for (a, b) in out.iter().zip(hand) {
        assert!((a - b).abs() <= 1e-14 * (1.0 + b.abs()), "{out:?} vs {hand:?}");
    }
    assert_eq!(tape.op_counts().sin_cos, 1);
    snapshot("compile_double_pendulum_tape", tape.to_string());
}

/// Evaluates `e` exactly at rational inputs; built-in calls (whose values are irrational) are
/// taken from libm at the exactly computed argument rounded to f64, so the comparison isolates
/// the tape's arithmetic from libm's.
fn exact(e: &Expr, values: &HashMap<String, f64>) -> Option<f64> {
    let mut map = HashMap::new();
    for s in e.free_symbols() {
        let v = *values.get(&s.to_string())?;
        map.insert(s.clone(), Expr::num(Rational::from_float(v)?));
    }
    let mut memo: HashMap<Expr, Expr> = HashMap::new();
    let r = exact_rec(e, &map, &mut memo)?;
    r.as_num().map(rational_to_f64)
}

fn exact_rec(e: &Expr, map: &HashMap<Symbol, Expr>, memo: &mut HashMap<Expr, Expr>) -> Option<Expr> {
    if let Some(v) = memo.get(e) {
        return Some(v.clone());
    }
    let v = match e.node() {
        Node::Num(_) => e.clone(),
        Node::Sym(s) => map.get(s)?.clone(),
        Node::Call(f, args) => {
            let a: Vec<f64> = args
                .iter()
                .map(|a| exact_rec(a, map, memo).and_then(|x| x.as_num().map(rational_to_f64)))
                .collect::<Option<_>>()?;
            Expr::num(Rational::from_float(f.eval(&a))?)
        }
        Node::Pow(b, x) if x.as_num().is_some_and(|r| !r.is_integer()) => {
            // Non-integer powers (square roots): the correctly rounded f64 value.
            let b = rational_to_f64(exact_rec(b, map, memo)?.as_num()?);
            let x = rational_to_f64(x.as_num()?);
            let v = if x == 0.5 {
                b.sqrt()
            } else if x == -0.5 {
                1.0 / b.sqrt()
            } else {
                b.powf(x)
            };
            Expr::num(Rational::from_float(v)?)
        }
        _ => {
            let mut kids = Vec::new();
            let mut ok = true;
            e.for_each_child(|c| match exact_rec(c, map, memo) {
                Some(k) => kids.push(k),
                None => ok = false,
            });
            if !ok {
                return None;
            }
            e.with_children(kids)
        }
    };
    memo.insert(e.clone(), v.clone());
    Some(v)
}

#[test]
fn rational_expressions_agree_with_exact_evaluation_to_a_few_ulps() {
    // Positive inputs and positive terms: no cancellation, so each operation's rounding
    // (≤ ½ ulp) adds up to a small bound; 8 ulps allows for the ~15 roundings here.
    let e = parse("(x^2 + 3 y^3 + x y / (1 + x^2)) / (2 + y^4) + x^5/7").unwrap();
    let tape = Tape::compile(std::slice::from_ref(&e), &["x", "y"], &[]).unwrap();
    let mut rng = Rng(1);
    let mut worst = 0;
    for _ in 0..200 {
        let (x, y) = (rng.uniform(0.5, 2.0), rng.uniform(0.5, 2.0));
        let want = exact(&e, &HashMap::from([("x".to_string(), x), ("y".to_string(), y)])).unwrap();
        worst = worst.max(ulps(eval1(&tape, &[x, y]), want));
    }
    assert!(worst <= 8, "worst error {worst} ulps");
}

/// The worst ulp error of a system's `W` and `F` outputs over random states against the exact
/// evaluation above, skipping outputs whose exact value is tiny against the terms that
/// cancel in it (there the relative error measures the conditioning, not the tape).
fn worst_ulps(sys: &compile_common::System, samples: usize, options: &CompileOptions) -> u64 {
    let (w, f) = mass_matrix_split(&sys.lagrangian, &sys.coords());
    let outputs: Vec<Expr> = w.iter().flatten().chain(f.iter()).cloned().collect();
    let n = sys.coords.len();
    let mut names: Vec<String> = sys.coords.clone();
    names.extend(sys.coords.iter().map(|q| format!("{q}'")));
    names.push("t".into());
    let inputs: Vec<&str> = names.iter().map(String::as_str).collect();
    let tape = Tape::compile_with_options(&outputs, &inputs, &sys.params, options).unwrap();
    let mut rng = Rng(7);
    let mut worst = 0;
    for _ in 0..samples {
        let y: Vec<f64> = (0..2 * n).map(|_| rng.uniform(0.5, 1.5)).chain([0.0]).collect();
        let mut env: HashMap<String, f64> = names.iter().cloned().zip(y.iter().copied()).collect();
        for (k, v) in &sys.params {
            env.insert(k.to_string(), *v);
        }
        let mut out = vec![0.0; outputs.len()];
        tape.eval(&y, &mut out);
        for (e, got) in outputs.iter().zip(&out) {
            let want = exact(e, &env).unwrap();
            let scale = lagrangian::eval::eval(&e.map_bottom_up(&mut |x| abs_terms(x)), &env).unwrap_or(want.abs());
            if want.abs() < 1e-3 * scale {
                continue;
            }
            worst = worst.max(ulps(*got, want));
        }
    }
    worst
}

/// `e` with every sum's terms replaced by their absolute values (the scale of cancellation).
fn abs_terms(e: &Expr) -> Option<Expr> {
    match e.node() {
        Node::Add(ts) => Some(Expr::add(ts.iter().map(|t| Expr::call(Func::Abs, vec![t.clone()])))),
        _ => None,
    }
}

#[test]
fn benchmark_systems_agree_with_exact_evaluation() {
    // Printed with --nocapture for BENCHMARKS.md, which documents a worst case of 7 ulps (the
    // 10-link chain); the bound is that documented accuracy rounded up to 8, the bound of the
    // libm-free test below (it was 64). The states are fixed (seeded), so this is not flaky.
    // Both back ends: the interpreter and the native code (the same bits, so the same worst
    // error; each is checked against the exact value on its own).
    for sys in benchmark_systems() {
        let samples = if sys.coords.len() > 5 { 20 } else { 100 };
        for (label, options) in [
            ("interpreted", CompileOptions::default().with_native(false)),
            ("native", CompileOptions::default().with_native(true)),
        ] {
            let worst = worst_ulps(&sys, samples, &options);
            println!("{} ({label}): worst {} ulps", sys.name, worst);
            assert!(worst <= 8, "{} ({label}): {worst} ulps", sys.name);
        }
    }
}

#[test]
fn transcendental_expressions_agree_with_the_reference_evaluator() {
    let e = parse("exp(-x^2) atan2(y, x) + tanh(x y) / cosh(y) - log(1 + x^2) asin(y/3)").unwrap();
    let tape = Tape::compile(std::slice::from_ref(&e), &["x", "y"], &[]).unwrap();
    let mut rng = Rng(3);
    for _ in 0..100 {
        let (x, y) = (rng.uniform(0.1, 2.0), rng.uniform(0.1, 2.0));
        let env = HashMap::from([("x".to_string(), x), ("y".to_string(), y)]);
        let want = lagrangian::eval::eval(&e, &env).unwrap();
        let got = eval1(&tape, &[x, y]);
        assert!((got - want).abs() <= 1e-14 * (1.0 + want.abs()), "{got} vs {want}");
    }
}

#[test]
fn batch_evaluation_equals_scalar_evaluation_exactly() {
    // 19 points: two full blocks of 8 and a partial one.
    let sys = compile_common::double_pendulum();
    let rhs = sys.compile();
    let tape = rhs.tape();
    let points = 19;
    let mut rng = Rng(11);
    let ni = tape.n_inputs();
    let inputs: Vec<f64> = (0..ni * points).map(|_| rng.uniform(-3.0, 3.0)).collect();
    let mut batch = vec![0.0; tape.n_outputs() * points];
    tape.eval_batch(&inputs, &mut batch, points);
    for k in 0..points {
        let x: Vec<f64> = (0..ni).map(|i| inputs[i * points + k]).collect();
        let mut out = vec![0.0; tape.n_outputs()];
        tape.eval(&x, &mut out);
        for j in 0..out.len() {
            assert_eq!(batch[j * points + k].to_bits(), out[j].to_bits());
        }
    }
}

#[test]
fn bad_input_gives_typed_errors() {
    let e = |s: &str| parse(s).unwrap();
    assert_eq!(Tape::compile(&[e("x + k")], &["x"], &[]).unwrap_err(), CompileError::Unbound { name: "k".into() });
    let v = lagrangian::parse_with("V(x)", &lagrangian::Declarations::new().with_functions(["V"])).unwrap();
    assert_eq!(Tape::compile(&[v], &["x"], &[]).unwrap_err(), CompileError::UndefinedFunction { name: "V".into() });
    let undefined = Expr::var("x").plus(&Expr::undefined());
    assert_eq!(Tape::compile(&[undefined], &["x"], &[]).unwrap_err(), CompileError::Undefined);
    assert!(matches!(
        Tape::compile(&[e("x log(-g)")], &["x"], &[("g", 1.0)]).unwrap_err(),
        CompileError::NonFiniteConstant { .. }
    ));
    assert!(matches!(
        Tape::compile(&[e("x")], &["x"], &[("g", f64::NAN)]).unwrap_err(),
        CompileError::NonFiniteParam { .. }
    ));
    assert_eq!(
        Tape::compile(&[e("x")], &["x", "x"], &[]).unwrap_err(),
        CompileError::DuplicateInput { name: "x".into() }
    );
    assert_eq!(
        Tape::compile(&[e("x")], &["x"], &[("x", 1.0)]).unwrap_err(),
        CompileError::ParamIsInput { name: "x".into() }
    );
}

#[test]
fn a_very_deep_expression_is_an_error_not_a_stack_overflow() {
    // sin(sin(…sin(x)…)) nested 5000 deep (built bottom-up, no recursion in the builder).
    let mut e = Expr::var("x");
    for _ in 0..5000 {
        e = Expr::call(Func::Sin, vec![e]);
    }
    assert!(matches!(Tape::compile(&[e], &["x"], &[]).unwrap_err(), CompileError::TooDeep { .. }));
}
