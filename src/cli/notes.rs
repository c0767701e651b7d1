//! `phase-space`, `discretize`: the commands for the later sections of the notes that go beyond
//! `W q'' = F` (first-order Lagrangians, §3.4; discrete mechanics, §4.7.2). They parse, call the library, and print.

use clap::Subcommand;
use lagrangian::compile::{ShootBudget, ShootError};
use lagrangian::expr::Expr;
use lagrangian::mechanics::{MechanicsError, Rule, System};
use lagrangian::print::plain;
use serde_json::{json, Value};

use super::mechanics::Report as Out;
use super::{bad_input, parse_arg, read_expr_arg, Common, Failure};

#[derive(Subcommand)]
pub enum NotesCommand {
    /// A first-order (phase-space) Lagrangian L = Σ a_i(z,t) z_i' − H(z,t): the one-form a,
    /// H, the two-form ω_ij = ∂a_j/∂z_i − ∂a_i/∂z_j, the equations ω z' = ∂H/∂z + ∂a/∂t, the
    /// Poisson tensor ω⁻¹ and the velocities z'.
    PhaseSpace {
        /// The Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        lagrangian: String,
        /// The phase-space variables z, in order (`x,p`).
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// Print the bracket {f, g} of the reduced phase space; give exactly two.
        #[arg(long, allow_hyphen_values = true)]
        bracket: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
    /// Geodesics of a line element ds² = Σ g_ij dq_i dq_j (differentials `dx`), a metric
    /// matrix or an embedded surface: the metric,
    /// the Christoffel symbols Γ^k_ij, the geodesic equations, the curvature (Riemann
    /// components R_abcd, scalar R, and for a surface the Gauss curvature K), the conserved
    /// quantities, and with --from/--to a shooting solution in unit time.
    Geodesic {
        /// The line element, e.g. "dθ^2 + sin(θ)^2 dφ^2" (or give --metric or --embedding).
        #[arg(allow_hyphen_values = true)]
        line_element: Option<String>,
        /// The metric as a matrix, rows separated by `;`, entries by `,`: "1, 0; 0, sin(θ)^2".
        #[arg(long, allow_hyphen_values = true, conflicts_with = "line_element")]
        metric: Option<String>,
        /// A surface x = X(q) in Euclidean space, its components separated by `,`
        /// ("sin(θ) cos(φ), sin(θ) sin(φ), cos(θ)"): the induced metric g_ij = X_i · X_j, and
        /// the curvature vector d²x/ds² of a geodesic shown to have no tangential component
        /// (§1.6.3).
        #[arg(long, allow_hyphen_values = true, conflicts_with_all = ["line_element", "metric"])]
        embedding: Option<String>,
        /// The coordinates, in order.
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// Start point (numbers, in coordinate order).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = super::finite_f64)]
        from: Vec<f64>,
        /// End point.
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = super::finite_f64)]
        to: Vec<f64>,
        /// Parameter values for the shooting (`R=2`).
        #[arg(long = "set", value_delimiter = ',', allow_hyphen_values = true)]
        set: Vec<String>,
        /// The shooting's budget of integration steps, all trial paths together.
        #[arg(long, value_name = "N", default_value_t = lagrangian::compile::ShootBudget::DEFAULT_STEPS)]
        max_steps: usize,
        /// The shooting's budget of wall-clock seconds.
        #[arg(long, value_name = "SECONDS", default_value_t = lagrangian::compile::ShootBudget::DEFAULT_SECONDS, value_parser = super::finite_f64)]
        time_limit: f64,
        #[command(flatten)]
        common: Common,
    },
    /// The trial-function (Ritz) method (§1.4.2): a trial path q(t; a_1…a_K) meeting the end
    /// conditions, the action S(a) = ∫ L dt (exact for an integrand polynomial in t, else by
    /// Gauss–Legendre quadrature), the conditions ∂S/∂a_k = 0 and their solution by Newton.
    Ritz {
        /// The Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        lagrangian: String,
        /// The coordinates, in order.
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// The trial path of each coordinate, in order (repeat the option), in t and the unknowns.
        #[arg(long, required = true, allow_hyphen_values = true)]
        trial: Vec<String>,
        /// The unknown coefficients a_k.
        #[arg(long, value_delimiter = ',', required = true)]
        unknowns: Vec<String>,
        /// The time span `t0,t1` (exact expressions).
        #[arg(long, value_delimiter = ',', required = true, allow_hyphen_values = true)]
        span: Vec<String>,
        /// q(t0), one per coordinate; `free` leaves that end free (natural boundary condition
        /// ∂L/∂q' = 0 there, (1.18)).
        #[arg(long, value_delimiter = ',', required = true, allow_hyphen_values = true)]
        from: Vec<String>,
        /// q(t1), one per coordinate, or `free`.
        #[arg(long, value_delimiter = ',', required = true, allow_hyphen_values = true)]
        to: Vec<String>,
        /// Parameter values for the numeric solution (`m=1,k=2`).
        #[arg(long = "set", value_delimiter = ',', allow_hyphen_values = true)]
        set: Vec<String>,
        /// Starting values of the unknowns for Newton (default 0).
        #[arg(long, value_delimiter = ',', allow_hyphen_values = true, value_parser = super::finite_f64)]
        guess: Vec<f64>,
        #[command(flatten)]
        common: Common,
    },
    /// Discrete mechanics: the discrete Lagrangian L_d(q_k, q_{k+1}) of L by a quadrature rule,
    /// the discrete Euler–Lagrange equations D₂L_d(q_{k−1}, q_k) + D₁L_d(q_k, q_{k+1}) = 0 and
    /// the discrete Legendre maps p_k = −D₁L_d, p_{k+1} = D₂L_d. For a coordinate x, x_0, x_1,
    /// x_2 are q_{k−1}, q_k, q_{k+1} in the equations and q_k, q_{k+1} in L_d.
    Discretize {
        /// The Lagrangian (`-` reads it from standard input).
        #[arg(allow_hyphen_values = true)]
        lagrangian: String,
        /// The coordinates, in order.
        #[arg(long, value_delimiter = ',', required = true)]
        coords: Vec<String>,
        /// The quadrature rule: midpoint, trapezoid (order 2) or gauss2 (order 4: a quadratic
        /// through q_k, an inner point x_m and q_{k+1}, two Gauss–Legendre nodes).
        #[arg(long, default_value = "midpoint")]
        rule: String,
        /// The step: a symbol (`h`) or an exact number.
        #[arg(long, default_value = "h", allow_hyphen_values = true)]
        step: String,
        #[command(flatten)]
        common: Common,
    },
    /// Iterates a map of phase space (§3.1, §4.7.2) from one start: plain assignments run in
    /// order, each seeing the values already assigned this step (the standard map `p = p + K
    /// sin(q)`, `q = q + p`); primed ones give the new values by equations that may use them
    /// (the implicit midpoint rule `q' = q + h (p + p')/2`, `p' = p - h (q + q')/2`), solved by
    /// Newton's method each step. Prints the last state; `--format json` gives every state.
    Map {
        /// The updates, each `name = expression` (or `name' = expression`).
        #[arg(required = true)]
        updates: Vec<String>,
        /// The state's variables, in order (`q,p`).
        #[arg(long, value_delimiter = ',', required = true)]
        vars: Vec<String>,
        /// The start, one value per variable.
        #[arg(long, value_delimiter = ',', required = true, allow_hyphen_values = true, value_parser = super::finite_f64)]
        from: Vec<f64>,
        /// How many iterations.
        #[arg(long)]
        steps: usize,
        /// Parameter values, `K=0.9,h=0.1`.
        #[arg(long, value_delimiter = ',')]
        params: Vec<String>,
        #[command(flatten)]
        common: Common,
    },
}

fn fail(e: MechanicsError) -> Failure {
    super::mechanics_failure(e)
}

pub fn run(cmd: NotesCommand) -> Result<(), Failure> {
    match cmd {
        NotesCommand::PhaseSpace { lagrangian, coords, bracket, common } => {
            phase_space(lagrangian, coords, bracket, common)?
        }
        NotesCommand::Geodesic {
            line_element,
            metric,
            embedding,
            coords,
            from,
            to,
            set,
            max_steps,
            time_limit,
            common,
        } => {
            let values = super::name_values("--set", &set, &common.positive)?;
            if max_steps == 0 || time_limit <= 0.0 {
                return Err(bad_input("error: --max-steps and --time-limit must be positive"));
            }
            let budget = ShootBudget { max_steps, time_limit: std::time::Duration::from_secs_f64(time_limit) };
            geodesic(line_element, metric, embedding, coords, (from, to), &values, budget, common)?
        }
        NotesCommand::Ritz { lagrangian, coords, trial, unknowns, span, from, to, set, guess, common } => {
            ritz(lagrangian, coords, trial, unknowns, span, from, to, set, guess, common)?
        }
        NotesCommand::Map { updates, vars, from, steps, params, common } => {
            iterate_map(updates, vars, from, steps, params, common)?
        }
        NotesCommand::Discretize { lagrangian, coords, rule, step, common } => {
            discretize(lagrangian, coords, rule, step, common)?
        }
    }
    Ok(())
}

/// `phase-space`: the first-order (phase-space) form of a Lagrangian: its one-form, Hamiltonian,
/// symplectic two-form ω, the equations ω z' = b, and where ω is invertible in closed form the
/// Poisson tensor, the velocities and an optional bracket {f, g}.
fn phase_space(lagrangian: String, coords: Vec<String>, bracket: Vec<String>, common: Common) -> Result<(), Failure> {
    if !bracket.is_empty() && bracket.len() != 2 {
        return Err(bad_input(format!(
            "error: --bracket takes exactly two expressions (f and g), {} given",
            bracket.len()
        )));
    }
    let text = read_expr_arg(&lagrangian)?;
    let decls = common.declarations();
    let names: Vec<&str> = coords.iter().map(|s| s.trim()).collect();
    let s = System::from_lagrangian_with(&text, &names, &decls).map_err(fail)?;
    let f = s.first_order().map_err(fail)?;
    let z = s.coordinates().to_vec();
    let mut out = Out::empty(common.format);
    out.json.insert("input".into(), json!(text.trim()));
    out.json.insert("coordinates".into(), json!(z.iter().map(|q| q.to_string()).collect::<Vec<_>>()));
    for (q, a) in z.iter().zip(&f.a) {
        let label = format!("a_{}", out.s(q));
        out.line(label, a);
    }
    out.json.insert("one_form".into(), json!(f.a.iter().map(plain).collect::<Vec<_>>()));
    out.line("H".into(), &f.h);
    out.json.insert("hamiltonian".into(), json!(plain(&f.h)));
    for i in 0..z.len() {
        for j in i + 1..z.len() {
            let label = format!("ω[{},{}]", out.s(&z[i]), out.s(&z[j]));
            out.line(label, &f.omega[i][j]);
        }
    }
    let omega: Vec<Vec<String>> = f.omega.iter().map(|r| r.iter().map(plain).collect()).collect();
    out.json.insert("two_form".into(), json!(omega));
    // ω z' = b, printed row by row as `Σ_j ω_ij z_j' = b_i`.
    let mut eqs = Vec::new();
    for (i, q) in z.iter().enumerate() {
        let lhs = Expr::add(f.omega[i].iter().zip(&z).map(|(w, zj)| w.times(&Expr::sym(zj.prime()))));
        let lhs = lagrangian::mechanics::tidy(&lhs);
        out.lines.push(format!("({})_{}: {} = {}", "ω z'", out.s(q), out.r(&lhs), out.r(&f.force[i])));
        eqs.push(json!({ "coordinate": q.to_string(), "lhs": plain(&lhs), "rhs": plain(&f.force[i]) }));
    }
    out.json.insert("equations".into(), Value::Array(eqs));
    f.check_nondegenerate().map_err(fail)?;
    match f.poisson_tensor() {
        Ok(p) => {
            for i in 0..z.len() {
                for j in i + 1..z.len() {
                    let label = format!("{{{}, {}}}", out.s(&z[i]), out.s(&z[j]));
                    out.line(label, &p[i][j]);
                }
            }
            let pj: Vec<Vec<String>> = p.iter().map(|r| r.iter().map(plain).collect()).collect();
            out.json.insert("poisson_tensor".into(), json!(pj));
            let v = f.velocities().map_err(fail)?;
            for (q, e) in z.iter().zip(&v) {
                let label = out.s(&q.prime());
                out.line(label, e);
            }
            out.json.insert("velocities".into(), json!(v.iter().map(plain).collect::<Vec<_>>()));
        }
        Err(MechanicsError::TooLarge { n, limit }) => {
            out.lines.push(format!(
                "note: {n} variables: the Poisson tensor is not formed in closed form beyond {limit}; \
                 the compiled right-hand side solves ω z' = b numerically"
            ));
        }
        Err(e) => return Err(fail(e)),
    }
    if let [fa, ga] = bracket.as_slice() {
        let (_, fe) = parse_arg(fa, &decls)?;
        let (_, ge) = parse_arg(ga, &decls)?;
        let b = f.bracket(&fe, &ge).map_err(fail)?;
        let label = format!("{{{}, {}}}", fa.trim(), ga.trim());
        out.line(label, &b);
        out.json.insert("bracket".into(), json!(plain(&b)));
    }
    out.print();
    Ok(())
}

/// `discretize`: the discrete Lagrangian of a quadrature rule, its discrete Euler–Lagrange
/// equations (with the inner-point conditions of a Galerkin rule) and the two discrete Legendre maps.
fn discretize(
    lagrangian: String,
    coords: Vec<String>,
    rule: String,
    step: String,
    common: Common,
) -> Result<(), Failure> {
    let Some(r) = Rule::from_name(rule.trim()) else {
        return Err(bad_input(format!(
            "error: unknown rule `{rule}` for discretize (expected midpoint, trapezoid or gauss2)"
        )));
    };
    let text = read_expr_arg(&lagrangian)?;
    let decls = common.declarations();
    let names: Vec<&str> = coords.iter().map(|s| s.trim()).collect();
    let s = System::from_lagrangian_with(&text, &names, &decls).map_err(fail)?;
    let (_, h) = parse_arg(&step, &decls)?;
    let d = s.discretize(r, &h).map_err(fail)?;
    let mut out = Out::empty(common.format);
    out.json.insert("input".into(), json!(text.trim()));
    out.json.insert("rule".into(), json!(r.name()));
    out.line("L_d".into(), &d.ld);
    out.json.insert("discrete_lagrangian".into(), json!(plain(&d.ld)));
    let del = d.euler_lagrange();
    for (q, e) in d.coords.iter().zip(&del) {
        let label = format!("DEL_{}", out.s(q));
        out.lines.push(format!("{label}: {} = 0", out.r(e)));
    }
    out.json.insert("discrete_euler_lagrange".into(), json!(del.iter().map(plain).collect::<Vec<_>>()));
    if !d.inner.is_empty() {
        // Galerkin: each step's inner point is fixed by ∂L̃/∂Q = 0.
        let stages = d.stage_equations();
        let labels = ["m0", "m1"].iter().flat_map(|tag| d.coords.iter().map(move |q| format!("{}_{tag}", q.name())));
        for (label, e) in labels.zip(&stages) {
            out.lines.push(format!("stage_{label}: {} = 0", out.r(e)));
        }
        for (m, e) in d.inner.iter().zip(&d.dm) {
            out.lines.push(format!("∂L_d/∂{}: {} = 0", out.s(m), out.r(e)));
        }
        out.json.insert("stage_equations".into(), json!(stages.iter().map(plain).collect::<Vec<_>>()));
        out.json.insert("inner_condition".into(), json!(d.dm.iter().map(plain).collect::<Vec<_>>()));
    }
    let (pk, pk1) = d.legendre_maps();
    for (q, e) in d.coords.iter().zip(&pk) {
        let label = format!("p_{}_0", q.name());
        out.line(label, e);
    }
    for (q, e) in d.coords.iter().zip(&pk1) {
        let label = format!("p_{}_1", q.name());
        out.line(label, e);
    }
    out.json.insert("momentum_k".into(), json!(pk.iter().map(plain).collect::<Vec<_>>()));
    out.json.insert("momentum_k1".into(), json!(pk1.iter().map(plain).collect::<Vec<_>>()));
    out.print();
    Ok(())
}

/// Splits `text` at `sep` outside brackets (`atan2(y, x), r` is two pieces).
fn split_top(text: &str, sep: char) -> Vec<String> {
    let mut out = vec![String::new()];
    let mut depth = 0i32;
    for c in text.chars() {
        match c {
            '(' | '[' | '{' => depth += 1,
            ')' | ']' | '}' => depth -= 1,
            _ => {}
        }
        if c == sep && depth == 0 {
            out.push(String::new());
        } else if let Some(last) = out.last_mut() {
            last.push(c);
        }
    }
    out
}

#[allow(clippy::too_many_arguments)]
fn geodesic(
    line_element: Option<String>,
    metric: Option<String>,
    embedding: Option<String>,
    coords: Vec<String>,
    (from, to): (Vec<f64>, Vec<f64>),
    values: &[(String, f64)],
    budget: ShootBudget,
    common: Common,
) -> Result<(), Failure> {
    use lagrangian::mechanics::{embedded, geodesic, geodesic_from_metric};
    let decls = common.declarations();
    let mut z = Vec::new();
    for c in &coords {
        let e = lagrangian::parse_with(c.trim(), &decls).map_err(Failure::parse)?;
        match e.as_sym() {
            Some(s) if s.primes() == 0 && !s.is_time() => z.push(s.clone()),
            _ => return Err(fail(MechanicsError::BadCoordinate(c.clone()))),
        }
    }
    let exprs = |pieces: Vec<String>| -> Result<Vec<Expr>, Failure> {
        pieces.iter().map(|p| parse_arg(p, &decls).map(|x| x.1)).collect()
    };
    let (input, g, surface) = match (line_element, metric, embedding) {
        (Some(text), None, None) => {
            let (text, ds2) = parse_arg(&text, &decls)?;
            (text, geodesic(&ds2, &z).map_err(fail)?, None)
        }
        (None, Some(text), None) => {
            let rows =
                split_top(&text, ';').into_iter().map(|row| exprs(split_top(&row, ','))).collect::<Result<_, _>>()?;
            (text, geodesic_from_metric(rows, &z).map_err(fail)?, None)
        }
        (None, None, Some(text)) => {
            let x = exprs(split_top(&text, ','))?;
            let emb = embedded(&x, &z).map_err(fail)?;
            (text, emb.geodesic.clone(), Some(emb))
        }
        _ => {
            return Err(bad_input("error: give the geometry once: a line element, --metric or --embedding".to_string()))
        }
    };
    let mut out = Out::empty(common.format);
    let fmt = common.format.expr_format();
    out.json.insert("input".into(), json!(input.trim()));
    let metric: Vec<Vec<String>> = g.metric.iter().map(|r| r.iter().map(plain).collect()).collect();
    out.json.insert("metric".into(), json!(metric));
    let curv = g.curvature();
    let sys = g.system().map_err(fail)?;
    out.lines.extend(g.report(&curv, &sys.conserved(), fmt));
    out.json.insert("equations".into(), json!(g.equations.iter().map(plain).collect::<Vec<_>>()));
    out.json.insert("scalar_curvature".into(), json!(plain(&curv.scalar)));
    if let Some(k) = &curv.gauss {
        out.json.insert("gauss_curvature".into(), json!(plain(k)));
    }
    if let Some(emb) = &surface {
        out.lines.extend(emb.report(fmt));
        out.json.insert("embedding".into(), json!(emb.surface.iter().map(plain).collect::<Vec<_>>()));
        out.json.insert("tangential_curvature".into(), json!(emb.tangential.iter().map(plain).collect::<Vec<_>>()));
    }
    if !from.is_empty() || !to.is_empty() {
        if from.len() != z.len() || to.len() != z.len() {
            return Err(bad_input(format!("error: --from and --to need {} numbers each", z.len())));
        }
        let bound: Vec<(&str, f64)> = values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
        let shot = lagrangian::compile::shoot_with(&g, &from, &to, &bound, 1, budget).map_err(|e| {
            let raise = match &e {
                ShootError::Budget { steps: true, .. } => "; to search longer, raise --max-steps",
                ShootError::Budget { steps: false, .. } => "; to search longer, raise --time-limit (seconds)",
                _ => "",
            };
            Failure { kind: "numeric", ..bad_input(format!("error: {e}{raise}")) }
        })?;
        out.lines.push(shot.report_line());
        out.json.insert("initial_velocity".into(), json!(shot.velocity));
    }
    out.print();
    Ok(())
}

#[allow(clippy::too_many_arguments)]
fn ritz(
    lagrangian: String,
    coords: Vec<String>,
    trial: Vec<String>,
    unknowns: Vec<String>,
    span: Vec<String>,
    from: Vec<String>,
    to: Vec<String>,
    set: Vec<String>,
    guess: Vec<f64>,
    common: Common,
) -> Result<(), Failure> {
    let text = read_expr_arg(&lagrangian)?;
    let decls = common.declarations();
    let names: Vec<&str> = coords.iter().map(|s| s.trim()).collect();
    let s = System::from_lagrangian_with(&text, &names, &decls).map_err(fail)?;
    let exprs =
        |v: &[String]| -> Result<Vec<Expr>, Failure> { v.iter().map(|x| parse_arg(x, &decls).map(|p| p.1)).collect() };
    let trial = exprs(&trial)?;
    let ends = |v: &[String]| -> Result<Vec<Option<Expr>>, Failure> {
        v.iter().map(|x| if x.trim() == "free" { Ok(None) } else { parse_arg(x, &decls).map(|p| Some(p.1)) }).collect()
    };
    let (from, to) = (ends(&from)?, ends(&to)?);
    let span = exprs(&span)?;
    let [t0, t1] = span.as_slice() else {
        return Err(bad_input(format!("error: --span takes two values t0,t1, {} given", span.len())));
    };
    let mut a = Vec::new();
    for u in &unknowns {
        match parse_arg(u, &decls)?.1.as_sym() {
            Some(sym) if sym.primes() == 0 && !sym.is_time() => a.push(sym.clone()),
            _ => return Err(bad_input(format!("error: the unknown `{u}` must be a plain name"))),
        }
    }
    let values = super::name_values("--set", &set, &common.positive)?;
    let r = s.ritz_ends(&trial, &a, (t0, t1), (&from, &to)).map_err(fail)?;
    let bound: Vec<(&str, f64)> = values.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let sol = r.solve(&guess, &bound).map_err(fail)?;
    let mut out = Out::empty(common.format);
    out.json.insert("input".into(), json!(text.trim()));
    out.json.insert("action".into(), json!(r.action_text()));
    out.json.insert("action_exact".into(), json!(r.action.is_some()));
    out.json.insert("conditions".into(), json!(r.condition_texts()));
    out.json.insert("solution".into(), json!(sol.values));
    out.json.insert("stationary_action".into(), json!(sol.action));
    if !r.natural.is_empty() {
        let nat: Vec<Value> = r
            .natural
            .iter()
            .zip(&sol.natural)
            .map(|((q, end, p), v)| json!({"coordinate": q.to_string(), "at": plain(end), "momentum": plain(p), "value": v}))
            .collect();
        out.json.insert("natural_boundary_conditions".into(), json!(nat));
    }
    out.lines = r.report(&sol, common.format.expr_format());
    out.print();
    Ok(())
}

/// `lagrangian map`: the orbit of one start under an explicit or implicit map.
fn iterate_map(
    updates: Vec<String>,
    vars: Vec<String>,
    from: Vec<f64>,
    steps: usize,
    params: Vec<String>,
    common: Common,
) -> Result<(), Failure> {
    let decls = common.declarations();
    let mut parsed = Vec::with_capacity(updates.len());
    for u in &updates {
        let (target, value) = u
            .split_once('=')
            .ok_or_else(|| bad_input(format!("error: an update is `name = expression`, got `{u}`")))?;
        parsed.push((super::parse_var(target.trim(), &decls)?, parse_arg(value, &decls)?.1));
    }
    let names: Vec<lagrangian::expr::Symbol> =
        vars.iter().map(|v| super::parse_var(v.trim(), &decls)).collect::<Result<_, _>>()?;
    let params = super::name_values("--params", &params, &common.positive)?;
    let params: Vec<(&str, f64)> = params.iter().map(|(k, v)| (k.as_str(), *v)).collect();
    let run = lagrangian::mechanics::PhaseMap::new(&names, &parsed, &params)
        .and_then(|m| m.run(&[from], steps))
        .map_err(|e| bad_input(format!("error: {e}")))?;
    if common.format == super::OutFormat::Json {
        let states: Vec<Vec<Option<f64>>> =
            run.orbits[0].iter().map(|s| s.iter().map(|x| x.is_finite().then_some(*x)).collect()).collect();
        println!(
            "{}",
            json!({"variables": vars, "implicit": run.implicit, "unsolved": run.unsolved, "states": states})
        );
    } else {
        for l in run.report() {
            println!("{l}");
        }
    }
    Ok(())
}
