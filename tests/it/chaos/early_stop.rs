//! The opt-in early stop of orbits whose mean MEGNO has diverged (`chaos::MegnoStop`): a
//! stopped orbit reports when it stopped and the indicators of that time, equal to the full
//! run's at the same step; an orbit the stop spares ends bit for bit as without it.

use lagrangian::chaos::{chaos_map, chaos_map_with, indicators_with, Budget, Indicator, MegnoStop};
use lagrangian::compile::Variational;
use lagrangian::parse;

const HH: &str = "1/2 (p_x^2 + p_y^2) + 1/2 (x^2 + y^2) + x^2 y - y^3/3";

fn henon_heiles() -> Variational {
    Variational::hamiltonian(&parse(HH).unwrap(), &["x", "y"], &["p_x", "p_y"], &[], 1, true).unwrap()
}

/// A start on the energy surface `E` with `x = 0` and given `y`, `p_y` (`p_x ≥ 0` from E).
fn hh_start(e: f64, y: f64, py: f64) -> Vec<f64> {
    let px2 = 2.0 * e - py * py - y * y + 2.0 * y * y * y / 3.0;
    vec![0.0, y, px2.sqrt(), py]
}

/// Every step's sample kept, no step or time limit.
fn every_step(stop: Option<MegnoStop>) -> Budget {
    Budget { max_steps: usize::MAX, deadline: None, time_limit: None, max_samples: usize::MAX, megno_stop: stop }
}

#[test]
fn a_chaotic_orbit_stops_where_its_full_run_first_crosses_the_level() {
    let hh = henon_heiles();
    let x0 = hh_start(1.0 / 6.0, -0.1, 0.05);
    let stop = MegnoStop::new(5.0, 50.0).unwrap();
    let full = indicators_with(&hh, &x0, 1000.0, 1e-12, &every_step(None)).unwrap();
    assert!(full.stopped_at.is_none());
    assert!(full.megno > 5.0, "the orbit is chaotic: Ȳ(1000) = {}", full.megno);
    // The first step of the full run ending at t ≥ 50 with Ȳ ≥ 5.
    let k = full.samples.iter().position(|s| s.t >= 50.0 && s.megno >= 5.0).expect("the full run crosses 5");
    let cross = full.samples[k];
    let r = indicators_with(&hh, &x0, 1000.0, 1e-12, &every_step(Some(stop))).unwrap();
    assert_eq!(r.stopped_at, Some(cross.t));
    assert!(cross.t < 1000.0);
    assert_eq!(r.steps, k + 1);
    assert_eq!(r.megno.to_bits(), cross.megno.to_bits());
    assert_eq!(r.lyapunov[0].to_bits(), cross.lyapunov.to_bits());
    assert_eq!(r.samples.last().map(|s| s.t), Some(cross.t));
    assert!(r.megno >= 5.0);
}

#[test]
fn an_orbit_the_stop_spares_ends_as_without_it() {
    let hh = henon_heiles();
    let x0 = hh_start(0.05, 0.1, 0.0);
    let stop = MegnoStop::new(3.0, 10.0).unwrap();
    let full = indicators_with(&hh, &x0, 500.0, 1e-12, &every_step(None)).unwrap();
    let r = indicators_with(&hh, &x0, 500.0, 1e-12, &every_step(Some(stop))).unwrap();
    assert!(r.stopped_at.is_none());
    assert_eq!(r, full);
    assert!(r.megno < 3.0, "regular: Ȳ = {}", r.megno);
}

#[test]
fn before_its_time_no_orbit_stops() {
    // The chaotic orbit's Ȳ passes 2.1 early on, but the stop waits for t ≥ T past the end.
    let hh = henon_heiles();
    let x0 = hh_start(1.0 / 6.0, -0.1, 0.05);
    let stop = MegnoStop::new(2.1, 400.0).unwrap();
    let full = indicators_with(&hh, &x0, 300.0, 1e-12, &every_step(None)).unwrap();
    assert!(full.samples.iter().any(|s| s.megno >= 2.1), "Ȳ reaches 2.1 before t = 300");
    let r = indicators_with(&hh, &x0, 300.0, 1e-12, &every_step(Some(stop))).unwrap();
    assert_eq!(r, full);
}

#[test]
fn a_map_marks_the_stopped_cells_and_keeps_the_others_values() {
    let hh = henon_heiles();
    let starts = vec![hh_start(0.05, 0.1, 0.0), hh_start(1.0 / 6.0, -0.1, 0.05)];
    let stop = MegnoStop::new(5.0, 50.0).unwrap();
    let cells = chaos_map_with(&hh, &starts, 1000.0, 1e-12, Indicator::Megno, &every_step(Some(stop)));
    let plain = chaos_map(&hh, &starts, 1000.0, 1e-12, Indicator::Megno);
    assert_eq!(cells[0].stopped_at, None);
    assert_eq!(cells[0].value.to_bits(), plain[0].to_bits());
    let at = cells[1].stopped_at.expect("the chaotic start stops");
    assert!((50.0..1000.0).contains(&at), "stopped at {at}");
    assert!(cells[1].value >= 5.0 && cells[1].value < plain[1], "{} against {}", cells[1].value, plain[1]);
}

#[test]
fn a_stop_below_the_quasi_periodic_value_or_not_finite_is_refused() {
    for (above, after) in
        [(2.0, 10.0), (1.0, 10.0), (f64::NAN, 10.0), (f64::INFINITY, 10.0), (5.0, -1.0), (5.0, f64::NAN)]
    {
        let e = MegnoStop::new(above, after).expect_err("refused");
        assert!(e.contains("MEGNO stop"), "{e}");
    }
    assert!(MegnoStop::new(2.5, 0.0).is_ok());
}
