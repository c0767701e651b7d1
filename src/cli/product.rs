//! `run SCENE [--explain]`, and the REPL (the binary with no subcommand, or `repl`).

use std::io::IsTerminal;
use std::path::PathBuf;

use clap::Subcommand;
use lagrangian::scene::{read_scene, ErrorKind, Mode, Options, SceneError, Session};

use super::Failure;

#[derive(Subcommand)]
pub enum ProductCommand {
    /// Run a scene file: derive what its outputs need, integrate, write plots and exports.
    Run {
        /// The scene file.
        scene: PathBuf,
        /// Print the plan: what was built, reused and skipped, and why.
        #[arg(long)]
        explain: bool,
        /// Directory for output files with relative names (default: the current directory).
        #[arg(long)]
        out_dir: Option<PathBuf>,
    },
    /// The interactive REPL (also what the binary starts with no subcommand).
    Repl,
}

fn report(e: &SceneError) -> Failure {
    let code = if e.kind == ErrorKind::NotAvailable { 1 } else { 2 };
    Failure { code, message: e.render(std::io::stderr().is_terminal()) }
}

pub fn run(cmd: ProductCommand) -> Result<(), Failure> {
    match cmd {
        ProductCommand::Run { scene, explain, out_dir } => {
            let text = read_scene(&scene).map_err(|e| report(&e))?;
            let mut opts = Options::new(Mode::Scene);
            opts.stem = scene.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
            opts.base_dir = scene.parent().map(PathBuf::from).unwrap_or_else(|| PathBuf::from("."));
            if let Some(d) = out_dir {
                opts.out_dir = d;
            }
            opts.progress = true;
            let mut session = Session::new(opts);
            let result = session.run_scene(&scene.display().to_string(), &text);
            for line in session.take_output() {
                println!("{line}");
            }
            if explain {
                print!("{}", session.explain());
            }
            result.map_err(|e| report(&e))
        }
        ProductCommand::Repl => repl(),
    }
}

/// The REPL; exits 0 at the end of input whatever happened in between (it survives errors).
pub fn repl() -> Result<(), Failure> {
    lagrangian::scene::repl::run(lagrangian::scene::repl::history_path());
    Ok(())
}
