//! [`System`]: coordinates, velocities, momenta, parameters and a Lagrangian or Hamiltonian.

use std::collections::{BTreeMap, BTreeSet, HashMap};

use crate::expr::{Expr, Symbol};
use crate::parse::{parse_with, Declarations};
use num_traits::Zero;

use super::MechanicsError;

/// What defines the dynamics.
#[derive(Clone, Debug, PartialEq)]
pub enum Kind {
    /// `L(q, q', t)`.
    Lagrangian(Expr),
    /// `H(q, p, t)`.
    Hamiltonian(Expr),
}

/// A mechanical system: generalized coordinates `q` with velocities `q'` and canonical
/// momenta `p_q`, parameters (every other free symbol except the time `t`), optional numeric
/// parameter values, and a Lagrangian or a Hamiltonian. Generalized forces `Q_i`, a Rayleigh
/// dissipation function and holonomic constraints `f_j(q, t) = 0` are optional extras of a
/// Lagrangian system.
///
/// Build it from text ([`System::from_lagrangian`], [`System::from_hamiltonian`], or the
/// `_with` variants taking parser [`Declarations`]), then refine with the `with_*` builders.
#[derive(Clone, Debug)]
pub struct System {
    pub(crate) coords: Vec<Symbol>,
    pub(crate) velocities: Vec<Symbol>,
    pub(crate) momenta: Vec<Symbol>,
    pub(crate) params: Vec<Symbol>,
    pub(crate) values: BTreeMap<Symbol, f64>,
    pub(crate) kind: Kind,
    pub(crate) decls: Declarations,
    pub(crate) source: String,
    /// Generalized non-potential forces `Q_i`, one per coordinate (zero when absent).
    pub(crate) forces: Vec<Expr>,
    /// Rayleigh dissipation function `R(q, q')`.
    pub(crate) rayleigh: Option<Expr>,
    /// Holonomic constraints `f_j(q, t) = 0`.
    pub(crate) constraints: Vec<Expr>,
    /// Velocity (nonholonomic) constraints `g_j = a_j(q, t)·q' + b_j(q, t) = 0`.
    pub(crate) velocity_constraints: Vec<Expr>,
}

/// The time symbol `t`.
pub(crate) fn time() -> Symbol {
    Symbol::new("t")
}

/// The momentum conjugate to `q`: `p_q`.
pub(crate) fn momentum_of(q: &Symbol) -> Symbol {
    Symbol::new(&format!("p_{}", q.name()))
}

impl System {
    /// A Lagrangian system from text; `coords` are the generalized coordinates, in order.
    pub fn from_lagrangian(text: &str, coords: &[&str]) -> Result<System, MechanicsError> {
        System::from_lagrangian_with(text, coords, &Declarations::new())
    }

    /// A Lagrangian system from text, parsed with declared functions and positive symbols.
    pub fn from_lagrangian_with(text: &str, coords: &[&str], decls: &Declarations) -> Result<System, MechanicsError> {
        let l = parse_with(text, decls)?;
        System::build(Kind::Lagrangian(l), text, coords, decls)
    }

    /// A Hamiltonian system from text: a function of the coordinates, the momenta `p_q` and `t`.
    pub fn from_hamiltonian(text: &str, coords: &[&str]) -> Result<System, MechanicsError> {
        System::from_hamiltonian_with(text, coords, &Declarations::new())
    }

    /// A Hamiltonian system from text, parsed with declared functions and positive symbols.
    pub fn from_hamiltonian_with(text: &str, coords: &[&str], decls: &Declarations) -> Result<System, MechanicsError> {
        let h = parse_with(text, decls)?;
        System::build(Kind::Hamiltonian(h), text, coords, decls)
    }

    /// A Lagrangian system from an expression already built.
    pub fn from_lagrangian_expr(l: Expr, coords: &[Symbol]) -> Result<System, MechanicsError> {
        let names: Vec<String> = coords.iter().map(|s| s.name().to_string()).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let decls = decls_of(&l, coords);
        System::build(Kind::Lagrangian(l.clone()), &l.to_string(), &names, &decls)
    }

    /// A Hamiltonian system from an expression already built.
    pub fn from_hamiltonian_expr(h: Expr, coords: &[Symbol]) -> Result<System, MechanicsError> {
        let names: Vec<String> = coords.iter().map(|s| s.name().to_string()).collect();
        let names: Vec<&str> = names.iter().map(String::as_str).collect();
        let decls = decls_of(&h, coords);
        System::build(Kind::Hamiltonian(h.clone()), &h.to_string(), &names, &decls)
    }

    fn build(kind: Kind, source: &str, coords: &[&str], decls: &Declarations) -> Result<System, MechanicsError> {
        if coords.is_empty() {
            return Err(MechanicsError::NoCoordinates);
        }
        let mut seen = BTreeSet::new();
        let mut cs = Vec::new();
        for c in coords {
            let c = c.trim();
            if c.is_empty() {
                return Err(MechanicsError::EmptyCoordinate);
            }
            crate::parse::refuse_lookalikes(c)?;
            if crate::parse::is_constant_name(c) {
                return Err(MechanicsError::ConstantName(c.to_string()));
            }
            let ok = !c.is_empty()
                && c != "t"
                && c.chars().next().is_some_and(char::is_alphabetic)
                && c.chars().all(|ch| ch.is_alphanumeric() || ch == '_');
            if !ok {
                return Err(MechanicsError::BadCoordinate(c.to_string()));
            }
            if !seen.insert(c.to_string()) {
                return Err(MechanicsError::DuplicateCoordinate(c.to_string()));
            }
            cs.push(decls.symbol(c, 0));
        }
        // A coordinate `p_x` beside `x` would be read as x's momentum in H (and `hamilton`
        // printed two equations for `p_x'`): refused, whatever the formulation.
        for c in &seen {
            if let Some(q) = c.strip_prefix("p_").filter(|q| seen.contains(*q)) {
                return Err(MechanicsError::MomentumNameCollision {
                    coord: q.to_string(),
                    momentum: c.clone(),
                    suggestion: c.replacen("p_", "p", 1),
                });
            }
        }
        let velocities: Vec<Symbol> = cs.iter().map(|q| Symbol::new(q.name()).with_primes(1)).collect();
        let momenta: Vec<Symbol> = cs.iter().map(momentum_of).collect();
        let (e, what) = match &kind {
            Kind::Lagrangian(l) => (l.clone(), "Lagrangian"),
            Kind::Hamiltonian(h) => (h.clone(), "Hamiltonian"),
        };
        if e.is_undefined() {
            return Err(MechanicsError::Undefined(what));
        }
        let free = e.free_symbols();
        let names: BTreeSet<&str> = cs.iter().map(Symbol::name).collect();
        // Primed symbols: only velocities of coordinates, and only in a Lagrangian.
        for s in &free {
            if s.primes() >= 2 {
                return Err(MechanicsError::HigherDerivative { symbol: s.to_string(), order: s.primes(), what });
            }
            if s.primes() == 1 {
                if matches!(kind, Kind::Hamiltonian(_)) {
                    return Err(MechanicsError::VelocityInHamiltonian(s.to_string()));
                }
                if !names.contains(s.name()) {
                    return Err(MechanicsError::VelocityOfNonCoordinate {
                        symbol: s.to_string(),
                        base: s.name().to_string(),
                    });
                }
            }
        }
        let free_names: BTreeSet<(String, u8)> = free.iter().map(|s| (s.name().to_string(), s.primes())).collect();
        for (q, p) in cs.iter().zip(&momenta) {
            let present = match kind {
                Kind::Lagrangian(_) => {
                    free_names.contains(&(q.name().to_string(), 0)) || free_names.contains(&(q.name().to_string(), 1))
                }
                Kind::Hamiltonian(_) => {
                    free_names.contains(&(q.name().to_string(), 0)) || free_names.contains(&(p.name().to_string(), 0))
                }
            };
            if !present {
                return Err(MechanicsError::CoordinateAbsent {
                    coordinate: q.to_string(),
                    velocity: match kind {
                        Kind::Lagrangian(_) => format!("{}'", q.name()),
                        Kind::Hamiltonian(_) => p.to_string(),
                    },
                    what,
                });
            }
            if matches!(kind, Kind::Lagrangian(_)) && free_names.contains(&(p.name().to_string(), 0)) {
                return Err(MechanicsError::MomentumNameClash(p.to_string()));
            }
        }
        let is_state = |s: &Symbol| {
            s.primes() > 0 || s.is_time() || names.contains(s.name()) || momenta.iter().any(|p| p.name() == s.name())
        };
        let params: Vec<Symbol> = free.iter().filter(|s| !is_state(s)).cloned().collect();
        let n = cs.len();
        Ok(System {
            coords: cs,
            velocities,
            momenta,
            params,
            values: BTreeMap::new(),
            kind,
            decls: decls.clone(),
            source: source.to_string(),
            forces: vec![Expr::zero(); n],
            rayleigh: None,
            constraints: Vec::new(),
            velocity_constraints: Vec::new(),
        })
    }

    /// Marks symbols as positive (masses, lengths, `g`), which lets simplification use
    /// `sqrt(m²) = m`. Unknown names are ignored: positivity is an assumption, not a demand.
    pub fn with_positive(self, names: &[&str]) -> System {
        let mut map = HashMap::new();
        for n in names {
            map.insert(Symbol::new(n), Expr::sym(Symbol::positive(n)));
        }
        let decls = self.decls.clone().with_positive(names.iter().copied());
        let coords_map = |s: &Symbol| {
            if names.contains(&s.name()) && s.primes() == 0 {
                Symbol::positive(s.name())
            } else {
                s.clone()
            }
        };
        let kind = match &self.kind {
            Kind::Lagrangian(l) => Kind::Lagrangian(l.subs(&map)),
            Kind::Hamiltonian(h) => Kind::Hamiltonian(h.subs(&map)),
        };
        System {
            coords: self.coords.iter().map(coords_map).collect(),
            params: self.params.iter().map(coords_map).collect(),
            values: self.values.iter().map(|(k, v)| (coords_map(k), *v)).collect(),
            forces: self.forces.iter().map(|f| f.subs(&map)).collect(),
            rayleigh: self.rayleigh.as_ref().map(|r| r.subs(&map)),
            constraints: self.constraints.iter().map(|f| f.subs(&map)).collect(),
            velocity_constraints: self.velocity_constraints.iter().map(|g| g.subs(&map)).collect(),
            kind,
            decls,
            ..self
        }
    }

    /// Declares undefined functions (`V` so that `V(r)` is a general potential) and parses the
    /// source text again with them.
    pub fn with_functions(self, names: &[&str]) -> Result<System, MechanicsError> {
        let decls = self.decls.clone().with_functions(names.iter().copied());
        let coords: Vec<&str> = self.coords.iter().map(Symbol::name).collect();
        let mut fresh = match self.kind {
            Kind::Lagrangian(_) => System::from_lagrangian_with(&self.source, &coords, &decls)?,
            Kind::Hamiltonian(_) => System::from_hamiltonian_with(&self.source, &coords, &decls)?,
        };
        fresh.values = self.values;
        fresh.forces = self.forces;
        fresh.rayleigh = self.rayleigh;
        fresh.constraints = self.constraints;
        fresh.velocity_constraints = self.velocity_constraints;
        Ok(fresh)
    }

    /// Gives parameters numeric values (for the compiler and numeric checks).
    pub fn with_params(mut self, values: &[(&str, f64)]) -> Result<System, MechanicsError> {
        for (name, v) in values {
            if crate::parse::is_constant_name(name) {
                return Err(MechanicsError::ConstantName((*name).to_string()));
            }
            let Some(p) = self.params.iter().find(|p| p.name() == *name) else {
                return Err(MechanicsError::UnknownParameter((*name).to_string()));
            };
            if !v.is_finite() {
                return Err(MechanicsError::BadParameterValue { name: (*name).to_string(), value: *v });
            }
            self.values.insert(p.clone(), *v);
        }
        Ok(self)
    }

    /// Adds a generalized force `Q` on coordinate `coord` (2.12): the equation becomes `E = Q`.
    pub fn with_force(mut self, coord: &str, text: &str) -> Result<System, MechanicsError> {
        let q = parse_with(text, &self.decls)?;
        let Some(i) = self.coords.iter().position(|c| c.name() == coord.trim()) else {
            return Err(MechanicsError::ForceOnNonCoordinate(coord.to_string()));
        };
        self.check_extra(&q, "force")?;
        self.absorb_params(&q);
        self.forces[i] = self.forces[i].plus(&q);
        Ok(self)
    }

    /// Sets a Rayleigh dissipation function `R(q, q')`: the equations become `E + ∂R/∂q' = 0`.
    pub fn with_rayleigh(mut self, text: &str) -> Result<System, MechanicsError> {
        let r = parse_with(text, &self.decls)?;
        self.check_extra(&r, "Rayleigh function")?;
        self.absorb_params(&r);
        self.rayleigh = Some(r);
        Ok(self)
    }

    /// A constraint's text as one expression that vanishes: `f` as written, `f = g` as `f − g`.
    fn parse_equation(&self, text: &str) -> Result<Expr, MechanicsError> {
        match text.split_once('=') {
            Some((a, b)) => Ok(parse_with(a, &self.decls)?.minus(&parse_with(b, &self.decls)?)),
            None => Ok(parse_with(text, &self.decls)?),
        }
    }

    /// Adds a holonomic constraint `f(q, t) = 0` (the text is `f`; `f = g` means `f − g`).
    pub fn with_constraint(mut self, text: &str) -> Result<System, MechanicsError> {
        let f = self.parse_equation(text)?;
        let names: BTreeSet<&str> = self.coords.iter().map(Symbol::name).collect();
        let free = f.free_symbols();
        if let Some(v) = free.iter().find(|s| s.primes() > 0) {
            return Err(MechanicsError::NotHolonomic {
                constraint: text.trim().to_string(),
                why: format!("it contains the time derivative `{v}`; a holonomic constraint is f(q, t) = 0"),
            });
        }
        if let Some(e) = constant_constraint(&f, text.trim()) {
            return Err(e);
        }
        if !free.iter().any(|s| names.contains(s.name())) {
            return Err(MechanicsError::NotHolonomic {
                constraint: text.trim().to_string(),
                why: "it involves no coordinate".to_string(),
            });
        }
        if f.is_undefined() {
            return Err(MechanicsError::Undefined("constraint"));
        }
        self.absorb_params(&f);
        self.constraints.push(f);
        Ok(self)
    }

    /// [`System::with_force`] for an expression already built (the scene's `force` statement).
    pub fn with_force_expr(mut self, coord: &str, q: Expr) -> Result<System, MechanicsError> {
        let Some(i) = self.coords.iter().position(|c| c.name() == coord.trim()) else {
            return Err(MechanicsError::ForceOnNonCoordinate(coord.to_string()));
        };
        self.check_extra(&q, "force")?;
        self.absorb_params(&q);
        self.forces[i] = self.forces[i].plus(&q);
        Ok(self)
    }

    /// [`System::with_rayleigh`] for an expression already built.
    pub fn with_rayleigh_expr(mut self, r: Expr) -> Result<System, MechanicsError> {
        self.check_extra(&r, "Rayleigh function")?;
        self.absorb_params(&r);
        self.rayleigh = Some(r);
        Ok(self)
    }

    /// [`System::with_constraint`] for an expression `f` already built (the constraint is
    /// `f = 0`).
    pub fn with_constraint_expr(mut self, f: Expr) -> Result<System, MechanicsError> {
        let names: BTreeSet<&str> = self.coords.iter().map(Symbol::name).collect();
        let free = f.free_symbols();
        let shown = f.to_string();
        if let Some(v) = free.iter().find(|s| s.primes() > 0) {
            return Err(MechanicsError::NotHolonomic {
                constraint: shown,
                why: format!("it contains the time derivative `{v}`; a holonomic constraint is f(q, t) = 0"),
            });
        }
        if let Some(e) = constant_constraint(&f, &shown) {
            return Err(e);
        }
        if !free.iter().any(|s| names.contains(s.name())) {
            return Err(MechanicsError::NotHolonomic {
                constraint: shown,
                why: "it involves no coordinate".to_string(),
            });
        }
        if f.is_undefined() {
            return Err(MechanicsError::Undefined("constraint"));
        }
        self.absorb_params(&f);
        self.constraints.push(f);
        Ok(self)
    }

    /// Adds the free symbols of a force, Rayleigh function or constraint that are not state
    /// or time to the parameters, so [`System::with_params`] can give them values.
    fn absorb_params(&mut self, e: &Expr) {
        let names: BTreeSet<&str> = self.coords.iter().map(Symbol::name).collect();
        for s in e.free_symbols() {
            let state = s.primes() > 0
                || s.is_time()
                || names.contains(s.name())
                || self.momenta.iter().any(|p| p.name() == s.name());
            if !state && !self.params.contains(&s) {
                self.params.push(s);
            }
        }
    }

    fn check_extra(&self, e: &Expr, _what: &'static str) -> Result<(), MechanicsError> {
        let names: BTreeSet<&str> = self.coords.iter().map(Symbol::name).collect();
        for s in e.free_symbols() {
            if s.primes() >= 2 {
                return Err(MechanicsError::HigherDerivative {
                    symbol: s.to_string(),
                    order: s.primes(),
                    what: "Lagrangian",
                });
            }
            if s.primes() == 1 && !names.contains(s.name()) {
                return Err(MechanicsError::VelocityOfNonCoordinate {
                    symbol: s.to_string(),
                    base: s.name().to_string(),
                });
            }
        }
        Ok(())
    }

    // ----- accessors ----------------------------------------------------------------------

    /// Refuses a Hamiltonian whose momenta are not named after its coordinates. Any other name is
    /// a parameter, so `p^2/2 + q^2/2` over `q` would make `p` a constant and freeze `q`
    /// (`q' = ∂H/∂p_q = 0`) without a word; a parameter `p_y` beside no coordinate `y` is the
    /// same mistake the other way round.
    pub fn check_momenta(&self) -> Result<(), MechanicsError> {
        let sys = self;
        let coords: Vec<&str> = sys.coordinates().iter().map(Symbol::name).collect();
        let lookalike = |name: &str| {
            name == "p"
                || name == "P"
                || name.starts_with("p_")
                || name.starts_with("P_")
                || coords.iter().any(|q| name == format!("p{q}"))
        };
        let params: Vec<&str> = sys.parameters().iter().map(Symbol::name).filter(|n| lookalike(n)).collect();
        let free: BTreeSet<String> = match sys.kind() {
            Kind::Hamiltonian(h) => h.free_symbols().iter().map(|s| s.name().to_string()).collect(),
            Kind::Lagrangian(_) => return Ok(()),
        };
        let absent: Vec<(&str, &str)> = coords
            .iter()
            .zip(sys.momenta())
            .filter(|(_, p)| !free.contains(p.name()))
            .map(|(q, p)| (*q, p.name()))
            .collect();
        let momenta: Vec<&str> = sys.momenta().iter().map(Symbol::name).collect();
        let named = format!("momenta are named after their coordinates: {}", momenta.join(", "));
        if let Some((q, p)) = absent.first() {
            let took = match params.first() {
                Some(n) => format!("; `{n}` is not one of them, so it was taken as a parameter"),
                None => String::new(),
            };
            return Err(MechanicsError::MomentumNames(format!(
                "H does not contain `{p}`, the momentum of `{q}`, so {q}' = ∂H/∂{p} = 0 and `{q}` would never move ({named}{took}); write `{p}` for the momentum of `{q}`, or leave `{q}` out of the coordinates if it is a fixed quantity"
            )));
        }
        if let Some(n) = params.iter().find(|n| n.starts_with("p_") || n.starts_with("P_")) {
            let base = &n[2..];
            return Err(MechanicsError::MomentumNames(format!(
                "`{n}` in H looks like the momentum of `{base}`, but `{base}` is not a coordinate, so `{n}` would be a constant parameter ({named}); add `{base}` to the coordinates, or rename the parameter"
            )));
        }
        Ok(())
    }

    /// The generalized coordinates `q`, in order.
    pub fn coordinates(&self) -> &[Symbol] {
        &self.coords
    }

    /// The velocities `q'`.
    pub fn velocities(&self) -> &[Symbol] {
        &self.velocities
    }

    /// The canonical momenta `p_q`.
    pub fn momenta(&self) -> &[Symbol] {
        &self.momenta
    }

    /// The accelerations `q''`.
    pub fn accelerations_symbols(&self) -> Vec<Symbol> {
        self.coords.iter().map(|q| Symbol::new(q.name()).with_primes(2)).collect()
    }

    /// The parameters: every free symbol that is not a coordinate, velocity, momentum or `t`.
    pub fn parameters(&self) -> &[Symbol] {
        &self.params
    }

    /// Numeric values given to parameters.
    pub fn param_values(&self) -> &BTreeMap<Symbol, f64> {
        &self.values
    }

    /// The Lagrangian, if this is a Lagrangian system.
    pub fn lagrangian(&self) -> Option<&Expr> {
        match &self.kind {
            Kind::Lagrangian(l) => Some(l),
            Kind::Hamiltonian(_) => None,
        }
    }

    /// The Hamiltonian, if this is a Hamiltonian system (see [`System::hamiltonian`] to derive it).
    pub fn hamiltonian_expr(&self) -> Option<&Expr> {
        match &self.kind {
            Kind::Hamiltonian(h) => Some(h),
            Kind::Lagrangian(_) => None,
        }
    }

    /// What defines the dynamics.
    pub fn kind(&self) -> &Kind {
        &self.kind
    }

    /// The declarations the text was parsed with.
    pub fn declarations(&self) -> &Declarations {
        &self.decls
    }

    /// Generalized forces `Q_i`, one per coordinate.
    pub fn forces(&self) -> &[Expr] {
        &self.forces
    }

    /// The Rayleigh dissipation function, if any.
    pub fn rayleigh(&self) -> Option<&Expr> {
        self.rayleigh.as_ref()
    }

    /// The holonomic constraints `f_j(q, t)` (each `= 0`).
    pub fn constraints(&self) -> &[Expr] {
        &self.constraints
    }

    /// The velocity constraints `g_j(q, q', t)` (each `= 0`, linear in the velocities).
    pub fn velocity_constraints(&self) -> &[Expr] {
        &self.velocity_constraints
    }

    /// Adds a velocity (nonholonomic) constraint `a(q, t)·q' + b(q, t) = 0` (the text is `g`;
    /// `g = h` means `g − h`). A constraint that is not linear in the velocities, or has none
    /// (a holonomic one), is refused naming what would work.
    pub fn with_velocity_constraint(self, text: &str) -> Result<System, MechanicsError> {
        let g = self.parse_equation(text)?;
        self.with_velocity_constraint_expr(g)
    }

    /// [`System::with_velocity_constraint`] for an expression `g` already built (`g = 0`).
    pub fn with_velocity_constraint_expr(mut self, g: Expr) -> Result<System, MechanicsError> {
        self.need_lagrangian("a velocity constraint")?;
        if g.is_undefined() {
            return Err(MechanicsError::Undefined("velocity constraint"));
        }
        self.velocity_constraint_row(&g)?;
        self.absorb_params(&g);
        self.velocity_constraints.push(g);
        Ok(self)
    }

    /// Refuses `what` when the system carries velocity constraints: every derivation that
    /// has no place for them (the Hamiltonian and everything built on it, the phase-space
    /// form, a discrete or averaged Lagrangian, a series of `L`) calls this first, so that it
    /// never returns the unconstrained system's result in their presence. The error names the
    /// routes that keep them.
    pub fn refuse_velocity_constraints(&self, what: &'static str) -> Result<(), MechanicsError> {
        if self.velocity_constraints.is_empty() {
            return Ok(());
        }
        let shown: Vec<String> =
            self.velocity_constraints.iter().map(|g| format!("{} = 0", crate::print::plain(g))).collect();
        Err(MechanicsError::DropsVelocityConstraints {
            what,
            constraints: shown.join(", "),
            plural: if shown.len() == 1 { "" } else { "s" },
        })
    }

    /// Whether the defining function depends on time explicitly.
    pub fn is_time_dependent(&self) -> bool {
        let e = match &self.kind {
            Kind::Lagrangian(l) => l,
            Kind::Hamiltonian(h) => h,
        };
        e.contains(&time())
    }

    /// Coordinate names as a set (the time-dependent symbols of `d/dt`).
    pub(crate) fn coord_names(&self) -> BTreeSet<String> {
        self.coords.iter().map(|s| s.name().to_string()).collect()
    }

    /// The Lagrangian or an error naming the operation that needs one.
    pub(crate) fn need_lagrangian(&self, op: &str) -> Result<&Expr, MechanicsError> {
        self.lagrangian()
            .ok_or_else(|| MechanicsError::WrongKind(format!("{op} needs a Lagrangian; this system has a Hamiltonian")))
    }

    /// A copy with the same coordinates, parameters and values but another defining function.
    pub(crate) fn with_kind(&self, kind: Kind) -> System {
        let source = match &kind {
            Kind::Lagrangian(e) | Kind::Hamiltonian(e) => e.to_string(),
        };
        let free = match &kind {
            Kind::Lagrangian(e) | Kind::Hamiltonian(e) => e.free_symbols(),
        };
        let names: BTreeSet<&str> = self.coords.iter().map(Symbol::name).collect();
        let params: Vec<Symbol> = free
            .into_iter()
            .filter(|s| {
                s.primes() == 0
                    && !s.is_time()
                    && !names.contains(s.name())
                    && !self.momenta.iter().any(|p| p.name() == s.name())
            })
            .collect();
        System {
            coords: self.coords.clone(),
            velocities: self.velocities.clone(),
            momenta: self.momenta.clone(),
            values: self.values.iter().filter(|(k, _)| params.contains(k)).map(|(k, v)| (k.clone(), *v)).collect(),
            params,
            kind,
            decls: self.decls.clone(),
            source,
            forces: vec![Expr::zero(); self.coords.len()],
            rayleigh: None,
            constraints: Vec::new(),
            velocity_constraints: Vec::new(),
        }
    }
}

/// Declarations that reproduce an expression's positive symbols and functions.
fn decls_of(e: &Expr, coords: &[Symbol]) -> Declarations {
    let mut positive: Vec<String> =
        e.free_symbols().into_iter().filter(|s| s.is_positive()).map(|s| s.name().to_string()).collect();
    positive.extend(coords.iter().filter(|s| s.is_positive()).map(|s| s.name().to_string()));
    Declarations::new().with_positive(positive).with_functions(e.applied_functions())
}

/// Whether `e` contains any of `syms`.
pub(crate) fn contains_any(e: &Expr, syms: &[Symbol]) -> bool {
    let free = e.free_symbols();
    syms.iter().any(|s| free.contains(s))
}

/// Substitutes zero for each of `syms`.
pub(crate) fn zero_out(e: &Expr, syms: &[Symbol]) -> Expr {
    let map: HashMap<Symbol, Expr> = syms.iter().map(|s| (s.clone(), Expr::zero())).collect();
    e.subs(&map)
}

/// A constraint `f = 0` whose `f` is a number is not a constraint on the motion at all:
/// `1 = 0` can never hold and `x = x` always does. Both used to be called "not holonomic".
pub(crate) fn constant_constraint(f: &Expr, shown: &str) -> Option<MechanicsError> {
    let value = f.as_num()?;
    Some(MechanicsError::WrongKind(if value.is_zero() {
        format!("constraint `{shown}` holds identically (it reduces to 0 = 0) and constrains nothing; remove it")
    } else {
        format!("constraint `{shown}` is contradictory: it reduces to {value} = 0, which never holds")
    }))
}
