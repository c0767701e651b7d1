//! The printed lines of the mechanics derivations, one builder per derivation, shared by every
//! front end.
//!
//! The command line (`lagrangian el|legendre|hamilton|conserved`) and the scene statements
//! (`el`, `legendre`, `hamilton`, `conserved`) call the same builder on the same
//! [`mechanics::System`](crate::mechanics::System) (forces, Rayleigh function and constraints
//! included) and render its [`Line`]s with the same [`render_line`], so both print the same
//! text for the same input; `tests/it/scene/parity.rs` compares them byte for byte.
//!
//! Conventions (PHYSICS.md §1–3):
//! - `E_q: E_q = R_q`: the Euler–Lagrange expression `E_q = d/dt ∂L/∂q' − ∂L/∂q` on the left,
//!   and on the right what drives it: the generalized force `Q_q` (2.12), the dissipation
//!   `−∂R/∂q'`, the constraint forces `Σ_j λ_j ∂f_j/∂q` (1.25–1.29); `0` for a closed system.
//! - Hamilton's equations (3.12) as the notes write them: every `q' = ∂H/∂p`, then every
//!   `p' = −∂H/∂q` (plus the same driving terms, with `q'` expressed through `∂H/∂p`).
//! - `conserved`: each candidate of Noether's theorem (an ignorable coordinate's momentum, the
//!   energy) is either conserved, with its reason, or said to be broken, with its rate of change
//!   and what breaks it.

use std::collections::HashMap;

use serde_json::{json, Value};

use crate::canonical::report::{conserved_lines, ConservedLine, SymmetryInput};
use crate::diff::Differentiator;
use crate::expr::{Expr, Symbol};
use crate::mechanics::{tidy, Kind, MechanicsError, System};
use crate::print::{plain, render, Format};

/// One printed line of a derivation.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Line {
    /// `label: lhs = rhs   (note)`; the label and the note are optional.
    Equation {
        /// A name printed before the equation (`E_θ`), followed by `: `.
        label: Option<String>,
        /// The left side (a name such as `H`, `p_x`, `x''`, `W[x,y]`, or an expression).
        lhs: Expr,
        /// The right side.
        rhs: Expr,
        /// Printed after the equation in parentheses (why a quantity is conserved).
        note: Option<String>,
    },
    /// A sentence on a line of its own (`note: …`, `(no conserved quantity …)`).
    Text(String),
}

impl Line {
    /// `lhs = rhs`.
    pub fn new(lhs: Expr, rhs: Expr) -> Line {
        Line::Equation { label: None, lhs, rhs, note: None }
    }

    /// `name = rhs`, the name printed as a symbol (`H`, `p_φ`, `F_x`, `W[x,y]`).
    pub fn named(name: &str, rhs: Expr) -> Line {
        Line::new(Expr::var(name), rhs)
    }

    /// `label: lhs = rhs`.
    pub fn labelled(label: impl Into<String>, lhs: Expr, rhs: Expr) -> Line {
        Line::Equation { label: Some(label.into()), lhs, rhs, note: None }
    }

    /// The same line with a note (a text line is returned unchanged).
    pub fn with_note(self, note: impl Into<String>) -> Line {
        match self {
            Line::Equation { label, lhs, rhs, .. } => Line::Equation { label, lhs, rhs, note: Some(note.into()) },
            text => text,
        }
    }

    /// A line of text.
    pub fn text(s: impl Into<String>) -> Line {
        Line::Text(s.into())
    }

    /// The right side of an equation line.
    pub fn rhs(&self) -> Option<&Expr> {
        match self {
            Line::Equation { rhs, .. } => Some(rhs),
            Line::Text(_) => None,
        }
    }
}

/// A line as text in `format`: the label and a left side that is a bare name are printed as
/// names (`E_θ`, `ṗ_x`, `E_{\theta}` in LaTeX), expressions as expressions.
pub fn render_line(line: &Line, format: Format) -> String {
    match line {
        Line::Text(s) => s.clone(),
        Line::Equation { label, lhs, rhs, note } => {
            let mut out = String::new();
            if let Some(l) = label {
                out.push_str(&name(l, format));
                out.push_str(": ");
            }
            out.push_str(&side(lhs, format));
            out.push_str(" = ");
            out.push_str(&render(rhs, format));
            if let Some(n) = note {
                out.push_str("   (");
                out.push_str(n);
                out.push(')');
            }
            out
        }
    }
}

/// Every line rendered in `format`.
pub fn render_lines(lines: &[Line], format: Format) -> Vec<String> {
    lines.iter().map(|l| render_line(l, format)).collect()
}

/// A line as JSON: `{"label", "lhs", "rhs", "note"}` with the expressions in plain form (which
/// re-parses), or `{"text"}`.
pub fn line_json(line: &Line) -> Value {
    match line {
        Line::Text(s) => json!({ "text": s }),
        Line::Equation { label, lhs, rhs, note } => json!({
            "label": label,
            "lhs": plain(lhs),
            "rhs": plain(rhs),
            "note": note,
        }),
    }
}

/// Every line as a JSON array.
pub fn lines_json(lines: &[Line]) -> Value {
    Value::Array(lines.iter().map(line_json).collect())
}

fn name(n: &str, format: Format) -> String {
    match format {
        Format::Latex => render(&Expr::var(n), format),
        _ => n.to_string(),
    }
}

/// A left side: an indexed name `W[x,θ1]` has its indices printed as names (`\theta_{1}` in
/// LaTeX), anything else is an expression.
fn side(lhs: &Expr, format: Format) -> String {
    if let Some(s) = lhs.as_sym().filter(|s| s.primes() == 0) {
        if let Some((base, rest)) = s.name().split_once('[') {
            if let Some(indices) = rest.strip_suffix(']') {
                let parts: Vec<String> = indices.split(',').map(|i| name(i, format)).collect();
                return format!("{}[{}]", name(base, format), parts.join(","));
            }
        }
    }
    render(lhs, format)
}

/// `el`: one line `E_q: E_q = Q_q − ∂R/∂q' + Σ λ_j ∂f_j/∂q` per coordinate, and when `W` is
/// singular one `note:` line saying why no accelerations follow (the `E_q` exist for every
/// Lagrangian; Remark 3.1).
pub fn euler_lagrange(s: &System) -> Result<Vec<Line>, MechanicsError> {
    let el = s.euler_lagrange()?;
    let rhs = s.driving_forces();
    let mut lines: Vec<Line> = s
        .coordinates()
        .iter()
        .zip(el)
        .zip(rhs)
        .map(|((q, e), r)| Line::labelled(format!("E_{}", q.name()), e, r))
        .collect();
    if let Some(note) = s.hessian_note()? {
        lines.push(Line::text(note));
    }
    Ok(lines)
}

/// `W q'' = F`: the upper triangle of `W` (`W[x,y] = …`) and `F` per coordinate (`F_x = …`),
/// `F` with the forces and the dissipation in it (3.5).
pub fn mass_matrix_split(s: &System) -> Result<Vec<Line>, MechanicsError> {
    let (w, f) = s.mass_matrix_split()?;
    let q = s.coordinates();
    let mut lines = Vec::new();
    for (i, row) in w.iter().enumerate() {
        for (j, e) in row.iter().enumerate().skip(i) {
            lines.push(Line::named(&format!("W[{},{}]", q[i].name(), q[j].name()), e.clone()));
        }
    }
    for (qi, fi) in q.iter().zip(f) {
        lines.push(Line::named(&format!("F_{}", qi.name()), fi));
    }
    Ok(lines)
}

/// The constraints as the augmented system uses them: `Φ[j,q] = ∂f_j/∂q` and the right side
/// `c_j` of `Φ q'' = c` (the constraint differentiated twice); empty without constraints.
pub fn constraints(s: &System) -> Result<Vec<Line>, MechanicsError> {
    if s.constraints().is_empty() && s.velocity_constraints().is_empty() {
        return Ok(Vec::new());
    }
    let c = s.constrained_equations()?;
    let mut lines = Vec::new();
    for (j, (row, cj)) in c.phi.iter().zip(&c.c).enumerate() {
        for (q, e) in s.coordinates().iter().zip(row) {
            lines.push(Line::named(&format!("Φ[{},{}]", j + 1, q.name()), e.clone()));
        }
        lines.push(Line::named(&format!("c_{}", j + 1), cj.clone()));
    }
    Ok(lines)
}

/// `q'' = …` per coordinate; with constraints the constrained accelerations and then each
/// multiplier `λ_j = …`, `λ` eliminated with the twice-differentiated constraints.
pub fn accelerations(s: &System) -> Result<Vec<Line>, MechanicsError> {
    let constrained = !s.constraints().is_empty() || !s.velocity_constraints().is_empty();
    let (acc, lambdas) = if constrained { s.constrained_accelerations()? } else { (s.accelerations()?, Vec::new()) };
    let mut lines: Vec<Line> =
        s.coordinates().iter().zip(acc).map(|(q, a)| Line::new(Expr::sym(q.with_primes(2)), a)).collect();
    lines.extend(s.constraint_multipliers().into_iter().zip(lambdas).map(|(l, v)| Line::new(Expr::sym(l), v)));
    Ok(lines)
}

/// The canonical momenta `p_q = ∂L/∂q'` (3.6), one line each.
pub fn momenta(s: &System) -> Result<Vec<Line>, MechanicsError> {
    let p = s.canonical_momenta()?;
    Ok(s.momenta().iter().zip(p).map(|(m, e)| Line::new(Expr::sym(m.clone()), e)).collect())
}

/// `H = …`: the Legendre transform (3.10) of a Lagrangian, or a Hamiltonian itself.
pub fn hamiltonian(h: &Expr) -> Line {
    Line::named("H", h.clone())
}

/// `lagrangian legendre`: the momenta, then `H`.
pub fn legendre(s: &System) -> Result<Vec<Line>, MechanicsError> {
    let mut lines = momenta(s)?;
    lines.push(hamiltonian(&s.hamiltonian()?));
    Ok(lines)
}

/// Hamilton's equations (3.12): every `q' = ∂H/∂p`, then every `p' = −∂H/∂q`. Forces, the
/// Rayleigh function and constraints add their terms to `p'` (with `q'` written as `∂H/∂p`,
/// so the right sides are in `q, p, t` and the multipliers `λ_j`): they are never dropped.
pub fn hamilton(s: &System) -> Result<Vec<Line>, MechanicsError> {
    let eqs = s.hamilton_equations()?;
    let mut lines: Vec<Line> =
        s.coordinates().iter().zip(eqs.qdot).map(|(q, e)| Line::new(Expr::sym(q.prime()), e)).collect();
    lines.extend(s.momenta().iter().zip(eqs.pdot).map(|(p, e)| Line::new(Expr::sym(p.prime()), e)));
    Ok(lines)
}

/// How the note of a [`conserved`] line that is *not* conserved begins.
pub const NOT_CONSERVED: &str = "not conserved: ";

/// `conserved`: the mechanics stage's Noether quantities, then the point symmetries the search
/// finds ([`conserved_lines`]), then every candidate that the forces, the dissipation or a
/// constraint break, as `p_x = …   (not conserved: dp_x/dt = …, by …)`. A system with
/// nothing to list gets one line saying so, with the search's bound.
pub fn conserved(s: &System) -> Vec<Line> {
    let t = Symbol::new("t");
    let mut d = Differentiator::new();
    let kind_expr = match s.kind() {
        Kind::Lagrangian(l) => l.clone(),
        Kind::Hamiltonian(h) => h.clone(),
    };
    let hamiltonian_kind = matches!(s.kind(), Kind::Hamiltonian(_));
    let drive = s.driving_forces();
    // In a Hamiltonian system the velocities in the forces are `∂H/∂p`.
    let to_momenta: HashMap<Symbol, Expr> = if hamiltonian_kind && s.has_driving_forces() {
        match s.hamilton_equations() {
            Ok(eqs) => s.velocities().iter().cloned().zip(eqs.qdot).collect(),
            Err(_) => HashMap::new(),
        }
    } else {
        HashMap::new()
    };
    let velocities: Vec<Expr> = match to_momenta.is_empty() {
        true => s.velocities().iter().map(|v| Expr::sym(v.clone())).collect(),
        false => s.velocities().iter().map(|v| to_momenta[v].clone()).collect(),
    };
    let drive: Vec<Expr> = drive.iter().map(|x| tidy(&x.subs(&to_momenta))).collect();
    let coords = s.coordinates();
    let lambdas = s.multipliers();
    let mus = s.velocity_multipliers(s.velocity_constraints().len());
    // What breaks the law of coordinate i (or, for `None`, the energy).
    let culprits = |i: Option<usize>, d: &mut Differentiator| -> Vec<String> {
        let mut who = Vec::new();
        for (k, q) in coords.iter().enumerate() {
            if (i.is_none() || i == Some(k)) && !s.forces()[k].is_zero() {
                who.push(format!("the force on {}", q.name()));
            }
        }
        if let Some(r) = s.rayleigh() {
            let acts = match i {
                Some(k) => !tidy(&d.diff(r, &s.velocities()[k])).is_zero(),
                None => true,
            };
            if acts {
                who.push("the Rayleigh dissipation R".to_string());
            }
        }
        for (j, f) in s.constraints().iter().enumerate() {
            let acts = match i {
                Some(k) => !tidy(&d.diff(f, &coords[k])).is_zero(),
                None => !tidy(&d.diff(f, &t)).is_zero(),
            };
            if acts {
                who.push(format!("constraint {} (multiplier {})", j + 1, lambdas[j].name()));
            }
        }
        for (j, g) in s.velocity_constraints().iter().enumerate() {
            // Its force μ a does work −μ b on the motion (a·q' = −b there).
            let acts = match i {
                Some(k) => !tidy(&d.diff(g, &s.velocities()[k])).is_zero(),
                None => !tidy(&crate::mechanics::zero_out(g, s.velocities())).is_zero(),
            };
            if acts {
                who.push(format!("velocity constraint {} (multiplier {})", j + 1, mus[j].name()));
            }
        }
        who
    };
    let mut known = Vec::new();
    let mut broken = Vec::new();
    let listed = s.conserved();
    // A candidate the forces leave alone keeps the mechanics stage's own line and reason.
    let kept = |c: &crate::mechanics::Conserved| ConservedLine {
        name: c.name.clone(),
        value: c.expr.clone(),
        note: c.reason.to_string(),
    };
    for (i, q) in coords.iter().enumerate() {
        if !tidy(&d.diff(&kind_expr, q)).is_zero() {
            continue;
        }
        let name = s.momenta()[i].to_string();
        let rate = drive[i].clone();
        if !rate.is_zero() {
            let value = match s.kind() {
                Kind::Lagrangian(l) => tidy(&d.diff(l, &s.velocities()[i])),
                Kind::Hamiltonian(_) => Expr::sym(s.momenta()[i].clone()),
            };
            broken.push((name, value, rate, culprits(Some(i), &mut d)));
        } else if let Some(c) = listed.iter().find(|c| c.name == name) {
            known.push(kept(c));
        }
    }
    if !kind_expr.contains(&t) {
        let name = if hamiltonian_kind { "H" } else { "h" };
        // dh/dt = Σ q'_i (Q_i − ∂R/∂q'_i + Σ λ ∂f/∂q_i) − ∂L/∂t with Σ q' ∂f/∂q = −∂f/∂t on
        // the constraints: the work of the forces minus Σ λ_j ∂f_j/∂t.
        let mut terms: Vec<Expr> = Vec::new();
        let mut d2 = Differentiator::new();
        for (k, v) in velocities.iter().enumerate() {
            let mut own = vec![s.forces()[k].subs(&to_momenta)];
            if let Some(r) = s.rayleigh() {
                own.push(d2.diff(r, &s.velocities()[k]).subs(&to_momenta).neg());
            }
            terms.push(v.times(&Expr::add(own)));
        }
        for (f, lam) in s.constraints().iter().zip(&lambdas) {
            terms.push(Expr::sym(lam.clone()).times(&d2.diff(f, &t)).neg());
        }
        // Σ_i q'_i μ a_i = −μ b on a velocity constraint a·q' + b = 0.
        for (g, mu) in s.velocity_constraints().iter().zip(&mus) {
            let b = crate::mechanics::zero_out(g, s.velocities());
            terms.push(Expr::sym(mu.clone()).times(&b).neg());
        }
        let rate = tidy(&Expr::add(terms));
        if !rate.is_zero() {
            let value = match s.kind() {
                Kind::Lagrangian(_) => tidy(&s.energy_function()),
                Kind::Hamiltonian(h) => h.clone(),
            };
            broken.push((name.to_string(), value, rate, culprits(None, &mut d)));
        } else if let Some(c) = listed.iter().find(|c| c.name == name) {
            known.push(kept(c));
        }
    }
    let h = s.hamiltonian().ok();
    let l = s.inverse_legendre().ok().and_then(|s| s.lagrangian().cloned());
    let input = SymmetryInput {
        lagrangian_hamiltonian: l.as_ref().zip(h.as_ref()),
        coords,
        in_momenta: hamiltonian_kind,
        constraints: s.constraints(),
        dissipative: s.forces().iter().any(|f| !f.is_zero()) || s.rayleigh().is_some(),
    };
    let (found, unattached) = conserved_lines(known, &input);
    let mut lines: Vec<Line> = found.into_iter().map(|c| Line::named(&c.name, c.value).with_note(c.note)).collect();
    for (name, value, rate, who) in broken {
        let by = if who.is_empty() { String::new() } else { format!(", broken by {}", who.join(" and ")) };
        lines.push(Line::named(&name, value).with_note(format!("{NOT_CONSERVED}d{name}/dt = {}{by}", plain(&rate))));
    }
    if let Some(bound) = unattached {
        match lines.last_mut() {
            Some(Line::Equation { note: Some(n), .. }) => {
                n.push_str("; ");
                n.push_str(&bound);
            }
            _ => lines.push(Line::text(format!("(no conserved quantity found by Noether's theorem; {bound})"))),
        }
    } else if lines.is_empty() {
        lines.push(Line::text("(no conserved quantity found by Noether's theorem)"));
    }
    lines
}

/// The lines of the flow's Jacobian (`lagrangian flow` and the scene's `flow`, notes §4.6.1):
/// the end state, `Φ(T)` with its rows and columns in the order of `state` (`q`, then `p`), and
/// the structural checks: `det Φ − 1` (Liouville), and for a Hamiltonian flow the symplectic
/// defect `max |ΦᵀJΦ − J|`. A forced or damped flow has neither property, so its `det Φ` is
/// printed as a value, not a residual, and the symplectic line says why it is absent.
pub fn flow(state: &[String], time: f64, flow: &crate::chaos::Flow) -> Vec<Line> {
    let n = state.len();
    let end: Vec<String> = state.iter().zip(&flow.end).map(|(k, v)| format!("{k} = {v}")).collect();
    let mut lines = vec![
        Line::text(format!("x(T) at T = {time}: {}", end.join(", "))),
        Line::text(format!("Φ(T), rows and columns in the order {}:", state.join(", "))),
    ];
    for row in flow.phi.chunks(n.max(1)) {
        let cells: Vec<String> = row.iter().map(|v| format!("{v:>24.16e}")).collect();
        lines.push(Line::text(format!("  [{} ]", cells.join(","))));
    }
    match flow.symplectic_defect {
        Some(defect) => {
            lines.push(Line::text(format!(
                "det Φ − 1 = {:.3e}   (Liouville: the flow keeps phase-space volume)",
                flow.det_minus_one
            )));
            lines.push(Line::text(format!("max |ΦᵀJΦ − J| = {defect:.3e}   (the flow is symplectic)")));
        }
        None => {
            lines.push(Line::text(format!(
                "det Φ − 1 = {:.3e}   (det Φ = {:.6e}: with forces or dissipation the flow need not keep phase-space volume)",
                flow.det_minus_one,
                flow.det_minus_one + 1.0
            )));
            lines.push(Line::text(
                "no symplectic defect: with forces or dissipation the flow is not Hamiltonian in general, so ΦᵀJΦ = J is no check of it",
            ));
        }
    }
    // Both checks sum products of two entries of Φ that cancel to O(1) (det Φ through its
    // cofactors, which for a symplectic Φ are entries of Φ⁻¹ = −JΦᵀJ), so rounding alone leaves
    // residuals of about n ε max|Φ|²: on an unstable or chaotic orbit that swamps the
    // integration error they are meant to show, and the printout says so.
    let big = flow.phi.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    let rounding = n as f64 * f64::EPSILON * big * big;
    if rounding > 1e-8 {
        lines.push(Line::text(format!(
            "note: Φ has entries up to {big:.1e} (the orbit separates from its neighbours), so rounding alone gives residuals of about n ε max|Φ|² = {rounding:.1e}: they do not measure the integration here; a shorter T does"
        )));
    }
    lines
}

#[cfg(feature = "frontends")]
/// The flow's checks against time, for a plot on a logarithmic axis: `|det Φ − 1|` and, for a
/// Hamiltonian flow, the symplectic defect (zeros, at `t = 0`, are left out by the log axis).
pub fn flow_figure(flow: &crate::chaos::Flow) -> crate::plot::Figure {
    use crate::plot::{Figure, Series};
    let mut series = vec![Series {
        label: "|det Φ − 1|".into(),
        points: flow.samples.iter().map(|s| (s.t, s.det_minus_one.abs())).collect(),
    }];
    if flow.symplectic_defect.is_some() {
        series.push(Series {
            label: "max |ΦᵀJΦ − J|".into(),
            points: flow.samples.iter().filter_map(|s| s.symplectic_defect.map(|d| (s.t, d))).collect(),
        });
    }
    Figure::log_y("the flow's Jacobian Φ(t): Liouville and symplectic checks", "t", "residual", series)
}

/// The flow's checks against time as a CSV table: `t,det_minus_one,symplectic_defect` (the
/// last column empty for a flow that is not Hamiltonian).
pub fn flow_table(flow: &crate::chaos::Flow) -> String {
    let mut s = String::from("t,det_minus_one,symplectic_defect\n");
    for p in &flow.samples {
        match p.symplectic_defect {
            Some(d) => s.push_str(&format!("{:e},{:e},{d:e}\n", p.t, p.det_minus_one)),
            None => s.push_str(&format!("{:e},{:e},\n", p.t, p.det_minus_one)),
        }
    }
    s
}
