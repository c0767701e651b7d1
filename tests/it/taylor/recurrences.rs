//! Taylor-mode AD of a tape, instruction by instruction, against an independent computation:
//! the Taylor coefficients of `f(t)` at `t₀` by Cauchy's integral formula,
//! `f_k = (1/2πi) ∮ f(z) / (z − t₀)^{k+1} dz`, evaluated with the trapezoidal rule on a circle
//! of radius `r` inside the disc of convergence in complex arithmetic (num-complex's own
//! elementary functions). The rule's aliasing error is `O((r/R)^N)`, negligible for `N = 256`
//! points and `r ≤ R/2`; its rounding error is about `ε · max|f| / r^k`, which sets the
//! tolerance of each comparison.

use std::f64::consts::PI;

use lagrangian::compile::{Instr, Tape, TaylorTape};
use lagrangian::{parse, Func};
use num_complex::Complex64 as C;

const ORDER: usize = 24;
const POINTS: usize = 256;

/// The coefficients `f_0 … f_ORDER` of `f` at `t0` and the bound `max |f|` on the circle.
fn cauchy(f: &dyn Fn(C) -> C, t0: f64, r: f64) -> (Vec<f64>, f64) {
    let mut coeffs = vec![0.0; ORDER + 1];
    let mut m = 0.0f64;
    let vals: Vec<C> = (0..POINTS)
        .map(|j| {
            let z = C::from_polar(r, 2.0 * PI * j as f64 / POINTS as f64);
            let v = f(C::new(t0, 0.0) + z);
            m = m.max(v.norm());
            v
        })
        .collect();
    for (k, ck) in coeffs.iter_mut().enumerate() {
        let mut acc = C::new(0.0, 0.0);
        for (j, v) in vals.iter().enumerate() {
            acc += v * C::from_polar(1.0, -2.0 * PI * (j * k) as f64 / POINTS as f64);
        }
        *ck = acc.re / POINTS as f64 / r.powi(k as i32);
    }
    (coeffs, m)
}

/// Expands the tape of `src` (a function of `t`) to `ORDER` at `t0` and compares every
/// coefficient with the Cauchy integral; returns the tape for kind checks.
fn check(src: &str, f: &dyn Fn(C) -> C, t0: f64, r: f64) -> Tape {
    let tape = Tape::compile(&[parse(src).unwrap()], &["t"], &[]).unwrap();
    let tt = TaylorTape::new(&tape);
    let s = ORDER + 1;
    // NaN everywhere: a recurrence that read a row nobody computed would show.
    let mut c = vec![f64::NAN; tt.n_rows() * s];
    tt.expand(&mut c, s, ORDER, |k, c| {
        c[k] = match k {
            0 => t0,
            1 => 1.0,
            _ => 0.0,
        }
    })
    .unwrap();
    let row = tt.output_row(0);
    let ours = &c[row * s..(row + 1) * s];
    let (exact, m) = cauchy(f, t0, r);
    // Order 0 is the interpreter's value, bit for bit.
    let mut out = [0.0];
    tape.interpreted().eval(&[t0], &mut out);
    assert_eq!(ours[0], out[0], "{src}: order 0 differs from the interpreter");
    for k in 0..=ORDER {
        let tol = 1e-12 * m / r.powi(k as i32);
        assert!(
            (ours[k] - exact[k]).abs() <= tol,
            "{src} at t0 = {t0}, order {k}: Taylor tape {:e}, Cauchy integral {:e} (tolerance {tol:e})\n{tape}",
            ours[k],
            exact[k]
        );
    }
    tape
}

fn has(tape: &Tape, pred: impl Fn(&Instr) -> bool) -> bool {
    tape.instrs().iter().any(pred)
}

fn call(f: Func) -> impl Fn(&Instr) -> bool {
    move |i| matches!(i, Instr::Call { f: g, .. } if *g == f)
}

#[test]
fn arithmetic_add_sub_neg_mul_div() {
    // A rational function: poles where 2 + t + t² = 0 (|t| = √2) and t = 3.
    let tape = check(
        "(t^3 - 2 t + 1) / (2 + t + t^2) - t / (3 - t)",
        &|t: C| (t * t * t - 2.0 * t + 1.0) / (2.0 + t + t * t) - t / (3.0 - t),
        0.1,
        0.6,
    );
    assert!(has(&tape, |i| matches!(i, Instr::Div { .. })));
    assert!(has(&tape, |i| matches!(i, Instr::Mul { .. })));
    assert!(has(&tape, |i| matches!(i, Instr::Sub { .. })));
    let tape = check("-(t^2) + t", &|t: C| -(t * t) + t, 0.5, 1.0);
    assert!(has(&tape, |i| matches!(i, Instr::Sub { .. } | Instr::Neg { .. })));
    let tape = check("-(t^2 + 1) * exp(t)", &|t: C| -(t * t + 1.0) * t.exp(), 0.5, 1.0);
    assert!(has(&tape, |i| matches!(i, Instr::Neg { .. })), "{tape}");
    let tape = check("t + t^2 + exp(t)", &|t: C| t + t * t + t.exp(), 0.3, 1.0);
    assert!(has(&tape, |i| matches!(i, Instr::Add { .. })));
}

#[test]
fn square_roots_and_powers() {
    let tape = check("sqrt(2 + t + t^2/4)", &|t: C| (2.0 + t + t * t / 4.0).sqrt(), 0.2, 0.6);
    assert!(has(&tape, |i| matches!(i, Instr::Sqrt { .. })));
    // A constant non-integer exponent.
    let tape = check("(2 + t)^(1/3)", &|t: C| (2.0 + t).powf(1.0 / 3.0), 0.2, 1.0);
    assert!(has(&tape, |i| matches!(i, Instr::Powf { .. } | Instr::Root { .. })));
    // An odd root is real for a negative base: the tape's `Root` instruction.
    let tape = check("(t - 2)^(1/3)", &|t: C| -(2.0 - t).powf(1.0 / 3.0), 0.2, 1.0);
    assert!(has(&tape, |i| matches!(i, Instr::Root { .. })), "{tape}");
    // An exponent that varies with t: exp(b log a).
    let tape = check("(2 + t)^(1 + t/2)", &|t: C| (2.0 + t).powc(1.0 + t / 2.0), 0.2, 1.0);
    assert!(has(&tape, |i| matches!(i, Instr::Powf { .. })));
    // Half-integer powers lower to sqrt and products.
    check("(1 + t^2)^(-3/2)", &|t: C| (1.0 + t * t).powf(-1.5), 0.3, 0.5);
}

/// The recurrences of orders ≥ 1 are rewritten (products with and quotients by constants as
/// scalings, squares over half their terms, powers of one row fused into one recurrence);
/// the series must not change.
#[test]
fn rewritten_recurrences_give_the_same_series() {
    let u = |t: C| 1.0 + t * t;
    // Kepler's force: −x/(u √u) with u = x² + y²; here 1/(u √u), a power −3/2 of u.
    check("1/((1 + t^2) sqrt(1 + t^2))", &move |t: C| u(t).powf(-1.5), 0.3, 0.5);
    // The same power while √u is also read elsewhere (it stays a row of its own).
    check("sqrt(1 + t^2) - 2/((1 + t^2) sqrt(1 + t^2))", &move |t: C| u(t).sqrt() - 2.0 * u(t).powf(-1.5), 0.3, 0.5);
    // Roots of roots, a root over its base, a power times a negated power.
    check("sqrt(sqrt(2 + t))", &|t: C| (2.0 + t).powf(0.25), 0.2, 1.0);
    check("(2 + t)^(1/3) / (2 + t)", &|t: C| (2.0 + t).powf(-2.0 / 3.0), 0.2, 1.0);
    check("-(2 + t)^(1/3) * (2 + t)^(0.7)", &|t: C| -(2.0 + t).powf(1.0 / 3.0 + 0.7), 0.2, 1.0);
    // Constants times and over a series, and a square.
    check(
        "3 (t + 2)^2 - (t^2 + t)/7 + 2.5 exp(t)",
        &|t: C| 3.0 * (t + 2.0) * (t + 2.0) - (t * t + t) / 7.0 + 2.5 * t.exp(),
        0.3,
        1.0,
    );
}

#[test]
fn kepler_runs_the_recurrences_of_its_decomposition() {
    // −x/|q|³ and −y/|q|³: x², y², u = x² + y², u^(−3/2), x u^(−3/2), y u^(−3/2). The plain
    // tape's √u and u √u are not recomputed at orders ≥ 1.
    let sys = lagrangian::mechanics::System::from_hamiltonian("1/2 (p_x^2 + p_y^2) - 1/sqrt(x^2 + y^2)", &["x", "y"]);
    let ode = sys.unwrap().compile_taylor().unwrap();
    let tt = ode.taylor_tape();
    assert_eq!(tt.n_recurrences(), 6, "{tt}");
}

#[test]
fn sine_and_cosine_alone_and_paired() {
    let g = |t: C| t * t / 3.0 + t;
    let tape = check("sin(t^2/3 + t)", &move |t: C| g(t).sin(), 0.4, 1.5);
    assert!(has(&tape, call(Func::Sin)));
    let tape = check("cos(t^2/3 + t)", &move |t: C| g(t).cos(), 0.4, 1.5);
    assert!(has(&tape, call(Func::Cos)));
    let tape = check(
        "sin(t^2/3 + t) * cos(t^2/3 + t) + cos(t^2/3 + t)",
        &move |t: C| g(t).sin() * g(t).cos() + g(t).cos(),
        0.4,
        1.5,
    );
    assert!(has(&tape, |i| matches!(i, Instr::SinCos { .. })));
}

/// The sums `Σ j a_j b_{k−j}` read a row `j · a_j` written once per order: an input's by one
/// recurrence of its own, shared by every function of it (here a sine–cosine pair and an
/// exponential), a computed value's with its own write (no recurrence). One row per argument,
/// not one per sum or per function, or the multiplication per term would come back as one
/// per function.
#[test]
fn functions_of_one_argument_share_its_weighted_row() {
    let n = |src: &str| TaylorTape::new(&Tape::compile(&[parse(src).unwrap()], &["t"], &[]).unwrap()).n_recurrences();
    // The weighting of `t`, then the sine–cosine pair.
    assert_eq!(n("sin(t)"), 2);
    // One weighting of `t`, the sine–cosine pair, the exponential, the sum.
    assert_eq!(n("sin(t) + exp(t)"), 4);
    assert_eq!(n("sin(t) + cos(t) + exp(t)"), 5);
    // Computed arguments `t² + t` and `2t`: no weighting recurrence; the sine–cosine pair,
    // two exponentials and two sums.
    assert_eq!(n("sin(t^2 + t) + exp(t^2 + t) + exp(2 t)"), n("t^2 + t") + n("2 t") + 5);
    check("sin(t) + cos(t) * exp(t)", &|t: C| t.sin() + t.cos() * t.exp(), 0.3, 1.5);
    let g = |t: C| t * t + t;
    check("sin(t^2 + t) * exp(t^2 + t)", &move |t: C| g(t).sin() * g(t).exp(), 0.3, 1.0);
}

#[test]
fn exponential_logarithm_and_hyperbolic_functions() {
    let tape = check("exp(sin(t))", &|t: C| t.sin().exp(), 0.3, 1.5);
    assert!(has(&tape, call(Func::Exp)));
    let tape = check("log(2 + t + t^2/2)", &|t: C| (2.0 + t + t * t / 2.0).ln(), 0.2, 0.6);
    assert!(has(&tape, call(Func::Log)));
    let tape = check("sinh(t^2 - t)", &|t: C| (t * t - t).sinh(), 0.3, 1.5);
    assert!(has(&tape, call(Func::Sinh)));
    let tape = check("cosh(t^2 - t)", &|t: C| (t * t - t).cosh(), 0.3, 1.5);
    assert!(has(&tape, call(Func::Cosh)));
    let tape = check("tanh(t/2 + 1/4)", &|t: C| (t / 2.0 + 0.25).tanh(), 0.3, 1.2);
    assert!(has(&tape, call(Func::Tanh)));
}

#[test]
fn tangent_and_inverse_trigonometric_functions() {
    // tan has poles at ±π/2 of its argument; asin/acos branch points at ±1, atan at ±i.
    let tape = check("tan(t/2 + 1/5)", &|t: C| (t / 2.0 + 0.2).tan(), 0.3, 1.0);
    assert!(has(&tape, call(Func::Tan)));
    let tape = check("asin(t/3 + 1/10)", &|t: C| (t / 3.0 + 0.1).asin(), 0.2, 1.2);
    assert!(has(&tape, call(Func::Asin)));
    let tape = check("acos(t/3 + 1/10)", &|t: C| (t / 3.0 + 0.1).acos(), 0.2, 1.2);
    assert!(has(&tape, call(Func::Acos)));
    let tape = check("atan(t^2 + t)", &|t: C| (t * t + t).atan(), 0.3, 0.25);
    assert!(has(&tape, call(Func::Atan)));
    // atan2(a, b) = atan(a/b) where b stays in the right half plane.
    let tape = check("atan2(t + 1/2, 2 + t^2)", &|t: C| ((t + 0.5) / (2.0 + t * t)).atan(), 0.2, 0.6);
    assert!(has(&tape, |i| matches!(i, Instr::Atan2 { .. })));
}

#[test]
fn inverse_hyperbolic_and_reciprocal_functions() {
    // asinh has branch points at ±i: t/3 + 1/10 reaches them at |t + 3/10| = 3.
    let tape = check("asinh(t/3 + 1/10)", &|t: C| (t / 3.0 + 0.1).asinh(), 0.2, 1.2);
    assert!(has(&tape, call(Func::Asinh)));
    // Negative arguments too, where `log(u + √(1 + u²))` would cancel.
    let tape = check("asinh(t/3 - 4)", &|t: C| (t / 3.0 - 4.0).asinh(), 0.2, 1.2);
    assert!(has(&tape, call(Func::Asinh)));
    // acosh has its branch point at 1: t/3 + 2 reaches it at |t + 3| = 3.
    let tape = check("acosh(t/3 + 2)", &|t: C| (t / 3.0 + 2.0).acosh(), 0.2, 1.2);
    assert!(has(&tape, call(Func::Acosh)));
    // atanh has branch points at ±1: t/2 − 1/5 reaches them at t = 12/5 and −8/5, 2.1 and 1.9
    // from t₀ = 0.3.
    let tape = check("atanh(t/2 - 1/5)", &|t: C| (t / 2.0 - 0.2).atanh(), 0.3, 0.9);
    assert!(has(&tape, call(Func::Atanh)));
    // sec has poles where cos vanishes, ±π/2 of its argument: t/2 + 1/5 reaches π/2 at
    // t ≈ 2.74, 2.44 from t₀ = 0.3.
    let tape = check("sec(t/2 + 1/5)", &|t: C| 1.0 / (t / 2.0 + 0.2).cos(), 0.3, 1.0);
    assert!(has(&tape, call(Func::Sec)));
    // csc has poles at 0 and π of its argument: t/2 + 1 reaches 0 at t = −2, 2.3 from t₀ = 0.3.
    let tape = check("csc(t/2 + 1)", &|t: C| 1.0 / (t / 2.0 + 1.0).sin(), 0.3, 1.0);
    assert!(has(&tape, call(Func::Csc)));
    // coth has poles at iπn of its argument: t/2 + 1 is 0 at t = −2, 2.3 from t₀ = 0.3.
    let tape = check("coth(t/2 + 1)", &|t: C| 1.0 / (t / 2.0 + 1.0).tanh(), 0.3, 1.0);
    assert!(has(&tape, call(Func::Coth)));
}

#[test]
fn error_function_against_hermite_polynomials() {
    // Cauchy's formula needs erf on complex numbers, which num-complex lacks; instead the
    // closed form dⁿ/dxⁿ erf x = (2/√π) (−1)^{n−1} H_{n−1}(x) e^{−x²} (physicists' Hermite
    // polynomials, H_{n+1} = 2x H_n − 2n H_{n−1}): the coefficients of erf(t/2 + 1/5) at t₀ are
    // erf's at x₀ = t₀/2 + 1/5 times 2^{−k}.
    let t0 = 0.3;
    let x0 = t0 / 2.0 + 0.2;
    let tape = Tape::compile(&[parse("erf(t/2 + 1/5)").unwrap()], &["t"], &[]).unwrap();
    assert!(has(&tape, call(Func::Erf)));
    let tt = TaylorTape::new(&tape);
    let s = ORDER + 1;
    let mut c = vec![f64::NAN; tt.n_rows() * s];
    tt.expand(&mut c, s, ORDER, |k, c| c[k] = [t0, 1.0][..].get(k).copied().unwrap_or(0.0)).unwrap();
    let row = tt.output_row(0);
    let ours = &c[row * s..(row + 1) * s];
    // erf(0.35) to 30 digits (mpmath): 0.379382053562310298130948736995.
    assert!((ours[0] - 0.379_382_053_562_310_3).abs() < 2e-16, "{}", ours[0]);
    let mut h = vec![1.0, 2.0 * x0];
    for n in 1..ORDER {
        h.push(2.0 * x0 * h[n] - 2.0 * n as f64 * h[n - 1]);
    }
    let mut fact = 1.0;
    for k in 1..=ORDER {
        fact *= k as f64;
        let sign = if k % 2 == 1 { 1.0 } else { -1.0 };
        let exact = std::f64::consts::FRAC_2_SQRT_PI * sign * h[k - 1] * (-x0 * x0).exp() / fact / 2f64.powi(k as i32);
        let tol = 1e-14 * 2f64.powi(-(k as i32)) + 1e-12 * exact.abs();
        assert!((ours[k] - exact).abs() <= tol, "order {k}: {:e} vs {exact:e}", ours[k]);
    }
}

#[test]
fn abs_away_from_its_kink() {
    // |t − 3| = 3 − t near 0, |t + 2| = t + 2.
    let tape = check("abs(t - 3) * abs(t + 2)", &|t: C| (3.0 - t) * (t + 2.0), 0.5, 1.0);
    assert!(has(&tape, call(Func::Abs)));
}

#[test]
fn abs_at_its_kink_is_an_error_not_a_wrong_series() {
    let tape = Tape::compile(&[parse("abs(t - 1)").unwrap()], &["t"], &[]).unwrap();
    let tt = TaylorTape::new(&tape);
    let s = 5;
    let mut c = vec![0.0; tt.n_rows() * s];
    let r = tt.expand(&mut c, s, 4, |k, c| c[k] = [1.0, 1.0, 0.0, 0.0, 0.0][k]);
    assert!(r.is_err());
    // An argument identically zero is smooth: |0| = 0.
    let tape = Tape::compile(&[parse("abs(t - t) + t").unwrap()], &["t"], &[]).unwrap();
    let tt = TaylorTape::new(&tape);
    let mut c = vec![0.0; tt.n_rows() * s];
    assert!(tt.expand(&mut c, s, 4, |k, c| c[k] = [1.0, 1.0, 0.0, 0.0, 0.0][k]).is_ok());
}
