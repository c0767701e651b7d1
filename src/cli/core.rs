//! `simplify`, `diff`, `dt`: the expression commands.

use clap::Subcommand;
use lagrangian::diff::Differentiator;
use lagrangian::simplify::{simplify_with, Budget, StopReason};

use super::{emit, parse_arg, parse_var, Common, Failure};

#[derive(Subcommand)]
pub enum CoreCommand {
    /// Simplify an expression.
    Simplify {
        /// The expression (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        expr: String,
        #[command(flatten)]
        common: Common,
    },
    /// Partial derivative by one or more variables, in order.
    Diff {
        /// The expression (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        expr: String,
        /// Variables to differentiate by (`θ`, `x'`).
        #[arg(required = true)]
        vars: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Total time derivative d/dt (symbols that appear primed, and `--coords`, depend on time).
    Dt {
        /// The expression (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        expr: String,
        /// Coordinates that depend on time even where they appear unprimed.
        #[arg(long, value_delimiter = ',')]
        coords: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
}

pub fn run(cmd: CoreCommand) -> Result<(), Failure> {
    match cmd {
        CoreCommand::Simplify { expr, common } => {
            let (text, e) = parse_arg(&expr, &common.declarations())?;
            let out = simplify_with(&e, &Budget::default());
            if out.stop != StopReason::Saturated {
                // The result is still the best equivalent form found; say why the search ended.
                eprintln!("note: simplification stopped early ({}); this is the best form found", out.stop);
            }
            emit(&text, &out.expr, common.format);
        }
        CoreCommand::Diff { expr, vars, common } => {
            let decls = common.declarations();
            let (text, e) = parse_arg(&expr, &decls)?;
            let mut d = Differentiator::new();
            let mut out = e;
            for v in &vars {
                let s = parse_var(v, &decls)?;
                out = d.diff(&out, &s);
            }
            let out = lagrangian::simplify::simplify(&out);
            emit(&text, &out, common.format);
        }
        CoreCommand::Dt { expr, coords, common } => {
            let (text, e) = parse_arg(&expr, &common.declarations())?;
            let out = lagrangian::diff::dt(&e, &coords.into_iter().collect());
            let out = lagrangian::simplify::simplify(&out);
            emit(&text, &out, common.format);
        }
    }
    Ok(())
}
