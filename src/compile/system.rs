//! Compiling a [`System`] from the mechanics stage: its equations, parameter values and state
//! layout go straight into the compiled right-hand sides.

use crate::mechanics::{Kind, System};

use super::{
    CompileError, ConstrainedRhs, HamiltonianRhs, ImplicitLegendreRhs, LagrangianRhs, SeparableHamiltonian,
    Stabilization,
};

fn names(syms: &[crate::Symbol]) -> Vec<String> {
    syms.iter().map(|s| s.to_string()).collect()
}

fn strs(v: &[String]) -> Vec<&str> {
    v.iter().map(String::as_str).collect()
}

impl System {
    fn bound_params(&self) -> Vec<(String, f64)> {
        self.param_values().iter().map(|(k, v)| (k.to_string(), *v)).collect()
    }

    fn with_param_refs<R>(&self, f: impl FnOnce(&[(&str, f64)]) -> R) -> R {
        let owned = self.bound_params();
        let refs: Vec<(&str, f64)> = owned.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        f(&refs)
    }

    /// `W q'' = F` of a Lagrangian system (with its generalized forces and Rayleigh
    /// dissipation), parameters bound to the values given by [`System::with_params`]; state
    /// `(q, q')`.
    ///
    /// ```
    /// use lagrangian::mechanics::System;
    /// use lagrangian::integrate::Rhs;
    /// let sys = System::from_lagrangian("1/2 m l^2 θ'^2 + m g l cos(θ)", &["θ"]).unwrap()
    ///     .with_params(&[("m", 1.0), ("l", 2.0), ("g", 9.81)]).unwrap();
    /// let rhs = sys.compile_rhs().unwrap();
    /// let mut dy = [0.0; 2];
    /// rhs.eval(0.0, &[0.5, 0.0], &mut dy);
    /// assert!((dy[1] + 9.81 / 2.0 * 0.5f64.sin()).abs() < 1e-14);
    /// ```
    pub fn compile_rhs(&self) -> Result<LagrangianRhs, CompileError> {
        if !self.constraints().is_empty() {
            return Err(CompileError::Unsupported {
                what: "holonomic constraints as W q'' = F (use compile_constrained for the augmented system)",
            });
        }
        if !self.velocity_constraints().is_empty() {
            return Err(CompileError::Unsupported {
                what: "velocity constraints as W q'' = F (use compile_constrained for the Lagrange–d'Alembert system)",
            });
        }
        if let Kind::Hamiltonian(_) = self.kind() {
            return Err(CompileError::Unsupported {
                what: "a Hamiltonian system as W q'' = F (use compile_hamiltonian)",
            });
        }
        let (w, f) = self.mass_matrix_split().map_err(CompileError::Mechanics)?;
        let coords = names(self.coordinates());
        self.with_param_refs(|p| LagrangianRhs::new(&w, &f, &strs(&coords), p))
    }

    /// The augmented system `[W Φᵀ; Φ 0][q''; −λ] = [F; c]` of a Lagrangian system with
    /// holonomic constraints ([`System::with_constraint`]) and velocity constraints
    /// ([`System::with_velocity_constraint`], their rows after the holonomic ones), forces and
    /// dissipation included,
    /// parameters bound; state `(q, q')`. With [`Stabilization::Projection`] integrate it with
    /// [`super::Projected`] around the method, so each step ends on the constraint manifold.
    ///
    /// ```
    /// use lagrangian::compile::Stabilization;
    /// use lagrangian::mechanics::System;
    /// use lagrangian::integrate::Rhs;
    /// // The pendulum in Cartesian coordinates: a mass on a rod of length l.
    /// let sys = System::from_lagrangian("1/2 m (x'^2 + y'^2) - m g y", &["x", "y"]).unwrap()
    ///     .with_constraint("x^2 + y^2 = l^2").unwrap()
    ///     .with_params(&[("m", 1.0), ("g", 9.81), ("l", 1.0)]).unwrap();
    /// let rhs = sys.compile_constrained(Stabilization::None).unwrap();
    /// let mut dy = [0.0; 4];
    /// rhs.eval(0.0, &[1.0, 0.0, 0.0, 0.0], &mut dy); // horizontal, at rest: free fall
    /// assert!((dy[3] + 9.81).abs() < 1e-12 && dy[2].abs() < 1e-12);
    /// ```
    pub fn compile_constrained(&self, stabilization: Stabilization) -> Result<ConstrainedRhs, CompileError> {
        if let Kind::Hamiltonian(_) = self.kind() {
            return Err(CompileError::Unsupported { what: "constraints on a Hamiltonian system" });
        }
        let (w, f) = self.mass_matrix_split().map_err(CompileError::Mechanics)?;
        self.with_param_refs(|p| {
            ConstrainedRhs::with_velocity_constraints(
                &w,
                &f,
                self.constraints(),
                self.velocity_constraints(),
                self.coordinates(),
                p,
                stabilization,
            )
        })
    }

    /// Hamilton's equations (with their exact Jacobian) of the system's Hamiltonian (derived by
    /// the Legendre transform for a Lagrangian system); state `(q, p)`.
    pub fn compile_hamiltonian(&self) -> Result<HamiltonianRhs, CompileError> {
        let h = self.hamiltonian().map_err(CompileError::Mechanics)?;
        let (q, p) = (names(self.coordinates()), names(self.momenta()));
        self.with_param_refs(|params| HamiltonianRhs::new(&h, &strs(&q), &strs(&p), params))
    }

    /// The drift/kick split of a separable Hamiltonian `T(p) + V(q, t)`;
    /// [`CompileError::NotSeparable`] otherwise.
    pub fn compile_separable(&self) -> Result<SeparableHamiltonian, CompileError> {
        let h = self.hamiltonian().map_err(CompileError::Mechanics)?;
        let (q, p) = (names(self.coordinates()), names(self.momenta()));
        self.with_param_refs(|params| SeparableHamiltonian::new(&h, &strs(&q), &strs(&p), params))
    }

    /// Hamilton's equations through the numeric Legendre map (Newton on `p = ∂L/∂q'`), for
    /// Lagrangians whose transform has no closed form; state `(q, p)`.
    pub fn compile_implicit_legendre(&self) -> Result<ImplicitLegendreRhs, CompileError> {
        let Some(l) = self.lagrangian() else {
            return Err(CompileError::Unsupported { what: "the Legendre map of a Hamiltonian system" });
        };
        self.refuse_velocity_constraints("the implicit Legendre map (Hamilton's equations)")
            .map_err(CompileError::Mechanics)?;
        let q = names(self.coordinates());
        self.with_param_refs(|params| ImplicitLegendreRhs::new(l, &strs(&q), params))
    }
}
