//! The printed text of `integral`, `action`, `average`, transformations from a generating
//! function and `conserved` (with the point-symmetry search), shared by the command line and
//! scene statements so both print the same lines for the same input (scene parity).

use crate::expr::{Expr, Symbol};
use crate::print::{render, symbol, Format};

use super::action_angle::ActionFrequency;
use super::average::{Averaged, LeadingOrder};
use super::generating::GeneratedTransform;
use super::reduce::ZeroCheck;
use super::solve::SolveError;

/// `df/dt = {f, H} + ∂f/∂t = …` and the verdict with how it was decided.
pub fn integral_lines(dfdt: &Expr, check: &ZeroCheck, format: Format) -> Vec<String> {
    let verdict = if check.is_zero() { "an integral of motion" } else { "not an integral of motion" };
    vec![format!("df/dt = {{f, H}} + ∂f/∂t = {}", render(dfdt, format)), format!("{verdict}: {}", check.describe())]
}

/// The table of `E`, `J(E)`, `T(E)`, `ω(E)` and the quadrature's relative error estimate;
/// a rotation is marked after its row.
pub fn action_table(rows: &[ActionFrequency]) -> Vec<String> {
    let mut out = vec![format!("{:>14} {:>22} {:>22} {:>22} {:>9}", "E", "J(E)", "T(E)", "ω(E)", "rel.err")];
    for r in rows {
        let mut line = format!(
            "{:>14.6e} {:>22.15e} {:>22.15e} {:>22.15e} {:>9.1e}",
            r.energy, r.action, r.period, r.omega, r.error_estimate
        );
        if r.rotation {
            line.push_str("  rotation: J = (1/2π)∫ p dq over one turn");
        }
        out.push(line);
    }
    out
}

/// `⟨L⟩ = …`, each `∂⟨L⟩/∂A = … = 0`, `J = ∂⟨L⟩/∂ω = …`, and the series solution when
/// asked (`small` names the small parameter).
pub fn average_lines(
    avg: &Averaged,
    frequency: &Symbol,
    lead: Option<(&str, &LeadingOrder)>,
    format: Format,
) -> Vec<String> {
    let e = |x: &Expr| render(x, format);
    let s = |x: &Symbol| symbol(x, format);
    let amplitudes: Vec<Symbol> = avg.relations.iter().map(|(a, _)| a.clone()).collect();
    let readable = super::average::grouped(&avg.lagrangian, lead.map(|(small, _)| small), &amplitudes);
    let mut out = vec![format!("⟨L⟩ = {}", e(&readable))];
    for (a, rel) in &avg.relations {
        out.push(format!("∂⟨L⟩/∂{} = {} = 0", s(a), e(rel)));
    }
    out.push(format!("J = ∂⟨L⟩/∂{} = {}", s(frequency), e(&avg.action)));
    if let Some((small, lo)) = lead {
        let order = match lo.order {
            1 => "first".to_string(),
            2 => "second".to_string(),
            3 => "third".to_string(),
            n => format!("{n}th"),
        };
        out.push(format!("to {order} order in {small}:"));
        out.push(format!("  {} = {}", s(frequency), e(&lo.frequency)));
        for (a, v) in &lo.amplitudes {
            out.push(format!("  {} = {}", s(a), e(v)));
        }
    }
    out
}

/// `name = value   (note)`: how `conserved` (and every derived line with a note) prints, in
/// scenes and on the command line alike.
pub fn noted_line(lhs: &str, rhs: &str, note: Option<&str>) -> String {
    match note {
        Some(n) => format!("{lhs} = {rhs}   ({n})"),
        None => format!("{lhs} = {rhs}"),
    }
}

/// One conserved quantity as `conserved` prints it: its name, its value and why it is conserved.
#[derive(Clone, Debug, PartialEq)]
pub struct ConservedLine {
    pub name: String,
    pub value: Expr,
    pub note: String,
}

/// What the symmetry search of `conserved` is given besides the mechanics stage's lines.
pub struct SymmetryInput<'a> {
    /// `L(q, q', t)` and `H(q, p, t)` of the system without forces; `None` when a Legendre
    /// transform does not exist (no search).
    pub lagrangian_hamiltonian: Option<(&'a Expr, &'a Expr)>,
    pub coords: &'a [Symbol],
    /// Print the charges in momenta (the input was a Hamiltonian) rather than velocities.
    pub in_momenta: bool,
    /// Holonomic constraints `f(q, t) = 0`: only generators along them are kept.
    pub constraints: &'a [Expr],
    /// Forces or a Rayleigh function are declared: no search.
    pub dissipative: bool,
}

/// `conserved`'s lines: the mechanics stage's `known` ones (ignorable momenta, energy), then
/// one `Q1`, `Q2`, … per point symmetry [`super::symmetry::point_symmetries`] finds that is
/// not already listed (a translation of one coordinate whose momentum is listed, a time
/// translation when the energy is), whose bracket `{Q, H} + ∂Q/∂t` is zero and which moves
/// along every constraint (`Σ ∂f/∂q ξ + ∂f/∂t τ = 0`). The search's bound goes into the last
/// line's note; when there is no line at all it is returned instead, for the front end to
/// print. With forces or dissipation there is no search, and the last note says so.
pub fn conserved_lines(mut lines: Vec<ConservedLine>, input: &SymmetryInput) -> (Vec<ConservedLine>, Option<String>) {
    use super::reduce::decide_zero;
    use super::symmetry::point_symmetries;
    if input.dissipative {
        let why = "no symmetry search: with forces or dissipation δL = dF/dt gives no conserved charge";
        return match lines.last_mut() {
            Some(last) => {
                last.note.push_str("; ");
                last.note.push_str(why);
                (lines, None)
            }
            None => (lines, Some(why.to_string())),
        };
    }
    let Some((l, h)) = input.lagrangian_hamiltonian else { return (lines, None) };
    let coords = input.coords;
    let search = point_symmetries(l, coords, h);
    let listed = |name: &str| lines.iter().any(|k| k.name == name);
    let has_energy = listed("h") || listed("H");
    let mut count = 0;
    let mut found = Vec::new();
    for s in search.found {
        // A translation of one coordinate is its ignorable momentum, a time translation the
        // energy: both already listed when they hold.
        let moved: Vec<usize> = (0..coords.len()).filter(|&i| !s.generator[i].is_zero()).collect();
        if s.kind == "translation" && moved.len() == 1 && listed(&format!("p_{}", coords[moved[0]].name())) {
            continue;
        }
        if s.kind == "time translation" && has_energy {
            continue;
        }
        if !s.check.is_zero() {
            continue;
        }
        let t = super::time();
        let along = input.constraints.iter().all(|f| {
            let df = Expr::add(coords.iter().zip(&s.generator).map(|(q, x)| crate::diff::diff(f, q).times(x)))
                .plus(&crate::diff::diff(f, &t).times(&s.time_change));
            decide_zero(&df) == ZeroCheck::Proven
        });
        if !along {
            continue;
        }
        count += 1;
        let xi: Vec<String> = s.generator.iter().map(crate::print::plain).collect();
        let mut what = format!("{}: ξ = ({})", s.kind, xi.join(", "));
        if !s.time_change.is_zero() {
            what.push_str(&format!(", τ = {}", crate::print::plain(&s.time_change)));
        }
        if !s.gauge.is_zero() {
            what.push_str(&format!(", F = {}", crate::print::plain(&s.gauge)));
        }
        found.push(ConservedLine {
            name: format!("Q{count}"),
            value: if input.in_momenta { s.charge } else { s.charge_velocities },
            note: format!("{what}; {{Q, H}} + ∂Q/∂t is {}", s.check.describe()),
        });
    }
    lines.extend(found);
    let bound = if search.bound.starts_with("not searched") {
        format!("point symmetries {}", search.bound)
    } else {
        format!("point symmetries searched: {}", search.bound)
    };
    match lines.last_mut() {
        Some(last) => {
            last.note.push_str("; ");
            last.note.push_str(&bound);
            (lines, None)
        }
        None => (lines, Some(bound)),
    }
}

/// The lines of a transformation from a generating function: the defining relations, the
/// inverse map (old variables) and the forward map (new variables), each in closed form or
/// said to stay implicit, the branch choices, and `K` (in the generator's variables when it
/// has no closed form in the new ones).
pub fn transform_lines(t: &GeneratedTransform, format: Format) -> Vec<String> {
    let eq = |s: &Symbol, e: &Expr| format!("{} = {}", symbol(s, format), render(e, format));
    let mut out = vec![format!("relations ({}):", t.kind)];
    out.extend(t.relations.iter().map(|(s, e)| format!("  {}", eq(s, e))));
    let mut show = |title: &str, r: &Result<Vec<(Symbol, Expr)>, SolveError>| match r {
        Ok(v) => {
            out.push(format!("{title}:"));
            out.extend(v.iter().map(|(s, e)| format!("  {}", eq(s, e))));
        }
        Err(e) => out.push(format!("{title}: no closed form ({e}); the relations above stay implicit")),
    };
    show("old variables (inverse map)", &t.inverse);
    show("new variables (forward map)", &t.forward);
    out.extend(t.branches.iter().map(|b| format!("branch: {b}")));
    match &t.hamiltonian {
        None => {}
        Some(Ok(k)) => out.push(format!("K = {}", render(k, format))),
        Some(Err(e)) => {
            if let Some(m) = &t.k_mixed {
                out.push(format!("K = H + ∂F/∂t = {} (in the generator's variables; {e})", render(m, format)));
            }
        }
    }
    out
}

/// The lines of an `average … for A in a..b` sweep: a heading, then a few rows (all of at most
/// six, else the first, quarter, half, three quarters and last) of the amplitude, the frequency
/// solved, the series' frequency beside it and the other amplitudes.
pub fn sweep_lines(sweep: &super::average::Sweep, principal: &Symbol, frequency: &Symbol) -> Vec<String> {
    use crate::print::fmt_num;
    let n = sweep.points.len();
    let (Some(first), Some(last)) = (sweep.points.first(), sweep.points.last()) else { return Vec::new() };
    let mut out = vec![format!(
        "the relations solved at {n} values of {principal} in {}..{} ({frequency} by Newton's method; the series to order {} beside it):",
        fmt_num(first.principal),
        fmt_num(last.principal),
        sweep.order
    )];
    let rows = if n <= 6 { (0..n).collect::<Vec<_>>() } else { vec![0, n / 4, n / 2, 3 * n / 4, n - 1] };
    for k in rows {
        let p = &sweep.points[k];
        let others: String = p.amplitudes.iter().map(|(s, v)| format!(", {s} = {}", fmt_num(*v))).collect();
        out.push(format!(
            "  {principal} = {}: {frequency} = {} (series {}){others}",
            fmt_num(p.principal),
            fmt_num(p.frequency),
            fmt_num(sweep.series[k])
        ));
    }
    out
}
