//! Nothing silently wrong: numbers the engine gives agree with what it
//! says symbolically, names that would be confused are refused, exported columns are finite.

use std::collections::HashMap;
use std::process::Command;

use lagrangian::compile::{CompileOptions, Tape};
use lagrangian::eval::eval;
use lagrangian::{parse, simplify::simplify};

fn bin() -> Command {
    let mut c = Command::new(env!("CARGO_BIN_EXE_lagrangian"));
    c.env("LAGRANGIAN_CACHE_DIR", "off");
    c
}

/// `x^(p/q)` with q odd at negative x: the reference evaluator, the interpreted tape and the
/// native tape give the real root, and agree with the simplifier's exact value.
#[test]
fn real_odd_roots_of_negative_bases_agree_everywhere() {
    // The simplifier's own value of (-8)^(1/3), (-8)^(2/3), (-32)^(-3/5), as exact numbers.
    let exact = |s: &str| eval(&simplify(&parse(s).unwrap()), &HashMap::new()).unwrap();
    assert_eq!(exact("(-8)^(1/3)"), -2.0);
    assert_eq!(exact("(-8)^(2/3)"), 4.0);
    assert_eq!(exact("(-32)^(-3/5)"), -0.125);
    let cases = [
        ("x^(1/3)", -8.0, -2.0, 1.0 / 3.0),
        ("x^(2/3)", -8.0, 4.0, 2.0 / 3.0),
        ("x^(-3/5)", -32.0, -0.125, -3.0 / 5.0),
        ("x^(5/3)", -27.0, -243.0, 5.0 / 3.0),
    ];
    for (src, x, want, r) in cases {
        let e = parse(src).unwrap();
        let env: HashMap<String, f64> = [("x".to_string(), x)].into();
        let reference = eval(&e, &env).unwrap();
        assert!((reference - want).abs() <= 1e-14 * want.abs(), "{src} at {x}: eval gives {reference}");
        for native in [false, true] {
            let opts = CompileOptions::default().with_native(native);
            let tape = Tape::compile_with_options(std::slice::from_ref(&e), &["x"], &[], &opts).unwrap();
            let mut out = [0.0];
            tape.eval(&[x], &mut out);
            assert!((out[0] - want).abs() <= 1e-14 * want.abs(), "{src} at {x} (native {native}): {}", out[0]);
        }
        // Positive bases are unchanged: the same value as powf to rounding.
        let env: HashMap<String, f64> = [("x".to_string(), 2.5)].into();
        let p = eval(&e, &env).unwrap();
        assert!((p - 2.5f64.powf(r)).abs() <= 4.0 * f64::EPSILON * p.abs(), "{src}");
    }
    // Interpreter and native code agree bit for bit on the new instruction.
    let e = parse("x^(1/3) + x^(-5/7) + x^(4/9)").unwrap();
    let interp = Tape::compile_with_options(
        std::slice::from_ref(&e),
        &["x"],
        &[],
        &CompileOptions::default().with_native(false),
    )
    .unwrap();
    let native = Tape::compile(&[e], &["x"], &[]).unwrap();
    for x in [-1e10, -3.5, -1.0, -1e-7, 1e-7, 0.3, 7.0, 1e12] {
        let (mut a, mut b) = ([0.0], [0.0]);
        interp.eval(&[x], &mut a);
        native.eval(&[x], &mut b);
        assert_eq!(a[0].to_bits(), b[0].to_bits(), "at {x}");
        assert!(a[0].is_finite(), "at {x}");
    }
}

#[test]
fn a_coordinate_named_like_a_momentum_is_refused_everywhere() {
    for args in [
        vec!["hamilton", "p_x^2/2 + x^2", "--coords", "x,p_x"],
        vec!["el", "x'^2/2 + p_x'^2/2", "--coords", "p_x,x"],
        vec!["legendre", "x'^2/2 + p_x'^2/2", "--coords", "x,p_x"],
        vec!["conserved", "x'^2/2 + p_x'^2/2", "--coords", "x,p_x"],
    ] {
        let out = bin().args(&args).output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {err}");
        assert!(err.contains("coordinate `p_x` has the name of the momentum of `x`"), "{args:?}: {err}");
        assert!(err.contains("rename it, e.g. `px`"), "{err}");
        assert!(out.stdout.is_empty(), "{}", String::from_utf8_lossy(&out.stdout));
    }
    let out = bin().args(["el", "x'^2/2", "--coords", "x,,y"]).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("an empty coordinate name"), "{err}");
}

#[test]
fn exports_refuse_non_finite_values_naming_column_row_and_time() {
    let dir = tempfile::tempdir().unwrap();
    // x0 = 1e200: the energy x²/2 overflows to inf although the state is finite.
    std::fs::write(
        dir.path().join("s.scene"),
        "coordinates x\nH = p_x^2/2 + x^2/2\nsimulate x = 1e200, p_x = 0 for t in 0..1 with rk4 dt = 0.5\nexport t, x, H to a.csv\n",
    )
    .unwrap();
    let out = bin().args(["run", "s.scene"]).current_dir(dir.path()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("column `H` is inf at t = 0 (row 1)"), "{err}");
    assert!(!dir.path().join("a.csv").exists());
}

/// `allow nonfinite` keeps them in a CSV, with a note counting them; JSON, which cannot spell
/// them, still refuses and says to use CSV.
#[test]
fn allow_nonfinite_keeps_them_in_csv_and_json_still_refuses() {
    let dir = tempfile::tempdir().unwrap();
    let scene = "coordinates x\nH = p_x^2/2 + x^2/2\nsimulate x = 1e200, p_x = 0 for t in 0..1 with rk4 dt = 0.5\n\
                 allow nonfinite\nexport t, x, H to a.csv\n";
    std::fs::write(dir.path().join("s.scene"), scene).unwrap();
    let out = bin().args(["run", "s.scene"]).current_dir(dir.path()).output().unwrap();
    let (stdout, err) = (String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert_eq!(out.status.code(), Some(0), "{err}");
    assert!(stdout.contains("non-finite value") && stdout.contains("column `H` at row 1"), "{stdout}");
    let csv = std::fs::read_to_string(dir.path().join("a.csv")).unwrap();
    let first: Vec<&str> = csv.lines().nth(1).unwrap().split(',').collect();
    // t = 0, x = 1e200 (finite, kept exactly), H = x²/2 overflows.
    assert_eq!(first[0].parse::<f64>().unwrap(), 0.0);
    assert_eq!(first[1].parse::<f64>().unwrap(), 1e200);
    assert_eq!(first[2], "inf", "{csv}");

    std::fs::write(dir.path().join("j.scene"), scene.replace("a.csv", "a.json")).unwrap();
    let out = bin().args(["run", "j.scene"]).current_dir(dir.path()).output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(2), "{err}");
    assert!(err.contains("column `H` is inf") && err.contains("export to `.csv`"), "{err}");
    assert!(!dir.path().join("a.json").exists());
}
