//! The register tape: the demanded outputs of a set of expressions lowered into a flat list of
//! instructions over numbered slots, evaluated in a tight loop.
//!
//! Lowering walks the hash-consed DAG from the demanded outputs only (so dead outputs cost
//! nothing) and memoises on node identity (so every shared subexpression is one slot). On
//! top of that it value-numbers the emitted instructions (two different nodes that lower to
//! the same `a·b` share it) and makes the choices that are cheap in floating point rather than
//! small as trees: integer powers become multiplication chains, half-integer powers `sqrt`,
//! negative powers a division (or, when the reciprocal is used more than once, one reciprocal
//! shared by all its users), `sin` and `cos` of one argument one `sin_cos`, and every
//! subexpression of bound parameters alone is folded to a constant at compile time.
//!
//! Slots are laid out as `inputs | constants | registers`; after lowering, registers are
//! reassigned by a liveness scan so the scratch a call needs stays small.

use std::cell::RefCell;
use std::collections::{HashMap, HashSet};
use std::fmt;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use num_traits::ToPrimitive;

use crate::eval::eval_with;
use crate::expr::{Expr, Func, Node, Rational, Symbol};

use super::native::{jit_disabled_by_env, Epilogue, NativeCode};
use super::CompileError;

/// The deepest expression the (recursive) lowering accepts before reporting an error instead
/// of risking the stack.
const MAX_DEPTH: usize = 1_000;

/// Largest integer exponent turned into a multiplication chain; larger ones use `powf`.
const MAX_CHAIN_EXP: i64 = 64;

/// One tape instruction. Operands and destinations are slot numbers.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Instr {
    /// `d = a + b`
    Add { d: u32, a: u32, b: u32 },
    /// `d = a − b`
    Sub { d: u32, a: u32, b: u32 },
    /// `d = a · b`
    Mul { d: u32, a: u32, b: u32 },
    /// `d = a / b`
    Div { d: u32, a: u32, b: u32 },
    /// `d = −a`
    Neg { d: u32, a: u32 },
    /// `d = √a`
    Sqrt { d: u32, a: u32 },
    /// `s = sin a`, `c = cos a` in one instruction.
    SinCos { s: u32, c: u32, a: u32 },
    /// `d = f(a)` for a one-argument built-in.
    Call { d: u32, f: Func, a: u32 },
    /// `d = atan2(a, b)`
    Atan2 { d: u32, a: u32, b: u32 },
    /// `d = a ^ b` for a non-integer, non-half-integer exponent.
    Powf { d: u32, a: u32, b: u32 },
    /// `d` = the real `q`-th root of `a`, `q` odd ([`crate::eval::real_root`]): negative for
    /// negative `a`, so `x^(p/q)` is real where the simplifier says it is.
    Root { d: u32, a: u32, q: u32 },
}

impl Instr {
    fn dsts(&self) -> [Option<u32>; 2] {
        match *self {
            Instr::SinCos { s, c, .. } => [Some(s), Some(c)],
            Instr::Add { d, .. }
            | Instr::Sub { d, .. }
            | Instr::Mul { d, .. }
            | Instr::Div { d, .. }
            | Instr::Neg { d, .. }
            | Instr::Sqrt { d, .. }
            | Instr::Call { d, .. }
            | Instr::Atan2 { d, .. }
            | Instr::Powf { d, .. }
            | Instr::Root { d, .. } => [Some(d), None],
        }
    }

    fn srcs(&self) -> [Option<u32>; 2] {
        match *self {
            Instr::Add { a, b, .. }
            | Instr::Sub { a, b, .. }
            | Instr::Mul { a, b, .. }
            | Instr::Div { a, b, .. }
            | Instr::Atan2 { a, b, .. }
            | Instr::Powf { a, b, .. } => [Some(a), Some(b)],
            Instr::Neg { a, .. }
            | Instr::Sqrt { a, .. }
            | Instr::SinCos { a, .. }
            | Instr::Call { a, .. }
            | Instr::Root { a, .. } => [Some(a), None],
        }
    }

    fn map_slots(&mut self, src: &impl Fn(u32) -> u32, dst: &mut impl FnMut(u32) -> u32) {
        // Sources are renamed before destinations: a destination may reuse a register freed by
        // this instruction's own last read.
        match self {
            Instr::Add { d, a, b }
            | Instr::Sub { d, a, b }
            | Instr::Mul { d, a, b }
            | Instr::Div { d, a, b }
            | Instr::Atan2 { d, a, b }
            | Instr::Powf { d, a, b } => {
                *a = src(*a);
                *b = src(*b);
                *d = dst(*d);
            }
            Instr::Neg { d, a } | Instr::Sqrt { d, a } | Instr::Call { d, a, .. } | Instr::Root { d, a, .. } => {
                *a = src(*a);
                *d = dst(*d);
            }
            Instr::SinCos { s, c, a } => {
                *a = src(*a);
                *s = dst(*s);
                *c = dst(*c);
            }
        }
    }
}

/// How many instructions of each kind a tape runs per evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct OpCounts {
    /// Additions and subtractions.
    pub add: usize,
    /// Multiplications.
    pub mul: usize,
    /// Divisions.
    pub div: usize,
    /// Negations.
    pub neg: usize,
    /// Square roots.
    pub sqrt: usize,
    /// `sin_cos` pairs.
    pub sin_cos: usize,
    /// Other built-in calls (`sin`, `exp`, `atan2`, …).
    pub call: usize,
    /// General powers `powf`.
    pub powf: usize,
}

impl OpCounts {
    /// All instructions.
    pub fn total(&self) -> usize {
        self.add + self.mul + self.div + self.neg + self.sqrt + self.sin_cos + self.call + self.powf
    }
}

impl fmt::Display for OpCounts {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "{} ops: {} add/sub, {} mul, {} div, {} neg, {} sqrt, {} sin_cos, {} call, {} powf",
            self.total(),
            self.add,
            self.mul,
            self.div,
            self.neg,
            self.sqrt,
            self.sin_cos,
            self.call,
            self.powf
        )
    }
}

/// Choices of the code generator.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct CompileOptions {
    /// Compute `sin` and `cos` of differences of inputs `a − b` from `sin_cos(a)` and
    /// `sin_cos(b)` when that saves calls (more differences than angles). Faster for chains of
    /// pendulums; the result then has an absolute error of a few ulps of 1 instead of a
    /// relative one, so `sin(a − b)` for nearly equal `a`, `b` loses relative accuracy (as the
    /// same formula written by hand does). On by default.
    pub angle_differences: bool,
    /// Compile the tape to machine code (Cranelift) when the host allows it, and evaluate it
    /// there; the interpreter remains the fallback when it does not. The native code computes
    /// the same bits as the interpreter. On by default unless the environment variable
    /// [`NO_JIT_ENV`](super::NO_JIT_ENV) is set (to anything but `0`).
    pub native: bool,
}

impl Default for CompileOptions {
    fn default() -> Self {
        CompileOptions { angle_differences: true, native: !jit_disabled_by_env() }
    }
}

impl CompileOptions {
    /// Sets [`CompileOptions::angle_differences`].
    pub fn with_angle_differences(mut self, on: bool) -> Self {
        self.angle_differences = on;
        self
    }

    /// Sets [`CompileOptions::native`]; `false` forces the interpreter.
    pub fn with_native(mut self, on: bool) -> Self {
        self.native = on;
        self
    }
}

/// A compiled set of expressions: `outputs = f(inputs)` with parameters bound.
///
/// Evaluation does not allocate (after a thread's first call, which sizes its scratch) and
/// the tape is `Sync`: each thread evaluates on its own scratch. When the tape was compiled to
/// machine code ([`Tape::is_native`]) evaluation calls that instead and needs no scratch.
#[derive(Clone, Debug)]
pub struct Tape {
    input_names: Vec<String>,
    consts: Vec<f64>,
    instrs: Vec<Instr>,
    outputs: Vec<u32>,
    n_slots: usize,
    /// Unique per compiled tape (clones share it, and their constants).
    id: u64,
    /// The same instructions as machine code, when compiled and available (shared by clones).
    native: Option<Arc<NativeCode>>,
}

/// A thread's scratch buffer, and which tape's constants it holds in place.
struct Scratch {
    /// The [`Tape::id`] whose constants sit in their slots, or 0 after any other use.
    owner: u64,
    buf: Vec<f64>,
}

thread_local! {
    static SCRATCH: RefCell<Scratch> = const { RefCell::new(Scratch { owner: 0, buf: Vec::new() }) };
}

/// Tape identities, so a thread's scratch knows whose constants it holds.
static NEXT_TAPE_ID: AtomicU64 = AtomicU64::new(1);

/// Runs `f` on a per-thread scratch buffer of at least `len` values. The buffer grows on a
/// thread's first call and is reused after, so steady-state evaluation does not allocate. A
/// re-entrant call (a closure evaluating a tape inside another evaluation) gets a fresh buffer
/// instead of panicking.
pub(crate) fn with_scratch<R>(len: usize, f: impl FnOnce(&mut [f64]) -> R) -> R {
    SCRATCH.with(|cell| match cell.try_borrow_mut() {
        Ok(mut sc) => {
            sc.owner = 0;
            if sc.buf.len() < len {
                sc.buf.resize(len, 0.0);
            }
            f(&mut sc.buf[..len])
        }
        Err(_) => f(&mut vec![0.0; len]),
    })
}

/// The number of points evaluated together by [`Tape::eval_batch`]: enough to amortise the
/// instruction dispatch and let the element-wise loops vectorise.
pub const LANES: usize = 8;

impl Tape {
    /// Compiles `outputs` as functions of the symbols named in `inputs` (plain spelling:
    /// `"x"`, `"θ1'"`, `"t"`), with the symbols in `params` bound to numbers.
    ///
    /// Only the outputs asked for are lowered, so anything they do not depend on is never
    /// computed. Every other symbol is an error.
    pub fn compile(outputs: &[Expr], inputs: &[&str], params: &[(&str, f64)]) -> Result<Tape, CompileError> {
        Tape::compile_with_options(outputs, inputs, params, &CompileOptions::default())
    }

    /// [`Tape::compile`] with explicit code generator choices.
    pub fn compile_with_options(
        outputs: &[Expr],
        inputs: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<Tape, CompileError> {
        let mut lower = Lower::start(inputs, params, outputs, options)?;
        let mut out_slots = Vec::with_capacity(outputs.len());
        for e in outputs {
            out_slots.push(lower.lower(e, 0)?);
        }
        Ok(lower.finish(inputs, out_slots, options.native))
    }

    /// Compiles the solution `x` of `W x = F` for a symmetric `W`, with the Cholesky
    /// factorisation and both triangular solves unrolled into the tape, so one run evaluates
    /// `W`, `F` and the solve with no interpretation of loops, and every structurally zero or
    /// constant entry of `W` is folded away (a diagonal `W` is divided out symbolically instead, by
    /// [`Tape::compile_diagonal_solve`]).
    ///
    /// Outputs: `x` (`n`), the Cholesky pivots `d_j` (`n`, before their square roots) and the
    /// diagonal `W_jj` (`n`), so the caller can reject a factorisation whose pivots are not
    /// safely positive and fall back to a pivoting solve.
    // The unrolled factorisation indexes like the textbook loops it transcribes.
    #[allow(clippy::needless_range_loop)]
    pub(crate) fn compile_cholesky_solve(
        w: &[Vec<Expr>],
        f: &[Expr],
        inputs: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<Tape, CompileError> {
        let n = f.len();
        // A structurally zero diagonal entry is left to the factorisation, whose pivot test
        // reports the singular matrix at run time.
        let diagonal = (0..n).all(|i| (0..n).all(|j| (i == j) != w[i][j].is_zero()));
        if diagonal {
            return Tape::compile_diagonal_solve(w, f, inputs, params, options);
        }
        let mut exprs: Vec<Expr> = f.to_vec();
        exprs.extend(w.iter().flatten().cloned());
        let mut lower = Lower::start(inputs, params, &exprs, options)?;
        let mut wl = vec![vec![0u32; n]; n];
        for i in 0..n {
            for j in 0..=i {
                wl[i][j] = lower.lower(&w[i][j], 0)?;
            }
        }
        let mut rhs = Vec::with_capacity(n);
        for fi in f {
            rhs.push(lower.lower(fi, 0)?);
        }
        // W = L Lᵀ, column by column; `r[j] = 1/L_jj` turns every division into a product.
        let mut l = vec![vec![0u32; n]; n];
        let mut r = vec![0u32; n];
        let mut pivots = Vec::with_capacity(n);
        for j in 0..n {
            let mut d = wl[j][j];
            for k in 0..j {
                let sq = lower.emit(Key::Mul(l[j][k], l[j][k]));
                d = lower.emit(Key::Sub(d, sq));
            }
            pivots.push(d);
            let root = lower.emit(Key::Sqrt(d));
            l[j][j] = root;
            r[j] = lower.recip(root);
            for i in j + 1..n {
                let mut x = wl[i][j];
                for k in 0..j {
                    let p = lower.emit(Key::Mul(l[i][k], l[j][k]));
                    x = lower.emit(Key::Sub(x, p));
                }
                l[i][j] = lower.emit(Key::Mul(x, r[j]));
            }
        }
        let mut z = vec![0u32; n];
        for i in 0..n {
            let mut v = rhs[i];
            for k in 0..i {
                let p = lower.emit(Key::Mul(l[i][k], z[k]));
                v = lower.emit(Key::Sub(v, p));
            }
            z[i] = lower.emit(Key::Mul(v, r[i]));
        }
        let mut x = vec![0u32; n];
        for i in (0..n).rev() {
            let mut v = z[i];
            for k in i + 1..n {
                let p = lower.emit(Key::Mul(l[k][i], x[k]));
                v = lower.emit(Key::Sub(v, p));
            }
            x[i] = lower.emit(Key::Mul(v, r[i]));
        }
        let mut outputs = x;
        outputs.extend(pivots);
        outputs.extend((0..n).map(|j| wl[j][j]));
        Ok(lower.finish(inputs, outputs, options.native))
    }

    /// The solve tape of [`Tape::compile_cholesky_solve`] for a diagonal `W`: each
    /// acceleration is the exact quotient `F_i / W_ii`, formed symbolically so that common
    /// factors cancel before any code exists (`−m ω² x / m` compiles to one product, where the
    /// unrolled factorisation would spend a square root and two products on the same `m`); the
    /// pivots of a diagonal matrix are its diagonal entries.
    fn compile_diagonal_solve(
        w: &[Vec<Expr>],
        f: &[Expr],
        inputs: &[&str],
        params: &[(&str, f64)],
        options: &CompileOptions,
    ) -> Result<Tape, CompileError> {
        let n = f.len();
        let mut exprs: Vec<Expr> = (0..n).map(|i| f[i].over(&w[i][i])).collect();
        exprs.extend((0..n).map(|i| w[i][i].clone()));
        let mut lower = Lower::start(inputs, params, &exprs, options)?;
        let mut outputs = Vec::with_capacity(3 * n);
        for e in &exprs {
            outputs.push(lower.lower(e, 0)?);
        }
        outputs.extend_from_within(n..2 * n);
        Ok(lower.finish(inputs, outputs, options.native))
    }

    /// The number of inputs.
    pub fn n_inputs(&self) -> usize {
        self.input_names.len()
    }

    /// The number of outputs.
    pub fn n_outputs(&self) -> usize {
        self.outputs.len()
    }

    /// The input names, in order.
    pub fn input_names(&self) -> &[String] {
        &self.input_names
    }

    /// The instructions, in execution order.
    pub fn instrs(&self) -> &[Instr] {
        &self.instrs
    }

    /// The number of instructions one evaluation runs.
    pub fn op_count(&self) -> usize {
        self.instrs.len()
    }

    /// The instructions by kind.
    pub fn op_counts(&self) -> OpCounts {
        let mut c = OpCounts::default();
        for ins in &self.instrs {
            match ins {
                Instr::Add { .. } | Instr::Sub { .. } => c.add += 1,
                Instr::Mul { .. } => c.mul += 1,
                Instr::Div { .. } => c.div += 1,
                Instr::Neg { .. } => c.neg += 1,
                Instr::Sqrt { .. } => c.sqrt += 1,
                Instr::SinCos { .. } => c.sin_cos += 1,
                Instr::Call { .. } | Instr::Atan2 { .. } => c.call += 1,
                Instr::Powf { .. } | Instr::Root { .. } => c.powf += 1,
            }
        }
        c
    }

    /// The number of `f64` slots (inputs, constants and registers) one evaluation uses.
    pub fn scratch_len(&self) -> usize {
        self.n_slots
    }

    /// The constants, in slot order after the inputs.
    pub(crate) fn consts(&self) -> &[f64] {
        &self.consts
    }

    /// Whether evaluation runs native machine code (see [`CompileOptions::native`]) rather
    /// than the interpreter.
    pub fn is_native(&self) -> bool {
        self.native.is_some()
    }

    /// The same tape without its machine code: evaluation goes through the interpreter, the
    /// reference the native back end is tested against.
    pub fn interpreted(&self) -> Tape {
        Tape { native: None, ..self.clone() }
    }

    /// Evaluates with the first `n_inputs − 1` inputs from `head` and the last one (the time,
    /// in every right-hand side) from `last`, so a state slice is passed without copying.
    ///
    /// # Panics
    /// If `head` or `out` is too short.
    #[inline]
    pub(crate) fn eval_split(&self, head: &[f64], last: f64, out: &mut [f64]) {
        let ni = self.input_names.len();
        let nh = ni.saturating_sub(1);
        let no = self.outputs.len();
        assert!(head.len() >= nh && out.len() >= no, "tape called with too few inputs or outputs");
        match &self.native {
            // SAFETY: `head` holds the `nh` inputs read and `out` the `no` outputs written at
            // stride 1 (asserted above).
            Some(code) => unsafe { code.call(head.as_ptr(), 1, last, out.as_mut_ptr(), 1) },
            None => self.with_slots(0, |s, _| {
                s[..nh].copy_from_slice(&head[..nh]);
                if ni > 0 {
                    s[nh] = last;
                }
                self.run_slots(s);
                for (o, &slot) in out.iter_mut().zip(&self.outputs) {
                    *o = s[slot as usize];
                }
            }),
        }
    }

    /// Evaluates with the inputs already in `slots[..n_inputs]`, writing the outputs to `out`:
    /// natively when possible, otherwise by the interpreter on `slots` (at least
    /// [`Tape::scratch_len`] values; its input slots are left as they were). For callers that
    /// stage inputs in a buffer they already hold.
    pub(crate) fn eval_staged(&self, slots: &mut [f64], out: &mut [f64]) {
        let ni = self.input_names.len();
        match &self.native {
            Some(_) => {
                let last = if ni > 0 { slots[ni - 1] } else { 0.0 };
                self.eval_split(&slots[..ni.saturating_sub(1)], last, out);
            }
            None => {
                self.run_in_place(slots);
                for (o, &slot) in out.iter_mut().zip(&self.outputs) {
                    *o = slots[slot as usize];
                }
            }
        }
    }

    /// Evaluates natively with input `i < n_inputs − 1` at `x[i · x_stride]`, the last input
    /// `last`, output `j` to `out[j · out_stride]`: with `x = &y[k..]` and a stride of
    /// `points`, point `k` of a structure-of-arrays batch in place. Returns `false` (doing
    /// nothing) when the tape has no native code.
    ///
    /// # Panics
    /// If `x` or `out` is too short for its stride.
    #[inline]
    pub(crate) fn eval_strided(
        &self,
        x: &[f64],
        x_stride: usize,
        last: f64,
        out: &mut [f64],
        out_stride: usize,
    ) -> bool {
        let Some(code) = &self.native else { return false };
        let nh = self.input_names.len().saturating_sub(1);
        let no = self.outputs.len();
        assert!(
            (nh == 0 || x.len() > (nh - 1) * x_stride) && (no == 0 || out.len() > (no - 1) * out_stride),
            "strided tape buffers too short"
        );
        // SAFETY: the largest index read is `(nh − 1)·x_stride < x.len()` and the largest
        // written `(no − 1)·out_stride < out.len()` (asserted above).
        unsafe { code.call(x.as_ptr(), x_stride, last, out.as_mut_ptr(), out_stride) };
        true
    }

    /// Evaluates the tape at `inputs`, writing `outputs`, on a caller-provided `scratch` of at
    /// least [`Tape::scratch_len`] values. Never allocates.
    ///
    /// # Panics
    /// If a slice is shorter than the tape needs (a programming error, not a data one).
    pub fn eval_with_scratch(&self, inputs: &[f64], outputs: &mut [f64], scratch: &mut [f64]) {
        if self.native.is_some() {
            return self.eval(inputs, outputs);
        }
        let s = &mut scratch[..self.n_slots];
        let ni = self.input_names.len();
        s[..ni].copy_from_slice(&inputs[..ni]);
        s[ni..ni + self.consts.len()].copy_from_slice(&self.consts);
        run(&self.instrs, s, self.n_slots);
        for (o, &slot) in outputs.iter_mut().zip(&self.outputs) {
            *o = s[slot as usize];
        }
    }

    /// Evaluates the tape at `inputs` into `outputs` (natively, or on this thread's scratch
    /// buffer).
    ///
    /// # Panics
    /// If `inputs` is shorter than [`Tape::n_inputs`] or `outputs` shorter than
    /// [`Tape::n_outputs`] (a programming error, not a data one), on either back end.
    pub fn eval(&self, inputs: &[f64], outputs: &mut [f64]) {
        let ni = self.input_names.len();
        assert!(
            inputs.len() >= ni && outputs.len() >= self.outputs.len(),
            "tape called with too few inputs or outputs"
        );
        if self.native.is_some() {
            let last = if ni > 0 { inputs[ni - 1] } else { 0.0 };
            return self.eval_split(&inputs[..ni.saturating_sub(1)], last, outputs);
        }
        self.with_slots(0, |s, _| {
            s[..ni].copy_from_slice(&inputs[..ni]);
            self.run_slots(s);
            for (o, &slot) in outputs.iter_mut().zip(&self.outputs) {
                *o = s[slot as usize];
            }
        });
    }

    /// Runs the tape on a scratch whose first [`Tape::n_inputs`] slots the caller has filled,
    /// leaving the outputs in their slots (see [`Tape::output_slot`]). For callers that keep
    /// more of their own data after the tape's slots in one buffer.
    pub(crate) fn run_in_place(&self, s: &mut [f64]) {
        let ni = self.input_names.len();
        s[ni..ni + self.consts.len()].copy_from_slice(&self.consts);
        run(&self.instrs, s, self.n_slots);
    }

    /// Like [`Tape::run_in_place`] with [`LANES`] values per slot (slot `i` at
    /// `s[i * LANES..(i + 1) * LANES]`).
    pub(crate) fn run_lanes_in_place(&self, s: &mut [f64]) {
        let ni = self.input_names.len();
        for (k, c) in self.consts.iter().enumerate() {
            s[(ni + k) * LANES..(ni + k + 1) * LANES].fill(*c);
        }
        run_lanes(&self.instrs, &mut s[..self.n_slots * LANES]);
    }

    /// Runs `f(slots, extra)` on this thread's scratch: `slots` is the tape's own region with
    /// its constants in place (copied only when another tape or use had the scratch last, so
    /// repeated calls of one right-hand side skip the copy), `extra` is `extra` more values for
    /// the caller. The caller fills the inputs and calls [`Tape::run_slots`].
    pub(crate) fn with_slots<R>(&self, extra: usize, f: impl FnOnce(&mut [f64], &mut [f64]) -> R) -> R {
        let len = self.n_slots + extra;
        let ni = self.input_names.len();
        SCRATCH.with(|cell| match cell.try_borrow_mut() {
            Ok(mut sc) => {
                if sc.buf.len() < len {
                    sc.buf.resize(len, 0.0);
                }
                if sc.owner != self.id {
                    sc.buf[ni..ni + self.consts.len()].copy_from_slice(&self.consts);
                    sc.owner = self.id;
                }
                let (slots, rest) = sc.buf[..len].split_at_mut(self.n_slots);
                f(slots, rest)
            }
            Err(_) => {
                let mut buf = vec![0.0; len];
                buf[ni..ni + self.consts.len()].copy_from_slice(&self.consts);
                let (slots, rest) = buf.split_at_mut(self.n_slots);
                f(slots, rest)
            }
        })
    }

    /// Runs the instructions on slots prepared by [`Tape::with_slots`].
    #[inline]
    pub(crate) fn run_slots(&self, s: &mut [f64]) {
        run(&self.instrs, s, self.n_slots);
    }

    /// The slot holding output `i` after [`Tape::run_in_place`].
    pub(crate) fn output_slot(&self, i: usize) -> usize {
        self.outputs[i] as usize
    }

    /// Evaluates many points at once, structure-of-arrays: input `i` of point `k` is
    /// `inputs[i * n + k]`, output `j` of point `k` is written to `outputs[j * n + k]`, where
    /// `n = points`. Points go through the tape [`LANES`] at a time, so each instruction is
    /// dispatched once per block and its arithmetic runs over contiguous lanes.
    ///
    /// # Panics
    /// If `inputs` or `outputs` is shorter than `points` times the inputs or outputs.
    pub fn eval_batch(&self, inputs: &[f64], outputs: &mut [f64], points: usize) {
        assert!(inputs.len() >= points * self.n_inputs() && outputs.len() >= points * self.n_outputs());
        let ni = self.n_inputs();
        if self.native.is_some() {
            for k in 0..points {
                let last = if ni > 0 { inputs[(ni - 1) * points + k] } else { 0.0 };
                self.eval_strided(&inputs[k..], points, last, &mut outputs[k..], points);
            }
            return;
        }
        with_scratch(self.n_slots * LANES, |s| {
            for (k, c) in self.consts.iter().enumerate() {
                s[(ni + k) * LANES..(ni + k + 1) * LANES].fill(*c);
            }
            let mut start = 0;
            while start < points {
                let len = LANES.min(points - start);
                for i in 0..ni {
                    let dst = &mut s[i * LANES..(i + 1) * LANES];
                    dst[..len].copy_from_slice(&inputs[i * points + start..i * points + start + len]);
                    // Pad a partial block with a harmless value; its lanes are never read back.
                    dst[len..].fill(0.5);
                }
                run_lanes(&self.instrs, s);
                for (j, &slot) in self.outputs.iter().enumerate() {
                    let src = &s[slot as usize * LANES..slot as usize * LANES + len];
                    outputs[j * points + start..j * points + start + len].copy_from_slice(src);
                }
                start += len;
            }
        });
    }

    /// Reassigns registers by liveness so that a slot is reused once its last reader has run.
    /// Inputs and constants keep their slots; outputs stay live to the end.
    fn allocate_registers(mut self) -> Tape {
        let fixed = (self.input_names.len() + self.consts.len()) as u32;
        let mut last_use: HashMap<u32, usize> = HashMap::new();
        for (i, ins) in self.instrs.iter().enumerate() {
            for s in ins.srcs().into_iter().flatten() {
                last_use.insert(s, i);
            }
        }
        for &o in &self.outputs {
            last_use.insert(o, usize::MAX);
        }
        let mut map: HashMap<u32, u32> = HashMap::new();
        let mut free: Vec<u32> = Vec::new();
        let mut next = fixed;
        for i in 0..self.instrs.len() {
            let mut ins = self.instrs[i];
            let src_map = |s: u32| if s < fixed { s } else { map.get(&s).copied().unwrap_or(s) };
            // Registers whose last reader is this instruction become free for its result.
            let dying: Vec<u32> =
                ins.srcs().into_iter().flatten().filter(|&s| s >= fixed && last_use.get(&s) == Some(&i)).collect();
            let renamed_srcs: Vec<u32> = dying.iter().map(|&s| src_map(s)).collect();
            let mut dst_assign: Vec<(u32, u32)> = Vec::new();
            let old_dsts = ins.dsts();
            for r in renamed_srcs {
                if !free.contains(&r) {
                    free.push(r);
                }
            }
            for d in old_dsts.into_iter().flatten() {
                // A result nobody reads (the unused half of a sin_cos) still needs a register.
                let r = free.pop().unwrap_or_else(|| {
                    next += 1;
                    next - 1
                });
                dst_assign.push((d, r));
            }
            let mut k = 0;
            ins.map_slots(&src_map, &mut |_| {
                k += 1;
                dst_assign[k - 1].1
            });
            for (d, r) in dst_assign {
                map.insert(d, r);
                if !last_use.contains_key(&d) {
                    free.insert(0, r);
                }
            }
            self.instrs[i] = ins;
        }
        self.outputs = self.outputs.iter().map(|&o| if o < fixed { o } else { map[&o] }).collect();
        self.n_slots = next as usize;
        self.check_slots();
        self
    }

    /// The invariant the unchecked interpreter relies on: every slot an instruction or output
    /// names is below `n_slots`. A violation is a compiler bug, so it panics at build time
    /// instead of reading out of bounds at run time.
    fn check_slots(&self) {
        let n = self.n_slots as u32;
        let ok = self.instrs.iter().all(|i| i.srcs().into_iter().chain(i.dsts()).flatten().all(|s| s < n))
            && self.outputs.iter().all(|&o| o < n)
            && (self.input_names.len() + self.consts.len()) as u32 <= n;
        assert!(ok, "compiler bug: a tape names a slot beyond its scratch");
    }
}

/// The scalar interpreter loop.
///
/// This is the innermost loop of every compiled right-hand side, so it reads and writes slots
/// without bounds checks. Soundness rests on an invariant of [`Tape`], checked once when a tape
/// is built ([`Tape::check_slots`]) and unchanged after (the fields are private and never
/// mutated): every slot an instruction names is below `scratch_len`. Here `s` is sliced to
/// exactly `scratch_len` values first, which panics rather than reading out of bounds if a
/// caller passed a shorter buffer.
#[inline]
fn run(instrs: &[Instr], s: &mut [f64], n_slots: usize) {
    let s = &mut s[..n_slots];
    let p = s.as_mut_ptr();
    // SAFETY: every index below is < n_slots == s.len() (see above), and `p` is derived from
    // the exclusive borrow `s`, which is not otherwise used inside the loop.
    let get = |i: u32| unsafe { *p.add(i as usize) };
    let set = |i: u32, v: f64| unsafe { *p.add(i as usize) = v };
    for ins in instrs {
        match *ins {
            Instr::Add { d, a, b } => set(d, get(a) + get(b)),
            Instr::Sub { d, a, b } => set(d, get(a) - get(b)),
            Instr::Mul { d, a, b } => set(d, get(a) * get(b)),
            Instr::Div { d, a, b } => set(d, get(a) / get(b)),
            Instr::Neg { d, a } => set(d, -get(a)),
            Instr::Sqrt { d, a } => set(d, get(a).sqrt()),
            Instr::SinCos { s: si, c, a } => {
                let (sv, cv) = get(a).sin_cos();
                set(si, sv);
                set(c, cv);
            }
            Instr::Call { d, f, a } => set(d, f.eval(&[get(a)])),
            Instr::Atan2 { d, a, b } => set(d, get(a).atan2(get(b))),
            Instr::Powf { d, a, b } => set(d, get(a).powf(get(b))),
            Instr::Root { d, a, q } => set(d, crate::eval::real_root(get(a), q)),
        }
    }
}

/// The lane interpreter: every slot holds [`LANES`] values.
fn run_lanes(instrs: &[Instr], s: &mut [f64]) {
    #[inline(always)]
    fn bin(s: &mut [f64], d: u32, a: u32, b: u32, f: impl Fn(f64, f64) -> f64) {
        let mut tmp = [0.0; LANES];
        let (a, b) = (a as usize * LANES, b as usize * LANES);
        for l in 0..LANES {
            tmp[l] = f(s[a + l], s[b + l]);
        }
        s[d as usize * LANES..(d as usize + 1) * LANES].copy_from_slice(&tmp);
    }
    #[inline(always)]
    fn un(s: &mut [f64], d: u32, a: u32, f: impl Fn(f64) -> f64) {
        let mut tmp = [0.0; LANES];
        let a = a as usize * LANES;
        for l in 0..LANES {
            tmp[l] = f(s[a + l]);
        }
        s[d as usize * LANES..(d as usize + 1) * LANES].copy_from_slice(&tmp);
    }
    for ins in instrs {
        match *ins {
            Instr::Add { d, a, b } => bin(s, d, a, b, |x, y| x + y),
            Instr::Sub { d, a, b } => bin(s, d, a, b, |x, y| x - y),
            Instr::Mul { d, a, b } => bin(s, d, a, b, |x, y| x * y),
            Instr::Div { d, a, b } => bin(s, d, a, b, |x, y| x / y),
            Instr::Neg { d, a } => un(s, d, a, |x| -x),
            Instr::Sqrt { d, a } => un(s, d, a, f64::sqrt),
            Instr::SinCos { s: si, c, a } => {
                let mut sv = [0.0; LANES];
                let mut cv = [0.0; LANES];
                let a = a as usize * LANES;
                for l in 0..LANES {
                    (sv[l], cv[l]) = s[a + l].sin_cos();
                }
                s[si as usize * LANES..(si as usize + 1) * LANES].copy_from_slice(&sv);
                s[c as usize * LANES..(c as usize + 1) * LANES].copy_from_slice(&cv);
            }
            Instr::Call { d, f, a } => un(s, d, a, |x| f.eval(&[x])),
            Instr::Atan2 { d, a, b } => bin(s, d, a, b, f64::atan2),
            Instr::Powf { d, a, b } => bin(s, d, a, b, f64::powf),
            Instr::Root { d, a, q } => un(s, d, a, |x| crate::eval::real_root(x, q)),
        }
    }
}

impl fmt::Display for Tape {
    /// One line per slot and instruction; constants print in the shortest form that reads
    /// back to the same `f64`, so the listing is deterministic and snapshot-friendly.
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        for (i, name) in self.input_names.iter().enumerate() {
            writeln!(f, "s{i} = input {name}")?;
        }
        let ni = self.input_names.len();
        for (k, c) in self.consts.iter().enumerate() {
            writeln!(f, "s{} = const {c:?}", ni + k)?;
        }
        for ins in &self.instrs {
            match *ins {
                Instr::Add { d, a, b } => writeln!(f, "s{d} = s{a} + s{b}")?,
                Instr::Sub { d, a, b } => writeln!(f, "s{d} = s{a} - s{b}")?,
                Instr::Mul { d, a, b } => writeln!(f, "s{d} = s{a} * s{b}")?,
                Instr::Div { d, a, b } => writeln!(f, "s{d} = s{a} / s{b}")?,
                Instr::Neg { d, a } => writeln!(f, "s{d} = -s{a}")?,
                Instr::Sqrt { d, a } => writeln!(f, "s{d} = sqrt(s{a})")?,
                Instr::SinCos { s, c, a } => writeln!(f, "s{s}, s{c} = sin_cos(s{a})")?,
                Instr::Call { d, f: func, a } => writeln!(f, "s{d} = {}(s{a})", func.name())?,
                Instr::Atan2 { d, a, b } => writeln!(f, "s{d} = atan2(s{a}, s{b})")?,
                Instr::Powf { d, a, b } => writeln!(f, "s{d} = s{a} ^ s{b}")?,
                Instr::Root { d, a, q } => writeln!(f, "s{d} = root{q}(s{a})")?,
            }
        }
        for (j, o) in self.outputs.iter().enumerate() {
            writeln!(f, "out{j} = s{o}")?;
        }
        write!(f, "# {}; {} slots", self.op_counts(), self.n_slots)
    }
}

/// A key for value numbering of emitted instructions (operands normalised for commutative
/// operations).
#[derive(Clone, Copy, PartialEq, Eq, Hash)]
enum Key {
    Add(u32, u32),
    Sub(u32, u32),
    Mul(u32, u32),
    Div(u32, u32),
    Neg(u32),
    Sqrt(u32),
    Call(Func, u32),
    Atan2(u32, u32),
    Powf(u32, u32),
    Root(u32, u32),
}

struct Lower {
    inputs: HashMap<String, u32>,
    params: HashMap<String, f64>,
    consts: Vec<f64>,
    const_slots: HashMap<u64, u32>,
    instrs: Vec<Instr>,
    n_regs: u32,
    /// Lowered nodes: slot and whether the slot holds the negated value.
    memo: HashMap<Expr, (u32, bool)>,
    values: HashMap<Key, u32>,
    is_const: HashMap<Expr, bool>,
    /// Arguments whose sine and cosine are both demanded.
    sin_and_cos: HashSet<Expr>,
    /// Sine/cosine arguments `a − b` computed by the angle-difference formulas.
    differences: HashMap<Expr, (Expr, Expr)>,
    sincos: HashMap<u32, (u32, u32)>,
    /// How many times each base is divided by (uses of its negative integer powers).
    divisions: HashMap<Expr, usize>,
    powers: HashMap<(u32, i64), u32>,
}

impl Lower {
    /// Checks the names and starts a lowering of `outputs`.
    fn start(
        inputs: &[&str],
        params: &[(&str, f64)],
        outputs: &[Expr],
        options: &CompileOptions,
    ) -> Result<Lower, CompileError> {
        let mut input_slots = HashMap::new();
        for (i, name) in inputs.iter().enumerate() {
            if input_slots.insert(name.to_string(), i as u32).is_some() {
                return Err(CompileError::DuplicateInput { name: name.to_string() });
            }
        }
        let mut param_map = HashMap::new();
        for (name, value) in params {
            if input_slots.contains_key(*name) {
                return Err(CompileError::ParamIsInput { name: name.to_string() });
            }
            if !value.is_finite() {
                return Err(CompileError::NonFiniteParam { name: name.to_string(), value: *value });
            }
            param_map.insert(name.to_string(), *value);
        }
        Ok(Lower::new(input_slots, param_map, outputs, options))
    }

    /// Numbers the slots densely and allocates registers.
    fn finish(mut self, inputs: &[&str], mut outputs: Vec<u32>, native: bool) -> Tape {
        let n_slots = finalize_numbering(inputs.len() as u32, self.consts.len() as u32, &mut self.instrs, &mut outputs);
        let tape = Tape {
            input_names: inputs.iter().map(|s| s.to_string()).collect(),
            consts: self.consts,
            instrs: self.instrs,
            outputs,
            n_slots: n_slots as usize,
            id: NEXT_TAPE_ID.fetch_add(1, Ordering::Relaxed),
            native: None,
        };
        let mut tape = tape.allocate_registers();
        if native {
            tape.native = NativeCode::compile(&tape, Epilogue::Plain).map(Arc::new);
        }
        tape
    }

    fn new(
        inputs: HashMap<String, u32>,
        params: HashMap<String, f64>,
        outputs: &[Expr],
        options: &CompileOptions,
    ) -> Lower {
        let mut parents: HashMap<Expr, usize> = HashMap::new();
        let mut seen: HashSet<Expr> = HashSet::new();
        let mut sins: HashSet<Expr> = HashSet::new();
        let mut coss: HashSet<Expr> = HashSet::new();
        let mut stack: Vec<Expr> = outputs.to_vec();
        while let Some(e) = stack.pop() {
            if !seen.insert(e.clone()) {
                continue;
            }
            match e.node() {
                Node::Call(Func::Sin, a) => {
                    sins.insert(a[0].clone());
                }
                Node::Call(Func::Cos, a) => {
                    coss.insert(a[0].clone());
                }
                _ => {}
            }
            e.for_each_child(|c| {
                *parents.entry(c.clone()).or_insert(0) += 1;
                stack.push(c.clone());
            });
        }
        let mut sin_and_cos: HashSet<Expr> = sins.intersection(&coss).cloned().collect();
        // Angle differences: when the sines and cosines of many differences `a − b` of fewer
        // inputs are needed (an n-link chain has n(n−1)/2 of them over n angles), one sin_cos
        // per input and the angle-difference formulas replace a sin_cos per difference.
        let mut differences: HashMap<Expr, (Expr, Expr)> = HashMap::new();
        if options.angle_differences {
            for arg in sins.union(&coss) {
                if let Some((a, b)) = input_difference(arg, &inputs) {
                    differences.insert(arg.clone(), (a, b));
                }
            }
            let angles: HashSet<Expr> = differences.values().flat_map(|(a, b)| [a.clone(), b.clone()]).collect();
            if differences.len() > angles.len() {
                sin_and_cos.extend(angles);
            } else {
                differences.clear();
            }
        }
        // How often each base is divided by: a base used in several negative powers gets one
        // shared reciprocal; one used once is folded into its product's single division.
        let mut divisions: HashMap<Expr, usize> = HashMap::new();
        for e in &seen {
            if let Node::Pow(b, x) = e.node() {
                if small_int(x).is_some_and(|k| k < 0) {
                    let uses = parents.get(e).copied().unwrap_or(0) + outputs.iter().filter(|o| *o == e).count();
                    *divisions.entry(b.clone()).or_insert(0) += uses;
                }
            }
        }
        Lower {
            inputs,
            params,
            consts: Vec::new(),
            const_slots: HashMap::new(),
            instrs: Vec::new(),
            n_regs: 0,
            memo: HashMap::new(),
            values: HashMap::new(),
            is_const: HashMap::new(),
            sin_and_cos,
            differences,
            divisions,
            sincos: HashMap::new(),
            powers: HashMap::new(),
        }
    }

    /// The slot of a constant. Constants are numbered before every instruction's result.
    fn constant(&mut self, v: f64) -> u32 {
        let bits = if v == 0.0 { 0 } else { v.to_bits() };
        if let Some(&s) = self.const_slots.get(&bits) {
            return s;
        }
        let slot = CONST_BASE + self.consts.len() as u32;
        self.consts.push(v);
        self.const_slots.insert(bits, slot);
        slot
    }

    fn emit(&mut self, key: Key) -> u32 {
        let key = match key {
            Key::Add(a, b) if a > b => Key::Add(b, a),
            Key::Mul(a, b) if a > b => Key::Mul(b, a),
            k => k,
        };
        if let Some(&s) = self.values.get(&key) {
            return s;
        }
        if let Some(s) = self.simplify(key) {
            return s;
        }
        let d = self.fresh();
        let ins = match key {
            Key::Add(a, b) => Instr::Add { d, a, b },
            Key::Sub(a, b) => Instr::Sub { d, a, b },
            Key::Mul(a, b) => Instr::Mul { d, a, b },
            Key::Div(a, b) => Instr::Div { d, a, b },
            Key::Neg(a) => Instr::Neg { d, a },
            Key::Sqrt(a) => Instr::Sqrt { d, a },
            Key::Call(f, a) => Instr::Call { d, f, a },
            Key::Atan2(a, b) => Instr::Atan2 { d, a, b },
            Key::Powf(a, b) => Instr::Powf { d, a, b },
            Key::Root(a, q) => Instr::Root { d, a, q },
        };
        self.instrs.push(ins);
        self.values.insert(key, d);
        d
    }

    /// The value of a constant slot.
    fn const_value(&self, slot: u32) -> Option<f64> {
        (CONST_BASE..REG_BASE).contains(&slot).then(|| self.consts[(slot - CONST_BASE) as usize])
    }

    /// Folds an instruction whose operands are constants (with the same floating-point
    /// operation the interpreter would run) and applies the identities `x·1 = x`, `x·0 = 0`,
    /// `x + 0 = x`, `x/1 = x`, so code generated over structurally sparse data (an unrolled
    /// solve with a diagonal or constant mass matrix) costs only what is not zero or one.
    // Guards rather than float literal patterns: the comparisons are meant as `==` on values.
    #[allow(clippy::redundant_guards)]
    fn simplify(&mut self, key: Key) -> Option<u32> {
        let c = |s: u32| self.const_value(s);
        let folded = match key {
            Key::Add(a, b) => match (c(a), c(b)) {
                (Some(x), Some(y)) => Some(x + y),
                (Some(x), None) if x == 0.0 => return Some(b),
                (None, Some(y)) if y == 0.0 => return Some(a),
                _ => None,
            },
            Key::Sub(a, b) => match (c(a), c(b)) {
                (Some(x), Some(y)) => Some(x - y),
                (Some(x), None) if x == 0.0 => return Some(self.emit(Key::Neg(b))),
                (None, Some(y)) if y == 0.0 => return Some(a),
                _ => None,
            },
            Key::Mul(a, b) => match (c(a), c(b)) {
                (Some(x), Some(y)) => Some(x * y),
                (Some(z), _) | (_, Some(z)) if z == 0.0 => Some(0.0),
                (Some(x), None) if x == 1.0 => return Some(b),
                (None, Some(y)) if y == 1.0 => return Some(a),
                (Some(x), None) if x == -1.0 => return Some(self.emit(Key::Neg(b))),
                (None, Some(y)) if y == -1.0 => return Some(self.emit(Key::Neg(a))),
                _ => None,
            },
            Key::Div(a, b) => match (c(a), c(b)) {
                (Some(x), Some(y)) => Some(x / y),
                (None, Some(y)) if y == 1.0 => return Some(a),
                (Some(x), None) if x == 0.0 => Some(0.0),
                _ => None,
            },
            Key::Neg(a) => c(a).map(|x| -x),
            Key::Sqrt(a) => c(a).map(f64::sqrt),
            Key::Call(f, a) => c(a).map(|x| f.eval(&[x])),
            Key::Atan2(a, b) => c(a).zip(c(b)).map(|(x, y)| x.atan2(y)),
            Key::Powf(a, b) => c(a).zip(c(b)).map(|(x, y)| x.powf(y)),
            Key::Root(a, q) => c(a).map(|x| crate::eval::real_root(x, q)),
        }?;
        Some(self.constant(folded))
    }

    fn fresh(&mut self) -> u32 {
        self.n_regs += 1;
        REG_BASE + self.n_regs - 1
    }

    fn neg(&mut self, a: u32) -> u32 {
        self.emit(Key::Neg(a))
    }

    /// Whether `e` depends on bound parameters and numbers only.
    fn constant_node(&mut self, e: &Expr) -> bool {
        self.constant_rec(e, 0)
    }

    /// Beyond [`MAX_DEPTH`] a node counts as not constant, so the lowering (which checks the
    /// depth itself) reports [`CompileError::TooDeep`] instead of this walk overflowing the stack.
    fn constant_rec(&mut self, e: &Expr, depth: usize) -> bool {
        if depth > MAX_DEPTH {
            return false;
        }
        if let Some(&c) = self.is_const.get(e) {
            return c;
        }
        let c = match e.node() {
            Node::Num(_) => true,
            Node::Sym(s) => self.params.contains_key(&s.to_string()),
            Node::Apply { .. } | Node::Undefined => false,
            _ => {
                let mut all = true;
                let mut kids = Vec::new();
                e.for_each_child(|c| kids.push(c.clone()));
                for k in kids {
                    all &= self.constant_rec(&k, depth + 1);
                }
                all
            }
        };
        self.is_const.insert(e.clone(), c);
        c
    }

    fn fold(&self, e: &Expr) -> Result<f64, CompileError> {
        let params = &self.params;
        let v = eval_with(e, &|s: &Symbol| params.get(&s.to_string()).copied()).map_err(|_| CompileError::Undefined)?;
        if !v.is_finite() {
            return Err(CompileError::NonFiniteConstant { expr: e.to_string(), value: v });
        }
        Ok(v)
    }

    fn lower(&mut self, e: &Expr, depth: usize) -> Result<u32, CompileError> {
        let (slot, neg) = self.lower_signed(e, depth)?;
        Ok(if neg { self.neg(slot) } else { slot })
    }

    /// Lowers `e` to a slot holding `e` (`false`) or `−e` (`true`): a product with a negative
    /// coefficient is returned unnegated so a sum can subtract it instead.
    fn lower_signed(&mut self, e: &Expr, depth: usize) -> Result<(u32, bool), CompileError> {
        if let Some(&r) = self.memo.get(e) {
            return Ok(r);
        }
        if depth > MAX_DEPTH {
            return Err(CompileError::TooDeep { limit: MAX_DEPTH });
        }
        let r = if self.constant_node(e) {
            let v = self.fold(e)?;
            (self.constant(v.abs()), v.is_sign_negative() && v != 0.0)
        } else {
            match e.node() {
                Node::Num(_) => unreachable_const(),
                Node::Sym(s) => {
                    let name = s.to_string();
                    match self.inputs.get(&name) {
                        Some(&slot) => (slot, false),
                        None => return Err(CompileError::Unbound { name }),
                    }
                }
                Node::Add(ts) => (self.lower_add(ts, depth)?, false),
                Node::Mul(fs) => self.lower_mul(fs, depth)?,
                Node::Pow(b, x) => (self.lower_pow(b, x, depth)?, false),
                Node::Call(f, args) => (self.lower_call(*f, args, depth)?, false),
                Node::Apply { name, .. } => return Err(CompileError::UndefinedFunction { name: name.to_string() }),
                Node::Undefined => return Err(CompileError::Undefined),
            }
        };
        self.memo.insert(e.clone(), r);
        Ok(r)
    }

    fn lower_add(&mut self, ts: &[Expr], depth: usize) -> Result<u32, CompileError> {
        let mut c = 0.0;
        let mut pos = Vec::new();
        let mut neg = Vec::new();
        // Terms that differ only in their parameter coefficients are like terms once the
        // parameters are bound (`m1 g sin θ + m2 g sin θ` is `19.62 sin θ`): collect them.
        let mut like: Vec<(Expr, f64)> = Vec::new();
        let mut index: HashMap<Expr, usize> = HashMap::new();
        for t in ts {
            if self.constant_node(t) {
                c += self.fold(t)?;
                continue;
            }
            let (coeff, rest) = match t.node() {
                Node::Mul(fs) => {
                    let mut k = 1.0;
                    let mut rest = Vec::new();
                    for f in fs {
                        if self.constant_node(f) {
                            k *= self.fold(f)?;
                        } else {
                            rest.push(f.clone());
                        }
                    }
                    (k, Expr::mul(rest))
                }
                _ => (1.0, t.clone()),
            };
            match index.get(&rest) {
                Some(&i) => like[i].1 += coeff,
                None => {
                    index.insert(rest.clone(), like.len());
                    like.push((rest, coeff));
                }
            }
        }
        for (rest, k) in like {
            if k == 0.0 {
                continue;
            }
            let slot = self.lower(&rest, depth + 1)?;
            let slot = if k.abs() == 1.0 {
                slot
            } else {
                let ks = self.constant(k.abs());
                self.emit(Key::Mul(ks, slot))
            };
            if k < 0.0 {
                neg.push(slot);
            } else {
                pos.push(slot);
            }
        }
        let mut acc = match pos.first() {
            Some(&p) => {
                let mut acc = p;
                for &q in &pos[1..] {
                    acc = self.emit(Key::Add(acc, q));
                }
                if c != 0.0 {
                    let k = self.constant(c);
                    acc = self.emit(Key::Add(acc, k));
                }
                acc
            }
            None if c != 0.0 => self.constant(c),
            None => {
                // Only negative terms: start from the first one negated.
                let first = neg.remove(0);
                self.neg(first)
            }
        };
        for n in neg {
            acc = self.emit(Key::Sub(acc, n));
        }
        Ok(acc)
    }

    fn lower_mul(&mut self, fs: &[Expr], depth: usize) -> Result<(u32, bool), CompileError> {
        let mut c = 1.0;
        for f in fs {
            if self.constant_node(f) {
                c *= self.fold(f)?;
            }
        }
        // A lone sign in front of a negative half-integer power goes into its reciprocal:
        // `−x r^(−3/2)` is `x · (−1/r^(3/2))`, and the signed reciprocal is shared like the
        // plain one (Kepler's two accelerations need one division and no negation). IEEE
        // negation is exact, so the value is the same.
        let signed = if c == -1.0 { fs.iter().position(|f| negative_half_power(f).is_some()) } else { None };
        if signed.is_some() {
            c = 1.0;
        }
        let mut num = Vec::new();
        let mut den = Vec::new();
        for (i, f) in fs.iter().enumerate() {
            if self.constant_node(f) {
                continue;
            }
            if signed == Some(i) {
                if let Some((b, k)) = negative_half_power(f) {
                    let mag = self.half_power(b, -k, depth)?;
                    let minus_one = self.constant(-1.0);
                    num.push(self.emit(Key::Div(minus_one, mag)));
                    continue;
                }
            }
            // A negative integer power of a base divided by only here joins the denominator;
            // a base divided by in several places gets one reciprocal, multiplied in.
            if let Node::Pow(b, x) = f.node() {
                if let Some(k) = small_int(x) {
                    if k < 0 && self.divisions.get(b).copied().unwrap_or(0) <= 1 {
                        let bs = self.lower(b, depth + 1)?;
                        den.push(self.pow_chain(bs, -k));
                        continue;
                    }
                }
            }
            num.push(self.lower(f, depth + 1)?);
        }
        // A constant factor other than ±1 is multiplied in anyway, so it carries the sign too
        // (`−4 x` is one product, not a product and a negation; IEEE negation is exact, so the
        // value is the same); a lone sign is left to the caller, whose subtraction absorbs it.
        let neg = c == -1.0 && !num.is_empty();
        let c = if neg { 1.0 } else { c };
        let mut acc: Option<u32> = None;
        for s in num {
            acc = Some(match acc {
                None => s,
                Some(a) => self.emit(Key::Mul(a, s)),
            });
        }
        if c != 1.0 || acc.is_none() {
            let k = self.constant(c);
            acc = Some(match acc {
                None => k,
                Some(a) => self.emit(Key::Mul(k, a)),
            });
        }
        let mut acc = acc.unwrap_or_else(|| self.constant(1.0));
        if !den.is_empty() {
            let mut d = den[0];
            for &s in &den[1..] {
                d = self.emit(Key::Mul(d, s));
            }
            acc = self.emit(Key::Div(acc, d));
        }
        Ok((acc, neg))
    }

    /// `x^n` for `n ≥ 1` by repeated squaring, memoised per (base, n) so `x²`, `x³`, `x⁴` of
    /// one base share their partial products.
    fn pow_chain(&mut self, x: u32, n: i64) -> u32 {
        if n == 1 {
            return x;
        }
        if let Some(&s) = self.powers.get(&(x, n)) {
            return s;
        }
        let r = if n % 2 == 0 {
            let h = self.pow_chain(x, n / 2);
            self.emit(Key::Mul(h, h))
        } else {
            let h = self.pow_chain(x, n - 1);
            self.emit(Key::Mul(h, x))
        };
        self.powers.insert((x, n), r);
        r
    }

    fn recip(&mut self, x: u32) -> u32 {
        let one = self.constant(1.0);
        self.emit(Key::Div(one, x))
    }

    /// `b^(k/2)` for odd `k > 0`: `b^⌊k/2⌋ · √b`.
    fn half_power(&mut self, b: &Expr, k: i64, depth: usize) -> Result<u32, CompileError> {
        let bs = self.lower(b, depth + 1)?;
        let root = self.emit(Key::Sqrt(bs));
        Ok(if k / 2 == 0 {
            root
        } else {
            let p = self.pow_chain(bs, k / 2);
            self.emit(Key::Mul(p, root))
        })
    }

    fn lower_pow(&mut self, b: &Expr, x: &Expr, depth: usize) -> Result<u32, CompileError> {
        if let Some(k) = small_int(x) {
            let bs = self.lower(b, depth + 1)?;
            return Ok(if k > 0 {
                self.pow_chain(bs, k)
            } else {
                // x^-k = (1/x)^k, so 1/x is shared by every negative power of x.
                let r = self.recip(bs);
                self.pow_chain(r, -k)
            });
        }
        if let Some(k) = half_integer(x) {
            // x^(k/2) = x^⌊|k|/2⌋ · √x, inverted for negative k.
            let mag = self.half_power(b, k.abs(), depth)?;
            return Ok(if k < 0 { self.recip(mag) } else { mag });
        }
        if let Some((p, q)) = x.as_num().and_then(crate::eval::odd_root_exponent) {
            // x^(p/q) with q odd: the real root, then an integer power (real for x < 0, as
            // the simplifier and the reference evaluator have it).
            let bs = self.lower(b, depth + 1)?;
            let root = self.emit(Key::Root(bs, q));
            let p = i64::from(p);
            return Ok(if p > 0 {
                self.pow_chain(root, p)
            } else {
                let r = self.recip(root);
                self.pow_chain(r, -p)
            });
        }
        let bs = self.lower(b, depth + 1)?;
        let xs = self.lower(x, depth + 1)?;
        Ok(self.emit(Key::Powf(bs, xs)))
    }

    /// One `sin_cos` per argument slot.
    fn sin_cos(&mut self, a: u32) -> (u32, u32) {
        if let Some(&p) = self.sincos.get(&a) {
            return p;
        }
        let s = self.fresh();
        let c = self.fresh();
        self.instrs.push(Instr::SinCos { s, c, a });
        self.sincos.insert(a, (s, c));
        (s, c)
    }

    fn lower_call(&mut self, f: Func, args: &[Expr], depth: usize) -> Result<u32, CompileError> {
        if args.len() != f.arity() {
            return Err(CompileError::Undefined);
        }
        if matches!(f, Func::Sin | Func::Cos) {
            if let Some((x, y)) = self.differences.get(&args[0]).cloned() {
                // sin(x − y) = sx·cy − cx·sy, cos(x − y) = cx·cy + sx·sy.
                let xs = self.lower(&x, depth + 1)?;
                let ys = self.lower(&y, depth + 1)?;
                let (sx, cx) = self.sin_cos(xs);
                let (sy, cy) = self.sin_cos(ys);
                return Ok(if f == Func::Sin {
                    let p = self.emit(Key::Mul(sx, cy));
                    let q = self.emit(Key::Mul(cx, sy));
                    self.emit(Key::Sub(p, q))
                } else {
                    let p = self.emit(Key::Mul(cx, cy));
                    let q = self.emit(Key::Mul(sx, sy));
                    self.emit(Key::Add(p, q))
                });
            }
        }
        let a = self.lower(&args[0], depth + 1)?;
        match f {
            Func::Sin | Func::Cos if self.sin_and_cos.contains(&args[0]) => {
                let (s, c) = self.sin_cos(a);
                Ok(if f == Func::Sin { s } else { c })
            }
            Func::Atan2 => {
                let b = self.lower(&args[1], depth + 1)?;
                Ok(self.emit(Key::Atan2(a, b)))
            }
            _ => Ok(self.emit(Key::Call(f, a))),
        }
    }
}

// Provisional numbering during lowering: constants from `CONST_BASE`, instruction results from
// `REG_BASE`; both are mapped to dense slots when the lowering is done (`finalize_numbering`).
const CONST_BASE: u32 = 1 << 30;
const REG_BASE: u32 = 1 << 31;

fn unreachable_const() -> (u32, bool) {
    // `constant_node` is true for every number, so numbers never reach the match.
    (0, false)
}

/// `(a, b)` when `e` is `a − b` for two input symbols.
fn input_difference(e: &Expr, inputs: &HashMap<String, u32>) -> Option<(Expr, Expr)> {
    let Node::Add(ts) = e.node() else { return None };
    if ts.len() != 2 {
        return None;
    }
    let is_input = |x: &Expr| x.as_sym().is_some_and(|s| inputs.contains_key(&s.to_string()));
    let (first, second) = (&ts[0], &ts[1]);
    for (a, nb) in [(first, second), (second, first)] {
        if let Node::Mul(fs) = nb.node() {
            if fs.len() == 2 && fs[0].is_num(-1) && is_input(a) && is_input(&fs[1]) {
                return Some((a.clone(), fs[1].clone()));
            }
        }
    }
    None
}

/// `k` when `x` is `k/2` for an odd `k` within the chain limit.
fn half_integer(x: &Expr) -> Option<i64> {
    let r = x.as_num()?;
    if *r.denom() != 2.into() {
        return None;
    }
    r.numer().to_i64().filter(|k| k.abs() <= 2 * MAX_CHAIN_EXP)
}

/// `(b, k)` when `f` is `b^(k/2)` with `k < 0` odd.
fn negative_half_power(f: &Expr) -> Option<(&Expr, i64)> {
    match f.node() {
        Node::Pow(b, x) => half_integer(x).filter(|k| *k < 0).map(|k| (b, k)),
        _ => None,
    }
}

fn small_int(x: &Expr) -> Option<i64> {
    let r: &Rational = x.as_num()?;
    if !r.is_integer() {
        return None;
    }
    let k = r.to_integer().to_i64()?;
    (k != 0 && k.abs() <= MAX_CHAIN_EXP).then_some(k)
}

/// Maps the provisional constant and register numbers of a lowering to dense slots:
/// inputs, then constants, then registers in order of definition.
fn finalize_numbering(n_inputs: u32, n_consts: u32, instrs: &mut [Instr], outputs: &mut [u32]) -> u32 {
    let map = |s: u32| -> u32 {
        if s >= REG_BASE {
            n_inputs + n_consts + (s - REG_BASE)
        } else if s >= CONST_BASE {
            n_inputs + (s - CONST_BASE)
        } else {
            s
        }
    };
    for ins in instrs.iter_mut() {
        ins.map_slots(&map, &mut |d| map(d));
    }
    for o in outputs.iter_mut() {
        *o = map(*o);
    }
    n_inputs + n_consts + instrs.iter().map(|i| i.dsts().iter().flatten().count() as u32).sum::<u32>()
}
