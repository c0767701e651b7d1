//! Consistency conditions of every scheme's coefficient data: sums equal to 1 to rounding,
//! palindromic (symmetric) compositions, the composition order conditions evaluated by the
//! Baker–Campbell–Hausdorff formula in a truncated free algebra, and Butcher order conditions
//! of the Runge–Kutta tableaux (RK4 all eight trees of order ≤ 4; Gauss–Legendre the
//! simplifying assumptions B(2s), C(s) and the symplecticity condition; DOP853 row sums,
//! quadrature conditions B(8) and the order-4 trees).

use std::collections::BTreeMap;

use lagrangian::integrate::coefficients::{
    dop853, SplittingKind, SplittingScheme, Tableau, SPLITTING_SCHEMES, YOSHIDA4_W0, YOSHIDA4_W1,
};

const ULP: f64 = f64::EPSILON;

/// `(kick, drift)` flow list of a scheme, as `(is_kick, coefficient)`.
fn flows(s: &SplittingScheme) -> Vec<(bool, f64)> {
    let mut out = Vec::new();
    match s.kind {
        SplittingKind::VerletComposition { weights } => {
            for &w in weights {
                out.push((true, 0.5 * w));
                out.push((false, w));
                out.push((true, 0.5 * w));
            }
        }
        SplittingKind::KickDrift { kicks, drifts } => {
            for (i, &b) in kicks.iter().enumerate() {
                out.push((true, b));
                if let Some(&a) = drifts.get(i) {
                    out.push((false, a));
                }
            }
        }
    }
    out
}

#[test]
fn splitting_coefficients_sum_to_one_and_symmetric_ones_are_palindromes() {
    for s in SPLITTING_SCHEMES {
        let f = flows(s);
        let kick: f64 = f.iter().filter(|x| x.0).map(|x| x.1).sum();
        let drift: f64 = f.iter().filter(|x| !x.0).map(|x| x.1).sum();
        let scale: f64 = f.iter().map(|x| x.1.abs()).sum();
        assert!((kick - 1.0).abs() <= 4.0 * ULP * scale, "{}: kicks sum to {kick}", s.name);
        assert!((drift - 1.0).abs() <= 4.0 * ULP * scale, "{}: drifts sum to {drift}", s.name);
        let palindrome = f.iter().zip(f.iter().rev()).all(|(a, b)| a == b);
        assert_eq!(palindrome, s.symmetric, "{}: symmetry flag vs coefficients", s.name);
    }
}

#[test]
fn yoshida4_is_the_closed_form() {
    let c = 2f64.cbrt();
    assert!((YOSHIDA4_W1 - 1.0 / (2.0 - c)).abs() <= 2.0 * ULP);
    assert!((YOSHIDA4_W0 + c / (2.0 - c)).abs() <= 4.0 * ULP);
}

/// Power sums Σ w_i^k of the Verlet compositions vanish for odd 3 ≤ k < order (the order
/// conditions for the terms h^k Y_k of the symmetric base method's modified equation).
#[test]
fn composition_power_sums_vanish() {
    for s in SPLITTING_SCHEMES {
        if let SplittingKind::VerletComposition { weights } = s.kind {
            for k in (3..s.order as i32).step_by(2) {
                let sum: f64 = weights.iter().map(|w| w.powi(k)).sum();
                let scale: f64 = weights.iter().map(|w| w.abs().powi(k)).sum();
                assert!(sum.abs() <= 16.0 * ULP * scale, "{}: Σ w^{k} = {sum:e}", s.name);
            }
        }
    }
}

// ---- Truncated free associative algebra for the BCH order conditions ----

/// Words over graded letters with real coefficients, truncated at a total degree.
type Elem = BTreeMap<Vec<u8>, f64>;

fn degree(w: &[u8], deg: &dyn Fn(u8) -> usize) -> usize {
    w.iter().map(|&g| deg(g)).sum()
}

fn mul(x: &Elem, y: &Elem, deg: &dyn Fn(u8) -> usize, max: usize) -> Elem {
    let mut out = Elem::new();
    for (wa, ca) in x {
        let da = degree(wa, deg);
        for (wb, cb) in y {
            if da + degree(wb, deg) > max {
                continue;
            }
            let mut w = wa.clone();
            w.extend_from_slice(wb);
            *out.entry(w).or_insert(0.0) += ca * cb;
        }
    }
    out
}

fn exp(x: &Elem, deg: &dyn Fn(u8) -> usize, max: usize) -> Elem {
    let mut out: Elem = [(vec![], 1.0)].into_iter().collect();
    let mut term = out.clone();
    for k in 1..=max {
        term = mul(&term, x, deg, max).into_iter().map(|(w, c)| (w, c / k as f64)).collect();
        for (w, c) in &term {
            *out.entry(w.clone()).or_insert(0.0) += c;
        }
    }
    out
}

fn log(x: &Elem, deg: &dyn Fn(u8) -> usize, max: usize) -> Elem {
    let mut z = x.clone();
    *z.entry(vec![]).or_insert(0.0) -= 1.0;
    z.remove(&vec![]);
    let mut out = Elem::new();
    let mut term: Elem = [(vec![], 1.0)].into_iter().collect();
    for k in 1..=max {
        term = mul(&term, &z, deg, max);
        let sign = if k % 2 == 1 { 1.0 } else { -1.0 };
        for (w, c) in &term {
            *out.entry(w.clone()).or_insert(0.0) += sign * c / k as f64;
        }
    }
    out
}

/// The logarithm of a Verlet composition with generic symmetric base method
/// `log S(h) = h Y1 + h³ Y3 + h⁵ Y5 + h⁷ Y7` (letters 1, 3, 5, 7 of degrees 1, 3, 5, 7).
fn composition_log(weights: &[f64], max: usize) -> Elem {
    let deg = |g: u8| g as usize;
    let mut prod: Elem = [(vec![], 1.0)].into_iter().collect();
    for &w in weights {
        let x: Elem =
            [1u8, 3, 5, 7].into_iter().filter(|&g| g as usize <= max).map(|g| (vec![g], w.powi(g as i32))).collect();
        prod = mul(&prod, &exp(&x, &deg, max), &deg, max);
    }
    log(&prod, &deg, max)
}

#[test]
fn compositions_satisfy_the_bch_order_conditions() {
    // One word per Lie element that can occur up to degree 7: Y3, Y5, [Y1,[Y1,Y3]], Y7,
    // [Y1,[Y1,[Y1,[Y1,Y3]]]], [Y1,[Y1,Y5]], [Y3,[Y3,Y1]] (each is the only Lie element of its
    // multidegree, so one coefficient decides it).
    let conditions: [(&[u8], u32); 7] =
        [(&[3], 4), (&[5], 6), (&[1, 1, 3], 6), (&[7], 8), (&[1, 1, 1, 1, 3], 8), (&[1, 1, 5], 8), (&[1, 3, 3], 8)];
    for s in SPLITTING_SCHEMES {
        let SplittingKind::VerletComposition { weights } = s.kind else { continue };
        let lg = composition_log(weights, 7);
        assert!((lg[&vec![1u8]] - 1.0).abs() < 1e-14, "{}: consistency", s.name);
        for (word, needed_for) in conditions {
            let c = lg.get(word).copied().unwrap_or(0.0);
            if s.order >= needed_for {
                assert!(c.abs() < 1e-12, "{}: coefficient of {word:?} is {c:e}", s.name);
            } else if s.order + 2 == needed_for && word.len() == 1 {
                // The first neglected condition really is violated (the test can fail).
                assert!(c.abs() > 1e-6, "{}: {word:?} unexpectedly satisfied", s.name);
            }
        }
    }
}

#[test]
fn blanes_moan_satisfies_the_order_4_splitting_conditions() {
    // Letters 'A' (drift) and 'B' (kick) of degree 1; order 4 for a symmetric splitting needs
    // the coefficients of [A,[A,B]] (word AAB) and [B,[B,A]] (word BBA) to vanish.
    let s = &lagrangian::integrate::coefficients::BLANES_MOAN4;
    let deg = |_: u8| 1usize;
    let mut prod: Elem = [(vec![], 1.0)].into_iter().collect();
    for (is_kick, c) in flows(s) {
        let x: Elem = [(vec![if is_kick { b'B' } else { b'A' }], c)].into_iter().collect();
        prod = mul(&prod, &exp(&x, &deg, 3), &deg, 3);
    }
    let lg = log(&prod, &deg, 3);
    assert!((lg[&vec![b'A']] - 1.0).abs() < 1e-14 && (lg[&vec![b'B']] - 1.0).abs() < 1e-14);
    for w in [b"AAB", b"BBA", b"ABA", b"BAB"] {
        let c = lg.get(w.as_slice()).copied().unwrap_or(0.0);
        assert!(c.abs() < 1e-14, "{}: {c:e}", String::from_utf8_lossy(w));
    }
    // Degree 2 vanishes by symmetry.
    assert!(lg.get(b"AB".as_slice()).copied().unwrap_or(0.0).abs() < 1e-15);
}

fn butcher_checks(t: &Tableau, tol: f64) {
    let s = t.stages;
    // Row sums.
    for i in 0..s {
        let r: f64 = (0..s).map(|j| t.a(i, j)).sum();
        assert!((r - t.c[i]).abs() < tol, "{}: row {i} sums to {r}, c = {}", t.name, t.c[i]);
    }
    // Quadrature B(p): Σ b c^{k−1} = 1/k.
    for k in 1..=t.order {
        let q: f64 = (0..s).map(|i| t.b[i] * t.c[i].powi(k as i32 - 1)).sum();
        assert!((q - 1.0 / k as f64).abs() < tol, "{}: B({k})", t.name);
    }
    if t.order >= 3 {
        let ac: Vec<f64> = (0..s).map(|i| (0..s).map(|j| t.a(i, j) * t.c[j]).sum()).collect();
        let b_ac: f64 = (0..s).map(|i| t.b[i] * ac[i]).sum();
        assert!((b_ac - 1.0 / 6.0).abs() < tol, "{}: b·Ac", t.name);
        if t.order >= 4 {
            let b_cac: f64 = (0..s).map(|i| t.b[i] * t.c[i] * ac[i]).sum();
            let ac2: f64 = (0..s).map(|i| t.b[i] * (0..s).map(|j| t.a(i, j) * t.c[j] * t.c[j]).sum::<f64>()).sum();
            let aac: f64 = (0..s).map(|i| t.b[i] * (0..s).map(|j| t.a(i, j) * ac[j]).sum::<f64>()).sum();
            assert!((b_cac - 1.0 / 8.0).abs() < tol, "{}: b·(c∘Ac)", t.name);
            assert!((ac2 - 1.0 / 12.0).abs() < tol, "{}: b·Ac²", t.name);
            assert!((aac - 1.0 / 24.0).abs() < tol, "{}: b·AAc", t.name);
        }
    }
}

#[test]
fn runge_kutta_tableaux_satisfy_order_conditions() {
    for t in [Tableau::euler(), Tableau::rk4(), Tableau::implicit_midpoint(), Tableau::gauss4(), Tableau::gauss6()] {
        butcher_checks(&t, 4.0 * ULP);
    }
    // Collocation: C(s), Σ_j a_ij c_j^{k−1} = c_i^k / k, and symplecticity
    // b_i a_ij + b_j a_ji = b_i b_j (Hairer, Lubich, Wanner, Thm. VI.4.3).
    for t in [Tableau::implicit_midpoint(), Tableau::gauss4(), Tableau::gauss6()] {
        let s = t.stages;
        for i in 0..s {
            for k in 1..=s as i32 {
                let lhs: f64 = (0..s).map(|j| t.a(i, j) * t.c[j].powi(k - 1)).sum();
                assert!((lhs - t.c[i].powi(k) / k as f64).abs() < 4.0 * ULP, "{}: C({k})", t.name);
            }
            for j in 0..s {
                let m = t.b[i] * t.a(i, j) + t.b[j] * t.a(j, i) - t.b[i] * t.b[j];
                assert!(m.abs() < 4.0 * ULP, "{}: symplecticity ({i},{j}) = {m:e}", t.name);
            }
        }
        // Symmetric nodes: c_i + c_{s−1−i} = 1.
        for i in 0..s {
            assert!((t.c[i] + t.c[s - 1 - i] - 1.0).abs() < 2.0 * ULP);
        }
    }
    // RK4 is not symplectic: the condition fails for some (i, j).
    let t = Tableau::rk4();
    let worst = (0..16)
        .map(|ij| {
            let (i, j) = (ij / 4, ij % 4);
            (t.b[i] * t.a(i, j) + t.b[j] * t.a(j, i) - t.b[i] * t.b[j]).abs()
        })
        .fold(0.0, f64::max);
    assert!(worst > 0.01);
}

#[test]
fn dop853_coefficients_are_consistent() {
    use dop853::{A, BHH, C, ER};
    // Row sums equal the nodes, for the 12 stages, the FSAL stage and the dense-output stages.
    for (i, row) in A.iter().enumerate() {
        let r: f64 = row.iter().map(|x| x.1).sum();
        let scale: f64 = row.iter().map(|x| x.1.abs()).sum::<f64>().max(1.0);
        assert!((r - C[i]).abs() <= 8.0 * ULP * scale, "row {i}: {r} vs c = {}", C[i]);
    }
    // The weights (row 12) integrate polynomials of degree < 8 exactly: B(8).
    let b = A[12];
    for k in 1..=8 {
        let q: f64 = b.iter().map(|&(j, bj)| bj * C[j].powi(k - 1)).sum();
        assert!((q - 1.0 / k as f64).abs() < 1e-14, "B({k}): {q}");
    }
    // Order-4 trees of the 8th-order weights.
    let mut ac = [0.0; 16];
    for i in 0..16 {
        ac[i] = A[i].iter().map(|&(j, a)| a * C[j]).sum();
    }
    let b_ac: f64 = b.iter().map(|&(i, bi)| bi * ac[i]).sum();
    let b_aac: f64 = b.iter().map(|&(i, bi)| bi * A[i].iter().map(|&(j, a)| a * ac[j]).sum::<f64>()).sum();
    assert!((b_ac - 1.0 / 6.0).abs() < 1e-14 && (b_aac - 1.0 / 24.0).abs() < 1e-14);
    // The 3rd-order embedded weights sum to one and integrate quadratics exactly; the
    // 5th-order estimator is a difference of two consistent weight vectors (sums to zero).
    let bhh: f64 = BHH.iter().map(|x| x.1).sum();
    assert!((bhh - 1.0).abs() < 4.0 * ULP);
    for k in 1..=3 {
        let q: f64 = BHH.iter().map(|&(j, w)| w * C[j].powi(k - 1)).sum();
        assert!((q - 1.0 / k as f64).abs() < 1e-14, "bhh B({k})");
    }
    let er: f64 = ER.iter().map(|x| x.1).sum();
    assert!(er.abs() < 1e-15, "Σ er = {er:e}");
}
