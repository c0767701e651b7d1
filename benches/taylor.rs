//! The Taylor method and the chaos indicators (`harness = false`: prints the tables behind
//! the Taylor section of BENCHMARKS.md). Run next to heyoka by `scripts/bench_taylor.sh`.
//! Times are this thread's CPU time, best of several runs (see `cpu_now`), except the chaos
//! map's, which runs on every thread and is wall time.
//!
//! ```text
//! cargo bench --bench taylor                    # everything (~1 minute on 2 cores)
//! cargo bench --bench taylor -- kepler          # one section: kepler, double-pendulum,
//!                                               #   step-profile, cold-start, large-tapes,
//!                                               #   compact-size, chaos-map, dp-split
//! ```
//!
//! Every system is compiled from text (the library's own path), not hand-written.

use std::f64::consts::PI;
use std::time::Instant;

use lagrangian::chaos::{chaos_map, Indicator};
use lagrangian::compile::{TaylorOde, Variational};
use lagrangian::integrate::problems::{DoublePendulum, Kepler};
use lagrangian::integrate::{Dop853, Integrate, Method, Options, Rhs, Status, Taylor, TaylorSystem};
use lagrangian::mechanics::System;

#[path = "../tests/it/support/n_link.rs"]
mod n_link;
use n_link::unit_n_link_system;

/// This thread's CPU time in seconds. On the shared 2-core machine (load 10–18 while six
/// engineers build) wall time counts other processes' time slices, and a long loop is
/// preempted more often than a short one; the thread's CPU time counts only its own work.
fn cpu_now() -> f64 {
    let mut ts = libc::timespec { tv_sec: 0, tv_nsec: 0 };
    // SAFETY: `ts` is a valid, writable timespec; the clock id is a constant Linux knows.
    unsafe { libc::clock_gettime(libc::CLOCK_THREAD_CPUTIME_ID, &mut ts) };
    ts.tv_sec as f64 + ts.tv_nsec as f64 * 1e-9
}

/// The minimum CPU time (see [`cpu_now`]) of `reps` runs of `f`, and its last result.
fn best<R>(reps: usize, mut f: impl FnMut() -> R) -> (f64, R) {
    let mut t = f64::INFINITY;
    let mut r = None;
    for _ in 0..reps {
        let t0 = cpu_now();
        r = Some(f());
        t = t.min(cpu_now() - t0);
    }
    (t, r.expect("at least one repeat"))
}

/// Kepler e = 0.9 over 1000 orbits from `y0`, the state sampled at the end of each orbit
/// from the step's dense output (as heyoka's `propagate_grid`): the largest relative energy
/// error over the samples, and the steps. Stopping a step at each orbit's end instead puts
/// the steps at the same phases in every orbit, so their truncation errors add up orbit after
/// orbit: 20× the error at tol 1e-13 (BENCHMARKS.md, ninth session).
fn kepler_orbits_from<S: ?Sized, M: Method<S>>(method: &M, sys: &S, y0: &[f64]) -> (f64, usize) {
    let e0 = Kepler.energy(y0);
    let orbits = 1000;
    let mut solver = method.solver(sys, 0.0, y0, 2.0 * PI * orbits as f64).expect("valid start");
    let (mut worst, mut k, mut y) = (0.0f64, 1, [0.0; 4]);
    loop {
        let status = solver.step().expect("Kepler integrates");
        while k <= orbits && 2.0 * PI * k as f64 <= solver.t() {
            solver.interpolate(2.0 * PI * k as f64, &mut y).expect("dense output");
            worst = worst.max(((Kepler.energy(&y) - e0) / e0).abs());
            k += 1;
        }
        if status == Status::Finished {
            return (worst, solver.steps());
        }
    }
}

/// [`kepler_orbits_from`] the pericentre.
fn kepler_orbits<S: ?Sized, M: Method<S>>(method: &M, sys: &S) -> (f64, usize) {
    kepler_orbits_from(method, sys, &Kepler::pericentre(0.9))
}

/// How many starts [`kepler_error_spread`] runs (odd, for a median).
const KEPLER_STARTS: u64 = 11;

/// The largest energy error of one run is a single sample of rounding noise: a change of the
/// step size in its tenth digit moves it by a factor 4. So the error reported is the median
/// (and range) over [`KEPLER_STARTS`] runs from the pericentre with `x₀` moved by 0, 1, 2, …
/// units in the last place, each error relative to its own start's energy.
/// `scripts/bench_taylor_heyoka.py` runs heyoka from the same starts.
fn kepler_error_spread<S: ?Sized, M: Method<S>>(method: &M, sys: &S) -> (f64, f64, f64) {
    let mut errs: Vec<f64> = (0..KEPLER_STARTS)
        .map(|j| {
            let mut y0 = Kepler::pericentre(0.9);
            y0[0] = f64::from_bits(y0[0].to_bits() + j);
            kepler_orbits_from(method, sys, &y0).0
        })
        .collect();
    errs.sort_by(f64::total_cmp);
    (errs[errs.len() / 2], errs[0], errs[errs.len() - 1])
}

fn kepler() {
    println!("## Kepler e = 0.9, 1000 orbits, sampled once per orbit (H = |p|²/2 − 1/|q|, compiled)");
    println!(
        "Time: best of 3 from the pericentre. Error: max relative energy error over the samples, median [range] over {KEPLER_STARTS} starts x₀ + j ulp."
    );
    let sys = System::from_hamiltonian("1/2 (p_x^2 + p_y^2) - 1/sqrt(x^2 + y^2)", &["x", "y"]).expect("valid H");
    let ode = sys.compile_taylor().expect("compiles").with_native(true);
    let rhs = sys.compile_hamiltonian().expect("compiles");
    println!("| method | time | max rel. energy error, median [range] | steps |");
    println!("|---|---|---|---|");
    let interp = ode.clone().with_native(false);
    let spread = |(med, lo, hi): (f64, f64, f64)| format!("{med:.2e} [{lo:.1e}, {hi:.1e}]");
    for (name, m) in [
        ("Taylor tol 1e-15", Taylor::new(1e-15)),
        ("Taylor tol 1e-15 compensated", Taylor::new(1e-15).compensated()),
        ("Taylor tol 1e-14", Taylor::new(1e-14)),
        ("Taylor tol 1e-13", Taylor::new(1e-13)),
    ] {
        let p = m.taylor_order();
        let t0 = Instant::now();
        let native = ode.native_for(p).is_some();
        let compile = t0.elapsed().as_secs_f64();
        let (t, (_, steps)) = best(3, || kepler_orbits(&m, &ode));
        let err = spread(kepler_error_spread(&m, &ode));
        println!(
            "| {name} (order {p}), {} | {:.1} ms | {err} | {steps} |",
            if native { format!("native ({:.1} ms to compile)", compile * 1e3) } else { "interpreted".into() },
            t * 1e3
        );
        // The interpreter gives the native code's bits (tests/it/taylor/native.rs): same errors.
        let (t, (_, steps)) = best(3, || kepler_orbits(&m, &interp));
        println!("| {name} (order {p}), interpreted | {:.1} ms | (as native) | {steps} |", t * 1e3);
    }
    // DOP853 refuses tolerances below Hairer's floor 10·ε; it runs at the floor.
    let m = Dop853::new(Dop853::MIN_RTOL, Dop853::MIN_RTOL).compensated();
    let (t, (err, steps)) = best(1, || kepler_orbits(&m, &rhs));
    println!("| DOP853 tol 10ε (its floor) compensated | {:.1} ms | {err:.2e} (one start) | {steps} |", t * 1e3);
}

/// The double pendulum of `shared/reference/double_pendulum.md`, from its Lagrangian.
fn double_pendulum_system() -> System {
    let l = "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
             + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)";
    System::from_lagrangian(l, &["θ1", "θ2"])
        .and_then(|s| s.with_params(&[("m1", 1.0), ("m2", 1.0), ("l1", 1.0), ("l2", 1.0), ("g", 9.81)]))
        .expect("valid L")
}

fn double_pendulum() {
    println!("## Double pendulum to t = 10 against the 50-digit reference (compiled from L)");
    let sys = double_pendulum_system();
    let ode = sys.compile_taylor().expect("compiles").with_native(true);
    let rhs = sys.compile_rhs().expect("compiles");
    let err = |y: &[f64]| (0..4).map(|i| (y[i] - DoublePendulum::REFERENCE_T10[i]).abs()).fold(0.0, f64::max);
    let interp = ode.clone().with_native(false);
    println!(
        "| tol | Taylor time | Taylor error | Taylor steps | interpreted Taylor time | DOP853 (compensated) time | DOP853 error |"
    );
    println!("|---|---|---|---|---|---|---|");
    for tol in [1e-6, 1e-8, 1e-10, 1e-12, 1e-14, 1e-15, 1e-16] {
        let run_t = |m: &Taylor, o: &TaylorOde| {
            m.integrate_with(o, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only())
        };
        let tm = Taylor::new(tol).compensated();
        // Compiled before timing (a run this short would otherwise pay for it in its first
        // repeat); the compile time is printed.
        let t0 = Instant::now();
        let native = ode.native_for(tm.taylor_order()).is_some();
        let compile = t0.elapsed().as_secs_f64();
        let (tt, tr) = best(5, || run_t(&tm, &ode).expect("integrates"));
        let (ti, _) = best(5, || run_t(&tm, &interp).expect("integrates"));
        let dtol = tol.max(Dop853::MIN_RTOL);
        let dm = Dop853::new(dtol, dtol).compensated();
        let (td, dr) = best(5, || {
            dm.integrate_with(&rhs, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only()).expect("integrates")
        });
        println!(
            "| {tol:.0e} | {:.3} ms{} | {:.1e} | {} | {:.3} ms | {:.3} ms | {:.1e} |",
            tt * 1e3,
            if native { format!(" (native, {:.1} ms to compile)", compile * 1e3) } else { " (interpreted)".into() },
            err(tr.last_state()),
            tr.stats.steps,
            ti * 1e3,
            td * 1e3,
            err(dr.last_state())
        );
    }
}

/// Where one step's time goes: the whole step (from a run), the expansion alone (the
/// recurrences, order 0 and the glue), and order 0 alone (an order-1 expansion), for the
/// native and the interpreted recurrences. The rest of a step is the Jorba–Zou step size,
/// the Horner sums of the update and the solver's bookkeeping.
fn profile_one(name: &str, ode: &TaylorOde, y: &[f64], p: usize, step_ns: &dyn Fn(&TaylorOde) -> f64) {
    let interp = ode.clone().with_native(false);
    let ode = &ode.clone().with_native(true);
    let native = ode.native_for(p).is_some();
    let per_call = |o: &TaylorOde, order: usize| {
        let mut scratch = vec![0.0; o.scratch_len(order)];
        let mut coeffs = vec![0.0; o.dim() * (order + 1)];
        let reps = 20_000;
        let (t, _) = best(3, || {
            for _ in 0..reps {
                o.expand(0.0, std::hint::black_box(y), order, &mut scratch, &mut coeffs).expect("expands");
            }
        });
        t / reps as f64 * 1e9
    };
    let (sn, si) = (step_ns(ode), step_ns(&interp));
    let (en, ei) = (per_call(ode, p), per_call(&interp, p));
    let o0 = per_call(&interp, 1);
    println!(
        "| {name}, order {p} | {sn:.0} ns | {en:.0} ns ({:.0} %) | {:.0} ns | {si:.0} ns | {ei:.0} ns ({:.0} %) | {o0:.0} ns |{}",
        100.0 * en / sn,
        sn - en,
        100.0 * ei / si,
        if native { "" } else { " (no native code)" }
    );
}

fn step_profile() {
    println!("## Where a Taylor step goes (ns per step; expansion = all coefficients of one step)");
    println!("| system | native: step | native: expansion (share) | native: rest of the step | interpreted: step | interpreted: expansion (share) | order 0 + glue |");
    println!("|---|---|---|---|---|---|---|");
    let sys = System::from_hamiltonian("1/2 (p_x^2 + p_y^2) - 1/sqrt(x^2 + y^2)", &["x", "y"]).expect("valid H");
    let ode = sys.compile_taylor().expect("compiles");
    let m = Taylor::new(1e-15);
    let kepler_step = |o: &TaylorOde| {
        let (t, (_, steps)) = best(3, || kepler_orbits(&m, o));
        t / steps as f64 * 1e9
    };
    profile_one("Kepler e = 0.9, tol 1e-15", &ode, &Kepler::pericentre(0.9), m.taylor_order(), &kepler_step);
    let sys = double_pendulum_system();
    let ode = sys.compile_taylor().expect("compiles");
    let m = Taylor::new(1e-12).compensated();
    let dp_step = |o: &TaylorOde| {
        let run = || m.integrate_with(o, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only());
        let (t, r) = best(20, || run().expect("integrates"));
        t / r.stats.steps as f64 * 1e9
    };
    profile_one("double pendulum, tol 1e-12", &ode, &DoublePendulum::Y0, m.taylor_order(), &dp_step);
}

/// The double pendulum's step at loose tolerances, split as in BENCHMARKS.md: the whole
/// step (a run to t = 10 over its steps), the expansion alone (`expand_in_place` at the start
/// state, as a step calls it) and the rest (step size, update, solver), ns per step, median of
/// `DP_ROUNDS` (default 5) rounds of best-of-5. `DP_LOOP=n` instead runs the tol `DP_TOL`
/// (default 1e-6) case `n` times and prints nothing else: a target for `perf record`.
fn dp_split() {
    let sys = double_pendulum_system();
    let ode = sys.compile_taylor().expect("compiles").with_native(true);
    if let Some(n) = std::env::var("DP_LOOP").ok().and_then(|s| s.parse::<usize>().ok()) {
        let tol: f64 = std::env::var("DP_TOL").ok().and_then(|s| s.parse().ok()).unwrap_or(1e-6);
        let m = Taylor::new(tol).compensated();
        ode.native_for(m.taylor_order());
        let t0 = cpu_now();
        let mut steps = 0;
        for _ in 0..n {
            let r = m.integrate_with(&ode, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only());
            steps += r.expect("integrates").stats.steps;
        }
        println!("tol {tol:e}: {:.1} ns per step", (cpu_now() - t0) / steps as f64 * 1e9);
        return;
    }
    let rounds: usize = std::env::var("DP_ROUNDS").ok().and_then(|s| s.parse().ok()).unwrap_or(5);
    println!("## Double pendulum step split (ns per step, CPU time, median of {rounds} rounds)");
    println!("| tol (order) | whole step | expansion | rest of the step | steps |");
    println!("|---|---|---|---|---|");
    let median = |mut v: Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    for tol in [1e-6, 1e-8, 1e-10, 1e-12] {
        let m = Taylor::new(tol).compensated();
        let p = m.taylor_order();
        ode.native_for(p);
        let run = || m.integrate_with(&ode, 0.0..10.0, &DoublePendulum::Y0, Options::new().final_only());
        let steps = run().expect("integrates").stats.steps;
        let mut buf = vec![0.0; ode.scratch_len(p)];
        let (mut whole, mut exp) = (Vec::new(), Vec::new());
        for _ in 0..rounds {
            let (t, _) = best(5, || run().expect("integrates"));
            whole.push(t / steps as f64 * 1e9);
            let reps = 20_000;
            let (t, _) = best(5, || {
                for _ in 0..reps {
                    ode.expand_in_place(0.0, std::hint::black_box(&DoublePendulum::Y0), p, &mut buf).expect("expands");
                }
            });
            exp.push(t / reps as f64 * 1e9);
        }
        let (w, e) = (median(whole), median(exp));
        println!("| {tol:.0e} ({p}) | {w:.0} | {e:.0} | {:.0} | {steps} |", w - e);
    }
}

fn cold_start() {
    println!("## Cold start: text → W, F → Taylor tape → trajectory to t = 1 (tol 1e-12), n-link pendulum, CPU time");
    println!(
        "| n | text → Taylor form | of which W, F (timed again separately) | integrate | total | Taylor rows | steps |"
    );
    println!("|---|---|---|---|---|---|---|");
    for n in [2, 10, 20] {
        let (w0, t0) = (Instant::now(), cpu_now());
        let sys = unit_n_link_system(n);
        let ode: TaylorOde = sys.compile_taylor().expect("compiles");
        let t1 = cpu_now();
        let mut y0 = vec![0.0; 2 * n];
        y0[..n].iter_mut().enumerate().for_each(|(i, q)| *q = 0.5 + 0.1 * i as f64);
        let tr = Taylor::new(1e-12).integrate_with(&ode, 0.0..1.0, &y0, Options::new().final_only()).expect("runs");
        let (t2, w2) = (cpu_now(), Instant::now());
        let (wf, _) = best(1, || sys.mass_matrix_split().expect("derives"));
        println!(
            "| {n} | {:.1} ms | {:.1} ms | {:.1} ms | {:.1} ms ({:.1} ms wall) | {} | {} |",
            (t1 - t0) * 1e3,
            wf * 1e3,
            (t2 - t1) * 1e3,
            (t2 - t0) * 1e3,
            (w2 - w0).as_secs_f64() * 1e3,
            ode.taylor_tape().n_rows(),
            tr.stats.steps
        );
    }
}

/// Large tapes through the default tiers: one expansion interpreted, on the compact code a
/// run reaches after `COMPACT_AFTER_EXPANSIONS` expansions, and on the final code
/// (`native_for`, unrolled where the tape allows); with each code's compile time.
fn large_tapes() {
    println!("## Large Taylor tapes: ns per expansion (CPU time) and compile time, by code");
    println!(
        "| system, order | recurrences | unrolled terms | interpreted | compact (compile) | final code (compile) | compact / interpreted | final / compact |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let var = Variational::of_system(&double_pendulum_system(), 1, true).expect("compiles");
    let mut cases = vec![(
        "double pendulum + tangent + MEGNO (chaos map), tol 1e-9".to_string(),
        var.taylor().clone(),
        var.initial_state(&[1.0, 2.0, 0.0, 0.0]),
        Taylor::new(1e-9).taylor_order(),
    )];
    for n in [3, 5, 10, 20] {
        let ode = unit_n_link_system(n).compile_taylor().expect("compiles");
        let mut y0 = vec![0.0; 2 * n];
        y0[..n].iter_mut().enumerate().for_each(|(i, q)| *q = 0.5 + 0.1 * i as f64);
        cases.push((format!("{n}-link pendulum, tol 1e-15"), ode, y0, Taylor::new(1e-15).taylor_order()));
    }
    for (name, ode, y0, p) in cases {
        let per_expansion = |o: &TaylorOde| {
            let mut scratch = vec![0.0; o.scratch_len(p)];
            let mut coeffs = vec![0.0; o.dim() * (p + 1)];
            let reps = if o.dim() > 20 { 200 } else { 2000 };
            let (t, _) = best(5, || {
                for _ in 0..reps {
                    o.expand(0.0, std::hint::black_box(&y0), p, &mut scratch, &mut coeffs).expect("expands");
                }
            });
            t / reps as f64 * 1e9
        };
        let interp = per_expansion(&ode.clone().with_native(false));
        let tiered = ode.clone();
        let mut scratch = vec![0.0; ode.scratch_len(p)];
        let mut coeffs = vec![0.0; ode.dim() * (p + 1)];
        for _ in 0..=lagrangian::compile::COMPACT_AFTER_EXPANSIONS {
            tiered.expand(0.0, &y0, p, &mut scratch, &mut coeffs).expect("expands");
        }
        // A tape past `MAX_COMPACT_RECURRENCES` has no compact code and stays interpreted.
        let on_compact = tiered.native_compiled(p).is_some_and(|c| c.is_compact());
        let compact = on_compact.then(|| per_expansion(&tiered));
        let (compact_ms, _) = best(3, || ode.taylor_tape().compile_native_compact(p + 1, p - 1));
        let (final_ms, code) = best(1, || tiered.native_for(p));
        let final_ns = per_expansion(&tiered);
        let form = match &code {
            Some(c) if c.is_whole() => "whole unrolled",
            Some(c) if c.is_compact() => "compact",
            Some(_) => "unrolled per order",
            None => "interpreted",
        };
        let (compact_cell, vs_interp, final_vs) = match compact {
            Some(c) => (
                format!("{c:.0} ({:.1} ms)", compact_ms * 1e3),
                format!("{:.2}", c / interp),
                format!("{:.2}", final_ns / c),
            ),
            None => ("none (too many recurrences)".into(), "—".into(), "—".into()),
        };
        println!(
            "| {name}, order {p} | {} | {} | {interp:.0} | {compact_cell} | {final_ns:.0}, {form} ({:.0} ms) | {vs_interp} | {final_vs} |",
            ode.taylor_tape().n_recurrences(),
            ode.taylor_tape().n_recurrences() * (p - 1) * (p - 1) / 2,
            final_ms * 1e3,
        );
    }
}

/// Where compact code stops paying: the recurrences alone (a `TaylorTape` expansion, no solve)
/// interpreted and as compact code, for n-link pendulums of growing size, at orders 11 and 19.
/// The inputs' series are fixed smooth values; only the time per expansion matters here.
fn compact_size() {
    println!("## Compact code against the interpreter by tape size (recurrences alone, µs per expansion, CPU time)");
    println!("| n-link | recurrences | order | coefficients | interpreted | compact | compact / interpreted |");
    println!("|---|---|---|---|---|---|---|");
    for n in [5, 8, 10, 12, 14, 16, 18, 20] {
        let ode = unit_n_link_system(n).compile_taylor().expect("compiles");
        let tt = ode.taylor_tape();
        for p in [11, 19] {
            let s = p + 1;
            let inputs = |k: usize, c: &mut [f64]| {
                for i in 0..tt.n_inputs() {
                    c[i * s + k] = if k == 0 { 0.3 + 0.01 * i as f64 } else { 0.1 / (k + i) as f64 };
                }
            };
            let code = tt.compile_native_compact(s, p).expect("compact code");
            let mut c = vec![0.0; tt.n_rows() * s];
            let mut per_expansion = |code: Option<&lagrangian::compile::TaylorNative>| {
                let reps = 100;
                let (t, _) = best(5, || {
                    for _ in 0..reps {
                        tt.expand_with(code, &mut c, s, p, inputs).expect("expands");
                    }
                });
                t / reps as f64 * 1e6
            };
            let (ti, tc) = (per_expansion(None), per_expansion(Some(&code)));
            println!(
                "| {n} | {} | {p} | {} KB | {ti:.1} | {tc:.1} | {:.2} |",
                tt.n_recurrences(),
                tt.n_rows() * s * 8 / 1024,
                tc / ti
            );
        }
    }
}

fn chaos() {
    let k: usize = std::env::var("CHAOS_GRID").ok().and_then(|s| s.parse().ok()).unwrap_or(8);
    println!("## Chaos map: double pendulum MEGNO over (θ1, θ2) at rest, {k} × {k} grid, t = 100, tol 1e-9, rayon");
    let sys = double_pendulum_system();
    let var = Variational::of_system(&sys, 1, true).expect("compiles");
    let starts: Vec<Vec<f64>> = (0..k * k)
        .map(|i| {
            let (a, b) = (i / k, i % k);
            let th = |j: usize| -PI + (j as f64 + 0.5) * 2.0 * PI / k as f64;
            vec![th(a), th(b), 0.0, 0.0]
        })
        .collect();
    let t0 = Instant::now();
    let map = chaos_map(&var, &starts, 100.0, 1e-9, Indicator::Megno);
    let secs = t0.elapsed().as_secs_f64();
    let failed = map.iter().filter(|v| v.is_nan()).count();
    println!(
        "{} points in {:.2} s on {} threads: {:.1} points/s ({} failed); 200 × 200 at this rate: {:.0} s",
        k * k,
        secs,
        rayon::current_num_threads(),
        (k * k) as f64 / secs,
        failed,
        40000.0 * secs / (k * k) as f64
    );
    let regular = map.iter().filter(|v| **v < 2.5).count();
    println!(
        "MEGNO < 2.5 (regular) at {regular} of {} points; max {:.1}",
        k * k,
        map.iter().cloned().fold(0.0, f64::max)
    );
    let _ = (var.dim(), TaylorSystem::dim(&var), Rhs::dim(&var));
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).filter(|a| !a.starts_with('-')).collect();
    let want = |s: &str| args.is_empty() || args.iter().any(|a| a == s);
    if want("kepler") {
        kepler();
    }
    if want("double-pendulum") {
        double_pendulum();
    }
    if want("step-profile") {
        step_profile();
    }
    if want("dp-split") {
        dp_split();
    }
    if want("cold-start") {
        cold_start();
    }
    if want("large-tapes") {
        large_tapes();
    }
    if want("compact-size") {
        compact_size();
    }
    if want("chaos-map") {
        chaos();
    }
}
