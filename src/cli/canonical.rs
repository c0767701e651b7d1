//! `pb`, `integral`, `canonical`, `is-canonical`, `lie`, `action`, `average`: the commands of
//! canonical perturbation theory (PHYSICS.md §4 and §2.5). They parse, call
//! `lagrangian::canonical`, and print.

use clap::{ArgGroup, Args, Subcommand};
use lagrangian::canonical::{self, ExplicitMap, Generator, GeneratorKind, PhaseSpace, Trial};
use lagrangian::parse::{parse_with, ParseError};
use lagrangian::print::{render, symbol};
use lagrangian::{Declarations, Expr, Symbol};
use serde_json::{json, Value};

use super::{bad_input, parse_arg, parse_var, Common, Failure, OutFormat};

#[derive(Subcommand)]
pub enum CanonicalCommand {
    /// Poisson bracket {f, g} = Σ (∂f/∂q ∂g/∂p − ∂f/∂p ∂g/∂q); momenta are p_<coord>.
    Pb {
        /// First argument f.
        #[arg(allow_hyphen_values = true)]
        f: String,
        /// Second argument g.
        #[arg(allow_hyphen_values = true)]
        g: String,
        /// Coordinates (momenta are `p_<name>` unless `--momenta` is given).
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// Momenta, in the order of `--coords`.
        #[arg(long, value_delimiter = ',')]
        momenta: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Whether f is an integral of motion of H: df/dt = {f, H} + ∂f/∂t = 0.
    Integral {
        /// The candidate f.
        #[arg(allow_hyphen_values = true)]
        f: String,
        /// The Hamiltonian.
        #[arg(long, allow_hyphen_values = true)]
        hamiltonian: String,
        /// Coordinates.
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// Momenta, in the order of `--coords`.
        #[arg(long, value_delimiter = ',')]
        momenta: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Canonical transformation from a generating function F1(q,Q,t), F2(q,P,t), F3(p,Q,t)
    /// or F4(p,P,t): relations, maps both ways, and K = H + ∂F/∂t.
    Canonical(Box<CanonicalArgs>),
    /// Whether an explicit map "Q = …, P = …" is canonical (fundamental brackets).
    IsCanonical {
        /// The map: new coordinates first, then new momenta, e.g. "Q = log(sin(p_q)/q), P = q cot(p_q)".
        #[arg(allow_hyphen_values = true)]
        map: String,
        /// Old coordinates.
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// Old momenta, in the order of `--coords`.
        #[arg(long, value_delimiter = ',')]
        momenta: Vec<String>,
        /// The old Hamiltonian, to express it in the new variables.
        #[arg(long, allow_hyphen_values = true)]
        hamiltonian: Option<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Lie series exp(ε{·, G}) f to a given order, or (with --flow H) the flow of H as a
    /// series in t.
    #[command(group(ArgGroup::new("lie_gen").required(true).args(["generator", "flow"])))]
    Lie {
        /// The function f to transform.
        #[arg(allow_hyphen_values = true)]
        f: String,
        /// The generator G.
        #[arg(long, allow_hyphen_values = true)]
        generator: Option<String>,
        /// An autonomous Hamiltonian whose flow to expand in t.
        #[arg(long, allow_hyphen_values = true)]
        flow: Option<String>,
        /// The highest power of ε (or t) kept.
        #[arg(long, default_value_t = 3)]
        order: usize,
        /// The small parameter's name.
        #[arg(long, default_value = "ε")]
        epsilon: String,
        /// Coordinates.
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// Momenta, in the order of `--coords`.
        #[arg(long, value_delimiter = ',')]
        momenta: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Action J(E) = (1/2π)∮p dq, period T(E) and ω(E) = 2π/T of a 1-dof H(q, p), by quadrature.
    Action {
        /// The Hamiltonian H(q, p), at most quadratic in p.
        #[arg(long, allow_hyphen_values = true)]
        hamiltonian: String,
        /// The coordinate.
        #[arg(long)]
        coord: String,
        /// Its momentum (default p_<coord>).
        #[arg(long)]
        momentum: Option<String>,
        /// Energies, comma-separated.
        #[arg(long, value_delimiter = ',', required = true, allow_hyphen_values = true, value_parser = super::finite_f64)]
        energy: Vec<f64>,
        /// Parameter values, `m=1,g=9.81`.
        #[arg(long, value_delimiter = ',')]
        params: Vec<String>,
        /// A coordinate value inside the well.
        #[arg(long, default_value_t = 0.0, allow_hyphen_values = true)]
        near: f64,
        #[command(flatten)]
        common: Common,
    },
    /// Averaged Lagrangian ⟨L⟩ = (1/2π)∫L dθ of a trial function periodic in θ, with
    /// ∂⟨L⟩/∂A_k = 0 and J = ∂⟨L⟩/∂ω.
    Average(Box<AverageArgs>),
}

/// Arguments of `canonical` (boxed: the largest subcommand).
#[derive(Args)]
#[command(group(ArgGroup::new("generator").required(true).args(["f1", "f2", "f3", "f4"])))]
pub struct CanonicalArgs {
    /// F1(q, Q, t): p = ∂F1/∂q, P = −∂F1/∂Q.
    #[arg(long, allow_hyphen_values = true)]
    pub f1: Option<String>,
    /// F2(q, P, t): p = ∂F2/∂q, Q = ∂F2/∂P.
    #[arg(long, allow_hyphen_values = true)]
    pub f2: Option<String>,
    /// F3(p, Q, t): q = −∂F3/∂p, P = −∂F3/∂Q.
    #[arg(long, allow_hyphen_values = true)]
    pub f3: Option<String>,
    /// F4(p, P, t): q = −∂F4/∂p, Q = ∂F4/∂P.
    #[arg(long, allow_hyphen_values = true)]
    pub f4: Option<String>,
    /// The old Hamiltonian H(q, p, t), to get K.
    #[arg(long, allow_hyphen_values = true)]
    pub hamiltonian: Option<String>,
    /// Old coordinates.
    #[arg(long, value_delimiter = ',', required = true)]
    pub coords: Vec<String>,
    /// Old momenta, in the order of `--coords`.
    #[arg(long, value_delimiter = ',')]
    pub momenta: Vec<String>,
    /// New variables: the new coordinates then the new momenta (`Q,P`; `X,Y,P_X,P_Y`).
    #[arg(long, value_delimiter = ',')]
    pub new: Vec<String>,
    /// Evaluate the inverse map numerically at these new-variable values (Q…, P…), by
    /// Newton's method on the implicit relations: works where no closed form exists.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub at: Vec<f64>,
    /// Initial guess for Newton's method (the generator's old variables), default 1.
    #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
    pub guess: Vec<f64>,
    /// Parameter values for --at, `m=1,w=2`.
    #[arg(long, value_delimiter = ',')]
    pub params: Vec<String>,
    #[command(flatten)]
    pub common: Common,
}

/// Arguments of `average` (boxed: a large subcommand).
#[derive(Args)]
pub struct AverageArgs {
    /// The Lagrangian L(q, q').
    #[arg(allow_hyphen_values = true)]
    pub lagrangian: String,
    /// Trial functions `x = …` (repeat for several coordinates).
    #[arg(long, required = true)]
    pub trial: Vec<String>,
    /// The phase.
    #[arg(long, default_value = "θ")]
    pub phase: String,
    /// The frequency ω = θ'.
    #[arg(long, default_value = "ω")]
    pub frequency: String,
    /// The amplitudes A_k (default: symbols of the trials absent from L).
    #[arg(long, value_delimiter = ',')]
    pub amplitudes: Vec<String>,
    /// Solve the relations as a series in this small parameter (needs --unperturbed).
    #[arg(long, requires = "unperturbed")]
    pub small: Option<String>,
    /// The frequency at zeroth order in --small, e.g. `ω0`.
    #[arg(long, requires = "small", allow_hyphen_values = true)]
    pub unperturbed: Option<String>,
    /// The amplitude left free in the series solution (default: the first).
    #[arg(long)]
    pub principal: Option<String>,
    /// The order of the series in --small (1 to 4).
    #[arg(long, default_value_t = 1, requires = "small")]
    pub order: usize,
    /// Also solve the relations numerically along the principal amplitude, `A=0.05..1`
    /// (needs --small, --unperturbed and --params for every other symbol).
    #[arg(long, requires = "small")]
    pub sweep: Option<String>,
    /// How many amplitudes --sweep solves at (2 to 10000).
    #[arg(long, default_value_t = 20, requires = "sweep")]
    pub points: usize,
    /// Parameter values for --sweep, `m=1,σ=1`.
    #[arg(long, value_delimiter = ',', requires = "sweep")]
    pub params: Vec<String>,
    #[command(flatten)]
    pub common: Common,
}

/// The highest Lie-series order the CLI accepts (each order nests one more bracket).
const MAX_LIE_ORDER: usize = canonical::lie::MAX_ORDER;

struct Out {
    format: OutFormat,
}

impl Out {
    fn e(&self, e: &Expr) -> String {
        render(e, self.format.expr_format())
    }
    fn s(&self, s: &Symbol) -> String {
        symbol(s, self.format.expr_format())
    }
    fn eq(&self, s: &Symbol, e: &Expr) -> String {
        format!("{} = {}", self.s(s), self.e(e))
    }
}

fn phase_space(coords: &[String], momenta: &[String]) -> Result<PhaseSpace, Failure> {
    let r = if momenta.is_empty() { PhaseSpace::new(coords) } else { PhaseSpace::with_momenta(coords, momenta) };
    r.map_err(|e| bad_input(format!("error: {e}")))
}

fn json_pairs(rel: &[(Symbol, Expr)]) -> Value {
    Value::Array(rel.iter().map(|(s, e)| json!({"variable": s.to_string(), "value": e.to_string()})).collect())
}

pub fn run(cmd: CanonicalCommand) -> Result<(), Failure> {
    match cmd {
        CanonicalCommand::Pb { f, g, coords, momenta, common } => {
            let decls = common.declarations();
            let ps = phase_space(&coords, &momenta)?;
            let (_, fe) = parse_arg(&f, &decls)?;
            let (_, ge) = parse_arg(&g, &decls)?;
            let r = canonical::poisson(&fe, &ge, &ps);
            let out = Out { format: common.format };
            if common.format == OutFormat::Json {
                println!("{}", json!({"f": fe.to_string(), "g": ge.to_string(), "bracket": r.to_string()}));
            } else {
                println!("{}", out.e(&r));
            }
        }
        CanonicalCommand::Integral { f, hamiltonian, coords, momenta, common } => {
            let decls = common.declarations();
            let ps = phase_space(&coords, &momenta)?;
            let (_, fe) = parse_arg(&f, &decls)?;
            let (_, h) = parse_arg(&hamiltonian, &decls)?;
            let dfdt = canonical::time_derivative(&fe, &h, &ps);
            let check = canonical::is_integral(&fe, &h, &ps);
            let out = Out { format: common.format };
            if common.format == OutFormat::Json {
                println!(
                    "{}",
                    json!({"f": fe.to_string(), "dfdt": dfdt.to_string(), "integral": check.is_zero(), "check": check.describe()})
                );
            } else {
                for l in canonical::report::integral_lines(&dfdt, &check, out.format.expr_format()) {
                    println!("{l}");
                }
            }
        }
        CanonicalCommand::Canonical(args) => canonical_transform(args)?,
        CanonicalCommand::IsCanonical { map, coords, momenta, hamiltonian, common } => {
            let decls = common.declarations();
            let old = phase_space(&coords, &momenta)?;
            let entries = parse_map(&map, &decls)?;
            let n = old.dof();
            if entries.len() != 2 * n {
                return Err(bad_input(format!(
                    "error: the map gives {} entries, but {n} degree(s) of freedom need {} (new coordinates, then new momenta)",
                    entries.len(),
                    2 * n
                )));
            }
            let names: Vec<String> = entries.iter().map(|(s, _)| s.to_string()).collect();
            let new =
                PhaseSpace::with_momenta(&names[..n], &names[n..]).map_err(|e| bad_input(format!("error: {e}")))?;
            let q_new = entries[..n].iter().map(|(_, e)| e.clone()).collect();
            let p_new = entries[n..].iter().map(|(_, e)| e.clone()).collect();
            let h = match &hamiltonian {
                Some(t) => Some(parse_arg(t, &decls)?.1),
                None => None,
            };
            let report = canonical::check_map(&ExplicitMap { old, new, q_new, p_new }, h.as_ref());
            print_map_report(&report, common.format);
        }
        CanonicalCommand::Lie { f, generator, flow, order, epsilon, coords, momenta, common } => {
            let decls = common.declarations();
            let ps = phase_space(&coords, &momenta)?;
            let (_, fe) = parse_arg(&f, &decls)?;
            if order > MAX_LIE_ORDER {
                return Err(bad_input(format!(
                    "error: --order {order} is above the limit {MAX_LIE_ORDER}: nested brackets grow quickly"
                )));
            }
            let r = match (generator, flow) {
                (Some(g), _) => {
                    let (_, ge) = parse_arg(&g, &decls)?;
                    let eps = parse_var(&epsilon, &decls)?;
                    canonical::lie_series(&fe, &ge, &eps, order, &ps)
                }
                (None, Some(h)) => {
                    let (_, he) = parse_arg(&h, &decls)?;
                    canonical::lie_flow(&fe, &he, order, &ps).map_err(|e| bad_input(format!("error: {e}")))?
                }
                (None, None) => return Err(bad_input("error: give --generator G or --flow H")),
            };
            let out = Out { format: common.format };
            if common.format == OutFormat::Json {
                println!("{}", json!({"f": fe.to_string(), "order": order, "series": r.to_string()}));
            } else {
                println!("{}", out.e(&r));
            }
        }
        CanonicalCommand::Action { hamiltonian, coord, momentum, energy, params, near, common } => {
            let decls = common.declarations();
            let (_, h) = parse_arg(&hamiltonian, &decls)?;
            let q = parse_var(&coord, &decls)?;
            let p = match momentum {
                Some(m) => parse_var(&m, &decls)?,
                None => Symbol::new(&format!("p_{coord}")),
            };
            let env = parse_params(&params, &common.positive)?;
            let mut rows = Vec::new();
            for e in energy {
                let r = canonical::action_frequency(&h, &q, &p, e, &env, near)
                    .map_err(|err| bad_input(format!("error: at E = {e}: {err}")))?;
                rows.push(r);
            }
            if common.format == OutFormat::Json {
                let v: Vec<Value> = rows
                    .iter()
                    .map(|r| json!({"energy": r.energy, "action": r.action, "period": r.period, "omega": r.omega,
                                   "turning_points": [r.turning_points.0, r.turning_points.1], "rotation": r.rotation, "relative_error_estimate": r.error_estimate}))
                    .collect();
                println!("{}", Value::Array(v));
            } else {
                for l in canonical::report::action_table(&rows) {
                    println!("{l}");
                }
            }
        }
        CanonicalCommand::Average(args) => average(*args)?,
    }
    Ok(())
}

/// `lagrangian average`: ⟨L⟩, its relations and J; with --small their series; with --sweep the
/// relations solved along an amplitude.
fn average(args: AverageArgs) -> Result<(), Failure> {
    let AverageArgs {
        lagrangian,
        trial,
        phase,
        frequency,
        amplitudes,
        small,
        unperturbed,
        principal,
        order,
        sweep,
        points,
        params,
        common,
    } = args;
    let decls = common.declarations();
    let (_, l) = parse_arg(&lagrangian, &decls)?;
    let mut trials = Vec::new();
    for t in &trial {
        let (lhs, rhs) = t
            .split_once('=')
            .ok_or_else(|| bad_input(format!("error: trial `{t}` is not of the form `x = expression`")))?;
        let coord = parse_var(lhs.trim(), &decls)?;
        // Two trial functions of one coordinate: the average would use one and drop the other.
        if trials.iter().any(|t: &Trial| t.coord == coord) {
            return Err(bad_input(format!("error: --trial gives `{coord}` twice; keep one trial function for it")));
        }
        let (_, expr) = parse_arg(rhs, &decls)?;
        trials.push(Trial { coord, expr });
    }
    let th = parse_var(&phase, &decls)?;
    let w = parse_var(&frequency, &decls)?;
    let amps: Vec<Symbol> = if amplitudes.is_empty() {
        let in_l = l.free_symbols();
        let mut set = std::collections::BTreeSet::new();
        for t in &trials {
            set.extend(t.expr.free_symbols().into_iter().filter(|s| *s != th && !in_l.contains(s)));
        }
        set.into_iter().collect()
    } else {
        let amps: Vec<Symbol> = amplitudes.iter().map(|a| parse_var(a, &decls)).collect::<Result<_, _>>()?;
        if let Some(k) = (1..amps.len()).find(|&k| amps[..k].contains(&amps[k])) {
            return Err(bad_input(format!("error: --amplitudes gives `{}` twice; name it once", amps[k])));
        }
        amps
    };
    let avg =
        canonical::average_lagrangian(&l, &trials, &th, &w, &amps).map_err(|e| bad_input(format!("error: {e}")))?;
    let lead = match (&small, &unperturbed) {
        (Some(sm), Some(w0)) => {
            let sm = parse_var(sm, &decls)?;
            let (_, w0) = parse_arg(w0, &decls)?;
            let pr = match &principal {
                Some(a) => parse_var(a, &decls)?,
                None => amps.first().cloned().ok_or_else(|| bad_input("error: no amplitudes to solve for"))?,
            };
            Some(
                canonical::leading_order(&avg, &w, &w0, &sm, &pr, order)
                    .map_err(|e| bad_input(format!("error: {e}")))?,
            )
        }
        _ => None,
    };
    let swept = match (&sweep, &lead) {
        (Some(spec), Some(lo)) => {
            let (name, range) = spec
                .split_once('=')
                .ok_or_else(|| bad_input(format!("error: --sweep takes A=from..to, got `{spec}`")))?;
            let principal = parse_var(name, &decls)?;
            let (a, b) = range
                .split_once("..")
                .and_then(|(a, b)| Some((a.trim().parse::<f64>().ok()?, b.trim().parse::<f64>().ok()?)))
                .filter(|(a, b)| a.is_finite() && b.is_finite())
                .ok_or_else(|| bad_input(format!("error: --sweep `{spec}`: expected A=from..to with two numbers")))?;
            if !(2..=10_000).contains(&points) {
                return Err(bad_input(format!("error: --points must be 2..=10000, not {points}")));
            }
            let values: Vec<f64> = (0..points).map(|k| a + (b - a) * k as f64 / (points - 1) as f64).collect();
            let env = parse_params(&params, &common.positive)?;
            let w0 = parse_arg(unperturbed.as_deref().unwrap_or_default(), &decls)?.1;
            let s = canonical::sweep(&avg, &w, &w0, lo, &principal, &values, &|s: &Symbol| env.get(s.name()).copied())
                .map_err(|e| bad_input(format!("error: {e}")))?;
            Some((principal, s))
        }
        _ => None,
    };
    let out = Out { format: common.format };
    if common.format == OutFormat::Json {
        let solved = swept.as_ref().map(|(a, s)| {
            let mut m = serde_json::Map::new();
            m.insert(a.to_string(), json!(s.points.iter().map(|p| p.principal).collect::<Vec<_>>()));
            m.insert(w.to_string(), json!(s.points.iter().map(|p| p.frequency).collect::<Vec<_>>()));
            m.insert(format!("{w}_series"), json!(s.series));
            for (k, (b, _)) in s.points.first().map(|p| p.amplitudes.clone()).unwrap_or_default().iter().enumerate() {
                m.insert(b.to_string(), json!(s.points.iter().map(|p| p.amplitudes[k].1).collect::<Vec<_>>()));
            }
            Value::Object(m)
        });
        let lo = lead
            .as_ref()
            .map(|lo| json!({"order": lo.order, "frequency": lo.frequency.to_string(), "amplitudes": json_pairs(&lo.amplitudes)}));
        let rel: Vec<Value> =
            avg.relations.iter().map(|(a, e)| json!({"amplitude": a.to_string(), "dL_dA": e.to_string()})).collect();
        println!(
            "{}",
            json!({"average": avg.lagrangian.to_string(), "relations": rel, "action": avg.action.to_string(),
                   "leading_order": lo, "solved": solved})
        );
    } else {
        let lead = lead.as_ref().map(|lo| (small.as_deref().unwrap_or("σ"), lo));
        for l in canonical::report::average_lines(&avg, &w, lead, out.format.expr_format()) {
            println!("{l}");
        }
        if let Some((a, s)) = &swept {
            for l in canonical::report::sweep_lines(s, a, &w) {
                println!("{l}");
            }
        }
    }
    Ok(())
}

/// `lagrangian canonical`: the relations of a generating function, the maps both ways, `K`,
/// and with --at a point mapped by Newton's method.
fn canonical_transform(args: Box<CanonicalArgs>) -> Result<(), Failure> {
    let CanonicalArgs { f1, f2, f3, f4, hamiltonian, coords, momenta, new, at, guess, params, common } = *args;
    let decls = common.declarations();
    let old = phase_space(&coords, &momenta)?;
    let new = new_space(&new, old.dof())?;
    let (kind, text) = match (f1, f2, f3, f4) {
        (Some(t), _, _, _) => (GeneratorKind::F1, t),
        (_, Some(t), _, _) => (GeneratorKind::F2, t),
        (_, _, Some(t), _) => (GeneratorKind::F3, t),
        (_, _, _, Some(t)) => (GeneratorKind::F4, t),
        _ => return Err(bad_input("error: give one of --f1, --f2, --f3, --f4")),
    };
    let (_, f) = parse_arg(&text, &decls)?;
    let h = match &hamiltonian {
        Some(t) => Some(parse_arg(t, &decls)?.1),
        None => None,
    };
    let g = Generator::new(kind, f, old, new).map_err(|e| bad_input(format!("error: {e}")))?;
    let t = g.transform(h.as_ref()).map_err(|e| bad_input(format!("error: {e}")))?;
    print_transform(&t, common.format);
    if !at.is_empty() {
        let env = parse_params(&params, &common.positive)?;
        // Without a guess, Newton starts from the printed inverse map, so that both give
        // the same root of the relations.
        let branch = g.inverse_branch_guess(&t, &at, &env);
        let guess = match (guess.is_empty(), &branch) {
            (false, _) => guess,
            (true, Some(b)) => b.clone(),
            (true, None) => vec![1.0; g.old.dof()],
        };
        let vals = g.numeric_inverse(&at, &env, &guess).map_err(|e| bad_input(format!("error: {e}")))?;
        let printed = branch.as_ref().and_then(|_| g.numeric_inverse(&at, &env, branch.as_ref()?).ok());
        if let Some(pv) =
            printed.filter(|pv| pv.iter().zip(&vals).any(|(a, b)| (a - b).abs() > 1e-9 * (1.0 + a.abs().max(b.abs()))))
        {
            let names = g.old.variables();
            let parts: Vec<String> = names.iter().zip(&pv).map(|(s, v)| format!("{s} = {v:.15e}")).collect();
            eprintln!(
                "note: from this --guess Newton's method found another root of the relations than the printed inverse map, which gives {}",
                parts.join(", ")
            );
        }
        let names = g.old.variables();
        if common.format == OutFormat::Json {
            let m: serde_json::Map<String, Value> =
                names.iter().zip(&vals).map(|(s, v)| (s.to_string(), json!(v))).collect();
            println!("{}", json!({ "numeric_inverse": m }));
        } else {
            let parts: Vec<String> = names.iter().zip(&vals).map(|(s, v)| format!("{s} = {v:.15e}")).collect();
            println!("numeric inverse at {:?}: {}", at, parts.join(", "));
        }
    }
    Ok(())
}

/// `name=value` pairs, checked against `--positive` ([`super::name_values`]).
fn parse_params(params: &[String], positive: &[String]) -> Result<lagrangian::eval::Env, Failure> {
    Ok(super::name_values("--params", params, positive)?.into_iter().collect())
}

/// The new phase space from `--new` (coordinates then momenta), or `Q,P` / `Q1..Qn,P1..Pn`.
fn new_space(names: &[String], n: usize) -> Result<PhaseSpace, Failure> {
    let names: Vec<String> = if names.is_empty() {
        if n == 1 {
            vec!["Q".into(), "P".into()]
        } else {
            (1..=n).map(|i| format!("Q{i}")).chain((1..=n).map(|i| format!("P{i}"))).collect()
        }
    } else {
        names.to_vec()
    };
    if names.len() != 2 * n {
        return Err(bad_input(format!(
            "error: --new lists {} names, but {n} degree(s) of freedom need {} (new coordinates, then new momenta)",
            names.len(),
            2 * n
        )));
    }
    PhaseSpace::with_momenta(&names[..n], &names[n..]).map_err(|e| bad_input(format!("error: {e}")))
}

/// Splits "Q = …, P = …" at top-level commas; errors point into the whole map.
fn parse_map(text: &str, decls: &Declarations) -> Result<Vec<(Symbol, Expr)>, Failure> {
    let mut parts = Vec::new();
    let mut depth = 0i32;
    let mut start = 0;
    for (i, ch) in text.char_indices() {
        match ch {
            '(' => depth += 1,
            ')' => depth -= 1,
            ',' if depth == 0 => {
                parts.push((start, &text[start..i]));
                start = i + 1;
            }
            _ => {}
        }
    }
    parts.push((start, &text[start..]));
    let mut out = Vec::new();
    for (at, part) in parts {
        let Some((lhs, rhs)) = part.split_once('=') else {
            return Err(bad_input(format!("error: `{}` is not of the form `Q = expression`", part.trim())));
        };
        let located = |e: ParseError, offset: usize| Failure::parse(e.within(text, offset));
        let s = parse_with(lhs, decls).map_err(|e| located(e, at))?;
        let s = s.as_sym().cloned().ok_or_else(|| bad_input(format!("error: `{}` is not a variable", lhs.trim())))?;
        let rhs_at = at + lhs.len() + 1;
        if rhs.trim().is_empty() {
            let blank = rhs.len() - rhs.trim_start().len();
            let e = ParseError::at(text, rhs_at + blank, format!("`{s} =` has no expression after `=`"));
            return Err(Failure::parse(e));
        }
        let e = parse_with(rhs, decls).map_err(|e| located(e, rhs_at))?;
        out.push((s, e));
    }
    Ok(out)
}

fn print_transform(t: &canonical::GeneratedTransform, format: OutFormat) {
    if format == OutFormat::Json {
        let map = |r: &Result<Vec<(Symbol, Expr)>, canonical::SolveError>| match r {
            Ok(v) => json!({"closed_form": true, "relations": json_pairs(v)}),
            Err(e) => json!({"closed_form": false, "reason": e.to_string()}),
        };
        let k = match &t.hamiltonian {
            None => Value::Null,
            Some(Ok(k)) => json!(k.to_string()),
            Some(Err(e)) => json!({"error": e.to_string(), "mixed": t.k_mixed.as_ref().map(|k| k.to_string())}),
        };
        println!(
            "{}",
            json!({"kind": t.kind.to_string(), "relations": json_pairs(&t.relations), "inverse": map(&t.inverse),
                   "forward": map(&t.forward), "branches": t.branches, "K": k})
        );
        return;
    }
    for l in canonical::report::transform_lines(t, format.expr_format()) {
        println!("{l}");
    }
}

fn print_map_report(r: &canonical::MapReport, format: OutFormat) {
    let out = Out { format };
    if format == OutFormat::Json {
        let br: Vec<Value> = r
            .brackets
            .iter()
            .map(|b| json!({"bracket": b.name, "value": b.value.to_string(), "expected": b.expected.to_string(), "check": b.check.describe()}))
            .collect();
        let k = match &r.hamiltonian {
            None => Value::Null,
            Some(Ok(k)) => json!(k.to_string()),
            Some(Err(e)) => json!({"error": e.to_string()}),
        };
        println!(
            "{}",
            json!({"canonical": r.canonicity.is_canonical(), "verdict": r.canonicity.describe(), "brackets": br, "K": k})
        );
        return;
    }
    let word = if r.canonicity.is_canonical() { "yes" } else { "no" };
    println!("canonical: {word}: {}", r.canonicity.describe());
    for b in &r.brackets {
        println!(
            "  {} = {} (expected {}; the difference is {})",
            b.name,
            out.e(&b.value),
            out.e(&b.expected),
            b.check.describe()
        );
    }
    if let Some(Ok(inv)) = &r.inverse {
        for (s, e) in inv {
            println!("  {}", out.eq(s, e));
        }
    }
    match &r.hamiltonian {
        None => {}
        Some(Ok(k)) => println!("K = {}", out.e(k)),
        Some(Err(e)) => println!("K: {e}"),
    }
}
