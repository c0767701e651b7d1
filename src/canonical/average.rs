//! The averaged Lagrangian (PHYSICS.md §2.5): for a trial path `q(θ, A_1, …)` periodic in the
//! phase `θ`, with `ω = θ'` and `q' ≈ ω ∂q/∂θ`, the exact phase average
//! `⟨L⟩ = (1/2π) ∫_0^{2π} L dθ`, the relations `∂⟨L⟩/∂A_k = 0` and the action
//! `J = ∂⟨L⟩/∂ω`.
//!
//! The average is exact because the integrand is a trigonometric polynomial in `θ`: it is
//! carried as a finite Fourier sum `Σ (a_k cos kθ + b_k sin kθ)` with symbolic coefficients,
//! products are reduced by the product-to-sum identities, and the average is `a_0`. Anything
//! that is not such a polynomial (a bare `θ`, a non-integer frequency, `θ` in a denominator)
//! is refused with the reason.

use std::collections::BTreeMap;

use num_traits::ToPrimitive;

use crate::diff::diff;
use crate::expr::{Expr, Func, Node, Symbol};

use super::reduce::{expand, nonneg_int, normalize};

/// A trial function `coord = expr(θ, amplitudes)`.
#[derive(Clone, Debug)]
pub struct Trial {
    /// The coordinate it replaces.
    pub coord: Symbol,
    /// Its value as a function of the phase.
    pub expr: Expr,
}

/// Why an average was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum AverageError {
    /// The integrand is not 2π-periodic in the phase.
    #[error("the trial function is not 2π-periodic in the phase `{phase}`: {reason}")]
    NotPeriodic {
        /// The phase.
        phase: String,
        /// Where periodicity fails.
        reason: String,
    },
    /// Periodic perhaps, but not a trigonometric polynomial this module averages exactly.
    #[error("cannot average exactly over `{phase}`: `{part}` is not a trigonometric polynomial in the phase")]
    NotTrigPolynomial {
        /// The phase.
        phase: String,
        /// The offending subexpression.
        part: String,
    },
    /// A power too large to multiply out.
    #[error("`{part}`: powers above {limit} of a phase-dependent factor are not multiplied out")]
    TooLarge {
        /// The offending power.
        part: String,
        /// The limit.
        limit: u32,
    },
    /// A velocity of a coordinate without a trial function remains.
    #[error("`{0}` remains after substituting the trial functions: give a trial function for every coordinate")]
    UnreplacedVelocity(String),
}

/// The largest power of a phase-dependent factor multiplied out.
pub const MAX_POWER: u32 = 64;

/// A finite Fourier sum: `(k, is_sin) → coefficient`, with `k ≥ 0` and no `sin 0`.
type Fourier = BTreeMap<(u64, bool), Expr>;

fn add_term(f: &mut Fourier, k: i64, is_sin: bool, c: Expr) {
    if c.is_zero() || (k == 0 && is_sin) {
        return;
    }
    let (k, c) = if k < 0 && is_sin { (-k, c.neg()) } else { (k.abs(), c) };
    let key = (k as u64, is_sin);
    let cur = f.remove(&key).unwrap_or_else(Expr::zero);
    let next = cur.plus(&c);
    if !next.is_zero() {
        f.insert(key, next);
    }
}

fn constant(c: Expr) -> Fourier {
    let mut f = Fourier::new();
    add_term(&mut f, 0, false, c);
    f
}

fn product(a: &Fourier, b: &Fourier) -> Fourier {
    let half = Expr::frac(1, 2);
    let mut out = Fourier::new();
    for (&(k1, s1), c1) in a {
        for (&(k2, s2), c2) in b {
            let c = expand(&c1.times(c2));
            let (k1, k2) = (k1 as i64, k2 as i64);
            let hc = half.times(&c);
            match (s1, s2) {
                (false, false) => {
                    add_term(&mut out, k1 - k2, false, hc.clone());
                    add_term(&mut out, k1 + k2, false, hc);
                }
                (true, true) => {
                    add_term(&mut out, k1 - k2, false, hc.clone());
                    add_term(&mut out, k1 + k2, false, hc.neg());
                }
                (true, false) => {
                    add_term(&mut out, k1 + k2, true, hc.clone());
                    add_term(&mut out, k1 - k2, true, hc);
                }
                (false, true) => {
                    add_term(&mut out, k1 + k2, true, hc.clone());
                    add_term(&mut out, k1 - k2, true, hc.neg());
                }
            }
        }
    }
    out
}

fn fourier(e: &Expr, th: &Symbol) -> Result<Fourier, AverageError> {
    if !e.contains(th) {
        return Ok(constant(e.clone()));
    }
    let phase = th.to_string();
    match e.node() {
        Node::Sym(_) => {
            Err(AverageError::NotPeriodic { phase, reason: format!("`{e}` grows without bound (a secular term)") })
        }
        Node::Add(ts) => {
            let mut out = Fourier::new();
            for t in ts {
                for ((k, s), c) in fourier(t, th)? {
                    add_term(&mut out, k as i64, s, c);
                }
            }
            Ok(out)
        }
        Node::Mul(fs) => {
            let mut acc = constant(Expr::one());
            for f in fs {
                acc = product(&acc, &fourier(f, th)?);
            }
            Ok(acc)
        }
        Node::Pow(b, x) => match x.as_num().and_then(nonneg_int) {
            Some(n) if n > MAX_POWER => Err(AverageError::TooLarge { part: e.to_string(), limit: MAX_POWER }),
            Some(n) => {
                let fb = fourier(b, th)?;
                let mut acc = constant(Expr::one());
                for _ in 0..n {
                    acc = product(&acc, &fb);
                }
                Ok(acc)
            }
            None => Err(AverageError::NotTrigPolynomial { phase, part: e.to_string() }),
        },
        Node::Call(f @ (Func::Sin | Func::Cos), args) => {
            let a = &args[0];
            let k_expr = diff(a, th);
            let Some(r) = k_expr.as_num() else {
                return Err(if k_expr.contains(th) {
                    AverageError::NotTrigPolynomial { phase, part: e.to_string() }
                } else {
                    AverageError::NotPeriodic {
                        phase,
                        reason: format!("the frequency `{k_expr}` of `{e}` is not a known integer"),
                    }
                });
            };
            if !r.is_integer() {
                return Err(AverageError::NotPeriodic {
                    phase,
                    reason: format!("`{e}` has frequency {r}, not an integer, so its period is not 2π"),
                });
            }
            let k = r.to_integer().to_i64().unwrap_or(0);
            let c = normalize(&a.minus(&k_expr.times(&Expr::sym(th.clone()))));
            let (sc, cc) = (Expr::call(Func::Sin, vec![c.clone()]), Expr::call(Func::Cos, vec![c]));
            let mut out = Fourier::new();
            // sin(kθ + c) = sin kθ cos c + cos kθ sin c; cos(kθ + c) = cos kθ cos c − sin kθ sin c.
            if *f == Func::Sin {
                add_term(&mut out, k, true, cc);
                add_term(&mut out, k, false, sc);
            } else {
                add_term(&mut out, k, false, cc);
                add_term(&mut out, k, true, sc.neg());
            }
            Ok(out)
        }
        _ => Err(AverageError::NotTrigPolynomial { phase, part: e.to_string() }),
    }
}

/// `(1/2π) ∫_0^{2π} e dθ`, exactly.
pub fn phase_average(e: &Expr, phase: &Symbol) -> Result<Expr, AverageError> {
    let f = fourier(&expand(e), phase)?;
    Ok(normalize(&f.get(&(0, false)).cloned().unwrap_or_else(Expr::zero)))
}

/// The averaged Lagrangian and what follows from it.
#[derive(Clone, Debug)]
pub struct Averaged {
    /// `⟨L⟩(A_k, ω)`.
    pub lagrangian: Expr,
    /// `(A_k, ∂⟨L⟩/∂A_k)`: each is `0` on the solution.
    pub relations: Vec<(Symbol, Expr)>,
    /// `J = ∂⟨L⟩/∂ω`.
    pub action: Expr,
}

/// Substitutes the trial functions (`q → q(θ)`, `q' → ω ∂q/∂θ`) into `l`, averages over the
/// phase, and differentiates by the amplitudes and the frequency.
pub fn average_lagrangian(
    l: &Expr,
    trials: &[Trial],
    phase: &Symbol,
    frequency: &Symbol,
    amplitudes: &[Symbol],
) -> Result<Averaged, AverageError> {
    let w = Expr::sym(frequency.clone());
    let mut map = std::collections::HashMap::new();
    for t in trials {
        // Check each trial on its own first, so an error names the trial, not its derivative.
        fourier(&expand(&t.expr), phase)?;
        map.insert(t.coord.clone(), t.expr.clone());
        map.insert(t.coord.prime(), w.times(&diff(&t.expr, phase)));
    }
    let sub = l.subs(&map);
    if let Some(s) = sub.free_symbols().into_iter().find(|s| s.primes() > 0) {
        return Err(AverageError::UnreplacedVelocity(s.to_string()));
    }
    let avg = phase_average(&sub, phase)?;
    let relations = amplitudes.iter().map(|a| (a.clone(), normalize(&diff(&avg, a)))).collect();
    let action = normalize(&diff(&avg, frequency));
    Ok(Averaged { lagrangian: avg, relations, action })
}

/// The leading-order solution of the averaged relations in a small parameter `σ`:
/// `ω = ω0 + σ ω1`, each secondary amplitude `B_k = σ b_k`, the principal amplitude `A` free.
#[derive(Clone, Debug)]
pub struct LeadingOrder {
    /// `ω` to first order in `σ`.
    pub frequency: Expr,
    /// Each secondary amplitude to first order in `σ`.
    pub amplitudes: Vec<(Symbol, Expr)>,
}

/// Why the leading-order solution failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum LeadingOrderError {
    /// The zeroth-order relations do not hold at `ω = ω0` with the secondary amplitudes zero.
    #[error("at σ = 0 the relation ∂⟨L⟩/∂{amplitude} = {value} does not vanish for ω = {omega0} and the other amplitudes 0: `{omega0}` is not the unperturbed frequency of this trial")]
    ZerothOrder {
        /// The amplitude whose relation fails.
        amplitude: String,
        /// Its value.
        value: String,
        /// The proposed unperturbed frequency.
        omega0: String,
    },
    /// The first-order equations could not be solved.
    #[error("the first-order equations have no unique solution: {0}")]
    FirstOrder(#[from] super::solve::SolveError),
    /// The principal amplitude is not among the relations.
    #[error("`{0}` is not one of the amplitudes")]
    UnknownAmplitude(String),
}

/// Solves the relations of `avg` to first order in `small` (Poincaré–Lindstedt on the averaged
/// Lagrangian): substitutes `ω = omega0 + σ ω1`, `B_k = σ b_k` for every amplitude except
/// `principal`, checks that the relations vanish at `σ = 0`, and solves the coefficients of `σ¹`
/// (linear in `ω1`, `b_k`) for `ω1` and the `b_k`.
pub fn leading_order(
    avg: &Averaged,
    frequency: &Symbol,
    omega0: &Expr,
    small: &Symbol,
    principal: &Symbol,
) -> Result<LeadingOrder, LeadingOrderError> {
    if !avg.relations.iter().any(|(a, _)| a == principal) {
        return Err(LeadingOrderError::UnknownAmplitude(principal.to_string()));
    }
    let s = Expr::sym(small.clone());
    let w1 = Symbol::new("__omega1");
    let mut map = std::collections::HashMap::new();
    map.insert(frequency.clone(), omega0.plus(&s.times(&Expr::sym(w1.clone()))));
    let mut unknowns = vec![w1.clone()];
    let mut coeff_syms = Vec::new();
    for (a, _) in &avg.relations {
        if a != principal {
            let b = Symbol::new(&format!("__b_{}", a.name()));
            map.insert(a.clone(), s.times(&Expr::sym(b.clone())));
            unknowns.push(b.clone());
            coeff_syms.push((a.clone(), b));
        }
    }
    let mut first = Vec::new();
    for (a, r) in &avg.relations {
        let sub = r.subs(&map);
        let zeroth = normalize(&sub.subs1(small, &Expr::zero()));
        if !super::reduce::decide_zero(&zeroth).is_zero() {
            return Err(LeadingOrderError::ZerothOrder {
                amplitude: a.to_string(),
                value: zeroth.to_string(),
                omega0: omega0.to_string(),
            });
        }
        let mut d1 = normalize(&diff(&sub, small).subs1(small, &Expr::zero()));
        // The principal relation carries a common factor A (the trivial solution A = 0).
        if a == principal {
            d1 = normalize(&d1.over(&Expr::sym(principal.clone())));
        }
        first.push(d1);
    }
    let (sol, _) = super::solve::solve_system(&first, &unknowns)?;
    let get = |u: &Symbol| sol.iter().find(|(v, _)| v == u).map(|(_, e)| e.clone()).unwrap_or_else(Expr::zero);
    let frequency = normalize(&omega0.plus(&s.times(&get(&w1))));
    let amplitudes = coeff_syms.iter().map(|(a, b)| (a.clone(), normalize(&s.times(&get(b))))).collect();
    Ok(LeadingOrder { frequency, amplitudes })
}
