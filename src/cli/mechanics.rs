//! `el`, `legendre`, `hamilton`, `conserved`, `transform`: the mechanics commands.

use clap::{Args, Subcommand};
use lagrangian::canonical::report::{conserved_lines, noted_line, ConservedLine, SymmetryInput};
use lagrangian::expr::{Expr, Symbol};
use lagrangian::mechanics::{MechanicsError, System};
use lagrangian::print::{render, symbol};
use serde_json::{json, Value};

use super::{bad_input, read_expr_arg, Common, Failure, OutFormat};

/// What every mechanics command takes besides its expression.
#[derive(Args, Clone)]
pub struct SystemArgs {
    /// The generalized coordinates, in order (`θ1,θ2`).
    #[arg(long, value_delimiter = ',', required = true)]
    pub coords: Vec<String>,
    /// A holonomic constraint `f(q, t)` (meaning f = 0) or `f = g`; repeatable.
    #[arg(long)]
    pub constraint: Vec<String>,
    /// A generalized force on one coordinate, `q=Q` (`θ=-b θ'`); repeatable.
    #[arg(long)]
    pub force: Vec<String>,
    /// A Rayleigh dissipation function R(q, q').
    #[arg(long)]
    pub rayleigh: Option<String>,
    #[command(flatten)]
    pub common: Common,
}

#[derive(Subcommand)]
pub enum MechanicsCommand {
    /// Euler–Lagrange equations E = d/dt ∂L/∂q' − ∂L/∂q = 0, and the split W q'' = F.
    El {
        /// The Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        lagrangian: String,
        /// Also solve for the accelerations (diagonal W, or up to 4 coupled coordinates).
        #[arg(long)]
        accelerations: bool,
        #[command(flatten)]
        system: SystemArgs,
    },
    /// Legendre transform L → H (canonical momenta p_q = ∂L/∂q').
    Legendre {
        /// The Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        lagrangian: String,
        /// Treat the input as a Hamiltonian and transform back H → L.
        #[arg(long)]
        inverse: bool,
        #[command(flatten)]
        system: SystemArgs,
    },
    /// Hamilton's equations q' = ∂H/∂p, p' = −∂H/∂q.
    Hamilton {
        /// The Hamiltonian in q, p_q, t (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        hamiltonian: String,
        /// The input is a Lagrangian: transform it first.
        #[arg(long)]
        lagrangian: bool,
        #[command(flatten)]
        system: SystemArgs,
    },
    /// Conserved quantities by Noether's theorem.
    Conserved {
        /// The Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        lagrangian: String,
        /// The input is a Hamiltonian.
        #[arg(long)]
        hamiltonian: bool,
        #[command(flatten)]
        system: SystemArgs,
    },
    /// Point transformation q = Q(s, t) and/or gauge term d/dt Λ(q, t) of a Lagrangian.
    Transform {
        /// The Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        lagrangian: String,
        /// An old coordinate as a function of the new ones, `x=r cos(φ)`; repeatable.
        #[arg(long = "map")]
        map: Vec<String>,
        /// The new coordinates (`r,φ`); required with --map.
        #[arg(long, value_delimiter = ',')]
        to: Vec<String>,
        /// A gauge function Λ(q, t): adds d/dt Λ to L.
        #[arg(long)]
        gauge: Option<String>,
        #[command(flatten)]
        system: SystemArgs,
    },
}

fn fail(e: MechanicsError) -> Failure {
    super::mechanics_failure(e)
}

fn build(text: &str, args: &SystemArgs, hamiltonian: bool) -> Result<System, Failure> {
    let coords: Vec<&str> = args.coords.iter().map(|s| s.trim()).collect();
    let decls = args.common.declarations();
    let mut s = if hamiltonian {
        System::from_hamiltonian_with(text, &coords, &decls)
    } else {
        System::from_lagrangian_with(text, &coords, &decls)
    }
    .map_err(fail)?;
    for f in &args.force {
        let Some((q, e)) = f.split_once('=') else {
            return Err(bad_input(format!("error: --force `{f}`: expected `coordinate=expression`")));
        };
        s = s.with_force(q, e).map_err(fail)?;
    }
    if let Some(r) = &args.rayleigh {
        s = s.with_rayleigh(r).map_err(fail)?;
    }
    for c in &args.constraint {
        s = s.with_constraint(c).map_err(fail)?;
    }
    Ok(s)
}

/// `conserved`'s lines, through the function that prints scene `conserved` too: the Noether
/// quantities of the mechanics stage, then the point symmetries the search finds (each
/// verified by its bracket with `H`), and the search's bound; the bound is returned apart
/// when there is no line to carry it.
fn conserved_report(s: &System) -> (Vec<ConservedLine>, Option<String>) {
    let known: Vec<ConservedLine> = s
        .conserved()
        .into_iter()
        .map(|c| ConservedLine { name: c.name, value: c.expr, note: c.reason.to_string() })
        .collect();
    let h = s.hamiltonian().ok();
    let l = s.inverse_legendre().ok().and_then(|s| s.lagrangian().cloned());
    let input = SymmetryInput {
        lagrangian_hamiltonian: l.as_ref().zip(h.as_ref()),
        coords: s.coordinates(),
        in_momenta: s.hamiltonian_expr().is_some(),
        constraints: s.constraints(),
        dissipative: s.forces().iter().any(|f| !f.is_zero()) || s.rayleigh().is_some(),
    };
    conserved_lines(known, &input)
}

/// Printed output: named expressions, in order, plus the JSON object (also the notes
/// commands' output, `cli/notes.rs`).
pub(super) struct Report {
    pub(super) format: OutFormat,
    pub(super) lines: Vec<String>,
    pub(super) json: serde_json::Map<String, Value>,
}

impl Report {
    /// No lines and an empty JSON object.
    pub(super) fn empty(format: OutFormat) -> Report {
        Report { format, lines: Vec::new(), json: serde_json::Map::new() }
    }

    fn new(format: OutFormat, system: &System, input: &str) -> Report {
        let mut json = serde_json::Map::new();
        json.insert("input".into(), json!(input.trim()));
        let coords: Vec<String> = system.coordinates().iter().map(|q| q.to_string()).collect();
        json.insert("coordinates".into(), json!(coords));
        Report { format, lines: Vec::new(), json }
    }

    pub(super) fn r(&self, e: &Expr) -> String {
        render(e, self.format.expr_format())
    }

    pub(super) fn s(&self, q: &Symbol) -> String {
        symbol(q, self.format.expr_format())
    }

    pub(super) fn line(&mut self, name: String, e: &Expr) {
        self.lines.push(format!("{name} = {}", self.r(e)));
    }

    fn per_coordinate(&mut self, key: &str, prefix: &str, coords: &[Symbol], exprs: &[Expr]) {
        let mut arr = Vec::new();
        for (q, e) in coords.iter().zip(exprs) {
            let name = format!("{prefix}_{}", self.s(q));
            self.line(name, e);
            arr.push(json!({ "coordinate": q.to_string(), "expr": lagrangian::print::plain(e) }));
        }
        self.json.insert(key.into(), Value::Array(arr));
    }

    fn matrix(&mut self, key: &str, name: &str, coords: &[Symbol], m: &[Vec<Expr>]) {
        let mut rows = Vec::new();
        for (i, row) in m.iter().enumerate() {
            for (j, e) in row.iter().enumerate() {
                if j >= i {
                    let label = format!("{name}[{},{}]", self.s(&coords[i]), self.s(&coords[j]));
                    self.line(label, e);
                }
            }
            rows.push(Value::Array(row.iter().map(|e| json!(lagrangian::print::plain(e))).collect()));
        }
        self.json.insert(key.into(), Value::Array(rows));
    }

    fn single(&mut self, key: &str, name: &str, e: &Expr) {
        self.line(name.to_string(), e);
        self.json.insert(key.into(), json!(lagrangian::print::plain(e)));
    }

    pub(super) fn print(self) {
        if self.format == OutFormat::Json {
            println!("{}", Value::Object(self.json));
        } else {
            for l in self.lines {
                println!("{l}");
            }
        }
    }
}

pub fn run(cmd: MechanicsCommand) -> Result<(), Failure> {
    match cmd {
        MechanicsCommand::El { lagrangian, accelerations, system } => {
            let text = read_expr_arg(&lagrangian)?;
            let s = build(&text, &system, false)?;
            if accelerations {
                // Nothing is printed when the accelerations asked for do not exist.
                s.check_regular().map_err(fail)?;
            }
            let mut out = Report::new(system.common.format, &s, &text);
            let eqs = s.equations().map_err(fail)?;
            out.per_coordinate("equations", "E", s.coordinates(), &eqs);
            let (w, f) = s.mass_matrix_split().map_err(fail)?;
            out.matrix("mass_matrix", "W", s.coordinates(), &w);
            out.per_coordinate("forcing", "F", s.coordinates(), &f);
            // A singular W still has its E_i (they are printed above); say why the
            // accelerations are missing instead of failing.
            let note = s.hessian_note().map_err(fail)?;
            if let Some(n) = &note {
                out.lines.push(n.clone());
            }
            out.json.insert("note".into(), json!(note));
            if !s.constraints().is_empty() {
                let c = s.constrained_equations().map_err(fail)?;
                let lam: Vec<String> = c.multipliers.iter().map(|l| l.to_string()).collect();
                out.json.insert("multipliers".into(), json!(lam));
                let mut rows = Vec::new();
                for (j, (row, cj)) in c.phi.iter().zip(&c.c).enumerate() {
                    for (q, e) in s.coordinates().iter().zip(row) {
                        let label = format!("Φ[{},{}]", j + 1, out.s(q));
                        out.line(label, e);
                    }
                    out.line(format!("c_{}", j + 1), cj);
                    rows.push(json!({
                        "phi": row.iter().map(lagrangian::print::plain).collect::<Vec<_>>(),
                        "c": lagrangian::print::plain(cj),
                    }));
                }
                out.json.insert("constraints".into(), Value::Array(rows));
            }
            if accelerations {
                let acc = s.accelerations().map_err(fail)?;
                let names: Vec<Symbol> = s.coordinates().to_vec();
                let mut arr = Vec::new();
                for (q, a) in names.iter().zip(&acc) {
                    let label = out.s(&Symbol::new(q.name()).with_primes(2));
                    out.line(label, a);
                    arr.push(json!({ "coordinate": q.to_string(), "expr": lagrangian::print::plain(a) }));
                }
                out.json.insert("accelerations".into(), Value::Array(arr));
            }
            out.print();
        }
        MechanicsCommand::Legendre { lagrangian, inverse, system } => {
            let text = read_expr_arg(&lagrangian)?;
            let s = build(&text, &system, inverse)?;
            let mut out = Report::new(system.common.format, &s, &text);
            if inverse {
                let l = s.inverse_legendre().map_err(fail)?;
                if let Some(l) = l.lagrangian() {
                    out.single("lagrangian", "L", l);
                }
            } else {
                let p = s.canonical_momenta().map_err(fail)?;
                let mut arr = Vec::new();
                for (m, e) in s.momenta().iter().zip(&p) {
                    let label = out.s(m);
                    out.line(label, e);
                    arr.push(json!({ "momentum": m.to_string(), "expr": lagrangian::print::plain(e) }));
                }
                out.json.insert("momenta".into(), Value::Array(arr));
                let h = s.hamiltonian().map_err(fail)?;
                out.single("hamiltonian", "H", &h);
            }
            out.print();
        }
        MechanicsCommand::Hamilton { hamiltonian, lagrangian, system } => {
            let text = read_expr_arg(&hamiltonian)?;
            let s = build(&text, &system, !lagrangian)?;
            let mut out = Report::new(system.common.format, &s, &text);
            let eqs = s.hamilton_equations().map_err(fail)?;
            out.json.insert("hamiltonian".into(), json!(lagrangian::print::plain(&eqs.hamiltonian)));
            let mut arr = Vec::new();
            for (i, q) in s.coordinates().iter().enumerate() {
                let p = &s.momenta()[i];
                let qd = out.s(&Symbol::new(q.name()).with_primes(1));
                let pd = format!("{}'", out.s(p));
                out.line(qd, &eqs.qdot[i]);
                out.line(pd, &eqs.pdot[i]);
                arr.push(json!({
                    "coordinate": q.to_string(),
                    "momentum": p.to_string(),
                    "qdot": lagrangian::print::plain(&eqs.qdot[i]),
                    "pdot": lagrangian::print::plain(&eqs.pdot[i]),
                }));
            }
            out.json.insert("equations".into(), Value::Array(arr));
            out.print();
        }
        MechanicsCommand::Conserved { lagrangian, hamiltonian, system } => {
            let text = read_expr_arg(&lagrangian)?;
            let s = build(&text, &system, hamiltonian)?;
            let mut out = Report::new(system.common.format, &s, &text);
            let (lines, unattached) = conserved_report(&s);
            let mut arr = Vec::new();
            for c in &lines {
                // The name rendered as the scene renders it, so both print the same line.
                let name = out.r(&Expr::var(&c.name));
                out.lines.push(noted_line(&name, &out.r(&c.value), Some(&c.note)));
                arr.push(json!({
                    "name": c.name,
                    "expr": lagrangian::print::plain(&c.value),
                    "reason": c.note,
                }));
            }
            if lines.is_empty() {
                let bound = unattached.map(|b| format!("; {b}")).unwrap_or_default();
                out.lines.push(format!("(no conserved quantity found by Noether's theorem{bound})"));
            }
            out.json.insert("conserved".into(), Value::Array(arr));
            out.print();
        }
        MechanicsCommand::Transform { lagrangian, map, to, gauge, system } => {
            let text = read_expr_arg(&lagrangian)?;
            let mut s = build(&text, &system, false)?;
            if map.is_empty() && gauge.is_none() {
                return Err(bad_input("error: give --map old=expr (with --to) and/or --gauge Λ"));
            }
            if !map.is_empty() {
                if to.is_empty() {
                    return Err(bad_input("error: --map needs --to with the new coordinates"));
                }
                let mut pairs = Vec::new();
                for m in &map {
                    let Some((a, b)) = m.split_once('=') else {
                        return Err(bad_input(format!("error: --map `{m}`: expected `old=expression`")));
                    };
                    pairs.push((a.trim(), b));
                }
                let to: Vec<&str> = to.iter().map(|s| s.trim()).collect();
                s = s.transform(&pairs, &to).map_err(fail)?;
            }
            if let Some(g) = &gauge {
                s = s.with_gauge(g).map_err(fail)?;
            }
            let mut out = Report::new(system.common.format, &s, &text);
            if let Some(l) = s.lagrangian() {
                out.single("lagrangian", "L", l);
            }
            out.print();
        }
    }
    Ok(())
}
