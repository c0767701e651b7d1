//! The `lagrangian` command line. Each subcommand group lives in its own file and only parses
//! arguments, calls the library and prints. Exit codes: 0 success, 2 bad input or a refused
//! resource limit, 1 internal error.

use std::io::Read;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use lagrangian::print::{render, Format};
use lagrangian::{parse_with, Declarations, Expr, Symbol};

mod canonical;
mod chaos;
mod core;
mod mechanics;
mod notes;
mod scene;

#[derive(Parser)]
#[command(name = "lagrangian", version, about = "Exact Lagrangian and Hamiltonian mechanics")]
struct Cli {
    /// The subcommand; none starts the REPL.
    #[command(subcommand)]
    command: Option<Command>,
}

/// Every subcommand, grouped by pipeline stage.
#[derive(Subcommand)]
enum Command {
    #[command(flatten)]
    Core(core::CoreCommand),
    #[command(flatten)]
    Mechanics(mechanics::MechanicsCommand),
    #[command(flatten)]
    Canonical(canonical::CanonicalCommand),
    #[command(flatten)]
    Notes(notes::NotesCommand),
    #[command(flatten)]
    Chaos(chaos::ChaosCommand),
    #[command(flatten)]
    Scene(scene::SceneCommand),
}

/// Options every expression command takes.
#[derive(Args, Clone)]
pub struct Common {
    /// Output format.
    #[arg(long, value_enum, default_value_t = OutFormat::Plain)]
    pub format: OutFormat,
    /// Symbols known to be positive (masses, lengths, g).
    #[arg(long, value_delimiter = ',', value_parser = plain_name)]
    pub positive: Vec<String>,
    /// Names of declared, undefined functions (`V` so that `V(r)` is a call).
    #[arg(long, value_delimiter = ',', value_parser = plain_name)]
    pub functions: Vec<String>,
}

/// How results are printed.
#[derive(Clone, Copy, PartialEq, Eq, ValueEnum)]
pub enum OutFormat {
    Plain,
    Unicode,
    Latex,
    Json,
}

impl OutFormat {
    /// The expression rendering for this output format (JSON carries the plain form).
    pub fn expr_format(self) -> Format {
        match self {
            OutFormat::Plain | OutFormat::Json => Format::Plain,
            OutFormat::Unicode => Format::Unicode,
            OutFormat::Latex => Format::Latex,
        }
    }
}

/// A name in a comma-separated list (`--positive m,l`): a letter, then letters, digits or
/// `_`. An empty entry (`m,,l`) or an expression (`1+2`) is an error, not silently ignored.
pub fn plain_name(s: &str) -> Result<String, String> {
    let s = s.trim();
    if s.is_empty() {
        return Err("an empty name in the list (two commas in a row, or a trailing comma?)".into());
    }
    let ok = s.chars().next().is_some_and(char::is_alphabetic) && s.chars().all(|c| c.is_alphanumeric() || c == '_');
    if !ok {
        return Err(format!("`{s}` is not a name (a letter, then letters, digits or `_`)"));
    }
    if let Some(msg) = lookalike(s) {
        return Err(msg);
    }
    Ok(s.to_string())
}

/// A finite number (`--energy`): `nan` and `inf` are refused.
pub fn finite_f64(s: &str) -> Result<f64, String> {
    let x: f64 = s.trim().parse().map_err(|e| format!("`{s}` is not a number: {e}"))?;
    if x.is_finite() {
        Ok(x)
    } else {
        Err(format!("`{s}` is not a finite number"))
    }
}

/// `name=value` pairs of a numeric option (`--set m=1,k=2`, `--params`): a plain name and a
/// finite number each, and a name declared `--positive` must have a positive value, as a
/// scene's `parameters positive m = -1` is refused: the symbolic stages simplified with
/// `m > 0` (`sqrt(m^2) = m`), so a negative value would give a silently wrong number. A name
/// given twice (`--set k=1,k=4`, or in two `--set`) is refused: its users keep one of the two
/// values, which one depending on the command, and the other would be dropped without a word.
pub fn name_values(flag: &str, pairs: &[String], positive: &[String]) -> Result<Vec<(String, f64)>, Failure> {
    let mut values: Vec<(String, f64)> = Vec::new();
    let mut written: Vec<&str> = Vec::new();
    for kv in pairs {
        let Some((k, v)) = kv.split_once('=') else {
            return Err(bad_input(format!("error: {flag} takes name=value, got `{kv}`")));
        };
        let k = plain_name(k).map_err(|e| bad_input(format!("error: {flag} `{kv}`: {e}")))?;
        let x: f64 =
            v.trim().parse().map_err(|_| bad_input(format!("error: {flag} {k}: `{}` is not a number", v.trim())))?;
        if !x.is_finite() {
            return Err(bad_input(format!("error: {flag} {k}: `{}` is not a finite number", v.trim())));
        }
        if x <= 0.0 && positive.iter().any(|p| p.trim() == k) {
            return Err(bad_input(format!(
                "error: {flag} {k}={}: `{k}` is declared positive (--positive) but its value is {x}; \
                 give a positive value, or drop `{k}` from --positive",
                v.trim()
            )));
        }
        if let Some(i) = values.iter().position(|(n, _)| *n == k) {
            return Err(bad_input(format!(
                "error: {flag} gives `{k}` twice (`{}` and `{}`); keep one",
                written[i].trim(),
                kv.trim()
            )));
        }
        values.push((k, x));
        written.push(kv);
    }
    Ok(values)
}

/// The first character of `text` that only looks like the Latin or Greek letter a reader
/// sees (Cyrillic `х`, full-width `ｘ`) or is a combining mark, as an error message with its
/// column: the parser's message ([`lagrangian::parse::lookalike_message`]), for names given
/// in lists (`--positive`), which are not parsed as expressions.
pub fn lookalike(text: &str) -> Option<String> {
    let (col, c, what) =
        text.chars().enumerate().find_map(|(i, c)| lagrangian::parse::lookalike_kind(c).map(|w| (i, c, w)))?;
    Some(format!("{} (column {})", lagrangian::parse::lookalike_message(c, what), col + 1))
}

/// A failure with its exit code.
pub struct Failure {
    pub code: u8,
    pub message: String,
    /// The message is a rendered diagnostic whose only escape sequences are its own colours
    /// (the user's text in it is already escaped); any other message has every control
    /// character escaped when printed.
    pub styled: bool,
    /// What the failure is, for `--format json` (`parse`, `mechanics`, `input`, `usage`, …).
    pub kind: &'static str,
    /// Where in the input, for `--format json`: a parse error's location.
    pub span: Option<Box<lagrangian::parse::ParseError>>,
}

impl Failure {
    /// A failure whose message is printed with its control characters escaped.
    pub fn new(code: u8, message: impl Into<String>) -> Failure {
        let kind = match code {
            2 => "input",
            130 => "interrupted",
            _ => "internal",
        };
        Failure { code, message: message.into(), styled: false, kind, span: None }
    }

    /// A parse error, with its location kept for `--format json`.
    pub fn parse(e: lagrangian::parse::ParseError) -> Failure {
        Failure { kind: "parse", ..Failure::new(2, e.to_string()) }.at(e)
    }

    fn at(mut self, e: lagrangian::parse::ParseError) -> Failure {
        self.span = Some(Box::new(e));
        self
    }

    /// The error as the JSON object `--format json` prints on standard output:
    /// `{"error": {"kind", "message", "span", "hints"}}` (documented in the README, under the command line).
    /// `message` is the sentence without the terminal's `error: ` prefix, source line and
    /// caret; `span` is `{"line", "column", "start", "end"}` (1-based line and column in
    /// characters, byte offsets `start..end` in the argument) or `null`.
    pub fn json(&self) -> serde_json::Value {
        let (message, span, hints) = match &self.span {
            Some(e) => (
                e.message.clone(),
                serde_json::json!({ "line": e.line, "column": e.column, "start": e.span.0, "end": e.span.1 }),
                e.hint.iter().cloned().collect::<Vec<_>>(),
            ),
            None => {
                let text = self.message.trim();
                let text = text.strip_prefix("error: ").unwrap_or(text);
                // A trailing `= hint: …` line of a message becomes a hint.
                let (message, hint) = match text.split_once("\n  = hint: ") {
                    Some((m, h)) => (m.to_string(), vec![h.trim().to_string()]),
                    None => (text.to_string(), Vec::new()),
                };
                (message, serde_json::Value::Null, hint)
            }
        };
        serde_json::json!({ "error": { "kind": self.kind, "message": message, "span": span, "hints": hints } })
    }
}

/// Bad input from the user: exit code 2.
pub fn bad_input(message: impl Into<String>) -> Failure {
    Failure::new(2, message)
}

/// A mechanics error: a parse error keeps its location, any other is of kind `mechanics`.
pub fn mechanics_failure(e: lagrangian::mechanics::MechanicsError) -> Failure {
    match e {
        lagrangian::mechanics::MechanicsError::Parse(p) => Failure::parse(p),
        other => Failure { kind: "mechanics", ..bad_input(other.to_string()) },
    }
}

impl Common {
    pub fn declarations(&self) -> Declarations {
        Declarations::new().with_positive(&self.positive).with_functions(&self.functions)
    }
}

/// The most standard input an expression argument reads: 64 MiB, far above any expression
/// the engine handles in reasonable time (a sum of 10⁵ symbols is under 1 MB), and bounded so
/// that `lagrangian simplify - < /dev/zero` is refused instead of exhausting memory.
pub const MAX_STDIN_BYTES: u64 = 64 << 20;

/// The text of an expression argument; `-` reads standard input (at most [`MAX_STDIN_BYTES`]).
pub fn read_expr_arg(arg: &str) -> Result<String, Failure> {
    if arg != "-" {
        return Ok(arg.to_string());
    }
    let mut bytes = Vec::new();
    std::io::stdin()
        .take(MAX_STDIN_BYTES + 1)
        .read_to_end(&mut bytes)
        .map_err(|e| bad_input(format!("error: cannot read standard input: {e}")))?;
    if bytes.len() as u64 > MAX_STDIN_BYTES {
        return Err(bad_input(format!(
            "error: standard input is longer than the limit of {} MB for an expression",
            MAX_STDIN_BYTES >> 20
        )));
    }
    let text = String::from_utf8(bytes).map_err(|e| {
        bad_input(format!(
            "error: standard input is not valid UTF-8 (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ))
    })?;
    // A byte-order mark some editors write is not part of the expression.
    Ok(text.strip_prefix('\u{feff}').map(str::to_string).unwrap_or(text))
}

/// Reads and parses an expression argument.
pub fn parse_arg(arg: &str, decls: &Declarations) -> Result<(String, Expr), Failure> {
    let text = read_expr_arg(arg)?;
    let text = text.strip_prefix('\u{feff}').map(str::to_string).unwrap_or(text);
    // Look-alike letters are refused by the parser, with their location.
    let e = parse_with(&text, decls).map_err(Failure::parse)?;
    Ok((text, e))
}

/// Parses a variable name (`θ`, `x'`, `p_x`).
pub fn parse_var(text: &str, decls: &Declarations) -> Result<Symbol, Failure> {
    let e = parse_with(text, decls).map_err(Failure::parse)?;
    e.as_sym().cloned().ok_or_else(|| bad_input(format!("error: `{text}` is not a variable")))
}

/// Prints one result expression.
pub fn emit(input: &str, result: &Expr, format: OutFormat) {
    match format {
        OutFormat::Json => {
            let v = serde_json::json!({ "input": input.trim(), "result": lagrangian::print::plain(result) });
            println!("{v}");
        }
        other => println!("{}", render(result, other.expr_format())),
    }
}

/// Restores the default action of `SIGPIPE`. Rust ignores the signal, so a write to a pipe
/// whose reader has gone (`lagrangian simplify … | head -c 1`) returns `EPIPE` and `println!`
/// panics. With the default action the process ends at that write with status 141, as `cat`
/// and `grep` do, before anything is half-printed; files are written whole before any
/// message names them, so none is left half-written.
fn default_sigpipe() {
    #[cfg(unix)]
    // SAFETY: `signal` with `SIG_DFL` installs no handler code; it is called once, at the
    // start of `main`, before any thread is spawned.
    unsafe {
        libc::signal(libc::SIGPIPE, libc::SIG_DFL);
    }
}

/// Whether the command line asks for `--format json` (read from the raw arguments, for a
/// usage error clap reports before anything is parsed).
fn asks_for_json(args: &[std::ffi::OsString]) -> bool {
    args.windows(2).any(|w| w[0] == "--format" && w[1] == "json") || args.iter().any(|a| a == "--format=json")
}

pub fn main() -> ExitCode {
    use clap::{CommandFactory, FromArgMatches};
    default_sigpipe();
    let args: Vec<std::ffi::OsString> = std::env::args_os().collect();
    let parsed = Cli::command().try_get_matches_from(&args).and_then(|m| Ok((Cli::from_arg_matches(&m)?, m)));
    let (cli, matches) = match parsed {
        Ok(p) => p,
        Err(e) if asks_for_json(&args) && e.use_stderr() => {
            // A usage error is an error object too when JSON was asked for (exit 2, as clap).
            let message = e.render().to_string();
            let message = message.lines().next().unwrap_or_default().to_string();
            let f = Failure { kind: "usage", ..bad_input(message) };
            println!("{}", f.json());
            return ExitCode::from(2);
        }
        Err(e) => e.exit(),
    };
    let json = matches
        .subcommand()
        .and_then(|(_, m)| m.try_get_one::<OutFormat>("format").ok().flatten())
        .is_some_and(|f| *f == OutFormat::Json);
    let result = match cli.command {
        Some(Command::Core(c)) => core::run(c),
        Some(Command::Mechanics(c)) => mechanics::run(c),
        Some(Command::Canonical(c)) => canonical::run(c),
        Some(Command::Notes(c)) => notes::run(c),
        Some(Command::Chaos(c)) => chaos::run(c),
        Some(Command::Scene(c)) => scene::run(c),
        None => scene::repl(&scene::CacheArgs::default()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) if json => {
            // One JSON object on standard output, nothing on standard error; the same exit code.
            println!("{}", f.json());
            ExitCode::from(f.code)
        }
        Err(f) => {
            let message = if f.styled { f.message } else { lagrangian::print::escape_controls(&f.message) };
            eprintln!("{message}");
            ExitCode::from(f.code)
        }
    }
}
