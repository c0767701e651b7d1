//! The one support module of the test binary. Here: running the `lagrangian` binary on scenes
//! (with the derivation cache off, so every run derives afresh), running an example scene into
//! a temporary directory with its printed output snapshotted, reading what it wrote, and the one
//! snapshot function. Beside it: `mechanics` (systems, random states, the snapshot report),
//! `n_link` (the n-link pendulum, also read by the benchmarks), `notes` (a numeric route to the
//! Euler–Lagrange expressions) and `compile` (model systems with hand-written right-hand sides).

#![allow(dead_code)]

pub mod compile;
pub mod mechanics;
pub mod n_link;
pub mod notes;

use std::collections::HashMap;
use std::path::{Path, PathBuf};
use std::process::Command;

/// Runs the binary with `args`: exit code, stdout, stderr.
pub fn run(args: &[&str]) -> (i32, String, String) {
    run_in_dir(None, args)
}

/// Runs the binary with `args` in `dir` (when given): exit code, stdout, stderr.
pub fn run_in_dir(dir: Option<&Path>, args: &[&str]) -> (i32, String, String) {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    cmd.args(args).env("LAGRANGIAN_CACHE_DIR", "off");
    if let Some(d) = dir {
        cmd.current_dir(d);
    }
    let out = cmd.output().expect("the binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

/// The REPL on pipes, run in `dir` with its history there and the derivation cache off (the
/// caller spawns it, and sets what else it needs).
pub fn piped_repl(dir: &Path) -> Command {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    cmd.arg("repl")
        .env("LAGRANGIAN_CACHE_DIR", "off")
        .env("LAGRANGIAN_HISTORY", dir.join("history"))
        .current_dir(dir)
        .stdin(std::process::Stdio::piped())
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped());
    cmd
}

/// Writes `scene` to `dir/test.scene` and runs it there with `args` after it: exit code,
/// stdout, stderr.
pub fn run_scene_in(dir: &Path, scene: &str, args: &[&str]) -> (i32, String, String) {
    let path = dir.join("test.scene");
    std::fs::write(&path, scene).expect("the scene is written");
    let mut all = vec!["run", path.to_str().expect("a UTF-8 path")];
    all.extend_from_slice(args);
    run_in_dir(Some(dir), &all)
}

/// Snapshot under the repository's `snapshots/` with the project's naming (no module prefix):
/// the one place that says where snapshots live, so a test file moving does not move them.
pub fn snapshot(name: &str, text: impl AsRef<str>) {
    let text = text.as_ref();
    insta::with_settings!({snapshot_path => concat!(env!("CARGO_MANIFEST_DIR"), "/snapshots"), prepend_module_to_snapshot => false}, {
        insta::assert_snapshot!(name, text);
    });
}

/// The `name = value` pairs of a scene's first `parameters` line (numbers only, an optional
/// trailing `positive`), in order: what a test reads from an example scene. A family
/// `m[0..2] = 1, 2, 3` gives `m0`, `m1`, `m2` their values in order.
pub fn scene_parameters(scene: &str) -> Vec<(String, f64)> {
    let line = scene.lines().find_map(|l| l.strip_prefix("parameters ")).expect("a `parameters` line");
    let mut out = Vec::new();
    let mut family: Vec<String> = Vec::new();
    for piece in line.trim_end_matches(" positive").split(", ") {
        let (names, value) = match piece.split_once(" = ") {
            Some((k, v)) => {
                family = scene_names(k);
                family.reverse();
                (family.pop(), v)
            }
            None => (family.pop(), piece),
        };
        let name = names.unwrap_or_else(|| panic!("a value with no name: {piece}"));
        out.push((name, value.parse().expect("a number")));
    }
    out
}

/// The names a declaration lists, with families expanded (`x[0..2], y` → x0, x1, x2, y).
pub fn scene_names(list: &str) -> Vec<String> {
    list.split(", ")
        .flat_map(|item| match item.split_once('[') {
            Some((base, range)) => {
                let (lo, hi) = range.trim_end_matches(']').split_once("..").expect("a range `a..b`");
                let (lo, hi): (u64, u64) = (lo.parse().expect("a whole number"), hi.parse().expect("a whole number"));
                (lo..=hi).map(|k| format!("{base}{k}")).collect()
            }
            None => vec![item.to_string()],
        })
        .collect()
}

/// The last state of a `map` orbit line, `  (start) → (last)`, as numbers.
pub fn map_last_state(line: &str) -> Vec<f64> {
    let last = line.split('→').nth(1).unwrap_or_else(|| panic!("not an orbit line: {line}"));
    last.trim_matches([' ', '(', ')']).split(", ").map(|x| x.parse().unwrap_or_else(|_| panic!("{line}"))).collect()
}

/// The columns of a CSV file, by header name.
pub fn read_csv(path: &Path) -> HashMap<String, Vec<f64>> {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    let mut lines = text.lines();
    let header: Vec<String> = lines.next().expect("a header").split(',').map(String::from).collect();
    let mut cols: HashMap<String, Vec<f64>> = header.iter().map(|h| (h.clone(), Vec::new())).collect();
    for line in lines {
        for (h, v) in header.iter().zip(line.split(',')) {
            cols.get_mut(h).expect("a header column").push(v.parse().expect("a number"));
        }
    }
    cols
}

/// An example scene that ran: where its files went and what it printed (with the output
/// directory written `OUT`).
pub struct Example {
    pub out: PathBuf,
    _dir: tempfile::TempDir,
    pub stdout: String,
}

/// Runs `examples/NAME.scene` into a temporary directory, asserts it succeeds, and snapshots
/// its printed output as `scene_example_NAME`.
pub fn example(name: &str) -> Example {
    let dir = tempfile::tempdir().expect("a temporary directory");
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("examples").join(format!("{name}.scene"));
    let (code, stdout, err) =
        run(&["run", scene.to_str().expect("a UTF-8 path"), "--out-dir", dir.path().to_str().expect("a UTF-8 path")]);
    assert_eq!(code, 0, "{name}: {err}\n{stdout}");
    let stdout = stdout.replace(&dir.path().display().to_string(), "OUT");
    snapshot(&format!("scene_example_{name}"), &stdout);
    Example { out: dir.path().to_path_buf(), _dir: dir, stdout }
}

impl Example {
    /// The columns of a CSV output, by header name.
    pub fn csv(&self, file: &str) -> HashMap<String, Vec<f64>> {
        read_csv(&self.out.join(file))
    }

    /// An SVG output's text, checked to be SVG and announced by a `wrote` line.
    pub fn svg(&self, file: &str) -> String {
        let text = std::fs::read_to_string(self.out.join(file)).unwrap_or_else(|e| panic!("{file}: {e}"));
        assert!(text.starts_with("<svg") && text.trim_end().ends_with("</svg>"), "{file} is not SVG");
        assert!(self.stdout.contains(&format!("wrote OUT/{file}")));
        text
    }

    /// The printed line starting with `prefix`, without it.
    pub fn line(&self, prefix: &str) -> String {
        self.stdout.lines().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no `{prefix}`")).to_string()
    }
}
