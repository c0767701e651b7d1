//! Taylor-mode automatic differentiation of a [`Tape`]: the normalised Taylor coefficients
//! `x_[k] = x⁽ᵏ⁾(t₀)/k!` of every value of the tape, order by order, and from them the Taylor
//! expansion of the solution of an ODE whose right-hand side the tape computes.
//!
//! Why a second form of the tape: the register tape reuses a slot as soon as its last reader
//! has run, which is right for one evaluation but wrong here, because order `k` of an
//! instruction reads orders `0..=k` of its operands, computed in earlier passes over the tape.
//! [`TaylorTape`] renames the tape into single assignment (one row of coefficients per value)
//! and adds, for the functions whose derivative is not a tape value already, one or two
//! auxiliary rows (the cosine of a lone sine, `1 + tan²`, `√(1 − a²)` of an arcsine, …), so
//! that every instruction has a recurrence of cost `O(k)` at order `k` (Griewank & Walther,
//! *Evaluating Derivatives*, 2nd ed. 2008, §13.2, Table 13.2; the same recurrences as
//! Jorba & Zou 2005, §2.1). Parameters and constants have order 0 only; the time input has
//! `t₀, 1, 0, …`.
//!
//! Order 0 is computed with exactly the floating-point operations of the interpreter, so the
//! zeroth coefficients equal a plain evaluation bit for bit. Orders ≥ 1 run recurrences
//! rewritten from those operations where a cheaper one gives the same series (scalings,
//! squares, fused powers: `higher_order_ops`).
//!
//! [`TaylorOde`] turns a tape into the right-hand side of an ODE in the integrators' layout:
//! for each state component the tape output (or the other state component, for `q' = v`) that
//! is its derivative, and optionally a linear solve `W a = F` per order for `W q'' = F`
//! systems (`W₀ a_k = F_k − Σ_{j≥1} W_j a_{k−j}`, one factorisation of `W₀` per expansion).

use std::fmt;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

use crate::expr::{Expr, Func};
use crate::integrate::{RhsError as StepError, StepFailure, TaylorSystem};
use crate::mechanics::{Kind, System};

use super::native::{
    compact_pays, unrolled_terms, CholeskySolve, Expansion, NativeTaylor, Ran, MAX_NATIVE_TAYLOR_TERMS,
};
use super::rhs::{factor, solve, Factor};
use super::tape::{Instr, Tape};
use super::{CompileError, HamiltonianRhs, LagrangianRhs};

/// One instruction of a [`TaylorTape`]. Operands and destinations are rows.
#[derive(Clone, Copy, Debug, PartialEq)]
pub(super) enum Op {
    Add {
        d: u32,
        a: u32,
        b: u32,
    },
    Sub {
        d: u32,
        a: u32,
        b: u32,
    },
    Mul {
        d: u32,
        a: u32,
        b: u32,
    },
    Div {
        d: u32,
        a: u32,
        b: u32,
    },
    Neg {
        d: u32,
        a: u32,
    },
    Sqrt {
        d: u32,
        a: u32,
    },
    /// `s = sin a`, `c = cos a` (one of them may be an auxiliary row).
    SinCos {
        s: u32,
        c: u32,
        a: u32,
    },
    /// `s = sinh a`, `c = cosh a`.
    SinhCosh {
        s: u32,
        c: u32,
        a: u32,
    },
    Exp {
        d: u32,
        a: u32,
    },
    Log {
        d: u32,
        a: u32,
    },
    /// `d = tan a` (`hyp`: `tanh a`) with `u = 1 ± d²`, so `d' = u a'`.
    Tan {
        d: u32,
        a: u32,
        u: u32,
        hyp: bool,
    },
    /// `d = asin a` (`acos` when `neg`) with `r = √(1 − a²)`, so `r d' = ±a'`.
    Asin {
        d: u32,
        a: u32,
        r: u32,
        neg: bool,
    },
    /// `d = atan a` with `u = 1 + a²`, so `u d' = a'`.
    Atan {
        d: u32,
        a: u32,
        u: u32,
    },
    /// `d = atan2(a, b)` with `u = a² + b²`, so `u d' = b a' − a b'`.
    Atan2 {
        d: u32,
        a: u32,
        b: u32,
        u: u32,
    },
    /// `d` = the real `q`-th root of `a` (odd `q`, negative `a` allowed): like `PowConst` with
    /// `e = 1/q`, since `a d' = d a'/q` holds on both sides of zero.
    Root {
        d: u32,
        a: u32,
        q: u32,
    },
    /// `d = a^e` for a constant exponent: `a d' = e d a'`.
    PowConst {
        d: u32,
        a: u32,
        e: u32,
    },
    /// `d = a^b` for a varying exponent, as `exp(b log a)`: `l = log a`, `m = b l`.
    PowVar {
        d: u32,
        a: u32,
        b: u32,
        l: u32,
        m: u32,
    },
    /// `d = |a|`: `± a` away from the kink.
    Abs {
        d: u32,
        a: u32,
    },
    /// `d = a · a`, the Cauchy product of a row with itself summed over half its terms.
    Sqr {
        d: u32,
        a: u32,
    },
    /// `d = f · a` for a constant `f` (a product with, or quotient by, a constant row): one
    /// multiplication per order instead of a Cauchy product.
    Scale {
        d: u32,
        a: u32,
        f: f64,
    },
    /// `d_j = j · a_j` (orders ≥ 1 only): the weighted row of an input or constant row that
    /// some recurrence's sum `Σ j a_j b_{k−j}` reads (see `weigh_rows`).
    Weigh {
        d: u32,
        a: u32,
    },
    /// `d = C · a^e` for constants `C` and `e`, a power of `a` built from roots, powers,
    /// products and quotients of it (`u √u`, `1/(u √u)`): `a d' = e d a'` whatever `C` is,
    /// with `d₀` from order 0.
    Power {
        d: u32,
        a: u32,
        e: f64,
    },
}

impl Op {
    /// The rows an operation writes.
    fn dests(&self) -> impl Iterator<Item = u32> {
        let (x, y) = match *self {
            Op::SinCos { s, c, .. } | Op::SinhCosh { s, c, .. } => (s, Some(c)),
            Op::Tan { d, u, .. } | Op::Atan { d, u, .. } | Op::Atan2 { d, u, .. } => (d, Some(u)),
            Op::Asin { d, r, .. } => (d, Some(r)),
            Op::PowVar { d, l, m, .. } => return [d, l, m].into_iter().take(3),
            Op::Add { d, .. }
            | Op::Sub { d, .. }
            | Op::Mul { d, .. }
            | Op::Div { d, .. }
            | Op::Neg { d, .. }
            | Op::Sqrt { d, .. }
            | Op::Exp { d, .. }
            | Op::Log { d, .. }
            | Op::Root { d, .. }
            | Op::PowConst { d, .. }
            | Op::Abs { d, .. }
            | Op::Sqr { d, .. }
            | Op::Scale { d, .. }
            | Op::Weigh { d, .. }
            | Op::Power { d, .. } => (d, None),
        };
        match y {
            Some(y) => [x, y, 0].into_iter().take(2),
            None => [x, 0, 0].into_iter().take(1),
        }
    }

    /// The rows whose weighted rows (`j · x_j`, see `weigh_rows`) this operation's sums read
    /// at orders ≥ 1: the argument of sin, cos, sinh, cosh, exp and tan, both of `atan2`, and
    /// the results of the recurrences that are solved for their own order `k`.
    fn weighted_operands(&self) -> impl Iterator<Item = u32> {
        let (x, y, z) = match *self {
            Op::SinCos { a, .. } | Op::SinhCosh { a, .. } | Op::Exp { a, .. } | Op::Tan { a, .. } => {
                (Some(a), None, None)
            }
            Op::Log { d, .. } | Op::Asin { d, .. } | Op::Atan { d, .. } => (Some(d), None, None),
            Op::Atan2 { d, a, b, .. } => (Some(a), Some(b), Some(d)),
            Op::PowVar { l, m, .. } => (Some(l), Some(m), None),
            _ => (None, None, None),
        };
        [x, y, z].into_iter().flatten()
    }

    /// The rows an operation reads besides its own destinations.
    fn sources(&self) -> impl Iterator<Item = u32> {
        let (a, b) = match *self {
            Op::Add { a, b, .. }
            | Op::Sub { a, b, .. }
            | Op::Mul { a, b, .. }
            | Op::Div { a, b, .. }
            | Op::Atan2 { a, b, .. }
            | Op::PowVar { a, b, .. } => (a, Some(b)),
            Op::PowConst { a, e, .. } => (a, Some(e)),
            Op::Neg { a, .. }
            | Op::Sqrt { a, .. }
            | Op::SinCos { a, .. }
            | Op::SinhCosh { a, .. }
            | Op::Exp { a, .. }
            | Op::Log { a, .. }
            | Op::Tan { a, .. }
            | Op::Asin { a, .. }
            | Op::Atan { a, .. }
            | Op::Root { a, .. }
            | Op::Abs { a, .. }
            | Op::Sqr { a, .. }
            | Op::Scale { a, .. }
            | Op::Weigh { a, .. }
            | Op::Power { a, .. } => (a, None),
        };
        match b {
            Some(b) => [a, b].into_iter().take(2),
            None => [a, 0].into_iter().take(1),
        }
    }
}

/// Why a Taylor expansion has no value.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TaylorError {
    /// `|x|` evaluated where `x = 0` but `x` is not identically zero: not differentiable.
    #[error(
        "abs(…) is not differentiable at its kink: its argument is 0 at t = {t} and changes there; state {state:?}"
    )]
    AbsKink { t: f64, state: Vec<f64> },
    /// A coefficient is infinite or NaN (a singularity within reach, a domain error).
    #[error("non-finite Taylor coefficient of order {order} at t = {t}; state {state:?}")]
    NonFinite { t: f64, order: usize, state: Vec<f64> },
    /// `W q'' = F` with a singular `W` at the expansion point.
    #[error(
        "the mass matrix is singular at t = {t} (no pivot for the velocity of coordinate {index}); state {state:?}"
    )]
    SingularMassMatrix { t: f64, index: usize, state: Vec<f64> },
}

/// A [`Tape`] in single-assignment form with the Taylor recurrence of each instruction.
///
/// Rows are laid out `inputs | constants | values`. A coefficient buffer holds `stride`
/// coefficients per row (`row · stride + k`), `stride > ` the highest order asked for.
#[derive(Clone, Debug)]
pub struct TaylorTape {
    n_inputs: usize,
    consts: Vec<f64>,
    /// Order 0: the tape's own operations, renamed, plus the auxiliary rows.
    ops0: Vec<Op>,
    /// Orders ≥ 1: the recurrences, rewritten by `higher_order_ops`.
    ops: Vec<Op>,
    outputs: Vec<u32>,
    n_rows: usize,
    /// The rows of the arguments of `abs` (whose sign must not change within a step).
    abs_args: Vec<u32>,
    /// For each row, its weighted row (`j · x_j` at orders ≥ 1; order 0 is never read), if a
    /// recurrence weights it (`weigh_rows`).
    weighted: Vec<Option<u32>>,
}

impl TaylorTape {
    /// The Taylor form of `tape`.
    pub fn new(tape: &Tape) -> TaylorTape {
        let n_inputs = tape.n_inputs();
        let consts = tape.consts().to_vec();
        let fixed = (n_inputs + consts.len()) as u32;
        let mut map: Vec<u32> = (0..tape.scratch_len() as u32).collect();
        let mut next = fixed;
        let mut fresh = || {
            next += 1;
            next - 1
        };
        let mut ops = Vec::with_capacity(tape.instrs().len());
        for ins in tape.instrs() {
            // Sources are read through the current renaming before destinations get new rows.
            let op = match *ins {
                Instr::Add { d, a, b } => {
                    let (a, b) = (map[a as usize], map[b as usize]);
                    map[d as usize] = fresh();
                    Op::Add { d: map[d as usize], a, b }
                }
                Instr::Sub { d, a, b } => {
                    let (a, b) = (map[a as usize], map[b as usize]);
                    map[d as usize] = fresh();
                    Op::Sub { d: map[d as usize], a, b }
                }
                Instr::Mul { d, a, b } => {
                    let (a, b) = (map[a as usize], map[b as usize]);
                    map[d as usize] = fresh();
                    Op::Mul { d: map[d as usize], a, b }
                }
                Instr::Div { d, a, b } => {
                    let (a, b) = (map[a as usize], map[b as usize]);
                    map[d as usize] = fresh();
                    Op::Div { d: map[d as usize], a, b }
                }
                Instr::Neg { d, a } => {
                    let a = map[a as usize];
                    map[d as usize] = fresh();
                    Op::Neg { d: map[d as usize], a }
                }
                Instr::Sqrt { d, a } => {
                    let a = map[a as usize];
                    map[d as usize] = fresh();
                    Op::Sqrt { d: map[d as usize], a }
                }
                Instr::SinCos { s, c, a } => {
                    let a = map[a as usize];
                    map[s as usize] = fresh();
                    map[c as usize] = fresh();
                    Op::SinCos { s: map[s as usize], c: map[c as usize], a }
                }
                Instr::Atan2 { d, a, b } => {
                    let (a, b) = (map[a as usize], map[b as usize]);
                    let d2 = fresh();
                    map[d as usize] = d2;
                    Op::Atan2 { d: d2, a, b, u: fresh() }
                }
                Instr::Powf { d, a, b } => {
                    let (a, b) = (map[a as usize], map[b as usize]);
                    let d2 = fresh();
                    map[d as usize] = d2;
                    if b < fixed && b as usize >= n_inputs {
                        Op::PowConst { d: d2, a, e: b }
                    } else {
                        Op::PowVar { d: d2, a, b, l: fresh(), m: fresh() }
                    }
                }
                Instr::Root { d, a, q } => {
                    let a = map[a as usize];
                    let d2 = fresh();
                    map[d as usize] = d2;
                    Op::Root { d: d2, a, q }
                }
                Instr::Call { d, f, a } => {
                    let a = map[a as usize];
                    let d2 = fresh();
                    map[d as usize] = d2;
                    match f {
                        Func::Sin => Op::SinCos { s: d2, c: fresh(), a },
                        Func::Cos => Op::SinCos { s: fresh(), c: d2, a },
                        Func::Sinh => Op::SinhCosh { s: d2, c: fresh(), a },
                        Func::Cosh => Op::SinhCosh { s: fresh(), c: d2, a },
                        Func::Tan => Op::Tan { d: d2, a, u: fresh(), hyp: false },
                        Func::Tanh => Op::Tan { d: d2, a, u: fresh(), hyp: true },
                        Func::Exp => Op::Exp { d: d2, a },
                        Func::Log => Op::Log { d: d2, a },
                        Func::Asin => Op::Asin { d: d2, a, r: fresh(), neg: false },
                        Func::Acos => Op::Asin { d: d2, a, r: fresh(), neg: true },
                        Func::Atan => Op::Atan { d: d2, a, u: fresh() },
                        Func::Abs => Op::Abs { d: d2, a },
                        // The lowering emits `atan2` as its own instruction; a one-operand call
                        // of it cannot occur (its second operand would be missing).
                        Func::Atan2 => Op::Atan2 { d: d2, a, b: a, u: fresh() },
                    }
                }
            };
            ops.push(op);
        }
        let outputs: Vec<u32> = (0..tape.n_outputs()).map(|j| map[tape.output_slot(j)]).collect();
        let abs_args: Vec<u32> =
            ops.iter().filter_map(|op| if let Op::Abs { a, .. } = op { Some(*a) } else { None }).collect();
        let n_rows = next as usize;
        let constant = |r: u32| (r as usize).checked_sub(n_inputs).and_then(|i| consts.get(i)).copied();
        let roots = outputs.iter().chain(&abs_args).copied();
        let higher = higher_order_ops(&ops, constant, n_rows, roots);
        let (higher, weighted, n_rows) = weigh_rows(higher, n_rows);
        TaylorTape { n_inputs, consts, ops0: ops, ops: higher, outputs, n_rows, abs_args, weighted }
    }

    /// Whether the argument of some `abs` changes sign between the expansion point and `h`
    /// (its polynomial, orders `0..=order` of a buffer filled by [`TaylorTape::expand`] or
    /// [`TaylorOde::expand`], evaluated at `h`): the series is then not the solution there.
    pub fn kink_within(&self, c: &[f64], stride: usize, order: usize, h: f64) -> bool {
        self.abs_args.iter().any(|&r| {
            let row = &c[r as usize * stride..r as usize * stride + order + 1];
            let end = row.iter().rev().fold(0.0, |acc, &x| acc * h + x);
            (row[0] > 0.0 && end < 0.0) || (row[0] < 0.0 && end > 0.0)
        })
    }

    /// The recurrences of orders ≥ 1, in order (for the native back end).
    pub(super) fn ops(&self) -> &[Op] {
        &self.ops
    }

    /// The operations of order 0, in order (for the native back end).
    pub(super) fn ops0(&self) -> &[Op] {
        &self.ops0
    }

    /// The number of rows the recurrences write at each order ≥ 1, weighted rows included.
    pub(super) fn rows_per_order(&self) -> usize {
        let dests = self.ops.iter().flat_map(Op::dests);
        dests.map(|d| 1 + usize::from(self.weighted[d as usize].is_some())).sum()
    }

    /// The weighted row of row `r` (`j · r_j`), if a recurrence weights it (`weigh_rows`).
    pub(super) fn weighted_row(&self, r: u32) -> Option<u32> {
        self.weighted[r as usize]
    }

    /// Row `r`'s weighted row in a coefficient buffer of stride `s` (the interpreter's sums).
    fn weighted_of<'c>(&self, c: &'c [f64], s: usize, r: u32) -> &'c [f64] {
        let w = self.weighted_row(r).expect("weigh_rows gives every weighted operand its row");
        row(c, w, s)
    }

    /// The value of a constant row (`None` for any other row).
    pub(super) fn row_constant(&self, r: u32) -> Option<f64> {
        (r as usize).checked_sub(self.n_inputs).and_then(|i| self.consts.get(i)).copied()
    }

    /// Machine code for orders `1..=max_order` of this tape's recurrences, for coefficient
    /// buffers of `stride` (`max_order < stride`): unrolled per order, or compact (see
    /// [`TaylorTape::compile_native_compact`]) when unrolling would make too much code; `None`
    /// when [`crate::compile::NO_JIT_ENV`] is set, the host has no JIT, or the tape is too
    /// large for either form. Its coefficients equal [`TaylorTape::run_order`]'s bit for bit.
    pub fn compile_native(&self, stride: usize, max_order: usize) -> Option<TaylorNative> {
        if super::native::jit_disabled_by_env() {
            return None;
        }
        NativeTaylor::compile(self, stride, max_order).map(|code| TaylorNative(Arc::new(code)))
    }

    /// Compact machine code for orders `1..=max_order`: one function taking the order, each
    /// recurrence's sum a loop, so the code grows with the recurrences alone (not with the
    /// square of the order, as unrolled code does). [`TaylorTape::compile_native`] and
    /// [`TaylorOde`] choose it for large tapes of at most 600 recurrences (past that its code
    /// no longer fits in the caches and the interpreter is faster); this asks for it whatever
    /// the size. Same bits as the interpreter.
    pub fn compile_native_compact(&self, stride: usize, max_order: usize) -> Option<TaylorNative> {
        if super::native::jit_disabled_by_env() {
            return None;
        }
        NativeTaylor::compile_compact(self, stride, max_order).map(|code| TaylorNative(Arc::new(code)))
    }

    /// The number of coefficient rows (inputs, constants, values and auxiliaries).
    pub fn n_rows(&self) -> usize {
        self.n_rows
    }

    /// The number of recurrences run at each order ≥ 1 (after `higher_order_ops`).
    pub fn n_recurrences(&self) -> usize {
        self.ops.len()
    }

    /// The number of inputs (rows `0..n_inputs`).
    pub fn n_inputs(&self) -> usize {
        self.n_inputs
    }

    /// The row holding output `j`.
    pub fn output_row(&self, j: usize) -> usize {
        self.outputs[j] as usize
    }

    /// The number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.outputs.len()
    }

    /// Prepares a coefficient buffer (`n_rows · stride` values): constants in their rows with
    /// zero higher coefficients. Inputs are the caller's.
    pub fn init(&self, c: &mut [f64], stride: usize) {
        for (i, &v) in self.consts.iter().enumerate() {
            let r = (self.n_inputs + i) * stride;
            c[r] = v;
            c[r + 1..r + stride].fill(0.0);
        }
    }

    /// Computes order `k` of every value, given orders `0..k` of every row and order `k` of
    /// the inputs. Order 0 runs the interpreter's operations. The only failure is an `abs`
    /// whose argument is 0 while its order-`k` coefficient is not (a kink).
    pub fn run_order(&self, c: &mut [f64], stride: usize, k: usize) -> Result<(), KinkAt> {
        assert!(c.len() >= self.n_rows * stride && k < stride, "Taylor buffer too short");
        if k == 0 {
            self.run_order0(c, stride);
            return Ok(());
        }
        // Divisions by order-0 values and by `k` are multiplications by their reciprocals,
        // which do not wait for order `k` of anything.
        let s = stride;
        let at = |c: &[f64], r: u32, j: usize| c[r as usize * s + j];
        let rk = 1.0 / k as f64;
        // Writes order `k` of row `r` and, if it has one, of its weighted row.
        let put = |c: &mut [f64], r: u32, v: f64| {
            c[r as usize * s + k] = v;
            if let Some(w) = self.weighted[r as usize] {
                c[w as usize * s + k] = v * k as f64;
            }
        };
        for op in &self.ops {
            match *op {
                Op::Weigh { d, a } => {
                    let v = at(c, a, k) * k as f64;
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
                    let v = at(c, a, k) * f;
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
                    let v = (at(c, a, k) - acc) * (1.0 / rb[0]);
                    put(c, d, v);
                }
                Op::Sqrt { d, a } => {
                    let rd = row(c, d, s);
                    let acc = square_inner(rd, k);
                    let v = (at(c, a, k) - acc) * (1.0 / (2.0 * rd[0]));
                    put(c, d, v);
                }
                Op::SinCos { s: si, c: co, a } | Op::SinhCosh { s: si, c: co, a } => {
                    let (wa, rs, rc) = (self.weighted_of(c, s, a), row(c, si, s), row(c, co, s));
                    let sv = weighted(wa, rc, k) * rk;
                    let cv = weighted(wa, rs, k) * rk;
                    let sign = if matches!(op, Op::SinCos { .. }) { -1.0 } else { 1.0 };
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
                    let v = (ra[k] - acc * rk) * (1.0 / ra[0]);
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
                Op::Asin { d, a, r, neg } => {
                    // r = √(1 − a²): r_k = (−Σ_{j=0}^{k} a_j a_{k−j} − Σ_{j=1}^{k−1} r_j r_{k−j}) / 2r₀.
                    let (ra, rr) = (row(c, a, s), row(c, r, s));
                    let rv = (-square(ra, k) - square_inner(rr, k)) * (1.0 / (2.0 * rr[0]));
                    // r d' = ±a': k r₀ d_k = ±k a_k − Σ_{j=1}^{k−1} j d_j r_{k−j}.
                    let wd = self.weighted_of(c, s, d);
                    let ak = if neg { -ra[k] } else { ra[k] };
                    let dv = (ak - weighted_short(wd, rr, k) * rk) * (1.0 / rr[0]);
                    put(c, r, rv);
                    put(c, d, dv);
                }
                Op::Atan { d, a, u } => {
                    let (ra, ru) = (row(c, a, s), row(c, u, s));
                    let uv = square(ra, k);
                    let wd = self.weighted_of(c, s, d);
                    let dv = (ra[k] - weighted_short(wd, ru, k) * rk) * (1.0 / ru[0]);
                    put(c, u, uv);
                    put(c, d, dv);
                }
                Op::Atan2 { d, a, b, u } => {
                    let (ra, rb, ru) = (row(c, a, s), row(c, b, s), row(c, u, s));
                    let uv = square(ra, k) + square(rb, k);
                    // u d' = b a' − a b'.
                    let (wa, wb) = (self.weighted_of(c, s, a), self.weighted_of(c, s, b));
                    let num = weighted(wa, rb, k) - weighted(wb, ra, k);
                    let wd = self.weighted_of(c, s, d);
                    let dv = (num - weighted_short(wd, ru, k)) * (1.0 / (k as f64 * ru[0]));
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
                    let v = constant_power(row(c, a, s), row(c, d, s), at(c, e, 0), k);
                    put(c, d, v);
                }
                Op::Power { d, a, e } => {
                    let v = constant_power(row(c, a, s), row(c, d, s), e, k);
                    put(c, d, v);
                }
                Op::PowVar { d, a, b, l, m } => {
                    let (ra, wl) = (row(c, a, s), self.weighted_of(c, s, l));
                    let lv = (ra[k] - weighted_short(wl, ra, k) * rk) * (1.0 / ra[0]);
                    put(c, l, lv);
                    let (rb, rl) = (row(c, b, s), row(c, l, s));
                    let v = cauchy(rb, rl, k);
                    put(c, m, v);
                    let (wm, rd) = (self.weighted_of(c, s, m), row(c, d, s));
                    let v = weighted(wm, rd, k) * rk;
                    put(c, d, v);
                }
                Op::Abs { d, a } => {
                    let (a0, ak) = (at(c, a, 0), at(c, a, k));
                    let v = if a0 > 0.0 {
                        ak
                    } else if a0 < 0.0 {
                        -ak
                    } else if ak == 0.0 {
                        0.0
                    } else {
                        return Err(KinkAt);
                    };
                    put(c, d, v);
                }
            }
        }
        Ok(())
    }

    /// Order 0: the interpreter's operations, plus the auxiliary rows.
    fn run_order0(&self, c: &mut [f64], s: usize) {
        let ix = |r: u32| r as usize * s;
        for op in &self.ops0 {
            match *op {
                Op::Add { d, a, b } => c[ix(d)] = c[ix(a)] + c[ix(b)],
                Op::Sub { d, a, b } => c[ix(d)] = c[ix(a)] - c[ix(b)],
                Op::Mul { d, a, b } => c[ix(d)] = c[ix(a)] * c[ix(b)],
                Op::Div { d, a, b } => c[ix(d)] = c[ix(a)] / c[ix(b)],
                Op::Neg { d, a } => c[ix(d)] = -c[ix(a)],
                Op::Sqrt { d, a } => c[ix(d)] = c[ix(a)].sqrt(),
                Op::SinCos { s: si, c: co, a } => {
                    let (sv, cv) = c[ix(a)].sin_cos();
                    c[ix(si)] = sv;
                    c[ix(co)] = cv;
                }
                Op::SinhCosh { s: si, c: co, a } => {
                    let x = c[ix(a)];
                    c[ix(si)] = x.sinh();
                    c[ix(co)] = x.cosh();
                }
                Op::Exp { d, a } => c[ix(d)] = c[ix(a)].exp(),
                Op::Log { d, a } => c[ix(d)] = c[ix(a)].ln(),
                Op::Tan { d, a, u, hyp } => {
                    let x = c[ix(a)];
                    let v = if hyp { x.tanh() } else { x.tan() };
                    c[ix(d)] = v;
                    c[ix(u)] = if hyp { 1.0 - v * v } else { 1.0 + v * v };
                }
                Op::Asin { d, a, r, neg } => {
                    let x = c[ix(a)];
                    c[ix(d)] = if neg { x.acos() } else { x.asin() };
                    c[ix(r)] = (1.0 - x * x).sqrt();
                }
                Op::Atan { d, a, u } => {
                    let x = c[ix(a)];
                    c[ix(d)] = x.atan();
                    c[ix(u)] = 1.0 + x * x;
                }
                Op::Atan2 { d, a, b, u } => {
                    let (x, y) = (c[ix(a)], c[ix(b)]);
                    c[ix(d)] = x.atan2(y);
                    c[ix(u)] = x * x + y * y;
                }
                Op::Root { d, a, q } => c[ix(d)] = crate::eval::real_root(c[ix(a)], q),
                Op::PowConst { d, a, e } => c[ix(d)] = c[ix(a)].powf(c[ix(e)]),
                Op::PowVar { d, a, b, l, m } => {
                    let (x, y) = (c[ix(a)], c[ix(b)]);
                    let lv = x.ln();
                    c[ix(d)] = x.powf(y);
                    c[ix(l)] = lv;
                    c[ix(m)] = y * lv;
                }
                Op::Abs { d, a } => c[ix(d)] = c[ix(a)].abs(),
                // Only in the recurrences of orders ≥ 1, which start from these rows' values
                // as the plain operations compute them; given here for completeness.
                Op::Sqr { d, a } => c[ix(d)] = c[ix(a)] * c[ix(a)],
                Op::Scale { d, a, f } => c[ix(d)] = c[ix(a)] * f,
                Op::Power { d, a, e } => c[ix(d)] = c[ix(a)].powf(e),
                Op::Weigh { d, .. } => c[ix(d)] = 0.0,
            }
        }
    }

    /// Fills orders `0..=order` of every row, with the inputs' coefficients given by
    /// `inputs(k, c)` (called before order `k` is computed, to write order `k` of the inputs).
    /// For functions of time alone and tests; ODEs use [`TaylorOde`].
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

/// The recurrences of orders ≥ 1, rewritten from the order-0 operations `ops0` where a cheaper
/// recurrence gives the same series (`constant(r)`: the value of a constant row):
///
/// * a product with, or quotient by, a constant is a [`Op::Scale`], one multiplication per
///   order instead of an `O(k)` sum;
/// * `a · a` is an [`Op::Sqr`], which sums half the terms of the Cauchy product;
/// * a power of one row built from roots, powers, products and quotients of it (Kepler's
///   `1/(u √u)`) is one [`Op::Power`], whose intermediate rows (`√u`, `u √u`) are dropped at
///   orders ≥ 1 when nothing else reads them (`roots`: the rows read from outside).
///
/// Order 0 still runs the plain operations, so its values equal the plain tape's bit for bit,
/// and each rewritten row's series starts from the value the plain tape computes.
fn higher_order_ops(
    ops0: &[Op],
    constant: impl Fn(u32) -> Option<f64>,
    n_rows: usize,
    roots: impl Iterator<Item = u32>,
) -> Vec<Op> {
    // `power[r] = Some((b, e))`: row `r` is a constant times `b^e`, through some root or power.
    let mut power: Vec<Option<(u32, f64)>> = vec![None; n_rows];
    let base = |power: &[Option<(u32, f64)>], r: u32| power[r as usize].unwrap_or((r, 1.0));
    let mut ops = Vec::with_capacity(ops0.len());
    for op in ops0 {
        let (dest, pw, new) = match *op {
            Op::Mul { d, a, b } => match (constant(a), constant(b)) {
                (Some(f), _) => (d, power[b as usize], Op::Scale { d, a: b, f }),
                (_, Some(f)) => (d, power[a as usize], Op::Scale { d, a, f }),
                _ => {
                    let ((ba, ea), (bb, eb)) = (base(&power, a), base(&power, b));
                    if ba == bb && (power[a as usize].is_some() || power[b as usize].is_some()) {
                        (d, Some((ba, ea + eb)), Op::Power { d, a: ba, e: ea + eb })
                    } else if a == b {
                        (d, None, Op::Sqr { d, a })
                    } else {
                        (d, None, *op)
                    }
                }
            },
            Op::Div { d, a, b } => match (constant(a), constant(b)) {
                (_, Some(f)) => (d, power[a as usize], Op::Scale { d, a, f: 1.0 / f }),
                (Some(_), None) => match power[b as usize] {
                    Some((bb, eb)) => (d, Some((bb, -eb)), Op::Power { d, a: bb, e: -eb }),
                    None => (d, None, *op),
                },
                _ => {
                    let ((ba, ea), (bb, eb)) = (base(&power, a), base(&power, b));
                    if ba == bb && (power[a as usize].is_some() || power[b as usize].is_some()) {
                        (d, Some((ba, ea - eb)), Op::Power { d, a: ba, e: ea - eb })
                    } else {
                        (d, None, *op)
                    }
                }
            },
            Op::Neg { d, a } => (d, power[a as usize], *op),
            // A square root of a plain row keeps its own (half-length) recurrence.
            Op::Sqrt { d, a } => match power[a as usize] {
                Some((b, e)) => (d, Some((b, e / 2.0)), Op::Power { d, a: b, e: e / 2.0 }),
                None => (d, Some((a, 0.5)), *op),
            },
            Op::Root { d, a, q } => {
                let (b, e) = base(&power, a);
                let e = e / f64::from(q);
                (d, Some((b, e)), Op::Power { d, a: b, e })
            }
            Op::PowConst { d, a, e } => match constant(e) {
                Some(x) => {
                    let (b, ea) = base(&power, a);
                    (d, Some((b, ea * x)), Op::Power { d, a: b, e: ea * x })
                }
                None => (d, None, *op),
            },
            _ => {
                ops.push(*op);
                continue;
            }
        };
        power[dest as usize] = pw;
        ops.push(new);
    }
    // Keep what the roots need, back to front.
    let mut live = vec![false; n_rows];
    for r in roots {
        live[r as usize] = true;
    }
    let mut kept: Vec<Op> = Vec::with_capacity(ops.len());
    for op in ops.iter().rev() {
        if op.dests().any(|d| live[d as usize]) {
            for r in op.sources() {
                live[r as usize] = true;
            }
            kept.push(*op);
        }
    }
    kept.reverse();
    kept
}

/// Gives every row that a recurrence weights (the sums `Σ j a_j b_{k−j}` of sin, cos, exp,
/// tan, log, the inverse functions and varying powers) a weighted row `j · a_j` of its own,
/// which the sums read instead of multiplying each term by `j`: one multiplication per order
/// instead of one per term (the double pendulum's three sines and cosines: six sums), and the
/// same bits, each term being `(j · a_j) · b_{k−j}` either way. A row that the recurrences
/// write gets its weighted row with each write of an order (`put` in
/// [`TaylorTape::run_order`], `TaylorEmitter::put`); an input or a constant, by an
/// [`Op::Weigh`] at the start of each order, when its order `k` is known. Returns the
/// operations, the map from rows to weighted rows and the new number of rows.
fn weigh_rows(ops: Vec<Op>, n_rows: usize) -> (Vec<Op>, Vec<Option<u32>>, usize) {
    let mut written = vec![false; n_rows];
    for d in ops.iter().flat_map(Op::dests) {
        written[d as usize] = true;
    }
    let mut weighted = vec![None; n_rows];
    let mut next = n_rows as u32;
    let mut weigh = Vec::new();
    for r in ops.iter().flat_map(Op::weighted_operands) {
        if weighted[r as usize].is_none() {
            weighted[r as usize] = Some(next);
            if !written[r as usize] {
                weigh.push(Op::Weigh { d: next, a: r });
            }
            next += 1;
        }
    }
    weighted.resize(next as usize, None);
    weigh.extend(ops);
    (weigh, weighted, next as usize)
}

/// The Taylor recurrences of a [`TaylorTape`] compiled to machine code for one stride
/// ([`TaylorTape::compile_native`]); clones share the code.
#[derive(Clone, Debug)]
pub struct TaylorNative(Arc<NativeTaylor>);

impl TaylorNative {
    /// The stride of the coefficient buffers the code was compiled for.
    pub fn stride(&self) -> usize {
        self.0.stride()
    }

    /// The highest order compiled (orders `1..=max_order`; order 0 is interpreted except in a
    /// whole expansion).
    pub fn max_order(&self) -> usize {
        self.0.max_order()
    }

    /// [`TaylorTape::run_order`] for `1 ≤ k ≤ max_order` on a buffer of this stride (code
    /// compiled per order).
    pub fn run_order(&self, c: &mut [f64], k: usize) -> Result<(), KinkAt> {
        if self.0.run_order(c, k) {
            Ok(())
        } else {
            Err(KinkAt)
        }
    }

    /// Whether this is the whole expansion of an ODE from order 0 (see
    /// [`TaylorOde::native_for`]).
    pub fn is_whole(&self) -> bool {
        self.0.is_whole()
    }

    /// Whether this is compact code (see [`TaylorTape::compile_native_compact`]).
    pub fn is_compact(&self) -> bool {
        self.0.is_compact()
    }

    /// Runs a whole expansion: orders `0..=max_order` and the state's next order after each
    /// (`c`: the whole scratch of [`TaylorOde::expand`], with the state's order 0 and the
    /// time's orders given).
    fn run_expansion(&self, c: &mut [f64]) -> Ran {
        self.0.run_expansion(c)
    }
}

/// How many expansions a [`TaylorOde`] with native code switched on
/// ([`TaylorOde::with_native`]) runs in the interpreter before compiling, so a cold start
/// never waits for Cranelift.
pub const NATIVE_AFTER_EXPANSIONS: usize = 64;

/// The same for a [`TaylorOde`] left at its default: about the number of expansions after
/// which unrolled code has repaid its compile time. Measured in BENCHMARKS.md: Kepler at order
/// 19 takes 8 ms to compile and then saves 0.34 µs per step (even after 2.5 · 10⁴ steps), the
/// double pendulum at order 15 13 ms and 0.75 µs (1.8 · 10⁴); both costs grow with the
/// unrolled terms. Waiting that long before compiling at most doubles the time of a run that
/// ends just after (as renting skis until their price is spent bounds the loss of buying).
pub const AUTO_NATIVE_AFTER_EXPANSIONS: usize = 1 << 15;

/// Orders whose unrolled recurrences have more terms than this wait for
/// [`UNROLL_AFTER_EXPANSIONS`] before unrolled code, not [`AUTO_NATIVE_AFTER_EXPANSIONS`]:
/// unrolled code's compile time grows faster than its terms (76 ms for the chaos map's
/// variational double pendulum at order 12, 7,623 terms; 0.45 s for a 5-link pendulum at
/// order 19, 21,546), compact code's only with the recurrences (8–9 ms for either), and
/// compact code runs only 15–35 % slower than unrolled code at these sizes (BENCHMARKS.md).
/// At this size unrolled code compiles in about the time of [`AUTO_NATIVE_AFTER_EXPANSIONS`]
/// interpreted expansions.
pub const COMPACT_ABOVE_TERMS: usize = 5_000;

/// By default every tape (of at most 600 recurrences) gets compact code after this many
/// interpreted expansions, until its unrolled code exists. Compact code's compile time over
/// what it saves per expansion against the interpreter is 3,000–5,000 expansions for every
/// tape measured (Kepler 0.9 ms / 0.19 µs, the chaos map's variational system 8 ms / 1.9 µs,
/// the 10-link pendulum 38 ms / 8 µs; BENCHMARKS.md), so waiting this long at most doubles
/// the cost of a run that ends just after, as for [`AUTO_NATIVE_AFTER_EXPANSIONS`]…
pub const COMPACT_AFTER_EXPANSIONS: usize = 1 << 12;

/// …and a tape past [`COMPACT_ABOVE_TERMS`] gets unrolled code (if it has at most
/// `native::MAX_NATIVE_TAYLOR_TERMS` terms) after this many expansions in all, when the run
/// has been long enough to repay its compile time: unrolled code's compile time over what it
/// saves per expansion against compact code is 0.9–1.7 · 10⁵ expansions for these tapes (the
/// chaos map's variational system 76 ms / 0.89 µs, the 3-link pendulum 74 ms / 0.43 µs, the
/// 5-link 445 ms / 2.7 µs; BENCHMARKS.md).
pub const UNROLL_AFTER_EXPANSIONS: usize = 1 << 17;

/// The native code of a [`TaylorOde`], per order, compiled on demand and shared by clones.
#[derive(Debug)]
struct NativeCache {
    allowed: bool,
    /// Expansions before a small tape's unrolled code is compiled.
    after: usize,
    /// Expansions before compact code is compiled (until the unrolled code exists).
    compact_after: usize,
    /// Expansions before a large tape's unrolled code is compiled.
    unroll_after: usize,
    /// Expansions so far (counted only until the final code exists).
    uses: AtomicUsize,
    /// `by_order[p]`: the final code for expansions of order `p` (stride `p + 1`, orders
    /// `1..p`), the fastest there is.
    by_order: Vec<OnceLock<Option<TaylorNative>>>,
    /// `compact[p]`: compact code, run until `by_order[p]` exists.
    compact: Vec<OnceLock<Option<TaylorNative>>>,
}

impl NativeCache {
    /// Compact code after `compact_after` expansions, then unrolled code after `after` (small
    /// tapes) or `unroll_after` (large tapes).
    fn new(allowed: bool, after: usize, compact_after: usize, unroll_after: usize) -> Arc<NativeCache> {
        let slots = || (0..=MAX_NATIVE_ORDER).map(|_| OnceLock::new()).collect();
        Arc::new(NativeCache {
            allowed,
            after,
            compact_after,
            unroll_after,
            uses: AtomicUsize::new(0),
            by_order: slots(),
            compact: slots(),
        })
    }

    /// The default tiers.
    fn auto() -> Arc<NativeCache> {
        NativeCache::new(true, AUTO_NATIVE_AFTER_EXPANSIONS, COMPACT_AFTER_EXPANSIONS, UNROLL_AFTER_EXPANSIONS)
    }
}

/// Orders above this are always interpreted (the integrator's own limit is 100).
const MAX_NATIVE_ORDER: usize = 100;

/// An `abs` met its kink (see [`TaylorTape::run_order`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KinkAt;

#[inline(always)]
fn row(c: &[f64], r: u32, s: usize) -> &[f64] {
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

/// The weight `w_i` of term `i` of a sum (`j = i + 1`), shared with the native code, which
/// must compute it the same way.
#[derive(Clone, Copy, Debug)]
pub(super) enum Weight {
    One,
    /// `e j − (k − j)` (`constant_power`).
    Power(f64),
}

impl Weight {
    /// The weight of term `i` at order `k`.
    #[inline(always)]
    pub(super) fn at(self, i: usize, k: usize) -> f64 {
        let j = i + 1;
        match self {
            Weight::One => 1.0,
            Weight::Power(e) => e * j as f64 - (k - j) as f64,
        }
    }
}

/// `Σ_i w(i) x_i y_{n−1−i}` over `n = x.len()` terms in the order described above;
/// `late_first` / `late_last` mark the first / last term as reading an order-`k` value. The
/// weight is a closure (each call site its own copy of the loop, measured 5–8 % faster for the
/// interpreter than a `Weight` matched inside it), which calls [`Weight::at`].
#[inline(always)]
fn sum4(x: &[f64], y: &[f64], w: impl Fn(usize) -> f64, late_first: bool, late_last: bool) -> f64 {
    let n = x.len();
    assert!(y.len() >= n);
    let lo = usize::from(late_first && n > 0);
    let hi = if late_last && n > lo { n - 1 } else { n };
    // SAFETY: every index below is `i < n` into `x` and `n − 1 − i` (with `i < n`) into `y`,
    // whose length is at least `n` (asserted).
    let term = |i: usize| unsafe { w(i) * *x.get_unchecked(i) * *y.get_unchecked(n - 1 - i) };
    // The partial sums start from −0.0, the identity of IEEE addition (`−0.0 + t` is `t`
    // for every `t`, where `+0.0 + (−0.0)` is `+0.0`), so the native code can start each
    // from its first term and leave out the partial sums that get none.
    let (mut s0, mut s1, mut s2, mut s3) = (-0.0, -0.0, -0.0, -0.0);
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

/// Solves `L Lᵀ x = b` in place (`x` holds `b`) with the factor `L` of `rhs::factor` and its
/// diagonal's reciprocals `inv`: `rhs::solve`'s substitutions with multiplications where it
/// divides. Each order of a `W q'' = F` expansion runs one solve on its dependency chain from
/// one order to the next, and the `2n` divisions (13 cycles or more each) were most of that
/// chain's latency. The whole native expansion does the same operations (the same bits).
fn cholesky_solve(l: &[f64], inv: &[f64], n: usize, x: &mut [f64]) {
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
fn cauchy(a: &[f64], b: &[f64], k: usize) -> f64 {
    sum4(&a[..=k], &b[..=k], |_| 1.0, true, true)
}

/// `Σ_{j=0}^{k} a_j a_{k−j}` over half its terms: `2 Σ_{1≤j<k−j} a_j a_{k−j} + a_{k/2}²`
/// (even `k`) plus `2a₀ · a_k`, the one term that reads order `k`, last.
#[inline(always)]
fn square(a: &[f64], k: usize) -> f64 {
    square_inner(a, k) + (2.0 * a[0]) * a[k]
}

/// `Σ_{j=1}^{k−1} a_j a_{k−j}` over half its terms: `2 Σ_{1≤j<k−j} a_j a_{k−j} + a_{k/2}²`.
#[inline(always)]
fn square_inner(a: &[f64], k: usize) -> f64 {
    let n = k.div_ceil(2) - 1;
    let half = sum4(&a[1..1 + n], &a[k - n..k], |_| 1.0, false, false);
    let mid = if k % 2 == 0 { a[k / 2] * a[k / 2] } else { 0.0 };
    2.0 * half + mid
}

/// `Σ_{j} x_j y_{n−1−j}` for two slices of length `n` (the second read backwards); `late`:
/// the last `x` is an order-`k` value.
#[inline(always)]
fn dot_rev(x: &[f64], y: &[f64], late: bool) -> f64 {
    sum4(x, y, |_| 1.0, false, late)
}

/// `Σ_{j=1}^{k} j a_j b_{k−j}` (the coefficient of `t^{k−1}` in `a' b`), given `a`'s weighted
/// row `wa` (`wa_j = j · a_j`, see `weigh_rows`): the terms `(j · a_j) · b_{k−j}`.
#[inline(always)]
fn weighted(wa: &[f64], b: &[f64], k: usize) -> f64 {
    sum4(&wa[1..=k], &b[..k], |_| 1.0, false, true)
}

/// `Σ_{j=1}^{k−1} j a_j b_{k−j}`, given `a`'s weighted row.
#[inline(always)]
fn weighted_short(wa: &[f64], b: &[f64], k: usize) -> f64 {
    if k < 2 {
        return -0.0;
    }
    sum4(&wa[1..k], &b[1..k], |_| 1.0, false, false)
}

/// Where the derivative of a state component comes from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Derivative {
    /// Tape output `j`.
    Output(usize),
    /// State component `i` (`q' = v` of a second-order system).
    State(usize),
    /// Acceleration `i` of the solve `W a = F` (see [`TaylorOde::second_order`]).
    Solve(usize),
}

/// `W a = F` solved per order: the tape outputs of `W` (row-major) and `F`.
#[derive(Clone, Debug)]
struct MassSolve {
    n: usize,
    w: Vec<usize>,
    f: Vec<usize>,
    symmetric: bool,
    /// Per row `i` of `W`, the columns `l` whose entry varies, with its coefficient row: the
    /// only ones with orders ≥ 1 (a constant entry, such as the `2` and `1` of the double
    /// pendulum's `W`, adds nothing to `Σ_{j≥1} W_j a_{k−j}`).
    varying: Vec<Vec<(usize, usize)>>,
}

/// The Taylor expansion of the solution of `y' = f(t, y)` from a compiled tape: the state is
/// the first [`TaylorOde::dim`] inputs, the time (if the tape reads it) the input after them.
#[derive(Clone, Debug)]
pub struct TaylorOde {
    tape: TaylorTape,
    /// The plain tape, for order-0 evaluation as a right-hand side.
    plain: Tape,
    dim: usize,
    time: Option<usize>,
    derivs: Vec<Derivative>,
    solve: Option<MassSolve>,
    native: Arc<NativeCache>,
}

impl TaylorOde {
    /// `y' = f(y, t)` with `f_i` tape output `i`; the tape's inputs are `y…, t` (the time last,
    /// as every compiled right-hand side has it) or `y…` alone.
    pub fn first_order(tape: &Tape) -> TaylorOde {
        let dim = tape.n_outputs();
        let time = (tape.n_inputs() > dim).then_some(dim);
        TaylorOde {
            tape: TaylorTape::new(tape),
            plain: tape.clone(),
            dim,
            time,
            derivs: (0..dim).map(Derivative::Output).collect(),
            solve: None,
            native: NativeCache::auto(),
        }
    }

    /// `W q'' = F` in `y = (q, q')` with `n` degrees of freedom, from a tape with inputs
    /// `q…, q'…, t` and outputs `W` (row-major, `n²`) then `F` (`n`). Per order `k` the
    /// accelerations solve `W₀ a_k = F_k − Σ_{j=1}^{k} W_j a_{k−j}` with one factorisation of
    /// `W₀` (Cholesky when `W` is symmetric and positive definite, else LU with pivoting).
    pub fn second_order(tape: &Tape, n: usize, symmetric: bool) -> TaylorOde {
        let mut derivs: Vec<Derivative> = (0..n).map(|i| Derivative::State(n + i)).collect();
        derivs.extend((0..n).map(Derivative::Solve));
        let taylor = TaylorTape::new(tape);
        let varying = (0..n)
            .map(|i| {
                (0..n)
                    .map(|l| (l, taylor.output_row(i * n + l)))
                    .filter(|&(_, r)| taylor.row_constant(r as u32).is_none())
                    .collect()
            })
            .collect();
        let solve = MassSolve { n, w: (0..n * n).collect(), f: (n * n..n * n + n).collect(), symmetric, varying };
        TaylorOde {
            tape: taylor,
            plain: tape.clone(),
            dim: 2 * n,
            time: (tape.n_inputs() > 2 * n).then_some(2 * n),
            derivs,
            solve: Some(solve),
            native: NativeCache::auto(),
        }
    }

    /// The dimension of the state.
    pub fn dim(&self) -> usize {
        self.dim
    }

    /// Turns the native Taylor code on early or off. By default each order's code is
    /// compiled when a run has been long enough for it to repay its compile time: compact
    /// code after [`COMPACT_AFTER_EXPANSIONS`] expansions, then unrolled code after
    /// [`AUTO_NATIVE_AFTER_EXPANSIONS`], or for a tape past [`COMPACT_ABOVE_TERMS`] after
    /// [`UNROLL_AFTER_EXPANSIONS`]. On: the fastest code after
    /// [`NATIVE_AFTER_EXPANSIONS`]; off, never (nor ever when
    /// [`crate::compile::NO_JIT_ENV`] is set). Results are the same bits whichever code runs.
    pub fn with_native(mut self, on: bool) -> TaylorOde {
        let n = NATIVE_AFTER_EXPANSIONS;
        self.native = NativeCache::new(on, n, n, n);
        self
    }

    /// The native code for expansions of `order`, compiled now if it is not yet (`None`:
    /// native code is off, the host has no JIT, or the tape is too large for unrolled and for
    /// compact code).
    ///
    /// A first-order system, and a `W q'' = F` system with a symmetric `W`, get the whole
    /// expansion as one function (orders, the Cholesky solve and the steps from each order of
    /// the right-hand side to the next of the state, see `native.rs`); a non-symmetric `W`,
    /// whose LU solve stays in Rust, one function per order; a tape too large to unroll at
    /// this order, compact code called once per order.
    pub fn native_for(&self, order: usize) -> Option<TaylorNative> {
        if !self.native.allowed || !(2..=MAX_NATIVE_ORDER).contains(&order) {
            return None;
        }
        self.native.by_order[order].get_or_init(|| self.compile_native(order)).clone()
    }

    /// The native code compiled so far for expansions of `order` (the final code if it
    /// exists, else compact code), compiling nothing.
    pub fn native_compiled(&self, order: usize) -> Option<TaylorNative> {
        let cache = &*self.native;
        let slot = |tier: &[OnceLock<Option<TaylorNative>>]| tier.get(order).and_then(|c| c.get().cloned().flatten());
        slot(&cache.by_order).or_else(|| slot(&cache.compact))
    }

    fn compile_native(&self, order: usize) -> Option<TaylorNative> {
        let stride = order + 1;
        // An LU-factored (non-symmetric) `W` keeps its solve in Rust, between per-order code.
        if self.solve.as_ref().is_some_and(|m| !m.symmetric) {
            return self.tape.compile_native(stride, order - 1);
        }
        if super::native::jit_disabled_by_env() {
            return None;
        }
        let n_rows = self.tape.n_rows();
        let glue = (0..self.dim)
            .map(|i| {
                let src = match self.derivs[i] {
                    Derivative::Output(j) => self.tape.output_row(j),
                    Derivative::State(j) => j,
                    Derivative::Solve(j) => n_rows + j,
                };
                (i as u32, src as u32)
            })
            .collect();
        // The accelerations are the `n` rows after the tape's, then comes the factor of `W₀`
        // (the layout `expand` splits its scratch into).
        let solve = self.solve.as_ref().map(|m| CholeskySolve {
            n: m.n,
            f_rows: m.f.iter().map(|&o| self.tape.output_row(o) as u32).collect(),
            varying: m.varying.iter().map(|v| v.iter().map(|&(l, r)| (l, r as u32)).collect()).collect(),
            acc_row: n_rows as u32,
            factor_at: (n_rows + m.n) * stride,
            w_rows: m.w.iter().map(|&o| self.tape.output_row(o) as u32).collect(),
        });
        let expansion = Expansion { glue, solve, mirror_at: self.mirror_at(stride), len: self.scratch_len(order) };
        match NativeTaylor::compile_expansion(&self.tape, stride, order - 1, &expansion) {
            Some(code) => Some(TaylorNative(Arc::new(code))),
            // Too large to unroll: compact code, one call per order (none past
            // `MAX_COMPACT_RECURRENCES`).
            None => self.tape.compile_native(stride, order - 1),
        }
    }

    /// The code an expansion of `order` runs on, compiled in the tiers [`TaylorOde::with_native`]
    /// describes: the interpreter (`None`), then compact code, then the final code
    /// ([`TaylorOde::native_for`]).
    fn native_tiered(&self, order: usize) -> Option<&TaylorNative> {
        let cache = &*self.native;
        if !cache.allowed || !(2..=MAX_NATIVE_ORDER).contains(&order) {
            return None;
        }
        let best = &cache.by_order[order];
        if let Some(code) = best.get() {
            return code.as_ref();
        }
        let uses = cache.uses.fetch_add(1, Ordering::Relaxed);
        let terms = unrolled_terms(&self.tape, order - 1);
        let final_after = match terms {
            t if t <= COMPACT_ABOVE_TERMS => cache.after,
            // Too large to unroll at all: the compact code is the final code.
            t if t > MAX_NATIVE_TAYLOR_TERMS => cache.compact_after,
            _ => cache.unroll_after,
        };
        if uses >= final_after {
            return best.get_or_init(|| self.compile_native(order)).as_ref();
        }
        if uses >= cache.compact_after && compact_pays(&self.tape) {
            let compact = || self.tape.compile_native_compact(order + 1, order - 1);
            return cache.compact[order].get_or_init(compact).as_ref();
        }
        None
    }

    /// The Taylor form of the tape.
    pub fn taylor_tape(&self) -> &TaylorTape {
        &self.tape
    }

    fn solve_len(&self, stride: usize) -> usize {
        match &self.solve {
            // accelerations (n · stride), factor (n²), perm (n), tmp (n), rhs (n), W₀ (n²)
            Some(m) => m.n * stride + 2 * m.n * m.n + 3 * m.n,
            None => 0,
        }
    }

    /// Scratch values [`TaylorOde::expand`] needs for `order`.
    pub fn scratch_len(&self, order: usize) -> usize {
        let stride = order + 1;
        let rows = self.tape.n_rows() + self.solve.as_ref().map_or(0, |m| m.n);
        self.mirror_at(stride) + rows * stride
    }

    /// Where the whole native expansion keeps the mirror images of its rows (after the rows
    /// and the solve's scratch; see `native::TaylorEmitter::pair`).
    fn mirror_at(&self, stride: usize) -> usize {
        self.tape.n_rows() * stride + self.solve_len(stride)
    }

    /// Fills `coeffs[i · (order + 1) + k]` with the normalised Taylor coefficients
    /// `y_i⁽ᵏ⁾(t)/k!`, `k = 0..=order`, of the solution through `(t, y)`, and refuses
    /// non-finite ones ([`TaylorError::NonFinite`], naming the order). The integrator calls
    /// [`TaylorOde::expand_in_place`] instead, which neither copies nor scans.
    pub fn expand(
        &self,
        t: f64,
        y: &[f64],
        order: usize,
        scratch: &mut [f64],
        coeffs: &mut [f64],
    ) -> Result<(), TaylorError> {
        let s = order + 1;
        let n = self.dim * s;
        assert!(coeffs.len() >= n, "coefficient buffer too short");
        self.expand_in_place(t, y, order, scratch)?;
        coeffs[..n].copy_from_slice(&scratch[..n]);
        match coeffs[..n].iter().position(|x| !x.is_finite()) {
            Some(bad) => Err(self.non_finite_at(t, y, order, bad)),
            None => Ok(()),
        }
    }

    /// The error for the non-finite coefficient `coeffs[at]` of the expansion at `(t, y)`.
    fn non_finite_at(&self, t: f64, y: &[f64], order: usize, at: usize) -> TaylorError {
        TaylorError::NonFinite { t, order: at % (order + 1), state: y[..self.dim].to_vec() }
    }

    /// [`TaylorOde::expand`] without the copy and the check: the coefficients are left in
    /// `scratch[i · (order + 1) + k]` (the state's rows come first), and may be non-finite.
    /// The Taylor integrator finds non-finite ones from its step's result instead, at no
    /// cost to good steps (`integrate::TaylorSystem::taylor_coefficients`).
    pub fn expand_in_place(&self, t: f64, y: &[f64], order: usize, scratch: &mut [f64]) -> Result<(), TaylorError> {
        let s = order + 1;
        let dim = self.dim;
        assert!(y.len() >= dim, "state too short");
        let rows = self.tape.n_rows() * s;
        let len = self.scratch_len(order);
        let kink = |_| TaylorError::AbsKink { t, state: y[..dim].to_vec() };
        let native = self.native_tiered(order);
        {
            let c = &mut scratch[..rows];
            self.tape.init(c, s);
            for i in 0..dim {
                c[i * s] = y[i];
            }
            if let Some(ti) = self.time {
                let r = &mut c[ti * s..(ti + 1) * s];
                r.fill(0.0);
                r[0] = t;
                if s > 1 {
                    r[1] = 1.0;
                }
            }
        }
        if let Some(code) = native.filter(|code| code.is_whole()) {
            match code.run_expansion(&mut scratch[..len]) {
                Ran::Done => return Ok(()),
                Ran::Kink => return Err(kink(KinkAt)),
                // `W₀` not finite or not positive definite: the interpreter redoes it all, and
                // factors by LU or reports the error.
                Ran::Redo => {}
            }
        }
        let native = native.filter(|code| !code.is_whole());
        let (c, rest) = scratch[..len].split_at_mut(rows);
        let mut kind = Factor::Cholesky;
        for k in 0..order {
            match native {
                Some(code) if k >= 1 => code.run_order(c, k).map_err(kink)?,
                _ => self.tape.run_order(c, s, k).map_err(kink)?,
            }
            if let Some(m) = &self.solve {
                let n = m.n;
                // The whole native expansion reads `acc` and `fm` at these offsets (the
                // `CholeskySolve` of `compile_native`).
                let (acc, rest) = rest.split_at_mut(n * s);
                let (fm, rest) = rest.split_at_mut(n * n);
                let (perm, rest) = rest.split_at_mut(n);
                let (tmp, rest) = rest.split_at_mut(n);
                let (rhs, rest) = rest.split_at_mut(n);
                let w0 = &mut rest[..n * n];
                let out = |j: usize| self.tape.output_row(j);
                if k == 0 {
                    for (e, &o) in w0.iter_mut().zip(&m.w) {
                        *e = c[out(o) * s];
                    }
                    if !w0.iter().all(|x| x.is_finite()) {
                        return Err(TaylorError::NonFinite { t, order: 0, state: y[..dim].to_vec() });
                    }
                    kind = factor(w0, fm, perm, n, m.symmetric).map_err(|index| TaylorError::SingularMassMatrix {
                        t,
                        index,
                        state: y[..dim].to_vec(),
                    })?;
                    if matches!(kind, Factor::Cholesky) {
                        // `perm` is LU's; a Cholesky factor keeps its diagonal's reciprocals there.
                        for i in 0..n {
                            perm[i] = 1.0 / fm[i * n + i];
                        }
                    }
                }
                for i in 0..n {
                    let mut v = c[out(m.f[i]) * s + k];
                    for &(l, r) in &m.varying[i] {
                        // Σ_{j=1}^{k} W_il,j a_l,k−j
                        v -= dot_rev(&c[r * s + 1..=r * s + k], &acc[l * s..l * s + k], true);
                    }
                    rhs[i] = v;
                }
                match kind {
                    Factor::Cholesky => cholesky_solve(fm, perm, n, rhs),
                    Factor::Lu => solve(kind, fm, perm, n, rhs, tmp),
                }
                for i in 0..n {
                    acc[i * s + k] = rhs[i];
                }
            }
            let inv = 1.0 / (k + 1) as f64;
            for i in 0..dim {
                let v = match self.derivs[i] {
                    Derivative::Output(j) => c[self.tape.output_row(j) * s + k],
                    Derivative::State(j) => c[j * s + k],
                    Derivative::Solve(j) => rest[j * s + k],
                };
                c[i * s + k + 1] = v * inv;
            }
        }
        Ok(())
    }

    /// The right-hand side `f(t, y)` at order 0 (the plain tape and, for `W q'' = F`, one
    /// solve): the first-order coefficients times one.
    pub fn eval_rate(&self, t: f64, y: &[f64], dy: &mut [f64]) -> Result<(), TaylorError> {
        let mut scratch = vec![0.0; self.scratch_len(1)];
        let mut coeffs = vec![0.0; 2 * self.dim];
        self.expand(t, y, 1, &mut scratch, &mut coeffs)?;
        for i in 0..self.dim {
            dy[i] = coeffs[2 * i + 1];
        }
        Ok(())
    }

    /// The plain tape.
    pub fn tape(&self) -> &Tape {
        &self.plain
    }
}

impl fmt::Display for TaylorTape {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} rows, {} operations at order 0, {} recurrences at orders ≥ 1",
            self.n_rows,
            self.ops0.len(),
            self.ops.len()
        )
    }
}

impl TaylorSystem for TaylorOde {
    fn dim(&self) -> usize {
        self.dim
    }
    fn scratch_len(&self, order: usize) -> usize {
        TaylorOde::scratch_len(self, order)
    }
    fn taylor_coefficients(&self, t: f64, y: &[f64], order: usize, buf: &mut [f64]) -> Result<(), StepError> {
        self.expand_in_place(t, y, order, buf).map_err(|e| StepError::new(e.to_string()))
    }
    /// Names the coefficient's order ([`TaylorError::NonFinite`]).
    fn non_finite(&self, t: f64, y: &[f64], order: usize, at: usize) -> StepFailure {
        StepError::new(self.non_finite_at(t, y, order, at).to_string()).into()
    }
    fn check_step(&self, scratch: &[f64], order: usize, h: f64) -> Result<(), StepError> {
        // Tape values are expanded to `order − 1` (the state's order-`order` terms come from
        // them), so their polynomial stops there.
        if self.tape.kink_within(scratch, order + 1, order - 1, h) {
            return Err(StepError::new(format!(
                "the argument of abs(…) changes sign within the step of size {h:e}: the right-hand side has a kink there, and the Taylor method needs it smooth"
            )));
        }
        Ok(())
    }
}

impl TaylorOde {
    /// The Taylor form of a compiled `W q'' = F` system (state `(q, q')`).
    pub fn from_lagrangian(rhs: &LagrangianRhs) -> TaylorOde {
        TaylorOde::second_order(rhs.tape(), rhs.dof(), rhs.is_symmetric())
    }

    /// The Taylor form of compiled Hamilton's equations (state `(q, p)`).
    pub fn from_hamiltonian(rhs: &HamiltonianRhs) -> TaylorOde {
        TaylorOde::first_order(rhs.tape())
    }

    /// `y' = f(y, t)` compiled from expressions: `state` names the components of `y` (plain
    /// spelling), `t` is the time, `params` are bound.
    pub fn from_exprs(f: &[Expr], state: &[&str], params: &[(&str, f64)]) -> Result<TaylorOde, CompileError> {
        if f.len() != state.len() {
            return Err(CompileError::Shape { what: "right-hand sides", expected: state.len(), got: f.len() });
        }
        let mut inputs: Vec<&str> = state.to_vec();
        inputs.push("t");
        let tape = Tape::compile(f, &inputs, params)?;
        Ok(TaylorOde::first_order(&tape))
    }
}

impl System {
    /// The Taylor form of the system's equations of motion: `W q'' = F` in `(q, q')` for a
    /// Lagrangian system, Hamilton's equations in `(q, p)` for a Hamiltonian one.
    ///
    /// For a Lagrangian system only the tape of `W` and `F` is built, and left interpreted:
    /// the Taylor tape evaluates every order itself, so the right-hand side's native code and
    /// unrolled Cholesky solve, which
    /// [`System::compile_rhs`] builds for the other methods, would be compiled for nothing —
    /// for the 10-link pendulum that was most of the cold start.
    pub fn compile_taylor(&self) -> Result<TaylorOde, CompileError> {
        match self.kind() {
            Kind::Hamiltonian(_) => Ok(TaylorOde::from_hamiltonian(&self.compile_hamiltonian()?)),
            _ => {
                if !self.constraints().is_empty() {
                    return Err(CompileError::Unsupported {
                        what: "holonomic constraints in the Taylor method (use the augmented system of compile_constrained with another method)",
                    });
                }
                let (w, f) = self.mass_matrix_split().map_err(CompileError::Mechanics)?;
                let n = w.len();
                let mut outputs: Vec<Expr> = w.iter().flatten().cloned().collect();
                outputs.extend(f.iter().cloned());
                let coords: Vec<String> = self.coordinates().iter().map(|s| s.to_string()).collect();
                let inputs = super::rhs::state_inputs(&coords);
                let inputs: Vec<&str> = inputs.iter().map(String::as_str).collect();
                let params: Vec<(String, f64)> = self.param_values().iter().map(|(k, v)| (k.to_string(), *v)).collect();
                let params: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
                let options = super::CompileOptions::default().with_native(false);
                let tape = Tape::compile_with_options(&outputs, &inputs, &params, &options)?;
                let symmetric = (0..n).all(|i| (0..i).all(|j| w[i][j] == w[j][i]));
                Ok(TaylorOde::second_order(&tape, n, symmetric))
            }
        }
    }
}
/// Coefficient `k` of `d = a^e` for a constant `e` (also the real root, `e = 1/q`), from
/// `a d' = e d a'`: `d_k = Σ_{j=1}^{k} (e j − (k − j)) a_j d_{k−j} / (k a₀)`.
#[inline(always)]
fn constant_power(ra: &[f64], rd: &[f64], e: f64, k: usize) -> f64 {
    let acc = sum4(&ra[1..=k], &rd[..k], |i| Weight::Power(e).at(i, k), false, true);
    acc * (1.0 / (k as f64 * ra[0]))
}
