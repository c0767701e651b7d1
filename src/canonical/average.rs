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

use num_traits::{Signed, ToPrimitive};

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
    /// Two trial functions for one coordinate: which one was meant is not guessed.
    #[error("`{0}` has two trial functions: give one per coordinate")]
    TrialGivenTwice(String),
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
        if map.contains_key(&t.coord) {
            return Err(AverageError::TrialGivenTwice(t.coord.to_string()));
        }
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

/// The solution of the averaged relations as a series in a small parameter `σ`:
/// `ω = ω0 + σ ω1 + … + σⁿ ωn`, each secondary amplitude `B_k = σ b_k1 + … + σⁿ b_kn`, the
/// principal amplitude `A` free.
#[derive(Clone, Debug)]
pub struct LeadingOrder {
    /// The order `n` of the series.
    pub order: usize,
    /// `ω` to order `n` in `σ`.
    pub frequency: Expr,
    /// Each secondary amplitude to order `n` in `σ`.
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
    /// The equations of one order could not be solved.
    #[error("the equations of one order in the small parameter have no unique solution: {0}")]
    FirstOrder(#[from] super::solve::SolveError),
    /// The order asked for is 0 or above [`MAX_AVERAGE_ORDER`].
    #[error("the order must be 1..={limit}, not {order}")]
    Order {
        /// Asked.
        order: usize,
        /// [`MAX_AVERAGE_ORDER`].
        limit: usize,
    },
    /// The principal amplitude is not among the relations.
    #[error("`{0}` is not one of the amplitudes")]
    UnknownAmplitude(String),
}

/// The most orders [`leading_order`] solves for: each order differentiates the relations once
/// more in `σ`, and the terms grow fast.
pub const MAX_AVERAGE_ORDER: usize = 4;

/// Solves the relations of `avg` to order `order` in `small` (Poincaré–Lindstedt on the averaged
/// Lagrangian): substitutes `ω = omega0 + σ ω1 + … + σⁿ ωn`, `B_k = σ b_k1 + … + σⁿ b_kn` for every
/// amplitude except `principal`, checks that the relations vanish at `σ = 0`, and solves the
/// coefficients of `σʲ` for `ωj` and the `b_kj`, order by order: each is linear in the unknowns
/// of its order once the lower orders are known.
pub fn leading_order(
    avg: &Averaged,
    frequency: &Symbol,
    omega0: &Expr,
    small: &Symbol,
    principal: &Symbol,
    order: usize,
) -> Result<LeadingOrder, LeadingOrderError> {
    if !avg.relations.iter().any(|(a, _)| a == principal) {
        return Err(LeadingOrderError::UnknownAmplitude(principal.to_string()));
    }
    if !(1..=MAX_AVERAGE_ORDER).contains(&order) {
        return Err(LeadingOrderError::Order { order, limit: MAX_AVERAGE_ORDER });
    }
    let s = Expr::sym(small.clone());
    let secondary: Vec<Symbol> = avg.relations.iter().map(|(a, _)| a.clone()).filter(|a| a != principal).collect();
    // The series found so far: ω and each secondary amplitude, through the orders solved.
    let mut w_series = omega0.clone();
    let mut b_series: Vec<Expr> = vec![Expr::zero(); secondary.len()];
    for k in 1..=order {
        let sk = s.powi(k as i64);
        let w_k = Symbol::new(&format!("__omega{k}"));
        let mut unknowns = vec![w_k.clone()];
        let mut map = std::collections::HashMap::new();
        map.insert(frequency.clone(), w_series.plus(&sk.times(&Expr::sym(w_k.clone()))));
        for (a, series) in secondary.iter().zip(&b_series) {
            let b = Symbol::new(&format!("__b{k}_{}", a.name()));
            map.insert(a.clone(), series.plus(&sk.times(&Expr::sym(b.clone()))));
            unknowns.push(b);
        }
        let mut equations = Vec::new();
        for (a, r) in &avg.relations {
            let sub = r.subs(&map);
            if k == 1 {
                let zeroth = normalize(&sub.subs1(small, &Expr::zero()));
                if !super::reduce::decide_zero(&zeroth).is_zero() {
                    return Err(LeadingOrderError::ZerothOrder {
                        amplitude: a.to_string(),
                        value: zeroth.to_string(),
                        omega0: omega0.to_string(),
                    });
                }
            }
            // The coefficient of σᵏ: the k-th derivative at σ = 0 (the k! does not change the
            // solution of the equation it sets to zero).
            let mut d = sub;
            for _ in 0..k {
                d = diff(&d, small);
            }
            let mut dk = normalize(&d.subs1(small, &Expr::zero()));
            // The principal relation carries a common factor A (the trivial solution A = 0).
            if a == principal {
                dk = normalize(&dk.over(&Expr::sym(principal.clone())));
            }
            equations.push(dk);
        }
        let (sol, _) = super::solve::solve_system(&equations, &unknowns)?;
        let get = |u: &Symbol| sol.iter().find(|(v, _)| v == u).map(|(_, e)| e.clone()).unwrap_or_else(Expr::zero);
        w_series = normalize(&w_series.plus(&sk.times(&get(&w_k))));
        for (series, b) in b_series.iter_mut().zip(&unknowns[1..]) {
            *series = normalize(&series.plus(&sk.times(&get(b))));
        }
    }
    let amplitudes = secondary.into_iter().zip(b_series).collect();
    Ok(LeadingOrder { order, frequency: w_series, amplitudes })
}

/// One point of the relations solved numerically: the principal amplitude, the frequency and
/// the secondary amplitudes (in the order of the relations).
#[derive(Clone, Debug, PartialEq)]
pub struct RelationPoint {
    /// The principal amplitude `A`.
    pub principal: f64,
    /// `ω` at that amplitude.
    pub frequency: f64,
    /// The secondary amplitudes.
    pub amplitudes: Vec<(Symbol, f64)>,
}

/// Why the relations could not be solved numerically.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum RelationsError {
    /// A symbol other than the unknowns and the principal amplitude has no value.
    #[error("`{0}` has no value (give it one: a scene parameter, `--params` or the system's params)")]
    Unbound(String),
    /// Newton's method found no solution near the guess.
    #[error("no solution of the relations near {principal} = {value} (Newton's method from ω = {guess} did not converge); a smaller step between the amplitudes, or a smaller amplitude to start from, would help")]
    NoSolution {
        /// The principal amplitude's name.
        principal: String,
        /// Its value.
        value: f64,
        /// The frequency the iteration started from.
        guess: f64,
    },
    /// The principal amplitude is zero (the trivial solution of its relation).
    #[error("{0} = 0 is the trivial solution; sweep amplitudes away from 0")]
    Trivial(String),
}

/// The relations of `avg` solved numerically for `ω` and the secondary amplitudes at each value
/// of the principal amplitude in `values`, with the other symbols from `params`: Newton's method
/// on the relations (the principal one divided by its amplitude, which removes the trivial
/// solution), started at the first value from `first_guess` (ω; the secondary amplitudes from 0)
/// and at each later value from the solution before it (continuation).
pub fn solve_relations(
    avg: &Averaged,
    frequency: &Symbol,
    principal: &Symbol,
    values: &[f64],
    first_guess: f64,
    params: &dyn Fn(&Symbol) -> Option<f64>,
) -> Result<Vec<RelationPoint>, RelationsError> {
    let unknowns: Vec<Symbol> = std::iter::once(frequency.clone())
        .chain(avg.relations.iter().map(|(a, _)| a.clone()).filter(|a| a != principal))
        .collect();
    let equations: Vec<Expr> = avg
        .relations
        .iter()
        .map(|(a, r)| if a == principal { normalize(&r.over(&Expr::sym(principal.clone()))) } else { r.clone() })
        .collect();
    let jacobian: Vec<Vec<Expr>> = equations.iter().map(|e| unknowns.iter().map(|u| diff(e, u)).collect()).collect();
    let n = unknowns.len();
    let mut x: Vec<f64> = std::iter::once(first_guess).chain(std::iter::repeat(0.0).take(n - 1)).collect();
    let mut out = Vec::with_capacity(values.len());
    for &a in values {
        if a == 0.0 {
            return Err(RelationsError::Trivial(principal.to_string()));
        }
        let guess = x[0];
        let mut solved = false;
        for _ in 0..50 {
            let at = |s: &Symbol| {
                if s == principal {
                    Some(a)
                } else if let Some(k) = unknowns.iter().position(|u| u == s) {
                    Some(x[k])
                } else {
                    params(s)
                }
            };
            let value = |e: &Expr| {
                crate::eval::eval_with(e, &at).map_err(|err| match err {
                    crate::eval::EvalError::Unbound(s) => RelationsError::Unbound(s),
                    _ => RelationsError::NoSolution { principal: principal.to_string(), value: a, guess },
                })
            };
            let mut r: Vec<f64> = equations.iter().map(|e| value(e).map(|v| -v)).collect::<Result<_, _>>()?;
            let mut m: Vec<f64> = jacobian.iter().flatten().map(&value).collect::<Result<_, _>>()?;
            if r.iter().chain(&m).any(|v| !v.is_finite()) || crate::linalg::solve_in_place(&mut m, &mut r, n).is_err() {
                break;
            }
            let (mut dmax, mut scale) = (0.0f64, 0.0f64);
            for (xi, di) in x.iter_mut().zip(&r) {
                *xi += di;
                dmax = dmax.max(di.abs());
                scale = scale.max(xi.abs());
            }
            if dmax <= 1e-13 * scale.max(1e-300) {
                solved = true;
                break;
            }
        }
        if !solved || x.iter().any(|v| !v.is_finite()) {
            return Err(RelationsError::NoSolution { principal: principal.to_string(), value: a, guess });
        }
        out.push(RelationPoint {
            principal: a,
            frequency: x[0],
            amplitudes: unknowns[1..].iter().cloned().zip(x[1..].iter().copied()).collect(),
        });
    }
    Ok(out)
}

/// `avg` written for reading: its content pulled out, then grouped by powers of the symbol named
/// `small` (when given) and, within each power, by monomials of the `amplitudes`, monomials with the same
/// coefficient summed: the anharmonic oscillator's ⟨L⟩ reads
/// `l0² m (A² (ω² − ω0²) + (B² + C²) (9 ω² − ω0²) − σ ω0² (…))/4`, as the notes group it,
/// instead of 13 expanded terms. The result equals `avg` (it is regrouped, never simplified
/// differently); anything that is not a polynomial in the amplitudes is kept with its
/// coefficient.
pub fn grouped(avg: &Expr, small: Option<&str>, amplitudes: &[Symbol]) -> Expr {
    use std::collections::BTreeMap as Map;
    // power of small → [(amplitude monomial, coefficient)], in the order first met.
    let mut by_power: Map<u32, Vec<(Expr, Expr)>> = Map::new();
    for t in expand(avg).terms() {
        let (c, rest) = t.coeff_rest();
        let mut power = 0u32;
        let (mut mono, mut coeff) = (Vec::new(), vec![Expr::num(c)]);
        for f in rest.factors() {
            let (b, x) = f.base_exp();
            let k = x.as_num().filter(|r| r.is_integer() && r.is_positive()).and_then(|r| r.to_integer().to_u32());
            match (b.as_sym(), k) {
                (Some(s), Some(k)) if s.primes() == 0 && Some(s.name()) == small => power += k,
                (Some(s), Some(_)) if amplitudes.contains(s) => mono.push(f.clone()),
                _ => coeff.push(f.clone()),
            }
        }
        let (mono, coeff) = (Expr::mul(mono), Expr::mul(coeff));
        let group = by_power.entry(power).or_default();
        match group.iter_mut().find(|(m, _)| *m == mono) {
            Some((_, c)) => *c = c.plus(&coeff),
            None => group.push((mono, coeff)),
        }
    }
    // The content: the monomial factors common to every term, and the rational content of the
    // lowest power (the notes' ¼ m l0², leaving ¾ inside the σ term).
    let outer = |e: &Expr| -> Expr {
        match crate::algebra::factor_content(e).node() {
            Node::Mul(fs) => Expr::mul(fs.iter().filter(|f| !matches!(f.node(), Node::Add(_))).cloned()),
            _ => Expr::one(),
        }
    };
    let symbolic = |e: Expr| Expr::mul(e.factors().into_iter().filter(|f| f.as_num().is_none()));
    let all = Expr::add(by_power.values().flatten().map(|(m, c)| m.times(c)));
    // The lowest power's terms of lowest degree in the amplitudes (the quadratic part of ⟨L⟩).
    let degree = |m: &Expr| {
        m.factors()
            .iter()
            .map(|f| f.base_exp().1.as_num().and_then(|r| r.to_integer().to_u32()).unwrap_or(0))
            .sum::<u32>()
    };
    let lowest = by_power
        .values()
        .next()
        .map(|g| {
            let d = g.iter().map(|(m, _)| degree(m)).min().unwrap_or(0);
            Expr::add(g.iter().filter(|(m, _)| degree(m) == d).map(|(m, c)| m.times(c)))
        })
        .unwrap_or_else(Expr::one);
    let content = symbolic(outer(&all)).times(&Expr::num(outer(&lowest).coeff_rest().0.abs()));
    if content.is_zero() {
        return avg.clone();
    }
    let sigma = small
        .and_then(|name| avg.free_symbols().into_iter().find(|s| s.primes() == 0 && s.name() == name))
        .map(Expr::sym);
    let mut out = Vec::new();
    for (power, group) in by_power {
        let group: Vec<(Expr, Expr)> = group.into_iter().map(|(m, c)| (m, c.over(&content))).collect();
        // Each power keeps its symbolic content and sign outside and its rationals inside
        // (`− σ ω0² (¾ A⁴ + A³ B + …)`).
        let (c, rest) = outer(&Expr::add(group.iter().map(|(m, c)| m.times(c)))).coeff_rest();
        let unit = if c.is_negative() { rest.neg() } else { rest };
        // Then monomials with the same coefficient are summed, with their common factor
        // pulled out: (9ω² − ω0²)(B² + C²), 3 A² (B² + C²).
        let mut by_coeff: Vec<(Expr, Vec<Expr>)> = Vec::new();
        for (mono, coeff) in group {
            let coeff = crate::algebra::factor_content(&coeff.over(&unit));
            match by_coeff.iter_mut().find(|(c, _)| *c == coeff) {
                Some((_, ms)) => ms.push(mono),
                None => by_coeff.push((coeff, vec![mono])),
            }
        }
        let part = unit.times(&Expr::add(
            by_coeff.into_iter().map(|(c, ms)| c.times(&crate::algebra::factor_content(&Expr::add(ms)))),
        ));
        out.push(match &sigma {
            Some(s) if power > 0 => s.powi(i64::from(power)).times(&part),
            _ => part,
        });
    }
    content.times(&Expr::add(out))
}

/// The relations solved along the principal amplitude, beside their series: what `average … for
/// A in a..b` prints and draws on every front end.
#[derive(Clone, Debug)]
pub struct Sweep {
    /// The solution at each amplitude.
    pub points: Vec<RelationPoint>,
    /// The series' frequency at each amplitude.
    pub series: Vec<f64>,
    /// The order of that series.
    pub order: usize,
}

/// [`solve_relations`] at `values` of `principal`, started from `omega0` (evaluated with
/// `params`), and the series `lo`'s frequency at the same amplitudes.
pub fn sweep(
    avg: &Averaged,
    frequency: &Symbol,
    omega0: &Expr,
    lo: &LeadingOrder,
    principal: &Symbol,
    values: &[f64],
    params: &dyn Fn(&Symbol) -> Option<f64>,
) -> Result<Sweep, RelationsError> {
    let number = |e: &Expr, a: f64| {
        crate::eval::eval_with(e, &|s: &Symbol| if s == principal { Some(a) } else { params(s) }).map_err(|err| {
            match err {
                crate::eval::EvalError::Unbound(s) => RelationsError::Unbound(s),
                other => RelationsError::Unbound(other.to_string()),
            }
        })
    };
    let first = values.first().copied().unwrap_or(0.0);
    let points = solve_relations(avg, frequency, principal, values, number(omega0, first)?, params)?;
    let series = values.iter().map(|&a| number(&lo.frequency, a)).collect::<Result<_, _>>()?;
    Ok(Sweep { points, series, order: lo.order })
}
