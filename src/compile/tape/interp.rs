//! The tape's interpreter: one evaluation, a strided or staged one, and batches of
//! [`LANES`] points at a time.

use std::cell::RefCell;

use super::{Instr, Tape};

/// A thread's scratch buffer, and which tape's constants it holds in place.
struct Scratch {
    /// The [`Tape::id`] whose constants sit in their slots, or 0 after any other use.
    owner: u64,
    buf: Vec<f64>,
}
thread_local! {
    static SCRATCH: RefCell<Scratch> = const { RefCell::new(Scratch { owner: 0, buf: Vec::new() }) };
}
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
