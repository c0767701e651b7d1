//! The `lagrangian` command line. Each subcommand group lives in its own file and only parses
//! arguments, calls the library and prints. Exit codes: 0 success, 2 bad input or a refused
//! resource limit, 1 internal error.

use std::io::Read;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use lagrangian::print::{render, Format};
use lagrangian::{parse_with, Declarations, Expr, Symbol};

mod canonical;
mod core;
mod mechanics;
mod notes;
mod product;

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
    Product(product::ProductCommand),
}

/// Options every expression command takes.
#[derive(Args, Clone)]
pub struct Common {
    /// Output format.
    #[arg(long, value_enum, default_value_t = OutFormat::Plain)]
    pub format: OutFormat,
    /// Symbols known to be positive (masses, lengths, g).
    #[arg(long, value_delimiter = ',')]
    pub positive: Vec<String>,
    /// Names of declared, undefined functions (`V` so that `V(r)` is a call).
    #[arg(long, value_delimiter = ',')]
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

/// A failure with its exit code.
pub struct Failure {
    pub code: u8,
    pub message: String,
}

/// Bad input from the user: exit code 2.
pub fn bad_input(message: impl Into<String>) -> Failure {
    Failure { code: 2, message: message.into() }
}

impl Common {
    pub fn declarations(&self) -> Declarations {
        Declarations::new().with_positive(&self.positive).with_functions(&self.functions)
    }
}

/// The text of an expression argument; `-` reads standard input.
pub fn read_expr_arg(arg: &str) -> Result<String, Failure> {
    if arg != "-" {
        return Ok(arg.to_string());
    }
    let mut bytes = Vec::new();
    std::io::stdin()
        .read_to_end(&mut bytes)
        .map_err(|e| bad_input(format!("error: cannot read standard input: {e}")))?;
    String::from_utf8(bytes).map_err(|e| {
        bad_input(format!(
            "error: standard input is not valid UTF-8 (invalid byte at offset {})",
            e.utf8_error().valid_up_to()
        ))
    })
}

/// Reads and parses an expression argument.
pub fn parse_arg(arg: &str, decls: &Declarations) -> Result<(String, Expr), Failure> {
    let text = read_expr_arg(arg)?;
    let e = parse_with(&text, decls).map_err(|e| bad_input(e.to_string()))?;
    Ok((text, e))
}

/// Parses a variable name (`θ`, `x'`, `p_x`).
pub fn parse_var(text: &str, decls: &Declarations) -> Result<Symbol, Failure> {
    let e = parse_with(text, decls).map_err(|e| bad_input(e.to_string()))?;
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

pub fn main() -> ExitCode {
    let cli = Cli::parse();
    let result = match cli.command {
        Some(Command::Core(c)) => core::run(c),
        Some(Command::Mechanics(c)) => mechanics::run(c),
        Some(Command::Canonical(c)) => canonical::run(c),
        Some(Command::Notes(c)) => notes::run(c),
        Some(Command::Product(c)) => product::run(c),
        None => product::repl(&product::CacheArgs::default()),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("{}", f.message);
            ExitCode::from(f.code)
        }
    }
}
