//! The native (Cranelift) Taylor recurrences against the interpreter, which is their
//! reference: for a tape using every instruction kind, every coefficient of every row up to
//! order 24 must be the interpreter's bit for bit (the native code adds the same terms in the
//! same order with the same IEEE operations), and so must whole Taylor integrations of
//! `W q'' = F` and Hamiltonian systems. The same holds for compact code (one function taking
//! the order, each sum a loop), for whole expansions from order 0 (`W₀`'s factor included),
//! and along the tiers a large tape passes through (interpreted, compact, unrolled).
//!
//! The interpreter itself is checked against Cauchy integrals in `taylor_recurrences.rs`.

use std::collections::BTreeSet;

use lagrangian::compile::{Instr, Tape, TaylorOde, TaylorTape, NO_JIT_ENV};
use lagrangian::integrate::problems::Kepler;
use lagrangian::integrate::{Integrate, Options, Taylor};
use lagrangian::mechanics::System;
use lagrangian::{parse, Func};

use crate::support::n_link;
use n_link::unit_n_link_system;

const ORDER: usize = 24;

/// Whether this run may expect native code (the JIT is on and the host is one Cranelift
/// supports natively).
fn jit_expected() -> bool {
    let off = std::env::var_os(NO_JIT_ENV).is_some_and(|v| !v.is_empty() && v != "0");
    !off && cfg!(any(target_arch = "x86_64", target_arch = "aarch64"))
}

/// The kind of an instruction, one name per `Instr` variant and per built-in called.
fn kind(i: &Instr) -> String {
    match i {
        Instr::Call { f, .. } => format!("call {f:?}"),
        other => format!("{other:?}").split(' ').next().unwrap_or("").to_string(),
    }
}

/// Expands `src` (a function of `t`) at `t0` to `ORDER` in both back ends; returns the kinds
/// of the tape's instructions after asserting that every row agrees bit for bit.
fn same_bits(src: &str, t0: f64) -> BTreeSet<String> {
    let tape = Tape::compile(&[parse(src).unwrap()], &["t"], &[]).unwrap();
    let tt = TaylorTape::new(&tape);
    let s = ORDER + 1;
    let time = |k: usize, c: &mut [f64]| {
        c[k] = match k {
            0 => t0,
            1 => 1.0,
            _ => 0.0,
        }
    };
    // Both buffers start as NaN: rows that orders ≥ 1 no longer need (the intermediate rows of
    // a fused power) stay NaN in both, and a recurrence reading a row never computed would
    // spread NaN into the output.
    let mut interp = vec![f64::NAN; tt.n_rows() * s];
    tt.expand(&mut interp, s, ORDER, time).unwrap();
    let native = tt.compile_native(s, ORDER);
    if !jit_expected() {
        return tape.instrs().iter().map(kind).collect();
    }
    let native = native.unwrap_or_else(|| panic!("{src}: no native Taylor code"));
    assert!(!native.is_compact(), "{src}: a small tape gets unrolled code");
    let compact = tt.compile_native_compact(s, ORDER).unwrap_or_else(|| panic!("{src}: no compact code"));
    assert!(compact.is_compact());
    for (form, code) in [("unrolled", native), ("compact", compact)] {
        assert_eq!((code.stride(), code.max_order()), (s, ORDER));
        let mut nat = vec![f64::NAN; tt.n_rows() * s];
        tt.expand_with(Some(&code), &mut nat, s, ORDER, time).unwrap();
        for (i, (a, b)) in interp.iter().zip(&nat).enumerate() {
            assert!(
                a.to_bits() == b.to_bits(),
                "{src}: row {}, order {}: interpreter {a:e}, {form} {b:e}\n{tape}",
                i / s,
                i % s
            );
        }
    }
    // The series are not trivial: the output's high orders are non-zero.
    let out = tt.output_row(0);
    assert!(interp[out * s + ORDER] != 0.0, "{src}: order {ORDER} vanishes");
    tape.instrs().iter().map(kind).collect()
}

#[test]
fn every_instruction_kind_agrees_with_the_interpreter_bit_for_bit() {
    let cases = [
        ("(t^3 - 2 t + 1) / (2 + t + t^2) - t / (3 - t)", 0.1),
        ("-(t^2 + 1) * exp(t) + t", 0.5),
        ("sqrt(2 + t + t^2/4)", 0.2),
        ("(2 + t)^(1/3)", 0.2),
        ("(t - 2)^(1/3)", 0.2),
        ("(2 + t)^(1 + t/2)", 0.2),
        ("(1 + t^2)^(-3/2) + (3 + t)^(0.7)", 0.3),
        ("sin(t^2/3 + t)", 0.4),
        ("cos(t^2/3 + t)", 0.4),
        ("sin(t^2/3 + t) * cos(t^2/3 + t) + cos(t^2/3 + t)", 0.4),
        ("exp(sin(t))", 0.3),
        ("log(2 + t + t^2/2)", 0.2),
        ("sinh(t^2 - t) + cosh(t^2 - t)", 0.3),
        ("sinh(t^2 - t)", 0.3),
        ("cosh(t^2 - t)", 0.3),
        ("tanh(t/2 + 1/4)", 0.3),
        ("tan(t/2 + 1/5)", 0.3),
        ("asin(t/3 + 1/10)", 0.2),
        ("acos(t/3 + 1/10)", 0.2),
        ("atan(t^2 + t)", 0.3),
        ("atan2(t + 1/2, 2 + t^2)", 0.2),
        ("abs(t - 3) / abs(t + 2)", 0.5),
        ("asinh(t/3 - 4) + asinh(t^2)", 0.2),
        ("acosh(t/3 + 2)", 0.2),
        ("atanh(t^2/3 + t/4)", 0.3),
        ("sec(t^2/3 + t)", 0.4),
        ("csc(t^2/3 + t + 1/2)", 0.4),
        ("coth(t/2 + 1)", 0.3),
        ("erf(t^2/3 + t - 1/2)", 0.4),
    ];
    let mut seen = BTreeSet::new();
    for (src, t0) in cases {
        seen.extend(same_bits(src, t0));
    }
    // Every instruction kind of the tape and every built-in but the one-operand `atan2`
    // (which the lowering never emits) occurred.
    let mut want: BTreeSet<String> =
        ["Add", "Sub", "Mul", "Div", "Neg", "Sqrt", "SinCos", "Atan2", "Powf", "Root"].map(String::from).into();
    for f in Func::ALL.into_iter().filter(|f| *f != Func::Atan2) {
        want.insert(format!("call {f:?}"));
    }
    let missing: Vec<_> = want.difference(&seen).collect();
    assert!(missing.is_empty(), "instruction kinds not covered: {missing:?} (seen {seen:?})");
}

#[test]
fn abs_kinks_are_reported_by_the_native_code_too() {
    // |t − 1| at t = 1 (order 1 moves), |(t − 1)²| at t = 1 (order 2 moves), |t − t| + t
    // (identically zero argument: smooth).
    for (src, kink) in [("abs(t - 1)", true), ("abs((t - 1)^2) + t", true), ("abs(t - t) + t", false)] {
        let tape = Tape::compile(&[parse(src).unwrap()], &["t"], &[]).unwrap();
        let tt = TaylorTape::new(&tape);
        let s = 6;
        let time = |k: usize, c: &mut [f64]| c[k] = [1.0, 1.0, 0.0, 0.0, 0.0, 0.0][k];
        let mut c = vec![0.0; tt.n_rows() * s];
        assert_eq!(tt.expand(&mut c, s, 5, time).is_err(), kink, "{src}: interpreter");
        for (form, code) in [("unrolled", tt.compile_native(s, 5)), ("compact", tt.compile_native_compact(s, 5))] {
            if let Some(native) = code {
                let mut c = vec![0.0; tt.n_rows() * s];
                assert_eq!(tt.expand_with(Some(&native), &mut c, s, 5, time).is_err(), kink, "{src}: {form}");
            } else {
                assert!(!jit_expected(), "{src}: no {form} code");
            }
        }
    }
}

#[test]
fn abs_kinks_are_reported_by_a_whole_native_expansion() {
    // x' = |x| + 1 expanded at x = 0: the argument of abs is 0 and its first coefficient is 1.
    let f = [parse("abs(x) + 1").unwrap()];
    let ode = TaylorOde::from_exprs(&f, &["x"], &[]).unwrap().with_native(true);
    let reference = ode.clone().with_native(false);
    let p = 6;
    if jit_expected() {
        assert!(ode.native_for(p).is_some_and(|n| n.is_whole()), "no whole native expansion");
    }
    let mut scratch = vec![0.0; ode.scratch_len(p)];
    let mut coeffs = vec![0.0; p + 1];
    for o in [&ode, &reference] {
        let err = o.expand(0.0, &[0.0], p, &mut scratch, &mut coeffs).unwrap_err();
        assert!(matches!(err, lagrangian::compile::TaylorError::AbsKink { .. }), "{err}");
    }
    // Away from the kink both give the same bits (x' = x + 1: x_k = 1.5/k! for k ≥ 1).
    let mut other = coeffs.clone();
    ode.expand(0.0, &[0.5], p, &mut scratch, &mut coeffs).unwrap();
    reference.expand(0.0, &[0.5], p, &mut scratch, &mut other).unwrap();
    assert_eq!(coeffs, other);
    assert!((coeffs[p] - 1.5 / 720.0).abs() < 1e-15, "{coeffs:?}");
}

#[test]
fn a_first_order_whole_expansion_computes_order_0_natively_with_the_same_bits() {
    // Every operation of order 0: the built-ins, atan2, square roots, real roots, constant and
    // variable powers, abs, quotients, and the time.
    let f = [
        "sin(y) cos(x) + tan(x/3) + exp(-x^2) + log(2 + y^2) + atan2(y, 1 + x^2)",
        "sinh(x/4) - cosh(y/5) + tanh(x) + asin(x/4) + acos(y/4) + atan(x y) + sqrt(3 + x^2)",
        "(2 + x^2)^(1/3) + (1 + y^2)^0.7 + (2 + x^2)^(1 + y/3) + abs(x - 5)/(3 + y^2) + t/10 - z",
    ]
    .map(|e| parse(e).unwrap());
    let ode = TaylorOde::from_exprs(&f, &["x", "y", "z"], &[]).unwrap().with_native(true);
    let reference = ode.clone().with_native(false);
    let p = 16;
    if jit_expected() {
        let code = ode.native_for(p).expect("native code");
        assert!(code.is_whole(), "{code:?}");
    }
    let mut scratch = vec![0.0; ode.scratch_len(p)];
    let (mut a, mut b) = (vec![0.0; 3 * (p + 1)], vec![0.0; 3 * (p + 1)]);
    for (t, y) in [(0.0, [0.1, 0.2, 0.3]), (0.7, [-0.5, 0.9, 2.0]), (-1.3, [1.2, -0.4, -1.0])] {
        ode.expand(t, &y, p, &mut scratch, &mut a).unwrap();
        reference.expand(t, &y, p, &mut scratch, &mut b).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&a), bits(&b), "t = {t}, y = {y:?}");
        assert!(a.iter().all(|x| x.is_finite()) && (0..3).all(|i| a[i * (p + 1) + p] != 0.0), "{a:?}");
    }
}

#[test]
fn a_small_tape_runs_on_compact_code_until_its_unrolled_code_is_due() {
    // Kepler (6 recurrences): default tiers, a run of more than `COMPACT_AFTER_EXPANSIONS`
    // steps and fewer than `AUTO_NATIVE_AFTER_EXPANSIONS` ends on compact code, with the
    // interpreter's bits.
    let (ode, reference) = (kepler(), kepler().with_native(false));
    let m = Taylor::new(1e-15);
    let y0 = Kepler::pericentre(0.6);
    let run = |o: &TaylorOde| m.integrate_with(o, 0.0..1000.0, &y0, Options::new().final_only()).unwrap();
    let (ra, rb) = (run(&ode), run(&reference));
    assert!(
        (lagrangian::compile::COMPACT_AFTER_EXPANSIONS..lagrangian::compile::AUTO_NATIVE_AFTER_EXPANSIONS)
            .contains(&ra.stats.steps),
        "{} steps",
        ra.stats.steps
    );
    assert_eq!(ra.last_state(), rb.last_state());
    let code = ode.native_compiled(m.taylor_order());
    assert_eq!(code.as_ref().is_some_and(|c| c.is_compact()), jit_expected(), "{code:?}");
}

const DOUBLE_PENDULUM: &str = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
                               + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";

fn double_pendulum() -> TaylorOde {
    System::from_lagrangian(DOUBLE_PENDULUM, &["θ1", "θ2"])
        .and_then(|s| s.with_params(&[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)]))
        .unwrap()
        .compile_taylor()
        .unwrap()
}

fn kepler() -> TaylorOde {
    System::from_hamiltonian("1/2 (p_x^2 + p_y^2) - 1/sqrt(x^2 + y^2)", &["x", "y"]).unwrap().compile_taylor().unwrap()
}

fn indefinite() -> TaylorOde {
    let l = "1/2 x'^2 - 1/2 (1 + x^2/10) y'^2 - 1/2 x^2 + 1/2 y^2";
    System::from_lagrangian(l, &["x", "y"]).unwrap().compile_taylor().unwrap()
}

#[test]
fn ode_expansions_and_whole_runs_equal_the_interpreter() {
    for (name, ode, y0, t1) in [
        ("double pendulum (W q'' = F)", double_pendulum(), vec![2.0, 2.5, 0.3, -0.2], 10.0),
        ("Kepler e = 0.6 (Hamiltonian)", kepler(), Kepler::pericentre(0.6).to_vec(), 20.0),
        // A symmetric but indefinite W: its Cholesky fails at order 0, so every expansion
        // falls back from the whole native expansion to the interpreter with an LU solve.
        ("indefinite W (LU)", indefinite(), vec![0.5, 0.3, 0.1, -0.2], 200.0),
    ] {
        // Native code is on by default, compiled on demand (see `TaylorOde::with_native`).
        assert_eq!(ode.native_for(19).is_some(), jit_expected(), "{name}: native code by default");
        let reference = ode.clone().with_native(false);
        let ode = ode.with_native(true);
        let p = 19;
        if jit_expected() {
            assert!(ode.native_for(p).is_some(), "{name}: no native code at order {p}");
        }
        assert!(reference.native_for(p).is_none());
        let mut a = vec![0.0; ode.scratch_len(p)];
        let mut b = a.clone();
        let (mut ca, mut cb) = (vec![0.0; ode.dim() * (p + 1)], vec![0.0; ode.dim() * (p + 1)]);
        ode.expand(0.3, &y0, p, &mut a, &mut ca).unwrap();
        reference.expand(0.3, &y0, p, &mut b, &mut cb).unwrap();
        assert_eq!(
            ca.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            cb.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
            "{name}"
        );
        assert!((0..ode.dim()).any(|i| ca[i * (p + 1) + p] != 0.0), "{name}: order {p} vanishes");
        // Whole runs: long enough to pass the interpreted warm-up, then native.
        let m = Taylor::new(1e-15);
        let run = |o: &TaylorOde| m.integrate_with(o, 0.0..t1, &y0, Options::new().final_only()).unwrap();
        let (ra, rb) = (run(&ode), run(&reference));
        assert!(ra.stats.steps > lagrangian::compile::NATIVE_AFTER_EXPANSIONS, "{name}: run too short to go native");
        assert_eq!(ra.last_state(), rb.last_state(), "{name}");
    }
}

#[test]
fn a_whole_expansion_leaves_out_only_the_last_coefficients_nothing_reads() {
    // The double pendulum's F reads sin θ₁ and sin θ₂; their cosines feed only the sines'
    // recurrences at later orders, so their last coefficients are left out. The state's
    // coefficients are the interpreter's bit for bit at the loose tolerances' orders (8, 11,
    // 13; the existing comparison runs order 19), and every other coefficient of every row too.
    if !jit_expected() {
        return;
    }
    let ode = double_pendulum().with_native(true);
    let reference = ode.clone().with_native(false);
    let y0 = [2.0, 2.5, 0.3, -0.2];
    for p in [8, 11, 13] {
        assert!(ode.native_for(p).is_some_and(|n| n.is_whole()), "order {p}: no whole native expansion");
        let (mut a, mut b) = (vec![0.0; ode.scratch_len(p)], vec![0.0; ode.scratch_len(p)]);
        let (mut ca, mut cb) = (vec![0.0; ode.dim() * (p + 1)], vec![0.0; ode.dim() * (p + 1)]);
        ode.expand(0.3, &y0, p, &mut a, &mut ca).unwrap();
        reference.expand(0.3, &y0, p, &mut b, &mut cb).unwrap();
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&ca), bits(&cb), "order {p}");
        let rows = ode.taylor_tape().n_rows();
        let differ: Vec<(usize, usize)> = (0..rows * (p + 1))
            .filter(|&i| a[i].to_bits() != b[i].to_bits())
            .map(|i| (i / (p + 1), i % (p + 1)))
            .collect();
        // Two rows (the cosines), at the last order the tape is expanded to (p − 1), and
        // nowhere else; the interpreter computed them, so they are not 0 there.
        assert_eq!(differ.len(), 2, "order {p}: {differ:?}");
        assert!(differ.iter().all(|&(r, k)| k == p - 1 && a[r * (p + 1) + k] == 0.0 && b[r * (p + 1) + k] != 0.0));
    }
}

#[test]
fn tapes_too_large_to_unroll_get_compact_code_with_the_same_bits_up_to_a_size() {
    // 40 chained products at order 100: far more terms than unrolled code may have.
    let src = (0..40).fold("t".to_string(), |acc, i| format!("({acc}) * (t + {i}/7)"));
    let tape = Tape::compile(&[parse(&src).unwrap()], &["t"], &[]).unwrap();
    let tt = TaylorTape::new(&tape);
    let (s, p) = (101, 100);
    // A stride that cannot hold the orders asked for is refused, not a buffer overrun.
    assert!(tt.compile_native(5, 5).is_none());
    assert!(tt.compile_native_compact(5, 5).is_none());
    let native = tt.compile_native(s, p);
    if !jit_expected() {
        return;
    }
    let native = native.expect("compact code");
    assert!(native.is_compact() && !native.is_whole());
    let time = |k: usize, c: &mut [f64]| c[k] = [0.3, 1.0].get(k).copied().unwrap_or(0.0);
    let mut interp = vec![f64::NAN; tt.n_rows() * s];
    let mut nat = interp.clone();
    tt.expand(&mut interp, s, p, time).unwrap();
    tt.expand_with(Some(&native), &mut nat, s, p, time).unwrap();
    let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
    assert_eq!(bits(&interp), bits(&nat));
    // A polynomial of degree 41: order 41 is its leading coefficient 1, every higher order 0.
    let out = tt.output_row(0) * s;
    assert_eq!(interp[out + 41], 1.0);
    assert!(interp[out + 42..out + s].iter().all(|&x| x == 0.0));
    // 700 products: past the recurrences compact code pays for (the interpreter is faster), so
    // no native code is chosen; asked for, compact code still gives the interpreter's bits.
    let src = (1..=700).fold("t".to_string(), |acc, i| format!("({acc}) * (1 + t/{i})"));
    let tt = TaylorTape::new(&Tape::compile(&[parse(&src).unwrap()], &["t"], &[]).unwrap());
    assert!(tt.n_recurrences() > 600);
    assert!(tt.compile_native(s, p).is_none());
    let compact = tt.compile_native_compact(s, p).expect("compact code on request");
    let mut interp = vec![f64::NAN; tt.n_rows() * s];
    let mut nat = interp.clone();
    tt.expand(&mut interp, s, p, time).unwrap();
    tt.expand_with(Some(&compact), &mut nat, s, p, time).unwrap();
    assert_eq!(bits(&interp), bits(&nat));
    let out = tt.output_row(0) * s;
    assert!(interp[out..out + s].iter().all(|x| x.is_finite()) && interp[out + p] != 0.0);
}

#[test]
fn a_large_tape_runs_on_compact_code_then_unrolled_code_with_the_same_bits() {
    // The 3-link pendulum (`W q'' = F`, symmetric `W`).
    let ode = unit_n_link_system(3).compile_taylor().unwrap();
    let m = Taylor::new(1e-15);
    let p = m.taylor_order();
    let terms = ode.taylor_tape().n_recurrences() * (p - 1) * (p - 1) / 2;
    assert!(terms > lagrangian::compile::COMPACT_ABOVE_TERMS, "{terms} terms: not a large tape");
    let y0 = [0.5, 0.6, 0.7, 0.0, 0.0, 0.0];
    let run = |o: &TaylorOde, t1: f64| m.integrate_with(o, 0.0..t1, &y0, Options::new().final_only()).unwrap();
    let reference = ode.clone().with_native(false);
    // Default tiers: a run of more than `COMPACT_AFTER_EXPANSIONS` steps ends on compact code.
    let tiered = ode.clone();
    let (ra, rb) = (run(&tiered, 400.0), run(&reference, 400.0));
    assert!(ra.stats.steps > lagrangian::compile::COMPACT_AFTER_EXPANSIONS, "{} steps", ra.stats.steps);
    assert_eq!(ra.last_state(), rb.last_state());
    let code = tiered.native_compiled(p);
    assert_eq!(code.as_ref().is_some_and(|c| c.is_compact()), jit_expected(), "{code:?}");
    // Switched on: the final code (a whole unrolled expansion) after a few expansions.
    let early = ode.with_native(true);
    assert_eq!(run(&early, 400.0).last_state(), rb.last_state());
    let code = early.native_compiled(p);
    assert_eq!(code.as_ref().is_some_and(|c| c.is_whole()), jit_expected(), "{code:?}");
}

#[test]
fn a_whole_expansion_hands_a_bad_mass_matrix_to_the_interpreter() {
    // W = 1/x² is infinite at x = 0 and W = −1 − x² is negative definite: the generated code's
    // order 0 must not go on with a Cholesky factor of either (it flags the expansion, and the
    // interpreter redoes it), so both give the interpreter's answer, a typed error or an LU
    // solve, never the native code's garbage.
    let p = 16;
    for (l, y) in [("1/2 x'^2/x^2 - x", [0.0, 1.0]), ("-1/2 (1 + x^2) x'^2 - x", [0.5, 1.0])] {
        let ode = System::from_lagrangian(l, &["x"]).unwrap().compile_taylor().unwrap().with_native(true);
        let reference = ode.clone().with_native(false);
        if jit_expected() {
            assert!(ode.native_for(p).is_some_and(|c| c.is_whole()), "{l}: no whole native expansion");
        }
        let mut scratch = vec![0.0; ode.scratch_len(p)];
        let (mut a, mut b) = (vec![0.0; 2 * (p + 1)], vec![0.0; 2 * (p + 1)]);
        let native = ode.expand(0.0, &y, p, &mut scratch, &mut a);
        let interpreted = reference.expand(0.0, &y, p, &mut scratch, &mut b);
        match (native, interpreted) {
            (Err(e), Err(f)) => assert_eq!(e.to_string(), f.to_string(), "{l}"),
            (Ok(()), Ok(())) => {
                let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
                assert_eq!(bits(&a), bits(&b), "{l}");
            }
            (n, i) => panic!("{l}: native {n:?}, interpreted {i:?}"),
        }
    }
}
