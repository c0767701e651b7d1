//! The statement registry: one row per statement — its keywords, its help topic, the grammar
//! rule it parses from and the function that reads that rule's pairs into the statement's
//! own type. The parser's dispatch (rule → reader), its list of statement words ("did you
//! mean", the REPL's completion) and `help` (here, handed to the `help` statement's reader)
//! are all derived from this table; the session runs
//! whatever the reader returned through `Stmt::run`. Adding a statement adds its grammar
//! rule, its row here and its own file under `statements/` (its type, reader, handler and
//! output file); nothing else lists statements.
//!
//! The table holds plain `fn` pointers (non-capturing closures) rather than one trait object
//! per row: a row is data that reads like the help it prints, and the lookup is a scan of a
//! `const` slice. Only the parsed statement is a trait object (`Box<dyn Stmt>`), because each
//! statement has its own type: the trait ties a type to its handler at compile time, where a
//! table of `fn(&mut Session, &dyn Any)` handlers would need a downcast that could fail at run
//! time.

use super::statements::animate::AnimateSpec;
use super::statements::canonical::{Action, Average, Integral, Lie, PointTransform, Transform};
use super::statements::chaos::ChaosSpec;
use super::statements::control::{AllowNonfinite, Help, History, Load};
use super::statements::declare::{Coordinates, Functions, Parameters};
use super::statements::define::Define;
use super::statements::dynamics::{Constraint, Force, Rayleigh};
use super::statements::energy_at::EnergyAt;
use super::statements::expansion::{Jacobian, Series};
use super::statements::figures::{Export, PlotSpec};
use super::statements::flow::FlowSpec;
use super::statements::geodesic::GeodesicSpec;
use super::statements::map::Map;
use super::statements::print::{Derive, FormatStmt, Print};
use super::statements::ritz::RitzSpec;
use super::statements::sections::ExportPoincare;
use super::statements::Stmt;
use super::syntax::error::{did_you_mean, ErrorKind, SceneError, Span};
use super::syntax::parser::{self, Language, Pair, Reader, Rule};

/// One statement's row: its help (keyword, form, description, example) and how it is read.
pub struct Topic {
    /// The topic's name (`help NAME`).
    pub word: &'static str,
    /// The words a statement of this topic starts with: the parser's statement list and the
    /// REPL's completion are these, in this order.
    pub keywords: &'static [&'static str],
    /// The statement's form.
    pub form: &'static str,
    /// What it does.
    pub about: &'static str,
    /// A complete example statement.
    pub example: &'static str,
    /// The grammar rule this topic's statements parse from and their reader; `None` for a
    /// topic that shares another row's rule (`megno` reads like `lyapunov`).
    pub read: Option<Read>,
}

/// A grammar rule and the function reading its pairs into a statement.
#[derive(Clone, Copy)]
pub struct Read {
    /// The rule (one of `stmt`'s alternatives in `grammar/scene.pest`).
    pub rule: Rule,
    /// Reads the rule's pair.
    pub(in crate::scene) read: ReadFn,
}

/// Reads one statement's pair into its statement.
pub(in crate::scene) type ReadFn = for<'i> fn(&Reader, Pair<'i, Rule>) -> Result<Box<dyn Stmt>, SceneError>;

/// A row's reader (a `const fn`, so the table stays a `const`).
const fn reads(rule: Rule, read: ReadFn) -> Option<Read> {
    Some(Read { rule, read })
}

/// One parsed statement and its span.
#[derive(Debug)]
pub struct Statement {
    /// What it says: the statement's own type, run by the session.
    pub(in crate::scene) node: Box<dyn Stmt>,
    /// Where it is (all its lines).
    pub span: Span,
}

/// Every statement, in the order `help` lists them.
pub const REGISTRY: &[Topic] = &[
    Topic { word: "coordinates", keywords: &["coordinates"], form: "coordinates q1, q2, … | coordinates x[0..4], …", about: "declares the generalized coordinates; `q'` is the velocity of `q`, `p_q` its momentum; `x[0..4]` declares x0 … x4 (inclusive), which expressions name `x[i]` (and their momenta `p_x[i]`)", example: "coordinates θ", read: reads(Rule::coordinates, |r, p| Ok(Box::new(Coordinates::read(r, p)?))) },
    Topic { word: "parameters", keywords: &["parameters"], form: "parameters a = VALUE, b, m[0..2] = V0, V1, V2, … [positive]", about: "declares constants, with optional values (needed to simulate); `m[0..2]` declares m0, m1, m2 with one value each, in order; `positive` applies to all of them", example: "parameters m = 1, l = 1, g = 9.81 positive", read: reads(Rule::parameters, |r, p| Ok(Box::new(Parameters::read(r, p)?))) },
    Topic { word: "functions", keywords: &["functions"], form: "functions V, …", about: "declares undefined functions such as a general potential `V(r)`; `V'(r)` is its derivative", example: "functions V", read: reads(Rule::functions, |r, p| Ok(Box::new(Functions::read(r, p)?))) },
    Topic { word: "define", keywords: &[], form: "NAME = EXPRESSION | NAME = el(L) | legendre(L) | hamilton(H) | conserved(L) | pb(f, g) | energy(L) | accelerations(L)", about: "defines `L`, `H` or any named expression; derivations on the right are computed only when an output needs them. `sum(i = 0..4, …)` and `sum(i < j in 0..4, …)` (each pair once) with `x[i]` for x0 … are expanded as they are read, so printed output shows the written-out terms, never `sum(…)`", example: "L = 1/2 m l^2 θ'^2 - m g l (1 - cos(θ))", read: reads(Rule::definition, |r, p| Ok(Box::new(Define::read(r, p)?))) },
    Topic { word: "el", keywords: &["el"], form: "el [as FORMAT]", about: "prints the Euler–Lagrange equations E_i = d/dt ∂L/∂q'_i − ∂L/∂q_i = Q_i − ∂R/∂q'_i + Σ λ_j ∂f_j/∂q_i (0 without force, rayleigh or constraint), as `lagrangian el` prints them", example: "el", read: reads(Rule::derive_stmt, |r, p| Ok(Box::new(Derive::read(r, p)?))) },
    Topic { word: "accelerations", keywords: &["accelerations"], form: "accelerations [as FORMAT]", about: "prints the accelerations q'' = W⁻¹ F with the declared forces and dissipation; with constraints the constrained accelerations (λ eliminated by the constraints differentiated twice) and each multiplier λ_j, as `lagrangian el --accelerations` prints them", example: "accelerations", read: None },
    Topic { word: "legendre", keywords: &["legendre"], form: "legendre [as FORMAT]", about: "prints the Hamiltonian H(q, p) obtained from L by the Legendre transform", example: "legendre", read: None },
    Topic { word: "hamilton", keywords: &["hamilton"], form: "hamilton [as FORMAT]", about: "prints Hamilton's equations q' = ∂H/∂p, then p' = −∂H/∂q plus the declared forces, dissipation and constraint terms (H from `H = …` or from L)", example: "hamilton", read: None },
    Topic { word: "conserved", keywords: &["conserved"], form: "conserved [as FORMAT]", about: "prints the conserved quantities with the reason for each: ignorable momenta, the energy, and the charges of the point symmetries found by a polynomial search (rotations, boosts, time changes; the search's bound is stated), as `lagrangian conserved` prints them", example: "conserved", read: None },
    Topic { word: "pb", keywords: &["pb"], form: "pb f, g", about: "prints the Poisson bracket {f, g} = Σ ∂f/∂q ∂g/∂p − ∂f/∂p ∂g/∂q", example: "pb θ, p_θ", read: None },
    Topic { word: "energy", keywords: &["energy"], form: "energy", about: "prints the energy function h = Σ q' ∂L/∂q' − L (or H)", example: "energy", read: None },
    Topic { word: "energy at", keywords: &[], form: "energy at q = …, q' = … | energy at q = …, p_q = …", about: "the energy function h = Σ q' ∂L/∂q' − L (or H) that `energy` prints, evaluated at one state with the scene's parameter values; a state variable h needs and not given is an error naming it", example: "energy at θ = 1, θ' = 0", read: reads(Rule::energy_at, |r, p| Ok(Box::new(EnergyAt::read(r, p)?))) },
    Topic { word: "average", keywords: &["average"], form: "average [L] with q = TRIAL, … phase θ frequency ω amplitudes A, … [small σ unperturbed ω0 [principal A] [order N] [for A in a..b [points N] [to FILE.svg|FILE.png|FILE.csv]]]", about: "the averaged Lagrangian ⟨L⟩ = (1/2π)∮ L dθ of a trial function periodic in the phase (q' → ω ∂q/∂θ), its relations ∂⟨L⟩/∂A = 0 and the action J = ∂⟨L⟩/∂ω; with `small`, the relations solved as a series in σ to order N (default 1, at most 4; as `lagrangian average --small --order`); with `for A in a..b`, the relations also solved numerically at N amplitudes (default 20) with the scene's parameter values, by Newton's method continued along A, printed beside the series and drawn (or tabulated) against A", example: "average L with x = A cos(θ) phase θ frequency ω amplitudes A", read: reads(Rule::average, |r, p| Ok(Box::new(Average::read(r, p)?))) },
    Topic { word: "transform", keywords: &["transform"], form: "transform [H] with F1|F2|F3|F4 = F new Q…, P…", about: "the canonical transformation generated by F (PHYSICS.md §4): the relations, the old variables in terms of the new ones and back, the branches taken and the new Hamiltonian K = H + ∂F/∂t, as `lagrangian canonical --f1 …` prints them", example: "transform with F1 = 1/2 m ω q^2 cot(Q) new Q, P", read: reads(Rule::transform, |r, p| Ok(Box::new(Transform::read(r, p)?))) },
    Topic { word: "transform (point)", keywords: &[], form: "transform [L] with x = X(s, t), … [to s1, s2, …] [as FORMAT]", about: "a point transformation: the Lagrangian in new coordinates (named by `to`, else the map's new symbols in order), the same as `lagrangian transform L --map … --to …`", example: "transform with x = r cos(φ), y = r sin(φ) to r, φ", read: reads(Rule::transform_point, |r, p| Ok(Box::new(PointTransform::read(r, p)))) },
    Topic { word: "lie", keywords: &["lie"], form: "lie f with G [order N] [in ε] | lie f flow [H] [order N] [as FORMAT]", about: "the Lie series exp(ε{·, G}) f to order N (default 3), or the flow of H (default the scene's) as a series in t; the same as `lagrangian lie`", example: "lie q flow order 4", read: reads(Rule::lie, |r, p| Ok(Box::new(Lie::read(r, p)?))) },
    Topic { word: "integral", keywords: &["integral"], form: "integral f [with H] [as FORMAT]", about: "whether f is an integral of motion: df/dt = {f, H} + ∂f/∂t, proven zero or not (the same as `lagrangian integral`)", example: "integral x p_y - y p_x", read: reads(Rule::integral, |r, p| Ok(Box::new(Integral::read(r, p)?))) },
    Topic { word: "series", keywords: &["series"], form: "series EXPR in x, … [order N] | series L about q = q0, … [order N] [as FORMAT]", about: "the power series of EXPR to total degree N (default 2) in the small quantities x, …; or of a Lagrangian about the point q = q0 in the displacements (which keep the coordinates' names) and the velocities: the small-oscillation Lagrangian L_lin of the notes (2.29); the same as `lagrangian series`", example: "series sin(x) in x order 5", read: reads(Rule::series, |r, p| Ok(Box::new(Series::read(r, p)?))) },
    Topic { word: "jacobian", keywords: &["jacobian"], form: "jacobian (X1, X2, …) in y1, y2, … [as FORMAT]", about: "the Jacobian matrix ∂X_i/∂y_j of a map of coordinates and its determinant, simplified (§1.3: the volume ratio of the ideal fluid); the same as `lagrangian jacobian`", example: "jacobian (r cos(φ), r sin(φ)) in r, φ", read: reads(Rule::jacobian, |r, p| Ok(Box::new(Jacobian::read(r, p)))) },
    Topic { word: "map", keywords: &["map"], form: "map q = Q(q, p), p = P(q, p), … | map q' = Q(q, p, q', p'), p' = … for N steps from q = A..B, p = C, … [points N] [to FILE.svg|FILE.png]", about: "iterates a map of phase space N times from starts spread evenly over each range (`points` values per range, default 10; several ranges give a grid), compiled once; draws the orbits and prints the last state of each (up to 10). Plain assignments run in order, each seeing the values already assigned this step (the standard map p = p + K sin q, q = q + p). Primed ones give the new values `q'`, `p'` by equations that may use them (the implicit midpoint rule q' = q + h (p + p')/2, p' = p − h (q + q')/2, notes §4.7.2), solved by Newton's method each step; an orbit whose step has no solution stops and is counted", example: "map q' = q + 0.1 (p + p')/2, p' = p - 0.1 (q + q')/2 for 500 steps from q = 1, p = 0", read: reads(Rule::map_stmt, |r, p| Ok(Box::new(Map::read(r, p)?))) },
    Topic { word: "action", keywords: &["action"], form: "action [H] at E = E1, E2, … [near q0]", about: "J(E) = (1/2π)∮ p dq, the period T(E) and ω(E) = 2π/T of a one-degree-of-freedom H by quadrature, for librations (turning points around q0) and rotations (an angle turning over the top: J = (1/2π)∫₀^{2π} p dq); the same table as `lagrangian action`", example: "action at E = 0.5, 1, 3", read: reads(Rule::action, |r, p| Ok(Box::new(Action::read(r, p)))) },
    Topic { word: "geodesic", keywords: &["geodesic"], form: "geodesic [ds^2 =] LINE_ELEMENT | metric (g11, g12, …), (g21, …), … | embedding (X, Y, Z) [from (q1, …) to (q1, …)] [as FORMAT]", about: "the geodesics of the scene's coordinates (differentials `dθ`): the metric, the Christoffel symbols Γ^k_ij, the geodesic equations, the curvature (R_abcd, the scalar, and K for a surface) and the conserved quantities, the same lines as `lagrangian geodesic`; for a surface x = X(q) also the induced metric X_i · X_j and the components X_i · d²x/ds² of a geodesic's curvature vector (0: it is normal to the surface, §1.6.3); `from … to …` adds a shooting solution in unit time", example: "geodesic ds^2 = dθ^2 + sin(θ)^2 dφ^2 from (1, 0) to (2, 1.5)", read: reads(Rule::geodesic, |r, p| Ok(Box::new(GeodesicSpec::read(r, p)))) },
    Topic { word: "ritz", keywords: &["ritz"], form: "ritz [L] with q = TRIAL, … for t in A..B from q = VALUE, … to q = VALUE, … solve a, b, … [near a0, b0, …] [as FORMAT]", about: "the trial-function method for fixed end points (§1.4.2): the action S(a) = ∫ L dt along the trial path (exact for an integrand polynomial in t, else Gauss–Legendre), the conditions ∂S/∂a = 0 and their solution by Newton from `near` (default 0); the same lines as `lagrangian ritz`", example: "ritz with x = t + a t (1 - t) for t in 0..1 from x = 0 to x = 1 solve a", read: reads(Rule::ritz, |r, p| Ok(Box::new(RitzSpec::read(r, p)?))) },
    Topic { word: "force", keywords: &["force"], form: "force q = Q(q, q', t)", about: "adds a generalized (non-potential) force on the coordinate q: the equation of motion becomes E_q = Q (PHYSICS.md (2.12)); runs integrate it from L (dop853, rk4, gauss6)", example: "force θ = A cos(Ω t)", read: reads(Rule::force, |r, p| Ok(Box::new(Force::read(r, p)?))) },
    Topic { word: "rayleigh", keywords: &["rayleigh"], form: "rayleigh [R =] R(q, q')", about: "sets the Rayleigh dissipation function: the equations become E + ∂R/∂q' = 0, and the energy decays as dE/dt = −2R for R quadratic in the velocities; with a name, R is also defined", example: "rayleigh R = 1/2 b x'^2", read: reads(Rule::rayleigh, |r, p| Ok(Box::new(Rayleigh::read(r, p)?))) },
    Topic { word: "constraint", keywords: &["constraint"], form: "constraint f(q, t) [= g(q, t)] | constraint velocity a(q, t)·q' + b(q, t) [= …]", about: "adds the holonomic constraint f − g = 0 with a multiplier λ1, λ2, … (in order). Runs solve the augmented system [W Φᵀ; Φ 0][q''; −λ] = [F; c] and are held on the constraint by `stabilize projection` (default) or `stabilize baumgarte [= RATE]`; `λ1` and `residual1` can be exported and plotted along the run, and the run summary reports the drift. `constraint velocity …` adds a nonholonomic constraint linear in the velocities (rolling: `constraint velocity x' = R φ' cos(θ)`) with a multiplier μ1, μ2, …: runs solve the Lagrange–d'Alembert equations W q'' = F + aᵀμ with a q'' = −ȧ q' − ḃ, held on a q' + b = 0 by projection of the velocities; its residual follows the holonomic ones", example: "constraint x^2 + y^2 = l^2", read: reads(Rule::constraint, |r, p| Ok(Box::new(Constraint::read(r, p)?))) },
    Topic { word: "print", keywords: &["print"], form: "print ITEM, … [as plain|unicode|latex]", about: "prints expressions, definitions or derivations; a derivation is also a function inside an expression (`pb(pb(x, p_x), H)`, `legendre(L) + 1`); each value is simplified as `lagrangian simplify` does (an identically zero one prints 0)", example: "print L as latex", read: reads(Rule::print, |r, p| Ok(Box::new(Print::read(r, p)?))) },
    Topic { word: "simulate", keywords: &["simulate"], form: "simulate q = …, q' = … for t in A..B [with METHOD] [dt = … | steps = … | tol = …] [record|stop when EXPR [= EXPR] [rising|falling]] [stabilize projection|baumgarte [= RATE]|none] [every N | points N] [drift = X] [max_steps = N] [as NAME]; an ensemble: simulate … for each y in A..B step H on E = VALUE solve p_x > 0 for t in …", about: "integrates the equations of motion (with the forces, dissipation and constraints declared before it). With `for each`, one run per value of the swept variable, each started on the level set E = VALUE by solving for the named variable on the given side of zero, integrated in parallel; `from NAME` then means all of them, `NAME_k` the k-th. The conserved energy (H, or h when L has no t) is checked after every step: a relative drift above X (default 1e-3) is a warning naming the run and the time (an error with `--strict`); adaptive methods stop after 10⁶ steps unless `max_steps = N` raises the budget; Ctrl-C stops the run. The methods are listed below. Velocities are turned into momenta through L when the method integrates H", example: "simulate θ = 3.0, θ' = 0 for t in 0..20 with gauss6 dt = 0.01", read: reads(Rule::simulate, |r, p| Ok(Box::new(r.simulate_stmt(p)?))) },
    Topic { word: "lyapunov", keywords: &["lyapunov"], form: "lyapunov q = …, q' = … for t in 0..T [tol = …] [max_steps = N] [time_limit = S] [as NAME]", about: "the Lyapunov spectrum of the orbit (Benettin's QR algorithm on the variational equations of H, Taylor method, tol 1e-12 by default): printed largest first; a Hamiltonian spectrum comes in ± pairs. `plot lyapunov` draws λ(t)", example: "lyapunov θ = 1, θ' = 0 for t in 0..100", read: reads(Rule::chaos, |r, p| Ok(Box::new(ChaosSpec::read(r, false, p)?))) },
    Topic { word: "megno", keywords: &["megno"], form: "megno q = …, q' = … for t in 0..T [tol = …] [max_steps = N] [time_limit = S] [as NAME]", about: "MEGNO ⟨Y⟩ of the orbit (Cincotta & Simó): → 2 for quasi-periodic motion, → 0 for isochronous linear motion, grows like λt/2 for chaotic motion; also prints the maximal exponent. `plot megno` draws ⟨Y⟩(t)", example: "megno θ = 1, θ' = 0 for t in 0..100", read: None },
    Topic { word: "fli", keywords: &["fli"], form: "fli q = …, q' = … for t in 0..T [tol = …] [max_steps = N] [time_limit = S] [as NAME]", about: "the fast Lyapunov indicator sup ln‖w(t)‖ of a unit tangent vector; `plot fli` draws it against t", example: "fli θ = 1, θ' = 0 for t in 0..100", read: None },
    Topic { word: "flow", keywords: &["flow"], form: "flow q = …, q' = … for t in 0..T [tol = …] [points N] [max_steps = N] [time_limit = S] [to FILE.svg|FILE.png|FILE.csv]", about: "the flow's Jacobian Φ(T) = ∂x(T)/∂x(0) in x = (q, p) by the variational equations (Taylor method, default tol 1e-14), printed with det Φ − 1 (Liouville) and, for a Hamiltonian flow, the symplectic defect max |ΦᵀJΦ − J| (notes §4.6.1), the same lines as `lagrangian flow`. With `force` or `rayleigh` the flow is not Hamiltonian: det Φ is printed as a value (e^{−γT} for x'' = −γx' − ω²x), the defect is not. With a file: |det Φ − 1| and the defect against t on a log axis, at about N steps (default 400), or a CSV table t, det_minus_one, symplectic_defect. Constraints are refused", example: "flow θ = 1, θ' = 0 for t in 0..10", read: reads(Rule::flow_stmt, |r, p| Ok(Box::new(FlowSpec::read(r, p)?))) },
    Topic { word: "chaos_map", keywords: &["chaos_map"], form: "chaos_map lyapunov|megno|fli x = A..B, y = C..D, OTHER = …, … for t in 0..T [on H = E solve p_x > 0] [points N] [tol = …] [max_steps = N] [time_limit = S] [stop megno >= L after T] [to FILE.svg|FILE.png|FILE.csv]", about: "the indicator over an N × N grid of starts (default 32 × 32; cell centres) on all cores, with a progress bar: a heat map, or a CSV table of x, y, value. A start that fails is blank (NaN in the table). With `on H = E solve p_x > 0` each start is put on the level set by solving for p_x on that side; cells with no such point are blank (an empty value in the table). With `stop megno >= L after T` (MEGNO maps only; L > 2, T ≥ 0) an orbit whose mean MEGNO reaches L once t ≥ T ends there: its cell holds ⟨Y⟩ at the stop (read it as ⟨Y⟩ ≥ L), the table gains a column `stopped_at` (empty for cells that ran to the end), and the heat map's title and the summary say so. The regular cells are unchanged, and the chaotic ones cost far less (the 200 × 200 double-pendulum map ran about 2.6× faster with `stop megno >= 5 after 10`)", example: "chaos_map megno θ = -3..3, θ' = -2..2 for t in 0..50 points 16", read: reads(Rule::chaos_map, |r, p| Ok(Box::new(ChaosSpec::read(r, true, p)?))) },
    Topic { word: "plot", keywords: &["plot"], form: "plot phase [q] | energy | lyapunov | megno | fli | path x, y | poincare x, y | separation a, b | work_precision [against REF] | EXPR, … vs t  [from RUN, …] [to FILE.svg|FILE.png]", about: "draws a phase portrait (with contours of H for one coordinate: O and X points and the separatrix), the relative energy error, a configuration-space path, a Poincaré section, time series, a chaos indicator of a `lyapunov`, `megno` or `fli` statement against t, the separation of two runs (log₁₀ of their phase-space distance against t, with the fitted slope printed as a finite-time Lyapunov estimate; the runs must take the same fixed steps), or a work-precision diagram (error against right-hand-side evaluations, one line per method; the error is the final coordinates' distance from the run REF, else the largest relative energy error)", example: "plot phase to pendulum_phase.svg", read: reads(Rule::plot, |r, p| Ok(Box::new(PlotSpec::read(r, p)?))) },
    Topic { word: "animate", keywords: &["animate"], form: "animate [path] (x, y), (x, y), … [from RUN] to FILE.gif [fps N] [duration SECONDS] [size PIXELS]", about: "writes the motion of a run as a GIF: a body at each point, arms joining consecutive points, the last body's trail and the time in the corner; the run's span is shown in `duration` seconds (default 4) at `fps` frames per second (default 10) on a square of `size` pixels (default 320)", example: "animate path (0, 0), (sin(θ), -cos(θ)) to pendulum.gif fps 10 duration 2 size 160", read: reads(Rule::animate, |r, p| Ok(Box::new(AnimateSpec::read(r, p)?))) },
    Topic { word: "export", keywords: &["export"], form: "export [ITEM, …] [from RUN] to FILE.csv|FILE.json", about: "writes a run's state (or expressions along it) as CSV or JSON, or derived equations as JSON; every stored state is written (a fixed-step run of more than 20,000 steps stores every k-th, with a printed note, unless `simulate … every N` or `points N` says otherwise)", example: "export t, θ, θ' to pendulum.csv", read: reads(Rule::export, |r, p| Ok(Box::new(Export::read(r, p)?))) },
    Topic { word: "allow", keywords: &["allow"], form: "allow nonfinite", about: "lets later `export … to FILE.csv` keep inf and NaN (written `inf`, `-inf`, `NaN`, with a note counting them) instead of refusing the export; JSON still refuses them, having no spelling for them", example: "allow nonfinite", read: reads(Rule::allow, |_, _| Ok(Box::new(AllowNonfinite))) },
    Topic { word: "export poincare", keywords: &[], form: "export poincare [EXPR, …] [from RUN] to FILE.csv|FILE.json", about: "writes the points recorded by `record when …` (the Poincaré section that `plot poincare` draws): the time, the event's number and the expressions (default: the state) at each crossing", example: "export poincare θ, θ' to section.csv", read: reads(Rule::export_poincare, |r, p| Ok(Box::new(ExportPoincare::read(r, p)?))) },
    Topic { word: "load", keywords: &["load"], form: "load FILE", about: "runs the statements of a scene file in this session", example: "load examples/pendulum.scene", read: reads(Rule::load, |r, p| Ok(Box::new(Load::read(r, p)?))) },
    Topic { word: "format", keywords: &["format"], form: "format plain|unicode|latex", about: "sets the default output format (Unicode at start)", example: "format latex", read: reads(Rule::format_stmt, |r, p| Ok(Box::new(FormatStmt::read(r, p)))) },
    Topic { word: "latex", keywords: &["latex", "unicode", "plain"], form: "latex | unicode | plain", about: "reprints the last result in that format", example: "latex", read: None },
    Topic { word: "history", keywords: &["history"], form: "history", about: "lists the remembered input lines (REPL)", example: "history", read: reads(Rule::history, |_, _| Ok(Box::new(History))) },
    Topic { word: "help", keywords: &["help"], form: "help [TOPIC]", about: "this help: with a topic (one or more words, as listed: `help energy at`), its form, what it does and an example", example: "help simulate", read: reads(Rule::help, |r, p| Ok(Box::new(Help::read(r, p, help)?))) },
];

/// The words that start a statement, in registry order (for "did you mean" and completion).
pub fn statement_words() -> impl Iterator<Item = &'static str> {
    REGISTRY.iter().flat_map(|t| t.keywords.iter().copied())
}

/// The scene language as the parser reads it: each rule through its row's reader.
const LANGUAGE: Language<Box<dyn Stmt>> = Language { read: read_statement, words: || statement_words().collect() };

/// Reads a statement's pair by its rule's row.
fn read_statement(r: &Reader, p: Pair<'_, Rule>) -> Result<Box<dyn Stmt>, SceneError> {
    let rule = p.as_rule();
    match REGISTRY.iter().find_map(|t| t.read.filter(|x| x.rule == rule)) {
        Some(x) => (x.read)(r, p),
        None => Err(SceneError::new(ErrorKind::Syntax, "unrecognised statement").at(r.span(&p))),
    }
}

/// Parses a whole scene into statements; stops at the first malformed one.
pub fn parse_scene(text: &str) -> Result<Vec<Statement>, SceneError> {
    let mut out = Vec::new();
    for (s, e) in parser::split_statements(text) {
        if let Some(stmt) = parse_statement_at(text, s, e)? {
            out.push(stmt);
        }
    }
    Ok(out)
}

/// Parses the statement in `text[start..end]` (spans are positions in `text`).
pub fn parse_statement_at(text: &str, start: usize, end: usize) -> Result<Option<Statement>, SceneError> {
    let node = parser::parse_statement_at(text, start, end, &LANGUAGE)?;
    Ok(node.map(|node| Statement { node, span: (start, end) }))
}

/// The help for `topic` (its words separated by single blanks): the form, what it does, an
/// example, and the longer topics that begin with it (`energy` names `energy at`); with no
/// topic, the overview. An unknown topic is `Err` with the nearest topic, if one is near.
pub fn help(topic: Option<&str>) -> Result<String, Option<&'static str>> {
    let Some(w) = topic else { return Ok(overview()) };
    let w = if ["plain", "unicode"].contains(&w) { "latex" } else { w };
    // `transform (point)` may be asked for without its brackets.
    let bare = |word: &str| word.replace(['(', ')'], "");
    let found = REGISTRY
        .iter()
        .find(|t| t.word == w || bare(t.word) == w || (t.word == "define" && ["L", "H", "="].contains(&w)));
    let Some(t) = found else { return Err(did_you_mean(w, REGISTRY.iter().map(|t| t.word))) };
    let mut s = format!("{}\n  {}\n  example: {}", t.form, t.about, t.example);
    if t.word == "simulate" {
        let methods: Vec<String> = crate::simulate::method::method_table().iter().map(|l| format!("    {l}")).collect();
        s.push_str(&format!("\n  methods:\n{}", methods.join("\n")));
    }
    let longer: Vec<String> = REGISTRY
        .iter()
        .filter(|u| u.word.strip_prefix(t.word).is_some_and(|rest| rest.starts_with(' ')))
        .map(|u| format!("`help {}`", u.word))
        .collect();
    if !longer.is_empty() {
        s.push_str(&format!("\n  see also: {}", longer.join(", ")));
    }
    Ok(s)
}

/// Every topic with its form.
fn overview() -> String {
    let mut s = String::from("statements (`help NAME` for details):\n");
    for t in REGISTRY {
        s.push_str(&format!("  {:<12} {}\n", t.word, t.form));
    }
    s.push_str("`#` starts a comment; a statement continues on the next line while a bracket is open, after a trailing operator, or on an indented line.");
    s
}
