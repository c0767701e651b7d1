//! `el`, `legendre`, `hamilton`, `conserved`, `transform`, `series`: the mechanics commands.

use clap::{Args, Subcommand};
use lagrangian::expr::{Expr, Symbol};
use lagrangian::mechanics::{MechanicsError, System};
use lagrangian::print::{render, symbol};
use lagrangian::report::{self, Line};
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
    /// A nonholonomic constraint linear in the velocities, `a(q, t)·q' + b(q, t)` (meaning = 0)
    /// or `lhs = rhs` (`x' = R φ' cos(θ)`); repeatable. `el` prints the Lagrange–d'Alembert
    /// equations with multipliers μ.
    #[arg(long, allow_hyphen_values = true)]
    pub velocity_constraint: Vec<String>,
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
    /// Jacobian matrix ∂x_i/∂y_j of a map of coordinates and its determinant (§1.3).
    Jacobian {
        /// The map, comma-separated components (`r cos(φ), r sin(φ)`).
        #[arg(allow_hyphen_values = true)]
        map: String,
        /// The variables the map depends on, in order (`r,φ`).
        #[arg(long = "in", value_delimiter = ',', required = true)]
        vars: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Series of an expression to a given order in named small quantities (`--in x,y`), or of
    /// a Lagrangian about a point (`--coords θ --about 0`): L_lin of the notes (2.29).
    Series {
        /// The expression or Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        expr: String,
        /// The small quantities (`ε` or `x,y`).
        #[arg(long = "in", value_delimiter = ',')]
        small: Vec<String>,
        /// The coordinates of a Lagrangian to expand about `--about`: their displacements and
        /// velocities are the small quantities.
        #[arg(long, value_delimiter = ',')]
        coords: Vec<String>,
        /// The point to expand about, one value per coordinate (default 0).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true)]
        about: Vec<String>,
        /// The highest total degree kept.
        #[arg(long, default_value_t = 2)]
        order: usize,
        #[command(flatten)]
        common: Common,
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
    // On the system, so that every command either includes them or refuses (hamilton, conserved
    // and legendre used to answer for the unconstrained system).
    for g in &args.velocity_constraint {
        s = s.with_velocity_constraint(g).map_err(fail)?;
    }
    Ok(s)
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

    /// Lines of a [`report`] builder, rendered as every front end renders them; in JSON they
    /// are listed under `lines` too.
    fn report(&mut self, lines: &[Line]) {
        self.lines.extend(report::render_lines(lines, self.format.expr_format()));
        let all = self.json.entry("lines").or_insert_with(|| Value::Array(Vec::new()));
        if let (Value::Array(a), Value::Array(new)) = (all, report::lines_json(lines)) {
            a.extend(new);
        }
    }

    pub(super) fn line(&mut self, name: String, e: &Expr) {
        self.lines.push(format!("{name} = {}", self.r(e)));
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

/// `[{coordinate, expr}]` under `key` in the JSON output.
fn per_coordinate_json(out: &mut Report, key: &str, coords: &[Symbol], exprs: &[Expr]) {
    let arr: Vec<Value> = coords
        .iter()
        .zip(exprs)
        .map(|(q, e)| json!({ "coordinate": q.to_string(), "expr": lagrangian::print::plain(e) }))
        .collect();
    out.json.insert(key.into(), Value::Array(arr));
}

pub fn run(cmd: MechanicsCommand) -> Result<(), Failure> {
    match cmd {
        MechanicsCommand::Jacobian { map, vars, common } => jacobian(map, vars, common),
        MechanicsCommand::Series { expr, small, coords, about, order, common } => {
            series(expr, small, coords, about, order, common)
        }
        MechanicsCommand::El { lagrangian, accelerations, system } => euler_lagrange(lagrangian, accelerations, system),
        MechanicsCommand::Legendre { lagrangian, inverse, system } => legendre(lagrangian, inverse, system),
        MechanicsCommand::Hamilton { hamiltonian, lagrangian, system } => hamilton(hamiltonian, lagrangian, system),
        MechanicsCommand::Conserved { lagrangian, hamiltonian, system } => conserved(lagrangian, hamiltonian, system),
        MechanicsCommand::Transform { lagrangian, map, to, gauge, system } => {
            transform(lagrangian, map, to, gauge, system)
        }
    }
}

/// `jacobian`: the Jacobian matrix of a map and its determinant.
fn jacobian(map: String, vars: Vec<String>, common: Common) -> Result<(), Failure> {
    let decls = common.declarations();
    let text = read_expr_arg(&map)?;
    let comps: Vec<Expr> = split_top_level(&text)
        .iter()
        .map(|c| super::parse_arg(c.trim(), &decls).map(|(_, e)| e))
        .collect::<Result<_, _>>()?;
    let ys: Vec<Symbol> = vars.iter().map(|v| super::parse_var(v.trim(), &decls)).collect::<Result<_, _>>()?;
    let Some((m, det)) = lagrangian::mechanics::jacobian(&comps, &ys) else {
        return Err(bad_input(format!(
            "error: the map has {} component(s) but --in names {} variable(s); a Jacobian determinant needs as many of each",
            comps.len(),
            ys.len()
        )));
    };
    let f = common.format.expr_format();
    if common.format == OutFormat::Json {
        let rows: Vec<Vec<String>> = m.iter().map(|r| r.iter().map(lagrangian::print::plain).collect()).collect();
        println!("{}", json!({"matrix": rows, "determinant": lagrangian::print::plain(&det)}));
    } else {
        for row in &m {
            println!("[{}]", row.iter().map(|e| render(e, f)).collect::<Vec<_>>().join(", "));
        }
        println!("det = {}", render(&det, f));
    }
    Ok(())
}

/// `series`: a truncated Taylor series in small quantities (`--in`), or of a Lagrangian about a point (`--coords`, `--about`).
fn series(
    expr: String,
    small: Vec<String>,
    coords: Vec<String>,
    about: Vec<String>,
    order: usize,
    common: Common,
) -> Result<(), Failure> {
    let decls = common.declarations();
    let (_, e) = super::parse_arg(&expr, &decls)?;
    let series_err = |e: lagrangian::mechanics::SeriesError| bad_input(e.to_string());
    let (result, terms) = match (small.is_empty(), coords.is_empty()) {
        (false, true) => {
            let vars: Vec<Symbol> =
                small.iter().map(|v| super::parse_var(v.trim(), &decls)).collect::<Result<_, _>>()?;
            let terms = lagrangian::mechanics::series_terms(&e, &vars, order).map_err(series_err)?;
            (lagrangian::mechanics::series(&e, &vars, order).map_err(series_err)?, terms)
        }
        (true, false) => {
            let qs: Vec<Symbol> =
                coords.iter().map(|v| super::parse_var(v.trim(), &decls)).collect::<Result<_, _>>()?;
            let point: Vec<Expr> = if about.is_empty() {
                vec![Expr::zero(); qs.len()]
            } else if about.len() == qs.len() {
                about.iter().map(|a| super::parse_arg(a.trim(), &decls).map(|(_, e)| e)).collect::<Result<_, _>>()?
            } else {
                return Err(bad_input(format!(
                    "error: --about gives {} value(s) for {} coordinate(s); give one per coordinate",
                    about.len(),
                    qs.len()
                )));
            };
            lagrangian::mechanics::series_about(&e, &qs, &point, order).map_err(series_err)?
        }
        (false, false) => {
            return Err(bad_input(
                "error: give either --in (small quantities) or --coords (expand a Lagrangian about --about), not both",
            ))
        }
        (true, true) => {
            return Err(bad_input(
                "error: name the small quantities with --in x,y, or the coordinates of a Lagrangian with --coords θ (and --about θ0)",
            ))
        }
    };
    let f = common.format.expr_format();
    if common.format == OutFormat::Json {
        let parts: Vec<String> = terms.iter().map(lagrangian::print::plain).collect();
        println!("{}", json!({"series": lagrangian::print::plain(&result), "order": order, "terms": parts}));
    } else {
        if !coords.is_empty() && !about.iter().all(|a| a.trim() == "0") {
            println!("# each coordinate stands for its displacement from --about");
        }
        println!("{}", render(&result, f));
    }
    Ok(())
}

/// `el`: the Euler–Lagrange equations, their split W q'' = F, the constraints' equations and, with `--accelerations`, the solved accelerations.
fn euler_lagrange(lagrangian: String, accelerations: bool, system: SystemArgs) -> Result<(), Failure> {
    let text = read_expr_arg(&lagrangian)?;
    let s = build(&text, &system, false)?;
    // Nothing is printed when the accelerations asked for do not exist.
    let acc = if accelerations { Some(report::accelerations(&s).map_err(fail)?) } else { None };
    let mut out = Report::new(system.common.format, &s, &text);
    out.report(&report::euler_lagrange(&s).map_err(fail)?);
    let eqs = s.equations().map_err(fail)?;
    per_coordinate_json(&mut out, "equations", s.coordinates(), &eqs);
    out.report(&report::mass_matrix_split(&s).map_err(fail)?);
    let (w, f) = s.mass_matrix_split().map_err(fail)?;
    let rows: Vec<Value> =
        w.iter().map(|row| Value::Array(row.iter().map(|e| json!(lagrangian::print::plain(e))).collect())).collect();
    out.json.insert("mass_matrix".into(), Value::Array(rows));
    per_coordinate_json(&mut out, "forcing", s.coordinates(), &f);
    out.json.insert("note".into(), json!(s.hessian_note().map_err(fail)?));
    if !s.constraints().is_empty() {
        let c = s.constrained_equations().map_err(fail)?;
        let lam: Vec<String> = c.multipliers.iter().map(|l| l.to_string()).collect();
        out.json.insert("multipliers".into(), json!(lam));
        out.report(&report::constraints(&s).map_err(fail)?);
        let rows: Vec<Value> = c
            .phi
            .iter()
            .zip(&c.c)
            .map(|(row, cj)| {
                json!({
                    "phi": row.iter().map(lagrangian::print::plain).collect::<Vec<_>>(),
                    "c": lagrangian::print::plain(cj),
                })
            })
            .collect();
        out.json.insert("constraints".into(), Value::Array(rows));
    }
    if !system.velocity_constraint.is_empty() {
        // `build` put them on the system; its own constraints are the ones printed.
        let c = s.lagrange_dalembert(&[]).map_err(fail)?;
        let f = system.common.format.expr_format();
        for (q, e) in s.coordinates().iter().zip(&c.equations) {
            out.lines.push(format!("Lagrange–d'Alembert {}: {} = 0", symbol(q, f), render(e, f)));
        }
        for (j, (row, cj)) in c.phi.iter().zip(&c.c).enumerate() {
            let lhs = Expr::add(row.iter().zip(s.accelerations_symbols()).map(|(a, q)| a.times(&Expr::sym(q))));
            let lhs = lagrangian::mechanics::tidy(&lhs);
            out.lines.push(format!("d/dt of velocity constraint {}: {} = {}", j + 1, render(&lhs, f), render(cj, f)));
        }
        let rows: Vec<Value> = c
            .phi
            .iter()
            .zip(&c.c)
            .zip(&c.equations)
            .map(|((row, cj), _)| json!({"a": row.iter().map(lagrangian::print::plain).collect::<Vec<_>>(), "c": lagrangian::print::plain(cj)}))
            .collect();
        out.json.insert("velocity_constraints".into(), Value::Array(rows));
        per_coordinate_json(&mut out, "lagrange_dalembert", s.coordinates(), &c.equations);
    }
    if let Some(acc) = acc {
        let n = s.coordinates().len();
        let rhs: Vec<Expr> = acc.iter().filter_map(|l| l.rhs().cloned()).collect();
        per_coordinate_json(&mut out, "accelerations", s.coordinates(), &rhs[..n]);
        if !s.constraints().is_empty() {
            let values: Vec<String> = rhs[n..].iter().map(lagrangian::print::plain).collect();
            out.json.insert("multiplier_values".into(), json!(values));
        }
        out.report(&acc);
    }
    out.print();
    Ok(())
}

/// `legendre`: the canonical momenta and the Hamiltonian, or with `--inverse` the Lagrangian of a Hamiltonian.
fn legendre(lagrangian: String, inverse: bool, system: SystemArgs) -> Result<(), Failure> {
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
        let arr: Vec<Value> = s
            .momenta()
            .iter()
            .zip(&p)
            .map(|(m, e)| json!({ "momentum": m.to_string(), "expr": lagrangian::print::plain(e) }))
            .collect();
        out.json.insert("momenta".into(), Value::Array(arr));
        let h = s.hamiltonian().map_err(fail)?;
        out.json.insert("hamiltonian".into(), json!(lagrangian::print::plain(&h)));
        out.report(&report::momenta(&s).map_err(fail)?);
        out.report(&[report::hamiltonian(&h)]);
    }
    out.print();
    Ok(())
}

/// `hamilton`: Hamilton's equations, one (q', p') pair per coordinate.
fn hamilton(hamiltonian: String, lagrangian: bool, system: SystemArgs) -> Result<(), Failure> {
    let text = read_expr_arg(&hamiltonian)?;
    let s = build(&text, &system, !lagrangian)?;
    let mut out = Report::new(system.common.format, &s, &text);
    let eqs = s.hamilton_equations().map_err(fail)?;
    let lines = report::hamilton(&s).map_err(fail)?;
    let n = s.coordinates().len();
    let rhs: Vec<&Expr> = lines.iter().filter_map(Line::rhs).collect();
    out.json.insert("hamiltonian".into(), json!(lagrangian::print::plain(&eqs.hamiltonian)));
    let arr: Vec<Value> = s
        .coordinates()
        .iter()
        .zip(s.momenta())
        .enumerate()
        .map(|(i, (q, p))| {
            json!({
                "coordinate": q.to_string(),
                "momentum": p.to_string(),
                "qdot": lagrangian::print::plain(rhs[i]),
                "pdot": lagrangian::print::plain(rhs[n + i]),
            })
        })
        .collect();
    out.json.insert("equations".into(), Value::Array(arr));
    out.report(&lines);
    out.print();
    Ok(())
}

/// `conserved`: the conserved quantities, with the candidates a force breaks listed apart.
fn conserved(lagrangian: String, hamiltonian: bool, system: SystemArgs) -> Result<(), Failure> {
    let text = read_expr_arg(&lagrangian)?;
    let s = build(&text, &system, hamiltonian)?;
    let mut out = Report::new(system.common.format, &s, &text);
    let lines = report::conserved(&s);
    // The candidates a force breaks are listed apart from the conserved quantities.
    let (mut kept, mut broken) = (Vec::new(), Vec::new());
    for l in &lines {
        if let Line::Equation { lhs, rhs, note, .. } = l {
            let entry = json!({
                "name": lagrangian::print::plain(lhs),
                "expr": lagrangian::print::plain(rhs),
                "reason": note,
            });
            if note.as_deref().is_some_and(|n| n.starts_with(report::NOT_CONSERVED)) {
                broken.push(entry);
            } else {
                kept.push(entry);
            }
        }
    }
    out.json.insert("conserved".into(), Value::Array(kept));
    out.json.insert("not_conserved".into(), Value::Array(broken));
    out.report(&lines);
    out.print();
    Ok(())
}

/// `transform`: the Lagrangian after a point transformation (`--map`, `--to`) and/or a gauge term.
fn transform(
    lagrangian: String,
    map: Vec<String>,
    to: Vec<String>,
    gauge: Option<String>,
    system: SystemArgs,
) -> Result<(), Failure> {
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
    Ok(())
}

/// Splits `a, f(b, c), d` at the commas outside parentheses.
fn split_top_level(text: &str) -> Vec<String> {
    let (mut parts, mut cur, mut depth) = (Vec::new(), String::new(), 0i32);
    for c in text.chars() {
        match c {
            '(' | '[' => depth += 1,
            ')' | ']' => depth -= 1,
            ',' if depth == 0 => {
                parts.push(std::mem::take(&mut cur));
                continue;
            }
            _ => {}
        }
        cur.push(c);
    }
    parts.push(cur);
    parts
}
