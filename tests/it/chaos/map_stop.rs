//! The scene's `chaos_map megno … stop megno >= L after T`: the library's early stop
//! (`chaos::MegnoStop` in the map's `Budget`) as a statement option. The map it writes is the
//! library's `chaos_map_each` with the same budget, cell by cell; the cells the stop spares are
//! bit for bit those of the map without it; the CSV's `stopped_at` column appears only with a
//! stop; the refusals (another indicator, another word, numbers the library refuses, the clause
//! twice) are located errors with the library's text.

use crate::support;

use lagrangian::chaos::{chaos_map_each, Budget, Cell, Indicator, MegnoStop};
use lagrangian::compile::Variational;
use lagrangian::parse;

/// Hénon–Heiles, written the same way in the scene and for the library, so both compile the
/// same expression.
const HH: &str = "1/2 (p_x^2 + p_y^2) + 1/2 (x^2 + y^2) + x^2 y - y^3/3";

/// The grid: `y` and `p_y` over their ranges, `x = 0`, `p_x = 0.38`, to t = 200 at tol 1e-10.
/// Chosen (by running it) so that some cells are regular (⟨Y⟩ ≈ 0.4 … 1.8 at t = 200) and some
/// chaotic (⟨Y⟩(200) from 3.7 to 9.7), and the stop at 3 after t = 20 ends those.
const Y: (f64, f64) = (-0.35, 0.45);
const PY: (f64, f64) = (-0.3, 0.3);
const PX: f64 = 0.38;
const SIDE: usize = 6;
const T: f64 = 200.0;
const TOL: f64 = 1e-10;
const ABOVE: f64 = 3.0;
const AFTER: f64 = 20.0;

fn map_line(stop: &str, file: &str) -> String {
    format!(
        "chaos_map megno y = {}..{}, p_y = {}..{}, x = 0, p_x = {PX} for t in 0..{T} points {SIDE} tol = {TOL:e}{stop} to {file}\n",
        Y.0, Y.1, PY.0, PY.1
    )
}

/// Runs the scene: the map with the stop to `stop.csv`, without it to `plain.csv`, and with it
/// as a heat map to `stop.svg`; returns the directory and the printed lines.
fn run_maps() -> (tempfile::TempDir, String) {
    let dir = tempfile::tempdir().unwrap();
    let stop = format!(" stop megno >= {ABOVE} after {AFTER}");
    let scene = format!(
        "coordinates x, y\nH = {HH}\n{}{}{}",
        map_line(&stop, "stop.csv"),
        map_line("", "plain.csv"),
        map_line(&stop, "stop.svg")
    );
    let (code, out, err) = support::run_scene_in(dir.path(), &scene, &["--out-dir", dir.path().to_str().unwrap()]);
    assert_eq!(code, 0, "{err}");
    (dir, out)
}

/// The cell centres row by row (`p_y` outer), `a + (b − a)(k + ½)/N`, and the canonical starts
/// `(x, y, p_x, p_y)` there.
fn grid() -> (Vec<(f64, f64)>, Vec<Vec<f64>>) {
    let c = |(a, b): (f64, f64), k: usize| a + (b - a) * (k as f64 + 0.5) / SIDE as f64;
    let mut centres = Vec::new();
    let mut starts = Vec::new();
    for j in 0..SIDE {
        for i in 0..SIDE {
            let (y, py) = (c(Y, i), c(PY, j));
            centres.push((y, py));
            starts.push(vec![0.0, y, PX, py]);
        }
    }
    (centres, starts)
}

/// The library's map of the same starts within `budget` (the scene's defaults: 10⁷ steps an
/// orbit, 600 s).
fn library(stop: Option<MegnoStop>) -> Vec<Cell> {
    let var = Variational::hamiltonian(&parse(HH).unwrap(), &["x", "y"], &["p_x", "p_y"], &[], 1, true).unwrap();
    let budget = Budget { megno_stop: stop, ..Budget::default() };
    let (_, starts) = grid();
    chaos_map_each(&var, &starts, T, TOL, Indicator::Megno, &budget)
}

/// The rows of a map's CSV as their fields.
fn rows(csv: &str) -> Vec<Vec<String>> {
    csv.lines().skip(1).map(|l| l.split(',').map(str::to_string).collect()).collect()
}

#[test]
fn a_scene_map_with_the_stop_is_the_librarys_map_cell_by_cell() {
    let (dir, out) = run_maps();
    let csv = std::fs::read_to_string(dir.path().join("stop.csv")).unwrap();
    assert_eq!(csv.lines().next(), Some("y,p_y,megno,stopped_at"));
    let lib = library(Some(MegnoStop::new(ABOVE, AFTER).unwrap()));
    let (centres, _) = grid();
    let rows = rows(&csv);
    assert_eq!(rows.len(), SIDE * SIDE);
    let mut stopped = 0;
    for ((row, cell), (y, py)) in rows.iter().zip(&lib).zip(&centres) {
        assert_eq!(row.len(), 4, "{row:?}");
        // `{:e}` prints the shortest text that reads back to the same f64, so bits compare.
        let f = |k: usize| row[k].parse::<f64>().unwrap();
        assert_eq!((f(0).to_bits(), f(1).to_bits()), (y.to_bits(), py.to_bits()), "{row:?}");
        assert_eq!(f(2).to_bits(), cell.value.to_bits(), "{row:?} against {cell:?}");
        match cell.stopped_at {
            None => assert_eq!(row[3], "", "{row:?}"),
            Some(t) => {
                stopped += 1;
                assert_eq!(f(3).to_bits(), t.to_bits(), "{row:?}");
                // A stopped cell reached the level, at or after the stop's time, before T.
                assert!(cell.value >= ABOVE && (AFTER..T).contains(&t), "{row:?}");
            }
        }
    }
    // The grid has both kinds, and the summary counts the stopped ones.
    assert!(stopped > 0 && stopped < SIDE * SIDE, "{stopped} stopped");
    let line = out.lines().find(|l| l.starts_with("chaos map")).unwrap();
    assert!(line.contains(&format!(", {stopped} stopped early at ⟨Y⟩ ≥ 3 after t = 20")), "{line}");
    // The heat map's title says what a stopped cell's colour is.
    let svg = std::fs::read_to_string(dir.path().join("stop.svg")).unwrap();
    assert!(svg.contains("MEGNO ⟨Y⟩ at t = 200; ⟨Y⟩ ≥ 3 after t = 20: stopped there (colour at the stop)"));
}

#[test]
fn cells_the_stop_spares_are_bit_identical_to_the_map_without_it() {
    let (dir, out) = run_maps();
    let with = rows(&std::fs::read_to_string(dir.path().join("stop.csv")).unwrap());
    let plain_csv = std::fs::read_to_string(dir.path().join("plain.csv")).unwrap();
    let plain = rows(&plain_csv);
    let mut spared = 0;
    for (w, p) in with.iter().zip(&plain) {
        assert_eq!(p.len(), 3, "{p:?}");
        if w[3].is_empty() {
            spared += 1;
            assert_eq!(w[..3], p[..], "a spared cell");
        } else {
            // A stopped cell's orbit would have gone on to T: its value there is another.
            assert_ne!(w[2], p[2]);
        }
    }
    assert!(spared > 0 && spared < with.len(), "{spared} of {} spared", with.len());
    // Without a stop the table is as it was before the option existed: three columns, the
    // values of the library's map without a stop, no word of stopping in the summary.
    let (centres, _) = grid();
    let mut expected = String::from("y,p_y,megno\n");
    for ((y, py), cell) in centres.iter().zip(library(None)) {
        assert_eq!(cell.stopped_at, None);
        expected.push_str(&format!("{y:e},{py:e},{:e}\n", cell.value));
    }
    assert_eq!(plain_csv, expected);
    let plain_line = out.lines().filter(|l| l.starts_with("chaos map")).nth(1).unwrap();
    assert!(!plain_line.contains("stopped"), "{plain_line}");
}

#[test]
fn the_stop_is_refused_where_it_does_not_apply_with_the_librarys_words() {
    let dir = tempfile::tempdir().unwrap();
    let base = "coordinates x\nH = 1/2 p_x^2 + 1/2 x^2\n";
    let map = "chaos_map megno x = -1..1, p_x = -1..1 for t in 0..10 points 2";
    let (low, early) = (MegnoStop::new(2.0, 1.0).unwrap_err(), MegnoStop::new(5.0, -1.0).unwrap_err());
    let mut shown = String::new();
    for (stmt, says, col) in [
        // Only a MEGNO map has ⟨Y⟩ to stop on: at the clause (column 67, by counting).
        (
            "chaos_map lyapunov x = -1..1, p_x = -1..1 for t in 0..10 points 2 stop megno >= 5 after 1 to m.csv"
                .to_string(),
            "`stop megno >= …` applies to MEGNO maps only, not to a `lyapunov` map",
            67,
        ),
        (
            "chaos_map fli x = -1..1, p_x = -1..1 for t in 0..10 points 2 stop megno >= 5 after 1 to m.csv".to_string(),
            "applies to MEGNO maps only, not to a `fli` map",
            62,
        ),
        // The level and the time are the library's to check (`MegnoStop::new`): its message.
        (format!("{map} stop megno >= 2 after 1 to m.csv"), low.as_str(), 64),
        (format!("{map} stop megno >= 5 after -1 to m.csv"), early.as_str(), 64),
        // Another word than `megno`, at the word.
        (format!("{map} stop fli >= 5 after 1 to m.csv"), "the early stop compares MEGNO ⟨Y⟩, not `fli`", 69),
        // The clause twice: the second is refused, not silently kept.
        (
            format!("{map} stop megno >= 5 after 1 stop megno >= 6 after 1 to m.csv"),
            "the early stop is given twice",
            88,
        ),
        // The grammar's own refusals say what was expected.
        (format!("{map} stop megno >= 5 to m.csv"), "expected `after T`", 80),
        (format!("{map} stop megno 5 after 1 to m.csv"), "expected `>=` (or `≥`), found `5`", 75),
    ] {
        let (code, _, err) = support::run_scene_in(dir.path(), &format!("{base}{stmt}\n"), &[]);
        let err = err.replace(&dir.path().join("test.scene").display().to_string(), "test.scene");
        assert_eq!(code, 2, "{stmt}: {err}");
        // The message as one line (the renderer wraps a long one at `│`).
        assert!(err.replace("\n  │ ", " ").contains(says), "{stmt}: {err}");
        assert!(err.contains(&format!("[test.scene:3:{col}]")), "{stmt}: {err}");
        assert!(!dir.path().join("m.csv").exists(), "{stmt}");
        shown.push_str(&err);
        shown.push('\n');
    }
    // The library's two messages, as the scene was written to show them.
    assert!(low.contains("must be finite and above 2") && early.contains("must be finite and at least 0"));
    support::snapshot("chaos_map_stop_refusals", &shown);
}

#[test]
fn help_shows_the_stop_in_the_form_of_chaos_map() {
    let dir = tempfile::tempdir().unwrap();
    let (code, out, err) = support::run_scene_in(dir.path(), "help chaos_map\n", &[]);
    assert_eq!(code, 0, "{err}");
    assert!(out.contains("[stop megno >= L after T]"), "{out}");
}
