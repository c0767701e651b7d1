//! The native back end (Cranelift) against the interpreter, which is the reference: the same
//! bits for every instruction kind, every built-in function, every model system and every
//! kind of compiled right-hand side, and the same trajectories.

use crate::support::compile as compile_common;

use compile_common::{benchmark_systems, kepler_polar, mass_matrix_split, Rng};
use lagrangian::compile::{
    CompileOptions, HamiltonianRhs, ImplicitLegendreRhs, Instr, LagrangianRhs, SeparableHamiltonian, Tape,
};
use lagrangian::integrate::{Gauss6, Integrate, Jacobian, Separable, Splitting};
use lagrangian::{parse, Func};

fn native() -> CompileOptions {
    CompileOptions::default().with_native(true)
}

fn interpreted() -> CompileOptions {
    CompileOptions::default().with_native(false)
}

/// Whether this host should have the JIT: on the hosts Cranelift supports, a tape that stays
/// interpreted is a failure of the back end, not a fallback to accept silently (unless the
/// environment variable forces the interpreter for the whole run).
fn jit_expected() -> bool {
    cfg!(any(target_arch = "x86_64", target_arch = "aarch64"))
        && std::env::var_os(lagrangian::compile::NO_JIT_ENV).is_none()
}

/// Equal as bits, or both NaN (a NaN's payload is not part of the contract).
fn same(a: f64, b: f64) -> bool {
    a.to_bits() == b.to_bits() || (a.is_nan() && b.is_nan())
}

fn assert_same(what: &str, a: &[f64], b: &[f64]) {
    assert_eq!(a.len(), b.len());
    for (i, (x, y)) in a.iter().zip(b).enumerate() {
        assert!(
            same(*x, *y),
            "{what}: output {i}: native {x:e} ({:#x}) vs interpreted {y:e} ({:#x})",
            x.to_bits(),
            y.to_bits()
        );
    }
}

#[test]
fn every_instruction_kind_and_builtin_matches_the_interpreter_bit_for_bit() {
    // One tape with every Instr kind and every built-in (abs is native, the rest are calls).
    let src = [
        "sin(x) + cos(x)", // sin_cos
        "sin(y)",
        "cos(x y)",
        "tan(x)",
        "exp(y)",
        "log(x)",
        "sinh(y)",
        "cosh(x)",
        "tanh(x - y)",
        "asin(y/4)",
        "acos(x/4)",
        "atan(x y)",
        "atan2(y, x)",
        "abs(y - x)",
        "x^(13/10)",   // powf
        "x^y",         // powf
        "sqrt(x + y)", // sqrt
        "x^(5/2)",
        "-x / y",     // neg, div
        "x^3 - y^-2", // mul chain, recip
        "asinh(y - x)",
        "acosh(x + 1/2)",
        "atanh(y/4)",
        "sec(x y)",
        "csc(x - y)",
        "coth(y)",
        "erf(x - y/2)",
    ];
    let exprs: Vec<_> = src.iter().map(|s| parse(s).unwrap()).collect();
    let nat = Tape::compile_with_options(&exprs, &["x", "y"], &[], &native()).unwrap();
    let int = Tape::compile_with_options(&exprs, &["x", "y"], &[], &interpreted()).unwrap();
    assert_eq!(nat.is_native(), jit_expected());
    assert!(!int.is_native());
    assert_eq!(nat.to_string(), int.to_string(), "the back end does not change the tape");
    // Every instruction kind and every one-argument built-in is on the tape.
    let has = |p: &dyn Fn(&Instr) -> bool| nat.instrs().iter().any(p);
    assert!(has(&|i| matches!(i, Instr::Add { .. })) && has(&|i| matches!(i, Instr::Sub { .. })));
    assert!(has(&|i| matches!(i, Instr::Mul { .. })) && has(&|i| matches!(i, Instr::Div { .. })));
    assert!(has(&|i| matches!(i, Instr::Neg { .. })) && has(&|i| matches!(i, Instr::Sqrt { .. })));
    assert!(has(&|i| matches!(i, Instr::SinCos { .. })) && has(&|i| matches!(i, Instr::Atan2 { .. })));
    assert!(has(&|i| matches!(i, Instr::Powf { .. })));
    for f in Func::ALL {
        if !matches!(f, Func::Atan2) {
            let called = has(&|i| matches!(i, Instr::Call { f: g, .. } if *g == f));
            // sin and cos of a shared argument become one SinCos; the others are plain calls.
            assert!(called || matches!(f, Func::Sin | Func::Cos), "{f:?} not on the tape");
        }
    }
    let mut rng = Rng(17);
    let mut points: Vec<[f64; 2]> = (0..2000).map(|_| [rng.uniform(0.05, 3.9), rng.uniform(-3.9, 3.9)]).collect();
    // Edges: zeros of both signs, out-of-domain values (NaN from log, asin), infinities, huge.
    for x in [0.0, -0.0, -1.0, 5.0, f64::INFINITY, f64::NEG_INFINITY, f64::NAN, 1e300, 1e-310] {
        for y in [0.0, -0.0, 2.0, -7.0, f64::INFINITY, f64::NAN, 1e-300] {
            points.push([x, y]);
        }
    }
    let (mut a, mut b) = (vec![0.0; exprs.len()], vec![0.0; exprs.len()]);
    for p in &points {
        nat.eval(p, &mut a);
        int.eval(p, &mut b);
        assert_same(&format!("at {p:?}"), &a, &b);
    }
    // Batch evaluation (strided loads and stores) too: 37 points, structure of arrays.
    let k = 37;
    let xs: Vec<f64> = (0..2 * k).map(|_| rng.uniform(0.1, 3.0)).collect();
    let (mut oa, mut ob) = (vec![0.0; exprs.len() * k], vec![0.0; exprs.len() * k]);
    nat.eval_batch(&xs, &mut oa, k);
    int.eval_batch(&xs, &mut ob, k);
    assert_same("batch", &oa, &ob);
}

#[test]
fn tapes_without_inputs_or_outputs_and_constant_tapes_work_natively() {
    let c = Tape::compile_with_options(&[parse("2").unwrap(), parse("x").unwrap()], &["x"], &[], &native()).unwrap();
    let mut out = [0.0; 2];
    c.eval(&[1.5], &mut out);
    assert_eq!(out, [2.0, 1.5]);
    let k = Tape::compile_with_options(&[parse("g/2").unwrap()], &[], &[("g", 9.0)], &native()).unwrap();
    let mut out = [0.0];
    k.eval(&[], &mut out);
    assert_eq!(out, [4.5]);
    let none = Tape::compile_with_options(&[], &["x"], &[], &native()).unwrap();
    none.eval(&[1.0], &mut []);
    assert_eq!(none.n_outputs(), 0);
}

/// The states the systems are compared on.
fn states(d: usize, kepler: bool, rng: &mut Rng, count: usize) -> Vec<Vec<f64>> {
    (0..count)
        .map(|_| {
            let mut y: Vec<f64> = (0..d).map(|_| rng.uniform(-2.0, 2.0)).collect();
            if kepler {
                y[0] = rng.uniform(0.5, 2.0);
            }
            y
        })
        .collect()
}

fn lagrangian(sys: &compile_common::System, options: &CompileOptions) -> LagrangianRhs {
    let (w, f) = mass_matrix_split(&sys.lagrangian, &sys.coords());
    LagrangianRhs::with_options(&w, &f, &sys.coords(), &sys.params, options).unwrap()
}

#[test]
fn every_model_system_agrees_with_the_interpreter() {
    let mut systems = benchmark_systems();
    systems.push(kepler_polar());
    let mut rng = Rng(99);
    for sys in &systems {
        let nat = lagrangian(sys, &native());
        let int = lagrangian(sys, &interpreted());
        let n = sys.coords.len();
        assert_eq!(nat.tape().is_native(), jit_expected(), "{}", sys.name);
        // The W, F tape and the unrolled solve tape: bit for bit, native vs interpreted.
        let inputs = 2 * n + 1;
        for y in states(inputs, sys.name.starts_with("Kepler"), &mut rng, 200) {
            let (mut a, mut b) = (vec![0.0; nat.tape().n_outputs()], vec![0.0; nat.tape().n_outputs()]);
            nat.tape().eval(&y, &mut a);
            nat.tape().interpreted().eval(&y, &mut b);
            assert_same(sys.name, &a, &b);
            if let Some(solve) = nat.solve_tape() {
                let (mut a, mut b) = (vec![0.0; solve.n_outputs()], vec![0.0; solve.n_outputs()]);
                solve.eval(&y, &mut a);
                solve.interpreted().eval(&y, &mut b);
                assert_same(sys.name, &a, &b);
            }
        }
        // Whole right-hand sides: the same bits up to 4 degrees of freedom (one solve tape
        // both ways); beyond, the native one unrolls the Cholesky solve (products with
        // reciprocal pivots) where the interpreted one runs `factor`'s loops (divisions), so
        // they agree to rounding.
        for y in states(2 * n, sys.name.starts_with("Kepler"), &mut rng, 100) {
            let (mut a, mut b) = (vec![0.0; 2 * n], vec![0.0; 2 * n]);
            nat.try_eval(0.3, &y, &mut a).unwrap();
            int.try_eval(0.3, &y, &mut b).unwrap();
            if n <= 4 {
                assert_same(sys.name, &a, &b);
            } else {
                for (x, z) in a.iter().zip(&b) {
                    assert!((x - z).abs() <= 1e-12 * (1.0 + z.abs()), "{}: {x} vs {z}", sys.name);
                }
            }
        }
    }
}

#[test]
fn batch_right_hand_sides_agree_with_the_interpreter() {
    for sys in [compile_common::double_pendulum(), compile_common::chain(5)] {
        let nat = lagrangian(&sys, &native());
        let d = sys.dim();
        let points = 29;
        let mut rng = Rng(4);
        let y: Vec<f64> = (0..d * points).map(|_| rng.uniform(-2.0, 2.0)).collect();
        let mut dy = vec![0.0; d * points];
        nat.eval_batch(0.0, &y, &mut dy, points).unwrap();
        // Each point equals the native scalar call exactly.
        for k in 0..points {
            let yk: Vec<f64> = (0..d).map(|i| y[i * points + k]).collect();
            let mut one = vec![0.0; d];
            nat.try_eval(0.0, &yk, &mut one).unwrap();
            let col: Vec<f64> = (0..d).map(|i| dy[i * points + k]).collect();
            assert_same(sys.name, &col, &one);
        }
        if d <= 8 {
            let int = lagrangian(&sys, &interpreted());
            let mut di = vec![0.0; d * points];
            int.eval_batch(0.0, &y, &mut di, points).unwrap();
            assert_same(sys.name, &dy, &di);
        }
    }
}

#[test]
fn jacobians_hamiltonians_and_splittings_agree_with_the_interpreter() {
    let mut rng = Rng(8);
    // Lagrangian Jacobian (double pendulum; 5-link where only rounding of the solves differs).
    let sys = compile_common::double_pendulum();
    let nat = lagrangian(&sys, &native()).with_jacobian().unwrap();
    let int = lagrangian(&sys, &interpreted()).with_jacobian().unwrap();
    assert_eq!(nat.tape().is_native(), jit_expected());
    for y in states(4, false, &mut rng, 50) {
        let (mut a, mut b) = ([0.0; 16], [0.0; 16]);
        nat.try_jacobian(0.0, &y, &mut a).unwrap();
        int.try_jacobian(0.0, &y, &mut b).unwrap();
        assert_same("Lagrangian Jacobian", &a, &b);
    }
    // Hamilton's equations and their Jacobian (central force, PHYSICS.md 3.29).
    let h = parse("p_r^2/(2 m) + p_φ^2/(2 m r^2) - mu/r + r sin(t)").unwrap();
    let params = [("m", 2.0), ("mu", 1.5)];
    let nat = HamiltonianRhs::with_options(&h, &["r", "φ"], &["p_r", "p_φ"], &params, &native()).unwrap();
    let int = HamiltonianRhs::with_options(&h, &["r", "φ"], &["p_r", "p_φ"], &params, &interpreted()).unwrap();
    assert_eq!(nat.tape().is_native() && nat.jacobian_tape().is_native(), jit_expected());
    for y in states(4, true, &mut rng, 50) {
        let (mut a, mut b) = ([0.0; 4], [0.0; 4]);
        nat.try_eval(0.7, &y, &mut a).unwrap();
        int.try_eval(0.7, &y, &mut b).unwrap();
        assert_same("Hamiltonian", &a, &b);
        let (mut ja, mut jb) = ([0.0; 16], [0.0; 16]);
        nat.jacobian(0.7, &y, &mut ja);
        int.jacobian(0.7, &y, &mut jb);
        assert_same("Hamiltonian Jacobian", &ja, &jb);
    }
    // Drift and kick of a separable Hamiltonian with a time-dependent potential.
    let h = parse("p1^2/(2 m) + p2^2/2 + k (q1 - q2)^4 + q1 cos(t) - g cos(q2)").unwrap();
    let params = [("m", 1.5), ("k", 0.3), ("g", 9.81)];
    let nat = SeparableHamiltonian::with_options(&h, &["q1", "q2"], &["p1", "p2"], &params, &native()).unwrap();
    let int = SeparableHamiltonian::with_options(&h, &["q1", "q2"], &["p1", "p2"], &params, &interpreted()).unwrap();
    assert_eq!(nat.drift_tape().is_native() && nat.kick_tape().is_native(), jit_expected());
    for y in states(4, false, &mut rng, 50) {
        let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
        nat.drift(&y[2..], &mut a);
        int.drift(&y[2..], &mut b);
        assert_same("drift", &a, &b);
        nat.kick(1.1, &y[..2], &mut a);
        int.kick(1.1, &y[..2], &mut b);
        assert_same("kick", &a, &b);
    }
    // The implicit Legendre map (Newton on natively evaluated ∂L/∂q' and W).
    let l = parse("-m c^2 sqrt(1 - x'^2/c^2) - 1/2 k x^2").unwrap();
    let params = [("m", 1.5), ("c", 2.0), ("k", 3.0)];
    let nat = ImplicitLegendreRhs::with_options(&l, &["x"], &params, &native()).unwrap();
    let int = ImplicitLegendreRhs::with_options(&l, &["x"], &params, &interpreted()).unwrap();
    for y in [[0.3, 0.1], [-1.0, 5.0], [2.0, -40.0]] {
        let (mut a, mut b) = ([0.0; 2], [0.0; 2]);
        nat.try_eval(0.0, &y, &mut a).unwrap();
        int.try_eval(0.0, &y, &mut b).unwrap();
        assert_same("implicit Legendre", &a, &b);
    }
}

#[test]
fn trajectories_are_the_same_either_way() {
    // Gauss-6 (Newton with the compiled Jacobian) on the double pendulum: bit for bit.
    let sys = compile_common::double_pendulum();
    let nat = lagrangian(&sys, &native()).with_jacobian().unwrap();
    let int = lagrangian(&sys, &interpreted()).with_jacobian().unwrap();
    let y0 = [2.0, 2.5, 0.0, 0.0];
    let a = Gauss6::new(1e-2).integrate(&nat, 0.0..5.0, &y0).unwrap();
    let b = Gauss6::new(1e-2).integrate(&int, 0.0..5.0, &y0).unwrap();
    assert_eq!(a.len(), b.len());
    assert_same("Gauss-6 double pendulum", a.last_state(), b.last_state());
    // Yoshida-4 on a separable chain of springs: bit for bit.
    let h = parse("p1^2/2 + p2^2/2 + (q1 - q2)^2/2 + q1^4/4").unwrap();
    let nat = SeparableHamiltonian::with_options(&h, &["q1", "q2"], &["p1", "p2"], &[], &native()).unwrap();
    let int = SeparableHamiltonian::with_options(&h, &["q1", "q2"], &["p1", "p2"], &[], &interpreted()).unwrap();
    let y0 = [1.0, -0.5, 0.0, 0.3];
    let a = Splitting::yoshida4(1e-2).integrate(&nat, 0.0..10.0, &y0).unwrap();
    let b = Splitting::yoshida4(1e-2).integrate(&int, 0.0..10.0, &y0).unwrap();
    assert_same("Yoshida-4", a.last_state(), b.last_state());
    // The 5-link chain, where the solves differ in rounding: the same trajectory to 1e-9 over
    // a short, non-chaotic stretch.
    let sys = compile_common::chain(5);
    let nat = lagrangian(&sys, &native());
    let int = lagrangian(&sys, &interpreted());
    let y0: Vec<f64> = (0..10).map(|i| if i < 5 { 0.1 * i as f64 } else { 0.0 }).collect();
    let a = Gauss6::new(1e-2).integrate(&nat, 0.0..1.0, &y0).unwrap();
    let b = Gauss6::new(1e-2).integrate(&int, 0.0..1.0, &y0).unwrap();
    for (x, z) in a.last_state().iter().zip(b.last_state()) {
        assert!((x - z).abs() < 1e-9, "{x} vs {z}");
    }
}

#[test]
fn native_right_hand_sides_are_shared_across_threads() {
    // The machine code is called from several threads at once with the same results.
    let sys = compile_common::chain(5);
    let rhs = lagrangian(&sys, &native());
    let mut rng = Rng(12);
    let ys = states(10, false, &mut rng, 64);
    let serial: Vec<Vec<f64>> = ys
        .iter()
        .map(|y| {
            let mut d = vec![0.0; 10];
            rhs.try_eval(0.0, y, &mut d).unwrap();
            d
        })
        .collect();
    std::thread::scope(|s| {
        let handles: Vec<_> = (0..4)
            .map(|_| {
                s.spawn(|| {
                    ys.iter()
                        .map(|y| {
                            let mut d = vec![0.0; 10];
                            rhs.try_eval(0.0, y, &mut d).unwrap();
                            d
                        })
                        .collect::<Vec<_>>()
                })
            })
            .collect();
        for h in handles {
            let got = h.join().unwrap();
            for (a, b) in got.iter().zip(&serial) {
                assert_same("threads", a, b);
            }
        }
    });
    // Dropping the right-hand side frees its code; a clone of a tape keeps it alive.
    let tape = rhs.tape().clone();
    drop(rhs);
    let mut out = vec![0.0; tape.n_outputs()];
    tape.eval(&[0.1; 11], &mut out);
    assert!(out.iter().all(|v| v.is_finite()));
}

/// Tapes above 60,000 instructions stay interpreted (Cranelift's compile time grows faster
/// than linearly with one huge block) and still give the right values; a tape of the same shape
/// below the limit goes native. The outputs are `sin(x + k)` and `sin(x + k) y` for
/// k = 1…n: two distinct instructions per output, plus a product.
#[test]
fn tapes_above_the_native_limit_fall_back_to_the_interpreter() {
    let outputs = |n: i64| -> Vec<lagrangian::Expr> {
        let (x, y) = (lagrangian::Expr::var("x"), lagrangian::Expr::var("y"));
        (1..=n)
            .flat_map(|k| {
                let s = lagrangian::Expr::call(Func::Sin, vec![x.plus(&lagrangian::Expr::int(k))]);
                [s.clone(), s.times(&y)]
            })
            .collect()
    };
    let big = Tape::compile_with_options(&outputs(21_000), &["x", "y"], &[], &native()).unwrap();
    assert!(big.instrs().len() > 60_000, "only {} instructions: not above the limit", big.instrs().len());
    assert!(!big.is_native(), "a tape of {} instructions was compiled natively", big.instrs().len());
    let (xv, yv) = (0.3, -1.7);
    let mut out = vec![0.0; big.n_outputs()];
    big.eval(&[xv, yv], &mut out);
    for k in [1usize, 7_777, 21_000] {
        let s = (xv + k as f64).sin();
        assert_eq!(out[2 * (k - 1)], s, "sin(x + {k})");
        assert_eq!(out[2 * (k - 1) + 1], s * yv, "sin(x + {k}) y");
    }
    let small = Tape::compile_with_options(&outputs(100), &["x", "y"], &[], &native()).unwrap();
    assert_eq!(small.is_native(), jit_expected());
}
