//! Standard test problems with hand-written right-hand sides and, where they exist, exact
//! solutions: the harmonic oscillator (closed form), the pendulum (Jacobi elliptic functions),
//! Kepler's problem (Kepler's equation), the double pendulum and Hénon–Heiles. Shared by the
//! tests, the benchmarks and the documentation; each system implements [`Separable`] (for
//! splitting methods) where its Hamiltonian is separable and [`Rhs`] (for Runge–Kutta and
//! collocation methods) on the state `(q, p)`.

use std::f64::consts::PI;

use super::{Jacobian, Rhs, Separable};

/// Jacobi amplitude and elliptic functions `(am, sn, cn, dn)` of `u` for the parameter
/// `m = k²`, `0 ≤ m ≤ 1`, by the arithmetic–geometric mean and descending Landen
/// transformation (Abramowitz & Stegun 16.4). Accurate to a few ulps for moderate `u`.
pub fn jacobi_elliptic(u: f64, m: f64) -> (f64, f64, f64, f64) {
    if m <= 0.0 {
        return (u, u.sin(), u.cos(), 1.0);
    }
    if m >= 1.0 {
        let am = 2.0 * u.exp().atan() - 0.5 * PI; // the Gudermannian function
        let sech = 1.0 / u.cosh();
        return (am, u.tanh(), sech, sech);
    }
    let mut a = [0.0f64; 16];
    let mut c = [0.0f64; 16];
    a[0] = 1.0;
    let mut b = (1.0 - m).sqrt();
    c[0] = m.sqrt();
    let mut n = 0;
    while n < 15 && c[n].abs() > f64::EPSILON * a[n] {
        a[n + 1] = 0.5 * (a[n] + b);
        c[n + 1] = 0.5 * (a[n] - b);
        b = (a[n] * b).sqrt();
        n += 1;
    }
    let mut phi = 2f64.powi(n as i32) * a[n] * u;
    for j in (1..=n).rev() {
        phi = 0.5 * (phi + (c[j] / a[j] * phi.sin()).asin());
    }
    let sn = phi.sin();
    (phi, sn, phi.cos(), (1.0 - m * sn * sn).sqrt())
}

/// The complete elliptic integral of the first kind `K(m) = ∫_0^{π/2} dθ / √(1 − m sin²θ)`,
/// by the arithmetic–geometric mean: `K = π / (2 AGM(1, √(1 − m)))`.
pub fn elliptic_k(m: f64) -> f64 {
    let (mut a, mut b) = (1.0f64, (1.0 - m).sqrt());
    for _ in 0..20 {
        if (a - b).abs() <= f64::EPSILON * a {
            break;
        }
        let an = 0.5 * (a + b);
        b = (a * b).sqrt();
        a = an;
    }
    PI / (2.0 * a)
}

/// The harmonic oscillator `H = p²/2 + ω² q²/2`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Oscillator {
    /// Angular frequency `ω`.
    pub omega: f64,
}

impl Oscillator {
    /// The energy `H(q, p)`.
    pub fn energy(&self, y: &[f64]) -> f64 {
        0.5 * y[1] * y[1] + 0.5 * self.omega * self.omega * y[0] * y[0]
    }
    /// The exact state at time `t` from `y0`: a rotation in `(ω q, p)`.
    pub fn exact(&self, y0: &[f64], t: f64) -> [f64; 2] {
        let (s, c) = (self.omega * t).sin_cos();
        [y0[0] * c + y0[1] / self.omega * s, -y0[0] * self.omega * s + y0[1] * c]
    }
}

impl Separable for Oscillator {
    fn dof(&self) -> usize {
        1
    }
    fn drift(&self, p: &[f64], dq: &mut [f64]) {
        dq[0] = p[0];
    }
    fn kick(&self, _t: f64, q: &[f64], dp: &mut [f64]) {
        dp[0] = -self.omega * self.omega * q[0];
    }
}

impl Rhs for Oscillator {
    fn dim(&self) -> usize {
        2
    }
    fn eval(&self, _t: f64, y: &[f64], dy: &mut [f64]) {
        dy[0] = y[1];
        dy[1] = -self.omega * self.omega * y[0];
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        Some(self)
    }
}

impl Jacobian for Oscillator {
    fn jacobian(&self, _t: f64, _y: &[f64], jac: &mut [f64]) {
        jac.copy_from_slice(&[0.0, 1.0, -self.omega * self.omega, 0.0]);
    }
}

/// The pendulum `H = p²/2 − ω² cos q` (`θ'' = −ω² sin θ`, PHYSICS.md (2.28) with
/// `ω² = g/l` and `p = θ'`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pendulum {
    /// Small-oscillation frequency `ω = √(g/l)`.
    pub omega: f64,
}

impl Pendulum {
    /// The energy `H(q, p)`.
    pub fn energy(&self, y: &[f64]) -> f64 {
        0.5 * y[1] * y[1] - self.omega * self.omega * y[0].cos()
    }
    /// The exact state at time `t` after release from rest at angle `theta0` (`|θ0| < π`):
    /// `sin(θ/2) = k sn(K − ω t; k)`, `θ' = −2 k ω cn(K − ω t; k)` with `k = sin(θ0/2)`.
    pub fn exact_from_rest(&self, theta0: f64, t: f64) -> [f64; 2] {
        let k = (0.5 * theta0).sin();
        let m = k * k;
        let big_k = elliptic_k(m);
        let (_, sn, cn, _) = jacobi_elliptic(big_k - self.omega * t, m);
        [2.0 * (k * sn).asin(), -2.0 * k * self.omega * cn]
    }
    /// The period of the oscillation with amplitude `theta0`: `4 K(sin²(θ0/2)) / ω`.
    pub fn period(&self, theta0: f64) -> f64 {
        4.0 * elliptic_k((0.5 * theta0).sin().powi(2)) / self.omega
    }
    /// The exact motion on the separatrix (energy `ω²`, the top reached as `t → ∞`) starting
    /// at the bottom with `θ' = 2ω`: `θ = 4 atan(e^{ωt}) − π`, `θ' = 2ω / cosh(ωt)`.
    pub fn exact_separatrix(&self, t: f64) -> [f64; 2] {
        let w = self.omega;
        [4.0 * (w * t).exp().atan() - PI, 2.0 * w / (w * t).cosh()]
    }
}

impl Separable for Pendulum {
    fn dof(&self) -> usize {
        1
    }
    fn drift(&self, p: &[f64], dq: &mut [f64]) {
        dq[0] = p[0];
    }
    fn kick(&self, _t: f64, q: &[f64], dp: &mut [f64]) {
        dp[0] = -self.omega * self.omega * q[0].sin();
    }
}

impl Rhs for Pendulum {
    fn dim(&self) -> usize {
        2
    }
    fn eval(&self, _t: f64, y: &[f64], dy: &mut [f64]) {
        dy[0] = y[1];
        dy[1] = -self.omega * self.omega * y[0].sin();
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        Some(self)
    }
}

impl Jacobian for Pendulum {
    fn jacobian(&self, _t: f64, y: &[f64], jac: &mut [f64]) {
        jac.copy_from_slice(&[0.0, 1.0, -self.omega * self.omega * y[0].cos(), 0.0]);
    }
}

/// Kepler's problem in the plane, `H = |p|²/2 − 1/|q|` (`μ = 1`); state `(x, y, p_x, p_y)`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct Kepler;

impl Kepler {
    /// The energy `H`.
    pub fn energy(&self, y: &[f64]) -> f64 {
        0.5 * (y[2] * y[2] + y[3] * y[3]) - 1.0 / y[0].hypot(y[1])
    }
    /// The angular momentum `x p_y − y p_x`.
    pub fn angular_momentum(&self, y: &[f64]) -> f64 {
        y[0] * y[3] - y[1] * y[2]
    }
    /// The state at pericentre of the orbit with semi-major axis 1 and eccentricity `e`
    /// (period `2π`, energy `−1/2`).
    pub fn pericentre(e: f64) -> [f64; 4] {
        [1.0 - e, 0.0, 0.0, ((1.0 + e) / (1.0 - e)).sqrt()]
    }
    /// The exact state at time `t` on the orbit that starts at [`Kepler::pericentre`]: the
    /// eccentric anomaly `E` solves Kepler's equation `E − e sin E = t` (Newton's method), and
    /// `x = cos E − e`, `y = √(1−e²) sin E`, `p = (−sin E, √(1−e²) cos E)/(1 − e cos E)`.
    pub fn exact(e: f64, t: f64) -> [f64; 4] {
        let m = t.rem_euclid(2.0 * PI);
        let mut ea = if e > 0.8 { PI } else { m };
        for _ in 0..60 {
            let d = (ea - e * ea.sin() - m) / (1.0 - e * ea.cos());
            ea -= d;
            if d.abs() <= 1e-16 * (1.0 + ea.abs()) {
                break;
            }
        }
        let (s, c) = ea.sin_cos();
        let r = (1.0 - e * e).sqrt();
        let den = 1.0 - e * c;
        [c - e, r * s, -s / den, r * c / den]
    }
}

impl Separable for Kepler {
    fn dof(&self) -> usize {
        2
    }
    fn drift(&self, p: &[f64], dq: &mut [f64]) {
        dq.copy_from_slice(p);
    }
    fn kick(&self, _t: f64, q: &[f64], dp: &mut [f64]) {
        let r2 = q[0] * q[0] + q[1] * q[1];
        let inv_r3 = 1.0 / (r2 * r2.sqrt());
        dp[0] = -q[0] * inv_r3;
        dp[1] = -q[1] * inv_r3;
    }
}

impl Rhs for Kepler {
    fn dim(&self) -> usize {
        4
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        let (dq, dp) = dy.split_at_mut(2);
        self.drift(&y[2..], dq);
        self.kick(t, &y[..2], dp);
    }
    fn as_jacobian(&self) -> Option<&dyn Jacobian> {
        Some(self)
    }
}

impl Jacobian for Kepler {
    fn jacobian(&self, _t: f64, y: &[f64], jac: &mut [f64]) {
        let (x, z) = (y[0], y[1]);
        let r2 = x * x + z * z;
        let r = r2.sqrt();
        let i3 = 1.0 / (r2 * r);
        let i5 = i3 / r2;
        #[rustfmt::skip]
        let j = [
            0.0, 0.0, 1.0, 0.0,
            0.0, 0.0, 0.0, 1.0,
            -i3 + 3.0 * x * x * i5, 3.0 * x * z * i5, 0.0, 0.0,
            3.0 * x * z * i5, -i3 + 3.0 * z * z * i5, 0.0, 0.0,
        ];
        jac.copy_from_slice(&j);
    }
}

/// The planar double pendulum of `shared/reference/double_pendulum.md`, in velocity form:
/// state `(θ1, θ2, θ1', θ2')`, accelerations from `W q'' = F` (2×2, Cramer's rule). Not
/// separable (the kinetic energy depends on `θ1 − θ2`), so only [`Rhs`] methods apply.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct DoublePendulum {
    /// Upper mass.
    pub m1: f64,
    /// Lower mass.
    pub m2: f64,
    /// Upper length.
    pub l1: f64,
    /// Lower length.
    pub l2: f64,
    /// Gravity.
    pub g: f64,
}

impl Default for DoublePendulum {
    /// The reference configuration: unit masses and lengths, `g = 9.81`.
    fn default() -> Self {
        DoublePendulum { m1: 1.0, m2: 1.0, l1: 1.0, l2: 1.0, g: 9.81 }
    }
}

impl DoublePendulum {
    /// The reference initial state: `θ1 = 2.0, θ2 = 2.5` at rest.
    pub const Y0: [f64; 4] = [2.0, 2.5, 0.0, 0.0];
    /// The reference state at `t = 10` (Taylor series in 50-digit arithmetic, accurate to
    /// about 1e-14; `shared/reference/double_pendulum.md`), all published digits kept.
    #[allow(clippy::excessive_precision)]
    pub const REFERENCE_T10: [f64; 4] = [
        -0.75312887429491135322337236831363874419582724673327,
        1.6279330820537040840890643526897016618948841824665,
        -4.0873688513441969336361436527166877795014151532526,
        -8.8697025783875326087224420092458445392757368821853,
    ];

    /// The energy `E = T + V` (conserved).
    pub fn energy(&self, y: &[f64]) -> f64 {
        let DoublePendulum { m1, m2, l1, l2, g } = *self;
        let (t1, t2, w1, w2) = (y[0], y[1], y[2], y[3]);
        0.5 * (m1 + m2) * l1 * l1 * w1 * w1 + 0.5 * m2 * l2 * l2 * w2 * w2 + m2 * l1 * l2 * w1 * w2 * (t1 - t2).cos()
            - (m1 + m2) * g * l1 * t1.cos()
            - m2 * g * l2 * t2.cos()
    }
}

impl Rhs for DoublePendulum {
    fn dim(&self) -> usize {
        4
    }
    fn eval(&self, _t: f64, y: &[f64], dy: &mut [f64]) {
        let DoublePendulum { m1, m2, l1, l2, g } = *self;
        let (t1, t2, w1, w2) = (y[0], y[1], y[2], y[3]);
        let (s, c) = (t1 - t2).sin_cos();
        // W = [[a, b], [b, d]], F = (f1, f2), from the Euler–Lagrange equations of L.
        let a = (m1 + m2) * l1 * l1;
        let b = m2 * l1 * l2 * c;
        let d = m2 * l2 * l2;
        let f1 = -m2 * l1 * l2 * w2 * w2 * s - (m1 + m2) * g * l1 * t1.sin();
        let f2 = m2 * l1 * l2 * w1 * w1 * s - m2 * g * l2 * t2.sin();
        let det = a * d - b * b;
        dy[0] = w1;
        dy[1] = w2;
        dy[2] = (d * f1 - b * f2) / det;
        dy[3] = (a * f2 - b * f1) / det;
    }
}

/// The Hénon–Heiles system `H = (p_x² + p_y²)/2 + (x² + y²)/2 + x² y − y³/3`.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct HenonHeiles;

impl HenonHeiles {
    /// The energy `H`.
    pub fn energy(&self, s: &[f64]) -> f64 {
        let (x, y, px, py) = (s[0], s[1], s[2], s[3]);
        0.5 * (px * px + py * py) + 0.5 * (x * x + y * y) + x * x * y - y * y * y / 3.0
    }
}

impl Separable for HenonHeiles {
    fn dof(&self) -> usize {
        2
    }
    fn drift(&self, p: &[f64], dq: &mut [f64]) {
        dq.copy_from_slice(p);
    }
    fn kick(&self, _t: f64, q: &[f64], dp: &mut [f64]) {
        let (x, y) = (q[0], q[1]);
        dp[0] = -x - 2.0 * x * y;
        dp[1] = -y - x * x + y * y;
    }
}

impl Rhs for HenonHeiles {
    fn dim(&self) -> usize {
        4
    }
    fn eval(&self, t: f64, y: &[f64], dy: &mut [f64]) {
        let (dq, dp) = dy.split_at_mut(2);
        self.drift(&y[2..], dq);
        self.kick(t, &y[..2], dp);
    }
}
