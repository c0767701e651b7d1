//! `lagrangian flow`: the flow's Jacobian of a mechanical system and its structural checks
//! (notes §4.6.1), computed by `lagrangian::chaos::flow` and printed by
//! `lagrangian::report::flow` (the scene's `flow` prints the same lines); this file only reads
//! the arguments.

use clap::Subcommand;
use serde_json::json;

use lagrangian::chaos;
use lagrangian::compile::Variational;
use lagrangian::mechanics::System;
use lagrangian::print::Format;
use lagrangian::report;

use super::{bad_input, finite_f64, mechanics_failure, name_values, read_expr_arg, Common, Failure, OutFormat};

#[derive(Subcommand)]
pub enum ChaosCommand {
    /// The flow's Jacobian Φ(T) = ∂x(T)/∂x(0) of a system in x = (q, p), with Liouville's
    /// check det Φ − 1 and the symplectic defect max |ΦᵀJΦ − J| (notes §4.6.1); both are zero
    /// for the exact flow of a Hamiltonian, so they measure the integration error. With
    /// --force or --rayleigh the flow is not Hamiltonian: det Φ is printed, the defect is not
    Flow {
        /// The Hamiltonian in q, p_q (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        hamiltonian: String,
        /// The input is a Lagrangian: its Legendre transform is used.
        #[arg(long)]
        lagrangian: bool,
        /// The generalized coordinates, in order.
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// The start: every coordinate and momentum, `q=1,p_q=0`.
        #[arg(long, value_delimiter = ',', required = true)]
        at: Vec<String>,
        /// The end time T.
        #[arg(long, value_parser = finite_f64)]
        time: f64,
        /// Parameter values, `m=1,k=2`.
        #[arg(long, value_delimiter = ',')]
        set: Vec<String>,
        /// A generalized force on one coordinate, `q=Q` (`q=-b q'`); repeatable.
        #[arg(long)]
        force: Vec<String>,
        /// A Rayleigh dissipation function R(q, q').
        #[arg(long)]
        rayleigh: Option<String>,
        /// The Taylor method's tolerance.
        #[arg(long, value_parser = finite_f64, default_value_t = 1e-14)]
        tol: f64,
        #[command(flatten)]
        common: Common,
    },
}

pub fn run(cmd: ChaosCommand) -> Result<(), Failure> {
    let ChaosCommand::Flow { hamiltonian, lagrangian, coords, at, time, set, force, rayleigh, tol, common } = cmd;
    let text = read_expr_arg(&hamiltonian)?;
    let names: Vec<&str> = coords.iter().map(|s| s.trim()).collect();
    let decls = common.declarations();
    let mut system = if lagrangian {
        System::from_lagrangian_with(&text, &names, &decls)
    } else {
        System::from_hamiltonian_with(&text, &names, &decls)
    }
    .map_err(mechanics_failure)?;
    for f in &force {
        let Some((q, e)) = f.split_once('=') else {
            return Err(bad_input(format!("error: --force `{f}`: expected `coordinate=expression`")));
        };
        system = system.with_force(q, e).map_err(mechanics_failure)?;
    }
    if let Some(r) = &rayleigh {
        system = system.with_rayleigh(r).map_err(mechanics_failure)?;
    }
    // A momentum not named after its coordinate would be a constant and freeze the coordinate.
    system.check_momenta().map_err(mechanics_failure)?;
    let params = name_values("--set", &set, &common.positive)?;
    let refs: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let system = system.with_params(&refs).map_err(mechanics_failure)?;
    if time <= 0.0 {
        return Err(bad_input(format!("error: --time must be positive, got {time}")));
    }
    // The start in the variational system's order (q, then p), every entry named once.
    let start = name_values("--at", &at, &[])?;
    let state: Vec<String> = system.coordinates().iter().chain(system.momenta()).map(|s| s.to_string()).collect();
    let mut x0 = Vec::with_capacity(state.len());
    for name in &state {
        // `name_values` has refused a name given twice.
        match start.iter().find(|(k, _)| k == name) {
            Some((_, v)) => x0.push(*v),
            None => {
                return Err(bad_input(format!("error: --at has no value for `{name}` (give {})", state.join(", "))))
            }
        }
    }
    if let Some((k, _)) = start.iter().find(|(k, _)| !state.contains(k)) {
        return Err(bad_input(format!(
            "error: --at `{k}` is not a coordinate or momentum (the state is {})",
            state.join(", ")
        )));
    }
    let n = state.len();
    let var = Variational::of_system(&system, n, false).map_err(|e| bad_input(format!("error: {e}")))?;
    let flow = chaos::flow(&var, &x0, time, tol).map_err(|e| Failure::new(2, format!("error: {e}")))?;
    if common.format == OutFormat::Json {
        let rows: Vec<&[f64]> = flow.phi.chunks(n).collect();
        let obj = json!({
            "state": state,
            "time": time,
            "end": flow.end,
            "phi": rows,
            "det_minus_one": flow.det_minus_one,
            "symplectic_defect": flow.symplectic_defect,
        });
        println!("{obj}");
        return Ok(());
    }
    for line in report::flow(&state, time, &flow) {
        println!("{}", report::render_line(&line, Format::Plain));
    }
    Ok(())
}
