//! The printed text of `integral`, `action` and `average`, shared by the command line and
//! scene statements so both print the same lines for the same input (issue 15, scene parity).

use crate::expr::{Expr, Symbol};
use crate::print::{render, symbol, Format};

use super::action_angle::ActionFrequency;
use super::average::{Averaged, LeadingOrder};
use super::reduce::ZeroCheck;

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

/// `⟨L⟩ = …`, each `∂⟨L⟩/∂A = … = 0`, `J = ∂⟨L⟩/∂ω = …`, and the first-order solution when
/// asked (`small` names the small parameter).
pub fn average_lines(
    avg: &Averaged,
    frequency: &Symbol,
    lead: Option<(&str, &LeadingOrder)>,
    format: Format,
) -> Vec<String> {
    let e = |x: &Expr| render(x, format);
    let s = |x: &Symbol| symbol(x, format);
    let mut out = vec![format!("⟨L⟩ = {}", e(&avg.lagrangian))];
    for (a, rel) in &avg.relations {
        out.push(format!("∂⟨L⟩/∂{} = {} = 0", s(a), e(rel)));
    }
    out.push(format!("J = ∂⟨L⟩/∂{} = {}", s(frequency), e(&avg.action)));
    if let Some((small, lo)) = lead {
        out.push(format!("to first order in {small}:"));
        out.push(format!("  {} = {}", s(frequency), e(&lo.frequency)));
        for (a, v) in &lo.amplitudes {
            out.push(format!("  {} = {}", s(a), e(v)));
        }
    }
    out
}
