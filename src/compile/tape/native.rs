//! The native back end: a [`Tape`] compiled to machine code with Cranelift.
//!
//! The tape is already a flat, common-subexpression-eliminated instruction list over slots,
//! so code generation is a single pass: each slot maps to the SSA value last written to it,
//! every instruction becomes one Cranelift instruction (or one call), and the whole tape is
//! one straight-line basic block. Cranelift's register allocator then keeps the slots in
//! machine registers and spills to the native stack; there is no scratch buffer, no
//! thread-local state and no instruction dispatch left at run time.
//!
//! The generated function has the host's C calling convention and the signature
//!
//! ```text
//! fn(x: *const f64, x_stride: usize, last: f64, out: *mut f64, out_stride: usize)
//! ```
//!
//! Input `i < n_inputs − 1` is read from `x[i · x_stride]`, the last input is the scalar
//! `last` (the time `t` of every right-hand side, so a state slice is passed as is), and
//! output `j` is written to `out[j · out_stride]`. Strides of 1 evaluate one contiguous
//! state; a stride of `points` evaluates one point of a structure-of-arrays batch in place.
//!
//! **Same numbers as the interpreter.** `+ − · /`, `√`, negation and `abs` are single IEEE
//! operations, correctly rounded in both back ends, and Cranelift neither reassociates nor
//! fuses floating-point operations (no FMA contraction), so they agree bit for bit. Every
//! transcendental calls one of the `extern "C"` wrappers below, which call the same Rust
//! functions (`Func::eval`, `f64::sin_cos`, `powf`, `atan2`) the interpreter calls, so those
//! agree bit for bit too. `tests/it/compile/native.rs` checks both claims on random inputs.
//!
//! **Failure is not an error.** An unsupported host, a Cranelift error, an allocation or
//! `mprotect` failure, or a tape larger than [`MAX_NATIVE_INSTRS`] makes [`NativeCode::compile`]
//! return `None` and the tape stays interpreted; nothing here panics out to the caller
//! (a panic inside Cranelift is caught and treated the same way).

use std::mem::ManuallyDrop;
use std::panic::{catch_unwind, AssertUnwindSafe};

use cranelift_codegen::ir::condcodes::FloatCC;
use cranelift_codegen::ir::{types, AbiParam, InstBuilder, MemFlags, Value};
use cranelift_codegen::isa::CallConv;
use cranelift_frontend::{FunctionBuilder, FunctionBuilderContext};
use cranelift_module::{Linkage, Module};

use crate::expr::Func;

use super::{Instr, Tape};
use crate::compile::jit::{atan2, call_f64, call_sin_cos, host_module, powf, real_root, wrapper, OwnedModule};

/// The signature of a plain generated function (see the module documentation).
type NativeFn = unsafe extern "C" fn(*const f64, usize, f64, *mut f64, usize);
/// The signature of a [`Epilogue::LagrangianSolve`] function: returns 1 when the fast path's
/// result is valid.
type NativeSolveFn = unsafe extern "C" fn(*const f64, usize, f64, *mut f64, usize) -> i32;
/// What the generated function does with the tape's outputs.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Epilogue {
    /// Output `j` to `out[j · out_stride]`.
    Plain,
    /// For the unrolled `W q'' = F` solve tape of `n` degrees of freedom (outputs: `q''`, the
    /// Cholesky pivots, the diagonal of `W`; inputs `q, q', t`): write the whole derivative
    /// `(q', q'')` to `out` and return whether the pivots are safely positive (above
    /// `n·ε·max W_jj`, the threshold of the pivoting solve) and `q''` is finite. The caller
    /// falls back to the pivoting solve otherwise, so a right-hand side call is one call of
    /// this function and nothing else. `check_pivots: false` leaves the pivot test out (only
    /// finiteness is checked): the caller has proven it once at compile time, for a constant `W`.
    LagrangianSolve { n: usize, check_pivots: bool },
}
/// Tapes longer than this stay interpreted: Cranelift's compile time grows faster than
/// linearly with one huge basic block, and such tapes (Jacobians of long chains) are not
/// the hot path.
pub(crate) const MAX_NATIVE_INSTRS: usize = 60_000;
/// Machine code for one tape, and the JIT module that owns the memory it lives in.
///
/// The function pointer is only reachable through `&NativeCode` ([`NativeCode::call`]), and
/// the module is freed only in `Drop`, so no call can outlive the code. Tapes hold this in an
/// `Arc`, so clones of a tape share one copy of the code.
pub(crate) struct NativeCode {
    /// Entry point, of type [`NativeFn`] or [`NativeSolveFn`] according to `epilogue`.
    func: *const u8,
    epilogue: Epilogue,
    /// Never touched after construction; frees the code when dropped.
    _module: OwnedModule,
    n_inputs: usize,
    n_outputs: usize,
}
// SAFETY: after `compile` returns, the JIT module is never accessed again except by `Drop`
// (which has exclusive access), so its interior `RefCell` and raw pointers are never used
// concurrently; freeing its memory from another thread is a plain deallocation. The code pages
// are read-only and executable, and the generated function only reads `x`, writes `out`
// (both owned by the caller of each call) and its own stack frame, and calls the wrappers
// below, which are pure functions of their arguments. So calling it from many threads at once
// is as safe as calling a pure Rust function.
unsafe impl Send for NativeCode {}
// SAFETY: see `Send`; `&NativeCode` allows only `call`, which shares nothing mutable.
unsafe impl Sync for NativeCode {}
impl std::fmt::Debug for NativeCode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "NativeCode({} inputs, {} outputs)", self.n_inputs, self.n_outputs)
    }
}
impl NativeCode {
    /// Compiles `tape` for the host, or `None` if that is not possible here.
    pub(crate) fn compile(tape: &Tape, epilogue: Epilogue) -> Option<NativeCode> {
        if tape.instrs().len() > MAX_NATIVE_INSTRS {
            return None;
        }
        if let Epilogue::LagrangianSolve { n, .. } = epilogue {
            if tape.n_inputs() != 2 * n + 1 || tape.n_outputs() != 3 * n {
                return None;
            }
        }
        // Cranelift reports errors as values, but an internal panic must not take the caller
        // down either: the interpreter is always there to fall back on.
        catch_unwind(AssertUnwindSafe(|| compile_inner(tape, epilogue))).ok().flatten()
    }

    /// Calls a [`Epilogue::Plain`] function.
    ///
    /// # Safety
    /// `x` must be valid for reads of `x[i · x_stride]` for every `i < n_inputs − 1`, and
    /// `out` valid for writes of `out[j · out_stride]` for every `j < n_outputs`.
    #[inline(always)]
    pub(crate) unsafe fn call(&self, x: *const f64, x_stride: usize, last: f64, out: *mut f64, out_stride: usize) {
        debug_assert_eq!(self.epilogue, Epilogue::Plain);
        // SAFETY: a `Plain` function has the type `NativeFn` (see `compile_inner`).
        let f = std::mem::transmute::<*const u8, NativeFn>(self.func);
        f(x, x_stride, last, out, out_stride)
    }

    /// Calls a [`Epilogue::LagrangianSolve`] function: `true` when `out` holds a valid
    /// derivative.
    ///
    /// # Safety
    /// `x` must be valid for reads of `x[i · x_stride]` for every `i < 2n`, and `out` valid for
    /// writes of `out[j · out_stride]` for every `j < 2n`.
    #[inline(always)]
    pub(crate) unsafe fn call_solve(
        &self,
        x: *const f64,
        x_stride: usize,
        t: f64,
        out: *mut f64,
        out_stride: usize,
    ) -> bool {
        debug_assert!(matches!(self.epilogue, Epilogue::LagrangianSolve { .. }));
        // SAFETY: a `LagrangianSolve` function has the type `NativeSolveFn`.
        let f = std::mem::transmute::<*const u8, NativeSolveFn>(self.func);
        f(x, x_stride, t, out, out_stride) != 0
    }
}
fn compile_inner(tape: &Tape, epilogue: Epilogue) -> Option<NativeCode> {
    let (mut module, call_conv, ptr) = host_module(&[("use_colocated_libcalls", "false")])?;

    let mut ctx = module.make_context();
    let sig = &mut ctx.func.signature;
    sig.call_conv = call_conv;
    for ty in [ptr, ptr, types::F64, ptr, ptr] {
        sig.params.push(AbiParam::new(ty));
    }
    if epilogue != Epilogue::Plain {
        sig.returns.push(AbiParam::new(types::I32));
    }
    let mut fbc = FunctionBuilderContext::new();
    let id = {
        let mut b = FunctionBuilder::new(&mut ctx.func, &mut fbc);
        let mut em = Emitter::new(&mut b, tape, call_conv, ptr);
        let emitted = em.body(tape, epilogue);
        if emitted.is_some() {
            b.finalize();
        }
        emitted
    }
    .and_then(|_| module.declare_function("tape", Linkage::Export, &ctx.func.signature).ok());
    let defined = id.and_then(|id| module.define_function(id, &mut ctx).ok().map(|_| id));
    module.clear_context(&mut ctx);
    let finalized = defined.and_then(|id| module.finalize_definitions().ok().map(|_| id));
    let Some(id) = finalized else {
        // SAFETY: no pointer into this module was ever handed out.
        unsafe { module.free_memory() };
        return None;
    };
    // The function has exactly the parameter list of `NativeFn` in the host's C calling
    // convention (`default_call_conv`), returning nothing (`Plain`) or an `i32`
    // (`NativeSolveFn`); `call` and `call_solve` transmute it accordingly.
    let func = module.get_finalized_function(id);
    Some(NativeCode {
        func,
        epilogue,
        _module: OwnedModule(ManuallyDrop::new(module)),
        n_inputs: tape.n_inputs(),
        n_outputs: tape.n_outputs(),
    })
}
/// Lowers one tape into the function under construction.
struct Emitter<'a, 'b> {
    b: &'a mut FunctionBuilder<'b>,
    /// The SSA value each slot holds right now (`None`: not yet written).
    slots: Vec<Option<Value>>,
    call_conv: CallConv,
    ptr: types::Type,
}
impl<'a, 'b> Emitter<'a, 'b> {
    fn new(b: &'a mut FunctionBuilder<'b>, tape: &Tape, call_conv: CallConv, ptr: types::Type) -> Self {
        Emitter { b, slots: vec![None; tape.scratch_len()], call_conv, ptr }
    }

    /// The value in slot `s`. Tapes are in definition order, so every slot read has been
    /// written (an input, a constant or an earlier result); `None` would be a compiler bug,
    /// and makes the tape stay interpreted.
    fn get(&self, s: u32) -> Option<Value> {
        self.slots.get(s as usize).copied().flatten()
    }

    fn set(&mut self, s: u32, v: Value) {
        self.slots[s as usize] = Some(v);
    }

    fn body(&mut self, tape: &Tape, epilogue: Epilogue) -> Option<()> {
        let block = self.b.create_block();
        self.b.append_block_params_for_function_params(block);
        self.b.switch_to_block(block);
        self.b.seal_block(block);
        let params = self.b.block_params(block).to_vec();
        let (x, xs, last, out, os) = (params[0], params[1], params[2], params[3], params[4]);
        let flags = MemFlags::trusted();
        let ni = tape.n_inputs();
        if ni > 0 {
            let xs8 = self.b.ins().ishl_imm(xs, 3);
            let mut p = x;
            for i in 0..ni - 1 {
                if i > 0 {
                    p = self.b.ins().iadd(p, xs8);
                }
                let v = self.b.ins().load(types::F64, flags, p, 0);
                self.set(i as u32, v);
            }
            self.set((ni - 1) as u32, last);
        }
        for (k, &c) in tape.consts().iter().enumerate() {
            let v = self.b.ins().f64const(c);
            self.set((ni + k) as u32, v);
        }
        // sin_cos returns through a 16-byte frame slot, made only when needed (a tape without
        // calls then needs no stack frame at all).
        let mut pair = None;
        for ins in tape.instrs() {
            match *ins {
                Instr::Add { d, a, b } => {
                    let (x, y) = (self.get(a)?, self.get(b)?);
                    let v = self.b.ins().fadd(x, y);
                    self.set(d, v);
                }
                Instr::Sub { d, a, b } => {
                    let (x, y) = (self.get(a)?, self.get(b)?);
                    let v = self.b.ins().fsub(x, y);
                    self.set(d, v);
                }
                Instr::Mul { d, a, b } => {
                    let (x, y) = (self.get(a)?, self.get(b)?);
                    let v = self.b.ins().fmul(x, y);
                    self.set(d, v);
                }
                Instr::Div { d, a, b } => {
                    let (x, y) = (self.get(a)?, self.get(b)?);
                    let v = self.b.ins().fdiv(x, y);
                    self.set(d, v);
                }
                Instr::Neg { d, a } => {
                    let x = self.get(a)?;
                    let v = self.b.ins().fneg(x);
                    self.set(d, v);
                }
                Instr::Sqrt { d, a } => {
                    let x = self.get(a)?;
                    let v = self.b.ins().sqrt(x);
                    self.set(d, v);
                }
                Instr::Call { d, f: Func::Abs, a } => {
                    let x = self.get(a)?;
                    let v = self.b.ins().fabs(x);
                    self.set(d, v);
                }
                Instr::Call { d, f, a } => {
                    let x = self.get(a)?;
                    let v = self.call(wrapper(f)? as usize, &[x]);
                    self.set(d, v);
                }
                Instr::Atan2 { d, a, b } => {
                    let (x, y) = (self.get(a)?, self.get(b)?);
                    let v = self.call(atan2 as *const () as usize, &[x, y]);
                    self.set(d, v);
                }
                Instr::Powf { d, a, b } => {
                    let (x, y) = (self.get(a)?, self.get(b)?);
                    let v = self.call(powf as *const () as usize, &[x, y]);
                    self.set(d, v);
                }
                Instr::Root { d, a, q } => {
                    let x = self.get(a)?;
                    let qv = self.b.ins().f64const(f64::from(q));
                    let v = self.call(real_root as *const () as usize, &[x, qv]);
                    self.set(d, v);
                }
                Instr::SinCos { s, c, a } => {
                    let x = self.get(a)?;
                    let (sv, cv) = call_sin_cos(self.b, self.call_conv, self.ptr, &mut pair, x);
                    self.set(s, sv);
                    self.set(c, cv);
                }
            }
        }
        let os8 = self.b.ins().ishl_imm(os, 3);
        let (n, check_pivots) = match epilogue {
            Epilogue::Plain => {
                let mut p = out;
                for j in 0..tape.n_outputs() {
                    if j > 0 {
                        p = self.b.ins().iadd(p, os8);
                    }
                    let v = self.get(tape.output_slot(j) as u32)?;
                    self.b.ins().store(flags, v, p, 0);
                }
                self.b.ins().return_(&[]);
                return Some(());
            }
            Epilogue::LagrangianSolve { n, check_pivots } => (n, check_pivots),
        };
        // out = (q', q''): the velocities are input slots n..2n.
        let mut p = out;
        for i in 0..2 * n {
            if i > 0 {
                p = self.b.ins().iadd(p, os8);
            }
            let v = if i < n { self.get((n + i) as u32)? } else { self.get(tape.output_slot(i - n) as u32)? };
            self.b.ins().store(flags, v, p, 0);
        }
        // The check of `LagrangianRhs::fast_ok`, in the same order of operations:
        // tol = (n·ε)·max_j W_jj; ok = ∧_j (d_j > tol) ∧ (q''_j − q''_j == 0, i.e. finite).
        // `fmax` propagates a NaN where `f64::max` skips it; a NaN diagonal makes the pivots
        // NaN as well, so both reject the state and the caller takes the pivoting path.
        let zero = self.b.ins().f64const(0.0);
        let mut ok = self.b.ins().iconst(types::I8, 1);
        if check_pivots {
            let mut scale = self.b.ins().f64const(0.0);
            for j in 0..n {
                let wjj = self.get(tape.output_slot(2 * n + j) as u32)?;
                scale = self.b.ins().fmax(scale, wjj);
            }
            let k = self.b.ins().f64const(n as f64 * f64::EPSILON);
            let tol = self.b.ins().fmul(k, scale);
            for j in 0..n {
                let d = self.get(tape.output_slot(n + j) as u32)?;
                let pos = self.b.ins().fcmp(FloatCC::GreaterThan, d, tol);
                ok = self.b.ins().band(ok, pos);
            }
        }
        for j in 0..n {
            let a = self.get(tape.output_slot(j) as u32)?;
            let diff = self.b.ins().fsub(a, a);
            let finite = self.b.ins().fcmp(FloatCC::Equal, diff, zero);
            ok = self.b.ins().band(ok, finite);
        }
        let ok = self.b.ins().uextend(types::I32, ok);
        self.b.ins().return_(&[ok]);
        Some(())
    }

    /// Calls the `extern "C"` function at `addr` with `f64` arguments, returning one `f64`.
    fn call(&mut self, addr: usize, args: &[Value]) -> Value {
        call_f64(self.b, self.call_conv, self.ptr, addr, args)
    }
}
