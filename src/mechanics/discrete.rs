//! Discrete mechanics (variational integrators): from `L(q, q', t)` a discrete Lagrangian
//! `L_d(q_k, q_{k+1}) ≈ ∫_{t_k}^{t_k + h} L dt`, its discrete Euler–Lagrange equations
//! `D₂L_d(q_{k−1}, q_k) + D₁L_d(q_k, q_{k+1}) = 0` and the discrete Legendre maps
//! `p_k = −D₁L_d(q_k, q_{k+1})`, `p_{k+1} = D₂L_d(q_k, q_{k+1})` (Marsden & West, *Discrete
//! mechanics and variational integrators*, Acta Numerica 10 (2001), §1.2–1.5). The map
//! `(q_k, p_k) → (q_{k+1}, p_{k+1})` they define is symplectic and conserves the discrete
//! Noether momenta of every symmetry of `L_d` (§1.3); this is the link between the
//! difference approximations of §4.7.2 and Hamilton's principle.
//!
//! Names: for a coordinate `x`, `x_0, x_1` are `q_k, q_{k+1}` in `L_d` and the Legendre maps,
//! and `x_0, x_1, x_2` are `q_{k−1}, q_k, q_{k+1}` in the discrete Euler–Lagrange equations;
//! `t` is the time of the first point of each `L_d` (`t_k`), so the equations, at `t_k`,
//! contain `L_d(q_{k−1}, q_k)` at `t − h`.

use std::collections::HashMap;

use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};

use super::system::{time, System};
use super::tidy::tidy;
use super::MechanicsError;

/// The quadrature rule that turns `∫ L dt` over one step into `L_d`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Rule {
    /// `h L((q_k + q_{k+1})/2, (q_{k+1} − q_k)/h, t_k + h/2)`: order 2.
    Midpoint,
    /// `h/2 [L(q_k, v, t_k) + L(q_{k+1}, v, t_k + h)]` with `v = (q_{k+1} − q_k)/h`: order 2
    /// (Störmer–Verlet for `L = ½ q'ᵀ M q' − V(q)`).
    Trapezoid,
    /// Galerkin: the quadratic through `q_k` (at `τ = 0`), an inner control point `Q` (the
    /// value at `τ = ½`) and `q_{k+1}` (at `τ = 1`), integrated by the 2-point Gauss–Legendre
    /// rule (nodes `½ ∓ √3/6`, weights `½`); `L_d` is `L̃(q_k, Q, q_{k+1})` made stationary in
    /// `Q`. Order 4 (Marsden & West 2001, §2.2 "Galerkin methods": `s` Gauss points with
    /// degree-`s` polynomials give order `2s`; the map is the Gauss collocation method).
    Gauss2,
}

impl Rule {
    /// From its name (`midpoint`, `trapezoid`).
    pub fn from_name(name: &str) -> Option<Rule> {
        match name {
            "midpoint" => Some(Rule::Midpoint),
            "trapezoid" | "trapezoidal" => Some(Rule::Trapezoid),
            "gauss2" => Some(Rule::Gauss2),
            _ => None,
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Rule::Midpoint => "midpoint",
            Rule::Trapezoid => "trapezoid",
            Rule::Gauss2 => "gauss2",
        }
    }

    /// The order of the map it gives (2, 2, 4).
    pub fn order(self) -> u32 {
        match self {
            Rule::Midpoint | Rule::Trapezoid => 2,
            Rule::Gauss2 => 4,
        }
    }
}

/// A discrete Lagrangian with its equations.
#[derive(Clone, Debug, PartialEq)]
pub struct Discrete {
    /// The quadrature rule it was built with.
    pub rule: Rule,
    /// The continuous coordinates, in order.
    pub coords: Vec<Symbol>,
    /// `q_k` (`x_0`), one per coordinate.
    pub q0: Vec<Symbol>,
    /// `q_{k+1}` (`x_1`).
    pub q1: Vec<Symbol>,
    /// `q_{k+1}` in the three-point equations (`x_2`).
    pub q2: Vec<Symbol>,
    /// The inner control points `Q` (`x_m`) of a Galerkin rule (`gauss2`), empty for the
    /// one-step rules; `L_d` is then `L̃(q_k, Q, q_{k+1})` with `∂L̃/∂Q = 0`.
    pub inner: Vec<Symbol>,
    /// The step.
    pub h: Expr,
    /// `L_d(q_k, q_{k+1})` at `t = t_k` (`L̃(q_k, Q, q_{k+1})` for a Galerkin rule).
    pub ld: Expr,
    /// `D₁L_d(q_k, q_{k+1})`, one per coordinate (`Q` held fixed: at `∂L̃/∂Q = 0` this is
    /// the derivative of the stationary value).
    pub d1: Vec<Expr>,
    /// `D₂L_d(q_k, q_{k+1})`.
    pub d2: Vec<Expr>,
    /// `∂L̃/∂Q`, one per inner point (each `= 0`); empty for the one-step rules.
    pub dm: Vec<Expr>,
}

/// The names `x_i` of step point `i` for each coordinate.
pub fn point_names(coords: &[Symbol], i: usize) -> Vec<Symbol> {
    point_names_tagged(coords, &i.to_string())
}

/// The names `x_tag` for each coordinate (`x_m`: a Galerkin inner point).
fn point_names_tagged(coords: &[Symbol], tag: &str) -> Vec<Symbol> {
    coords.iter().map(|q| Symbol::new(&format!("{}_{tag}", q.name()))).collect()
}

impl System {
    /// The discrete Lagrangian of the system's `L` by `rule` with step `h` (a symbol or an
    /// exact number), with its slot derivatives.
    pub fn discretize(&self, rule: Rule, h: &Expr) -> Result<Discrete, MechanicsError> {
        let l = self.need_lagrangian("discretize")?;
        self.refuse_velocity_constraints("a discrete Lagrangian (variational integrator)")?;
        if !self.constraints.is_empty() || self.rayleigh.is_some() || self.forces.iter().any(|f| !f.is_zero()) {
            return Err(MechanicsError::WrongKind(
                "discretize takes a Lagrangian alone (no forces, dissipation or constraints)".into(),
            ));
        }
        if h.is_zero() {
            return Err(MechanicsError::WrongKind("the step h of discretize must not be zero".into()));
        }
        // The step is a constant of the scheme: a step in t, or in a coordinate, would be
        // substituted into L with the time and the positions and mean nothing (`--step t`
        // printed `DEL_x: undefined = 0`).
        let (q0, q1, q2) = (point_names(&self.coords, 0), point_names(&self.coords, 1), point_names(&self.coords, 2));
        for s in h.free_symbols() {
            let what = if s.is_time() {
                Some("the time `t`".to_string())
            } else if s.primes() > 0 {
                Some(format!("the velocity `{s}`"))
            } else if self.coords.contains(&s) || self.coords.iter().any(|q| q.name() == s.name()) {
                Some(format!("the coordinate `{s}`"))
            } else if q0.iter().chain(&q1).chain(&q2).any(|p| p.name() == s.name()) {
                Some(format!("the point `{s}` of the scheme"))
            } else {
                None
            };
            if let Some(what) = what {
                return Err(MechanicsError::WrongKind(format!(
                    "the step of discretize is a constant (a symbol such as `h`, or a number), but it contains {what}"
                )));
            }
        }
        let inner = if rule == Rule::Gauss2 { point_names_tagged(&self.coords, "m") } else { Vec::new() };
        let stage_names = if rule == Rule::Gauss2 {
            [point_names_tagged(&self.coords, "m0"), point_names_tagged(&self.coords, "m1")].concat()
        } else {
            Vec::new()
        };
        let free = l.free_symbols();
        if let Some(c) = q0.iter().chain(&q1).chain(&q2).chain(&inner).chain(&stage_names).find(|s| free.contains(*s)) {
            return Err(MechanicsError::MomentumNameClash(c.to_string()));
        }
        let t = Expr::sym(time());
        let a: Vec<Expr> = q0.iter().cloned().map(Expr::sym).collect();
        let b: Vec<Expr> = q1.iter().cloned().map(Expr::sym).collect();
        let vel: Vec<Expr> = a.iter().zip(&b).map(|(a, b)| b.minus(a).over(h)).collect();
        let at = |pos: &[Expr], time_at: &Expr| -> Expr {
            let mut m: HashMap<Symbol, Expr> = HashMap::new();
            for (i, q) in self.coords.iter().enumerate() {
                m.insert(q.clone(), pos[i].clone());
                m.insert(self.velocities[i].clone(), vel[i].clone());
            }
            m.insert(time(), time_at.clone());
            l.subs(&m)
        };
        let half = Expr::frac(1, 2);
        let ld = match rule {
            Rule::Midpoint => {
                let mid: Vec<Expr> = a.iter().zip(&b).map(|(a, b)| a.plus(b).times(&half)).collect();
                h.times(&at(&mid, &t.plus(&h.times(&half))))
            }
            Rule::Trapezoid => h.times(&half).times(&at(&a, &t).plus(&at(&b, &t.plus(h)))),
            Rule::Gauss2 => {
                // q(τ) = q_k + ℓ₁(τ)(q_{k+1} − q_k) + ℓ_m(τ)(Q − q_k) with the Lagrange basis
                // on τ = 0, ½, 1 (ℓ₁ = 2τ(τ − ½), ℓ_m = 4τ(1 − τ)), written in differences so
                // that with q_{k+1} = q_k + Δ the compiled map sees Δ, not a cancellation.
                // At τ = ½ + s, s = ±√3/6: ℓ₁ = 1/6 + s, ℓ_m = 2/3, ℓ₁' = 1 + 4s, ℓ_m' = −8s.
                let mids: Vec<Expr> = inner.iter().cloned().map(Expr::sym).collect();
                let s3 = Expr::int(3).sqrt().times(&Expr::frac(1, 6));
                let mut total = Vec::new();
                for sign in [-1, 1] {
                    let s = s3.times(&Expr::int(sign));
                    let (l1, lm) = (Expr::frac(1, 6).plus(&s), Expr::frac(2, 3));
                    let (d1, dm) = (Expr::one().plus(&s.times(&Expr::int(4))), s.times(&Expr::int(-8)));
                    let mut m: HashMap<Symbol, Expr> = HashMap::new();
                    for (i, q) in self.coords.iter().enumerate() {
                        let (db, dq) = (b[i].minus(&a[i]), mids[i].minus(&a[i]));
                        m.insert(q.clone(), a[i].plus(&l1.times(&db)).plus(&lm.times(&dq)));
                        m.insert(self.velocities[i].clone(), d1.times(&db).plus(&dm.times(&dq)).over(h));
                    }
                    m.insert(time(), t.plus(&h.times(&Expr::frac(1, 2).plus(&s))));
                    total.push(l.subs(&m));
                }
                h.times(&half).times(&Expr::add(total))
            }
        };
        let ld = tidy(&ld);
        let mut d = Differentiator::new();
        let d1 = q0.iter().map(|s| tidy(&d.diff(&ld, s))).collect();
        let d2 = q1.iter().map(|s| tidy(&d.diff(&ld, s))).collect();
        let dm = inner.iter().map(|s| tidy(&d.diff(&ld, s))).collect();
        Ok(Discrete { rule, coords: self.coords.clone(), q0, q1, q2, inner, h: h.clone(), ld, d1, d2, dm })
    }
}

impl Discrete {
    /// The discrete Euler–Lagrange expressions `D₂L_d(q_{k−1}, q_k) + D₁L_d(q_k, q_{k+1})` at
    /// `t = t_k`, in `x_0, x_1, x_2`; each is `= 0`.
    ///
    /// For a Galerkin rule the inner point of step `k − 1 → k` is `x_m0` and that of
    /// `k → k+1` is `x_m1`; [`Discrete::stage_equations`] gives the conditions on them.
    pub fn euler_lagrange(&self) -> Vec<Expr> {
        let (back, shift) = self.three_point_slots();
        self.d2.iter().zip(&self.d1).map(|(d2, d1)| tidy(&d2.subs(&back).plus(&d1.subs(&shift)))).collect()
    }

    /// The Galerkin stage conditions `∂L̃/∂Q = 0` of both steps in the three-point names
    /// (`x_m0` between `x_0, x_1` at `t − h`, then `x_m1` between `x_1, x_2` at `t`); empty
    /// for the one-step rules.
    pub fn stage_equations(&self) -> Vec<Expr> {
        let (back, shift) = self.three_point_slots();
        let first = self.dm.iter().map(|e| tidy(&e.subs(&back)));
        first.chain(self.dm.iter().map(|e| tidy(&e.subs(&shift)))).collect()
    }

    /// Substitutions taking `L_d`'s slots to the step `k − 1 → k` (at `t − h`) and to the
    /// step `k → k+1`.
    fn three_point_slots(&self) -> (HashMap<Symbol, Expr>, HashMap<Symbol, Expr>) {
        let mut back: HashMap<Symbol, Expr> = [(time(), Expr::sym(time()).minus(&self.h))].into_iter().collect();
        let mut shift: HashMap<Symbol, Expr> = HashMap::new();
        for i in 0..self.coords.len() {
            shift.insert(self.q0[i].clone(), Expr::sym(self.q1[i].clone()));
            shift.insert(self.q1[i].clone(), Expr::sym(self.q2[i].clone()));
        }
        for (m, q) in self.inner.iter().zip(&self.coords) {
            back.insert(m.clone(), Expr::var(&format!("{}_m0", q.name())));
            shift.insert(m.clone(), Expr::var(&format!("{}_m1", q.name())));
        }
        (back, shift)
    }

    /// The discrete Legendre maps `(p_k, p_{k+1}) = (−D₁L_d, D₂L_d)` in `x_0, x_1`.
    pub fn legendre_maps(&self) -> (Vec<Expr>, Vec<Expr>) {
        (self.d1.iter().map(|e| tidy(&e.neg())).collect(), self.d2.clone())
    }
}
