//! Compiled right-hand sides against hand-written Rust closures of the same systems, measured
//! in the same run; the batch entry point per point; ensemble throughput on 1 and 2 threads.
//!
//! ```text
//! cargo bench --bench rhs
//! ```

#[path = "../tests/it/support/compile.rs"]
mod compile_common;

use std::hint::black_box;
use std::time::{Duration, Instant};

use compile_common::{benchmark_systems, mass_matrix_split, Rng};
use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use lagrangian::compile::{ensemble_with_threads, CompileOptions, LagrangianRhs, RhsError};
use lagrangian::integrate::Rhs;

/// Minimum time per call over many short alternating rounds of `a` and `b`. The machine is
/// shared, so a slow round is someone else's load; the minimum of interleaved rounds compares
/// the two under the same conditions.
fn paired(calls: usize, mut a: impl FnMut(), mut b: impl FnMut()) -> (f64, f64) {
    let (mut best_a, mut best_b) = (f64::INFINITY, f64::INFINITY);
    for _ in 0..200 {
        let t = Instant::now();
        for _ in 0..calls {
            a();
        }
        best_a = best_a.min(t.elapsed().as_nanos() as f64 / calls as f64);
        let t = Instant::now();
        for _ in 0..calls {
            b();
        }
        best_b = best_b.min(t.elapsed().as_nanos() as f64 / calls as f64);
    }
    (best_a, best_b)
}

/// [`paired`] for three contestants, interleaved the same way.
fn paired3(calls: usize, mut a: impl FnMut(), mut b: impl FnMut(), mut c: impl FnMut()) -> (f64, f64, f64) {
    let mut best = [f64::INFINITY; 3];
    let time = |f: &mut dyn FnMut()| {
        let t = Instant::now();
        f();
        t.elapsed().as_nanos() as f64 / calls as f64
    };
    for _ in 0..200 {
        best[0] = best[0].min(time(&mut || (0..calls).for_each(|_| a())));
        best[1] = best[1].min(time(&mut || (0..calls).for_each(|_| b())));
        best[2] = best[2].min(time(&mut || (0..calls).for_each(|_| c())));
    }
    (best[0], best[1], best[2])
}

/// A benchmark system compiled for the interpreter (the reference back end).
fn interpreted(sys: &compile_common::System) -> LagrangianRhs {
    let (w, f) = mass_matrix_split(&sys.lagrangian, &sys.coords());
    let options = CompileOptions::default().with_native(false);
    LagrangianRhs::with_options(&w, &f, &sys.coords(), &sys.params, &options).expect("benchmark systems compile")
}

fn rhs_calls(c: &mut Criterion) {
    eprintln!(
        "paired minimum ns/call (native, interpreted, hand-written; native/hand, interpreted/hand; ops of the native path):"
    );
    for sys in benchmark_systems() {
        let rhs = sys.compile();
        let int = interpreted(&sys);
        let d = sys.dim();
        let mut rng = Rng(1);
        let y: Vec<f64> = (0..d).map(|_| rng.uniform(0.5, 1.5)).collect();
        let (mut d1, mut d2, mut d3) = (vec![0.0; d], vec![0.0; d], vec![0.0; d]);
        let (a, i, b) = paired3(
            2000,
            || rhs.eval(0.0, black_box(&y), black_box(&mut d1)),
            || int.eval(0.0, black_box(&y), black_box(&mut d2)),
            || (sys.hand)(0.0, black_box(&y), black_box(&mut d3)),
        );
        let ops = match rhs.solve_tape() {
            Some(t) => format!("W, F and unrolled solve: {}", t.op_counts()),
            None => format!("W, F (loop solve): {}", rhs.tape().op_counts()),
        };
        let native = if rhs.tape().is_native() { "native" } else { "NO JIT: interpreted" };
        eprintln!("PAIRED | {} | {a:.1} | {i:.1} | {b:.1} | {:.2} | {:.2} | {native}; {ops}", sys.name, a / b, i / b);
    }

    let mut group = c.benchmark_group("rhs");
    group.measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    for sys in benchmark_systems() {
        let rhs = sys.compile();
        let d = sys.dim();
        let mut rng = Rng(1);
        let y: Vec<f64> = (0..d).map(|_| rng.uniform(0.5, 1.5)).collect();
        let mut dy = vec![0.0; d];
        group.bench_function(BenchmarkId::new("compiled", sys.name), |b| {
            b.iter(|| rhs.eval(0.0, black_box(&y), black_box(&mut dy)))
        });
        let int = interpreted(&sys);
        group.bench_function(BenchmarkId::new("interpreted", sys.name), |b| {
            b.iter(|| int.eval(0.0, black_box(&y), black_box(&mut dy)))
        });
        group.bench_function(BenchmarkId::new("hand-written", sys.name), |b| {
            b.iter(|| (sys.hand)(0.0, black_box(&y), black_box(&mut dy)))
        });
    }
    group.finish();
}

fn batch(c: &mut Criterion) {
    let mut group = c.benchmark_group("batch");
    group.measurement_time(Duration::from_secs(3)).warm_up_time(Duration::from_secs(1));
    let points = 1024;
    for sys in [compile_common::double_pendulum(), compile_common::chain(5)] {
        let rhs = sys.compile();
        let d = sys.dim();
        let mut rng = Rng(2);
        let y: Vec<f64> = (0..d * points).map(|_| rng.uniform(0.5, 1.5)).collect();
        let mut dy = vec![0.0; d * points];
        group.throughput(Throughput::Elements(points as u64));
        group.bench_function(BenchmarkId::new("compiled batch", sys.name), |b| {
            b.iter(|| rhs.eval_batch(0.0, black_box(&y), black_box(&mut dy), points).unwrap())
        });
        let (mut ys, mut dys) = (vec![0.0; d], vec![0.0; d]);
        group.bench_function(BenchmarkId::new("compiled scalar loop", sys.name), |b| {
            b.iter(|| {
                for k in 0..points {
                    (0..d).for_each(|i| ys[i] = y[i * points + k]);
                    rhs.eval(0.0, black_box(&ys), &mut dys);
                    (0..d).for_each(|i| dy[i * points + k] = dys[i]);
                }
            })
        });
        {
            let int = interpreted(&sys);
            let (mut dyb, mut dyi, mut ys2, mut dys2, mut dyh) =
                (vec![0.0; d * points], vec![0.0; d * points], vec![0.0; d], vec![0.0; d], vec![0.0; d]);
            let (b_ns, i_ns, s_ns) = paired3(
                5,
                || rhs.eval_batch(0.0, black_box(&y), black_box(&mut dyb), points).unwrap(),
                || int.eval_batch(0.0, black_box(&y), black_box(&mut dyi), points).unwrap(),
                || {
                    for k in 0..points {
                        (0..d).for_each(|i| ys2[i] = y[i * points + k]);
                        rhs.eval(0.0, black_box(&ys2), &mut dys2);
                    }
                },
            );
            let (_, h_ns) = paired(
                5,
                || {},
                || {
                    for k in 0..points {
                        (0..d).for_each(|i| ys2[i] = y[i * points + k]);
                        (sys.hand)(0.0, black_box(&ys2), &mut dyh);
                    }
                },
            );
            let p = points as f64;
            eprintln!(
                "BATCH | {} | native batch {:.1} ns/point | interpreted batch {:.1} ns/point | native scalar {:.1} ns/point | hand-written scalar {:.1} ns/point",
                sys.name,
                b_ns / p,
                i_ns / p,
                s_ns / p,
                h_ns / p
            );
        }
        let tape = rhs.tape();
        let ni = tape.n_inputs();
        let x: Vec<f64> = (0..ni * points).map(|_| rng.uniform(0.5, 1.5)).collect();
        let mut out = vec![0.0; tape.n_outputs() * points];
        group.bench_function(BenchmarkId::new("tape batch (W, F only)", sys.name), |b| {
            b.iter(|| tape.eval_batch(black_box(&x), black_box(&mut out), points))
        });
    }
    group.finish();
}

/// Classical RK4 with fixed step, written here so the benchmark does not depend on the
/// integrator module.
fn rk4(rhs: &LagrangianRhs, y0: &[f64], h: f64, steps: usize) -> Result<Vec<f64>, RhsError> {
    let mut y = [y0[0], y0[1]];
    let (mut k1, mut k2, mut k3, mut k4, mut tmp) = ([0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2], [0.0; 2]);
    let mut t = 0.0;
    for _ in 0..steps {
        rhs.try_eval(t, &y, &mut k1)?;
        (0..2).for_each(|i| tmp[i] = y[i] + 0.5 * h * k1[i]);
        rhs.try_eval(t + 0.5 * h, &tmp, &mut k2)?;
        (0..2).for_each(|i| tmp[i] = y[i] + 0.5 * h * k2[i]);
        rhs.try_eval(t + 0.5 * h, &tmp, &mut k3)?;
        (0..2).for_each(|i| tmp[i] = y[i] + h * k3[i]);
        rhs.try_eval(t + h, &tmp, &mut k4)?;
        (0..2).for_each(|i| y[i] += h / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]));
        t += h;
    }
    Ok(y.to_vec())
}

fn ensembles(c: &mut Criterion) {
    let mut group = c.benchmark_group("ensemble");
    group.sample_size(10).measurement_time(Duration::from_secs(10)).warm_up_time(Duration::from_secs(1));
    let n = 100_000;
    let rhs = compile_common::pendulum().compile();
    let mut rng = Rng(3);
    let init: Vec<f64> = (0..2 * n).map(|_| rng.uniform(-1.0, 1.0)).collect();
    group.throughput(Throughput::Elements(n as u64));
    for threads in [1, 2] {
        group.bench_function(BenchmarkId::new("pendulum 1e5 x RK4 20 steps, threads", threads), |b| {
            b.iter(|| ensemble_with_threads(threads, &init, 2, |y0| rk4(&rhs, y0, 0.05, 20)).unwrap())
        });
    }
    group.finish();
}

criterion_group!(benches, rhs_calls, batch, ensembles);
criterion_main!(benches);
