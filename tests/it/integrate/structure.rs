//! Geometric structure: bounded energy error of symplectic methods on Kepler e = 0.9 versus
//! the secular drift of RK4; reversibility of symmetric methods; symplecticity `Mᵀ J M = J`
//! of the one-step map (Jacobian by Richardson-extrapolated central differences).
//!
//! The long runs here are 10⁶ steps for the explicit methods; the implicit Gauss methods run
//! 10⁵ steps in `cargo test` (10⁶ steps of Gauss 6 take ~10 s in the dev profile) and the full
//! 10⁶ in `cargo bench --bench work_precision` (see BENCHMARKS.md).

use lagrangian::integrate::problems::{HenonHeiles, Kepler, Pendulum};
use lagrangian::integrate::{ExplicitRk, FnJacobian, Gauss, Integrate, Method, Options, Splitting, Status};

/// Energy error statistics of a run: least-squares slope of `E(t) − E0` (per unit time), and
/// the mean of `|E − E0|` over the first and last tenth of the run.
struct Drift {
    slope: f64,
    first: f64,
    last: f64,
    max: f64,
    t_end: f64,
}

fn energy_drift<S: ?Sized, M: Method<S>>(
    m: &M,
    sys: &S,
    y0: &[f64],
    h: f64,
    steps: usize,
    energy: &dyn Fn(&[f64]) -> f64,
) -> Drift {
    let t_end = h * steps as f64;
    let mut solver = m.solver(sys, 0.0, y0, t_end).expect("valid input");
    let e0 = energy(y0);
    let (mut sx, mut sy, mut sxx, mut sxy, mut n) = (0.0, 0.0, 0.0, 0.0, 0.0);
    let (mut first, mut nf, mut last, mut nl, mut max) = (0.0, 0.0, 0.0, 0.0, 0.0f64);
    loop {
        let status = solver.step().expect("no failure");
        let (t, de) = (solver.t(), energy(solver.y()) - e0);
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
        if status == Status::Finished {
            break;
        }
    }
    let slope = (n * sxy - sx * sy) / (n * sxx - sx * sx);
    Drift { slope, first: first / nf, last: last / nl, max, t_end }
}

fn report(name: &str, d: &Drift) {
    println!(
        "{name:24} slope {:+.3e}/unit time (×T = {:+.2e}); mean |ΔE| first 10% {:.2e}, last 10% {:.2e}; max {:.2e}",
        d.slope,
        d.slope * d.t_end,
        d.first,
        d.last,
        d.max
    );
}

#[test]
fn symplectic_methods_have_bounded_energy_error_on_kepler_e09_while_rk4_drifts() {
    let y0 = Kepler::pericentre(0.9);
    let energy = |y: &[f64]| Kepler.energy(y);
    let h = 0.002; // 10⁶ steps = 2000 time units ≈ 318 orbits
    let explicit: [(&str, Splitting); 4] = [
        ("leapfrog", Splitting::leapfrog(h)),
        ("Yoshida 4", Splitting::yoshida4(h)),
        ("Blanes-Moan 4", Splitting::blanes_moan4(h)),
        ("Yoshida 8", Splitting::yoshida8(h)),
    ];
    for (name, m) in &explicit {
        let d = energy_drift(m, &Kepler, &y0, h, 1_000_000, &energy);
        report(name, &d);
        assert!(d.last < 2.0 * d.first + 1e-14, "{name}: energy error grows");
        assert!((d.slope * d.t_end).abs() < 0.2 * d.max + 1e-13, "{name}: secular drift");
    }
    for (name, m) in [("implicit midpoint", Gauss::midpoint(h)), ("Gauss 6", Gauss::gauss6(h))] {
        let d = energy_drift(&m, &Kepler, &y0, h, 100_000, &energy);
        report(name, &d);
        assert!(d.last < 2.0 * d.first + 1e-14, "{name}: energy error grows");
        assert!((d.slope * d.t_end).abs() < 0.2 * d.max + 1e-13, "{name}: secular drift");
    }
    let d = energy_drift(&ExplicitRk::rk4(h), &Kepler, &y0, h, 1_000_000, &energy);
    report("RK4", &d);
    assert!(d.last > 5.0 * d.first, "RK4 should drift: first {:e}, last {:e}", d.first, d.last);
    assert!((d.slope * d.t_end).abs() > 0.5 * d.max, "RK4 drift should be secular");
}

fn roundtrip<S: ?Sized, M: Method<S>>(m: &M, sys: &S, y0: &[f64], t: f64) -> f64 {
    let fwd = m.integrate_with(sys, 0.0..t, y0, Options::new().final_only()).expect("forward");
    let back = m.integrate_with(sys, t..0.0, fwd.last_state(), Options::new().final_only()).expect("backward");
    assert_eq!(back.last_time(), 0.0);
    back.last_state().iter().zip(y0).map(|(a, b)| (a - b).abs()).fold(0.0, f64::max)
}

#[test]
fn symmetric_methods_are_reversible() {
    let sys = Pendulum { omega: 1.0 };
    let y0 = [2.5, 0.3];
    let (h, t) = (0.1, 10.0); // 100 steps each way
    let splittings = [
        Splitting::leapfrog(h),
        Splitting::yoshida4(h),
        Splitting::blanes_moan4(h),
        Splitting::yoshida6(h),
        Splitting::yoshida8(h),
    ];
    for m in &splittings {
        let e = roundtrip(m, &sys, &y0, t);
        println!("{:16} forward-backward error {e:.2e}", m.info().name);
        assert!(e < 1e-13, "not reversible: {e:e}");
    }
    for m in [Gauss::midpoint(h), Gauss::gauss4(h), Gauss::gauss6(h)] {
        let e = roundtrip(&m, &sys, &y0, t);
        println!("{:16} forward-backward error {e:.2e}", m.info().name);
        assert!(e < 1e-13, "not reversible: {e:e}");
    }
    // Non-symmetric methods do not return: the test can tell.
    let e = roundtrip(&ExplicitRk::rk4(h), &sys, &y0, t);
    println!("RK4              forward-backward error {e:.2e}");
    assert!(e > 1e-8);
    let e = roundtrip(&Splitting::symplectic_euler(h), &sys, &y0, t);
    println!("symplectic Euler forward-backward error {e:.2e}");
    assert!(e > 1e-4);
}

/// `max |Mᵀ J M − J|` for the one-step map of `m` at `y` (dimension 2n), with `M` by central
/// differences at δ and δ/2 combined by Richardson extrapolation (error O(δ⁴)).
fn symplecticity_defect<S: ?Sized, M: Method<S>>(m: &M, sys: &S, y: &[f64], h: f64) -> f64 {
    let d = y.len();
    let step = |y: &[f64]| -> Vec<f64> {
        m.integrate_with(sys, 0.0..h, y, Options::new().final_only()).expect("one step").last_state().to_vec()
    };
    let central = |j: usize, delta: f64| -> Vec<f64> {
        let mut yp = y.to_vec();
        let mut ym = y.to_vec();
        yp[j] += delta;
        ym[j] -= delta;
        let (fp, fm) = (step(&yp), step(&ym));
        (0..d).map(|i| (fp[i] - fm[i]) / (2.0 * delta)).collect()
    };
    let delta = 1e-3;
    let mut mm = vec![0.0; d * d]; // mm[i * d + j] = ∂Φ_i/∂y_j
    for j in 0..d {
        let (c1, c2) = (central(j, delta), central(j, delta / 2.0));
        for i in 0..d {
            mm[i * d + j] = (4.0 * c2[i] - c1[i]) / 3.0;
        }
    }
    let n = d / 2;
    let jm = |i: usize, j: usize| -> f64 {
        if i < n && j == i + n {
            1.0
        } else if i >= n && j + n == i {
            -1.0
        } else {
            0.0
        }
    };
    let mut worst: f64 = 0.0;
    for a in 0..d {
        for b in 0..d {
            let mut s = 0.0;
            for i in 0..d {
                for j in 0..d {
                    s += mm[i * d + a] * jm(i, j) * mm[j * d + b];
                }
            }
            worst = worst.max((s - jm(a, b)).abs());
        }
    }
    worst
}

#[test]
fn one_step_maps_of_symplectic_methods_are_symplectic() {
    let y = [0.2, -0.1, 0.3, 0.25];
    let h = 0.3;
    for m in [
        Splitting::symplectic_euler(h),
        Splitting::leapfrog(h),
        Splitting::yoshida4(h),
        Splitting::blanes_moan4(h),
        Splitting::yoshida6(h),
        Splitting::yoshida8(h),
    ] {
        let defect = symplecticity_defect(&m, &HenonHeiles, &y, h);
        println!("Hénon–Heiles {:16} |MᵀJM − J| = {defect:.2e}", m.info().name);
        assert!(defect < 5e-12, "defect {defect:e}");
    }
    // Gauss methods on a non-separable Hamiltonian H = p²(1 + q²)/2 + q²/2 (with Jacobian).
    let nonsep = FnJacobian {
        dim: 2,
        f: |_t: f64, y: &[f64], dy: &mut [f64]| {
            dy[0] = y[1] * (1.0 + y[0] * y[0]);
            dy[1] = -(y[0] * y[1] * y[1] + y[0]);
        },
        jac: |_t: f64, y: &[f64], j: &mut [f64]| {
            j.copy_from_slice(&[2.0 * y[0] * y[1], 1.0 + y[0] * y[0], -(y[1] * y[1] + 1.0), -2.0 * y[0] * y[1]]);
        },
    };
    let y = [0.7, -0.4];
    for m in [Gauss::midpoint(h), Gauss::gauss4(h), Gauss::gauss6(h)] {
        let defect = symplecticity_defect(&m, &nonsep, &y, h);
        println!("non-separable {:15} |MᵀJM − J| = {defect:.2e}", m.info().name);
        assert!(defect < 5e-12, "defect {defect:e}");
    }
    let rk4_hh = symplecticity_defect(&ExplicitRk::rk4(h), &HenonHeiles, &[0.2, -0.1, 0.3, 0.25], h);
    let rk4_ns = symplecticity_defect(&ExplicitRk::rk4(h), &nonsep, &y, h);
    println!("RK4 |MᵀJM − J| = {rk4_hh:.2e} (Hénon–Heiles), {rk4_ns:.2e} (non-separable)");
    assert!(rk4_hh > 1e-7 && rk4_ns > 1e-7, "RK4 is not symplectic");
}
