//! Integrator names as the scene language spells them, and what each needs from the
//! symbolic side (the demand that decides which derivations a `simulate` builds).

/// How a method advances the state, which decides the formulation it needs.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Family {
    /// Splitting (leapfrog, Yoshida): needs a separable `H = T(p) + V(q)`.
    Splitting,
    /// Implicit collocation (midpoint, Gauss–Legendre): any right-hand side, plus a Jacobian.
    Implicit,
    /// Explicit fixed step (Euler, RK4).
    Explicit,
    /// Adaptive with a tolerance (DOP853, Taylor).
    Adaptive,
    /// A discrete Lagrangian's map (`variational`): needs `L`, state `(q, p)`.
    Variational,
}

/// An integrator.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Method {
    /// Its name in the scene language.
    pub name: &'static str,
    /// Its family.
    pub family: Family,
    /// Its order.
    pub order: u32,
    /// Whether it is symplectic.
    pub symplectic: bool,
}

/// Every method, in the order `help simulate` lists them.
pub const METHODS: &[Method] = &[
    Method { name: "leapfrog", family: Family::Splitting, order: 2, symplectic: true },
    Method { name: "verlet", family: Family::Splitting, order: 2, symplectic: true },
    Method { name: "yoshida4", family: Family::Splitting, order: 4, symplectic: true },
    Method { name: "yoshida6", family: Family::Splitting, order: 6, symplectic: true },
    Method { name: "yoshida8", family: Family::Splitting, order: 8, symplectic: true },
    Method { name: "blanes_moan", family: Family::Splitting, order: 4, symplectic: true },
    Method { name: "symplectic_euler", family: Family::Splitting, order: 1, symplectic: true },
    Method { name: "midpoint", family: Family::Implicit, order: 2, symplectic: true },
    Method { name: "gauss4", family: Family::Implicit, order: 4, symplectic: true },
    Method { name: "gauss6", family: Family::Implicit, order: 6, symplectic: true },
    Method { name: "euler", family: Family::Explicit, order: 1, symplectic: false },
    Method { name: "rk4", family: Family::Explicit, order: 4, symplectic: false },
    Method { name: "dop853", family: Family::Adaptive, order: 8, symplectic: false },
    Method { name: "taylor", family: Family::Adaptive, order: 20, symplectic: false },
    Method { name: "variational", family: Family::Variational, order: 2, symplectic: true },
    Method { name: "variational_trapezoid", family: Family::Variational, order: 2, symplectic: true },
    Method { name: "variational_gauss2", family: Family::Variational, order: 4, symplectic: true },
];

/// The default when `simulate` names no method.
pub const DEFAULT_METHOD: &str = "dop853";

/// The method called `name`.
pub fn method(name: &str) -> Option<Method> {
    METHODS.iter().copied().find(|m| m.name == name)
}
