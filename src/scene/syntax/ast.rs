//! The statement tree's shared pieces (a statement with its own file under `statements/` keeps
//! its type there, beside its reader and handler). Expressions stay as source text with their span until the session
//! parses them with its current declarations (which functions exist, which symbols are
//! positive): declarations earlier in a scene change how later text parses.

pub use super::error::Span;

/// A piece of source: an expression, a name or a path, with its byte span in the scene.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Src {
    /// The text as written.
    pub text: String,
    /// Where it is.
    pub span: Span,
}

/// The derivations a statement can ask for by name.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub enum DerivKind {
    /// Euler–Lagrange equations of `L`.
    El,
    /// The Legendre transform `L → H`.
    Legendre,
    /// Hamilton's equations of `H`.
    Hamilton,
    /// Conserved quantities (Noether).
    Conserved,
    /// A Poisson bracket `{f, g}`.
    Pb,
    /// The energy function `h = Σ q' ∂L/∂q' − L` (or `H`).
    Energy,
    /// The accelerations `q'' = …` of `L` (with constraints, and the multipliers).
    Accelerations,
}

impl DerivKind {
    /// Its keyword.
    pub fn keyword(self) -> &'static str {
        match self {
            DerivKind::El => "el",
            DerivKind::Legendre => "legendre",
            DerivKind::Hamilton => "hamilton",
            DerivKind::Conserved => "conserved",
            DerivKind::Pb => "pb",
            DerivKind::Energy => "energy",
            DerivKind::Accelerations => "accelerations",
        }
    }

    /// From its keyword.
    pub fn from_keyword(s: &str) -> Option<DerivKind> {
        Some(match s {
            "el" => DerivKind::El,
            "legendre" => DerivKind::Legendre,
            "hamilton" => DerivKind::Hamilton,
            "conserved" => DerivKind::Conserved,
            "pb" => DerivKind::Pb,
            "energy" => DerivKind::Energy,
            "accelerations" => DerivKind::Accelerations,
            _ => return None,
        })
    }
}

/// `el`, `legendre(L)`, `pb(Lx, Ly)`: a derivation with its arguments.
#[derive(Clone, Debug)]
pub struct DerivCall {
    /// Which derivation.
    pub kind: DerivKind,
    /// Its arguments (none means the session's `L` or `H`).
    pub args: Vec<Src>,
    /// The whole call.
    pub span: Span,
}

/// Something to print or export.
#[derive(Clone, Debug)]
pub enum Item {
    /// A derivation (`el`, `pb(f, g)`).
    Derivation(DerivCall),
    /// An expression (`H`, `m l^2 θ'`).
    Expr(Src),
}

/// The right-hand side of a definition.
#[derive(Clone, Debug)]
pub enum DefValue {
    /// `T = 1/2 m x'^2`
    Expr(Src),
    /// `H = legendre(L)`
    Derivation(DerivCall),
}

/// `record when y = 0 rising` or `stop when r = 0.1`.
#[derive(Clone, Debug)]
pub struct EventSpec {
    /// `stop` (true) or `record` (false).
    pub terminal: bool,
    /// The left side; the event is where `lhs − rhs` crosses zero.
    pub lhs: Src,
    /// The right side (zero when absent).
    pub rhs: Option<Src>,
    /// Only upward (`Some(true)`) or downward (`Some(false)`) crossings.
    pub rising: Option<bool>,
    /// The whole clause.
    pub span: Span,
}

/// `simulate …`.
#[derive(Clone, Debug)]
pub struct SimSpec {
    /// `θ = 3.0`, `θ' = 0`, `p_x = 1`.
    pub inits: Vec<(Src, Src)>,
    /// The name after `for` (must be `t`).
    pub time_var: Src,
    /// Start and end of the time span.
    pub t0: Src,
    pub t1: Src,
    /// The whole `a..b`.
    pub span_span: Span,
    /// `with NAME`.
    pub method: Option<Src>,
    /// `dt = …`.
    pub dt: Option<Src>,
    /// `tol = …`.
    pub tol: Option<Src>,
    /// `steps = …` (the number of fixed steps, instead of `dt`).
    pub steps: Option<Src>,
    /// `record when …`, `stop when …`.
    pub events: Vec<EventSpec>,
    /// `as NAME`.
    pub name: Option<Src>,
    /// `stabilize projection | baumgarte [= RATE] | none` (constrained runs).
    pub stabilize: Option<StabilizeSpec>,
    /// `every N`: keep every N-th step.
    pub every: Option<Src>,
    /// `points N`: keep about N states.
    pub points: Option<Src>,
    /// `drift = …`: the relative energy drift above which the run is reported.
    pub drift: Option<Src>,
    /// `max_steps = …`: the step budget of a run (of each orbit, in a chaos statement).
    pub max_steps: Option<Src>,
    /// `time_limit = …`: a chaos statement's time budget, in seconds.
    pub time_limit: Option<Src>,
    /// `for each y in A..B step H on E = VALUE solve p > 0`: an ensemble of runs.
    pub ensemble: Option<EnsembleSpec>,
}

/// `for each y in A..B step H on E = VALUE solve p > 0` of a `simulate` statement.
#[derive(Clone, Debug)]
pub struct EnsembleSpec {
    /// The swept state variable.
    pub var: Src,
    /// First value.
    pub from: Src,
    /// Last value (included when the steps reach it).
    pub to: Src,
    /// Step between values.
    pub step: Src,
    /// The named expression held fixed (`H`).
    pub on: Src,
    /// Its value.
    pub value: Src,
    /// The state variable solved for.
    pub solve: Src,
    /// Solve on the positive (`> 0`) or negative side.
    pub positive: bool,
    /// The whole clause.
    pub span: Span,
}

/// `stabilize …` of a `simulate` statement.
#[derive(Clone, Debug)]
pub struct StabilizeSpec {
    /// `projection`, `baumgarte` or `none`.
    pub kind: String,
    /// The Baumgarte rate, if given.
    pub rate: Option<Src>,
    /// The whole clause.
    pub span: Span,
}

/// The span of the first whole-word occurrence of `spelled` in `src`, else all of `src`.
pub(in crate::scene) fn symbol_span(src: &Src, spelled: &str) -> Span {
    let text = &src.text;
    let is_ident = |c: char| c.is_alphanumeric() || c == '_' || c == '\'';
    let mut from = 0;
    while let Some(i) = text[from..].find(spelled) {
        let start = from + i;
        let end = start + spelled.len();
        let before_ok = text[..start].chars().next_back().map_or(true, |c| !is_ident(c));
        let after_ok = text[end..].chars().next().map_or(true, |c| !is_ident(c));
        if before_ok && after_ok {
            return (src.span.0 + start, src.span.0 + end);
        }
        from = end;
    }
    src.span
}
