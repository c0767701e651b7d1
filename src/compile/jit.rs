//! The Cranelift plumbing both native back ends share: a JIT module for the host, the module's
//! ownership by the code it holds, and the `extern "C"` wrappers generated code calls for the
//! transcendental functions (each calls exactly what the interpreters call, so both back ends
//! return the same bits).

use std::mem::ManuallyDrop;

use cranelift_codegen::ir::{types, AbiParam, InstBuilder, Signature, StackSlot, StackSlotData, StackSlotKind, Value};
use cranelift_codegen::isa::CallConv;
use cranelift_codegen::settings::{self, Configurable};
use cranelift_frontend::FunctionBuilder;
use cranelift_jit::{JITBuilder, JITModule};
use cranelift_module::default_libcall_names;

use crate::expr::Func;

/// A JIT module for the host, optimising for speed, with its calling convention and pointer
/// type; `extra` are further Cranelift settings. `None` where the host has no Cranelift back
/// end or a setting is refused.
///
/// Plain absolute addresses (`is_pic` off): the wrappers are called through pointers baked into
/// the code, so nothing needs a GOT or a symbol lookup.
pub(super) fn host_module(extra: &[(&str, &str)]) -> Option<(JITModule, CallConv, types::Type)> {
    let mut flags = settings::builder();
    flags.set("opt_level", "speed").ok()?;
    flags.set("is_pic", "false").ok()?;
    for &(name, value) in extra {
        flags.set(name, value).ok()?;
    }
    flags.set("enable_verifier", if cfg!(debug_assertions) { "true" } else { "false" }).ok()?;
    let isa = cranelift_native::builder().ok()?.finish(settings::Flags::new(flags)).ok()?;
    let call_conv = isa.default_call_conv();
    let ptr = isa.pointer_type();
    Some((JITModule::new(JITBuilder::with_isa(isa, default_libcall_names())), call_conv, ptr))
}

/// The environment variable that forces the interpreter for every tape compiled while it is
/// set to anything but `0` or the empty string (for comparisons and for hosts where the JIT
/// misbehaves).
pub const NO_JIT_ENV: &str = "LAGRANGIAN_NO_JIT";
/// Whether [`NO_JIT_ENV`] asks for the interpreter.
pub(super) fn jit_disabled_by_env() -> bool {
    std::env::var_os(NO_JIT_ENV).is_some_and(|v| !v.is_empty() && v != "0")
}
/// A finished JIT module, owned by the compiled code it holds: dropping it frees the code.
/// Only the owner of a generated function's pointer holds one, so when it drops no `&owner`
/// exists and no call through that pointer is running or can start.
pub(super) struct OwnedModule(pub(super) ManuallyDrop<JITModule>);
impl Drop for OwnedModule {
    fn drop(&mut self) {
        // SAFETY: see the type's comment: the owner is being dropped, so no generated function
        // of this module is running; the module is taken exactly once.
        unsafe { ManuallyDrop::take(&mut self.0).free_memory() }
    }
}
/// Calls the `extern "C"` function at `addr` with `f64` arguments, returning one `f64`.
pub(super) fn call_f64(
    b: &mut FunctionBuilder,
    call_conv: CallConv,
    ptr: types::Type,
    addr: usize,
    args: &[Value],
) -> Value {
    let mut sig = Signature::new(call_conv);
    for _ in args {
        sig.params.push(AbiParam::new(types::F64));
    }
    sig.returns.push(AbiParam::new(types::F64));
    let sig = b.import_signature(sig);
    let callee = b.ins().iconst(ptr, addr as i64);
    let call = b.ins().call_indirect(sig, callee, args);
    b.inst_results(call)[0]
}
/// `(sin x, cos x)` by the `sin_cos` wrapper, which writes them to the function's 16-byte
/// stack slot `pair` (made on first use).
pub(super) fn call_sin_cos(
    b: &mut FunctionBuilder,
    call_conv: CallConv,
    ptr: types::Type,
    pair: &mut Option<StackSlot>,
    x: Value,
) -> (Value, Value) {
    let pair =
        *pair.get_or_insert_with(|| b.create_sized_stack_slot(StackSlotData::new(StackSlotKind::ExplicitSlot, 16, 3)));
    let addr = b.ins().stack_addr(ptr, pair, 0);
    let mut sig = Signature::new(call_conv);
    sig.params.push(AbiParam::new(types::F64));
    sig.params.push(AbiParam::new(ptr));
    let sig = b.import_signature(sig);
    let callee = b.ins().iconst(ptr, sin_cos as *const () as usize as i64);
    b.ins().call_indirect(sig, callee, &[x, addr]);
    (b.ins().stack_load(types::F64, pair, 0), b.ins().stack_load(types::F64, pair, 8))
}

/// The wrapper for a one-argument built-in (its [`Spec::native`](crate::func::Spec::native));
/// `None` for `abs` (one native instruction) and `atan2`, which the lowering always emits as
/// its own instruction (a tape with a one-argument `atan2` would stay interpreted).
pub(super) fn wrapper(f: Func) -> Option<extern "C" fn(f64) -> f64> {
    f.spec().native
}
pub(super) extern "C" fn atan2(a: f64, b: f64) -> f64 {
    a.atan2(b)
}
pub(super) extern "C" fn powf(a: f64, b: f64) -> f64 {
    a.powf(b)
}
/// The real odd root, with `q` passed as an exact small integer in an `f64`.
pub(super) extern "C" fn real_root(a: f64, q: f64) -> f64 {
    crate::eval::real_root(a, q as u32)
}
/// `out[0] = sin x`, `out[1] = cos x`.
///
/// # Safety
/// Called only by generated code, with `out` pointing at its own 16-byte stack slot.
extern "C" fn sin_cos(x: f64, out: *mut f64) {
    let (s, c) = x.sin_cos();
    // SAFETY: `out` is the generated function's 8-aligned 16-byte stack slot (see `body`).
    unsafe {
        *out = s;
        *out.add(1) = c;
    }
}

// ---------------------------------------------------------------------------------------------
// Taylor recurrences
// ---------------------------------------------------------------------------------------------
