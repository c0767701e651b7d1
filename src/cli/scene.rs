//! `run SCENE [--explain]`, and the REPL (the binary with no subcommand, or `repl`).

use std::io::IsTerminal;
use std::path::PathBuf;

use clap::Args;
use clap::Subcommand;
use lagrangian::scene::{read_scene, Cache, ErrorKind, Mode, Options, SceneError, Session};

use super::Failure;

#[derive(Subcommand)]
pub enum SceneCommand {
    /// Run a scene file: derive what its outputs need, integrate, write plots and exports.
    Run {
        /// The scene file.
        scene: PathBuf,
        /// Print the plan: what was built, reused, loaded from the disk cache or skipped, and why.
        #[arg(long)]
        explain: bool,
        /// Directory for output files with relative names (default: the current directory).
        #[arg(long)]
        out_dir: Option<PathBuf>,
        /// Let the scene write outside the output directory (absolute paths, `..`, links).
        #[arg(long)]
        allow_outside: bool,
        /// Relative energy drift above which a run is reported on standard error (a
        /// `simulate … drift = X` overrides it for that run).
        #[arg(long, value_name = "X", default_value_t = lagrangian::integrate::drift::DEFAULT_THRESHOLD, value_parser = super::finite_f64)]
        drift: f64,
        /// Make excess energy drift (or an energy jump in one step) an error: exit status 2
        /// and no output files.
        #[arg(long)]
        strict: bool,
        #[command(flatten)]
        cache: CacheArgs,
    },
    /// The interactive REPL (also what the binary starts with no subcommand).
    Repl {
        #[command(flatten)]
        cache: CacheArgs,
    },
}

/// Where derivations are kept between runs.
#[derive(Args, Clone, Default)]
pub struct CacheArgs {
    /// Directory of the derivation cache (default: `$LAGRANGIAN_CACHE_DIR`, else
    /// `$XDG_CACHE_HOME/lagrangian`, else `~/.cache/lagrangian`).
    #[arg(long, value_name = "DIR")]
    cache_dir: Option<PathBuf>,
    /// Neither read nor write the on-disk derivation cache (also `LAGRANGIAN_CACHE_DIR=off`).
    #[arg(long, conflicts_with = "cache_dir")]
    no_cache: bool,
}

impl CacheArgs {
    /// The derivation cache these options ask for: on disk unless disabled or no directory
    /// can be found, else in memory only.
    pub fn cache(&self) -> Cache {
        if self.no_cache {
            return Cache::new();
        }
        let dir = self.cache_dir.clone().or_else(lagrangian::cache::configured_dir);
        dir.map_or_else(Cache::new, Cache::with_dir)
    }
}

fn report(e: &SceneError) -> Failure {
    let code = if e.kind == ErrorKind::NotAvailable { 1 } else { 2 };
    let color = std::io::stderr().is_terminal();
    Failure { styled: color, kind: "scene", ..Failure::new(code, e.render(color)) }
}

pub fn run(cmd: SceneCommand) -> Result<(), Failure> {
    match cmd {
        SceneCommand::Run { scene, explain, out_dir, allow_outside, drift, strict, cache } => {
            if drift <= 0.0 {
                return Err(Failure::new(2, format!("error: --drift must be positive, found {drift}")));
            }
            // Ctrl-C stops the running statement at its next check; the staged files are
            // removed and the exit status is 130 (128 + SIGINT). A second Ctrl-C exits at once.
            if let Err(e) = lagrangian::cancel::install_ctrlc(lagrangian::cancel::SecondPress::Exit) {
                eprintln!("warning: {e}; Ctrl-C will end the process without cleaning up");
            }
            // SIGTERM and SIGHUP end it too, with the staged files removed (status 143 / 129).
            #[cfg(unix)]
            if let Err(e) = lagrangian::cancel::install_termination() {
                eprintln!("warning: {e}; SIGTERM will end the process without cleaning up");
            }
            let text = read_scene(&scene).map_err(|e| report(&e))?;
            let mut opts = Options::new(Mode::Scene);
            opts.stem = scene.file_stem().and_then(|s| s.to_str()).unwrap_or("scene").to_string();
            opts.base_dir = scene.parent().map(PathBuf::from).unwrap_or_else(|| PathBuf::from("."));
            if let Some(d) = out_dir {
                // A missing output directory is created (with its parents), as a user naming
                // a fresh directory for a scene's figures expects.
                std::fs::create_dir_all(&d).map_err(|e| {
                    Failure::new(2, format!("error: cannot create the output directory `{}`: {e}", d.display()))
                })?;
                opts.out_dir = d;
            }
            opts.allow_outside = allow_outside;
            opts.drift_threshold = drift;
            opts.strict = strict;
            opts.progress = lagrangian::scene::progress::Draw::from_env();
            let mut session = Session::new(opts).with_cache(cache.cache());
            let result = session.run_scene(&scene.display().to_string(), &text);
            for line in session.take_output() {
                println!("{line}");
            }
            for line in session.take_warnings() {
                eprintln!("{}", lagrangian::print::escape_controls(&line));
            }
            if explain {
                print!("{}", session.explain());
            }
            result.map_err(|e| match e.kind {
                ErrorKind::Interrupted => Failure::new(130, "interrupted"),
                _ => report(&e),
            })
        }
        SceneCommand::Repl { cache } => repl(&cache),
    }
}

/// The REPL; exits 0 at the end of input whatever happened in between (it survives errors).
pub fn repl(cache: &CacheArgs) -> Result<(), Failure> {
    lagrangian::scene::repl::run(lagrangian::scene::repl::history_path(), cache.cache());
    Ok(())
}
