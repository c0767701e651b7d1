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
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Rule {
    /// `h L((q_k + q_{k+1})/2, (q_{k+1} − q_k)/h, t_k + h/2)`: order 2.
    Midpoint,
    /// `h/2 [L(q_k, v, t_k) + L(q_{k+1}, v, t_k + h)]` with `v = (q_{k+1} − q_k)/h`: order 2
    /// (Störmer–Verlet for `L = ½ q'ᵀ M q' − V(q)`).
    Trapezoid,
}

impl Rule {
    /// From its name (`midpoint`, `trapezoid`).
    pub fn from_name(name: &str) -> Option<Rule> {
        match name {
            "midpoint" => Some(Rule::Midpoint),
            "trapezoid" | "trapezoidal" => Some(Rule::Trapezoid),
            _ => None,
        }
    }

    /// Its name.
    pub fn name(self) -> &'static str {
        match self {
            Rule::Midpoint => "midpoint",
            Rule::Trapezoid => "trapezoid",
        }
    }
}

/// A discrete Lagrangian with its equations.
#[derive(Clone, Debug, PartialEq)]
pub struct Discrete {
    /// The continuous coordinates, in order.
    pub coords: Vec<Symbol>,
    /// `q_k` (`x_0`), one per coordinate.
    pub q0: Vec<Symbol>,
    /// `q_{k+1}` (`x_1`).
    pub q1: Vec<Symbol>,
    /// `q_{k+1}` in the three-point equations (`x_2`).
    pub q2: Vec<Symbol>,
    /// The step.
    pub h: Expr,
    /// `L_d(q_k, q_{k+1})` at `t = t_k`.
    pub ld: Expr,
    /// `D₁L_d(q_k, q_{k+1})`, one per coordinate.
    pub d1: Vec<Expr>,
    /// `D₂L_d(q_k, q_{k+1})`.
    pub d2: Vec<Expr>,
}

/// The names `x_i` of step point `i` for each coordinate.
pub fn point_names(coords: &[Symbol], i: usize) -> Vec<Symbol> {
    coords.iter().map(|q| Symbol::new(&format!("{}_{i}", q.name()))).collect()
}

impl System {
    /// The discrete Lagrangian of the system's `L` by `rule` with step `h` (a symbol or an
    /// exact number), with its slot derivatives.
    pub fn discretize(&self, rule: Rule, h: &Expr) -> Result<Discrete, MechanicsError> {
        let l = self.need_lagrangian("discretize")?;
        if !self.constraints.is_empty() || self.rayleigh.is_some() || self.forces.iter().any(|f| !f.is_zero()) {
            return Err(MechanicsError::WrongKind(
                "discretize takes a Lagrangian alone (no forces, dissipation or constraints)".into(),
            ));
        }
        if h.is_zero() {
            return Err(MechanicsError::WrongKind("the step h of discretize must not be zero".into()));
        }
        let (q0, q1, q2) = (point_names(&self.coords, 0), point_names(&self.coords, 1), point_names(&self.coords, 2));
        let free = l.free_symbols();
        if let Some(c) = q0.iter().chain(&q1).chain(&q2).find(|s| free.contains(*s)) {
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
        };
        let ld = tidy(&ld);
        let mut d = Differentiator::new();
        let d1 = q0.iter().map(|s| tidy(&d.diff(&ld, s))).collect();
        let d2 = q1.iter().map(|s| tidy(&d.diff(&ld, s))).collect();
        Ok(Discrete { coords: self.coords.clone(), q0, q1, q2, h: h.clone(), ld, d1, d2 })
    }
}

impl Discrete {
    /// The discrete Euler–Lagrange expressions `D₂L_d(q_{k−1}, q_k) + D₁L_d(q_k, q_{k+1})` at
    /// `t = t_k`, in `x_0, x_1, x_2`; each is `= 0`.
    pub fn euler_lagrange(&self) -> Vec<Expr> {
        // D₂L_d(x_0, x_1) at t − h, and D₁L_d(x_1, x_2) at t: shift the slots of the latter.
        let back: HashMap<Symbol, Expr> = [(time(), Expr::sym(time()).minus(&self.h))].into_iter().collect();
        let mut shift: HashMap<Symbol, Expr> = HashMap::new();
        for i in 0..self.coords.len() {
            shift.insert(self.q0[i].clone(), Expr::sym(self.q1[i].clone()));
            shift.insert(self.q1[i].clone(), Expr::sym(self.q2[i].clone()));
        }
        self.d2.iter().zip(&self.d1).map(|(d2, d1)| tidy(&d2.subs(&back).plus(&d1.subs(&shift)))).collect()
    }

    /// The discrete Legendre maps `(p_k, p_{k+1}) = (−D₁L_d, D₂L_d)` in `x_0, x_1`.
    pub fn legendre_maps(&self) -> (Vec<Expr>, Vec<Expr>) {
        (self.d1.iter().map(|e| tidy(&e.neg())).collect(), self.d2.clone())
    }
}
