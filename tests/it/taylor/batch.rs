//! The Taylor method's batch mode: many starts expanded together in SIMD lanes, each
//! trajectory bit for bit the one a single run computes (the batch's promise), whatever the
//! lane width and whatever its neighbours do (a regular orbit beside a chaotic one, a
//! collision beside an escape).

use lagrangian::compile::TaylorOde;
use std::sync::atomic::AtomicUsize;

use lagrangian::integrate::{
    BatchOutput, Integrate, IntegrateError, LaneTask, Options, RunState, Solver, Status, Taylor,
};
use lagrangian::mechanics::System;
use lagrangian::simulate::{self, Compiled, MethodId, RunOptions, Sampling, SimulateError, Trajectory};

const DOUBLE_PENDULUM: &str = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
                               + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";

fn double_pendulum() -> System {
    System::from_lagrangian(DOUBLE_PENDULUM, &["θ1", "θ2"])
        .unwrap()
        .with_params(&[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)])
        .unwrap()
}

/// Starts at rest on a grid of angles in [−2, 2]² (regular near the origin, chaotic far from
/// it), and a few with velocities, including a whirling one.
fn starts() -> Vec<Vec<f64>> {
    let mut s = Vec::new();
    for i in 0..5 {
        for j in 0..4 {
            s.push(vec![-2.0 + i as f64, -2.0 + 4.0 * j as f64 / 3.0, 0.0, 0.0]);
        }
    }
    s.push(vec![0.1, -0.1, 0.0, 0.0]);
    s.push(vec![3.0, 3.1, 5.0, -7.0]);
    s.push(vec![0.0, 0.0, 12.0, 0.0]);
    s
}

fn bits(t: &Trajectory) -> (Vec<u64>, Vec<Vec<u64>>, usize, usize) {
    (
        t.t.iter().map(|x| x.to_bits()).collect(),
        t.y.iter().map(|y| y.iter().map(|x| x.to_bits()).collect()).collect(),
        t.steps,
        t.evaluations,
    )
}

fn assert_same(batch: &[Result<Trajectory, SimulateError>], c: &Compiled, starts: &[Vec<f64>], o: &RunOptions) {
    assert_eq!(batch.len(), starts.len());
    for (y0, got) in starts.iter().zip(batch) {
        let alone = simulate::integrate(c, y0, o, &mut |_| {});
        match (got, &alone) {
            (Ok(a), Ok(b)) => {
                assert_eq!(bits(a), bits(b), "start {y0:?}");
                assert!(a.events.is_empty() && a.stopped_by.is_none() && a.aux.is_empty());
            }
            (Err(a), Err(b)) => assert_eq!(a.to_string(), b.to_string(), "start {y0:?}"),
            _ => panic!("start {y0:?}: batch {got:?}, alone {alone:?}"),
        }
    }
}

/// Final states and states on a time grid, at two tolerances the ensemble batches (orders 13 and
/// 18), from the ensemble (batch) and from one run per start: the same bits, steps and
/// expansions.
#[test]
fn ensemble_equals_single_runs_bit_for_bit() {
    let sys = double_pendulum();
    let c = simulate::compile_system(&sys, MethodId::Taylor, &[]).unwrap();
    let starts = starts();
    for tol in [1e-10, 1e-15] {
        let grid: Vec<f64> = (0..=20).map(|k| k as f64 * 0.25).collect();
        for sampling in [Sampling::Final, Sampling::Times(grid)] {
            let mut o = RunOptions::new(MethodId::Taylor, 0.0, 5.0);
            o.rtol = Some(tol);
            o.sampling = sampling;
            let batch = simulate::ensemble(&c, &starts, &o, Some(1), &mut |_| {});
            assert_same(&batch, &c, &starts, &o);
        }
    }
}

/// The batch ran (it is not the one-start-at-a-time fallback), and its results do not depend
/// on the lane width: 2, 4 and 8 lanes give the single run's bits, also backwards in time.
#[test]
fn every_lane_width_gives_the_single_runs_bits() {
    let ode: TaylorOde = double_pendulum().compile_taylor().unwrap();
    let starts = starts();
    let refs: Vec<&[f64]> = starts.iter().map(Vec::as_slice).collect();
    let m = Taylor::new(1e-10);
    for span in [0.0..3.0, 0.0..-3.0] {
        let alone: Vec<Vec<f64>> = starts
            .iter()
            .map(|y0| {
                let tr = m.integrate_with(&ode, span.clone(), y0, Options::new().final_only()).unwrap();
                tr.states[tr.states.len() - 4..].to_vec()
            })
            .collect();
        for lanes in [2, 4, 8] {
            let runs =
                m.integrate_batch(&ode, lanes, span.clone(), &refs, BatchOutput::Final, 1_000_000, None).unwrap();
            for (run, want) in runs.iter().zip(&alone) {
                let run = run.as_ref().expect("no start fails");
                let got = run.y.last().unwrap();
                assert_eq!(
                    got.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                    want.iter().map(|x| x.to_bits()).collect::<Vec<_>>(),
                    "{lanes} lanes"
                );
                assert_eq!(run.t.last().copied(), Some(span.end));
            }
        }
    }
}

/// One lane's failure does not stop the others: an attractive 1/q potential from rest at
/// q = 1 falls into the singularity at t = π/(2√2) ≈ 1.11, while its neighbours with enough
/// energy escape. The failing start reports the single run's error; the others finish.
#[test]
fn a_collision_in_one_lane_leaves_the_others_alone() {
    let sys = System::from_hamiltonian("1/2 p_q^2 - 1/q", &["q"]).unwrap();
    let c = simulate::compile_system(&sys, MethodId::Taylor, &[]).unwrap();
    let starts: Vec<Vec<f64>> = (0..11).map(|k| vec![1.0, if k == 5 { 0.0 } else { 1.5 + 0.1 * k as f64 }]).collect();
    let mut o = RunOptions::new(MethodId::Taylor, 0.0, 2.0);
    o.rtol = Some(1e-12);
    o.sampling = Sampling::Final;
    let batch = simulate::ensemble(&c, &starts, &o, Some(1), &mut |_| {});
    assert_same(&batch, &c, &starts, &o);
    assert!(batch[5].is_err(), "the start at rest collides");
    assert_eq!(batch.iter().filter(|r| r.is_ok()).count(), 10);
}

/// A system with `abs` (whose kink is a per-trajectory failure) is not batched, and the
/// ensemble runs it one start at a time with the same results.
#[test]
fn abs_runs_one_start_at_a_time() {
    let sys = System::from_lagrangian("1/2 x'^2 - abs(x)", &["x"]).unwrap();
    let ode = sys.compile_taylor().unwrap();
    assert!(!ode.batchable());
    let m = Taylor::new(1e-10);
    assert!(m.integrate_batch(&ode, 4, 0.0..1.0, &[&[0.5, 0.0]], BatchOutput::Final, 1000, None).is_none());
    let c = simulate::compile_system(&sys, MethodId::Taylor, &[]).unwrap();
    let starts = vec![vec![0.5, 0.0], vec![1.0, 0.0]];
    let mut o = RunOptions::new(MethodId::Taylor, 0.0, 0.5);
    o.sampling = Sampling::Final;
    let batch = simulate::ensemble(&c, &starts, &o, Some(1), &mut |_| {});
    assert_same(&batch, &c, &starts, &o);
}

/// Final states of `starts` by the batch over `lanes` lanes, as bits (`None`: the start failed).
fn batch_bits(
    ode: &TaylorOde,
    lanes: usize,
    m: &Taylor,
    span: std::ops::Range<f64>,
    starts: &[Vec<f64>],
) -> Vec<Option<Vec<u64>>> {
    let refs: Vec<&[f64]> = starts.iter().map(Vec::as_slice).collect();
    let runs = m.integrate_batch(ode, lanes, span, &refs, BatchOutput::Final, 1_000_000, None).unwrap();
    runs.iter().map(|r| r.as_ref().map(|r| r.y.last().unwrap().iter().map(|x| x.to_bits()).collect())).collect()
}

/// Once native code is on, the batch expands through native code (it is compiled, for the
/// order the run used) and gives the interpreter lanes' bits, which are the single run's, at
/// every lane width: lane pairs at 2 lanes, and at 4 and 8 where the host has no wide code.
#[test]
fn native_lane_pairs_give_the_interpreter_lanes_bits() {
    let plain: TaylorOde = double_pendulum().compile_taylor().unwrap();
    let interpreted = plain.clone().with_native(false);
    let starts = starts();
    let m = Taylor::new(1e-12);
    let want = batch_bits(&interpreted, 8, &m, 0.0..3.0, &starts);
    assert!(want.iter().all(Option::is_some));
    assert!(!interpreted.native_lanes_ran());
    for lanes in [2, 4, 8] {
        let native = plain.clone().with_native(true);
        assert!(!native.native_lanes_ran());
        assert_eq!(batch_bits(&native, lanes, &m, 0.0..3.0, &starts), want, "{lanes} lanes");
        assert_eq!(native.native_lanes_ran(), jit_on(), "{lanes} lanes: native code ran");
        assert_eq!(native.wide_lanes_ran(), wide_expected(lanes), "{lanes} lanes: wide code, else lane pairs");
    }
}

/// A `W` that is symmetric but, in one lane, not positive definite (`W = 2 − x²` at x = 1.8,
/// where the single run factors by LU), among starts of positive `W`: the first eight run on
/// native code once it exists. While the LU start is in a lane (in the second eight), lane-pair
/// code (2 lanes) hands the batch back to the interpreter, and wide code (8 lanes, where the
/// host has it) solves that lane by LU between its orders. Every start gets the single run's
/// bits.
#[test]
fn a_lane_whose_mass_matrix_needs_lu_falls_back_to_the_interpreter() {
    let sys = System::from_lagrangian("1/2 (2 - x^2) x'^2 - 1/2 x^2", &["x"]).unwrap();
    let plain: TaylorOde = sys.compile_taylor().unwrap();
    let starts: Vec<Vec<f64>> = (0..16).map(|i| vec![if i == 12 { 1.8 } else { 0.05 * i as f64 }, 0.01]).collect();
    let m = Taylor::new(1e-12);
    let alone: Vec<Option<Vec<u64>>> = starts
        .iter()
        .map(|y0| {
            let tr = m.integrate_with(&plain, 0.0..0.5, y0, Options::new().final_only()).ok()?;
            Some(tr.states[tr.states.len() - 2..].iter().map(|x| x.to_bits()).collect())
        })
        .collect();
    assert!(alone[12].is_some(), "the LU start integrates alone");
    for lanes in [2, 8] {
        let native = plain.clone().with_native(true);
        for round in 0..3 {
            assert_eq!(batch_bits(&native, lanes, &m, 0.0..0.5, &starts), alone, "{lanes} lanes, round {round}");
        }
        assert_eq!(native.native_lanes_ran(), jit_on(), "{lanes} lanes");
        assert_eq!(native.wide_lanes_ran(), wide_expected(lanes), "{lanes} lanes");
    }
}

/// Whether this host runs batch expansions of `lanes` lanes on wide code: the JIT is on, the
/// host is x86-64 Unix, and its vector registers hold that many lanes (`simd_lanes`: 8 with
/// AVX-512F, 4 with AVX2).
fn wide_expected(lanes: usize) -> bool {
    let host = cfg!(all(target_arch = "x86_64", unix)) && matches!(lanes, 4 | 8);
    jit_on() && host && lagrangian::compile::simd_lanes() >= lanes
}

/// Whether native code is on (the JIT is not switched off by the environment).
fn jit_on() -> bool {
    !std::env::var_os(lagrangian::compile::NO_JIT_ENV).is_some_and(|v| !v.is_empty() && v != "0")
}

/// Wide code (4 lanes per AVX2 register, 8 per AVX-512 register) gives the interpreter lanes'
/// bits for every recurrence: a first-order system with every function, roots, constant and
/// variable powers, quotients and the time, at both widths. Where the host lacks the registers
/// the batch runs on lane pairs and the bits are the same.
#[test]
fn wide_code_gives_the_interpreter_lanes_bits_for_every_operation() {
    let f = [
        "sin(y) cos(x) + tan(x/3) + exp(-x^2) + log(2 + y^2) + atan2(y, 1 + x^2) + erf(x/2) - 1/(2 + z^2)",
        "sinh(x/4) - cosh(y/5) + tanh(x) + asin(x/4) + acos(y/8) + atan(x y) + sqrt(3 + x^2) + asinh(y) \
         + acosh(2 + x^2) + atanh(y/8)",
        "(2 + x^2)^(1/3) + (1 + y^2)^0.7 + (2 + x^2)^(1 + y/3) + t/10 - z + sec(x/3) + csc(1 + y^2/4) \
         + coth(2 + x^2) + (x - 3)^(1/3)",
    ]
    .map(|e| lagrangian::parse(e).unwrap());
    let plain = TaylorOde::from_exprs(&f, &["x", "y", "z"], &[]).unwrap();
    let starts: Vec<Vec<f64>> =
        (0..24).map(|i| vec![-0.5 + i as f64 / 24.0, 0.4 - i as f64 / 30.0, (i % 5) as f64 / 4.0]).collect();
    let m = Taylor::new(1e-12);
    let interpreted = plain.clone().with_native(false);
    let want = batch_bits(&interpreted, 8, &m, 0.0..0.3, &starts);
    assert!(want.iter().all(Option::is_some), "every start integrates");
    for lanes in [4, 8] {
        let native = plain.clone().with_native(true);
        assert_eq!(batch_bits(&native, lanes, &m, 0.0..0.3, &starts), want, "{lanes} lanes");
        assert_eq!(native.wide_lanes_ran(), wide_expected(lanes), "{lanes} lanes: the wide code ran");
    }
}

/// The double pendulum (a `W q'' = F` system, its solve in Rust between the wide code's orders)
/// on wide code at the host's widths, against the interpreter lanes, which are the single runs.
#[test]
fn wide_code_gives_the_interpreter_lanes_bits_for_a_mass_matrix_system() {
    let plain: TaylorOde = double_pendulum().compile_taylor().unwrap();
    let starts = starts();
    let m = Taylor::new(1e-12);
    let want = batch_bits(&plain.clone().with_native(false), 8, &m, 0.0..3.0, &starts);
    for lanes in [4, 8] {
        let native = plain.clone().with_native(true);
        assert_eq!(batch_bits(&native, lanes, &m, 0.0..3.0, &starts), want, "{lanes} lanes");
        assert_eq!(native.wide_lanes_ran(), wide_expected(lanes), "{lanes} lanes: the wide code ran");
        assert_eq!(native.native_lanes_ran(), jit_on(), "{lanes} lanes: native code ran");
    }
}

/// The wide code's encoder against the bytes GNU as 2.40 gives for the same instructions in
/// Intel syntax (`{disp32}` and `{vex3}` asking for the forms the encoder writes):
/// `vaddpd zmm1, zmm2, zmm3`; `vmulpd zmm9, zmm10, [rdi + 0x100]`; `vmovupd zmm12, [rsi + 0x40]`;
/// `vmovupd [rdi + 0x80], zmm15`; `vpxorq zmm8, zmm8, [rsi]`; `vdivpd zmm13, zmm13, zmm11`; and
/// `vsubpd ymm1, ymm2, ymm3`; `vmovupd ymm9, [rdi + 0x20]`; `vxorpd ymm0, ymm0, [rsi + 0x20]`;
/// `vmovupd [rdi + 0x20], ymm12`; `vmulpd ymm10, ymm11, ymm12`; `vzeroupper`; `ret`.
/// What a driver's per-step code reads of one trajectory, as bits: the time, the state, the
/// step before, the dense output (whole and one component) inside the step; every third step
/// it replaces the state (as the chaos maps renormalise) and reads the interpolant again,
/// which is then Hermite's, as a single run's solver does after `set_state`.
fn observe<V: RunState>(run: &mut V, seen: &mut Vec<u64>) {
    let (t, n) = (run.t(), run.y().len());
    let (t0, y0) = run.previous();
    seen.extend([t.to_bits(), t0.to_bits(), run.steps() as u64]);
    seen.extend(y0.iter().chain(run.y()).map(|x| x.to_bits()));
    let mut out = vec![0.0; n];
    let mid = 0.5 * (t0 + t);
    run.interpolate(mid, &mut out).unwrap();
    seen.extend(out.iter().map(|x| x.to_bits()));
    seen.push(run.dense_component(n - 1, 0.3).map_or(0, f64::to_bits));
    if run.steps() % 3 == 0 {
        let y: Vec<f64> = run.y().iter().map(|v| 0.5 * v).collect();
        run.set_state(t, &y);
        assert_eq!(run.dense_component(0, 0.3), None, "no dense output after set_state");
        run.interpolate(mid, &mut out).unwrap();
        seen.extend(out.iter().map(|x| x.to_bits()));
    }
}

/// A task that records [`observe`] after every step, for 12 steps.
struct Observe;

impl LaneTask for Observe {
    type Lane = Vec<u64>;
    type Output = Vec<u64>;
    fn begin<V: RunState>(&self, _: usize, _: &V) -> Result<Vec<u64>, Vec<u64>> {
        Ok(Vec::new())
    }
    fn before_step<V: RunState>(&self, seen: &mut Vec<u64>, run: &V) -> Option<Vec<u64>> {
        (run.steps() == 12).then(|| std::mem::take(seen))
    }
    fn after_step<V: RunState>(
        &self,
        seen: &mut Vec<u64>,
        run: &mut V,
        step: Result<Status, IntegrateError>,
    ) -> Option<Vec<u64>> {
        step.unwrap();
        observe(run, seen);
        None
    }
}

/// A lane of the batch answers the per-step code's questions (state, previous step, dense
/// output, one component, `set_state` and the Hermite interpolant after it) with the bits a
/// single run's `Solver` gives, so the chaos maps' and ensembles' shared per-step code runs the
/// single run's arithmetic on lanes; with compensated summation and a step cap too.
#[test]
fn a_lane_answers_as_a_single_runs_solver() {
    let ode = double_pendulum().compile_taylor().unwrap();
    let starts = starts();
    let refs: Vec<&[f64]> = starts.iter().map(Vec::as_slice).collect();
    for m in [Taylor::new(1e-12), Taylor::new(1e-12).compensated(), Taylor::new(1e-12).with_h_max(0.01)] {
        let queue = AtomicUsize::new(0);
        let lanes = m.integrate_lanes(&ode, 8, 0.0..10.0, &refs, &queue, &Observe, None).unwrap();
        assert_eq!(lanes.len(), starts.len());
        for (index, seen) in lanes {
            let mut solver = Solver::new(&m, &ode, 0.0, &starts[index], 10.0).unwrap();
            let mut alone = Vec::new();
            while solver.steps() < 12 {
                solver.step().unwrap();
                observe(&mut solver, &mut alone);
            }
            assert_eq!(seen, Some(alone), "start {:?}, {m:?}", starts[index]);
        }
    }
}

#[test]
fn the_wide_encoder_writes_the_assemblers_bytes() {
    let [zmm, ymm] = lagrangian::compile::wide_encoding_samples();
    let want_zmm: Vec<u8> = [
        &[0x62, 0xF1, 0xED, 0x48, 0x58, 0xCB][..],
        &[0x62, 0x71, 0xAD, 0x48, 0x59, 0x8F, 0x00, 0x01, 0x00, 0x00],
        &[0x62, 0x71, 0xFD, 0x48, 0x10, 0xA6, 0x40, 0x00, 0x00, 0x00],
        &[0x62, 0x71, 0xFD, 0x48, 0x11, 0xBF, 0x80, 0x00, 0x00, 0x00],
        &[0x62, 0x71, 0xBD, 0x48, 0xEF, 0x86, 0x00, 0x00, 0x00, 0x00],
        &[0x62, 0x51, 0x95, 0x48, 0x5E, 0xEB],
    ]
    .concat();
    let want_ymm: Vec<u8> = [
        &[0xC4, 0xE1, 0x6D, 0x5C, 0xCB][..],
        &[0xC4, 0x61, 0x7D, 0x10, 0x8F, 0x20, 0x00, 0x00, 0x00],
        &[0xC4, 0xE1, 0x7D, 0x57, 0x86, 0x20, 0x00, 0x00, 0x00],
        &[0xC4, 0x61, 0x7D, 0x11, 0xA7, 0x20, 0x00, 0x00, 0x00],
        &[0xC4, 0x41, 0x25, 0x59, 0xD4],
        &[0xC5, 0xF8, 0x77, 0xC3],
    ]
    .concat();
    assert_eq!(zmm, want_zmm);
    assert_eq!(ymm, want_ymm);
}
