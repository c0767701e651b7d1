//! Chaos maps on the Taylor method's batch lanes (`chaos::indicators_map`, `chaos_map_with`,
//! `chaos_map`): every cell's indicators are bit for bit those of its orbit run alone
//! (`chaos::indicators_with`), whatever its neighbours in the lanes do: a regular orbit
//! beside a chaotic one, an orbit stopped early by the MEGNO stop, a collision, a step budget.

use lagrangian::chaos::{
    chaos_map, chaos_map_each, chaos_map_with, indicators, indicators_map, indicators_with, Budget, Indicator,
    Indicators, MegnoStop,
};
use lagrangian::compile::Variational;
use lagrangian::integrate::IntegrateError;
use lagrangian::mechanics::System;
use lagrangian::parse;

const DOUBLE_PENDULUM: &str = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
                               + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";

/// The double pendulum's variational system with `tangents` tangent vectors and MEGNO.
fn double_pendulum(tangents: usize) -> Variational {
    let sys = System::from_lagrangian(DOUBLE_PENDULUM, &["θ1", "θ2"])
        .unwrap()
        .with_params(&[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)])
        .unwrap();
    Variational::of_system(&sys, tangents, true).unwrap()
}

/// A 6 × 6 grid of (θ1, θ2) in [−3, 3]² at rest: regular near the origin, chaotic far out.
fn grid() -> Vec<Vec<f64>> {
    (0..36).map(|k| vec![-3.0 + 1.2 * (k / 6) as f64, -3.0 + 1.2 * (k % 6) as f64, 0.0, 0.0]).collect()
}

/// Everything an orbit reports, as bits.
fn bits(r: &Indicators) -> Vec<u64> {
    let mut v: Vec<u64> = r.lyapunov.iter().map(|x| x.to_bits()).collect();
    v.extend([r.fli, r.megno, r.megno_lyapunov].map(f64::to_bits));
    for s in &r.samples {
        v.extend([s.t, s.lyapunov, s.log_norm, s.megno].map(f64::to_bits));
    }
    v.push(r.steps as u64);
    v.push(r.stopped_at.map_or(u64::MAX, f64::to_bits));
    v
}

fn error_bits(e: &IntegrateError) -> (String, u64, Vec<u64>, usize) {
    (e.reason.to_string(), e.t.to_bits(), e.state.iter().map(|x| x.to_bits()).collect(), e.steps)
}

/// Each cell of `map` against its orbit run alone within `budget`.
fn assert_alone(
    map: &[Result<Indicators, IntegrateError>],
    var: &Variational,
    starts: &[Vec<f64>],
    t_end: f64,
    tol: f64,
    budget: &Budget,
) {
    assert_eq!(map.len(), starts.len());
    for (x0, got) in starts.iter().zip(map) {
        match (got, &indicators_with(var, x0, t_end, tol, budget)) {
            (Ok(a), Ok(b)) => assert_eq!(bits(a), bits(b), "start {x0:?}"),
            (Err(a), Err(b)) => assert_eq!(error_bits(a), error_bits(b), "start {x0:?}"),
            (a, b) => panic!("start {x0:?}: map {a:?}, alone {b:?}"),
        }
    }
}

/// The 6 × 6 map with the early stop (Ȳ ≥ 5 after t = 10) and two tangent vectors (the
/// Lyapunov spectrum's renormalisation as well as MEGNO's quadrature): every cell, stopped or
/// run to the end, regular or chaotic, has its single run's bits, on native batch code
/// and on the interpreter's lanes.
#[test]
fn a_map_in_lanes_equals_its_cells_run_alone_bit_for_bit() {
    let starts = grid();
    let budget = Budget {
        max_steps: usize::MAX,
        deadline: None,
        time_limit: None,
        max_samples: 7,
        megno_stop: Some(MegnoStop::new(5.0, 10.0).unwrap()),
    };
    for native in [true, false] {
        let var = double_pendulum(2).with_native(native);
        let map = indicators_map(&var, &starts, 40.0, 1e-9, &budget);
        assert_eq!(var.taylor().native_lanes_ran(), native, "the lanes ran on native code: {native}");
        assert_alone(&map, &var, &starts, 40.0, 1e-9, &budget);
        let ok: Vec<&Indicators> = map.iter().map(|r| r.as_ref().expect("no orbit fails")).collect();
        let stopped = ok.iter().filter(|r| r.stopped_at.is_some()).count();
        let regular = ok.iter().filter(|r| r.stopped_at.is_none() && r.megno < 2.5).count();
        assert!(stopped >= 10 && regular >= 4, "a mixed map: {stopped} stopped, {regular} regular");
        // The map's cells are the orbits' values.
        let cells = chaos_map_with(&var, &starts, 40.0, 1e-9, Indicator::Megno, &budget);
        for (c, r) in cells.iter().zip(&ok) {
            assert_eq!((c.value.to_bits(), c.stopped_at), (r.megno.to_bits(), r.stopped_at));
        }
    }
}

/// `chaos_map` (each orbit within the default budget of its own) gives each start the value of
/// `indicators` run alone, for every indicator; `chaos_map_each` with the early stop (what
/// Python's `chaos_map(..., megno_stop=)` calls) the value and stop of `indicators_with`.
#[test]
fn chaos_map_equals_indicators_per_start() {
    let var = double_pendulum(1);
    let starts: Vec<Vec<f64>> = grid().into_iter().step_by(3).collect();
    for which in [Indicator::Megno, Indicator::Fli, Indicator::Lyapunov] {
        let map = chaos_map(&var, &starts, 15.0, 1e-10, which);
        for (x0, v) in starts.iter().zip(&map) {
            let alone = indicators(&var, x0, 15.0, 1e-10).unwrap().value(which);
            assert_eq!(v.to_bits(), alone.to_bits(), "{which:?} at {x0:?}");
        }
    }
    let budget = Budget { megno_stop: Some(MegnoStop::new(5.0, 10.0).unwrap()), ..Budget::default() };
    let cells = chaos_map_each(&var, &starts, 30.0, 1e-10, Indicator::Megno, &budget);
    for (x0, c) in starts.iter().zip(&cells) {
        let alone = indicators_with(&var, x0, 30.0, 1e-10, &budget).unwrap();
        assert_eq!((c.value.to_bits(), c.stopped_at), (alone.megno.to_bits(), alone.stopped_at), "{x0:?}");
    }
    assert!(cells.iter().any(|c| c.stopped_at.is_some()) && cells.iter().any(|c| c.stopped_at.is_none()));
}

/// One lane's failure leaves the other lanes' values as they are alone: in the attractive
/// `1/q` potential the start at rest falls into the singularity at t = π/(2√2) ≈ 1.11 while its
/// neighbours escape; the failing cell reports its single run's error (NaN in the map), the
/// others their single runs' bits. A step budget that ends some orbits and not others does
/// the same.
#[test]
fn a_failing_lane_leaves_the_others_unchanged() {
    let h = parse("1/2 p^2 - 1/q").unwrap();
    let var = Variational::hamiltonian(&h, &["q"], &["p"], &[], 1, true).unwrap().with_native(true);
    let starts: Vec<Vec<f64>> = (0..11).map(|k| vec![1.0, if k == 5 { 0.0 } else { 1.5 + 0.1 * k as f64 }]).collect();
    let budget = Budget { max_steps: usize::MAX, deadline: None, time_limit: None, max_samples: 5, megno_stop: None };
    let map = indicators_map(&var, &starts, 2.0, 1e-12, &budget);
    assert!(var.taylor().native_lanes_ran());
    assert_alone(&map, &var, &starts, 2.0, 1e-12, &budget);
    assert!(map[5].is_err(), "the start at rest collides");
    assert_eq!(map.iter().filter(|r| r.is_ok()).count(), 10);
    let cells = chaos_map_with(&var, &starts, 2.0, 1e-12, Indicator::Megno, &budget);
    assert!(cells[5].value.is_nan() && cells.iter().filter(|c| c.value.is_finite()).count() == 10);

    // A step budget between the regular and the chaotic orbits' needs.
    let dp = double_pendulum(1);
    let starts = grid();
    let free = Budget { max_steps: usize::MAX, ..budget };
    let steps: Vec<usize> =
        indicators_map(&dp, &starts, 20.0, 1e-9, &free).iter().map(|r| r.as_ref().unwrap().steps).collect();
    let (least, most) = (steps.iter().min().unwrap(), steps.iter().max().unwrap());
    assert!(least < most);
    let limited = Budget { max_steps: (least + most) / 2, ..budget };
    let map = indicators_map(&dp, &starts, 20.0, 1e-9, &limited);
    assert_alone(&map, &dp, &starts, 20.0, 1e-9, &limited);
    let over = map.iter().filter(|r| r.is_err()).count();
    assert!(over > 0 && over < starts.len(), "{over} of {} ran out of steps", starts.len());
    assert!(map.iter().flatten().all(|r| r.steps <= limited.max_steps));
}
