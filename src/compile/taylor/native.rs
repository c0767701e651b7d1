//! The Taylor back end: the recurrences of a [`TaylorTape`] compiled to machine code with
//! Cranelift, unrolled per order, as one whole expansion, or compact (one function for every
//! order); the coefficients are the interpreter's, bit for bit (`tests/it/taylor/native.rs`).

use std::mem::ManuallyDrop;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::Arc;

use cranelift_codegen::ir::condcodes::{FloatCC, IntCC};
use cranelift_codegen::ir::{types, AbiParam, InstBuilder, MemFlags, StackSlot, Value};
use cranelift_codegen::isa::CallConv;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_module::{Linkage, Module};

use crate::expr::Func;

use super::ir::{ArcKind, KinkAt, Op, Weight};
use super::TaylorTape;
use crate::compile::jit::{atan2, call_f64, call_sin_cos, host_module, powf, real_root, wrapper, OwnedModule};
use crate::compile::tape::MAX_NATIVE_INSTRS;

/// What a whole expansion does after the recurrences of each order `k = 1..=max_order`, as
/// `TaylorOde::expand` does between orders: for `W q'' = F`, solve for order `k` of the
/// accelerations; then `c[dst, k + 1] = c[src, k] · (1/(k + 1))` for every `(dst, src)` of
/// `glue` (state row, row of its derivative).
pub(crate) struct Expansion {
    pub glue: Vec<(u32, u32)>,
    pub solve: Option<CholeskySolve>,
    /// Where the rows' mirror images start in the buffer ([`TaylorEmitter::pair`]): row `r`'s
    /// coefficient `j` also at `mirror_at + r · stride + (stride − 1 − j)`.
    pub mirror_at: usize,
    /// The length of the buffer the expansion reads and writes (`TaylorOde::scratch_len`,
    /// which owns the layout).
    pub len: usize,
}
/// Order `k` of the accelerations `a` of `W q'' = F`, from `W₀ a_k = F_k − Σ_{j≥1} W_j a_{k−j}`
/// with `W₀ = L Lᵀ` factored at order 0 (by `linalg::factor`, in the buffer after the rows). The
/// accelerations are rows `acc_row + l` of the buffer.
pub(crate) struct CholeskySolve {
    pub n: usize,
    /// The row of `F_i`.
    pub f_rows: Vec<u32>,
    /// Per `i`, the varying entries of row `i` of `W`: `(l, row of W_il)`.
    pub varying: Vec<Vec<(usize, u32)>>,
    pub acc_row: u32,
    /// Where `L` starts in the buffer (`L_ij` at `factor_at + i n + j`).
    pub factor_at: usize,
    /// The row of every entry `W_ij` (`i n + j`), for the factorisation at order 0.
    pub w_rows: Vec<u32>,
}
/// What a whole expansion's return value means: bit 0, an `abs` met its kink; bit 1, `W₀` was
/// not finite or not positive definite, so the rest is garbage and the interpreter must redo
/// the expansion (and choose LU, or report the error).
const STATUS_KINK: i32 = 1;
const STATUS_REDO: i32 = 2;
/// One slot of lane-pair code's buffer ([`NativeTaylor::compile_lanes`]): lane 0's and lane 1's
/// value. Aligned as an `F64X2`, because the generated loads and stores say they are aligned
/// (and may become SSE memory operands, which must be).
#[derive(Clone, Copy, Debug, Default, PartialEq)]
#[repr(C, align(16))]
pub(crate) struct LanePair(pub [f64; 2]);
/// How a whole native expansion ended ([`NativeTaylor::run_expansion`]).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Ran {
    Done,
    Kink,
    /// `W₀` needs the interpreter (see [`STATUS_REDO`]).
    Redo,
}
/// The signature of generated Taylor code, every form: `fn(c: *mut f64, arg: usize) -> i32`,
/// computing in place in the coefficient buffer `c` and returning its status
/// ([`STATUS_KINK`], and for a whole expansion [`STATUS_REDO`]). `arg` is the order `k` for
/// compact code (one function for every order) and [`WINDOW_BYTES`] for unrolled code (see
/// [`TaylorEmitter::window`]).
type TaylorFn = unsafe extern "C" fn(*mut f64, usize) -> i32;
/// The lowest order whose whole expansion sums two terms at once ([`TaylorEmitter::pair`]).
/// Each sum pays two lane extractions and each coefficient a store to its mirror, which the
/// halved multiplications repay once sums are long: the double pendulum at orders 13–20 ran
/// 3–12 % faster with pairs, at order 11 the same and at order 8 3 % slower, and the chaos
/// map's variational system at order 12 2 % slower.
const PAIRS_FROM_ORDER: usize = 13;
/// The span of the buffer one base register of unrolled code reaches with a one-byte
/// displacement (`−128..=127` around it): see [`TaylorEmitter::window`].
const WINDOW_BYTES: usize = 256;
/// How many base registers unrolled code keeps (for the first 3 kB of its buffer): each one
/// is live through the whole function, and more would crowd out the registers of larger
/// tapes (the 5-link pendulum, a 26 kB buffer at order 19, ran 3–4 % slower with a base
/// register every 256 bytes).
const MAX_WINDOWS: usize = 12;
/// How many orders unrolled code keeps in SSA values (see [`TaylorEmitter::at`]): `k` and
/// `k − 1` when at most [`SSA_TWO_ORDERS_MAX_ROWS`] rows are written per order, else `k` alone.
///
/// An SSA value of order `k − 1` is read at order `k` once for each sum it appears in, so
/// with many rows per order those values outnumber the 16 vector registers, and Cranelift
/// spills them to the stack, a second copy of what the buffer already holds. Reading them
/// from the buffer instead, per expansion: double pendulum (24 rows per order) 8–13 % faster
/// at orders 11–19, 3-link pendulum 2246 → 2035 ns, 5-link 8376 → 7246 ns, the chaos map's
/// variational system 2553 → 2404 ns; Kepler (10 rows) 2 % slower, so it keeps both.
fn ssa_orders(tape: &TaylorTape, expansion: Option<&Expansion>) -> usize {
    let rows = tape.rows_per_order() + expansion.map_or(0, |g| g.glue.len() + g.solve.as_ref().map_or(0, |m| m.n));
    if rows <= SSA_TWO_ORDERS_MAX_ROWS {
        2
    } else {
        1
    }
}
/// See [`ssa_orders`].
const SSA_TWO_ORDERS_MAX_ROWS: usize = 12;
/// How a [`NativeTaylor`] lays the recurrences out in machine code.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Form {
    /// One straight-line function per order.
    PerOrder,
    /// One straight-line function for a whole expansion ([`NativeTaylor::compile_expansion`]).
    Whole,
    /// One function for every order, the order its argument and each sum a loop
    /// ([`NativeTaylor::compile_compact`]).
    Compact,
}
/// Machine code for the Taylor recurrences of one [`TaylorTape`](TaylorTape) at a fixed
/// stride: one straight-line function per order `k = 1..=max_order` (order 0, which calls the
/// transcendental functions, stays in the interpreter).
///
/// Why unrolled: at a fixed order every index of every Cauchy sum is a constant, so each
/// term is two loads at constant offsets, a multiply and an add, with no loop counter, no
/// bounds check and no instruction dispatch; and because the code is one basic block, the
/// processor overlaps the dependency chains of independent instructions (the interpreter runs
/// one sum after the other, each a chain of dependent additions). Each sum adds its terms
/// in the interpreter's order with the interpreter's operations (Cranelift does not
/// reassociate or fuse), so the coefficients are the interpreter's, bit for bit.
///
/// A first-order ODE can instead have its whole expansion in one function
/// ([`NativeTaylor::compile_expansion`]): orders `1..=max_order` each followed by the step
/// from order `k` of the right-hand side to order `k + 1` of the state. Then the values an
/// order computes reach the next order in registers rather than through memory and a call,
/// and the processor can start on order `k + 1`'s sums while order `k`'s last recurrences
/// are still in flight.
///
/// Unrolled code grows as `recurrences · order²`; past [`MAX_NATIVE_TAYLOR_TERMS`] terms it
/// would take Cranelift seconds and overflow the instruction cache. Such tapes get compact
/// code ([`NativeTaylor::compile_compact`], after heyoka's "compact mode"): one function whose
/// argument is the order, each recurrence's sum a loop over the terms with the
/// interpreter's four partial sums, so the code grows as `recurrences` alone and the
/// coefficients are still the interpreter's bit for bit. What it saves over the interpreter
/// is the instruction dispatch, the slice bounds checks and the row arithmetic. Unlike
/// heyoka's (one function per kind of recurrence, looping over their operands), its code
/// still grows with the tape, so the largest tapes ([`MAX_COMPACT_RECURRENCES`]) stay
/// interpreted.
pub(crate) struct NativeTaylor {
    /// Per order: `funcs[k − 1]` computes order `k`. Whole expansion or compact: `funcs[0]`.
    funcs: Vec<*const u8>,
    form: Form,
    max_order: usize,
    _module: OwnedModule,
    stride: usize,
    n_rows: usize,
    /// The length of the buffer the code reads and writes, in `f64`s.
    buffer_len: usize,
    /// Lane-pair code ([`NativeTaylor::compile_lanes`]).
    lanes: bool,
}
// SAFETY: as for `NativeCode`: the module is touched only by `Drop`, and each generated
// function reads and writes only the buffer its caller passes (exclusively, `&mut`).
unsafe impl Send for NativeTaylor {}
// SAFETY: see `Send`.
unsafe impl Sync for NativeTaylor {}
impl std::fmt::Debug for NativeTaylor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "NativeTaylor({:?}, {} rows, stride {}, orders 1..={})",
            self.form, self.n_rows, self.stride, self.max_order
        )
    }
}
/// Taylor tapes whose unrolled recurrences would have more terms than this (about
/// `recurrences · order² / 2`) get compact code instead: Cranelift's compile time grows with
/// the unrolled code, and code this large runs out of the instruction cache.
pub(crate) const MAX_NATIVE_TAYLOR_TERMS: usize = 60_000;
/// Tapes with more recurrences than this stay interpreted rather than run compact code. Compact
/// code is still a few hundred bytes per recurrence, and the interpreter's is a few kilobytes in
/// all: measured on this project's machine (1 MB of L2 per core), compact code ran at 0.64–1.04×
/// the interpreter's time up to the 16-link pendulum's 1,480 recurrences, the gain shrinking with
/// size, then 1.2–2.5× slower at 1,881 and 2,330 (18- and 20-link), once code and coefficients no
/// longer fit in L2 (BENCHMARKS.md, "Where compact code stops paying"). Past a few hundred
/// recurrences it gains 18 % at most, so the limit leaves room for smaller caches.
pub(crate) const MAX_COMPACT_RECURRENCES: usize = 600;
/// Whether compact code pays for `tape` (at most [`MAX_COMPACT_RECURRENCES`] recurrences).
pub(crate) fn compact_pays(tape: &TaylorTape) -> bool {
    tape.ops().len() <= MAX_COMPACT_RECURRENCES
}
/// The terms of `tape`'s recurrences unrolled to `max_order` (about).
pub(crate) fn unrolled_terms(tape: &TaylorTape, max_order: usize) -> usize {
    tape.ops().len().saturating_mul(max_order).saturating_mul(max_order) / 2
}
impl NativeTaylor {
    /// Compiles orders `1..=max_order` of `tape` for coefficient buffers of `stride`
    /// (`max_order < stride`): unrolled per order, or compact past [`MAX_NATIVE_TAYLOR_TERMS`];
    /// `None` when the host has no JIT or the tape is too large even for compact code.
    pub(crate) fn compile(tape: &TaylorTape, stride: usize, max_order: usize) -> Option<NativeTaylor> {
        if unrolled_terms(tape, max_order) > MAX_NATIVE_TAYLOR_TERMS {
            return compact_pays(tape).then(|| Self::compile_compact(tape, stride, max_order)).flatten();
        }
        Self::compile_with(tape, stride, max_order, Form::PerOrder, None, false)
    }

    /// Compact code for orders `1..=max_order` whatever the tape's size (up to
    /// [`MAX_NATIVE_INSTRS`] recurrences; [`MAX_COMPACT_RECURRENCES`] is where it stops paying).
    pub(crate) fn compile_compact(tape: &TaylorTape, stride: usize, max_order: usize) -> Option<NativeTaylor> {
        if tape.ops().len() > MAX_NATIVE_INSTRS {
            return None;
        }
        Self::compile_with(tape, stride, max_order, Form::Compact, None, false)
    }

    /// The whole expansion of an ODE in one function (see [`Expansion`]); `None` also when
    /// it would be too large to unroll.
    pub(crate) fn compile_expansion(
        tape: &TaylorTape,
        stride: usize,
        max_order: usize,
        expansion: &Expansion,
    ) -> Option<NativeTaylor> {
        if max_order + 1 >= stride || unrolled_terms(tape, max_order) > MAX_NATIVE_TAYLOR_TERMS {
            return None;
        }
        Self::compile_with(tape, stride, max_order, Form::Whole, Some(expansion), false)
    }

    /// [`NativeTaylor::compile_expansion`] for two expansions side by side: every value an
    /// `F64X2` whose lane `l` is expansion `l`'s, in a buffer of the same layout whose slots
    /// hold both lanes (slot `i` at `f64`s `2i`, `2i + 1`; [`NativeTaylor::run_lanes`]).
    /// Each lane runs the scalar code's operations in the same order (the pairs of
    /// [`TaylorEmitter::pair`] aside, which do not change the bits), and the transcendental
    /// functions are called lane by lane through the same wrappers, so each lane gets the
    /// scalar expansion's bits. `W₀`'s factor is flagged for the interpreter when any lane's
    /// is. `None` also for tapes with `abs`, whose kinks a batch does not split.
    pub(crate) fn compile_lanes(
        tape: &TaylorTape,
        stride: usize,
        max_order: usize,
        expansion: &Expansion,
    ) -> Option<NativeTaylor> {
        let abs = tape.ops().iter().any(|op| matches!(op, Op::Abs { .. }));
        if abs || max_order + 1 >= stride || unrolled_terms(tape, max_order) > MAX_NATIVE_TAYLOR_TERMS {
            return None;
        }
        Self::compile_with(tape, stride, max_order, Form::Whole, Some(expansion), true)
    }

    fn compile_with(
        tape: &TaylorTape,
        stride: usize,
        max_order: usize,
        form: Form,
        expansion: Option<&Expansion>,
        lanes: bool,
    ) -> Option<NativeTaylor> {
        // Every offset must fit Cranelift's 32-bit immediate.
        let len = expansion.map_or(tape.n_rows().saturating_mul(stride), |g| g.len);
        if max_order == 0 || max_order >= stride || len > (i32::MAX as usize) / 16 {
            return None;
        }
        catch_unwind(AssertUnwindSafe(|| compile_taylor_code(tape, stride, max_order, form, expansion, lanes)))
            .ok()
            .flatten()
    }

    /// Whether this is a whole expansion ([`NativeTaylor::compile_expansion`]).
    pub(crate) fn is_whole(&self) -> bool {
        self.form == Form::Whole
    }

    /// Whether this is compact code ([`NativeTaylor::compile_compact`]).
    pub(crate) fn is_compact(&self) -> bool {
        self.form == Form::Compact
    }

    /// Runs a whole expansion: orders `0..=max_order` and the glue after each (the state's
    /// order 0 and the time's orders given).
    pub(crate) fn run_expansion(&self, c: &mut [f64]) -> Ran {
        assert!(self.is_whole() && !self.lanes, "not a whole expansion");
        self.run_whole(c)
    }

    /// [`NativeTaylor::run_expansion`] of lane-pair code ([`NativeTaylor::compile_lanes`]) on
    /// its buffer of two `f64`s per slot; [`Ran::Kink`] or [`Ran::Redo`] when any lane needs it.
    pub(crate) fn run_lanes(&self, c: &mut [LanePair]) -> Ran {
        assert!(self.is_whole() && self.lanes, "not lane-pair code");
        // SAFETY: `LanePair` is two `f64`s with no padding (`repr(C)`, size 16), so `c` is
        // `2 · c.len()` of them.
        let flat = unsafe { std::slice::from_raw_parts_mut(c.as_mut_ptr().cast::<f64>(), 2 * c.len()) };
        self.run_whole(flat)
    }

    fn run_whole(&self, c: &mut [f64]) -> Ran {
        match self.call(c, 0) {
            s if s & STATUS_REDO != 0 => Ran::Redo,
            s if s & STATUS_KINK != 0 => Ran::Kink,
            _ => Ran::Done,
        }
    }

    /// Runs the generated code for order `k` (any `k` for a whole expansion, which ignores
    /// it) on `c`; its status: 0, or [`STATUS_KINK`] and [`STATUS_REDO`] bits.
    fn call(&self, c: &mut [f64], k: usize) -> i32 {
        assert!(c.len() >= self.buffer_len, "Taylor buffer too short");
        let (func, arg) = match self.form {
            Form::Compact => (self.funcs[0], k),
            Form::Whole => (self.funcs[0], WINDOW_BYTES),
            Form::PerOrder => (self.funcs[k - 1], WINDOW_BYTES),
        };
        // SAFETY: every generated function has the type `TaylorFn` (see `compile_taylor_code`)
        // and touches only `c[0 .. buffer_len]` (the rows, and for a whole expansion the
        // accelerations, `L` and the mirror images after them: `TaylorOde::scratch_len`),
        // which the assertion guarantees; compact code reads and writes orders `0..=k` of the
        // rows, and `run_order` asserts `k ≤ max_order < stride`.
        unsafe { std::mem::transmute::<*const u8, TaylorFn>(func)(c.as_mut_ptr(), arg) }
    }

    /// The stride the code was compiled for.
    pub(crate) fn stride(&self) -> usize {
        self.stride
    }

    /// The highest order compiled.
    pub(crate) fn max_order(&self) -> usize {
        self.max_order
    }

    /// Computes order `k` of every row of `c` (orders `0..k` and order `k` of the inputs
    /// given); `false` when an `abs` met its kink.
    pub(crate) fn run_order(&self, c: &mut [f64], k: usize) -> bool {
        assert!(!self.is_whole() && (1..=self.max_order).contains(&k), "order {k} not compiled");
        self.call(c, k) == 0
    }
}
fn compile_taylor_code(
    tape: &TaylorTape,
    stride: usize,
    max_order: usize,
    form: Form,
    expansion: Option<&Expansion>,
    lanes: bool,
) -> Option<NativeTaylor> {
    let (mut module, call_conv, ptr) = host_module(&[])?;
    let mut ctx = module.make_context();
    let mut fbc = FunctionBuilderContext::new();
    let mut ids = Vec::with_capacity(max_order);
    let mut ok = true;
    // The orders each function computes: one each (per order); all of them in one function
    // (whole expansion, from order 0, see `TaylorEmitter::order0`); for compact code a
    // placeholder, its order being the function's argument.
    let funcs: Vec<Vec<usize>> = match form {
        Form::Whole => vec![(0..=max_order).collect()],
        Form::PerOrder => (1..=max_order).map(|k| vec![k]).collect(),
        Form::Compact => vec![vec![0]],
    };
    for orders in &funcs {
        ctx.func.signature.call_conv = call_conv;
        // The buffer, and the order (compact code) or the window span (unrolled code).
        ctx.func.signature.params.push(AbiParam::new(ptr));
        ctx.func.signature.params.push(AbiParam::new(ptr));
        ctx.func.signature.returns.push(AbiParam::new(types::I32));
        let emitted = {
            let mut b = FunctionBuilder::new(&mut ctx.func, &mut fbc);
            let block = b.create_block();
            b.append_block_params_for_function_params(block);
            b.switch_to_block(block);
            b.seal_block(block);
            let base = b.block_params(block)[0];
            let second = b.block_params(block)[1];
            let k = match form {
                Form::Compact => {
                    let k = b.block_params(block)[1];
                    let kf = b.ins().fcvt_from_uint(types::F64, k);
                    let one = b.ins().f64const(1.0);
                    let rk = b.ins().fdiv(one, kf);
                    let k8 = b.ins().ishl_imm(k, 3);
                    let at_k = b.ins().iadd(base, k8);
                    Order::Runtime { k, kf, rk, at_k }
                }
                _ => Order::Fixed(0),
            };
            let rows = tape.n_rows() + expansion.and_then(|g| g.solve.as_ref()).map_or(0, |m| m.n);
            let known = if form == Form::Compact { Vec::new() } else { vec![None; rows * stride] };
            let windows = Windows { span: second, bases: Vec::new() };
            // Pairs are scalar code's: lane-pair code's values are vectors already.
            let mirror = expansion.filter(|_| !lanes && max_order + 1 >= PAIRS_FROM_ORDER).map(|g| g.mirror_at);
            let mut em = TaylorEmitter {
                b: &mut b,
                tape,
                call_conv,
                base,
                ptr,
                s: stride,
                k,
                known,
                reloads: 0,
                windows,
                mirror,
                last_order: (form == Form::Whole).then_some(max_order),
                dead_last: if form == Form::Whole { tape.dead_at_last_order() } else { Vec::new() },
                inv_diag: Vec::new(),
                ssa_orders: ssa_orders(tape, expansion),
                sin_cos_slot: None,
                lanes,
            };
            let mut kink = Some(em.b.ins().iconst(types::I8, 0));
            let mut redo = None;
            for &k in orders {
                if form != Form::Compact {
                    em.k = Order::Fixed(k);
                }
                if form == Form::Whole && k == 0 {
                    em.order0();
                    if let Some(m) = expansion.and_then(|g| g.solve.as_ref()) {
                        redo = Some(em.cholesky_factor(m));
                    }
                } else {
                    kink = kink.zip(em.order()).map(|(a, b)| em.b.ins().bor(a, b));
                }
                if let Some(g) = expansion {
                    if let Some(m) = &g.solve {
                        em.cholesky_solve(m, k);
                    }
                    for &(dst, src) in &g.glue {
                        let v = em.at(src, k);
                        let inv = em.c(1.0 / (k + 1) as f64);
                        let v = em.b.ins().fmul(v, inv);
                        em.put_at(dst, k + 1, v);
                    }
                }
            }
            if let Some(kink) = kink {
                let mut r = em.b.ins().uextend(types::I32, kink);
                if let Some(redo) = redo {
                    let redo = em.b.ins().uextend(types::I32, redo);
                    let redo = em.b.ins().imul_imm(redo, i64::from(STATUS_REDO));
                    r = em.b.ins().bor(r, redo);
                }
                em.b.ins().return_(&[r]);
                b.seal_all_blocks();
                b.finalize();
            }
            kink.is_some()
        };
        let name = match form {
            Form::Whole if lanes => "taylor_expansion_lanes".to_string(),
            Form::Whole => "taylor_expansion".to_string(),
            Form::Compact => "taylor_compact".to_string(),
            Form::PerOrder => format!("taylor_order_{}", orders[0]),
        };
        let id = emitted.then(|| module.declare_function(&name, Linkage::Export, &ctx.func.signature).ok()).flatten();
        let defined = id.and_then(|id| module.define_function(id, &mut ctx).ok().map(|_| id));
        module.clear_context(&mut ctx);
        match defined {
            Some(id) => ids.push(id),
            None => {
                ok = false;
                break;
            }
        }
    }
    if !ok || module.finalize_definitions().is_err() {
        // SAFETY: no pointer into this module was ever handed out.
        unsafe { module.free_memory() };
        return None;
    }
    let funcs = ids.into_iter().map(|id| module.get_finalized_function(id)).collect();
    Some(NativeTaylor {
        funcs,
        form,
        max_order,
        _module: OwnedModule(ManuallyDrop::new(module)),
        stride,
        n_rows: tape.n_rows(),
        buffer_len: expansion.map_or(tape.n_rows() * stride, |g| g.len) * if lanes { 2 } else { 1 },
        lanes,
    })
}
/// The order a [`TaylorEmitter`] writes.
#[derive(Clone, Copy)]
enum Order {
    /// A constant (unrolled code: every index is an immediate offset).
    Fixed(usize),
    /// The argument `k` of compact code, with `k` as a float, `1/k` (as the interpreter
    /// computes it) and the address of order `k` of row 0.
    Runtime { k: Value, kf: Value, rk: Value, at_k: Value },
}
/// A coefficient index `m·k + c` (`m` is 0 or 1), `k` the order being computed.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
struct Ix {
    m: isize,
    c: isize,
}
impl Ix {
    /// Order `k` itself.
    const K: Ix = Ix { m: 1, c: 0 };

    /// Order `c`.
    const fn at(c: isize) -> Ix {
        Ix { m: 0, c }
    }

    /// Order `k + c`.
    const fn k(c: isize) -> Ix {
        Ix { m: 1, c }
    }

    fn plus(self, o: Ix) -> Ix {
        Ix { m: self.m + o.m, c: self.c + o.c }
    }

    fn minus(self, o: Ix) -> Ix {
        Ix { m: self.m - o.m, c: self.c - o.c }
    }

    fn eval(self, k: usize) -> usize {
        usize::try_from(self.m * k as isize + self.c).expect("a coefficient index is never negative")
    }
}
/// The number of terms of a sum.
#[derive(Clone, Copy)]
enum Len {
    Ix(Ix),
    /// `⌈k/2⌉ − 1`: the distinct pairs of a square's inner sum.
    HalfInner,
}
/// Emits order `k` of every recurrence of a Taylor tape, mirroring
/// `TaylorTape::run_order` operation for operation.
struct TaylorEmitter<'a, 'b> {
    b: &'a mut FunctionBuilder<'b>,
    /// The tape whose recurrences are emitted.
    tape: &'a TaylorTape,
    call_conv: CallConv,
    base: Value,
    /// The integer type of addresses and of the order.
    ptr: types::Type,
    s: usize,
    k: Order,
    /// Unrolled code: coefficient `j` of row `r` at `r · s + j`, for those written or loaded so
    /// far in this function (stored, and read as these SSA values while they are among the
    /// last [`ssa_orders`], see [`TaylorEmitter::at`]). Compact code loads every time.
    known: Vec<Option<Value>>,
    /// Loads made by [`TaylorEmitter::reload`] so far (each gets its own address expression).
    reloads: usize,
    /// Unrolled code's base registers into the buffer ([`TaylorEmitter::window`]).
    windows: Windows,
    /// Whole expansions: where the mirror images of the rows start ([`TaylorEmitter::pair`]).
    mirror: Option<usize>,
    /// Whole expansions: the last order, at which the rows of `dead_last` are left out
    /// ([`TaylorTape::dead_at_last_order`]).
    last_order: Option<usize>,
    dead_last: Vec<bool>,
    /// `W q'' = F`: the reciprocals of the diagonal of `W₀`'s Cholesky factor, from order 0.
    inv_diag: Vec<Value>,
    /// Unrolled code reads the last `ssa_orders` orders (`k`, and `k − 1` if 2) as SSA
    /// values and reloads older ones ([`ssa_orders`]).
    ssa_orders: usize,
    /// The stack slot the `sin_cos` wrapper writes to (`call_sin_cos`), made on first use.
    sin_cos_slot: Option<StackSlot>,
    /// Lane-pair code ([`NativeTaylor::compile_lanes`]): every value an `F64X2` of two
    /// expansions side by side, every buffer slot 16 bytes.
    lanes: bool,
}
/// The base registers of unrolled code: `bases[w] = base + w · span`, made on first use;
/// `span` is the function's argument [`WINDOW_BYTES`].
struct Windows {
    span: Value,
    bases: Vec<Option<Value>>,
}
impl TaylorEmitter<'_, '_> {
    /// Coefficient `j` of row `r` (unrolled code). Order `k` (and for small tapes `k − 1`, see
    /// [`ssa_orders`]) is read as the SSA value that wrote it (it is on the dependency chain
    /// from one order to the next, where a reload would add store-forwarding latency); older
    /// orders are reloaded (see [`TaylorEmitter::reload`]).
    fn at(&mut self, r: u32, j: usize) -> Value {
        let i = r as usize * self.s + j;
        match (self.known[i], self.k) {
            (Some(_), Order::Fixed(k)) if j + self.ssa_orders <= k => self.reload(i),
            (Some(v), _) => v,
            (None, _) => {
                let (p, off) = self.window(i);
                let ty = self.ty();
                let v = self.b.ins().load(ty, MemFlags::trusted(), p, off);
                self.mirror_store(r, j, v);
                self.known[i] = Some(v);
                v
            }
        }
    }

    /// Coefficient `i` of the buffer, which this function has already stored or loaded, read
    /// again from the buffer for one use.
    ///
    /// Kept in an SSA value instead, every coefficient of an unrolled expansion lives for all
    /// later orders, so Cranelift spills nearly all of them to the stack and reloads each at
    /// every use: a second copy of a buffer that already holds them, and a third of the code
    /// (Kepler: 1,369 reloads and 108 spills in 3,989 instructions). A plain `load` does not
    /// help: it is a side effect, kept in emission order, while the mid-end sinks the pure
    /// arithmetic to its first use, so every sum's loads would run ahead of its arithmetic
    /// and be spilled again. A `readonly` `notrap` load is pure, so it is placed next to its
    /// use. Each one has its own address expression (`base + 8u` plus `8i − 8u`, folded back
    /// into one addressing mode), or value numbering would merge all reads of a coefficient
    /// into one long-lived value, the spill again.
    ///
    /// `readonly` holds for these words from the point they are read: a function is one
    /// straight-line block, in which a pure value is placed no earlier than its first use,
    /// and that use follows the store of the coefficient, which is never written again. The
    /// bit-for-bit comparisons with the interpreter on reused buffers
    /// (`tests/it/taylor/native.rs`) would catch a load moved above its store.
    fn reload(&mut self, i: usize) -> Value {
        self.pure_load(self.ty(), MemFlags::trusted(), i)
    }

    /// A `readonly` load of type `ty` at word `i` of the buffer with its own address
    /// expression ([`TaylorEmitter::reload`]; `flags` without `readonly`).
    fn pure_load(&mut self, ty: types::Type, flags: MemFlags, i: usize) -> Value {
        self.reloads += 1;
        let u = 8 * (self.reloads % (1 << 24)) as i64;
        let (p, off) = self.window(i);
        let at = self.b.ins().iadd_imm(p, u);
        self.b.ins().load(ty, flags.with_readonly(), at, (off as i64 - u) as i32)
    }

    /// A base register and a one-byte displacement for coefficient `i` of the buffer
    /// (unrolled code).
    ///
    /// With the buffer's one base register, every access past its first 128 bytes takes a
    /// four-byte displacement: Kepler's order-18 expansion was 17.8 kB of instructions (and a
    /// 5 kB constant pool), ~1,500 of its 3,257 instructions loads and stores of 8 bytes
    /// each. How fast that code ran moved by up to 20 % with the placement of the
    /// integrator's own code, and the effect grows with the code's size (1 % at order 8, 12 %
    /// at order 18), which points at the instruction caches. Base registers every
    /// [`WINDOW_BYTES`] bytes (up to [`MAX_WINDOWS`]) reach each coefficient with a one-byte
    /// displacement (16.0 kB). Each is `base + w · span`, where `span` is a function argument,
    /// so that Cranelift cannot fold it back into `base` plus a constant.
    fn window(&mut self, i: usize) -> (Value, i32) {
        let bytes = self.slot_bytes() * i;
        let w = (bytes + WINDOW_BYTES / 2) / WINDOW_BYTES;
        let off = (bytes as i64 - (w * WINDOW_BYTES) as i64) as i32;
        if w == 0 || w >= MAX_WINDOWS {
            // Past the windows, the buffer's own base register and a long displacement.
            return if w == 0 { (self.base, off) } else { (self.base, bytes as i32) };
        }
        if self.windows.bases.len() <= w {
            self.windows.bases.resize(w + 1, None);
        }
        let p = match self.windows.bases[w] {
            Some(p) => p,
            None => {
                let shift = self.b.ins().imul_imm(self.windows.span, w as i64);
                let p = self.b.ins().iadd(self.base, shift);
                self.windows.bases[w] = Some(p);
                p
            }
        };
        (p, off)
    }

    /// Coefficient `j` of row `r`, in either kind of code.
    fn coef(&mut self, r: u32, j: Ix) -> Value {
        match self.k {
            Order::Fixed(k) => self.at(r, j.eval(k)),
            Order::Runtime { .. } => {
                let (p, off) = self.addr(r, j);
                self.b.ins().load(types::F64, MemFlags::trusted(), p, off)
            }
        }
    }

    /// Compact code: a base address and an immediate offset for coefficient `j` of row `r`.
    fn addr(&mut self, r: u32, j: Ix) -> (Value, i32) {
        let Order::Runtime { at_k, .. } = self.k else { unreachable!("addresses are for compact code") };
        let off = ((r as usize * self.s) as isize + j.c) * 8;
        let p = match j.m {
            0 => self.base,
            1 => at_k,
            _ => unreachable!("indices are j or k + j"),
        };
        (p, off as i32)
    }

    /// The value of `m·k + c` as an integer (compact code).
    fn index_value(&mut self, j: Ix) -> Value {
        let Order::Runtime { k, .. } = self.k else { unreachable!("run-time indices are for compact code") };
        match j.m {
            0 => self.b.ins().iconst(self.ptr, j.c as i64),
            _ => self.b.ins().iadd_imm(k, j.c as i64),
        }
    }

    /// Writes order `k` of row `r` and, if it has one, of its weighted row (`k · v`, as
    /// `TaylorTape::run_order`'s `put`).
    fn put(&mut self, r: u32, v: Value) {
        match self.k {
            Order::Fixed(k) => self.put_at(r, k, v),
            Order::Runtime { at_k, .. } => {
                self.b.ins().store(MemFlags::trusted(), v, at_k, (r as usize * self.s * 8) as i32);
            }
        }
        if let Some(w) = self.tape.weighted_row(r) {
            let kf = self.kf();
            let wv = self.b.ins().fmul(v, kf);
            self.put(w, wv);
        }
    }

    /// Writes coefficient `j` of row `r` (unrolled code).
    fn put_at(&mut self, r: u32, j: usize, v: Value) {
        let i = r as usize * self.s + j;
        let (p, off) = self.window(i);
        self.b.ins().store(MemFlags::trusted(), v, p, off);
        self.mirror_store(r, j, v);
        self.known[i] = Some(v);
    }

    /// Stores coefficient `j` of row `r` in its row's mirror image too, if there is one.
    fn mirror_store(&mut self, r: u32, j: usize, v: Value) {
        if let Some(m) = self.mirror {
            let (p, off) = self.window(m + r as usize * self.s + self.s - 1 - j);
            self.b.ins().store(MemFlags::trusted(), v, p, off);
        }
    }

    /// Coefficients `j` and `j + 1` of row `r` (`descending`: `j` and `j − 1`) as the two lanes
    /// of a vector, for two terms of a sum at once ([`TaylorEmitter::sum`]).
    ///
    /// Two consecutive terms of a Cauchy product read one row upwards and the other
    /// downwards: `a_i b_{k−i}` and `a_{i+1} b_{k−i−1}`. A row's mirror image (stored next to
    /// every coefficient, one store each) has the downward pair at consecutive addresses, so
    /// both pairs are single loads: pure loads at their own addresses, as
    /// [`TaylorEmitter::reload`]'s. Coefficients kept in registers ([`ssa_orders`]),
    /// or not yet in the buffer, are put into the lanes one by one: a vector load of words
    /// stored just before would wait for the stores to complete.
    fn pair(&mut self, r: u32, j: usize, descending: bool) -> Value {
        let Order::Fixed(k) = self.k else { unreachable!("pairs are for unrolled code") };
        let j1 = if descending { j - 1 } else { j + 1 };
        let row = r as usize * self.s;
        let old = |em: &Self, j: usize| j + em.ssa_orders <= k && em.known[row + j].is_some();
        if old(self, j) && old(self, j1) {
            let i = match (descending, self.mirror) {
                (false, _) => row + j,
                (true, Some(m)) => m + row + self.s - 1 - j,
                (true, None) => unreachable!("descending pairs need the mirror"),
            };
            // Words are 8-byte aligned, pairs not 16-byte aligned: no `aligned` flag.
            return self.pure_load(types::F64X2, MemFlags::new().with_notrap(), i);
        }
        let (x0, x1) = (self.at(r, j), self.at(r, j1));
        let v = self.b.ins().scalar_to_vector(types::F64X2, x0);
        self.b.ins().insertlane(v, x1, 1)
    }

    /// The constant `x` (in every lane of lane-pair code).
    fn c(&mut self, x: f64) -> Value {
        if self.lanes {
            self.pair_const(x, x)
        } else {
            self.b.ins().f64const(x)
        }
    }

    /// The type of a value: `F64`, or `F64X2` in lane-pair code.
    fn ty(&self) -> types::Type {
        if self.lanes {
            types::F64X2
        } else {
            types::F64
        }
    }

    /// The bytes of one buffer slot (one coefficient of every lane).
    fn slot_bytes(&self) -> usize {
        if self.lanes {
            16
        } else {
            8
        }
    }

    /// An `i8` that is 1 when the comparison mask `m` (an `fcmp` of values) holds in any lane.
    fn any_lane(&mut self, m: Value) -> Value {
        if self.lanes {
            self.b.ins().vany_true(m)
        } else {
            m
        }
    }

    /// The vector constant `(x, y)`.
    fn pair_const(&mut self, x: f64, y: f64) -> Value {
        let bytes: Vec<u8> = x.to_le_bytes().into_iter().chain(y.to_le_bytes()).collect();
        let c = self.b.func.dfg.constants.insert(bytes.into());
        self.b.ins().vconst(types::F64X2, c)
    }

    /// `k` as a float.
    fn kf(&mut self) -> Value {
        match self.k {
            Order::Fixed(k) => self.c(k as f64),
            Order::Runtime { kf, .. } => kf,
        }
    }

    /// `1/k`.
    fn rk(&mut self) -> Value {
        match self.k {
            Order::Fixed(k) => self.c(1.0 / k as f64),
            Order::Runtime { rk, .. } => rk,
        }
    }

    /// `w · x · y`, evaluated as `(x · w) · y`, with the multiplication by a weight of exactly
    /// 1 left out (`1 · x = x` in IEEE arithmetic). A constant goes second in every product
    /// here (the same bits: IEEE multiplication commutes), where x86 lowering reads it from the
    /// constant pool as a memory operand; first, it was put in a register, shared by value
    /// numbering across the function, kept alive and spilled (Kepler: 70 constants).
    fn term(&mut self, w: Option<Value>, x: Value, y: Value) -> Value {
        let x = match w {
            Some(w) => self.b.ins().fmul(x, w),
            None => x,
        };
        self.b.ins().fmul(x, y)
    }

    /// `Σ_i w_i · a[a0 + i] · b[b0 − i]`, `i = 0..len`, in the interpreter's order (`sum4` in
    /// `interp.rs`): the terms reading order `k` (`b0 = k` first, `a0 + len − 1 = k` last)
    /// added at the end, the others round-robin into four partial sums (from their first
    /// terms; two terms at a time in vector lanes from [`PAIRS_FROM_ORDER`]), combined as
    /// `(s₀ + s₁) + (s₂ + s₃)`.
    fn sum(&mut self, a: u32, a0: Ix, b: u32, b0: Ix, len: Len, w: Weight) -> Value {
        let Order::Fixed(k) = self.k else { return self.sum_loop(a, a0, b, b0, len, w) };
        let (a0, b0) = (a0.eval(k), b0.eval(k));
        let len = match len {
            Len::Ix(l) => l.eval(k),
            Len::HalfInner => k.div_ceil(2) - 1,
        };
        let lo = usize::from(len > 0 && b0 == k);
        let hi = if len > lo && a0 + len - 1 == k { len - 1 } else { len };
        let term = |em: &mut Self, i: usize| {
            let (x, y) = (em.at(a, a0 + i), em.at(b, b0 - i));
            let wi = w.at(i, k);
            let wv = (wi != 1.0).then(|| em.c(wi));
            em.term(wv, x, y)
        };
        // `None` is a partial sum still at its −0.0, which adds exactly nothing.
        let add = |em: &mut Self, s: Option<Value>, t: Option<Value>| match (s, t) {
            (Some(s), Some(t)) => Some(em.b.ins().fadd(s, t)),
            (s, t) => s.or(t),
        };
        let mut acc = [None; 4];
        // Quads of terms, two by two in vector lanes when the rows are mirrored: lanes 0 and 1
        // of `pairs[0]` are partial sums 0 and 1, those of `pairs[1]` sums 2 and 3, each lane
        // the scalar code's operations on its own term, so the bits are the same.
        let mut from = lo;
        if self.mirror.is_some() && hi - lo >= 4 {
            let mut pairs: [Option<Value>; 2] = [None; 2];
            while from + 2 <= hi {
                // The last two or three terms: their first two go to partial sums 0 and 1
                // (`pairs[0]`), as in the scalar order; a third is left to the scalar code.
                let halves = if from + 4 <= hi { 2 } else { 1 };
                for (h, lanes) in pairs.iter_mut().enumerate().take(halves) {
                    let i = from + 2 * h;
                    let x = self.pair(a, a0 + i, false);
                    let y = self.pair(b, b0 - i, true);
                    let (w0, w1) = (w.at(i, k), w.at(i + 1, k));
                    let x = if w0 == 1.0 && w1 == 1.0 {
                        x
                    } else {
                        let wv = self.pair_const(w0, w1);
                        self.b.ins().fmul(x, wv)
                    };
                    let t = self.b.ins().fmul(x, y);
                    *lanes = Some(match *lanes {
                        Some(s) => self.b.ins().fadd(s, t),
                        None => t,
                    });
                }
                from += 2 * halves;
            }
            for (h, lanes) in pairs.into_iter().enumerate() {
                let v = lanes.expect("at least one quad");
                acc[2 * h] = Some(self.b.ins().extractlane(v, 0));
                acc[2 * h + 1] = Some(self.b.ins().extractlane(v, 1));
            }
        }
        for i in from..hi {
            let t = term(self, i);
            let r = (i - lo) % 4;
            acc[r] = add(self, acc[r], Some(t));
        }
        let s01 = add(self, acc[0], acc[1]);
        let s23 = add(self, acc[2], acc[3]);
        let mut s = add(self, s01, s23);
        if lo == 1 {
            let t = term(self, 0);
            s = add(self, s, Some(t));
        }
        if hi < len {
            let t = term(self, len - 1);
            s = add(self, s, Some(t));
        }
        s.unwrap_or_else(|| self.c(-0.0))
    }

    /// [`TaylorEmitter::sum`] in compact code: the same terms in the same order, as a loop of
    /// four terms per pass (one into each partial sum) and a tail of up to three. Which terms
    /// read order `k` does not depend on `k` for the sums of the recurrences (every one has at
    /// least the terms that read order `k`), so they are known here.
    fn sum_loop(&mut self, a: u32, a0: Ix, b: u32, b0: Ix, len: Len, w: Weight) -> Value {
        let Order::Runtime { k, kf, .. } = self.k else { unreachable!("loops are for compact code") };
        let late_first = b0 == Ix::K;
        let late_last = matches!(len, Len::Ix(l) if a0.plus(l) == Ix::k(1));
        let lo = isize::from(late_first);
        let n = match len {
            Len::Ix(l) => self.index_value(l),
            Len::HalfInner => {
                let km1 = self.b.ins().iadd_imm(k, -1);
                self.b.ins().ushr_imm(km1, 1)
            }
        };
        let ptr = self.ptr;
        let remaining = self.b.ins().iadd_imm(n, -(lo + isize::from(late_last)) as i64);
        let (pa, oa) = self.addr(a, a0.plus(Ix::at(lo)));
        let px = self.b.ins().iadd_imm(pa, i64::from(oa));
        let (pb, ob) = self.addr(b, b0.minus(Ix::at(lo)));
        let py = self.b.ins().iadd_imm(pb, i64::from(ob));
        let j0 = self.c((lo + 1) as f64);
        // The partial sums start from −0.0, as `sum4`'s do.
        let start = self.c(-0.0);
        // The weight of the term whose `j` is `j` (a float holding an integer).
        let weight = |em: &mut Self, j: Value| match w {
            Weight::One => None,
            Weight::Power(e) => {
                let kmj = em.b.ins().fsub(kf, j);
                let ev = em.c(e);
                let ej = em.b.ins().fmul(ev, j);
                Some(em.b.ins().fsub(ej, kmj))
            }
        };
        // Term `r` of a pass whose first term has `x` at `px`, `y` at `py` and `j`.
        let pass_term = |em: &mut Self, px: Value, py: Value, j: Value, r: i32| {
            let x = em.b.ins().load(types::F64, MemFlags::trusted(), px, 8 * r);
            let y = em.b.ins().load(types::F64, MemFlags::trusted(), py, -8 * r);
            let j = if r == 0 {
                j
            } else {
                let rv = em.c(f64::from(r));
                em.b.ins().fadd(j, rv)
            };
            let wv = weight(em, j);
            em.term(wv, x, y)
        };
        let header = self.b.create_block();
        for t in [ptr, ptr, ptr, types::F64, types::F64, types::F64, types::F64, types::F64] {
            self.b.append_block_param(header, t);
        }
        let body = self.b.create_block();
        let tail = self.b.create_block();
        let join = self.b.create_block();
        for _ in 0..3 {
            self.b.append_block_param(join, types::F64);
        }
        self.b.ins().jump(header, &[remaining, px, py, j0, start, start, start, start]);

        self.b.switch_to_block(header);
        let hp = self.b.block_params(header).to_vec();
        let (rem, px, py, j, acc) = (hp[0], hp[1], hp[2], hp[3], [hp[4], hp[5], hp[6], hp[7]]);
        let more = self.b.ins().icmp_imm(IntCC::SignedGreaterThanOrEqual, rem, 4);
        self.b.ins().brif(more, body, &[], tail, &[]);

        self.b.switch_to_block(body);
        self.b.seal_block(body);
        let mut next = acc;
        for (r, s) in next.iter_mut().enumerate() {
            let t = pass_term(self, px, py, j, r as i32);
            *s = self.b.ins().fadd(*s, t);
        }
        let rem4 = self.b.ins().iadd_imm(rem, -4);
        let px4 = self.b.ins().iadd_imm(px, 32);
        let py4 = self.b.ins().iadd_imm(py, -32);
        let four = self.c(4.0);
        let j4 = self.b.ins().fadd(j, four);
        self.b.ins().jump(header, &[rem4, px4, py4, j4, next[0], next[1], next[2], next[3]]);
        self.b.seal_block(header);

        // The tail: term `r` goes into partial sum `r` while `r < rem`.
        self.b.switch_to_block(tail);
        self.b.seal_block(tail);
        let mut sums = [acc[0], acc[1], acc[2]];
        for r in 0..3 {
            let take = self.b.ins().icmp_imm(IntCC::SignedGreaterThan, rem, r);
            let add = self.b.create_block();
            self.b.ins().brif(take, add, &[], join, &sums);
            self.b.switch_to_block(add);
            self.b.seal_block(add);
            let t = pass_term(self, px, py, j, r as i32);
            sums[r as usize] = self.b.ins().fadd(sums[r as usize], t);
        }
        self.b.ins().jump(join, &sums);
        self.b.switch_to_block(join);
        self.b.seal_block(join);
        let jp = self.b.block_params(join).to_vec();
        let s01 = self.b.ins().fadd(jp[0], jp[1]);
        let s23 = self.b.ins().fadd(jp[2], acc[3]);
        let mut s = self.b.ins().fadd(s01, s23);
        if late_first {
            let (x, y) = (self.coef(a, a0), self.coef(b, b0));
            let one = self.c(1.0);
            let wv = weight(self, one);
            let t = self.term(wv, x, y);
            s = self.b.ins().fadd(s, t);
        }
        if let (true, Len::Ix(l)) = (late_last, len) {
            let (x, y) = (self.coef(a, Ix::K), self.coef(b, b0.minus(l).plus(Ix::at(1))));
            let jl = self.b.ins().fcvt_from_sint(types::F64, n);
            let wv = weight(self, jl);
            let t = self.term(wv, x, y);
            s = self.b.ins().fadd(s, t);
        }
        s
    }

    /// Order 0 of `W q'' = F`: the Cholesky factor `L` of `W₀` into the buffer at
    /// `factor_at`, operation for operation as `linalg::factor` (so the bits are the
    /// interpreter's), and a flag (`i8`) set when an entry of `W₀` is not finite or a pivot is
    /// at most `n ε max|W₀|`: then the interpreter redoes the expansion, which factors by LU
    /// or reports the error. The code runs on regardless (one straight-line block), on
    /// garbage that is never used.
    fn cholesky_factor(&mut self, m: &CholeskySolve) -> Value {
        let n = m.n;
        let mut a: Vec<Value> = m.w_rows.iter().map(|&r| self.at(r, 0)).collect();
        let inf = self.c(f64::INFINITY);
        let mut redo = self.b.ins().iconst(types::I8, 0);
        let mut scale = self.c(0.0);
        for &x in &a {
            let ax = self.b.ins().fabs(x);
            // Not finite: `|x| < ∞` fails (NaN included).
            let bad = self.b.ins().fcmp(FloatCC::UnorderedOrGreaterThanOrEqual, ax, inf);
            let bad = self.any_lane(bad);
            redo = self.b.ins().bor(redo, bad);
            // `f64::max` of finite values (a non-finite one sets `redo` anyway).
            scale = self.b.ins().fmax(scale, ax);
        }
        let ne = self.c(n as f64 * f64::EPSILON);
        let tol = self.b.ins().fmul(ne, scale);
        for j in 0..n {
            let mut d = a[j * n + j];
            for k in 0..j {
                let p = self.b.ins().fmul(a[j * n + k], a[j * n + k]);
                d = self.b.ins().fsub(d, p);
            }
            let small = self.b.ins().fcmp(FloatCC::LessThanOrEqual, d, tol);
            let small = self.any_lane(small);
            redo = self.b.ins().bor(redo, small);
            let l = self.b.ins().sqrt(d);
            a[j * n + j] = l;
            for i in j + 1..n {
                let mut x = a[i * n + j];
                for k in 0..j {
                    let p = self.b.ins().fmul(a[i * n + k], a[j * n + k]);
                    x = self.b.ins().fsub(x, p);
                }
                a[i * n + j] = self.b.ins().fdiv(x, l);
            }
        }
        for i in 0..n {
            for j in 0..=i {
                let off = ((m.factor_at + i * n + j) * self.slot_bytes()) as i32;
                self.b.ins().store(MemFlags::trusted(), a[i * n + j], self.base, off);
            }
        }
        let one = self.c(1.0);
        self.inv_diag = (0..n).map(|i| self.b.ins().fdiv(one, a[i * n + i])).collect();
        redo
    }

    /// Order `k` of the accelerations (`TaylorOde::expand` and its `cholesky_solve`, with the
    /// reciprocals of the factor's diagonal from order 0, operation for operation; unrolled
    /// code).
    fn cholesky_solve(&mut self, m: &CholeskySolve, k: usize) {
        let n = m.n;
        let mut x = Vec::with_capacity(n);
        for i in 0..n {
            let mut v = self.at(m.f_rows[i], k);
            for &(l, w) in &m.varying[i] {
                // Order 0 has no terms: the interpreter's empty sum, −0.0.
                let d = match k {
                    0 => self.c(-0.0),
                    _ => self.sum(w, Ix::at(1), m.acc_row + l as u32, Ix::k(-1), Len::Ix(Ix::K), Weight::One),
                };
                v = self.b.ins().fsub(v, d);
            }
            x.push(v);
        }
        let lf = |em: &mut Self, i: usize, j: usize| {
            let off = ((m.factor_at + i * n + j) * em.slot_bytes()) as i32;
            let ty = em.ty();
            em.b.ins().load(ty, MemFlags::trusted(), em.base, off)
        };
        for i in 0..n {
            let mut v = x[i];
            for (j, &xj) in x.iter().enumerate().take(i) {
                let l = lf(self, i, j);
                let p = self.b.ins().fmul(l, xj);
                v = self.b.ins().fsub(v, p);
            }
            x[i] = self.b.ins().fmul(v, self.inv_diag[i]);
        }
        for i in (0..n).rev() {
            let mut v = x[i];
            for (j, &xj) in x.iter().enumerate().skip(i + 1) {
                let l = lf(self, j, i);
                let p = self.b.ins().fmul(l, xj);
                v = self.b.ins().fsub(v, p);
            }
            x[i] = self.b.ins().fmul(v, self.inv_diag[i]);
        }
        for (i, &v) in x.iter().enumerate() {
            self.put_at(m.acc_row + i as u32, k, v);
        }
    }

    /// `Σ_{j=0}^{k} a_j b_{k−j}` (`cauchy`).
    fn cauchy(&mut self, a: u32, b: u32) -> Value {
        self.sum(a, Ix::at(0), b, Ix::K, Len::Ix(Ix::k(1)), Weight::One)
    }

    /// `Σ_{j=1}^{k} j a_j b_{k−j}` (`weighted`), read from `a`'s weighted row.
    fn weighted(&mut self, a: u32, b: u32) -> Value {
        let wa = self.weighted_row(a);
        self.sum(wa, Ix::at(1), b, Ix::k(-1), Len::Ix(Ix::K), Weight::One)
    }

    /// `Σ_{j=1}^{k−1} j a_j b_{k−j}` (`weighted_short`; an empty sum is `−0.0` either way).
    fn weighted_short(&mut self, a: u32, b: u32) -> Value {
        if matches!(self.k, Order::Fixed(k) if k < 2) {
            return self.c(-0.0);
        }
        let wa = self.weighted_row(a);
        self.sum(wa, Ix::at(1), b, Ix::k(-1), Len::Ix(Ix::k(-1)), Weight::One)
    }

    /// The weighted row of row `r` (`j · r_j`, `weigh_rows` in `ir.rs`).
    fn weighted_row(&self, r: u32) -> u32 {
        self.tape.weighted_row(r).expect("weigh_rows gives every weighted operand its row")
    }

    /// `Σ_{j=1}^{k−1} a_j a_{k−j}` over half its terms (`square_inner` in `interp.rs`):
    /// `2 Σ_{1≤j<k−j} a_j a_{k−j} + (a_{k/2}² or 0)`.
    fn square_inner(&mut self, r: u32) -> Value {
        let half = self.sum(r, Ix::at(1), r, Ix::k(-1), Len::HalfInner, Weight::One);
        let twice = self.twice(half);
        let mid = match self.k {
            Order::Fixed(k) if k % 2 == 0 => {
                let m = self.at(r, k / 2);
                self.b.ins().fmul(m, m)
            }
            Order::Fixed(_) => self.c(0.0),
            Order::Runtime { k, .. } => {
                // a_{⌊k/2⌋}² for even k (the load is in the row whatever k), else 0.
                let half = self.b.ins().ushr_imm(k, 1);
                let bytes = self.b.ins().ishl_imm(half, 3);
                let p = self.b.ins().iadd(self.base, bytes);
                let m = self.b.ins().load(types::F64, MemFlags::trusted(), p, (r as usize * self.s * 8) as i32);
                let sq = self.b.ins().fmul(m, m);
                let odd = self.b.ins().band_imm(k, 1);
                let zero = self.c(0.0);
                self.b.ins().select(odd, zero, sq)
            }
        };
        self.b.ins().fadd(twice, mid)
    }

    /// `Σ_{j=0}^{k} a_j a_{k−j}` (`square`): the inner sum, then `2a₀ · a_k`.
    fn square(&mut self, r: u32) -> Value {
        let inner = self.square_inner(r);
        let a0 = self.coef(r, Ix::at(0));
        let a0x2 = self.twice(a0);
        let ak = self.coef(r, Ix::K);
        let late = self.b.ins().fmul(a0x2, ak);
        self.b.ins().fadd(inner, late)
    }

    /// `2 · x`, as `x + x` (the same bits, NaN and signed zeros included). An expansion has
    /// more multiplications than additions (the double pendulum at order 11: 934 and 610), and
    /// AMD's Zen cores run the two on separate pipes (two each), so the multiplication pipes
    /// are the busier ones.
    fn twice(&mut self, x: Value) -> Value {
        self.b.ins().fadd(x, x)
    }

    /// `x · (1/k)`.
    fn times_rk(&mut self, x: Value) -> Value {
        let rk = self.rk();
        self.b.ins().fmul(x, rk)
    }

    /// `x · (1/y)`.
    fn times_recip(&mut self, x: Value, y: Value) -> Value {
        let one = self.c(1.0);
        let r = self.b.ins().fdiv(one, y);
        self.b.ins().fmul(x, r)
    }

    /// `(e j − (k − j)) a_j d_{k−j}` summed, times `1/(k a₀)` (`constant_power`).
    fn constant_power(&mut self, a: u32, d: u32, e: f64) -> Value {
        let acc = self.sum(a, Ix::at(1), d, Ix::k(-1), Len::Ix(Ix::K), Weight::Power(e));
        let a0 = self.coef(a, Ix::at(0));
        let kf = self.kf();
        let den = self.b.ins().fmul(a0, kf);
        self.times_recip(acc, den)
    }

    /// `x ∘ y` for an `Add`, `Sub`, `Mul` or `Div` (one IEEE operation, as in the interpreter).
    fn arith(&mut self, op: &Op, x: Value, y: Value) -> Value {
        match op {
            Op::Add { .. } => self.b.ins().fadd(x, y),
            Op::Sub { .. } => self.b.ins().fsub(x, y),
            Op::Mul { .. } => self.b.ins().fmul(x, y),
            Op::Div { .. } => self.b.ins().fdiv(x, y),
            _ => unreachable!("not an arithmetic operation"),
        }
    }

    /// Order 0 of every row: `TaylorTape::run_order0`'s operations (the plain tape's, and the
    /// auxiliary rows), the transcendental functions called through the wrappers the plain
    /// native code calls, so the values are the interpreter's bit for bit.
    fn order0(&mut self) {
        let tape = self.tape;
        for op in tape.ops0() {
            match *op {
                Op::Add { d, a, b } | Op::Sub { d, a, b } | Op::Mul { d, a, b } | Op::Div { d, a, b } => {
                    let (x, y) = (self.at(a, 0), self.at(b, 0));
                    let v = self.arith(op, x, y);
                    self.put_at(d, 0, v);
                }
                Op::Neg { d, a } => {
                    let x = self.at(a, 0);
                    let v = self.b.ins().fneg(x);
                    self.put_at(d, 0, v);
                }
                Op::Sqrt { d, a } => {
                    let x = self.at(a, 0);
                    let v = self.b.ins().sqrt(x);
                    self.put_at(d, 0, v);
                }
                Op::Abs { d, a } => {
                    let x = self.at(a, 0);
                    let v = self.b.ins().fabs(x);
                    self.put_at(d, 0, v);
                }
                Op::Sqr { d, a } => {
                    let x = self.at(a, 0);
                    let v = self.b.ins().fmul(x, x);
                    self.put_at(d, 0, v);
                }
                Op::Scale { d, a, f } => {
                    let x = self.at(a, 0);
                    let fv = self.c(f);
                    let v = self.b.ins().fmul(x, fv);
                    self.put_at(d, 0, v);
                }
                Op::Weigh { d, .. } => {
                    let zero = self.c(0.0);
                    self.put_at(d, 0, zero);
                }
                Op::SinCos { .. } | Op::SinhCosh { .. } | Op::Exp { .. } | Op::Log { .. } | Op::Tan { .. } => {
                    self.elementary0(op)
                }
                Op::Asin { .. }
                | Op::Atan { .. }
                | Op::Erf { .. }
                | Op::Atan2 { .. }
                | Op::Root { .. }
                | Op::PowConst { .. }
                | Op::Power { .. }
                | Op::PowVar { .. } => self.inverse_or_power0(op),
            }
        }
    }

    /// `f(x)` by the native wrapper of a one-argument built-in.
    fn unary(&mut self, f: Func, x: Value) -> Value {
        match wrapper(f) {
            Some(w) => self.call_fn(w as usize, &[x]),
            None => unreachable!("abs and atan2 have their own operations"),
        }
    }

    /// `f(x, y)` for a two-argument wrapper.
    fn binary(&mut self, f: extern "C" fn(f64, f64) -> f64, x: Value, y: Value) -> Value {
        self.call_fn(f as usize, &[x, y])
    }

    /// A call of the `extern "C" fn(f64, …) -> f64` at `addr`; in lane-pair code one call
    /// per lane, on that lane's arguments (so each lane gets the scalar code's bits).
    fn call_fn(&mut self, addr: usize, args: &[Value]) -> Value {
        if !self.lanes {
            return call_f64(self.b, self.call_conv, self.ptr, addr, args);
        }
        let mut lane_call = |lane: u8| {
            let xs: Vec<Value> = args.iter().map(|&x| self.b.ins().extractlane(x, lane)).collect();
            call_f64(self.b, self.call_conv, self.ptr, addr, &xs)
        };
        let (v0, v1) = (lane_call(0), lane_call(1));
        let out = self.b.ins().scalar_to_vector(types::F64X2, v0);
        self.b.ins().insertlane(out, v1, 1)
    }

    /// `(sin x, cos x)` by the `sin_cos` wrapper (per lane in lane-pair code).
    fn sin_cos(&mut self, x: Value) -> (Value, Value) {
        if !self.lanes {
            return call_sin_cos(self.b, self.call_conv, self.ptr, &mut self.sin_cos_slot, x);
        }
        let x0 = self.b.ins().extractlane(x, 0);
        let x1 = self.b.ins().extractlane(x, 1);
        let (s0, c0) = call_sin_cos(self.b, self.call_conv, self.ptr, &mut self.sin_cos_slot, x0);
        let (s1, c1) = call_sin_cos(self.b, self.call_conv, self.ptr, &mut self.sin_cos_slot, x1);
        let (s, c) = (self.b.ins().scalar_to_vector(types::F64X2, s0), self.b.ins().scalar_to_vector(types::F64X2, c0));
        (self.b.ins().insertlane(s, s1, 1), self.b.ins().insertlane(c, c1, 1))
    }

    /// Order 0 of the sine–cosine, hyperbolic, exponential, logarithm and tangent rows.
    fn elementary0(&mut self, op: &Op) {
        let one = self.c(1.0);
        match *op {
            Op::SinCos { s, c, a } => {
                let x = self.at(a, 0);
                let (sv, cv) = self.sin_cos(x);
                self.put_at(s, 0, sv);
                self.put_at(c, 0, cv);
            }
            Op::SinhCosh { s, c, a } => {
                let x = self.at(a, 0);
                let sv = self.unary(Func::Sinh, x);
                let cv = self.unary(Func::Cosh, x);
                self.put_at(s, 0, sv);
                self.put_at(c, 0, cv);
            }
            Op::Exp { d, a } => {
                let x = self.at(a, 0);
                let v = self.unary(Func::Exp, x);
                self.put_at(d, 0, v);
            }
            Op::Log { d, a } => {
                let x = self.at(a, 0);
                let v = self.unary(Func::Log, x);
                self.put_at(d, 0, v);
            }
            Op::Tan { d, a, u, hyp } => {
                // u = 1 − tanh² or 1 + tan².
                let x = self.at(a, 0);
                let v = self.unary(if hyp { Func::Tanh } else { Func::Tan }, x);
                let sq = self.b.ins().fmul(v, v);
                let uv = if hyp { self.b.ins().fsub(one, sq) } else { self.b.ins().fadd(one, sq) };
                self.put_at(d, 0, v);
                self.put_at(u, 0, uv);
            }
            _ => unreachable!("`order0` emits the other operations"),
        }
    }

    /// Order 0 of the inverse functions' and the powers' rows.
    fn inverse_or_power0(&mut self, op: &Op) {
        let one = self.c(1.0);
        match *op {
            Op::Asin { d, a, r, kind } => {
                // r as `ArcKind::root` computes it.
                let x = self.at(a, 0);
                let v = self.unary(kind.func(), x);
                let rv = match kind {
                    ArcKind::Asin | ArcKind::Acos | ArcKind::Asinh => {
                        let sq = self.b.ins().fmul(x, x);
                        let rest = if kind == ArcKind::Asinh {
                            self.b.ins().fadd(one, sq)
                        } else {
                            self.b.ins().fsub(one, sq)
                        };
                        self.b.ins().sqrt(rest)
                    }
                    ArcKind::Acosh => {
                        let below = self.b.ins().fsub(x, one);
                        let above = self.b.ins().fadd(x, one);
                        let (p, q) = (self.b.ins().sqrt(below), self.b.ins().sqrt(above));
                        self.b.ins().fmul(p, q)
                    }
                };
                self.put_at(d, 0, v);
                self.put_at(r, 0, rv);
            }
            Op::Atan { d, a, u, hyp } => {
                // u = 1 + x² (atanh: 1 − x²).
                let x = self.at(a, 0);
                let v = self.unary(if hyp { Func::Atanh } else { Func::Atan }, x);
                let sq = self.b.ins().fmul(x, x);
                let uv = if hyp { self.b.ins().fsub(one, sq) } else { self.b.ins().fadd(one, sq) };
                self.put_at(d, 0, v);
                self.put_at(u, 0, uv);
            }
            Op::Erf { d, a, .. } => {
                let x = self.at(a, 0);
                let v = self.unary(Func::Erf, x);
                self.put_at(d, 0, v);
            }
            Op::Atan2 { d, a, b, u } => {
                // u = x² + y².
                let (x, y) = (self.at(a, 0), self.at(b, 0));
                let v = self.binary(atan2, x, y);
                let (xx, yy) = (self.b.ins().fmul(x, x), self.b.ins().fmul(y, y));
                let uv = self.b.ins().fadd(xx, yy);
                self.put_at(d, 0, v);
                self.put_at(u, 0, uv);
            }
            Op::Root { d, a, q } => {
                let x = self.at(a, 0);
                let qv = self.c(f64::from(q));
                let v = self.binary(real_root, x, qv);
                self.put_at(d, 0, v);
            }
            Op::PowConst { d, a, e } => {
                let (x, y) = (self.at(a, 0), self.at(e, 0));
                let v = self.binary(powf, x, y);
                self.put_at(d, 0, v);
            }
            Op::PowVar { d, a, b, l, m } => {
                // l = ln x, m = y l.
                let (x, y) = (self.at(a, 0), self.at(b, 0));
                let lv = self.unary(Func::Log, x);
                let v = self.binary(powf, x, y);
                let mv = self.b.ins().fmul(y, lv);
                self.put_at(d, 0, v);
                self.put_at(l, 0, lv);
                self.put_at(m, 0, mv);
            }
            Op::Power { d, a, e } => {
                let x = self.at(a, 0);
                let ev = self.c(e);
                let v = self.binary(powf, x, ev);
                self.put_at(d, 0, v);
            }
            _ => unreachable!("`order0` emits the other operations"),
        }
    }

    /// All recurrences at order `k`; the value is the kink flag (an `i8`).
    fn order(&mut self) -> Option<Value> {
        let tape = self.tape;
        let mut kink = self.b.ins().iconst(types::I8, 0);
        let (k, zero) = (Ix::K, Ix::at(0));
        for op in tape.ops() {
            match *op {
                Op::Add { d, a, b } | Op::Sub { d, a, b } => {
                    let (x, y) = (self.coef(a, k), self.coef(b, k));
                    let v = self.arith(op, x, y);
                    self.put(d, v);
                }
                Op::Neg { d, a } => {
                    let x = self.coef(a, k);
                    let v = self.b.ins().fneg(x);
                    self.put(d, v);
                }
                Op::Scale { d, a, f } => {
                    let x = self.coef(a, k);
                    let fv = self.c(f);
                    let v = self.b.ins().fmul(x, fv);
                    self.put(d, v);
                }
                Op::Weigh { d, a } => {
                    let x = self.coef(a, k);
                    let kf = self.kf();
                    let v = self.b.ins().fmul(x, kf);
                    self.put(d, v);
                }
                Op::Mul { d, a, b } => {
                    let v = self.cauchy(a, b);
                    self.put(d, v);
                }
                Op::Sqr { d, a } => {
                    let v = self.square(a);
                    self.put(d, v);
                }
                Op::Div { d, a, b } => {
                    // (a_k − Σ_{i<k} b_{1+i} d_{k−1−i}) · (1/b₀)
                    let acc = self.sum(b, Ix::at(1), d, Ix::k(-1), Len::Ix(Ix::K), Weight::One);
                    let ak = self.coef(a, k);
                    let num = self.b.ins().fsub(ak, acc);
                    let b0 = self.coef(b, zero);
                    let v = self.times_recip(num, b0);
                    self.put(d, v);
                }
                Op::Sqrt { d, a } => {
                    let acc = self.square_inner(d);
                    let ak = self.coef(a, k);
                    let num = self.b.ins().fsub(ak, acc);
                    let d0 = self.coef(d, zero);
                    let den = self.twice(d0);
                    let v = self.times_recip(num, den);
                    self.put(d, v);
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
                | Op::PowVar { .. } => self.function_order(op)?,
                Op::Abs { d, a } => {
                    // a₀ > 0: a_k; a₀ < 0: −a_k; otherwise (0 or NaN) 0 if a_k == 0, else a kink.
                    let (a0, ak) = (self.coef(a, zero), self.coef(a, k));
                    let zero = self.c(0.0);
                    let pos = self.b.ins().fcmp(FloatCC::GreaterThan, a0, zero);
                    let negc = self.b.ins().fcmp(FloatCC::LessThan, a0, zero);
                    let nak = self.b.ins().fneg(ak);
                    let inner = self.b.ins().select(negc, nak, zero);
                    let v = self.b.ins().select(pos, ak, inner);
                    let at_kink = self.b.ins().fcmp(FloatCC::UnorderedOrEqual, a0, zero);
                    let moving = self.b.ins().fcmp(FloatCC::NotEqual, ak, zero);
                    let here = self.b.ins().band(at_kink, moving);
                    kink = self.b.ins().bor(kink, here);
                    self.put(d, v);
                }
            }
        }
        Some(kink)
    }

    /// Order `k` of the cosine (`cosh`) of a pair, from its weighted sum `w`.
    fn cos_order(&mut self, op: &Op, w: Value) -> Value {
        match (op, self.k) {
            // `(x · (1/k)) · (−1)` is `x · (−(1/k))` bit for bit (rounding to nearest
            // commutes with negation): one multiplication less, on the chain from one
            // order to the next.
            (Op::SinCos { .. }, Order::Fixed(k)) => {
                let m = self.c(-(1.0 / k as f64));
                self.b.ins().fmul(w, m)
            }
            (Op::SinCos { .. }, Order::Runtime { .. }) => {
                let cv = self.times_rk(w);
                let m = self.c(-1.0);
                self.b.ins().fmul(cv, m)
            }
            _ => self.times_rk(w),
        }
    }

    /// Whether row `r` is left out at this order: the last of a whole expansion, where
    /// nothing reads it ([`TaylorTape::dead_at_last_order`]).
    fn dead_at_last_order(&self, r: u32) -> bool {
        matches!(self.k, Order::Fixed(k) if Some(k) == self.last_order) && self.dead_last[r as usize]
    }

    /// Order `k` of a function's recurrence (the operations `order` leaves to it); `None` when
    /// a constant exponent's row has no constant.
    fn function_order(&mut self, op: &Op) -> Option<()> {
        let (k, zero) = (Ix::K, Ix::at(0));
        match *op {
            Op::SinCos { s, c, a } | Op::SinhCosh { s, c, a } => {
                if self.dead_at_last_order(c) {
                    let w = self.weighted(a, c);
                    let sv = self.times_rk(w);
                    self.put(s, sv);
                    return Some(());
                }
                if self.dead_at_last_order(s) {
                    let w = self.weighted(a, s);
                    let cv = self.cos_order(op, w);
                    self.put(c, cv);
                    return Some(());
                }
                let w = self.weighted(a, c);
                let sv = self.times_rk(w);
                let w = self.weighted(a, s);
                let cv = self.cos_order(op, w);
                self.put(s, sv);
                self.put(c, cv);
            }
            Op::Exp { d, a } => {
                let w = self.weighted(a, d);
                let v = self.times_rk(w);
                self.put(d, v);
            }
            Op::Log { d, a } => {
                let acc = self.weighted_short(d, a);
                let q = self.times_rk(acc);
                let ak = self.coef(a, k);
                let num = self.b.ins().fsub(ak, q);
                let a0 = self.coef(a, zero);
                let v = self.times_recip(num, a0);
                self.put(d, v);
            }
            Op::Tan { d, a, u, hyp } => {
                let w = self.weighted(a, u);
                let dv = self.times_rk(w);
                self.put(d, dv);
                let sq = self.square(d);
                let uv = if hyp { self.b.ins().fneg(sq) } else { sq };
                self.put(u, uv);
            }
            Op::Erf { d, a, e } => {
                let w = self.weighted(a, e);
                let v = self.times_rk(w);
                let two_over_root_pi = self.c(std::f64::consts::FRAC_2_SQRT_PI);
                let dv = self.b.ins().fmul(v, two_over_root_pi);
                self.put(d, dv);
            }
            Op::Asin { d, a, r, kind } => {
                let sq = self.square(a);
                let sq = if kind.plus_square() { sq } else { self.b.ins().fneg(sq) };
                let inner = self.square_inner(r);
                let num = self.b.ins().fsub(sq, inner);
                let r0 = self.coef(r, zero);
                let den = self.twice(r0);
                let rv = self.times_recip(num, den);
                let ak = self.coef(a, k);
                let ak = if kind.neg() { self.b.ins().fneg(ak) } else { ak };
                let w = self.weighted_short(d, r);
                let q = self.times_rk(w);
                let num = self.b.ins().fsub(ak, q);
                let dv = self.times_recip(num, r0);
                self.put(r, rv);
                self.put(d, dv);
            }
            Op::Atan { d, a, u, hyp } => {
                let uv = self.square(a);
                let uv = if hyp { self.b.ins().fneg(uv) } else { uv };
                let w = self.weighted_short(d, u);
                let q = self.times_rk(w);
                let ak = self.coef(a, k);
                let num = self.b.ins().fsub(ak, q);
                let u0 = self.coef(u, zero);
                let dv = self.times_recip(num, u0);
                self.put(u, uv);
                self.put(d, dv);
            }
            Op::Atan2 { d, a, b, u } => {
                let x = self.square(a);
                let y = self.square(b);
                let uv = self.b.ins().fadd(x, y);
                let x = self.weighted(a, b);
                let y = self.weighted(b, a);
                let num = self.b.ins().fsub(x, y);
                let w = self.weighted_short(d, u);
                let num = self.b.ins().fsub(num, w);
                let kf = self.kf();
                let u0 = self.coef(u, zero);
                let den = self.b.ins().fmul(u0, kf);
                let dv = self.times_recip(num, den);
                self.put(u, uv);
                self.put(d, dv);
            }
            Op::Root { d, a, q } => {
                let v = self.constant_power(a, d, 1.0 / f64::from(q));
                self.put(d, v);
            }
            Op::PowConst { d, a, e } => {
                let v = self.constant_power(a, d, self.tape.row_constant(e)?);
                self.put(d, v);
            }
            Op::Power { d, a, e } => {
                let v = self.constant_power(a, d, e);
                self.put(d, v);
            }
            Op::PowVar { d, a, b, l, m } => {
                let w = self.weighted_short(l, a);
                let q = self.times_rk(w);
                let ak = self.coef(a, k);
                let num = self.b.ins().fsub(ak, q);
                let a0 = self.coef(a, zero);
                let lv = self.times_recip(num, a0);
                self.put(l, lv);
                let mv = self.cauchy(b, l);
                self.put(m, mv);
                let w = self.weighted(m, d);
                let dv = self.times_rk(w);
                self.put(d, dv);
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
            | Op::Abs { .. } => unreachable!("`order` emits the arithmetic and `abs` itself"),
        }
        Some(())
    }
}

/// The Taylor recurrences of a [`TaylorTape`] compiled to machine code for one stride
/// ([`TaylorTape::compile_native`]); clones share the code.
#[derive(Clone, Debug)]
pub struct TaylorNative(pub(super) Arc<NativeTaylor>);
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
    /// [`TaylorOde::native_for`](super::TaylorOde::native_for)).
    pub fn is_whole(&self) -> bool {
        self.0.is_whole()
    }

    /// Whether this is compact code (see [`TaylorTape::compile_native_compact`]).
    pub fn is_compact(&self) -> bool {
        self.0.is_compact()
    }

    /// Runs a whole expansion: orders `0..=max_order` and the state's next order after each
    /// (`c`: the whole scratch of [`TaylorOde::expand`](super::TaylorOde::expand), with the state's order 0 and the
    /// time's orders given).
    pub(super) fn run_expansion(&self, c: &mut [f64]) -> Ran {
        self.0.run_expansion(c)
    }
}
