//! Lowering: expressions to a tape (value numbering, power chains, constant folding), then
//! register allocation by a liveness scan.

use std::collections::{HashMap, HashSet};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

use num_traits::ToPrimitive;

use crate::eval::eval_with;
use crate::expr::{Expr, Func, Node, Rational, Symbol};

use super::native::{Epilogue, NativeCode};
use super::{CompileOptions, Instr, Tape};
use crate::compile::error::CompileError;

/// The deepest expression the (recursive) lowering accepts before reporting an error instead
/// of risking the stack.
const MAX_DEPTH: usize = 1_000;
/// Largest integer exponent turned into a multiplication chain; larger ones use `powf`.
const MAX_CHAIN_EXP: i64 = 64;
/// Tape identities, so a thread's scratch knows whose constants it holds.
static NEXT_TAPE_ID: AtomicU64 = AtomicU64::new(1);

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
            Node::Num(_) | Node::Pi => true,
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
                Node::Num(_) | Node::Pi => unreachable_const(),
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
