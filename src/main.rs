//! The `lagrangian` command line. Each subcommand parses its arguments, calls the library and
//! prints; exit code 0 on success, 2 on bad input or a refused resource limit, 1 on an
//! internal error.

use std::io::Read;
use std::process::ExitCode;

use clap::{Args, Parser, Subcommand, ValueEnum};
use lagrangian::diff::Differentiator;
use lagrangian::print::{render, Format};
use lagrangian::{parse_with, Declarations, Expr, Symbol};

#[derive(Parser)]
#[command(name = "lagrangian", version, about = "Exact Lagrangian and Hamiltonian mechanics")]
struct Cli {
    #[command(subcommand)]
    command: Command,
}

#[derive(Subcommand)]
enum Command {
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

#[derive(Args)]
struct Common {
    /// Output format.
    #[arg(long, value_enum, default_value_t = OutFormat::Plain)]
    format: OutFormat,
    /// Symbols known to be positive (masses, lengths, g).
    #[arg(long, value_delimiter = ',')]
    positive: Vec<String>,
    /// Names of declared, undefined functions (`V` so that `V(r)` is a call).
    #[arg(long, value_delimiter = ',')]
    functions: Vec<String>,
}

#[derive(Clone, Copy, ValueEnum)]
enum OutFormat {
    Plain,
    Unicode,
    Latex,
    Json,
}

/// A failure with its exit code.
struct Failure {
    code: u8,
    message: String,
}

fn bad_input(message: impl Into<String>) -> Failure {
    Failure { code: 2, message: message.into() }
}

impl Common {
    fn declarations(&self) -> Declarations {
        Declarations::new().with_positive(&self.positive).with_functions(&self.functions)
    }
}

fn read_expr_arg(arg: &str) -> Result<String, Failure> {
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

fn parse_arg(arg: &str, decls: &Declarations) -> Result<(String, Expr), Failure> {
    let text = read_expr_arg(arg)?;
    let e = parse_with(&text, decls).map_err(|e| bad_input(e.to_string()))?;
    Ok((text, e))
}

fn parse_var(text: &str, decls: &Declarations) -> Result<Symbol, Failure> {
    let e = parse_with(text, decls).map_err(|e| bad_input(e.to_string()))?;
    e.as_sym().cloned().ok_or_else(|| bad_input(format!("error: `{text}` is not a variable")))
}

fn emit(input: &str, result: &Expr, format: OutFormat) {
    match format {
        OutFormat::Json => {
            let v = serde_json::json!({ "input": input.trim(), "result": lagrangian::print::plain(result) });
            println!("{v}");
        }
        OutFormat::Plain => println!("{}", render(result, Format::Plain)),
        OutFormat::Unicode => println!("{}", render(result, Format::Unicode)),
        OutFormat::Latex => println!("{}", render(result, Format::Latex)),
    }
}

fn run(cli: Cli) -> Result<(), Failure> {
    match cli.command {
        Command::Simplify { expr, common } => {
            let (text, e) = parse_arg(&expr, &common.declarations())?;
            let out = lagrangian::simplify::simplify(&e);
            emit(&text, &out, common.format);
        }
        Command::Diff { expr, vars, common } => {
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
        Command::Dt { expr, coords, common } => {
            let (text, e) = parse_arg(&expr, &common.declarations())?;
            let out = lagrangian::diff::dt(&e, &coords.into_iter().collect());
            let out = lagrangian::simplify::simplify(&out);
            emit(&text, &out, common.format);
        }
    }
    Ok(())
}

fn main() -> ExitCode {
    let cli = Cli::parse();
    match run(cli) {
        Ok(()) => ExitCode::SUCCESS,
        Err(f) => {
            eprintln!("{}", f.message);
            ExitCode::from(f.code)
        }
    }
}
