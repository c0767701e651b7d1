//! Numeric evaluation of an expression at a point, in `f64`.
//!
//! This is the reference evaluator: simple, recursive over the DAG with a memo so shared
//! subexpressions are computed once. Fast repeated evaluation is the compiler's job.

use std::collections::HashMap;
use std::fmt;

use num_traits::ToPrimitive;

use crate::expr::{Expr, Node, Rational, Symbol};

/// The real `q`-th root of `x` for odd `q`: negative for negative `x`, so that `(-8)^(1/3)`
/// is `-2` numerically as it is symbolically (the simplifier takes real odd roots; `powf`
/// would give NaN). `cbrt` for `q = 3`. Shared by this evaluator and the compiled tape (and
/// its native code), so all three agree bit for bit.
pub fn real_root(x: f64, q: u32) -> f64 {
    match q {
        1 => x,
        3 => x.cbrt(),
        _ => {
            let r = x.abs().powf(1.0 / f64::from(q));
            if x < 0.0 {
                -r
            } else {
                r
            }
        }
    }
}

/// `(p, q)` when the exponent `r = p/q` has an odd denominator `q > 1` and both fit the
/// root-then-power evaluation (`|p| ≤ 64`, `q < 2³¹`), so that `x^r = (x^(1/q))^p` is real
/// for negative `x`.
pub(crate) fn odd_root_exponent(r: &Rational) -> Option<(i32, u32)> {
    let q = r.denom().to_u32()?;
    if q < 3 || q % 2 == 0 || q > i32::MAX as u32 {
        return None;
    }
    let p = r.numer().to_i32().filter(|p| p.abs() <= 64)?;
    Some((p, q))
}

/// Why an expression has no numeric value.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum EvalError {
    /// A symbol has no value in the environment.
    Unbound(String),
    /// A declared function (`V(r)`) has no numeric definition.
    UndefinedFunction(String),
    /// The expression is undefined (`1/0`).
    Undefined,
}

impl fmt::Display for EvalError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            EvalError::Unbound(s) => write!(f, "`{s}` has no value"),
            EvalError::UndefinedFunction(s) => write!(f, "the declared function `{s}` has no numeric definition"),
            EvalError::Undefined => write!(f, "the expression is undefined"),
        }
    }
}

impl std::error::Error for EvalError {}

/// Values for symbols, keyed by their plain spelling (`x`, `θ'`, `p_x`).
pub type Env = HashMap<String, f64>;

/// Converts an exact rational to the nearest `f64` (infinite beyond the range).
pub fn rational_to_f64(r: &Rational) -> f64 {
    r.to_f64().unwrap_or_else(|| {
        // Huge numerators and denominators: divide their leading bits.
        let shift = r.numer().bits().max(r.denom().bits()).saturating_sub(1000);
        let n = (r.numer() >> shift).to_f64().unwrap_or(f64::NAN);
        let d = (r.denom() >> shift).to_f64().unwrap_or(f64::NAN);
        n / d
    })
}

/// Evaluates `e` with the symbol values in `env`.
pub fn eval(e: &Expr, env: &Env) -> Result<f64, EvalError> {
    let mut memo: HashMap<Expr, f64> = HashMap::new();
    eval_rec(e, &|s: &Symbol| env.get(&s.to_string()).copied(), &mut memo)
}

/// Evaluates `e` with symbol values from a lookup function.
pub fn eval_with(e: &Expr, lookup: &dyn Fn(&Symbol) -> Option<f64>) -> Result<f64, EvalError> {
    let mut memo: HashMap<Expr, f64> = HashMap::new();
    eval_rec(e, lookup, &mut memo)
}

fn eval_rec(
    e: &Expr,
    lookup: &dyn Fn(&Symbol) -> Option<f64>,
    memo: &mut HashMap<Expr, f64>,
) -> Result<f64, EvalError> {
    if let Some(v) = memo.get(e) {
        return Ok(*v);
    }
    let v = match e.node() {
        Node::Num(r) => rational_to_f64(r),
        Node::Pi => std::f64::consts::PI,
        Node::Sym(s) => lookup(s).ok_or_else(|| EvalError::Unbound(s.to_string()))?,
        Node::Add(ts) => {
            let mut acc = 0.0;
            for t in ts {
                acc += eval_rec(t, lookup, memo)?;
            }
            acc
        }
        Node::Mul(fs) => {
            let mut acc = 1.0;
            for f in fs {
                acc *= eval_rec(f, lookup, memo)?;
            }
            acc
        }
        Node::Pow(b, x) => {
            let bv = eval_rec(b, lookup, memo)?;
            match x.as_num() {
                Some(r) if r.is_integer() && r.numer().bits() < 31 => bv.powi(r.to_integer().to_i32().unwrap_or(0)),
                Some(r) if *r == Rational::new(1.into(), 2.into()) => bv.sqrt(),
                Some(r) if bv < 0.0 => match odd_root_exponent(r) {
                    Some((p, q)) => real_root(bv, q).powi(p),
                    None => bv.powf(eval_rec(x, lookup, memo)?),
                },
                _ => bv.powf(eval_rec(x, lookup, memo)?),
            }
        }
        Node::Call(f, args) => {
            let mut vals = [0.0; 2];
            for (slot, a) in vals.iter_mut().zip(args) {
                *slot = eval_rec(a, lookup, memo)?;
            }
            f.eval(&vals[..args.len()])
        }
        Node::Apply { name, .. } => return Err(EvalError::UndefinedFunction(name.to_string())),
        Node::Undefined => return Err(EvalError::Undefined),
    };
    memo.insert(e.clone(), v);
    Ok(v)
}
