//! The Taylor interpreter: the recurrences of each operation, order by order.

use super::ir::KinkAt;
use super::native::TaylorNative;

use super::ir::{Op, Weight};
use super::TaylorTape;
use crate::lanes::Lane;

impl TaylorTape {
    /// Whether the argument of some `abs` changes sign between the expansion point and `h`
    /// (its polynomial, orders `0..=order` of a buffer filled by [`TaylorTape::expand`] or
    /// [`TaylorOde::expand`](super::TaylorOde::expand), evaluated at `h`): the series is then not the solution there.
    pub fn kink_within(&self, c: &[f64], stride: usize, order: usize, h: f64) -> bool {
        self.abs_args.iter().any(|&r| {
            let row = &c[r as usize * stride..r as usize * stride + order + 1];
            let end = row.iter().rev().fold(0.0, |acc, &x| acc * h + x);
            (row[0] > 0.0 && end < 0.0) || (row[0] < 0.0 && end > 0.0)
        })
    }

    /// Row `r`'s weighted row in a coefficient buffer of stride `s` (the interpreter's sums).
    fn weighted_of<'c, L: Lane>(&self, c: &'c [L], s: usize, r: u32) -> &'c [L] {
        let w = self.weighted_row(r).expect("weigh_rows gives every weighted operand its row");
        row(c, w, s)
    }

    /// Prepares a coefficient buffer (`n_rows · stride` values): constants in their rows with
    /// zero higher coefficients. Inputs are the caller's.
    #[inline(always)]
    pub fn init<L: Lane>(&self, c: &mut [L], stride: usize) {
        for (i, &v) in self.consts.iter().enumerate() {
            let r = (self.n_inputs + i) * stride;
            c[r] = L::splat(v);
            c[r + 1..r + stride].fill(L::splat(0.0));
        }
    }

    /// Computes order `k` of every value, given orders `0..k` of every row and order `k` of
    /// the inputs. Order 0 runs the interpreter's operations. The only failure is an `abs`
    /// whose argument is 0 while its order-`k` coefficient is not (a kink).
    pub fn run_order<L: Lane>(&self, c: &mut [L], stride: usize, k: usize) -> Result<(), KinkAt> {
        self.run_order_inline(c, stride, k)
    }

    /// [`TaylorTape::run_order`], inlined into its caller: a batch expansion compiled for
    /// wider vector registers than the baseline (`target_feature`) gets the whole
    /// interpreter compiled for them.
    #[inline(always)]
    pub(super) fn run_order_inline<L: Lane>(&self, c: &mut [L], stride: usize, k: usize) -> Result<(), KinkAt> {
        assert!(c.len() >= self.n_rows * stride && k < stride, "Taylor buffer too short");
        if k == 0 {
            self.run_order0(c, stride);
            return Ok(());
        }
        // Divisions by order-0 values and by `k` are multiplications by their reciprocals,
        // which do not wait for order `k` of anything.
        let s = stride;
        let at = |c: &[L], r: u32, j: usize| c[r as usize * s + j];
        // Writes order `k` of row `r` and, if it has one, of its weighted row.
        let put = |c: &mut [L], r: u32, v: L| {
            c[r as usize * s + k] = v;
            if let Some(w) = self.weighted[r as usize] {
                c[w as usize * s + k] = v * L::splat(k as f64);
            }
        };
        for op in &self.ops {
            match *op {
                Op::Weigh { d, a } => {
                    let v = at(c, a, k) * L::splat(k as f64);
                    put(c, d, v);
                }
                Op::Add { d, a, b } => {
                    let v = at(c, a, k) + at(c, b, k);
                    put(c, d, v);
                }
                Op::Sub { d, a, b } => {
                    let v = at(c, a, k) - at(c, b, k);
                    put(c, d, v);
                }
                Op::Neg { d, a } => {
                    let v = -at(c, a, k);
                    put(c, d, v);
                }
                Op::Scale { d, a, f } => {
                    let v = at(c, a, k) * L::splat(f);
                    put(c, d, v);
                }
                Op::Mul { d, a, b } => {
                    let (ra, rb) = (row(c, a, s), row(c, b, s));
                    let v = cauchy(ra, rb, k);
                    put(c, d, v);
                }
                Op::Sqr { d, a } => {
                    let ra = row(c, a, s);
                    let v = square(ra, k);
                    put(c, d, v);
                }
                Op::Div { d, a, b } => {
                    let (rb, rd) = (row(c, b, s), row(c, d, s));
                    let acc = dot_rev(&rb[1..=k], &rd[..k], true);
                    let v = (at(c, a, k) - acc) * (L::splat(1.0) / rb[0]);
                    put(c, d, v);
                }
                Op::Sqrt { d, a } => {
                    let rd = row(c, d, s);
                    let acc = square_inner(rd, k);
                    let v = (at(c, a, k) - acc) * (L::splat(1.0) / (L::splat(2.0) * rd[0]));
                    put(c, d, v);
                }
                Op::SinCos { .. }
                | Op::SinhCosh { .. }
                | Op::Exp { .. }
                | Op::Log { .. }
                | Op::Tan { .. }
                | Op::Asin { .. }
                | Op::Atan { .. }
                | Op::Erf { .. }
                | Op::Atan2 { .. }
                | Op::Root { .. }
                | Op::PowConst { .. }
                | Op::Power { .. }
                | Op::PowVar { .. } => self.function_order(op, c, s, k),
                Op::Abs { d, a } => {
                    let (a0, ak) = (at(c, a, 0), at(c, a, k));
                    let mut v = ak;
                    for i in 0..L::WIDTH {
                        let (a0, ak) = (a0.lane(i), ak.lane(i));
                        let x = if a0 > 0.0 {
                            ak
                        } else if a0 < 0.0 {
                            -ak
                        } else if ak == 0.0 {
                            0.0
                        } else {
                            return Err(KinkAt);
                        };
                        v.set_lane(i, x);
                    }
                    put(c, d, v);
                }
            }
        }
        Ok(())
    }

    /// Order `k` of a function's recurrence (the operations `run_order` leaves to it), with
    /// `run_order`'s reciprocals and writes.
    #[inline(always)]
    fn function_order<L: Lane>(&self, op: &Op, c: &mut [L], s: usize, k: usize) {
        let at = |c: &[L], r: u32, j: usize| c[r as usize * s + j];
        let rk = L::splat(1.0 / k as f64);
        let put = |c: &mut [L], r: u32, v: L| {
            c[r as usize * s + k] = v;
            if let Some(w) = self.weighted[r as usize] {
                c[w as usize * s + k] = v * L::splat(k as f64);
            }
        };
        match *op {
            Op::SinCos { s: si, c: co, a } | Op::SinhCosh { s: si, c: co, a } => {
                let (wa, rs, rc) = (self.weighted_of(c, s, a), row(c, si, s), row(c, co, s));
                let sv = weighted(wa, rc, k) * rk;
                let cv = weighted(wa, rs, k) * rk;
                let sign = L::splat(if matches!(op, Op::SinCos { .. }) { -1.0 } else { 1.0 });
                put(c, si, sv);
                let v = sign * cv;
                put(c, co, v);
            }
            Op::Exp { d, a } => {
                let (wa, rd) = (self.weighted_of(c, s, a), row(c, d, s));
                let v = weighted(wa, rd, k) * rk;
                put(c, d, v);
            }
            Op::Log { d, a } => {
                // a d' = a': k a₀ d_k = k a_k − Σ_{j=1}^{k−1} j d_j a_{k−j}.
                let (ra, wd) = (row(c, a, s), self.weighted_of(c, s, d));
                let acc = weighted_short(wd, ra, k);
                let v = (ra[k] - acc * rk) * (L::splat(1.0) / ra[0]);
                put(c, d, v);
            }
            Op::Tan { d, a, u, hyp } => {
                let (wa, ru) = (self.weighted_of(c, s, a), row(c, u, s));
                let dv = weighted(wa, ru, k) * rk;
                put(c, d, dv);
                let sq = square(row(c, d, s), k);
                let v = if hyp { -sq } else { sq };
                put(c, u, v);
            }
            Op::Asin { d, a, r, kind } => {
                // r = √(c ∓ a²): r_k = (∓Σ_{j=0}^{k} a_j a_{k−j} − Σ_{j=1}^{k−1} r_j r_{k−j}) / 2r₀.
                let (ra, rr) = (row(c, a, s), row(c, r, s));
                let sq = if kind.plus_square() { square(ra, k) } else { -square(ra, k) };
                let rv = (sq - square_inner(rr, k)) * (L::splat(1.0) / (L::splat(2.0) * rr[0]));
                // r d' = ±a': k r₀ d_k = ±k a_k − Σ_{j=1}^{k−1} j d_j r_{k−j}.
                let wd = self.weighted_of(c, s, d);
                let ak = if kind.neg() { -ra[k] } else { ra[k] };
                let dv = (ak - weighted_short(wd, rr, k) * rk) * (L::splat(1.0) / rr[0]);
                put(c, r, rv);
                put(c, d, dv);
            }
            Op::Atan { d, a, u, hyp } => {
                let (ra, ru) = (row(c, a, s), row(c, u, s));
                let uv = if hyp { -square(ra, k) } else { square(ra, k) };
                let wd = self.weighted_of(c, s, d);
                let dv = (ra[k] - weighted_short(wd, ru, k) * rk) * (L::splat(1.0) / ru[0]);
                put(c, u, uv);
                put(c, d, dv);
            }
            Op::Erf { d, a, e } => {
                // k d_k = (2/√π) Σ_{j=1}^{k} j a_j e_{k−j}.
                let (wa, re) = (self.weighted_of(c, s, a), row(c, e, s));
                let v = weighted(wa, re, k) * rk * L::splat(std::f64::consts::FRAC_2_SQRT_PI);
                put(c, d, v);
            }
            Op::Atan2 { d, a, b, u } => {
                let (ra, rb, ru) = (row(c, a, s), row(c, b, s), row(c, u, s));
                let uv = square(ra, k) + square(rb, k);
                // u d' = b a' − a b'.
                let (wa, wb) = (self.weighted_of(c, s, a), self.weighted_of(c, s, b));
                let num = weighted(wa, rb, k) - weighted(wb, ra, k);
                let wd = self.weighted_of(c, s, d);
                let dv = (num - weighted_short(wd, ru, k)) * (L::splat(1.0) / (L::splat(k as f64) * ru[0]));
                put(c, u, uv);
                put(c, d, dv);
            }
            // `higher_order_ops` turns roots and constant powers into `Power`; these two arms
            // keep `run_order` right for any tape.
            Op::Root { d, a, q } => {
                let v = constant_power(row(c, a, s), row(c, d, s), 1.0 / f64::from(q), k);
                put(c, d, v);
            }
            Op::PowConst { d, a, e } => {
                // A constant row: the same in every lane.
                let e = at(c, e, 0).lane(0);
                let v = constant_power(row(c, a, s), row(c, d, s), e, k);
                put(c, d, v);
            }
            Op::Power { d, a, e } => {
                let v = constant_power(row(c, a, s), row(c, d, s), e, k);
                put(c, d, v);
            }
            Op::PowVar { d, a, b, l, m } => {
                let (ra, wl) = (row(c, a, s), self.weighted_of(c, s, l));
                let lv = (ra[k] - weighted_short(wl, ra, k) * rk) * (L::splat(1.0) / ra[0]);
                put(c, l, lv);
                let (rb, rl) = (row(c, b, s), row(c, l, s));
                let v = cauchy(rb, rl, k);
                put(c, m, v);
                let (wm, rd) = (self.weighted_of(c, s, m), row(c, d, s));
                let v = weighted(wm, rd, k) * rk;
                put(c, d, v);
            }
            Op::Add { .. }
            | Op::Sub { .. }
            | Op::Neg { .. }
            | Op::Scale { .. }
            | Op::Weigh { .. }
            | Op::Mul { .. }
            | Op::Sqr { .. }
            | Op::Div { .. }
            | Op::Sqrt { .. }
            | Op::Abs { .. } => unreachable!("`run_order` runs the arithmetic and `abs` itself"),
        }
    }

    /// Order 0: the interpreter's operations, plus the auxiliary rows.
    #[inline(always)]
    fn run_order0<L: Lane>(&self, c: &mut [L], s: usize) {
        let ix = |r: u32| r as usize * s;
        for op in &self.ops0 {
            match *op {
                Op::Add { d, a, b } => c[ix(d)] = c[ix(a)] + c[ix(b)],
                Op::Sub { d, a, b } => c[ix(d)] = c[ix(a)] - c[ix(b)],
                Op::Mul { d, a, b } => c[ix(d)] = c[ix(a)] * c[ix(b)],
                Op::Div { d, a, b } => c[ix(d)] = c[ix(a)] / c[ix(b)],
                Op::Neg { d, a } => c[ix(d)] = -c[ix(a)],
                Op::Sqrt { d, a } => c[ix(d)] = c[ix(a)].map(f64::sqrt),
                Op::SinCos { s: si, c: co, a } => {
                    let (sv, cv) = c[ix(a)].map2(sin_cos);
                    c[ix(si)] = sv;
                    c[ix(co)] = cv;
                }
                Op::SinhCosh { s: si, c: co, a } => {
                    let x = c[ix(a)];
                    c[ix(si)] = x.map(f64::sinh);
                    c[ix(co)] = x.map(f64::cosh);
                }
                Op::Exp { d, a } => c[ix(d)] = c[ix(a)].map(f64::exp),
                Op::Log { d, a } => c[ix(d)] = c[ix(a)].map(f64::ln),
                Op::Tan { d, a, u, hyp } => {
                    let x = c[ix(a)];
                    let v = x.map(if hyp { f64::tanh } else { f64::tan });
                    c[ix(d)] = v;
                    c[ix(u)] = v.map(|v| if hyp { 1.0 - v * v } else { 1.0 + v * v });
                }
                Op::Asin { d, a, r, kind } => {
                    let x = c[ix(a)];
                    c[ix(d)] = x.map(|x| kind.func().eval(&[x]));
                    c[ix(r)] = x.map(|x| kind.root(x));
                }
                Op::Atan { d, a, u, hyp } => {
                    let x = c[ix(a)];
                    c[ix(d)] = x.map(if hyp { f64::atanh } else { f64::atan });
                    c[ix(u)] = x.map(|x| if hyp { 1.0 - x * x } else { 1.0 + x * x });
                }
                Op::Erf { d, a, .. } => c[ix(d)] = c[ix(a)].map(|x| crate::expr::Func::Erf.eval(&[x])),
                Op::Atan2 { d, a, b, u } => {
                    let (x, y) = (c[ix(a)], c[ix(b)]);
                    c[ix(d)] = x.zip(y, f64::atan2);
                    c[ix(u)] = x * x + y * y;
                }
                Op::Root { d, a, q } => c[ix(d)] = c[ix(a)].map(|x| crate::eval::real_root(x, q)),
                Op::PowConst { d, a, e } => c[ix(d)] = c[ix(a)].zip(c[ix(e)], f64::powf),
                Op::PowVar { d, a, b, l, m } => {
                    let (x, y) = (c[ix(a)], c[ix(b)]);
                    let lv = x.map(f64::ln);
                    c[ix(d)] = x.zip(y, f64::powf);
                    c[ix(l)] = lv;
                    c[ix(m)] = y * lv;
                }
                Op::Abs { d, a } => c[ix(d)] = c[ix(a)].map(f64::abs),
                // Only in the recurrences of orders ≥ 1, which start from these rows' values
                // as the plain operations compute them; given here for completeness.
                Op::Sqr { d, a } => c[ix(d)] = c[ix(a)] * c[ix(a)],
                Op::Scale { d, a, f } => c[ix(d)] = c[ix(a)] * L::splat(f),
                Op::Power { d, a, e } => c[ix(d)] = c[ix(a)].map(|x| x.powf(e)),
                Op::Weigh { d, .. } => c[ix(d)] = L::splat(0.0),
            }
        }
    }

    /// Fills orders `0..=order` of every row, with the inputs' coefficients given by
    /// `inputs(k, c)` (called before order `k` is computed, to write order `k` of the inputs).
    /// For functions of time alone and tests; ODEs use [`TaylorOde`](super::TaylorOde).
    pub fn expand(
        &self,
        c: &mut [f64],
        stride: usize,
        order: usize,
        inputs: impl FnMut(usize, &mut [f64]),
    ) -> Result<(), KinkAt> {
        self.expand_with(None, c, stride, order, inputs)
    }

    /// [`TaylorTape::expand`] with orders `1..` run by `native` where it has them (compiled
    /// by [`TaylorTape::compile_native`] of this tape for this `stride`).
    pub fn expand_with(
        &self,
        native: Option<&TaylorNative>,
        c: &mut [f64],
        stride: usize,
        order: usize,
        mut inputs: impl FnMut(usize, &mut [f64]),
    ) -> Result<(), KinkAt> {
        self.init(c, stride);
        let native = native.filter(|n| n.stride() == stride);
        for k in 0..=order {
            inputs(k, c);
            match native {
                Some(n) if k >= 1 && k <= n.max_order() => n.run_order(c, k)?,
                _ => self.run_order(c, stride, k)?,
            }
        }
        Ok(())
    }
}

/// `x.sin_cos()` out of line, where LLVM makes the pair one `sincos` call, as in the native
/// code's order 0 (`jit::sin_cos`; glibc's `sincos` gives `sin`'s and `cos`'s bits). Inlined
/// into the batch's lane loop they stayed two calls, 12 % of a batch run (`perf`).
#[inline(never)]
fn sin_cos(x: f64) -> (f64, f64) {
    x.sin_cos()
}

#[inline(always)]
fn row<L: Lane>(c: &[L], r: u32, s: usize) -> &[L] {
    &c[r as usize * s..(r as usize + 1) * s]
}

// The sums below are the interpreter's inner loops (O(order²) per instruction and step).
//
// Every sum `Σ_i w_i x_i y_{n−1−i}` is added in one fixed order, which the native code
// (`native.rs`) follows term for term so both give the same bits: the terms that read an
// order-`k` coefficient (the first when `y`'s last element is order `k`, the last when `x`'s
// is) are added last, and the others go round-robin into four partial sums, combined as
// `(s₀ + s₁) + (s₂ + s₃)`. Why: four chains of additions instead of one cut the latency of a
// long sum about fourfold, and leaving the order-`k` terms to the end lets the native code
// compute everything else of an instruction before its operands' order `k` exists, so the
// chain from one instruction to the next at the same order is two additions long instead of
// `k` (the profile in BENCHMARKS.md: the sums are ~90 % of a step).
/// `Σ_i w(i) x_i y_{n−1−i}` over `n = x.len()` terms in the order described above;
/// `late_first` / `late_last` mark the first / last term as reading an order-`k` value. The
/// weight is a closure (each call site its own copy of the loop, measured 5–8 % faster for the
/// interpreter than a `Weight` matched inside it), which calls [`Weight::at`].
#[inline(always)]
fn sum4<L: Lane>(x: &[L], y: &[L], w: impl Fn(usize) -> f64, late_first: bool, late_last: bool) -> L {
    let n = x.len();
    assert!(y.len() >= n);
    let lo = usize::from(late_first && n > 0);
    let hi = if late_last && n > lo { n - 1 } else { n };
    // SAFETY: every index below is `i < n` into `x` and `n − 1 − i` (with `i < n`) into `y`,
    // whose length is at least `n` (asserted).
    let term = |i: usize| unsafe { L::splat(w(i)) * *x.get_unchecked(i) * *y.get_unchecked(n - 1 - i) };
    // The partial sums start from −0.0, the identity of IEEE addition (`−0.0 + t` is `t`
    // for every `t`, where `+0.0 + (−0.0)` is `+0.0`), so the native code can start each
    // from its first term and leave out the partial sums that get none.
    let z = L::splat(-0.0);
    let (mut s0, mut s1, mut s2, mut s3) = (z, z, z, z);
    let mut i = lo;
    while i + 4 <= hi {
        s0 += term(i);
        s1 += term(i + 1);
        s2 += term(i + 2);
        s3 += term(i + 3);
        i += 4;
    }
    if i < hi {
        s0 += term(i);
    }
    if i + 1 < hi {
        s1 += term(i + 1);
    }
    if i + 2 < hi {
        s2 += term(i + 2);
    }
    let mut s = (s0 + s1) + (s2 + s3);
    if lo == 1 {
        s += term(0);
    }
    if hi < n {
        s += term(n - 1);
    }
    s
}
/// Solves `L Lᵀ x = b` in place (`x` holds `b`) with the factor `L` of `linalg::factor` and its
/// diagonal's reciprocals `inv`: `linalg::solve`'s substitutions with multiplications where it
/// divides. Each order of a `W q'' = F` expansion runs one solve on its dependency chain from
/// one order to the next, and the `2n` divisions (13 cycles or more each) were most of that
/// chain's latency. The whole native expansion does the same operations (the same bits).
#[inline(always)]
pub(super) fn cholesky_solve<L: Lane>(l: &[L], inv: &[L], n: usize, x: &mut [L]) {
    for i in 0..n {
        let mut v = x[i];
        for k in 0..i {
            v -= l[i * n + k] * x[k];
        }
        x[i] = v * inv[i];
    }
    for i in (0..n).rev() {
        let mut v = x[i];
        for k in i + 1..n {
            v -= l[k * n + i] * x[k];
        }
        x[i] = v * inv[i];
    }
}
/// `Σ_{j=0}^{k} a_j b_{k−j}` (both end terms read order `k`).
#[inline(always)]
fn cauchy<L: Lane>(a: &[L], b: &[L], k: usize) -> L {
    sum4(&a[..=k], &b[..=k], |_| 1.0, true, true)
}
/// `Σ_{j=0}^{k} a_j a_{k−j}` over half its terms: `2 Σ_{1≤j<k−j} a_j a_{k−j} + a_{k/2}²`
/// (even `k`) plus `2a₀ · a_k`, the one term that reads order `k`, last.
#[inline(always)]
fn square<L: Lane>(a: &[L], k: usize) -> L {
    square_inner(a, k) + (L::splat(2.0) * a[0]) * a[k]
}
/// `Σ_{j=1}^{k−1} a_j a_{k−j}` over half its terms: `2 Σ_{1≤j<k−j} a_j a_{k−j} + a_{k/2}²`.
#[inline(always)]
fn square_inner<L: Lane>(a: &[L], k: usize) -> L {
    let n = k.div_ceil(2) - 1;
    let half = sum4(&a[1..1 + n], &a[k - n..k], |_| 1.0, false, false);
    let mid = if k % 2 == 0 { a[k / 2] * a[k / 2] } else { L::splat(0.0) };
    L::splat(2.0) * half + mid
}
/// `Σ_{j} x_j y_{n−1−j}` for two slices of length `n` (the second read backwards); `late`:
/// the last `x` is an order-`k` value.
#[inline(always)]
pub(super) fn dot_rev<L: Lane>(x: &[L], y: &[L], late: bool) -> L {
    sum4(x, y, |_| 1.0, false, late)
}
/// `Σ_{j=1}^{k} j a_j b_{k−j}` (the coefficient of `t^{k−1}` in `a' b`), given `a`'s weighted
/// row `wa` (`wa_j = j · a_j`, see `weigh_rows`): the terms `(j · a_j) · b_{k−j}`.
#[inline(always)]
fn weighted<L: Lane>(wa: &[L], b: &[L], k: usize) -> L {
    sum4(&wa[1..=k], &b[..k], |_| 1.0, false, true)
}
/// `Σ_{j=1}^{k−1} j a_j b_{k−j}`, given `a`'s weighted row.
#[inline(always)]
fn weighted_short<L: Lane>(wa: &[L], b: &[L], k: usize) -> L {
    if k < 2 {
        return L::splat(-0.0);
    }
    sum4(&wa[1..k], &b[1..k], |_| 1.0, false, false)
}
/// Coefficient `k` of `d = a^e` for a constant `e` (also the real root, `e = 1/q`), from
/// `a d' = e d a'`: `d_k = Σ_{j=1}^{k} (e j − (k − j)) a_j d_{k−j} / (k a₀)`.
#[inline(always)]
fn constant_power<L: Lane>(ra: &[L], rd: &[L], e: f64, k: usize) -> L {
    let acc = sum4(&ra[1..=k], &rd[..k], |i| Weight::Power(e).at(i, k), false, true);
    acc * (L::splat(1.0) / (L::splat(k as f64) * ra[0]))
}
