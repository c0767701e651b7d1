//! The `variational` simulate methods (§4.7.2): what such a run needs and refuses.

use crate::scene::syntax::ast::SimSpec;
use crate::scene::syntax::error::{ErrorKind, SceneError, Span};

/// A `variational` run needs `L` and takes no events (the map has no continuous rate to
/// locate a crossing inside a step).
pub(in crate::scene) fn check_variational_run(
    method: &str,
    spec: &SimSpec,
    has_l: bool,
    span: Span,
) -> Result<(), SceneError> {
    if let Some(ev) = spec.events.first() {
        return Err(SceneError::new(
            ErrorKind::Syntax,
            format!("`{method}` steps a discrete map and cannot locate events inside a step"),
        )
        .at(ev.span)
        .hint("drop the `record`/`stop` clause, or use `gauss4` or `dop853` for the event"));
    }
    if !has_l {
        return Err(SceneError::new(
            ErrorKind::Undeclared,
            format!("`{method}` discretizes the Lagrangian, and no `L` is defined"),
        )
        .at(span)
        .hint("define `L = …` first"));
    }
    Ok(())
}
