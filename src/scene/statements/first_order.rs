//! Scene-side rules for first-order (phase-space) Lagrangians `L = Σ a_i(z, t) z'_i − H(z, t)`
//! (§3.4): which `L` takes that route in `simulate`, and what its initial state and events
//! may mention. The equations are `mechanics::FirstOrder`'s; the session only routes.

use std::collections::HashMap;

use crate::expr::{Expr, Symbol};
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};

/// The state of a first-order Lagrangian is `z` alone: its velocities follow from
/// `ω z' = b` and are not initial data, and there are no momenta `p_z`.
pub(in crate::scene) fn check_first_order_inits(
    coords: &[Symbol],
    given: &HashMap<String, (f64, Span)>,
) -> Result<(), SceneError> {
    for q in coords {
        for name in [format!("{}'", q.name()), format!("p_{}", q.name())] {
            if let Some((_, span)) = given.get(&name) {
                return Err(SceneError::new(
                    ErrorKind::Syntax,
                    format!(
                        "`L` is first order in the velocities, so its state is {} alone: `{name}` is not initial data",
                        coords.iter().map(|c| c.name()).collect::<Vec<_>>().join(", ")
                    ),
                )
                .at(*span)
                .hint(format!("remove `{name} = …`; the velocities follow from ω z' = ∂H/∂z")));
            }
        }
    }
    Ok(())
}

/// Events of a first-order run are functions of `z` and `t` (the velocity slots are filled
/// only at the kept states, not inside a step).
pub(in crate::scene) fn check_first_order_event(e: &Expr, span: Span) -> Result<(), SceneError> {
    if let Some(v) = e.free_symbols().into_iter().find(|s| s.primes() > 0) {
        return Err(SceneError::new(
            ErrorKind::Syntax,
            format!("an event of a first-order Lagrangian's run must not use the velocity `{v}`"),
        )
        .at(span)
        .hint("write the event in the phase-space variables z and t"));
    }
    Ok(())
}
