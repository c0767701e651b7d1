//! Tests of `src/integrate/taylor.rs` (formerly its in-crate unit tests).
use lagrangian::integrate::taylor::*;
use num_rational::BigRational;
use num_traits::ToPrimitive;
use proptest::prelude::*;

/// [`polynomial`] as it was written before its loops (the reference for its bits).
fn iterator_polynomial(c: &[f64], x: f64, lo: usize) -> f64 {
    let c = &c[lo.min(c.len())..];
    let (head, tail) = c.split_at(c.len().min(HORNER_TERMS));
    let x2 = x * x;
    let x4 = x2 * x2;
    let block = |b: &[f64]| match *b {
        [c0, c1, c2, c3] => (c0 + c1 * x) + (c2 + c3 * x) * x2,
        [c0, c1, c2] => (c0 + c1 * x) + c2 * x2,
        [c0, c1] => c0 + c1 * x,
        [c0] => c0,
        _ => 0.0,
    };
    let mut blocks = tail.chunks(4).rev();
    let top = blocks.next().map_or(0.0, block);
    let tail = blocks.fold(top, |acc, b| acc * x4 + block(b));
    head.iter().rev().fold(tail, |acc, &ck| acc * x + ck)
}

fn exact(x: f64) -> BigRational {
    BigRational::from_float(x).expect("finite")
}

proptest! {
    /// The blocked evaluation is within a few rounding errors of the exact value of the
    /// polynomial (exact rational arithmetic on the same doubles), relative to the sum of
    /// its terms' magnitudes, for coefficients decaying as a Taylor series' do at a step
    /// (`r` per order), and equals Horner's rule bit for bit up to `HORNER_TERMS` of them.
    #[test]
    fn polynomial_is_accurate(c in prop::collection::vec(-1.0f64..1.0, 0..40), r in 0.05f64..1.0, x in -1.0f64..1.0, lo in 0usize..3) {
        let c: Vec<f64> = c.iter().enumerate().map(|(k, v)| v * r.powi(k as i32)).collect();
        let got = polynomial(&c, x, lo);
        let tail = &c[lo.min(c.len())..];
        let (mut sum, mut mag, mut xk) = (exact(0.0), 0.0f64, exact(1.0));
        for &ck in tail {
            sum += exact(ck) * &xk;
            mag += (exact(ck) * &xk).to_f64().unwrap().abs();
            xk *= exact(x);
        }
        let err = (exact(got) - sum).to_f64().unwrap().abs();
        prop_assert!(err <= 8.0 * f64::EPSILON * mag + f64::MIN_POSITIVE, "error {err:e}, terms {mag:e}");
        if tail.len() <= HORNER_TERMS {
            let horner = tail.iter().rev().fold(0.0, |acc, &ck| acc * x + ck);
            prop_assert_eq!(got.to_bits(), horner.to_bits());
        }
    }

    /// The loops of [`polynomial`] give the bits of its former form with iterator
    /// adaptors (below), at every length and starting order.
    #[test]
    fn polynomial_keeps_the_bits_of_its_iterator_form(c in prop::collection::vec(-1.0f64..1.0, 0..40), x in -1.0f64..1.0, lo in 0usize..3) {
        prop_assert_eq!(polynomial(&c, x, lo).to_bits(), iterator_polynomial(&c, x, lo).to_bits());
    }

    /// When the brackets of [`smaller_root`] decide, they decide as the two `log2` do, so
    /// the step size keeps the bits of taking both roots; over norms from 1e-300 to 1e300,
    /// orders 2–30, and pairs of nearly equal roots (where they must not decide wrongly).
    #[test]
    fn smaller_root_decides_as_both_logs(ea in -300.0f64..300.0, d in -0.2f64..0.2, eb in -300.0f64..300.0, near in any::<bool>(), p in 2usize..30) {
        let a = 10f64.powf(ea);
        let (ia, ib) = (1.0 / (p - 1) as f64, 1.0 / p as f64);
        // Near: `b` with nearly the same root as `a`.
        let b = if near { 2f64.powf((a.log2() * ia + d * 1e-3) / ib) } else { 10f64.powf(eb) };
        let exact = (a.log2() * ia).min(b.log2() * ib);
        if let Some(first) = smaller_root(a, ia, b, ib) {
            let chosen = if first { a.log2() * ia } else { b.log2() * ib };
            prop_assert_eq!(chosen.to_bits(), exact.to_bits(), "a {:e} b {:e} p {}", a, b, p);
        }
    }
}
