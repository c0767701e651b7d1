//! The canonical subcommands end to end: output re-parses to the expected expressions, bad
//! input exits with code 2 and a clear message.

use std::process::Command;

use lagrangian::{parse, parse_with, Declarations, Expr};

fn run(args: &[&str]) -> (i32, String, String) {
    let out = Command::new(env!("CARGO_BIN_EXE_lagrangian")).args(args).output().expect("binary runs");
    (
        out.status.code().unwrap_or(-1),
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn line_after<'a>(out: &'a str, prefix: &str) -> &'a str {
    out.lines().find_map(|l| l.strip_prefix(prefix)).unwrap_or_else(|| panic!("no line `{prefix}…` in\n{out}"))
}

#[test]
fn pb_of_angular_momenta() {
    let (code, out, err) = run(&["pb", "y p_z - z p_y", "z p_x - x p_z", "--coords", "x,y,z"]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(parse(out.trim()).expect("plain output re-parses"), parse("x p_y - y p_x").expect("parses"));
    let (_, json, _) = run(&["pb", "x", "p_x", "--coords", "x", "--format", "json"]);
    let v: serde_json::Value = serde_json::from_str(json.trim()).expect("valid JSON");
    assert_eq!(v["bracket"], "1");
    let (_, latex, _) = run(&["pb", "x^2", "p_x^2", "--coords", "x", "--format", "latex"]);
    assert_eq!(latex.trim(), "4 p_{x} x", "LaTeX rendering of 4 x p_x");
}

#[test]
fn canonical_oscillator_gives_k_equal_omega_p() {
    let (code, out, err) = run(&[
        "canonical",
        "--hamiltonian",
        "p_q^2/(2 m) + 1/2 m ω^2 q^2",
        "--coords",
        "q",
        "--f1",
        "1/2 m ω q^2 cot(Q)",
        "--new",
        "Q,P",
        "--positive",
        "m,ω",
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(parse(line_after(&out, "K = ")).expect("re-parses"), parse("ω P").expect("parses"));
    let decls = Declarations::new().with_positive(["m", "ω"]);
    let q = parse_with(line_after(&out, "  q = "), &decls).expect("re-parses");
    assert_eq!(q, parse_with("sqrt(2 P/(m ω)) sin(Q)", &decls).expect("parses"));
    assert!(out.contains("branch:"), "the ± root is named:\n{out}");
}

#[test]
fn is_canonical_yes_and_no() {
    let (code, out, _) = run(&["is-canonical", "Q = log(sin(p_q)/q), P = q cot(p_q)", "--coords", "q"]);
    assert_eq!(code, 0);
    assert!(out.starts_with("canonical: yes"), "{out}");
    let (code, out, _) = run(&["is-canonical", "Q = q, P = 2 p_q", "--coords", "q"]);
    assert_eq!(code, 0);
    assert!(out.starts_with("canonical: no: not canonical: {Q, P} = 2"), "{out}");
    let (code, _, err) = run(&["is-canonical", "Q = q", "--coords", "q"]);
    assert_eq!(code, 2);
    assert!(err.contains("need 2"), "{err}");
}

#[test]
fn integral_lie_action_average() {
    let (code, out, _) = run(&[
        "integral",
        "x p_y - y p_x",
        "--hamiltonian",
        "(p_x^2 + p_y^2)/2 + V(sqrt(x^2 + y^2))",
        "--functions",
        "V",
        "--coords",
        "x,y",
    ]);
    assert_eq!(code, 0);
    assert!(out.contains("an integral of motion: zero (proven symbolically)"), "{out}");
    let (_, out, _) = run(&["lie", "q", "--generator", "p_q", "--order", "3", "--coords", "q"]);
    assert_eq!(parse(out.trim()).expect("re-parses"), parse("q + ε").expect("parses"));
    let (code, out, err) =
        run(&["action", "--hamiltonian", "p_q^2/2 + 2 q^2", "--coord", "q", "--energy", "1,3", "--format", "json"]);
    assert_eq!(code, 0, "{err}");
    // ω0 = 2 (k = 4, m = 1): J = E/2.
    let v: serde_json::Value = serde_json::from_str(out.trim()).expect("valid JSON");
    for row in v.as_array().expect("array") {
        let (e, j) = (row["energy"].as_f64().expect("E"), row["action"].as_f64().expect("J"));
        assert!((j - e / 2.0).abs() < 1e-13 * e, "{row}");
    }
    let (code, out, _) =
        run(&["average", "1/2 m x'^2 - 1/2 m w0^2 x^2", "--trial", "x = A cos(θ)", "--frequency", "w"]);
    assert_eq!(code, 0);
    let j: Expr = parse(line_after(&out, "J = ∂⟨L⟩/∂w = ")).expect("re-parses");
    assert_eq!(j, parse("m w A^2/2").expect("parses"));
    // The anharmonic example, solved to first order in σ (hand result in
    // tests/it/canonical/average.rs): B = σA³/16, C = 0.
    let (code, out, err) = run(&[
        "average",
        "1/2 m x'^2 - 1/2 m ω0^2 (x^2 + σ x^4/l0^2)",
        "--trial",
        "x = l0 (A cos(θ) + B cos(3θ) + C sin(3θ))",
        "--phase",
        "θ",
        "--frequency",
        "ω",
        "--small",
        "σ",
        "--unperturbed",
        "ω0",
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(parse(line_after(&out, "  B = ")).expect("re-parses"), parse("σ A^3/16").expect("parses"));
    assert_eq!(line_after(&out, "  C = "), "0");
}

#[test]
fn numeric_inverse_where_no_closed_form_exists() {
    let (code, out, err) =
        run(&["canonical", "--f2", "q P + q^5 + q^3 P^2", "--coords", "q", "--at", "1.7,0.4", "--format", "json"]);
    assert_eq!(code, 0, "{err}");
    let lines: Vec<&str> = out.lines().collect();
    let t: serde_json::Value = serde_json::from_str(lines[0]).expect("valid JSON");
    assert_eq!(t["inverse"]["closed_form"], false);
    let v: serde_json::Value = serde_json::from_str(lines[1]).expect("valid JSON");
    let q = v["numeric_inverse"]["q"].as_f64().expect("q");
    // Q = ∂F2/∂P = q + 2 q³ P must hold at the numeric point.
    assert!((q + 0.8 * q.powi(3) - 1.7).abs() < 1e-14, "q = {q}");
}

#[test]
fn numeric_inverse_takes_the_branch_of_the_printed_inverse_map() {
    // F1 = ½ m ω q² cot Q (notes §4.2.1): p = m ω q cot Q and P = m ω q²/(2 sin² Q) are even
    // in (q, p), so (q, p) and (−q, −p) both satisfy them. The printed inverse map is the
    // notes' q = √(2P/(mω)) sin Q, p = √(2Pmω) cos Q; at Q = 4, P = 1, m = ω = 1 that is
    // q = √2 sin 4 = −1.0703, p = √2 cos 4 = −0.9244, and `--at` must give the same point
    // (Newton from the default guess 1 used to land on +1.0703, +0.9244).
    let args = ["canonical", "--f1", "1/2 m ω q^2 cot(Q)", "--coords", "q", "--at", "4,1", "--params", "m=1,ω=1"];
    let (code, out, err) = run(&[&args[..], &["--format", "json"]].concat());
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(out.lines().nth(1).expect("two lines")).expect("valid JSON");
    let (q, pq) = (v["numeric_inverse"]["q"].as_f64().expect("q"), v["numeric_inverse"]["p_q"].as_f64().expect("p"));
    let (q_hand, p_hand) = (2f64.sqrt() * 4f64.sin(), 2f64.sqrt() * 4f64.cos());
    assert!((q - q_hand).abs() < 1e-13 && (pq - p_hand).abs() < 1e-13, "q = {q}, p = {pq}");
    // A guess on the other root is honoured, with a note naming the printed map's root.
    let (code, out, err) = run(&[&args[..], &["--guess", "1"]].concat());
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("q = 1.070280352902273e0"), "{out}");
    assert!(err.contains("another root") && err.contains("q = -1.070280352902273e0"), "{err}");
}

#[test]
fn bad_input_exits_with_code_2_and_says_why() {
    let (code, _, err) = run(&["canonical", "--f1", "q^2 + Q^2", "--coords", "q"]);
    assert_eq!(code, 2);
    assert!(err.contains("not a valid generating function"), "{err}");
    let (code, _, err) = run(&["average", "1/2 x'^2 - 1/2 x^2", "--trial", "x = A cos(θ/2)"]);
    assert_eq!(code, 2);
    assert!(err.contains("not 2π-periodic"), "{err}");
    let (code, _, err) = run(&["action", "--hamiltonian", "p_q^2/2", "--coord", "q", "--energy", "1"]);
    assert_eq!(code, 2);
    assert!(err.contains("not a libration"), "{err}");
    let (code, _, err) = run(&["pb", "x", "p_x", "--coords", "x,x"]);
    assert_eq!(code, 2);
    assert!(err.contains("declared twice"), "{err}");
    let (code, _, err) = run(&["lie", "q", "--flow", "p_q^2/2 + t q", "--coords", "q"]);
    assert_eq!(code, 2);
    assert!(err.contains("autonomous"), "{err}");
    // Resource limits are errors, not hangs.
    let (code, _, err) = run(&["lie", "q", "--flow", "p_q^2/2 - cos(q)", "--coords", "q", "--order", "1000"]);
    assert_eq!(code, 2);
    assert!(err.contains("above the limit"), "{err}");
    let (code, _, err) = run(&["average", "x^2", "--trial", "x = A cos(θ)^1000"]);
    assert_eq!(code, 2);
    assert!(err.contains("not multiplied out"), "{err}");
}
