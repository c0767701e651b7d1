//! When a Taylor tape gets machine code, and which form: the tiering policy between the
//! interpreter, unrolled, whole-expansion and compact code.

use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::{Arc, OnceLock};

use crate::compile::jit::jit_disabled_by_env;

use super::native::{compact_pays, unrolled_terms, NativeTaylor, TaylorNative, MAX_NATIVE_TAYLOR_TERMS};
use super::wide::WideTaylor;
use super::TaylorTape;

/// How many expansions a [`TaylorOde`](super::TaylorOde) with native code switched on
/// ([`TaylorOde::with_native`](super::TaylorOde::with_native)) runs in the interpreter before compiling, so a cold start
/// never waits for Cranelift.
pub const NATIVE_AFTER_EXPANSIONS: usize = 64;
/// The same for a [`TaylorOde`](super::TaylorOde) left at its default: about the number of expansions after
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
/// The native code of a [`TaylorOde`](super::TaylorOde), per order, compiled on demand and shared by clones.
#[derive(Debug)]
pub(super) struct NativeCache {
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
    /// Batch expansions' code per order (`batch.rs`), and the lanes expanded so far without it.
    lanes: Vec<OnceLock<Option<Arc<BatchCode>>>>,
    lane_uses: AtomicUsize,
    /// Whether a batch expansion has run on native code (wide or lane pairs) to its end.
    lanes_ran: AtomicBool,
    /// Whether a batch expansion has run on wide code to its end.
    wide_ran: AtomicBool,
}

/// The machine code of batch expansions of one order.
#[derive(Debug)]
pub(super) enum BatchCode {
    /// The tape's recurrences over 4 or 8 lanes in the host's vector registers (`wide.rs`),
    /// and the work between two orders, one order per call; order 0 and `W₀`'s factor stay in
    /// Rust.
    Wide(WideTaylor),
    /// The whole expansion in Cranelift's 2-lane vectors, one call per pair of lanes
    /// (`NativeTaylor::compile_lanes`): hosts without AVX2, and batches of 2 lanes.
    Pairs(Box<NativeTaylor>),
}
impl NativeCache {
    /// Compact code after `compact_after` expansions, then unrolled code after `after` (small
    /// tapes) or `unroll_after` (large tapes).
    pub(super) fn new(allowed: bool, after: usize, compact_after: usize, unroll_after: usize) -> Arc<NativeCache> {
        let slots = || (0..=MAX_NATIVE_ORDER).map(|_| OnceLock::new()).collect();
        Arc::new(NativeCache {
            allowed,
            after,
            compact_after,
            unroll_after,
            uses: AtomicUsize::new(0),
            by_order: slots(),
            compact: slots(),
            lanes: (0..=MAX_NATIVE_ORDER).map(|_| OnceLock::new()).collect(),
            lane_uses: AtomicUsize::new(0),
            lanes_ran: AtomicBool::new(false),
            wide_ran: AtomicBool::new(false),
        })
    }

    /// The default tiers.
    pub(super) fn auto() -> Arc<NativeCache> {
        NativeCache::new(true, AUTO_NATIVE_AFTER_EXPANSIONS, COMPACT_AFTER_EXPANSIONS, UNROLL_AFTER_EXPANSIONS)
    }
}
/// Orders above this are always interpreted (the integrator's own limit is 100).
const MAX_NATIVE_ORDER: usize = 100;

impl TaylorTape {
    /// Machine code for orders `1..=max_order` of this tape's recurrences, for coefficient
    /// buffers of `stride` (`max_order < stride`): unrolled per order, or compact (see
    /// [`TaylorTape::compile_native_compact`]) when unrolling would make too much code; `None`
    /// when [`crate::compile::NO_JIT_ENV`] is set, the host has no JIT, or the tape is too
    /// large for either form. Its coefficients equal [`TaylorTape::run_order`]'s bit for bit.
    pub fn compile_native(&self, stride: usize, max_order: usize) -> Option<TaylorNative> {
        if jit_disabled_by_env() {
            return None;
        }
        NativeTaylor::compile(self, stride, max_order).map(|code| TaylorNative(Arc::new(code)))
    }

    /// Compact machine code for orders `1..=max_order`: one function taking the order, each
    /// recurrence's sum a loop, so the code grows with the recurrences alone (not with the
    /// square of the order, as unrolled code does). [`TaylorTape::compile_native`] and
    /// [`TaylorOde`](super::TaylorOde) choose it for large tapes of at most 600 recurrences (past that its code
    /// no longer fits in the caches and the interpreter is faster); this asks for it whatever
    /// the size. Same bits as the interpreter.
    pub fn compile_native_compact(&self, stride: usize, max_order: usize) -> Option<TaylorNative> {
        if jit_disabled_by_env() {
            return None;
        }
        NativeTaylor::compile_compact(self, stride, max_order).map(|code| TaylorNative(Arc::new(code)))
    }
}

impl NativeCache {
    /// The final code for `order`, compiled now by `compile` if it is not yet; `None` when
    /// native code is off or the order is out of range.
    pub(super) fn final_code(
        &self,
        order: usize,
        compile: impl FnOnce() -> Option<TaylorNative>,
    ) -> Option<TaylorNative> {
        if !self.allowed || !(2..=MAX_NATIVE_ORDER).contains(&order) {
            return None;
        }
        self.by_order[order].get_or_init(compile).clone()
    }

    /// The code a batch expansion of `order` over `width` lanes runs on, in the tiers of the
    /// final code (a lane counts as one expansion): `None` until then, or when native code is
    /// off or the tape has none (too large to unroll, or `abs`).
    pub(super) fn lanes_tiered(
        &self,
        tape: &TaylorTape,
        order: usize,
        width: usize,
        compile: impl FnOnce() -> Option<BatchCode>,
    ) -> Option<&BatchCode> {
        if !self.allowed || !(2..=MAX_NATIVE_ORDER).contains(&order) {
            return None;
        }
        let slot = &self.lanes[order];
        if let Some(code) = slot.get() {
            return code.as_deref();
        }
        let uses = self.lane_uses.fetch_add(width, Ordering::Relaxed);
        let after = match unrolled_terms(tape, order - 1) {
            t if t <= COMPACT_ABOVE_TERMS => self.after,
            _ => self.unroll_after,
        };
        if uses < after {
            return None;
        }
        slot.get_or_init(|| compile().map(Arc::new)).as_deref()
    }

    /// Records that a batch expansion ran on native code (wide or lane pairs) to its end.
    pub(super) fn note_lanes_ran(&self) {
        if !self.lanes_ran.load(Ordering::Relaxed) {
            self.lanes_ran.store(true, Ordering::Relaxed);
        }
    }

    /// Whether a batch expansion has run on native code (wide or lane pairs) to its end.
    pub(super) fn lanes_ran(&self) -> bool {
        self.lanes_ran.load(Ordering::Relaxed)
    }

    /// Records that a batch expansion ran on wide code to its end.
    pub(super) fn note_wide_ran(&self) {
        if !self.wide_ran.load(Ordering::Relaxed) {
            self.wide_ran.store(true, Ordering::Relaxed);
        }
    }

    /// Whether a batch expansion has run on wide code to its end.
    pub(super) fn wide_ran(&self) -> bool {
        self.wide_ran.load(Ordering::Relaxed)
    }

    /// The code compiled so far for `order` (the final code if it exists, else compact code),
    /// compiling nothing.
    pub(super) fn compiled(&self, order: usize) -> Option<TaylorNative> {
        let slot = |tier: &[OnceLock<Option<TaylorNative>>]| tier.get(order).and_then(|c| c.get().cloned().flatten());
        slot(&self.by_order).or_else(|| slot(&self.compact))
    }

    /// The code an expansion of `order` of `tape` runs on, in the tiers this cache was made
    /// with: the interpreter (`None`), then compact code, then the final code, which
    /// `compile_final` compiles when its time has come.
    pub(super) fn tiered(
        &self,
        tape: &TaylorTape,
        order: usize,
        compile_final: impl FnOnce() -> Option<TaylorNative>,
    ) -> Option<&TaylorNative> {
        if !self.allowed || !(2..=MAX_NATIVE_ORDER).contains(&order) {
            return None;
        }
        let best = &self.by_order[order];
        if let Some(code) = best.get() {
            return code.as_ref();
        }
        let uses = self.uses.fetch_add(1, Ordering::Relaxed);
        let terms = unrolled_terms(tape, order - 1);
        let final_after = match terms {
            t if t <= COMPACT_ABOVE_TERMS => self.after,
            // Too large to unroll at all: the compact code is the final code.
            t if t > MAX_NATIVE_TAYLOR_TERMS => self.compact_after,
            _ => self.unroll_after,
        };
        if uses >= final_after {
            return best.get_or_init(compile_final).as_ref();
        }
        if uses >= self.compact_after && compact_pays(tape) {
            let compact = || tape.compile_native_compact(order + 1, order - 1);
            return self.compact[order].get_or_init(compact).as_ref();
        }
        None
    }
}
