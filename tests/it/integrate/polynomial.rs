//! Tests of `src/integrate/taylor.rs` (formerly its in-crate unit tests).
use lagrangian::integrate::taylor::*;
use num_rational::BigRational;
use num_traits::ToPrimitive;
use proptest::prelude::*;

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
}
