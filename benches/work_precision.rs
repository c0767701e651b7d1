//! Work-precision diagrams and long runs of the integrators (`harness = false`: prints the
//! tables behind BENCHMARKS.md and writes SVG plots to `benches/plots/`).
//!
//! ```text
//! cargo bench --bench work_precision              # everything (~2 minutes on 2 cores)
//! cargo bench --bench work_precision -- quick     # work-precision only, fewer repeats
//! cargo bench --bench work_precision -- double-pendulum   # only the double-pendulum diagram
//! ```
//!
//! Every right-hand side here is hand-written (`lagrangian::integrate::problems`): these tables
//! compare the integrators with each other. What users run — text → `System` → compiled
//! right-hand side → integrator — is `benches/pipeline.rs`; other software is measured in the
//! same run as that by `benches/anchors/run.sh`. No figure of other software is typed in here.

use std::fmt::Write as _;
use std::time::{Duration, Instant};

use lagrangian::integrate::problems::{DoublePendulum, Kepler, Pendulum};
use lagrangian::integrate::{
    Dop853, ExplicitRk, Gauss, Integrate, IntegrateError, Method, Options, Rhs, Splitting, Status,
};
use plotters::prelude::*;

type Run<'a> = Box<dyn Fn(f64) -> Result<Vec<f64>, IntegrateError> + 'a>;

/// One method on one problem: a parameter sweep (steps per unit time, or a tolerance).
struct Series<'a> {
    name: &'static str,
    params: Vec<f64>,
    run: Run<'a>,
}

#[derive(Clone)]
struct Point {
    method: &'static str,
    param: f64,
    secs: f64,
    err: f64,
}

/// Wall time of `f`: the minimum over repeats totalling at least `budget` (at most 20).
fn time<R>(budget: Duration, f: impl Fn() -> R) -> (f64, R) {
    let t0 = Instant::now();
    let r = f();
    let mut best = t0.elapsed();
    let reps = if best >= budget { 0 } else { ((budget.as_secs_f64() / best.as_secs_f64()) as usize).min(19) };
    for _ in 0..reps {
        let t0 = Instant::now();
        std::hint::black_box(f());
        best = best.min(t0.elapsed());
    }
    (best.as_secs_f64(), r)
}

fn max_err(a: &[f64], b: &[f64]) -> f64 {
    a.iter().zip(b).map(|(x, y)| (x - y).abs()).fold(0.0, f64::max)
}

fn fixed<'a, S: ?Sized, M: Method<S> + 'a>(
    name: &'static str,
    make: impl Fn(f64) -> M + 'a,
    sys: &'a S,
    t1: f64,
    y0: &'a [f64],
    steps: &[f64],
) -> Series<'a> {
    Series {
        name,
        params: steps.to_vec(),
        run: Box::new(move |n| {
            let m = make(t1 / n);
            m.integrate_with(sys, 0.0..t1, y0, Options::new().final_only()).map(|tr| tr.last_state().to_vec())
        }),
    }
}

fn dop<'a, S: Rhs + ?Sized>(sys: &'a S, t1: f64, y0: &'a [f64], tols: &[f64]) -> Series<'a> {
    Series {
        name: "DOP853",
        params: tols.to_vec(),
        run: Box::new(move |tol| {
            Dop853::new(tol, tol)
                .integrate_with(sys, 0.0..t1, y0, Options::new().final_only())
                .map(|tr| tr.last_state().to_vec())
        }),
    }
}

fn geometric(from: f64, to: f64, per_decade: usize) -> Vec<f64> {
    let n = ((to / from).log10() * per_decade as f64).round() as usize;
    (0..=n).map(|i| (from * 10f64.powf(i as f64 / per_decade as f64)).round()).collect()
}

/// Runs every series; stops a sweep when the error reaches round-off or a run takes > 1 s.
fn sweep(problem: &str, exact: &[f64], series: &[Series<'_>], budget: Duration) -> Vec<Point> {
    let mut points = Vec::new();
    println!("\n## {problem}\n");
    println!("| method | steps or tol | time | final error |");
    println!("|---|---|---|---|");
    for s in series {
        for &p in &s.params {
            let (secs, r) = time(budget, || (s.run)(p));
            match r {
                Ok(y) => {
                    let err = max_err(&y, exact);
                    println!("| {} | {p:.3e} | {} | {err:.2e} |", s.name, fmt_time(secs));
                    let prev = points.last().filter(|q: &&Point| q.method == s.name).map(|q| q.err);
                    points.push(Point { method: s.name, param: p, secs, err });
                    // Stop at round-off: tiny error, or no more progress below 1e-10.
                    let stalled = prev.is_some_and(|e| e < 1e-10 && err > 0.5 * e);
                    if err < 1e-14 || stalled || secs > 1.0 {
                        break;
                    }
                }
                Err(e) => println!("| {} | {p:.3e} | {} | failed: {} |", s.name, fmt_time(secs), e.reason),
            }
        }
    }
    points
}

fn fmt_time(s: f64) -> String {
    if s < 1e-3 {
        format!("{:.1} µs", s * 1e6)
    } else if s < 1.0 {
        format!("{:.2} ms", s * 1e3)
    } else {
        format!("{s:.2} s")
    }
}

/// The fastest run of each method reaching `target`.
fn fastest_at(points: &[Point], target: f64) -> Vec<(&'static str, f64, f64)> {
    let mut names: Vec<&'static str> = points.iter().map(|p| p.method).collect();
    names.dedup();
    names
        .into_iter()
        .filter_map(|n| {
            points
                .iter()
                .filter(|p| p.method == n && p.err <= target)
                .min_by(|a, b| a.secs.total_cmp(&b.secs))
                .map(|p| (n, p.secs, p.err))
        })
        .collect()
}

/// plotters (with its `ab_glyph` text backend) must be given a font to measure and place
/// text, even in SVG. Registers the first system sans-serif font found; without one, plots
/// are drawn without text (axes and lines only) and a note is printed.
fn register_system_font() -> bool {
    let candidates = [
        "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/TTF/DejaVuSans.ttf",
        "/usr/share/fonts/dejavu/DejaVuSans.ttf",
        "/usr/share/fonts/truetype/liberation/LiberationSans-Regular.ttf",
        "/System/Library/Fonts/Supplemental/Arial.ttf",
        "C:\\Windows\\Fonts\\arial.ttf",
    ];
    for path in candidates {
        if let Ok(bytes) = std::fs::read(path) {
            let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
            if plotters::style::register_font("sans-serif", FontStyle::Normal, bytes).is_ok() {
                return true;
            }
        }
    }
    println!("note: no system font found; plots are written without text");
    false
}

static FONT: std::sync::OnceLock<bool> = std::sync::OnceLock::new();

fn have_font() -> bool {
    *FONT.get_or_init(register_system_font)
}

const COLORS: [RGBColor; 12] = [
    RGBColor(31, 119, 180),
    RGBColor(255, 127, 14),
    RGBColor(44, 160, 44),
    RGBColor(214, 39, 40),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
    RGBColor(188, 189, 34),
    RGBColor(23, 190, 207),
    RGBColor(0, 0, 0),
    RGBColor(120, 120, 255),
];

fn plot(
    path: &str,
    title: &str,
    points: &[Point],
    refs: &[(&str, f64, f64)],
) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new(path, (900, 620)).into_drawing_area();
    root.fill(&WHITE)?;
    let xs = points.iter().map(|p| p.secs).chain(refs.iter().map(|r| r.1));
    let ys = points.iter().map(|p| p.err.max(1e-16)).chain(refs.iter().map(|r| r.2));
    let (x0, x1) = xs.fold((f64::INFINITY, 0.0f64), |(a, b), x| (a.min(x), b.max(x)));
    let (y0, y1) = ys.fold((f64::INFINITY, 0.0f64), |(a, b), y| (a.min(y), b.max(y)));
    let text = have_font();
    let mut builder = ChartBuilder::on(&root);
    builder.margin(12);
    if text {
        builder.caption(title, ("sans-serif", 20)).x_label_area_size(40).y_label_area_size(60);
    }
    let mut chart =
        builder.build_cartesian_2d((x0 / 2.0..x1 * 2.0).log_scale(), (y0 / 3.0..(y1 * 3.0).min(1e3)).log_scale())?;
    if text {
        chart
            .configure_mesh()
            .x_desc("wall time per integration [s]")
            .y_desc("max-norm error of the final state")
            .x_label_formatter(&|v| format!("{v:.0e}"))
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()?;
    }
    let mut names: Vec<&'static str> = points.iter().map(|p| p.method).collect();
    names.dedup();
    for (i, n) in names.iter().enumerate() {
        let c = COLORS[i % COLORS.len()];
        let pts: Vec<(f64, f64)> =
            points.iter().filter(|p| p.method == *n && p.err < 1e3).map(|p| (p.secs, p.err.max(1e-16))).collect();
        chart
            .draw_series(LineSeries::new(pts.clone(), c.stroke_width(2)))?
            .label(*n)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c.stroke_width(2)));
        chart.draw_series(pts.into_iter().map(|p| Circle::new(p, 3, c.filled())))?;
    }
    for (label, t, e) in refs {
        chart
            .draw_series(std::iter::once(TriangleMarker::new((*t, *e), 7, RED.filled())))?
            .label(*label)
            .legend(|(x, y)| TriangleMarker::new((x + 9, y), 5, RED.filled()));
    }
    if text {
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()?;
    }
    root.present()?;
    Ok(())
}

/// A hand-written RK4 loop over the same right-hand side, outside the integration framework:
/// the baseline that measures the framework's overhead.
fn hand_rk4<S: Rhs>(sys: &S, t1: f64, y0: &[f64], n: usize) -> Vec<f64> {
    let d = y0.len();
    let h = t1 / n as f64;
    let (mut y, mut k1, mut k2, mut k3, mut k4, mut tmp) =
        (y0.to_vec(), vec![0.0; d], vec![0.0; d], vec![0.0; d], vec![0.0; d], vec![0.0; d]);
    for i in 0..n {
        let t = i as f64 * h;
        sys.eval(t, &y, &mut k1);
        for j in 0..d {
            tmp[j] = y[j] + 0.5 * h * k1[j];
        }
        sys.eval(t + 0.5 * h, &tmp, &mut k2);
        for j in 0..d {
            tmp[j] = y[j] + 0.5 * h * k2[j];
        }
        sys.eval(t + 0.5 * h, &tmp, &mut k3);
        for j in 0..d {
            tmp[j] = y[j] + h * k3[j];
        }
        sys.eval(t + h, &tmp, &mut k4);
        for j in 0..d {
            y[j] += h / 6.0 * (k1[j] + 2.0 * k2[j] + 2.0 * k3[j] + k4[j]);
        }
    }
    y
}

fn work_precision(budget: Duration, dp_only: bool, report: &mut String) {
    if !dp_only {
        // Pendulum, released from rest at 2 rad, to t = 20 (about 2.4 periods); exact solution by
        // Jacobi elliptic functions.
        let pend = Pendulum { omega: 1.0 };
        let (t1, y0) = (20.0, [2.0, 0.0]);
        let exact = pend.exact_from_rest(2.0, t1);
        let n_lo = geometric(20.0, 2e6, 2);
        let n_hi = geometric(10.0, 2e5, 3);
        let series = separable_and_rk(&pend, t1, &y0, &n_lo, &n_hi);
        let p = sweep("Pendulum θ0 = 2, t = 20 (exact: Jacobi elliptic functions)", &exact, &series, budget);
        plot("benches/plots/work_precision_pendulum.svg", "Pendulum (θ0 = 2, t = 20)", &p, &[]).expect("plot");
        summary(report, "Pendulum θ0 = 2, t = 20", &p, &[1e-6, 1e-10]);

        // Kepler e = 0.9 to t = 20 (3.2 orbits); exact by Kepler's equation.
        let y0k = Kepler::pericentre(0.9);
        let exact = Kepler::exact(0.9, t1);
        let n_lo = geometric(200.0, 4e6, 2);
        let n_hi = geometric(100.0, 4e5, 3);
        let series = separable_and_rk(&Kepler, t1, &y0k, &n_lo, &n_hi);
        let p = sweep("Kepler e = 0.9, t = 20 (exact: Kepler's equation)", &exact, &series, budget);
        plot("benches/plots/work_precision_kepler.svg", "Kepler e = 0.9 (t = 20)", &p, &[]).expect("plot");
        summary(report, "Kepler e = 0.9, t = 20", &p, &[1e-4, 1e-8]);
    }

    // Double pendulum to t = 10 against the 50-digit reference. Not separable: Runge–Kutta,
    // collocation and DOP853 only.
    let dp = DoublePendulum::default();
    let y0d = DoublePendulum::Y0;
    let exact = DoublePendulum::REFERENCE_T10;
    let t1 = 10.0;
    let n_lo = geometric(1e3, 1e7, 2);
    let n_hi = geometric(200.0, 2e5, 3);
    let series = vec![
        fixed("Euler", ExplicitRk::euler, &dp, t1, &y0d, &geometric(1e4, 1e7, 1)),
        fixed("RK4", ExplicitRk::rk4, &dp, t1, &y0d, &n_lo),
        fixed("implicit midpoint", Gauss::midpoint, &dp, t1, &y0d, &n_lo),
        fixed("Gauss 4", Gauss::gauss4, &dp, t1, &y0d, &n_hi),
        fixed("Gauss 6", Gauss::gauss6, &dp, t1, &y0d, &n_hi),
        dop(&dp, t1, &y0d, &[1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15]),
        Series {
            name: "DOP853 compensated",
            params: vec![1e-11, 1e-12, 1e-13, 1e-14, 1e-15],
            run: Box::new(move |tol| {
                Dop853::new(tol, tol)
                    .compensated()
                    .integrate_with(&dp, 0.0..t1, &y0d, Options::new().final_only())
                    .map(|tr| tr.last_state().to_vec())
            }),
        },
        fixed("RK4 compensated", |h| ExplicitRk::rk4(h).compensated(), &dp, t1, &y0d, &geometric(1e4, 1e6, 2)),
    ];
    let p =
        sweep("Double pendulum θ = (2.0, 2.5) at rest, t = 10 (reference: 50-digit Taylor)", &exact, &series, budget);
    // Same-run baseline: a hand-written RK4 loop at dt = 1e-4.
    let (secs, y) = time(budget, || hand_rk4(&dp, t1, &y0d, 100_000));
    let hand_err = max_err(&y, &exact);
    println!("\nhand-written RK4 loop, dt = 1e-4: {} for error {hand_err:.2e}", fmt_time(secs));
    plot("benches/plots/work_precision_double_pendulum.svg", "Double pendulum (t = 10)", &p, &[]).expect("plot");
    summary(report, "Double pendulum, t = 10", &p, &[4.6e-4, 4.8e-5, 1.1e-5, 9e-7]);
    let _ = writeln!(
        report,
        "\nSame run, hand-written RK4 loop (no framework) at dt = 1e-4: {} for error {hand_err:.2e}.",
        fmt_time(secs)
    );
}

fn separable_and_rk<'a, S>(sys: &'a S, t1: f64, y0: &'a [f64], n_lo: &[f64], n_hi: &[f64]) -> Vec<Series<'a>>
where
    S: lagrangian::integrate::Separable + Rhs,
{
    let low: Vec<f64> = n_lo.iter().copied().filter(|&n| n >= 20.0 * t1).collect();
    vec![
        fixed("Euler", ExplicitRk::euler, sys, t1, y0, &low),
        fixed("symplectic Euler", Splitting::symplectic_euler, sys, t1, y0, &low),
        fixed("leapfrog", Splitting::leapfrog, sys, t1, y0, n_lo),
        fixed("Yoshida 4", Splitting::yoshida4, sys, t1, y0, n_hi),
        fixed("Blanes-Moan 4", Splitting::blanes_moan4, sys, t1, y0, n_hi),
        fixed("Yoshida 6", Splitting::yoshida6, sys, t1, y0, n_hi),
        fixed("Yoshida 8", Splitting::yoshida8, sys, t1, y0, n_hi),
        fixed("RK4", ExplicitRk::rk4, sys, t1, y0, n_hi),
        fixed("implicit midpoint", Gauss::midpoint, sys, t1, y0, n_lo),
        fixed("Gauss 4", Gauss::gauss4, sys, t1, y0, n_hi),
        fixed("Gauss 6", Gauss::gauss6, sys, t1, y0, n_hi),
        dop(sys, t1, y0, &[1e-4, 1e-5, 1e-6, 1e-7, 1e-8, 1e-9, 1e-10, 1e-11, 1e-12, 1e-13, 1e-14, 1e-15]),
    ]
}

fn summary(report: &mut String, problem: &str, points: &[Point], targets: &[f64]) {
    let _ = writeln!(report, "\n### {problem}: fastest run reaching each error\n");
    let _ = write!(report, "| method |");
    for t in targets {
        let _ = write!(report, " err ≤ {t:.1e} |");
    }
    let _ = writeln!(report);
    let _ = writeln!(report, "|---|{}", "---|".repeat(targets.len()));
    let mut names: Vec<&'static str> = points.iter().map(|p| p.method).collect();
    names.dedup();
    for n in names {
        let _ = write!(report, "| {n} |");
        for &t in targets {
            match fastest_at(points, t).into_iter().find(|x| x.0 == n) {
                Some((_, s, e)) => {
                    let param = points.iter().find(|p| p.method == n && p.secs == s).map_or(0.0, |p| p.param);
                    let what =
                        if n.starts_with("DOP853") { format!("tol {param:.0e}") } else { format!("{param:.0} steps") };
                    let _ = write!(report, " {} ({what}, {e:.1e}) |", fmt_time(s));
                }
                None => {
                    let _ = write!(report, " – |");
                }
            }
        }
        let _ = writeln!(report);
    }
}

/// Kepler e = 0.5 for 10⁵ orbits with Yoshida 8 (solution D), 512 steps per orbit, with and
/// without compensated summation. The maximum energy error is taken over every step (the
/// once-per-orbit samples, always at the starting phase, are kept for the drift fit and the
/// plot, and their maximum is reported beside it: it misses the oscillation within an orbit).
fn long_run(report: &mut String) {
    let orbits = 100_000usize;
    let per_orbit = 512usize;
    let h = 2.0 * std::f64::consts::PI / per_orbit as f64;
    let y0 = Kepler::pericentre(0.5);
    let e0 = Kepler.energy(&y0);
    let _ = writeln!(report, "\n### Long run: Kepler e = 0.5, {orbits} orbits, Yoshida 8, {per_orbit} steps per orbit (h = 2π/{per_orbit})\n");
    let _ = writeln!(report, "| summation | time | max rel. energy error, every step | max at the start phase only | final rel. error | drift slope (per orbit) | RMS growth exponent |");
    let _ = writeln!(report, "|---|---|---|---|---|---|---|");
    let mut curves = Vec::new();
    for compensated in [true, false] {
        let m = if compensated { Splitting::yoshida8(h).compensated() } else { Splitting::yoshida8(h) };
        let t_end = h * (orbits * per_orbit) as f64;
        let t0 = Instant::now();
        let mut s = m.solver(&Kepler, 0.0, &y0, t_end).expect("valid");
        let mut errs = Vec::with_capacity(orbits);
        let mut every: f64 = 0.0;
        loop {
            let st = s.step().expect("no failure");
            let rel = (Kepler.energy(s.y()) - e0) / e0.abs();
            every = every.max(rel.abs());
            if s.steps() % per_orbit == 0 {
                errs.push(rel);
            }
            if st == Status::Finished {
                break;
            }
        }
        let secs = t0.elapsed().as_secs_f64();
        let n = errs.len() as f64;
        let max = errs.iter().fold(0.0f64, |m, e| m.max(e.abs()));
        // Least-squares slope of the signed error against the orbit number.
        let (sx, sy) = (n * (n + 1.0) / 2.0, errs.iter().sum::<f64>());
        let sxx = n * (n + 1.0) * (2.0 * n + 1.0) / 6.0;
        let sxy: f64 = errs.iter().enumerate().map(|(i, e)| (i + 1) as f64 * e).sum();
        let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
        // RMS error in windows [N/2^k/2, N/2^k], fitted against log N: 0.5 is a random walk
        // (Brouwer's law), 1 a systematic drift.
        let mut pts = Vec::new();
        let mut hi = errs.len();
        while hi >= 64 {
            let lo = hi / 2;
            let rms = (errs[lo..hi].iter().map(|e| e * e).sum::<f64>() / (hi - lo) as f64).sqrt();
            pts.push((((lo + hi) as f64 / 2.0).ln(), rms.ln()));
            hi = lo;
        }
        let k = pts.len() as f64;
        let (ax, ay) = (pts.iter().map(|p| p.0).sum::<f64>() / k, pts.iter().map(|p| p.1).sum::<f64>() / k);
        let expo = pts.iter().map(|p| (p.0 - ax) * (p.1 - ay)).sum::<f64>()
            / pts.iter().map(|p| (p.0 - ax).powi(2)).sum::<f64>();
        let label = if compensated { "compensated (Kahan)" } else { "plain" };
        println!("\nlong run {label}: {secs:.2} s, max rel. energy error {every:.2e} (every step; {max:.2e} at the start phase), final {:.2e}, slope {slope:.2e}/orbit, RMS exponent {expo:.2}", errs[errs.len() - 1]);
        let _ = writeln!(
            report,
            "| {label} | {secs:.1} s | {every:.2e} | {max:.2e} | {:.2e} | {slope:.2e} | {expo:.2} |",
            errs[errs.len() - 1]
        );
        curves.push((label, errs));
    }
    plot_long(&curves).expect("plot");
}

fn plot_long(curves: &[(&str, Vec<f64>)]) -> Result<(), Box<dyn std::error::Error>> {
    let root = SVGBackend::new("benches/plots/long_run_kepler.svg", (900, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let n = curves[0].1.len() as f64;
    let ymax = curves.iter().flat_map(|c| c.1.iter()).fold(0.0f64, |m, e| m.max(e.abs())) * 1.2;
    let text = have_font();
    let mut builder = ChartBuilder::on(&root);
    builder.margin(12);
    if text {
        builder
            .caption("Kepler e = 0.5, Yoshida 8: relative energy error per orbit", ("sans-serif", 18))
            .x_label_area_size(40)
            .y_label_area_size(70);
    }
    let mut chart = builder.build_cartesian_2d(0.0..n, -ymax..ymax)?;
    if text {
        chart
            .configure_mesh()
            .x_desc("orbit")
            .y_desc("(E − E0)/|E0|")
            .y_label_formatter(&|v| format!("{v:.1e}"))
            .draw()?;
    }
    for (i, (label, errs)) in curves.iter().enumerate() {
        let c = COLORS[i];
        let stride = (errs.len() / 2000).max(1);
        chart
            .draw_series(LineSeries::new(errs.iter().enumerate().step_by(stride).map(|(k, e)| (k as f64, *e)), c))?
            .label(*label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 18, y)], c));
    }
    if text {
        chart.configure_series_labels().position(SeriesLabelPosition::UpperLeft).border_style(BLACK).draw()?;
    }
    root.present()?;
    Ok(())
}

/// 10⁶ steps of Kepler e = 0.9 (h = 0.002) for every method, energy error slope.
fn structure_long(report: &mut String) {
    let y0 = Kepler::pericentre(0.9);
    let e0 = Kepler.energy(&y0);
    let h = 0.002;
    let steps = 1_000_000usize;
    let _ = writeln!(report, "\n### 10⁶ steps of Kepler e = 0.9 (h = 0.002, t = 2000 ≈ 318 orbits)\n");
    let _ = writeln!(
        report,
        "| method | time | max abs. energy error | mean first 10% | mean last 10% | fitted slope × T |"
    );
    let _ = writeln!(report, "|---|---|---|---|---|---|");
    fn one<M: Method<Kepler>>(name: &str, m: &M, y0: &[f64], e0: f64, h: f64, steps: usize, report: &mut String) {
        let t_end = h * steps as f64;
        let t0 = Instant::now();
        let mut s = m.solver(&Kepler, 0.0, y0, t_end).expect("valid");
        let (mut sx, mut sy, mut sxx, mut sxy, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
        let (mut first, mut nf, mut last, mut nl, mut max) = (0.0, 0.0, 0.0, 0.0, 0.0f64);
        loop {
            let st = s.step().expect("no failure");
            let (t, de) = (s.t(), Kepler.energy(s.y()) - e0);
            sx += t;
            sy += de;
            sxx += t * t;
            sxy += t * de;
            n += 1.0;
            max = max.max(de.abs());
            if t < 0.1 * t_end {
                first += de.abs();
                nf += 1.0;
            } else if t > 0.9 * t_end {
                last += de.abs();
                nl += 1.0;
            }
            if st == Status::Finished {
                break;
            }
        }
        let secs = t0.elapsed().as_secs_f64();
        let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
        println!(
            "{name:20} {secs:.2} s, max |ΔE| {max:.2e}, first {:.2e}, last {:.2e}, slope×T {:+.2e}",
            first / nf,
            last / nl,
            slope * t_end
        );
        let _ = writeln!(
            report,
            "| {name} | {} | {max:.2e} | {:.2e} | {:.2e} | {:+.2e} |",
            fmt_time(secs),
            first / nf,
            last / nl,
            slope * t_end
        );
    }
    one("leapfrog", &Splitting::leapfrog(h), &y0, e0, h, steps, report);
    one("Yoshida 4", &Splitting::yoshida4(h), &y0, e0, h, steps, report);
    one("Blanes-Moan 4", &Splitting::blanes_moan4(h), &y0, e0, h, steps, report);
    one("Yoshida 6", &Splitting::yoshida6(h), &y0, e0, h, steps, report);
    one("Yoshida 8", &Splitting::yoshida8(h), &y0, e0, h, steps, report);
    one("implicit midpoint", &Gauss::midpoint(h), &y0, e0, h, steps, report);
    one("Gauss 4", &Gauss::gauss4(h), &y0, e0, h, steps, report);
    one("Gauss 6", &Gauss::gauss6(h), &y0, e0, h, steps, report);
    one("RK4", &ExplicitRk::rk4(h), &y0, e0, h, steps, report);
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let quick = args.iter().any(|a| a == "quick");
    let dp_only = args.iter().any(|a| a == "double-pendulum");
    std::fs::create_dir_all("benches/plots").expect("plot directory");
    let mut report = String::new();
    let budget = Duration::from_millis(if quick { 5 } else { 60 });
    work_precision(budget, dp_only, &mut report);
    if !quick && !dp_only {
        structure_long(&mut report);
        long_run(&mut report);
    }
    println!("\n# Summary (markdown)\n{report}");
}
