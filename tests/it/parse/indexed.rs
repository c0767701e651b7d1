//! Indexed names and sums: `x[i]`, `sum(i = a..b, …)`, `sum(i < j in a..b, …)` and the scene
//! declarations `x[0..4]`, `m[0..4] = …`. They are expanded as the text is read, so the second
//! route for every expected value is the written-out text, parsed (and run) the old way.

use std::collections::HashMap;
use std::path::Path;
use std::time::Instant;

use lagrangian::print::plain;
use lagrangian::{parse, parse_with, Declarations, Expr, ParseError};
use proptest::prelude::*;

use crate::support::{read_csv, run_scene_in, scene_names, scene_parameters};

fn p(text: &str) -> Expr {
    parse(text).unwrap_or_else(|e| panic!("{text}: {e}"))
}

fn err(text: &str, decls: &Declarations) -> ParseError {
    match parse_with(text, decls) {
        Ok(e) => panic!("{text} parsed as {e}"),
        Err(e) => e,
    }
}

/// The byte column (1-based) of the first occurrence of `what` in `text`.
fn col(text: &str, what: &str) -> usize {
    text.find(what).unwrap_or_else(|| panic!("`{what}` not in {text}")) + 1
}

/// The N-body Hamiltonian in `dims` dimensions for bodies `0..n`, written out term by term in
/// the order a person (or the old generator script) writes it.
fn written_out_nbody(n: usize, dims: &[&str]) -> String {
    let kinetic: Vec<String> = (0..n)
        .map(|i| {
            let p2: Vec<String> = dims.iter().map(|d| format!("p_{d}{i}^2")).collect();
            format!("({})/(2 m{i})", p2.join(" + "))
        })
        .collect();
    let mut pairs = Vec::new();
    for i in 0..n {
        for j in i + 1..n {
            let r2: Vec<String> = dims.iter().map(|d| format!("({d}{i} - {d}{j})^2")).collect();
            pairs.push(format!("m{i} m{j}/sqrt({})", r2.join(" + ")));
        }
    }
    format!("{} - G ({})", kinetic.join(" + "), pairs.join(" + "))
}

/// The same with indexed sums, as a physicist writes it.
fn summed_nbody(n: usize, dims: &[&str]) -> String {
    let p2: Vec<String> = dims.iter().map(|d| format!("p_{d}[i]^2")).collect();
    let r2: Vec<String> = dims.iter().map(|d| format!("({d}[i] - {d}[j])^2")).collect();
    format!(
        "sum(i = 0..{last}, ({})/(2 m[i])) - G sum(i < j in 0..{last}, m[i] m[j]/sqrt({}))",
        p2.join(" + "),
        r2.join(" + "),
        last = n - 1
    )
}

/// A three-body scene in the plane, its Hamiltonian `h` and coordinates `coords`: prints H and
/// Hamilton's equations, integrates with the Taylor method and exports the states.
fn three_body_scene(coords: &str, params: &str, h: &str) -> String {
    format!(
        "coordinates {coords}\nparameters {params}\nH = {h}\nprint H\nhamilton\n\
         simulate x0 = 1, y0 = 0, x1 = 0, y1 = 1, x2 = -1, y2 = 0, p_x0 = 0, p_y0 = 0.2, p_x1 = -0.1, \
         p_y1 = 0, p_x2 = 0, p_y2 = -0.1 for t in 0..3 with taylor tol = 1e-12 as run\n\
         export from run to out.csv\n"
    )
}

/// Three bodies: the sum form and the shorthand declarations give the very tree of the
/// written-out form, hence the same printed Hamiltonian, equations and trajectory, byte for byte.
#[test]
fn three_body_sums_read_as_the_written_out_hamiltonian() {
    let (sum, full) = (summed_nbody(3, &["x", "y"]), written_out_nbody(3, &["x", "y"]));
    let decls = Declarations::new().with_positive(["G", "m0", "m1", "m2"]);
    let (a, b) = (parse_with(&sum, &decls).unwrap(), parse_with(&full, &decls).unwrap());
    assert_eq!(a, b);
    assert_eq!(plain(&a), plain(&b));

    let dir = tempfile::tempdir().unwrap();
    let written = three_body_scene("x0, x1, x2, y0, y1, y2", "G = 1, m0 = 1, m1 = 2, m2 = 3 positive", &full);
    let short = three_body_scene("x[0..2], y[0..2]", "G = 1, m[0..2] = 1, 2, 3 positive", &sum);
    let (code, out_written, e) = run_scene_in(dir.path(), &written, &[]);
    assert_eq!(code, 0, "{e}");
    let csv_written = std::fs::read(dir.path().join("out.csv")).unwrap();
    let (code, out_short, e) = run_scene_in(dir.path(), &short, &[]);
    assert_eq!(code, 0, "{e}");
    let csv_short = std::fs::read(dir.path().join("out.csv")).unwrap();
    assert!(out_written.contains("p_x0/m0") && out_written.contains("m1 (x1 - x0)/((x0 - x1)"), "{out_written}");
    assert!(!out_short.contains("sum("), "printing never shows a sum: {out_short}");
    assert_eq!(out_short, out_written);
    assert_eq!(csv_short, csv_written);
}

/// The outer solar system example (indexed sums, family declarations) against the written-out
/// scene it replaced: the same Hamiltonian tree, and the same exported numbers in every cell
/// over 10³ Jupiter orbits (the columns come in the declaration order, x0 … x4 then y0 …, where
/// the written-out scene interleaved x0, y0, z0; each column is compared by name).
#[test]
fn outer_solar_system_example_is_the_written_out_system() {
    let root = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = std::fs::read_to_string(root.join("examples/outer_solar_system.scene")).unwrap();
    let line = |prefix: &str| scene.lines().find_map(|l| l.strip_prefix(prefix)).unwrap().to_string();
    let h = line("H = ");
    assert!(h.contains("sum(i < j in 0..4"), "the example uses the indexed form");
    let params = scene_parameters(&scene);
    let names: Vec<&str> = params.iter().map(|(k, _)| k.as_str()).collect();
    assert_eq!(names, ["G", "m0", "m1", "m2", "m3", "m4"]);
    let coords = scene_names(&line("coordinates "));
    assert_eq!(coords.len(), 15);
    let decls = Declarations::new()
        .with_positive(&names)
        .with_families_of(coords.iter().map(String::as_str).chain(names.iter().copied()));
    let full = written_out_nbody(5, &["x", "y", "z"]);
    assert_eq!(parse_with(&h, &decls).unwrap(), parse_with(&full, &decls).unwrap());

    // The scene as it was written before indexed sums (coordinates interleaved by body).
    let interleaved: Vec<String> = (0..5).flat_map(|i| ["x", "y", "z"].map(|d| format!("{d}{i}"))).collect();
    let values: Vec<String> = params.iter().map(|(k, v)| format!("{k} = {v:?}")).collect();
    let old = format!(
        "coordinates {}\nparameters {} positive\nH = {full}\nsimulate {}\nexport from solar to old.csv\n",
        interleaved.join(", "),
        values.join(", "),
        line("simulate ")
    );
    let dir = tempfile::tempdir().unwrap();
    let (code, _, e) = run_scene_in(dir.path(), &old, &[]);
    assert_eq!(code, 0, "{e}");
    let example = root.join("examples/outer_solar_system.scene");
    let (code, _, e) = crate::support::run_in_dir(
        Some(dir.path()),
        &["run", example.to_str().unwrap(), "--out-dir", dir.path().to_str().unwrap()],
    );
    assert_eq!(code, 0, "{e}");
    let text = |f: &str| -> HashMap<String, Vec<String>> {
        let body = std::fs::read_to_string(dir.path().join(f)).unwrap();
        let mut lines = body.lines();
        let header: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
        let mut cols: HashMap<String, Vec<String>> = header.iter().map(|h| (h.clone(), vec![])).collect();
        for l in lines {
            for (h, v) in header.iter().zip(l.split(',')) {
                cols.get_mut(h).unwrap().push(v.to_string());
            }
        }
        cols
    };
    let (a, b) = (text("old.csv"), text("outer_solar_system.csv"));
    assert_eq!(a.len(), 31);
    assert!(a["t"].len() > 15_000, "{} rows", a["t"].len());
    assert_eq!(a, b, "every exported number is the same text");
    assert_eq!(read_csv(&dir.path().join("old.csv"))["x4"].len(), a["t"].len());
}

#[test]
fn indices_name_plain_symbols() {
    assert_eq!(p("x[3]"), p("x3"));
    assert_eq!(p("p_x[ 2 + 1 ]"), p("p_x3"));
    assert_eq!(p("x[1]' + θ[2]''"), p("x1' + θ2''"));
    assert_eq!(p("sum(i = 0..2, m[i] x[i]'^2)"), p("m0 x0'^2 + m1 x1'^2 + m2 x2'^2"));
    // A bound index standing alone is its value.
    assert_eq!(p("sum(k = 1..3, k^2 x[k])"), p("x1 + 4 x2 + 9 x3"));
    // Bounds may use enclosing indices: the nested form of the pair sum is the pair sum.
    assert_eq!(p("sum(i = 0..3, sum(j = i+1..3, x[i] x[j]))"), p("sum(i < j in 0..3, x[i] x[j])"));
    assert_eq!(p("sum(i < j in 0..3, x[i] x[j])"), p("x0 x1 + x0 x2 + x0 x3 + x1 x2 + x1 x3 + x2 x3"));
    assert_eq!(p("sum(i = 0..1, x[i+1] - x[i])"), p("x2 - x0"));
    // An inner range that moves with the outer index may hold nothing at its end: zero.
    assert_eq!(p("sum(i = 0..2, sum(j = 0..i-1, x[i] x[j]))"), p("x1 x0 + x2 x0 + x2 x1"));
    // A sum of one term, and a lone sum times a coefficient, as their written-out forms.
    assert_eq!(p("sum(i = 4..4, x[i])"), p("x4"));
    assert_eq!(p("2 sum(i = 0..1, x[i])"), p("2 (x0 + x1)"));
    assert_eq!(p("-sum(i = 0..1, x[i]) y"), p("-(x0 + x1) y"));
    // A declared function `sum` is still callable when its arguments bind nothing.
    let d = Declarations::new().with_functions(["sum"]);
    assert_eq!(parse_with("sum(x)", &d).unwrap(), parse_with("sum(x)", &d).unwrap());
}

#[test]
fn errors_say_where_and_what_would_work() {
    let none = Declarations::new();
    let fam = Declarations::new().with_families_of(["x0", "x1", "x2", "x3", "x4", "m0", "m1"]);

    let t = "sum(i = 0..4, x[i+1])";
    let e = err(t, &fam);
    assert!(e.message.contains("index 5 is outside `x`'s declared range 0..4"), "{e}");
    assert_eq!(e.column, col(t, "i+1"));
    // Without declarations (the command line) the same text is x1 + … + x5.
    assert_eq!(parse_with(t, &none).unwrap(), p("x1 + x2 + x3 + x4 + x5"));
    // A momentum belongs to its coordinate's family.
    let t = "p_x[7]^2";
    let e = err(t, &fam);
    assert!(e.message.contains("index 7 is outside `x`'s declared range 0..4"), "{e}");
    assert_eq!(e.column, col(t, "7"));

    let t = "m[0] x[i]";
    let e = err(t, &none);
    assert!(e.message.contains("`i` is not an index bound by an enclosing `sum`"), "{e}");
    assert_eq!(e.column, col(t, "i]"));
    assert!(e.hint.as_deref().unwrap().contains("sum(i = 0..4"), "{e}");

    for (t, at) in [("sum(i = 3..1, x[i])", "3..1"), ("1 + sum(i < j in 2..2, x[i] x[j])", "2..2")] {
        let e = err(t, &none);
        assert!(e.message.contains("is empty"), "{t}: {e}");
        assert_eq!(e.column, col(t, at), "{t}");
    }

    let t = "sum(i = 0..2, sum(i = 0..3, x[i]))";
    let e = err(t, &none);
    assert!(e.message.contains("`i` is already bound by an enclosing `sum`"), "{e}");
    assert_eq!(e.column, 19);
    let e = err("sum(i < i in 0..3, x[i])", &none);
    assert!(e.message.contains("already bound"), "{e}");

    let t = "sum(i = 0..2, x[i - 1])";
    let e = err(t, &none);
    assert!(e.message.contains("is -1, and indices are whole numbers ≥ 0"), "{e}");
    assert_eq!(e.column, col(t, "i - 1"));
    let e = err("x[99999999999999999999999]", &none);
    assert!(e.message.contains("index too large"), "{e}");
    for t in ["sum(i = 0..4)", "sum(i in 0..4, x[i])", "2 sum(i = 0...4, x[i])"] {
        let e = err(t, &none);
        assert!(e.hint.as_deref().is_some_and(|h| h.contains("sum(i = 0..4, body)")), "{t}: {e}");
    }
    let e = err("sin[2] + pi[0]", &none);
    assert!(e.message.contains("cannot be indexed"), "{e}");
    let e = err("sum(i = 0..2, i' x[i])", &none);
    assert!(e.message.contains("no time derivative"), "{e}");
}

/// Ranges past the resource limit are refused before any expansion, in microseconds, however
/// large: one sum, nested sums, pair sums, and the largest range `u64` can write.
#[test]
fn oversized_sums_are_refused_at_once() {
    let t0 = Instant::now();
    for t in [
        "sum(i = 0..10000, x[i])",
        "sum(i = 0..200, sum(j = 0..200, x[i] y[j]))",
        "sum(i < j in 0..200, x[i] x[j])",
        "sum(i = 0..18446744073709551615, x[i])",
        "sum(i < j in 0..18446744073709551615, x[i])",
        "sum(i = 0..99, sum(j = 0..99, x[i] y[j]))",
    ] {
        let e = err(t, &Declarations::new());
        assert!(e.message.contains("more than 10000 terms"), "{t}: {e}");
        assert!(e.column > 1, "{t}: the caret is on the range");
    }
    // The limit itself is reachable.
    assert!(parse("sum(i = 1..10000, x[i])").is_ok());
    // A long body times many terms is bounded by the text it would expand to.
    let body = vec!["x[i]"; 2000].join(" + ");
    let e = err(&format!("sum(i = 0..999, {body})"), &Declarations::new());
    assert!(e.message.contains("bytes of text"), "{e}");
    assert!(t0.elapsed().as_secs_f64() < 30.0, "{:?}", t0.elapsed());
}

/// Scene declarations: families expand in order, values go to members in order, and the
/// mistakes are refused with the statement's line.
#[test]
fn scene_families() {
    let dir = tempfile::tempdir().unwrap();
    let ok = "coordinates x[0..1]\nparameters k, m[0..1] = 2, 3 positive\n\
              H = sum(i = 0..1, p_x[i]^2/(2 m[i])) + k/2 (x[1] - x[0])^2\nprint H\nhamilton\n";
    let (code, out, e) = run_scene_in(dir.path(), ok, &[]);
    assert_eq!(code, 0, "{e}");
    let full = "coordinates x0, x1\nparameters k, m0 = 2, m1 = 3 positive\n\
                H = p_x0^2/(2 m0) + p_x1^2/(2 m1) + k/2 (x1 - x0)^2\nprint H\nhamilton\n";
    let (code, out_full, e) = run_scene_in(dir.path(), full, &[]);
    assert_eq!(code, 0, "{e}");
    assert_eq!(out, out_full);

    for (scene, line, says) in [
        ("coordinates x[3..1]\n", 1, "the range 3..1 of `x` is empty"),
        ("coordinates x\nparameters m[0..2] = 1, 2\n", 2, "`m[0..2]` has 3 members but 2 values"),
        ("coordinates x[0..1]\nH = p_x[2]^2/2\nprint H\n", 2, "index 2 is outside `x`'s declared range 0..1"),
        ("coordinates x[0..1]\nH = sum(i = 0..1, p_x[i]^2/2) + x[j]\nprint H\n", 2, "`j` is not an index bound"),
        ("coordinates x[0..100000]\n", 1, "declares more than 10000 names"),
    ] {
        let (code, _, e) = run_scene_in(dir.path(), scene, &[]);
        assert_ne!(code, 0, "{scene}");
        assert!(e.contains(says), "{scene}: {e}");
        assert!(e.contains(&format!("test.scene:{line}:")) || e.contains(&format!("line {line}")), "{scene}: {e}");
    }
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 64, ..ProptestConfig::default() })]

    /// Random ranges and coefficients: each sum form is its written-out text, and its printed
    /// form re-parses to the same expression and shows no `sum`.
    #[test]
    fn sums_expand_to_their_written_out_form(
        lo in 0u64..20, len in 1u64..12, coeffs in proptest::collection::vec(-9i64..10, 12), power in 1u32..4
    ) {
        let hi = lo + len - 1;
        // A bound index standing alone is its number: `(i - K) y[i]` against `(k - K) y{k}`.
        let shift = coeffs[0];
        let valued = format!("sum(i = {lo}..{hi}, (i - ({shift})) y[i])");
        let written: Vec<String> = (lo..=hi).map(|k| format!("({}) y{k}", k as i64 - shift)).collect();
        prop_assert_eq!(p(&valued), p(&written.join(" + ")));
        let single = format!("sum(i = {lo}..{hi}, c[i] x[i]^{power})");
        let written: Vec<String> = (lo..=hi).map(|k| format!("c{k} x{k}^{power}")).collect();
        prop_assert_eq!(p(&single), p(&written.join(" + ")));

        let pairs = format!("sum(i < j in {lo}..{hi}, (q[i] - q[j])^2)");
        let mut written = Vec::new();
        for i in lo..=hi {
            for j in i + 1..=hi {
                written.push(format!("(q{i} - q{j})^2"));
            }
        }
        if written.is_empty() {
            prop_assert!(parse(&pairs).is_err());
        } else {
            let e = p(&pairs);
            prop_assert_eq!(&e, &p(&written.join(" + ")));
            let printed = plain(&e);
            prop_assert!(!printed.contains("sum("), "{}", printed);
            prop_assert_eq!(p(&printed), e);
        }
        let printed = plain(&p(&single));
        prop_assert!(!printed.contains("sum(") && !printed.contains('['), "{}", printed);
        prop_assert_eq!(p(&printed), p(&single));
    }

    /// Arbitrary text around `sum(` and `[` never panics: it parses or is refused with a
    /// location inside the input.
    #[test]
    fn indexed_syntax_never_panics(
        parts in proptest::collection::vec(
            prop_oneof![
                Just("sum("), Just("i"), Just("j"), Just(" = "), Just(" < "), Just(" in "), Just(".."),
                Just(", "), Just(")"), Just("x["), Just("]"), Just("0"), Just("7"), Just("+"), Just("-"),
                Just("'"), Just("99999999999999999999"), Just("m"), Just("("),
            ],
            0..24,
        )
    ) {
        let text: String = parts.concat();
        if let Err(e) = parse(&text) {
            prop_assert!(e.span.0 <= text.len(), "{}: {:?}", text, e.span);
        }
    }
}
