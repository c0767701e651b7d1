//! Generating functions F1–F4 (PHYSICS.md §4):
//!
//! | type | variables | old ↔ new relations |
//! |---|---|---|
//! | F1 | `(q, Q, t)` | `p = ∂F1/∂q`, `P = −∂F1/∂Q` |
//! | F2 | `(q, P, t)` | `p = ∂F2/∂q`, `Q = ∂F2/∂P` |
//! | F3 | `(p, Q, t)` | `q = −∂F3/∂p`, `P = −∂F3/∂Q` |
//! | F4 | `(p, P, t)` | `q = −∂F4/∂p`, `Q = ∂F4/∂P` |
//!
//! and `K = H + ∂F/∂t` in every case. A generator's own old variable is `x` (`q` or `p`) and its
//! own new variable `y` (`Q` or `P`); the relations give the old complement of `x` and the new
//! complement of `y`. The inverse map `(q, p)(Q, P, t)` solves the new-complement relations for
//! `x`; the forward map `(Q, P)(q, p, t)` solves the old-complement relations for `y`. `F` is a
//! valid generator only where the mixed Hessian `∂²F/∂x∂y` is non-singular.

use std::fmt;

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::compact::compact;
use super::reduce::{decide_zero, normalize, tidy};
use super::solve::{determinant, solve_system, SolveError};
use super::{time, PhaseSpace};

/// Which of the four generating-function types.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum GeneratorKind {
    /// `F1(q, Q, t)`.
    F1,
    /// `F2(q, P, t)`.
    F2,
    /// `F3(p, Q, t)`.
    F3,
    /// `F4(p, P, t)`.
    F4,
}

impl fmt::Display for GeneratorKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let s = match self {
            GeneratorKind::F1 => "F1",
            GeneratorKind::F2 => "F2",
            GeneratorKind::F3 => "F3",
            GeneratorKind::F4 => "F4",
        };
        f.write_str(s)
    }
}

impl GeneratorKind {
    /// `(x uses old momenta, y uses new momenta)`.
    fn uses_momenta(self) -> (bool, bool) {
        match self {
            GeneratorKind::F1 => (false, false),
            GeneratorKind::F2 => (false, true),
            GeneratorKind::F3 => (true, false),
            GeneratorKind::F4 => (true, true),
        }
    }
    /// Signs `(old complement = s_x ∂F/∂x, new complement = s_y ∂F/∂y)`.
    fn signs(self) -> (i64, i64) {
        match self {
            GeneratorKind::F1 => (1, -1),
            GeneratorKind::F2 => (1, 1),
            GeneratorKind::F3 => (-1, -1),
            GeneratorKind::F4 => (-1, 1),
        }
    }
}

/// A generating function with the phase spaces it maps between.
#[derive(Clone, Debug)]
pub struct Generator {
    /// The type.
    pub kind: GeneratorKind,
    /// `F`.
    pub f: Expr,
    /// Old variables `(q, p)`.
    pub old: PhaseSpace,
    /// New variables `(Q, P)`.
    pub new: PhaseSpace,
}

/// Why a generating function was refused.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum TransformError {
    /// The old and new phase spaces differ in dimension.
    #[error("the old phase space has {old} degrees of freedom but the new one has {new}")]
    DofMismatch {
        /// Old degrees of freedom.
        old: usize,
        /// New degrees of freedom.
        new: usize,
    },
    /// `F` depends on a variable its type excludes (an `F1` containing `p`).
    #[error("a generating function of type {kind} depends on ({allowed}, t) only, but it contains `{symbol}`")]
    WrongVariable {
        /// The type.
        kind: GeneratorKind,
        /// The offending variable.
        symbol: String,
        /// The variables the type allows.
        allowed: String,
    },
    /// `det ∂²F/∂x∂y = 0`: `F` does not define a transformation.
    #[error("not a valid generating function: the mixed Hessian det(∂²{kind}/∂{x}∂{y}) = {hessian} vanishes identically ({check}), so the relations cannot be solved for the new variables")]
    SingularGenerator {
        /// The type.
        kind: GeneratorKind,
        /// Old variables of `F`.
        x: String,
        /// New variables of `F`.
        y: String,
        /// The determinant.
        hessian: String,
        /// How its vanishing was established.
        check: String,
    },
}

/// A relation `lhs = rhs` between old and new variables.
pub type Relation = (Symbol, Expr);

/// Everything a generating function gives.
#[derive(Clone, Debug)]
pub struct GeneratedTransform {
    /// The type.
    pub kind: GeneratorKind,
    /// The implicit relations of the table, each `variable = ±∂F/∂(…)`.
    pub relations: Vec<Relation>,
    /// `(q, p)` as functions of `(Q, P, t)`, or why no closed form was found.
    pub inverse: Result<Vec<Relation>, SolveError>,
    /// `(Q, P)` as functions of `(q, p, t)`, or why no closed form was found.
    pub forward: Result<Vec<Relation>, SolveError>,
    /// Branches chosen while solving.
    pub branches: Vec<String>,
    /// `K(Q, P, t) = H + ∂F/∂t` when a Hamiltonian was given (or why it could not be
    /// expressed in the new variables).
    pub hamiltonian: Option<Result<Expr, SolveError>>,
    /// `H + ∂F/∂t` in the generator's own variables, before inversion.
    pub k_mixed: Option<Expr>,
}

impl Generator {
    /// A generator, with its variables checked.
    pub fn new(kind: GeneratorKind, f: Expr, old: PhaseSpace, new: PhaseSpace) -> Result<Generator, TransformError> {
        if old.dof() != new.dof() {
            return Err(TransformError::DofMismatch { old: old.dof(), new: new.dof() });
        }
        let g = Generator { kind, f, old, new };
        let (x, y) = (g.x(), g.y());
        let (xc, yc) = (g.x_complement(), g.y_complement());
        for s in g.f.free_symbols() {
            if xc.contains(&s) || yc.contains(&s) {
                let allowed: Vec<String> = x.iter().chain(&y).map(|s| s.to_string()).collect();
                return Err(TransformError::WrongVariable { kind, symbol: s.to_string(), allowed: allowed.join(", ") });
            }
        }
        Ok(g)
    }

    fn x(&self) -> Vec<Symbol> {
        if self.kind.uses_momenta().0 {
            self.old.momenta.clone()
        } else {
            self.old.coords.clone()
        }
    }
    fn y(&self) -> Vec<Symbol> {
        if self.kind.uses_momenta().1 {
            self.new.momenta.clone()
        } else {
            self.new.coords.clone()
        }
    }
    fn x_complement(&self) -> Vec<Symbol> {
        if self.kind.uses_momenta().0 {
            self.old.coords.clone()
        } else {
            self.old.momenta.clone()
        }
    }
    fn y_complement(&self) -> Vec<Symbol> {
        if self.kind.uses_momenta().1 {
            self.new.coords.clone()
        } else {
            self.new.momenta.clone()
        }
    }

    /// The mixed Hessian determinant `det ∂²F/∂x_i∂y_j`.
    pub fn hessian_determinant(&self) -> Expr {
        let mut d = Differentiator::new();
        let (x, y) = (self.x(), self.y());
        let m: Vec<Vec<Expr>> = x
            .iter()
            .map(|xi| {
                y.iter()
                    .map(|yj| {
                        let fx = d.diff(&self.f, xi);
                        d.diff(&fx, yj)
                    })
                    .collect()
            })
            .collect();
        normalize(&determinant(&m))
    }

    /// The relations, the maps both ways where the solver finds them, and `K` for `h`.
    pub fn transform(&self, h: Option<&Expr>) -> Result<GeneratedTransform, TransformError> {
        let det = self.hessian_determinant();
        let check = decide_zero(&det);
        let (x, y) = (self.x(), self.y());
        if check.is_zero() {
            let names = |v: &[Symbol]| v.iter().map(|s| s.to_string()).collect::<Vec<_>>().join(",");
            return Err(TransformError::SingularGenerator {
                kind: self.kind,
                x: names(&x),
                y: names(&y),
                hessian: det.to_string(),
                check: check.describe(),
            });
        }
        let (sx, sy) = self.kind.signs();
        let mut d = Differentiator::new();
        let xc = self.x_complement();
        let yc = self.y_complement();
        let old_rel: Vec<Relation> = x
            .iter()
            .zip(&xc)
            .map(|(xi, ci)| (ci.clone(), normalize(&Expr::int(sx).times(&d.diff(&self.f, xi)))))
            .collect();
        let new_rel: Vec<Relation> = y
            .iter()
            .zip(&yc)
            .map(|(yi, ci)| (ci.clone(), normalize(&Expr::int(sy).times(&d.diff(&self.f, yi)))))
            .collect();
        let mut branches = Vec::new();

        // Inverse: solve the new-complement relations for x, then the old complement.
        let inverse = solve_system(&as_equations(&new_rel), &x).map(|(xs, br)| {
            branches.extend(br);
            let xmap: std::collections::HashMap<Symbol, Expr> = xs.iter().cloned().collect();
            let mut out: Vec<Relation> = Vec::new();
            for (s, v) in &xs {
                out.push((s.clone(), compact(&tidy(v))));
            }
            for (c, rhs) in &old_rel {
                out.push((c.clone(), compact(&normalize(&tidy(&rhs.subs(&xmap))))));
            }
            order_like(&out, &self.old)
        });
        // Forward: solve the old-complement relations for y, then the new complement.
        let forward = solve_system(&as_equations(&old_rel), &y).map(|(ys, br)| {
            branches.extend(br);
            let ymap: std::collections::HashMap<Symbol, Expr> = ys.iter().cloned().collect();
            let mut out: Vec<Relation> = Vec::new();
            for (s, v) in &ys {
                out.push((s.clone(), compact(&tidy(v))));
            }
            for (c, rhs) in &new_rel {
                out.push((c.clone(), compact(&normalize(&tidy(&rhs.subs(&ymap))))));
            }
            order_like(&out, &self.new)
        });

        let (k_mixed, hamiltonian) = match h {
            None => (None, None),
            Some(h) => {
                // H with the old complement replaced, plus ∂F/∂t: a function of (x, y, t).
                let cmap: std::collections::HashMap<Symbol, Expr> = old_rel.iter().cloned().collect();
                let mixed = normalize(&h.subs(&cmap).plus(&d.diff(&self.f, &time())));
                let k = match &inverse {
                    Ok(inv) => {
                        let xmap: std::collections::HashMap<Symbol, Expr> =
                            inv.iter().filter(|(s, _)| x.contains(s)).cloned().collect();
                        Ok(compact(&normalize(&tidy(&mixed.subs(&xmap)))))
                    }
                    Err(e) => Err(e.clone()),
                };
                (Some(mixed), Some(k))
            }
        };
        let mut relations = old_rel;
        relations.extend(new_rel);
        Ok(GeneratedTransform { kind: self.kind, relations, inverse, forward, branches, hamiltonian, k_mixed })
    }
}

/// Why a numeric evaluation of the map failed.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum NumericMapError {
    /// A symbol has no value.
    #[error("cannot evaluate the relations: {0}")]
    Eval(String),
    /// Newton's method did not converge from the guess.
    #[error("Newton's method did not converge from the initial guess (residual {residual:.3e} after {iterations} iterations); try another guess")]
    NoConvergence {
        /// The last residual norm.
        residual: f64,
        /// Iterations done.
        iterations: usize,
    },
    /// The Jacobian of the relations is singular at an iterate.
    #[error("the Jacobian of the relations is singular at the current iterate")]
    Singular,
    /// The value or guess has the wrong length.
    #[error("expected {expected} values, got {got}")]
    Length {
        /// Expected count.
        expected: usize,
        /// Given count.
        got: usize,
    },
    /// Ctrl-C (the process-wide [`crate::cancel`] token) stopped the iteration.
    #[error("interrupted after {0} Newton iterations")]
    Interrupted(usize),
}

impl Generator {
    /// The generator's old variables at a point of the new ones, from the closed-form inverse
    /// of `t` (`None` when it has none, or it is not finite there). The relations of a
    /// generating function often have several roots (F1 = ½ m ω q² cot Q is even in `q`, so
    /// `(q, p)` and `(−q, −p)` both satisfy them); starting Newton's method of
    /// [`Generator::numeric_inverse`] here puts its answer on the branch the printed inverse
    /// map took, so the two never disagree.
    pub fn inverse_branch_guess(
        &self,
        t: &GeneratedTransform,
        new_values: &[f64],
        params: &crate::eval::Env,
    ) -> Option<Vec<f64>> {
        let inverse = t.inverse.as_ref().ok()?;
        let mut env = params.clone();
        for (s, v) in self.new.variables().iter().zip(new_values) {
            env.insert(s.to_string(), *v);
        }
        self.x()
            .iter()
            .map(|xi| {
                let (_, e) = inverse.iter().find(|(s, _)| s == xi)?;
                crate::eval::eval(e, &env).ok().filter(|v| v.is_finite())
            })
            .collect()
    }

    /// The inverse map at one point, numerically, for when no closed form exists: given the new
    /// variables (`new_values`: `Q_1…Q_n, P_1…P_n`) and values for `t` and the parameters in
    /// `params`, solves the new-complement relations for the generator's old variables by
    /// Newton's method from `guess`, then evaluates the old complement. Returns
    /// `q_1…q_n, p_1…p_n`.
    pub fn numeric_inverse(
        &self,
        new_values: &[f64],
        params: &crate::eval::Env,
        guess: &[f64],
    ) -> Result<Vec<f64>, NumericMapError> {
        let n = self.old.dof();
        if new_values.len() != 2 * n || guess.len() != n {
            let (expected, got) = if new_values.len() != 2 * n { (2 * n, new_values.len()) } else { (n, guess.len()) };
            return Err(NumericMapError::Length { expected, got });
        }
        let (sx, sy) = self.kind.signs();
        let mut d = Differentiator::new();
        let (x, y, yc) = (self.x(), self.y(), self.y_complement());
        let eqs: Vec<Expr> = y
            .iter()
            .zip(&yc)
            .map(|(yi, ci)| Expr::sym(ci.clone()).minus(&Expr::int(sy).times(&d.diff(&self.f, yi))))
            .collect();
        let jac: Vec<Vec<Expr>> = eqs.iter().map(|e| x.iter().map(|xi| d.diff(e, xi)).collect()).collect();
        let mut env = params.clone();
        for (s, v) in self.new.variables().iter().zip(new_values) {
            env.insert(s.to_string(), *v);
        }
        let mut xs = guess.to_vec();
        let ev = |e: &Expr, env: &crate::eval::Env| {
            crate::eval::eval(e, env).map_err(|e| NumericMapError::Eval(e.to_string()))
        };
        let mut residual = f64::INFINITY;
        for it in 0..100 {
            crate::cancel::check().map_err(|_| NumericMapError::Interrupted(it))?;
            for (s, v) in x.iter().zip(&xs) {
                env.insert(s.to_string(), *v);
            }
            let f: Vec<f64> = eqs.iter().map(|e| ev(e, &env)).collect::<Result<_, _>>()?;
            residual = f.iter().map(|v| v * v).sum::<f64>().sqrt();
            let scale = 1.0 + xs.iter().map(|v| v.abs()).fold(0.0, f64::max);
            if residual <= 1e-14 * scale {
                let mut out = vec![0.0; 2 * n];
                let (x_is_p, _) = self.kind.uses_momenta();
                for i in 0..n {
                    let c = ev(&Expr::int(sx).times(&d.diff(&self.f, &x[i])), &env)?;
                    if x_is_p {
                        out[i] = c;
                        out[n + i] = xs[i];
                    } else {
                        out[i] = xs[i];
                        out[n + i] = c;
                    }
                }
                return Ok(out);
            }
            let jm: Vec<f64> = jac.iter().flatten().map(|e| ev(e, &env)).collect::<Result<_, _>>()?;
            let m = nalgebra::DMatrix::from_row_slice(n, n, &jm);
            let rhs = nalgebra::DVector::from_vec(f);
            let step = m.lu().solve(&rhs).ok_or(NumericMapError::Singular)?;
            for (xi, si) in xs.iter_mut().zip(step.iter()) {
                *xi -= si;
            }
            if it == 99 {
                break;
            }
        }
        Err(NumericMapError::NoConvergence { residual, iterations: 100 })
    }
}

fn as_equations(rel: &[Relation]) -> Vec<Expr> {
    rel.iter().map(|(s, e)| Expr::sym(s.clone()).minus(e)).collect()
}

/// Orders relations as the phase space lists its variables: coordinates, then momenta.
fn order_like(rel: &[Relation], ps: &PhaseSpace) -> Vec<Relation> {
    ps.variables().iter().filter_map(|v| rel.iter().find(|(s, _)| s == v).cloned()).collect()
}
