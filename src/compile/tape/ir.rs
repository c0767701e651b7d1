//! The tape itself: its instructions, its options and its accessors.

use std::fmt;
use std::sync::Arc;

use crate::expr::Func;

use crate::compile::jit::jit_disabled_by_env;

use super::native::NativeCode;

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
    pub(super) fn dsts(&self) -> [Option<u32>; 2] {
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

    pub(super) fn srcs(&self) -> [Option<u32>; 2] {
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

    pub(super) fn map_slots(&mut self, src: &impl Fn(u32) -> u32, dst: &mut impl FnMut(u32) -> u32) {
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
    /// [`NO_JIT_ENV`](crate::compile::NO_JIT_ENV) is set (to anything but `0`).
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
    pub(super) input_names: Vec<String>,
    pub(super) consts: Vec<f64>,
    pub(super) instrs: Vec<Instr>,
    pub(super) outputs: Vec<u32>,
    pub(super) n_slots: usize,
    /// Unique per compiled tape (clones share it, and their constants).
    pub(super) id: u64,
    /// The same instructions as machine code, when compiled and available (shared by clones).
    pub(super) native: Option<Arc<NativeCode>>,
}

impl Tape {
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
