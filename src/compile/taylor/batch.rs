//! Batch expansions: `B` initial conditions of one [`TaylorOde`] expanded together, one per
//! lane of [`Lanes<B>`], by the same interpreter as a single expansion (see `lanes.rs` for
//! why the lanes get the scalar method's bits); and, once native code pays (the tiers of the
//! single run's code), by native code:
//!
//! - *wide code* where the host's vector registers hold the lanes (8 per AVX-512 register, 4
//!   per AVX2 one; `wide.rs`): the tape's recurrences of each order ≥ 1 for all lanes at once,
//!   and between the orders the mass matrix's solve and the state's next coefficients when
//!   every lane's `W₀` is Cholesky's; order 0 (libm), `W₀`'s factor and an LU lane's solve are
//!   here, in Rust;
//! - else *lane-pair code*: the whole expansion compiled with every value an `F64X2` of two
//!   lanes (`NativeTaylor::compile_lanes`), run once per pair of lanes. A pair whose `W₀` needs
//!   the interpreter (not finite, or not positive definite: LU) sends the whole batch
//!   expansion back to the interpreter, which handles it lane by lane as before.
//!
//! Either way each lane has the scalar native code's bits (which are the interpreter's).
//!
//! The per-order mass-matrix solve of a `W q'' = F` system factors `W₀` on whole lanes when
//! every lane's is positive definite (Cholesky), else lane by lane (each lane's pivots are its
//! own); when every lane's factor is Cholesky's it runs the substitutions on whole lanes, and a
//! lane whose `W₀` is not positive definite is solved alone, by LU, as the scalar method does.

// Lanes, rows and factor entries are addressed by index, as the layout is written.
#![allow(clippy::needless_range_loop)]

use super::interp::{cholesky_solve, dot_rev};
use super::layout::BatchLayout;
use super::native::{LanePair, NativeTaylor, Ran};
use super::ode::Derivative;
use super::tiers::BatchCode;
use super::wide::{Glue, GlueSolve, WideTaylor};
use super::TaylorOde;
use crate::integrate::TaylorBatchSystem;
use crate::lanes::{Lane, Lanes};
use crate::linalg::{factor, solve, Factor};

/// The scratch of `B`-lane expansions of one order.
#[derive(Clone, Debug)]
pub struct LaneWork<const B: usize> {
    order: usize,
    /// The tape's rows (`row · (order + 1) + k`), the accelerations' rows of a `W q'' = F`
    /// system, `W₀`'s factor per lane and for a Cholesky factor its diagonal's reciprocals, and
    /// the solve's right-hand side, where `layout` puts them.
    c: Vec<Lanes<B>>,
    layout: BatchLayout,
    /// Each lane's factorisation of `W₀`, with its own LU permutation.
    kinds: [Factor; B],
    perms: Vec<f64>,
    /// One lane's `W₀` and its factor, for `linalg::factor`.
    w0: Vec<f64>,
    fm: Vec<f64>,
    /// Lane-pair code's buffers, one per pair of lanes (`expand`'s layout, two lanes per
    /// slot), made when the code first runs; the constants' rows are written once.
    pairs: Vec<Vec<LanePair>>,
}

/// The scratch of a batch expansion, at the width the host's vector registers suggest.
#[derive(Clone, Debug)]
pub enum TaylorBatch {
    /// Two lanes (SSE2, NEON).
    Two(Box<LaneWork<2>>),
    /// Four lanes (AVX2).
    Four(Box<LaneWork<4>>),
    /// Eight lanes (AVX-512).
    Eight(Box<LaneWork<8>>),
}

impl<const B: usize> LaneWork<B> {
    fn new(ode: &TaylorOde, order: usize) -> Self {
        let layout = ode.batch_layout(order);
        let n = layout.n;
        let z = Lanes::splat(0.0);
        LaneWork {
            order,
            c: vec![z; layout.len()],
            layout,
            kinds: [Factor::Cholesky; B],
            perms: vec![0.0; n * B],
            w0: vec![0.0; n * n],
            fm: vec![0.0; n * n],
            pairs: Vec::new(),
        }
    }
}

/// The points of a batch expansion and where its results go (see [`TaylorOde::expand_lanes`]):
/// lane `l`'s time `t[l]` and state `y[l · dim ..]`, its coefficients in lane `l` of `out`,
/// its failure in `failed[l]`. `O` is the caller's width, which the batch's equals.
struct Points<'a, const O: usize> {
    t: &'a [f64],
    y: &'a [f64],
    out: &'a mut [Lanes<O>],
    failed: &'a mut [bool],
}

/// Copies a batch's state rows into the caller's lanes (of the same width).
#[inline(always)]
fn copy_lanes<const B: usize, const O: usize>(out: &mut [Lanes<O>], c: &[Lanes<B>]) {
    let n = B.min(O);
    for (o, v) in out.iter_mut().zip(c) {
        o.0[..n].copy_from_slice(&v.0[..n]);
    }
}

impl TaylorOde {
    /// Whether a batch expansion has run on native code (wide code or lane-pair code, see the
    /// module's documentation; it is compiled in the single run's tiers, and never when native
    /// code is off), rather than on the interpreter's lanes.
    pub fn native_lanes_ran(&self) -> bool {
        self.native.lanes_ran()
    }

    /// Whether a batch expansion has run on wide code (`wide.rs`: 4 or 8 lanes per vector
    /// register, on hosts with AVX2 or AVX-512), rather than on lane pairs or the interpreter.
    pub fn wide_lanes_ran(&self) -> bool {
        self.native.wide_ran()
    }

    /// The code for batch expansions of `order` over `lanes` lanes: wide code where the host
    /// has the vector registers, else lane-pair code, which a non-symmetric `W` does not get
    /// (its LU solve is not in the whole expansion, as for the single run).
    fn compile_batch(&self, order: usize, lanes: usize) -> Option<BatchCode> {
        if crate::compile::jit::jit_disabled_by_env() {
            return None;
        }
        if let Some(code) = WideTaylor::compile(&self.tape, &self.glue(order), order - 1, lanes) {
            return Some(BatchCode::Wide(code));
        }
        if self.solve.as_ref().is_some_and(|m| !m.symmetric) {
            return None;
        }
        NativeTaylor::compile_lanes(&self.tape, order + 1, order - 1, &self.expansion(order))
            .map(|code| BatchCode::Pairs(Box::new(code)))
    }

    /// What the wide code does between the tape's orders (`wide::Glue`), in the layout of a
    /// batch expansion of `order`.
    fn glue(&self, order: usize) -> Glue {
        let layout = self.batch_layout(order);
        let derivs = self.derivs.iter().map(|d| match *d {
            Derivative::Output(j) => self.tape.output_row(j),
            Derivative::State(j) => j,
            Derivative::Solve(j) => layout.acc_row(j),
        });
        let solve = self.solve.as_ref().map(|m| {
            let f = m.f.iter().map(|&o| self.tape.output_row(o) as u32).collect();
            let varying = m.varying.iter().map(|v| v.iter().map(|&(l, r)| (l, r as u32)).collect()).collect();
            GlueSolve { f, varying }
        });
        Glue { derivs: derivs.map(|r| r as u32).collect(), solve, layout }
    }

    /// Where a batch expansion of `order` keeps its values.
    fn batch_layout(&self, order: usize) -> BatchLayout {
        BatchLayout { rows: self.tape.n_rows(), n: self.solve.as_ref().map_or(0, |m| m.n), stride: order + 1 }
    }

    /// [`TaylorOde::expand_lanes`] by the native lane-pair code `code`, one call per pair of
    /// lanes; `false` (with `out` partly written) when a pair's `W₀` needs the interpreter,
    /// which then redoes the whole batch.
    fn expand_native_lanes<const B: usize, const O: usize>(
        &self,
        code: &NativeTaylor,
        w: &mut LaneWork<B>,
        t: &[f64],
        y: &[f64],
        out: &mut [Lanes<O>],
    ) -> bool {
        let order = w.order;
        let (s, dim) = (order + 1, self.dim);
        if w.pairs.is_empty() {
            let mut consts = vec![0.0; self.tape.n_rows() * s];
            self.tape.init(&mut consts, s);
            let len = self.scratch_len(order);
            let buffer = |_| {
                let mut b = vec![LanePair::default(); len];
                b.iter_mut().zip(&consts).for_each(|(p, &x)| *p = LanePair([x, x]));
                b
            };
            // `B` is even (2, 4 or 8).
            w.pairs = (0..B / 2).map(buffer).collect();
        }
        for (p, c) in w.pairs.iter_mut().enumerate() {
            let (l0, l1) = (2 * p, 2 * p + 1);
            for i in 0..dim {
                c[i * s] = LanePair([y[l0 * dim + i], y[l1 * dim + i]]);
            }
            if let Some(ti) = self.time {
                // Orders ≥ 2 of the time stay the zeros the buffer was made with.
                c[ti * s] = LanePair([t[l0], t[l1]]);
                c[ti * s + 1] = LanePair([1.0; 2]);
            }
            if code.run_lanes(c) != Ran::Done {
                return false;
            }
            for (o, v) in out.iter_mut().zip(&c[..dim * s]) {
                if l1 < O {
                    o.0[l0] = v.0[0];
                    o.0[l1] = v.0[1];
                }
            }
        }
        self.native.note_lanes_ran();
        true
    }

    /// Whether a batch expansion (`expand_lanes`) can run this system: every operation but `abs`,
    /// whose kink is a per-lane failure the batch does not split (such systems run one
    /// trajectory at a time).
    pub fn batchable(&self) -> bool {
        self.tape.abs_args.is_empty()
    }

    /// Expands `B` states at once, each lane exactly as [`TaylorOde::expand_in_place`] would
    /// (the same bits). `t[l]`, `y[l · dim ..]` is lane `l`'s point; its coefficients go to
    /// lane `l` of `out[i · (order + 1) + k]`. A lane whose mass matrix is not
    /// finite or is singular is marked in `failed`; the others are unaffected. Orders ≥ 1 of
    /// the tape run on `wide` code when given, else in the interpreter.
    #[inline(always)]
    fn expand_lanes<const B: usize, const O: usize>(
        &self,
        wide: Option<&WideTaylor>,
        w: &mut LaneWork<B>,
        x: Points<'_, O>,
    ) {
        let Points { t, y, out, failed } = x;
        let order = w.order;
        let s = order + 1;
        let dim = self.dim;
        let c = &mut w.c[..];
        self.tape.init(c, s);
        for i in 0..dim {
            c[i * s] = Lanes(std::array::from_fn(|l| y[l * dim + i]));
        }
        if let Some(ti) = self.time {
            let r = &mut c[ti * s..(ti + 1) * s];
            r.fill(Lanes::splat(0.0));
            r[0] = Lanes(std::array::from_fn(|l| t[l]));
            if s > 1 {
                r[1] = Lanes::splat(1.0);
            }
        }
        for k in 0..order {
            match wide {
                Some(code) if k > 0 => {
                    code.run_order(c, k);
                    if w.kinds.iter().all(|k| matches!(k, Factor::Cholesky)) {
                        code.run_glue(c, k);
                        continue;
                    }
                }
                _ => {
                    if self.tape.run_order_inline(c, s, k).is_err() {
                        // Only `abs` fails, and `batchable` keeps it out.
                        failed.fill(true);
                        return;
                    }
                }
            }
            if let Some(m) = &self.solve {
                let n = m.n;
                let out_row = |j: usize| self.tape.output_row(j);
                let ly = w.layout;
                if k == 0 && !(m.symmetric && self.cholesky_lanes(c, ly, &mut w.kinds)) {
                    let (w0, fm) = (&mut w.w0, &mut w.fm);
                    for l in 0..B {
                        for (e, &o) in w0.iter_mut().zip(&m.w) {
                            *e = c[out_row(o) * s].lane(l);
                        }
                        let perm = &mut w.perms[l * n..(l + 1) * n];
                        let kind = if w0.iter().all(|x| x.is_finite()) {
                            factor(w0, fm, perm, n, m.symmetric).ok()
                        } else {
                            None
                        };
                        let Some(kind) = kind else {
                            failed[l] = true;
                            // An identity factor keeps this lane's arithmetic finite; its
                            // coefficients are not used.
                            fm.fill(0.0);
                            (0..n).for_each(|i| fm[i * n + i] = 1.0);
                            w.kinds[l] = Factor::Cholesky;
                            for i in 0..n * n {
                                c[ly.factor(i)].set_lane(l, fm[i]);
                            }
                            for i in 0..n {
                                c[ly.inv(i)].set_lane(l, 1.0);
                            }
                            continue;
                        };
                        w.kinds[l] = kind;
                        for i in 0..n * n {
                            c[ly.factor(i)].set_lane(l, fm[i]);
                        }
                        if matches!(kind, Factor::Cholesky) {
                            for i in 0..n {
                                c[ly.inv(i)].set_lane(l, 1.0 / fm[i * n + i]);
                            }
                        }
                    }
                }
                for i in 0..n {
                    let mut v = c[out_row(m.f[i]) * s + k];
                    for &(l, r) in &m.varying[i] {
                        v -= dot_rev(&c[r * s + 1..=r * s + k], &c[ly.acc(l, 0)..ly.acc(l, k)], true);
                    }
                    c[ly.rhs(i)] = v;
                }
                if w.kinds.iter().all(|k| matches!(k, Factor::Cholesky)) {
                    let (head, rhs) = c.split_at_mut(ly.rhs(0));
                    cholesky_solve(&head[ly.factor(0)..ly.inv(0)], &head[ly.inv(0)..ly.inv(n)], n, &mut rhs[..n]);
                } else {
                    let (mut fm, mut x, mut tmp) = (vec![0.0; n * n], vec![0.0; n], vec![0.0; n]);
                    for l in 0..B {
                        for i in 0..n * n {
                            fm[i] = c[ly.factor(i)].lane(l);
                        }
                        for i in 0..n {
                            x[i] = c[ly.rhs(i)].lane(l);
                        }
                        match w.kinds[l] {
                            Factor::Cholesky => {
                                let inv: Vec<f64> = (0..n).map(|i| c[ly.inv(i)].lane(l)).collect();
                                cholesky_solve(&fm, &inv, n, &mut x);
                            }
                            Factor::Lu => solve(Factor::Lu, &fm, &w.perms[l * n..(l + 1) * n], n, &mut x, &mut tmp),
                        }
                        for i in 0..n {
                            c[ly.rhs(i)].set_lane(l, x[i]);
                        }
                    }
                }
                for i in 0..n {
                    c[ly.acc(i, k)] = c[ly.rhs(i)];
                }
            }
            let inv = Lanes::splat(1.0 / (k + 1) as f64);
            for i in 0..dim {
                let v = match self.derivs[i] {
                    Derivative::Output(j) => c[self.tape.output_row(j) * s + k],
                    Derivative::State(j) => c[j * s + k],
                    Derivative::Solve(j) => c[w.layout.acc(j, k)],
                };
                c[i * s + k + 1] = v * inv;
            }
        }
        copy_lanes(out, &c[..dim * s]);
    }
}

impl TaylorOde {
    /// `W₀`'s Cholesky factor in every lane at once, by `linalg::factor`'s operations in its
    /// order (so each lane has the bits of factoring its own `W₀`), when every lane's `W₀` is
    /// finite and positive definite past `linalg::singular_below`; else `false`, and the caller
    /// factors the lanes one by one. Factoring lane by lane was a fifth of a batch expansion of
    /// the double pendulum on wide code (BENCHMARKS.md).
    #[inline(always)]
    fn cholesky_lanes<const B: usize>(&self, c: &mut [Lanes<B>], ly: BatchLayout, kinds: &mut [Factor; B]) -> bool {
        let Some(m) = &self.solve else { return false };
        let (n, s) = (m.n, ly.stride);
        let (c, tail) = c.split_at_mut(ly.factor(0));
        let (f, inv) = tail.split_at_mut(n * n);
        for (e, &o) in f.iter_mut().zip(&m.w) {
            *e = c[self.tape.output_row(o) * s];
        }
        if f.iter().any(|x| x.0.iter().any(|v| !v.is_finite())) {
            return false;
        }
        let scale = f.iter().fold(Lanes::splat(0.0), |acc, x| acc.zip(*x, |a, x| a.max(x.abs())));
        let tol = Lanes::splat(n as f64 * f64::EPSILON) * scale;
        for j in 0..n {
            let mut d = f[j * n + j];
            for k in 0..j {
                d -= f[j * n + k] * f[j * n + k];
            }
            if (0..B).any(|l| d.lane(l) <= tol.lane(l)) {
                return false;
            }
            let l = d.map(f64::sqrt);
            f[j * n + j] = l;
            for i in j + 1..n {
                let mut x = f[i * n + j];
                for k in 0..j {
                    x -= f[i * n + k] * f[j * n + k];
                }
                f[i * n + j] = x / l;
            }
        }
        for i in 0..n {
            inv[i] = Lanes::splat(1.0) / f[i * n + i];
        }
        *kinds = [Factor::Cholesky; B];
        true
    }
}

impl TaylorBatchSystem for TaylorOde {
    type Batch = TaylorBatch;

    fn batch(&self, order: usize, lanes: usize) -> Option<TaylorBatch> {
        if !self.batchable() {
            return None;
        }
        Some(match lanes {
            0..=2 => TaylorBatch::Two(Box::new(LaneWork::new(self, order))),
            3..=4 => TaylorBatch::Four(Box::new(LaneWork::new(self, order))),
            _ => TaylorBatch::Eight(Box::new(LaneWork::new(self, order))),
        })
    }

    fn lanes(batch: &TaylorBatch) -> usize {
        match batch {
            TaylorBatch::Two(_) => 2,
            TaylorBatch::Four(_) => 4,
            TaylorBatch::Eight(_) => 8,
        }
    }

    fn expand_batch<const B: usize>(
        &self,
        batch: &mut TaylorBatch,
        t: &[f64],
        y: &[f64],
        out: &mut [Lanes<B>],
        failed: &mut [bool],
    ) {
        // The caller's width is the batch's (`lanes`); any other is refused.
        let x = Points { t, y, out, failed };
        match (batch, B) {
            (TaylorBatch::Two(w), 2) => self.expand_batch_of(w, x),
            (TaylorBatch::Four(w), 4) => self.expand_batch_of(w, x),
            (TaylorBatch::Eight(w), 8) => self.expand_batch_of(w, x),
            _ => x.failed.fill(true),
        }
    }
}

impl TaylorOde {
    /// A batch expansion over `B` lanes on the code the tiers have for it: wide code, else
    /// lane pairs, else (or when a pair needs LU) the interpreter.
    fn expand_batch_of<const B: usize, const O: usize>(&self, w: &mut LaneWork<B>, x: Points<'_, O>) {
        let Points { t, y, out, failed } = x;
        let order = w.order;
        let wide = match self.native.lanes_tiered(&self.tape, order, B, || self.compile_batch(order, B)) {
            Some(BatchCode::Wide(code)) if code.lanes() == B => Some(code),
            Some(BatchCode::Pairs(code)) => {
                if self.expand_native_lanes(code, w, t, y, out) {
                    return;
                }
                None
            }
            _ => None,
        };
        self.expand_lanes_at_width(wide, w, Points { t, y, out, failed });
        if wide.is_some() {
            self.native.note_lanes_ran();
            self.native.note_wide_ran();
        }
    }

    /// [`TaylorOde::expand_lanes`] compiled for the vector registers `B` lanes fill.
    fn expand_lanes_at_width<const B: usize, const O: usize>(
        &self,
        wide: Option<&WideTaylor>,
        w: &mut LaneWork<B>,
        x: Points<'_, O>,
    ) {
        #[cfg(target_arch = "x86_64")]
        {
            if B == 8 && std::arch::is_x86_feature_detected!("avx512f") {
                // SAFETY: the CPU has AVX-512F (checked just above).
                return unsafe { self.expand_lanes_avx512(wide, w, x) };
            }
            if B >= 4 && std::arch::is_x86_feature_detected!("avx2") {
                // SAFETY: the CPU has AVX2 (checked just above).
                return unsafe { self.expand_lanes_avx2(wide, w, x) };
            }
        }
        self.expand_lanes(wide, w, x)
    }
}

/// The batch expansion compiled for the vector registers its width fills: the whole
/// interpreter is inlined into these, so its lane loops become single AVX2 / AVX-512
/// instructions (and its four partial sums of eight lanes fit in registers, where with the
/// baseline's sixteen 2-lane registers they spilled to the stack). The same IEEE operations
/// in the same order: no fused multiply-add is enabled, so the bits do not change.
#[cfg(target_arch = "x86_64")]
impl TaylorOde {
    #[target_feature(enable = "avx2")]
    unsafe fn expand_lanes_avx2<const B: usize, const O: usize>(
        &self,
        wide: Option<&WideTaylor>,
        w: &mut LaneWork<B>,
        x: Points<'_, O>,
    ) {
        self.expand_lanes(wide, w, x)
    }

    #[target_feature(enable = "avx512f")]
    unsafe fn expand_lanes_avx512<const B: usize, const O: usize>(
        &self,
        wide: Option<&WideTaylor>,
        w: &mut LaneWork<B>,
        x: Points<'_, O>,
    ) {
        self.expand_lanes(wide, w, x)
    }
}
