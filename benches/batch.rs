//! The Taylor method's batch mode against one start at a time (`harness = false`: prints a
//! table). The measure of BENCHMARKS.md's "Ensembles" rows: double-pendulum starts at rest on
//! an n × n grid of (θ1, θ2) in [−2, 2]², to t = 10, on one thread, thread CPU time, median
//! of interleaved rounds. Both sides run `simulate::ensemble`'s work: the batch through
//! `Taylor::integrate_batch`, the other through `simulate::integrate` per start (what the
//! ensemble did before, and still does for runs the batch cannot take). The results are
//! compared bit for bit before timing.
//!
//! ```text
//! cargo bench --bench batch                 # 32 × 32 at tol 1e-12 and 40 × 40 at 1e-10
//! BATCH_ROUNDS=9 cargo bench --bench batch
//! BATCH_PROFILE=1e-12 cargo bench --bench batch   # that row's batch side alone (for perf)
//! ```

use lagrangian::compile::simd_lanes;
use lagrangian::integrate::{BatchOutput, Taylor};
use lagrangian::mechanics::System;
use lagrangian::simulate::{self, MethodId, RunOptions, Sampling};

fn thread_cpu() -> f64 {
    // CLOCK_THREAD_CPUTIME_ID through /proc is not per thread; the runs below are on this
    // thread alone, so the process's CPU time is the thread's.
    std::fs::read_to_string("/proc/self/stat")
        .ok()
        .and_then(|s| {
            let rest = s.rsplit_once(')')?.1.split_whitespace().collect::<Vec<_>>();
            let (u, st): (f64, f64) = (rest.get(11)?.parse().ok()?, rest.get(12)?.parse().ok()?);
            Some((u + st) / 100.0)
        })
        .unwrap_or(f64::NAN)
}

fn median(mut v: Vec<f64>) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let rounds: usize = std::env::var("BATCH_ROUNDS").ok().and_then(|s| s.parse().ok()).unwrap_or(5);
    let l = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
             + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";
    let sys = System::from_lagrangian(l, &["θ1", "θ2"])
        .unwrap()
        .with_params(&[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)])
        .unwrap();
    let c = simulate::compile_system(&sys, MethodId::Taylor, &[]).unwrap();
    let ode = sys.compile_taylor().unwrap();
    let lanes = simd_lanes();
    println!("lanes: {lanes}; load {}", std::fs::read_to_string("/proc/loadavg").unwrap_or_default().trim());
    println!("| starts | tol | one at a time (ms) | batch (ms) | ratio |");
    println!("|---|---|---|---|---|");
    // Under a profiler: one row's batch side alone, no comparison.
    let profile: Option<f64> = std::env::var("BATCH_PROFILE").ok().and_then(|s| s.parse().ok());
    for (side, tol) in [(32usize, 1e-12), (40, 1e-16), (40, 1e-10), (40, 1e-8), (40, 1e-6)] {
        if profile.is_some_and(|p| p != tol) {
            continue;
        }
        let starts: Vec<Vec<f64>> = (0..side * side)
            .map(|k| {
                let (i, j) = (k / side, k % side);
                let a = |i: usize| -2.0 + 4.0 * i as f64 / (side - 1) as f64;
                vec![a(i), a(j), 0.0, 0.0]
            })
            .collect();
        let refs: Vec<&[f64]> = starts.iter().map(Vec::as_slice).collect();
        let mut o = RunOptions::new(MethodId::Taylor, 0.0, 10.0);
        o.rtol = Some(tol);
        o.sampling = Sampling::Final;
        let single = || -> Vec<Vec<f64>> {
            starts.iter().map(|y0| simulate::integrate(&c, y0, &o, &mut |_| {}).unwrap().y.pop().unwrap()).collect()
        };
        let m = Taylor::new(tol);
        let batch = || -> Vec<Vec<f64>> {
            m.integrate_batch(&ode, lanes, 0.0..10.0, &refs, BatchOutput::Final, usize::MAX, None)
                .unwrap()
                .into_iter()
                .map(|r| r.unwrap().y.pop().unwrap())
                .collect()
        };
        if profile.is_some() {
            // One untimed run of each side first: each compiles its system's native code on
            // first use (the two sides hold different compiled systems).
            std::hint::black_box((batch(), simulate::ensemble(&c, &starts, &o, Some(1), &mut |_| {})));
            let t0 = thread_cpu();
            for _ in 0..rounds {
                std::hint::black_box(batch());
            }
            let ms = (thread_cpu() - t0) * 1e3 / rounds as f64;
            // The ensemble's own path (its driver, trajectories built), for comparison.
            let (t1, wall) = (thread_cpu(), std::time::Instant::now());
            for _ in 0..rounds {
                std::hint::black_box(simulate::ensemble(&c, &starts, &o, Some(1), &mut |_| {}));
            }
            let per = |x: f64| x * 1e3 / rounds as f64;
            println!(
                "simulate::ensemble, threads 1: {:.0} ms CPU (all threads) a round, {:.0} ms wall",
                per(thread_cpu() - t1),
                per(wall.elapsed().as_secs_f64())
            );
            let runs = m.integrate_batch(&ode, lanes, 0.0..10.0, &refs, BatchOutput::Final, usize::MAX, None).unwrap();
            let steps: usize = runs.iter().map(|r| r.as_ref().map_or(0, |r| r.steps)).sum();
            println!(
                "batch side alone, {tol:e}: {ms:.0} ms a round, {steps} steps ({:.0} ns a step)",
                ms * 1e6 / steps as f64
            );
            continue;
        }
        assert_eq!(single(), batch(), "the batch gives the single runs' states");
        let (mut ts, mut tb) = (Vec::new(), Vec::new());
        for _ in 0..rounds {
            let t0 = (thread_cpu(),);
            std::hint::black_box(single());
            ts.push(thread_cpu() - t0.0);
            let t0 = thread_cpu();
            std::hint::black_box(batch());
            tb.push(thread_cpu() - t0);
        }
        let (s, b) = (median(ts) * 1e3, median(tb) * 1e3);
        println!("| {} | {tol:e} | {s:.0} | {b:.0} | {:.2} |", side * side, b / s);
    }
}
