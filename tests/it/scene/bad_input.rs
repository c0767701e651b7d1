//! The scene bad-input corpus: each mistake gives a clear diagnostic (message, where, a
//! hint), exit code 2, no panic and no output file.

use std::path::Path;
use std::process::Command;

const BASE: &str = "coordinates θ\nparameters m = 1, l = 1, g = 9.81 positive\nH = p_θ^2/(2 m l^2) + m g l (1 - cos(θ))\nplot phase to early.svg\n";

fn run_bytes(dir: &Path, scene: &[u8]) -> (i32, String) {
    let path = dir.join("bad.scene");
    std::fs::write(&path, scene).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .arg("run")
        .arg(&path)
        .env("LAGRANGIAN_CACHE_DIR", "off")
        .current_dir(dir)
        .output()
        .unwrap();
    (out.status.code().unwrap_or(-1), String::from_utf8_lossy(&out.stderr).into_owned())
}

/// Runs `scene`; checks exit code 2, the pieces of the diagnostic, and that the only file
/// left is the scene (the plot drawn before the mistake is not written).
fn check(scene: &[u8], pieces: &[&str]) {
    let dir = tempfile::tempdir().unwrap();
    let (code, err) = run_bytes(dir.path(), scene);
    assert_eq!(code, 2, "{err}");
    for p in pieces {
        assert!(err.contains(p), "expected `{p}` in:\n{err}");
    }
    assert!(!err.contains("panicked"), "{err}");
    let left: Vec<String> =
        std::fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name().to_string_lossy().into_owned()).collect();
    assert_eq!(left, ["bad.scene"], "output left behind");
}

fn with(extra: &str) -> Vec<u8> {
    format!("{BASE}{extra}").into_bytes()
}

#[test]
fn unknown_statement() {
    check(&with("integrate θ = 1\n"), &["unknown statement `integrate`", "5 │ integrate θ = 1", "`help` lists"]);
}

#[test]
fn missing_parameter_value() {
    check(
        b"coordinates x\nparameters m = 1, k positive\nH = p_x^2/(2 m) + k x^2/2\n\
          simulate x = 1, p_x = 0 for t in 0..1 with gauss6 dt = 0.1\nplot energy\n",
        &["parameter `k` has no value", "declare `k` with a value before `simulate`"],
    );
}

#[test]
fn undefined_symbol() {
    check(&with("print H + m g ll\n"), &["undefined symbol `ll`", "did you mean `l`?", "5 │ print H + m g ll"]);
}

#[test]
fn method_name_typo() {
    check(
        &with("simulate θ = 1, p_θ = 0 for t in 0..1 with yoshda4 dt = 0.1\n"),
        &["unknown integration method `yoshda4`", "did you mean `yoshida4`?"],
    );
}

#[test]
fn backwards_time_span() {
    check(
        &with("simulate θ = 1, p_θ = 0 for t in 20..0 with leapfrog dt = 0.01\nplot θ vs t\n"),
        &["the time span runs backwards", "write `for t in 0..20`", "end must be after start"],
    );
}

#[test]
fn unwritable_plot_path() {
    check(&with("plot phase to no/such/dir/phase.svg\n"), &["cannot write", "must exist and be writable"]);
    check(&with("plot phase to phase.pdf\n"), &["cannot tell the image format", "`.svg` or `.png`"]);
}

#[test]
fn not_utf8() {
    let mut bytes = b"coordinates x\nprint x".to_vec();
    bytes.push(0xff);
    bytes.extend_from_slice(b"\n");
    check(&bytes, &["is not UTF-8", "invalid byte 0xff at line 2, column 8", "save the scene as UTF-8"]);
}

#[test]
fn ten_megabyte_scene() {
    let line = "print 1 + 2 + 3 + 4 + 5 + 6 + 7 + 8 + 9 + 10 + 11 + 12 + 13 + 14 + 15 + 16 + 17\n";
    let scene: String = line.repeat(10_000_000 / line.len() + 1);
    check(scene.as_bytes(), &["10.0 MB", "limited to 4 MB"]);
}

#[test]
fn deeply_nested_expression() {
    let deep = format!("print {}1{}\n", "(".repeat(5000), ")".repeat(5000));
    check(&with(&deep), &["nesting deeper than 1000 levels"]);
}

#[test]
fn velocity_of_a_parameter_and_bad_load() {
    check(&with("print m'\n"), &["`m` is a parameter", "declare it with `coordinates m`"]);
    check(&with("load nowhere.scene\n"), &["cannot read", "nowhere.scene"]);
}

#[test]
fn lookalike_identifiers() {
    // Cyrillic `х`, full-width `ｘ` and a combining acute accent, each refused at its place.
    check(&with("print x + \u{445}\n"), &["U+0445", "Cyrillic letter", "names are ASCII or Greek"]);
    check(&with("print \u{ff58}\n"), &["U+FF58", "full-width character"]);
    check(&with("print x\u{301}\n"), &["U+0301", "combining mark"]);
    // In a comment they are fine.
    let dir = tempfile::tempdir().unwrap();
    let (code, err) = run_bytes(dir.path(), &with("# комментарий ｘ\nprint 1\n"));
    assert_eq!(code, 0, "{err}");
}

/// D11 of the hostile run: a chaos map's range wider than f64 holds is refused at the range. Before,
/// `θ = -1e308..1e308` wrote `inf` cell centres, reported every start failed, and exited 0.
#[test]
fn chaos_map_range_wider_than_f64() {
    check(
        &with("chaos_map megno θ = -1e308..1e308, p_θ = -1..1 for t in 0..1 points 2 to m.csv\n"),
        &[
            "the range of `θ` is wider than f64 can hold (1e308 − (-1e308) overflows)",
            "5 │ chaos_map",
            "narrow the range",
        ],
    );
    check(
        &with("chaos_map megno θ = -1..1, p_θ = -1e308..1.7e308 for t in 0..1 points 2 to m.csv\n"),
        &["the range of `p_θ` is wider than f64 can hold"],
    );
}

/// D13 of the hostile run: `rayleigh L = …` made the dissipation function the Lagrangian (the run
/// integrated R as L, exit 0); a Rayleigh function's name must be its own.
#[test]
fn rayleigh_cannot_take_the_name_of_the_lagrangian() {
    let scene = |stmt: &str| {
        format!(
            "coordinates x\nparameters b = 1\nL = 1/2 x'^2 - 1/2 x^2\nV = x^2\n{stmt}\n\
             simulate x = 1, x' = 0 for t in 0..1 with rk4 dt = 0.1\nexport x to out.csv\n"
        )
        .into_bytes()
    };
    check(
        &scene("rayleigh L = 1/2 b x'^2"),
        &["`L` is the name of the Lagrangian", "5 │ rayleigh L", "rayleigh R = …"],
    );
    check(&scene("rayleigh H = 1/2 b x'^2"), &["`H` is the name of the Hamiltonian"]);
    check(&scene("rayleigh V = 1/2 b x'^2"), &["`V` is already a definition"]);
    check(&scene("rayleigh x = 1/2 b x'^2"), &["`x` is already a coordinate"]);
    // A name of its own is defined, and no name is fine.
    for stmt in ["rayleigh R = 1/2 b x'^2\nprint R", "rayleigh 1/2 b x'^2"] {
        let dir = tempfile::tempdir().unwrap();
        let (code, err) = run_bytes(dir.path(), &scene(stmt));
        assert_eq!(code, 0, "{stmt}: {err}");
    }
}

/// D14 of the hostile run: a figure of an expression that is not finite anywhere along the run is
/// refused at the expression (exports refuse such values too); before, the plot or GIF was
/// written with nothing on it and exit 0. Partly non-finite values are drawn with a note.
#[test]
fn figures_of_nowhere_finite_expressions() {
    let run = "coordinates x\nL = 1/2 x'^2 - 1/2 x^2\nsimulate x = 1, x' = 0 for t in 0..10 with rk4 dt = 0.1\n";
    let with_run = |stmt: &str| format!("{run}{stmt}\n").into_bytes();
    for (stmt, what) in [
        ("plot sqrt(-1 - x^2) vs t to a.svg", "`sqrt(-1 - x^2)` is not finite at any of the 101 stored states of run1"),
        ("plot x, log(x - 2) vs t to a.svg", "`log(x - 2)` is not finite at any"),
        ("plot path x, sqrt(-1 - x^2) to a.svg", "`sqrt(-1 - x^2)` is not finite at any"),
        ("animate (x, sqrt(-1 - x^2)) to a.gif", "`sqrt(-1 - x^2)` is not finite at any"),
    ] {
        check(&with_run(stmt), &[what, "nothing to draw", "leaves its domain"]);
    }
    // Partly finite: drawn, with a note counting the points left out. x = cos t, so
    // sqrt(x − 1/2) is NaN where cos t < 1/2: from t = 1.1 (the first stored t past π/3).
    let dir = tempfile::tempdir().unwrap();
    std::fs::write(dir.path().join("p.scene"), with_run("plot path x, sqrt(x - 0.5) to b.svg")).unwrap();
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian"))
        .args(["run", "p.scene"])
        .env("LAGRANGIAN_CACHE_DIR", "off")
        .current_dir(dir.path())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert_eq!(out.status.code(), Some(0), "{}", String::from_utf8_lossy(&out.stderr));
    let expected = (0..=100).filter(|k| (f64::from(*k) * 0.1).cos() < 0.5).count();
    assert!(
        stdout.contains(&format!(
            "note: `sqrt(x - 0.5)` is not finite at {expected} of the 101 stored states of run1 (the first at t = 1.1)"
        )),
        "{stdout}"
    );
    assert!(dir.path().join("b.svg").exists());
}

/// numbers in messages are short and say what they are. Before,
/// `1e308` printed as 309 digits, `1.0000001` as `1.` and `2.5e-7` as `0.`.
#[test]
fn numbers_in_messages_are_short_and_exact_enough() {
    for (span, shown) in
        [("5..1e308", "found 5..1e308"), ("1.0000001..2", "found 1.0000001..2"), ("2.5e-7..1", "found 2.5e-7..1")]
    {
        check(&with(&format!("megno θ = 1, p_θ = 0 for t in {span}\n")), &[shown]);
    }
}
