//! Batch expansions in machine code as wide as the host's vector registers: every coefficient
//! of the tape a vector of `B` lanes, 8 in one AVX-512 `zmm` register or 4 in one AVX2 `ymm`,
//! one instruction per operation for all the lanes of a batch.
//!
//! Why an emitter of our own beside Cranelift: Cranelift's x86-64 back end has vectors of 128
//! bits only, so the lane-pair code (`native.rs`) does two lanes per instruction, a quarter of
//! what an AVX-512 register holds; the batch expansion was most of a batch run's time
//! (BENCHMARKS.md, "The Taylor method's batch mode"). What the recurrences need is small: loads,
//! stores, the four IEEE operations, the square root and a sign flip, on whole vectors at
//! addresses known when the code is emitted. So this module encodes those few instructions
//! itself (Intel SDM vol. 2, the VEX and EVEX prefixes) and emits, per order, straight-line code
//! that keeps every value in the coefficient buffer between operations, as the interpreter does.
//!
//! The code is the interpreter's `run_order` for `Lanes<B>` written out (`interp.rs`): every
//! operation, every term of every sum and every partial sum in the same order, no fused
//! multiply-add. Each lane therefore gets the interpreter's bits, which are the single run's
//! (tests: `cargo test --test it taylor::batch`). Order 0 (the libm calls), the mass matrix's
//! solve and the state's coefficients between orders stay in Rust (`batch.rs`).

// Registers, rows and orders are small integers addressed by index, as the encoding is written.
#![allow(clippy::needless_range_loop)]

use std::collections::HashMap;

use super::ir::{Op, Weight};
use super::layout::BatchLayout;
use super::native::{unrolled_terms, MAX_NATIVE_TAYLOR_TERMS};
use super::TaylorTape;
use crate::lanes::Lanes;

/// What a batch expansion does between two orders of the tape (`TaylorOde::expand_lanes`):
/// the per-order solve of a `W q'' = F` system with `W₀`'s Cholesky factor, and the state's
/// next coefficients.
#[derive(Clone, Debug)]
pub(crate) struct Glue {
    /// Per state component, the row whose order `k` is its derivative's (a tape row, a state
    /// row, or an acceleration's row of the layout).
    pub(crate) derivs: Vec<u32>,
    pub(crate) solve: Option<GlueSolve>,
    pub(crate) layout: BatchLayout,
}

/// The solve of [`Glue`]: per row `i` of `W`, the row of `F_i` and the varying entries
/// (acceleration `l`, coefficient row `r`).
#[derive(Clone, Debug)]
pub(crate) struct GlueSolve {
    pub(crate) f: Vec<u32>,
    pub(crate) varying: Vec<Vec<(usize, u32)>>,
}

/// The vector operations the recurrences use (their opcodes in map `0F`, prefix `66`).
#[derive(Clone, Copy)]
enum V {
    Add,
    Sub,
    Mul,
    Div,
    /// The sign flip, as an XOR with `−0.0` (`vpxorq` for `zmm`, `vxorpd` for `ymm`).
    Xor,
}

/// The base register of a memory operand: the coefficient buffer or the constants.
#[derive(Clone, Copy)]
enum Base {
    /// `rdi`, the first argument (System V).
    Coefs,
    /// `rsi`, the second argument.
    Consts,
}

impl Base {
    fn reg(self) -> u8 {
        match self {
            Base::Coefs => 7,
            Base::Consts => 6,
        }
    }
}

/// An operand in the second source's place: a register or `[base + disp32]`.
#[derive(Clone, Copy)]
enum Rm {
    Reg(u8),
    Mem(Base, u32),
}

/// The x86-64 encoder of the few instructions the emitter uses, for `zmm` (EVEX, 512 bits) or
/// `ymm` (VEX, 256 bits) registers 0–15. Memory operands are `[rdi + disp32]` or
/// `[rsi + disp32]` (ModRM `mod = 10`: an unscaled 32-bit displacement in both encodings).
struct Asm {
    code: Vec<u8>,
    zmm: bool,
}

impl Asm {
    fn opcode(op: V, zmm: bool) -> u8 {
        match op {
            V::Add => 0x58,
            V::Mul => 0x59,
            V::Sub => 0x5C,
            V::Div => 0x5E,
            V::Xor if zmm => 0xEF,
            V::Xor => 0x57,
        }
    }

    /// The prefix, opcode, ModRM and displacement of `opcode reg, vvvv, rm` (`vvvv` 0 when the
    /// instruction has no second source).
    fn emit(&mut self, opcode: u8, reg: u8, vvvv: u8, rm: Rm) {
        debug_assert!(reg < 16 && vvvv < 16);
        let r = (reg >> 3) & 1;
        let b = match rm {
            Rm::Reg(x) => (x >> 3) & 1,
            Rm::Mem(..) => 0,
        };
        let v = !vvvv & 0xF;
        if self.zmm {
            // EVEX: 62, P0 = R̄ X̄ B̄ R̄' 0 0 m m (map 0F = 01), P1 = W v̄v̄v̄v̄ 1 p p (W1, 66 = 01),
            // P2 = z L'L b V̄' a a a (512 bits = 10, no mask).
            self.code.push(0x62);
            self.code.push(((1 - r) << 7) | (1 << 6) | ((1 - b) << 5) | (1 << 4) | 0b01);
            self.code.push((1 << 7) | (v << 3) | (1 << 2) | 0b01);
            self.code.push(0b0100_1000);
        } else {
            // Three-byte VEX: C4, R̄ X̄ B̄ m-mmmm (map 0F = 00001), W v̄v̄v̄v̄ L p p (256 bits, 66).
            self.code.push(0xC4);
            self.code.push(((1 - r) << 7) | (1 << 6) | ((1 - b) << 5) | 0b00001);
            self.code.push((v << 3) | (1 << 2) | 0b01);
        }
        self.code.push(opcode);
        match rm {
            Rm::Reg(x) => self.code.push(0xC0 | ((reg & 7) << 3) | (x & 7)),
            Rm::Mem(base, disp) => {
                self.code.push(0x80 | ((reg & 7) << 3) | base.reg());
                self.code.extend_from_slice(&disp.to_le_bytes());
            }
        }
    }

    /// `d = a op b`.
    fn op(&mut self, op: V, d: u8, a: u8, b: Rm) {
        let code = Asm::opcode(op, self.zmm);
        self.emit(code, d, a, b);
    }

    /// `vmovupd d, a` (a load, or a register copy).
    fn load(&mut self, d: u8, a: Rm) {
        self.emit(0x10, d, 0, a);
    }

    /// `vmovupd [base + disp], a`.
    fn store(&mut self, base: Base, disp: u32, a: u8) {
        self.emit(0x11, a, 0, Rm::Mem(base, disp));
    }

    /// `vzeroupper; ret`.
    fn ret(&mut self) {
        self.code.extend_from_slice(&[0xC5, 0xF8, 0x77, 0xC3]);
    }
}

/// Registers 0–3 hold a sum's partial sums and 4–7 its terms; 8–14 hold an operation's values
/// across its sums, and 15 the weighted copy of a value being stored.
const WEIGHTED_TMP: u8 = 15;

/// The emitter of one order's code: `run_order` for `Lanes<B>`, instruction for instruction.
struct Emitter<'t> {
    asm: Asm,
    tape: &'t TaylorTape,
    stride: usize,
    /// Bytes per coefficient in the buffer (`Lanes<B>`'s size: 64, its alignment, for both
    /// widths) and per constant (a vector: 64 or 32).
    slot: usize,
    vb: usize,
    /// The constants' vectors (each splat over the lanes), by their bits.
    consts: Vec<f64>,
    index: HashMap<u64, u32>,
}

impl Emitter<'_> {
    fn at(&self, row: u32, j: usize) -> Rm {
        self.slot_at(row as usize * self.stride + j)
    }

    /// Entry `i` of the buffer.
    fn slot_at(&self, i: usize) -> Rm {
        Rm::Mem(Base::Coefs, self.disp(i))
    }

    /// The displacement of entry `i` (`compile` checks that every entry's fits 31 bits).
    fn disp(&self, i: usize) -> u32 {
        (i * self.slot) as u32
    }

    fn store_at(&mut self, i: usize, v: u8) {
        let disp = self.disp(i);
        self.asm.store(Base::Coefs, disp, v);
    }

    fn konst(&mut self, x: f64) -> Rm {
        let n = self.index.len() as u32;
        let i = *self.index.entry(x.to_bits()).or_insert(n);
        if i == n {
            self.consts.push(x);
        }
        Rm::Mem(Base::Consts, i * self.vb as u32)
    }

    fn load_at(&mut self, d: u8, row: u32, j: usize) {
        let a = self.at(row, j);
        self.asm.load(d, a);
    }

    fn load_const(&mut self, d: u8, x: f64) {
        let a = self.konst(x);
        self.asm.load(d, a);
    }

    /// `d = a op x` for a constant `x`.
    fn op_const(&mut self, op: V, d: u8, a: u8, x: f64) {
        let k = self.konst(x);
        self.asm.op(op, d, a, k);
    }

    /// `d = a op row_j`.
    fn op_at(&mut self, op: V, d: u8, a: u8, row: u32, j: usize) {
        let m = self.at(row, j);
        self.asm.op(op, d, a, m);
    }

    /// `d = −a`.
    fn neg(&mut self, d: u8, a: u8) {
        self.op_const(V::Xor, d, a, -0.0);
    }

    /// Writes order `k` of row `r` from register `v` and, if `r` has one, of its weighted row
    /// (`v · k`), as the interpreter's `put`.
    fn put(&mut self, r: u32, k: usize, v: u8) {
        self.store_at(r as usize * self.stride + k, v);
        if let Some(w) = self.tape.weighted_row(r) {
            self.op_const(V::Mul, WEIGHTED_TMP, v, k as f64);
            self.store_at(w as usize * self.stride + k, WEIGHTED_TMP);
        }
    }

    /// `d = Σ_{i<n} w_i x_{xo+i} y_{yo+n−1−i}`, the interpreter's `sum4`: the terms that read
    /// order `k` (`late_first`, `late_last`) last, the others round-robin into four partial
    /// sums combined as `(s₀ + s₁) + (s₂ + s₃)`. A partial sum that gets no term is the
    /// interpreter's `−0.0`, the identity of IEEE addition, so it is left out.
    #[allow(clippy::too_many_arguments)] // the sum's two rows, offsets, length, weight and ends
    fn sum4(&mut self, d: u8, x: (u32, usize), y: (u32, usize), n: usize, w: Weight, k: usize, late: (bool, bool)) {
        let lo = usize::from(late.0 && n > 0);
        let hi = if late.1 && n > lo { n - 1 } else { n };
        // Term `i` into register `r`: `(w_i · x_i) · y_{n−1−i}`; a unit weight is left out
        // (`1 · x = x` exactly).
        let term = |e: &mut Self, r: u8, i: usize| {
            match w {
                Weight::One => e.load_at(r, x.0, x.1 + i),
                Weight::Power(_) => {
                    e.load_const(r, w.at(i, k));
                    e.op_at(V::Mul, r, r, x.0, x.1 + i);
                }
            }
            e.op_at(V::Mul, r, r, y.0, y.1 + n - 1 - i);
        };
        let mut have = [false; 4];
        for i in lo..hi {
            let p = ((i - lo) % 4) as u8;
            if have[p as usize] {
                term(self, 4 + p, i);
                self.asm.op(V::Add, p, p, Rm::Reg(4 + p));
            } else {
                term(self, p, i);
                have[p as usize] = true;
            }
        }
        let pair = |e: &mut Self, a: u8, b: u8| match (have[a as usize], have[b as usize]) {
            (true, true) => {
                e.asm.op(V::Add, a, a, Rm::Reg(b));
                Some(a)
            }
            (true, false) => Some(a),
            (false, true) => Some(b),
            (false, false) => None,
        };
        let (l, r) = (pair(self, 0, 1), pair(self, 2, 3));
        let mut s = match (l, r) {
            (Some(a), Some(b)) => {
                self.asm.op(V::Add, a, a, Rm::Reg(b));
                Some(a)
            }
            (a, b) => a.or(b),
        };
        for i in [(lo == 1).then_some(0), (hi < n).then(|| n - 1)].into_iter().flatten() {
            match s {
                Some(a) => {
                    term(self, 4, i);
                    self.asm.op(V::Add, a, a, Rm::Reg(4));
                }
                None => {
                    term(self, 0, i);
                    s = Some(0);
                }
            }
        }
        match s {
            Some(a) => self.asm.load(d, Rm::Reg(a)),
            None => self.load_const(d, -0.0),
        }
    }

    /// `Σ_{j=0}^{k} a_j b_{k−j}`.
    fn cauchy(&mut self, d: u8, a: u32, b: u32, k: usize) {
        self.sum4(d, (a, 0), (b, 0), k + 1, Weight::One, k, (true, true));
    }

    /// `Σ_{j=1}^{k} j a_j b_{k−j}` from `a`'s weighted row `wa`.
    fn weighted(&mut self, d: u8, wa: u32, b: u32, k: usize) {
        self.sum4(d, (wa, 1), (b, 0), k, Weight::One, k, (false, true));
    }

    /// `Σ_{j=1}^{k−1} j a_j b_{k−j}` from `a`'s weighted row `wa`.
    fn weighted_short(&mut self, d: u8, wa: u32, b: u32, k: usize) {
        if k < 2 {
            self.load_const(d, -0.0);
        } else {
            self.sum4(d, (wa, 1), (b, 1), k - 1, Weight::One, k, (false, false));
        }
    }

    /// `2 Σ_{1≤j<k−j} a_j a_{k−j} + a_{k/2}²` (the last term for even `k` only, else `+ 0`).
    fn square_inner(&mut self, d: u8, a: u32, k: usize) {
        let n = k.div_ceil(2) - 1;
        self.sum4(d, (a, 1), (a, k - n), n, Weight::One, k, (false, false));
        self.load_const(4, 2.0);
        self.asm.op(V::Mul, 4, 4, Rm::Reg(d));
        if k % 2 == 0 {
            self.load_at(5, a, k / 2);
            self.op_at(V::Mul, 5, 5, a, k / 2);
        } else {
            self.load_const(5, 0.0);
        }
        self.asm.op(V::Add, d, 4, Rm::Reg(5));
    }

    /// `Σ_{j=0}^{k} a_j a_{k−j}`: the inner sum, then `(2 a₀) · a_k`.
    fn square(&mut self, d: u8, a: u32, k: usize) {
        self.square_inner(d, a, k);
        self.load_const(4, 2.0);
        self.op_at(V::Mul, 4, 4, a, 0);
        self.op_at(V::Mul, 4, 4, a, k);
        self.asm.op(V::Add, d, d, Rm::Reg(4));
    }

    /// `d = 1 / (f · row₀)` (`f = 1`: `1 / row₀`).
    fn reciprocal(&mut self, d: u8, f: Option<f64>, row: u32) {
        self.load_const(d, 1.0);
        match f {
            None => self.op_at(V::Div, d, d, row, 0),
            Some(f) => {
                self.load_const(4, f);
                self.op_at(V::Mul, 4, 4, row, 0);
                self.asm.op(V::Div, d, d, Rm::Reg(4));
            }
        }
    }

    /// `d = (x_k − acc / k) · (1/row₀)` with `acc` in register `acc` (the quotient
    /// recurrences of `log`, `atan`, `asin` and `pow`); `neg`: `−x_k`.
    fn quotient(&mut self, d: u8, x: u32, neg: bool, acc: u8, row: u32, k: usize) {
        self.load_at(d, x, k);
        if neg {
            self.neg(d, d);
        }
        self.op_const(V::Mul, acc, acc, 1.0 / k as f64);
        self.asm.op(V::Sub, d, d, Rm::Reg(acc));
        self.reciprocal(13, None, row);
        self.asm.op(V::Mul, d, d, Rm::Reg(13));
    }

    /// `d = Σ (e j − (k − j)) a_j d_{k−j} / (k a₀)` (`constant_power`).
    fn constant_power(&mut self, v: u8, a: u32, d: u32, e: f64, k: usize) {
        self.sum4(v, (a, 1), (d, 0), k, Weight::Power(e), k, (false, true));
        self.reciprocal(13, Some(k as f64), a);
        self.asm.op(V::Mul, v, v, Rm::Reg(13));
    }

    /// What `expand_lanes` does after order `k` of the tape when every lane's `W₀` has a
    /// Cholesky factor: the right-hand side `F_k − Σ W_j a_{k−j}`, the two substitutions of
    /// `cholesky_solve`, the accelerations' order `k`, and the state's order `k + 1`, with the
    /// same operations in the same order.
    fn glue(&mut self, g: &Glue, k: usize) {
        let ly = g.layout;
        if let Some(GlueSolve { f, varying }) = &g.solve {
            let n = f.len();
            for i in 0..n {
                self.load_at(8, f[i], k);
                for &(l, r) in &varying[i] {
                    let acc = ly.acc_row(l) as u32;
                    self.sum4(9, (r, 1), (acc, 0), k, Weight::One, k, (false, true));
                    self.asm.op(V::Sub, 8, 8, Rm::Reg(9));
                }
                self.store_at(ly.rhs(i), 8);
            }
            let forward: Vec<(usize, Vec<usize>)> = (0..n).map(|i| (i, (0..i).map(|j| i * n + j).collect())).collect();
            let backward = (0..n).rev().map(|i| (i, (i + 1..n).map(|j| j * n + i).collect::<Vec<_>>()));
            for (i, entries) in forward.into_iter().chain(backward) {
                self.asm.load(8, self.slot_at(ly.rhs(i)));
                for e in entries {
                    // The entry `(i, j)` or `(j, i)` times `x_j`, `j` the entry's other index.
                    let j = if e / n == i { e % n } else { e / n };
                    self.asm.load(9, self.slot_at(ly.factor(e)));
                    self.asm.op(V::Mul, 9, 9, self.slot_at(ly.rhs(j)));
                    self.asm.op(V::Sub, 8, 8, Rm::Reg(9));
                }
                self.asm.op(V::Mul, 8, 8, self.slot_at(ly.inv(i)));
                self.store_at(ly.rhs(i), 8);
            }
            for i in 0..n {
                self.asm.load(8, self.slot_at(ly.rhs(i)));
                self.store_at(ly.acc(i, k), 8);
            }
        }
        for (i, &r) in g.derivs.iter().enumerate() {
            self.load_at(8, r, k);
            self.op_const(V::Mul, 8, 8, 1.0 / (k + 1) as f64);
            self.store_at(i * self.stride + k + 1, 8);
        }
    }

    /// Order `k` of operation `op`; `None` for an operation this emitter does not take (`abs`,
    /// a constant power of a non-constant row), whose tape then has no wide code.
    fn order(&mut self, op: &Op, k: usize) -> Option<()> {
        let rk = 1.0 / k as f64;
        match *op {
            Op::Weigh { d, a } => {
                self.load_at(8, a, k);
                self.op_const(V::Mul, 8, 8, k as f64);
                self.put(d, k, 8);
            }
            Op::Add { d, a, b } | Op::Sub { d, a, b } => {
                self.load_at(8, a, k);
                let v = if matches!(op, Op::Add { .. }) { V::Add } else { V::Sub };
                self.op_at(v, 8, 8, b, k);
                self.put(d, k, 8);
            }
            Op::Neg { d, a } => {
                self.load_at(8, a, k);
                self.neg(8, 8);
                self.put(d, k, 8);
            }
            Op::Scale { d, a, f } => {
                self.load_at(8, a, k);
                self.op_const(V::Mul, 8, 8, f);
                self.put(d, k, 8);
            }
            Op::Mul { d, a, b } => {
                self.cauchy(8, a, b, k);
                self.put(d, k, 8);
            }
            Op::Sqr { d, a } => {
                self.square(8, a, k);
                self.put(d, k, 8);
            }
            Op::Div { d, a, b } => {
                self.sum4(9, (b, 1), (d, 0), k, Weight::One, k, (false, true));
                self.load_at(8, a, k);
                self.asm.op(V::Sub, 8, 8, Rm::Reg(9));
                self.reciprocal(13, None, b);
                self.asm.op(V::Mul, 8, 8, Rm::Reg(13));
                self.put(d, k, 8);
            }
            Op::Sqrt { d, a } => {
                self.square_inner(9, d, k);
                self.load_at(8, a, k);
                self.asm.op(V::Sub, 8, 8, Rm::Reg(9));
                self.reciprocal(13, Some(2.0), d);
                self.asm.op(V::Mul, 8, 8, Rm::Reg(13));
                self.put(d, k, 8);
            }
            Op::SinCos { s, c, a } | Op::SinhCosh { s, c, a } => {
                let wa = self.tape.weighted_row(a)?;
                self.weighted(8, wa, c, k);
                self.op_const(V::Mul, 8, 8, rk);
                self.weighted(9, wa, s, k);
                self.op_const(V::Mul, 9, 9, rk);
                self.put(s, k, 8);
                let sign = if matches!(op, Op::SinCos { .. }) { -1.0 } else { 1.0 };
                self.load_const(10, sign);
                self.asm.op(V::Mul, 9, 10, Rm::Reg(9));
                self.put(c, k, 9);
            }
            Op::Exp { d, a } => {
                let wa = self.tape.weighted_row(a)?;
                self.weighted(8, wa, d, k);
                self.op_const(V::Mul, 8, 8, rk);
                self.put(d, k, 8);
            }
            Op::Log { d, a } => {
                let wd = self.tape.weighted_row(d)?;
                self.weighted_short(9, wd, a, k);
                self.quotient(8, a, false, 9, a, k);
                self.put(d, k, 8);
            }
            Op::Tan { d, a, u, hyp } => {
                let wa = self.tape.weighted_row(a)?;
                self.weighted(8, wa, u, k);
                self.op_const(V::Mul, 8, 8, rk);
                self.put(d, k, 8);
                self.square(9, d, k);
                if hyp {
                    self.neg(9, 9);
                }
                self.put(u, k, 9);
            }
            Op::Asin { d, a, r, kind } => {
                self.square(10, a, k);
                if !kind.plus_square() {
                    self.neg(10, 10);
                }
                self.square_inner(11, r, k);
                self.asm.op(V::Sub, 10, 10, Rm::Reg(11));
                self.reciprocal(12, Some(2.0), r);
                self.asm.op(V::Mul, 10, 10, Rm::Reg(12));
                let wd = self.tape.weighted_row(d)?;
                self.weighted_short(9, wd, r, k);
                self.quotient(8, a, kind.neg(), 9, r, k);
                self.put(r, k, 10);
                self.put(d, k, 8);
            }
            Op::Atan { d, a, u, hyp } => {
                self.square(10, a, k);
                if hyp {
                    self.neg(10, 10);
                }
                let wd = self.tape.weighted_row(d)?;
                self.weighted_short(9, wd, u, k);
                self.quotient(8, a, false, 9, u, k);
                self.put(u, k, 10);
                self.put(d, k, 8);
            }
            Op::Erf { d, a, e } => {
                let wa = self.tape.weighted_row(a)?;
                self.weighted(8, wa, e, k);
                self.op_const(V::Mul, 8, 8, rk);
                self.op_const(V::Mul, 8, 8, std::f64::consts::FRAC_2_SQRT_PI);
                self.put(d, k, 8);
            }
            Op::Atan2 { d, a, b, u } => {
                self.square(10, a, k);
                self.square(11, b, k);
                self.asm.op(V::Add, 10, 10, Rm::Reg(11));
                let (wa, wb, wd) = (self.tape.weighted_row(a)?, self.tape.weighted_row(b)?, self.tape.weighted_row(d)?);
                self.weighted(8, wa, b, k);
                self.weighted(9, wb, a, k);
                self.asm.op(V::Sub, 8, 8, Rm::Reg(9));
                self.weighted_short(9, wd, u, k);
                self.asm.op(V::Sub, 8, 8, Rm::Reg(9));
                self.reciprocal(13, Some(k as f64), u);
                self.asm.op(V::Mul, 8, 8, Rm::Reg(13));
                self.put(u, k, 10);
                self.put(d, k, 8);
            }
            Op::Root { d, a, q } => {
                self.constant_power(8, a, d, 1.0 / f64::from(q), k);
                self.put(d, k, 8);
            }
            Op::PowConst { d, a, e } => {
                let e = self.tape.row_constant(e)?;
                self.constant_power(8, a, d, e, k);
                self.put(d, k, 8);
            }
            Op::Power { d, a, e } => {
                self.constant_power(8, a, d, e, k);
                self.put(d, k, 8);
            }
            Op::PowVar { d, a, b, l, m } => {
                let wl = self.tape.weighted_row(l)?;
                self.weighted_short(9, wl, a, k);
                self.quotient(8, a, false, 9, a, k);
                self.put(l, k, 8);
                self.cauchy(8, b, l, k);
                self.put(m, k, 8);
                let wm = self.tape.weighted_row(m)?;
                self.weighted(8, wm, d, k);
                self.op_const(V::Mul, 8, 8, rk);
                self.put(d, k, 8);
            }
            Op::Abs { .. } => return None,
        }
        Some(())
    }
}

/// Wide machine code for orders `1..=max_order` of a tape's recurrences over `lanes` lanes
/// (`Lanes<lanes>` coefficient buffers of a fixed stride): one entry point per order.
pub(crate) struct WideTaylor {
    code: ExecutableCode,
    /// `entries[k − 1]`: the offsets of order `k`'s recurrences and of its glue.
    entries: Vec<(usize, usize)>,
    /// The constants, each splat over the lanes, at the address the code reads them from.
    consts: Vec<f64>,
    lanes: usize,
    /// The length of the buffers it runs on.
    len: usize,
}

impl std::fmt::Debug for WideTaylor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("WideTaylor")
            .field("lanes", &self.lanes)
            .field("orders", &self.entries.len())
            .field("bytes", &self.code.len)
            .finish()
    }
}

impl WideTaylor {
    /// The code for `lanes` lanes (8: AVX-512F, 4: AVX2) of orders `1..=max_order`, if the host
    /// has those registers, the tape has only operations the emitter takes and at most
    /// `MAX_NATIVE_TAYLOR_TERMS` terms unrolled, and the system lets code be mapped executable.
    pub(crate) fn compile(tape: &TaylorTape, glue: &Glue, max_order: usize, lanes: usize) -> Option<WideTaylor> {
        let stride = glue.layout.stride;
        // Past the lane-pair code's size the unrolled code no longer fits the instruction
        // cache; such tapes batch on the interpreter's lanes.
        let too_large = unrolled_terms(tape, max_order) > MAX_NATIVE_TAYLOR_TERMS;
        if !host_has(lanes) || too_large || max_order >= stride || glue.layout.rows != tape.n_rows() {
            return None;
        }
        let (vb, slot) = (lanes * 8, std::mem::size_of::<Lanes<8>>());
        let mut e = Emitter {
            asm: Asm { code: Vec::new(), zmm: lanes == 8 },
            tape,
            stride,
            slot,
            vb,
            consts: Vec::new(),
            index: HashMap::new(),
        };
        let mut entries = Vec::with_capacity(max_order);
        for k in 1..=max_order {
            let tape_at = e.asm.code.len();
            for op in tape.ops() {
                e.order(op, k)?;
            }
            e.asm.ret();
            let glue_at = e.asm.code.len();
            e.glue(glue, k);
            e.asm.ret();
            entries.push((tape_at, glue_at));
        }
        // Displacements are 32-bit: a buffer past 2 GiB has no code.
        let span = glue.layout.len() * slot;
        if span > i32::MAX as usize || e.consts.len() * vb > i32::MAX as usize {
            return None;
        }
        let consts = e.consts.iter().flat_map(|&x| std::iter::repeat(x).take(lanes)).collect();
        let code = ExecutableCode::new(&e.asm.code)?;
        Some(WideTaylor { code, entries, consts, lanes, len: glue.layout.len() })
    }

    /// The number of lanes.
    pub(crate) fn lanes(&self) -> usize {
        self.lanes
    }

    /// Computes order `k` (`1..=max_order`) of every row of the tape in `c` (the
    /// interpreter's `run_order`, with the same bits in every lane).
    pub(crate) fn run_order<const B: usize>(&self, c: &mut [Lanes<B>], k: usize) {
        self.call(c, self.entries[k - 1].0);
    }

    /// `expand_lanes`' work after order `k` of the tape, when every lane's `W₀` has a
    /// Cholesky factor (see `Emitter::glue`).
    pub(crate) fn run_glue<const B: usize>(&self, c: &mut [Lanes<B>], k: usize) {
        self.call(c, self.entries[k - 1].1);
    }

    fn call<const B: usize>(&self, c: &mut [Lanes<B>], entry: usize) {
        assert!(
            B == self.lanes && std::mem::size_of::<Lanes<B>>() == std::mem::size_of::<Lanes<8>>(),
            "wide Taylor code of {} lanes run on {B}",
            self.lanes
        );
        assert!(c.len() >= self.len, "wide Taylor buffer too short");
        // SAFETY: the code at `entry` was emitted above for this buffer's layout and width: it
        // reads and writes `c` only below `len` entries (checked just above), reads only
        // `consts`, and uses only the vector registers the host has (`host_has`, checked when
        // compiled) and those the System V convention lets a callee clobber.
        unsafe {
            let f: extern "sysv64" fn(*mut f64, *const f64) = std::mem::transmute(self.code.ptr.add(entry));
            f(c.as_mut_ptr().cast(), self.consts.as_ptr());
        }
    }
}

/// Whether the host has the vector registers of `lanes` lanes (4 or 8) and runs the code's
/// calling convention: [`simd_lanes`](crate::compile::simd_lanes) at least `lanes`, on x86-64
/// Unix.
fn host_has(lanes: usize) -> bool {
    cfg!(all(target_arch = "x86_64", unix)) && matches!(lanes, 4 | 8) && crate::compile::simd_lanes() >= lanes
}

/// Machine code in pages mapped readable and executable (never writable and executable at
/// once), unmapped when dropped.
struct ExecutableCode {
    ptr: *const u8,
    len: usize,
}

// SAFETY: the mapping is immutable once made; only `Drop` unmaps it.
unsafe impl Send for ExecutableCode {}
// SAFETY: as above.
unsafe impl Sync for ExecutableCode {}

impl ExecutableCode {
    #[cfg(unix)]
    fn new(bytes: &[u8]) -> Option<ExecutableCode> {
        let len = bytes.len().max(1);
        // SAFETY: a fresh anonymous private mapping of `len` bytes, written while it is
        // writable only, then made read-and-execute; on any failure it is unmapped.
        unsafe {
            let p = libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                -1,
                0,
            );
            if p == libc::MAP_FAILED {
                return None;
            }
            std::ptr::copy_nonoverlapping(bytes.as_ptr(), p.cast::<u8>(), bytes.len());
            if libc::mprotect(p, len, libc::PROT_READ | libc::PROT_EXEC) != 0 {
                libc::munmap(p, len);
                return None;
            }
            Some(ExecutableCode { ptr: p.cast::<u8>().cast_const(), len })
        }
    }

    #[cfg(not(unix))]
    fn new(_: &[u8]) -> Option<ExecutableCode> {
        None
    }
}

impl Drop for ExecutableCode {
    fn drop(&mut self) {
        #[cfg(unix)]
        // SAFETY: `ptr` and `len` are the mapping `new` made, unmapped only here.
        unsafe {
            libc::munmap(self.ptr.cast_mut().cast(), self.len);
        }
    }
}

/// The encoder's bytes for a fixed list of instructions, in the `zmm` and the `ymm` forms, for
/// the test that checks them against an assembler's (`tests/it/taylor/batch.rs`).
#[doc(hidden)]
pub fn wide_encoding_samples() -> [Vec<u8>; 2] {
    let mut z = Asm { code: vec![], zmm: true };
    z.op(V::Add, 1, 2, Rm::Reg(3));
    z.op(V::Mul, 9, 10, Rm::Mem(Base::Coefs, 0x100));
    z.load(12, Rm::Mem(Base::Consts, 0x40));
    z.store(Base::Coefs, 0x80, 15);
    z.op(V::Xor, 8, 8, Rm::Mem(Base::Consts, 0));
    z.op(V::Div, 13, 13, Rm::Reg(11));
    let mut y = Asm { code: vec![], zmm: false };
    y.op(V::Sub, 1, 2, Rm::Reg(3));
    y.load(9, Rm::Mem(Base::Coefs, 0x20));
    y.op(V::Xor, 0, 0, Rm::Mem(Base::Consts, 0x20));
    y.store(Base::Coefs, 0x20, 12);
    y.op(V::Mul, 10, 11, Rm::Reg(12));
    y.ret();
    [z.code, y.code]
}
