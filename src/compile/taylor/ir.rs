//! The Taylor tape: a [`Tape`] renamed into single assignment with the auxiliary rows its
//! recurrences need, and the cheaper operations orders ≥ 1 run.

use std::fmt;

use crate::expr::Func;

use crate::compile::tape::{Instr, Tape};

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
    /// `d = asin a`, `acos a`, `asinh a` or `acosh a` (`kind`) with `r` the root of
    /// [`ArcKind::root`] (`√(1 − a²)`, `√(1 + a²)`, `√(a² − 1)`), so `r d' = ±a'` (`−` for `acos`).
    Asin {
        d: u32,
        a: u32,
        r: u32,
        kind: ArcKind,
    },
    /// `d = atan a` with `u = 1 + a²` (`hyp`: `atanh a` with `u = 1 − a²`), so `u d' = a'`.
    Atan {
        d: u32,
        a: u32,
        u: u32,
        hyp: bool,
    },
    /// `d = erf a` with `e = exp(−a²)` (its own rows), so `d' = (2/√π) e a'`.
    Erf {
        d: u32,
        a: u32,
        e: u32,
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
/// The inverse functions whose derivative is `±1/r` for the square root `r` of a quadratic in
/// their argument: one recurrence ([`Op::Asin`]) serves them all.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum ArcKind {
    Asin,
    Acos,
    Asinh,
    Acosh,
}

impl ArcKind {
    /// The function computed.
    pub(super) fn func(self) -> Func {
        match self {
            ArcKind::Asin => Func::Asin,
            ArcKind::Acos => Func::Acos,
            ArcKind::Asinh => Func::Asinh,
            ArcKind::Acosh => Func::Acosh,
        }
    }

    /// Whether `r² = ±1 + a²` (`asinh`: `1 + a²`, `acosh`: `a² − 1`) rather than `1 − a²`.
    pub(super) fn plus_square(self) -> bool {
        matches!(self, ArcKind::Asinh | ArcKind::Acosh)
    }

    /// `r = √(1 − x²)`, `√(1 + x²)` or `√(x² − 1)` at order 0; `acosh` takes `√(x − 1) √(x + 1)`,
    /// NaN exactly where `acosh` itself is (`x < 1`, also below `−1` where `x² − 1 > 0`).
    pub(super) fn root(self, x: f64) -> f64 {
        match self {
            ArcKind::Asin | ArcKind::Acos => (1.0 - x * x).sqrt(),
            ArcKind::Asinh => (1.0 + x * x).sqrt(),
            ArcKind::Acosh => (x - 1.0).sqrt() * (x + 1.0).sqrt(),
        }
    }

    /// Whether `r d' = −a'` (`acos`).
    pub(super) fn neg(self) -> bool {
        self == ArcKind::Acos
    }
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
            | Op::Erf { d, .. }
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
            Op::SinCos { a, .. }
            | Op::SinhCosh { a, .. }
            | Op::Exp { a, .. }
            | Op::Tan { a, .. }
            | Op::Erf { a, .. } => (Some(a), None, None),
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
            Op::PowConst { a, e, .. } | Op::Erf { a, e, .. } => (a, Some(e)),
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
/// A [`Tape`] in single-assignment form with the Taylor recurrence of each instruction.
///
/// Rows are laid out `inputs | constants | values`. A coefficient buffer holds `stride`
/// coefficients per row (`row · stride + k`), `stride > ` the highest order asked for.
#[derive(Clone, Debug)]
pub struct TaylorTape {
    pub(super) n_inputs: usize,
    pub(super) consts: Vec<f64>,
    /// Order 0: the tape's own operations, renamed, plus the auxiliary rows.
    pub(super) ops0: Vec<Op>,
    /// Orders ≥ 1: the recurrences, rewritten by `higher_order_ops`.
    pub(super) ops: Vec<Op>,
    pub(super) outputs: Vec<u32>,
    pub(super) n_rows: usize,
    /// The rows of the arguments of `abs` (whose sign must not change within a step).
    pub(super) abs_args: Vec<u32>,
    /// For each row, its weighted row (`j · x_j` at orders ≥ 1; order 0 is never read), if a
    /// recurrence weights it (`weigh_rows`).
    pub(super) weighted: Vec<Option<u32>>,
}

impl TaylorTape {
    /// The Taylor form of `tape`.
    pub fn new(tape: &Tape) -> TaylorTape {
        let n_inputs = tape.n_inputs();
        let mut consts = tape.consts().to_vec();
        // `sec`, `csc` and `coth` run as `1/cos`, `1/sin` and `1/tanh`, whose division reads a
        // row holding 1 (the tape's own, if it has one); the plain tape calls the function
        // itself, which computes the same quotient.
        let reciprocal = |f: Func| matches!(f, Func::Sec | Func::Csc | Func::Coth);
        let needs_one = tape.instrs().iter().any(|i| matches!(*i, Instr::Call { f, .. } if reciprocal(f)));
        let one = match consts.iter().position(|c| c.to_bits() == 1f64.to_bits()) {
            Some(i) => (n_inputs + i) as u32,
            None if needs_one => {
                consts.push(1.0);
                (n_inputs + consts.len() - 1) as u32
            }
            // Read by no operation.
            None => u32::MAX,
        };
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
                        Func::Asin => Op::Asin { d: d2, a, r: fresh(), kind: ArcKind::Asin },
                        Func::Acos => Op::Asin { d: d2, a, r: fresh(), kind: ArcKind::Acos },
                        Func::Asinh => Op::Asin { d: d2, a, r: fresh(), kind: ArcKind::Asinh },
                        Func::Acosh => Op::Asin { d: d2, a, r: fresh(), kind: ArcKind::Acosh },
                        Func::Atan => Op::Atan { d: d2, a, u: fresh(), hyp: false },
                        Func::Atanh => Op::Atan { d: d2, a, u: fresh(), hyp: true },
                        Func::Sec | Func::Csc => {
                            let (s, c) = (fresh(), fresh());
                            ops.push(Op::SinCos { s, c, a });
                            Op::Div { d: d2, a: one, b: if f == Func::Sec { c } else { s } }
                        }
                        Func::Erf => {
                            let (q, n, e) = (fresh(), fresh(), fresh());
                            ops.push(Op::Mul { d: q, a, b: a });
                            ops.push(Op::Neg { d: n, a: q });
                            ops.push(Op::Exp { d: e, a: n });
                            Op::Erf { d: d2, a, e }
                        }
                        Func::Coth => {
                            let t = fresh();
                            ops.push(Op::Tan { d: t, a, u: fresh(), hyp: true });
                            Op::Div { d: d2, a: one, b: t }
                        }
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

    /// Per row, whether its last coefficient of an expansion is read by nothing: one half of
    /// a sine–cosine (or sinh–cosh) pair that only its partner's recurrence reads, at later
    /// orders, and that is no output, no argument of `abs` and not weighted (the double
    /// pendulum's `cos θ₁` and `cos θ₂`, whose sines alone enter `F`). A whole expansion
    /// leaves these coefficients out at its last order (`TaylorEmitter::dead_at_last_order`).
    pub(super) fn dead_at_last_order(&self) -> Vec<bool> {
        let mut read = vec![false; self.n_rows];
        for &r in self.outputs.iter().chain(&self.abs_args) {
            read[r as usize] = true;
        }
        for op in &self.ops {
            for r in op.sources().chain(op.weighted_operands()) {
                read[r as usize] = true;
            }
        }
        let mut dead = vec![false; self.n_rows];
        for op in &self.ops {
            if let Op::SinCos { s, c, .. } | Op::SinhCosh { s, c, .. } = *op {
                for r in [s, c] {
                    dead[r as usize] = !read[r as usize] && self.weighted[r as usize].is_none();
                }
            }
        }
        dead
    }

    /// The value of a constant row (`None` for any other row).
    pub(super) fn row_constant(&self, r: u32) -> Option<f64> {
        (r as usize).checked_sub(self.n_inputs).and_then(|i| self.consts.get(i)).copied()
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

/// An `abs` met its kink (see [`TaylorTape::run_order`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct KinkAt;
