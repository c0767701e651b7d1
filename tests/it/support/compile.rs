//! Model systems shared by the compiler's tests and benchmarks: each as a Lagrangian with
//! its mass matrix and forcing derived here by `crate::diff` (PHYSICS.md §2, eq. 3.5), and as a
//! hand-written Rust closure of the same equations (derived by hand, in the comments).
#![allow(dead_code)]
// The hand-written baselines index like the textbook formulas they transcribe.
#![allow(clippy::needless_range_loop)]

use lagrangian::diff::Differentiator;
use lagrangian::{Expr, Rational, Symbol};

/// Multiplies products of sums out (and small positive integer powers of sums), so like terms
/// meet and cancel in the canonical sum: the form the mechanics stage hands to the compiler
/// (its `mass_matrix_split` contracts `F` as a polynomial the same way).
pub fn expand(e: &Expr) -> Expr {
    e.map_bottom_up(&mut |x| match x.node() {
        lagrangian::Node::Mul(fs) if fs.iter().any(|f| matches!(f.node(), lagrangian::Node::Add(_))) => {
            let mut acc = vec![Expr::one()];
            for f in fs {
                let terms = f.terms();
                acc = acc.iter().flat_map(|a| terms.iter().map(move |t| a.times(t))).collect();
            }
            Some(Expr::add(acc))
        }
        lagrangian::Node::Pow(b, k) if matches!(b.node(), lagrangian::Node::Add(_)) => {
            let k = k.as_num().filter(|r| r.is_integer() && *r > &Rational::from_integer(1.into()))?;
            let k: i64 = k.to_integer().try_into().ok().filter(|k| *k <= 4)?;
            let mut acc = vec![Expr::one()];
            for _ in 0..k {
                acc = acc.iter().flat_map(|a| b.terms().into_iter().map(move |t| a.times(&t))).collect();
            }
            Some(Expr::add(acc))
        }
        _ => None,
    })
}

/// `W_ij = ∂²L/∂q'_i∂q'_j` and `F_i = ∂L/∂q_i − Σ_j ∂²L/∂q'_i∂q_j q'_j − ∂²L/∂q'_i∂t`.
pub fn mass_matrix_split(l: &Expr, coords: &[&str]) -> (Vec<Vec<Expr>>, Vec<Expr>) {
    let q: Vec<Symbol> = coords.iter().map(|c| Symbol::new(c)).collect();
    let v: Vec<Symbol> = q.iter().map(Symbol::prime).collect();
    let t = Symbol::new("t");
    let mut d = Differentiator::new();
    let p: Vec<Expr> = v.iter().map(|vi| d.diff(l, vi)).collect();
    let w = p.iter().map(|pi| v.iter().map(|vj| d.diff(pi, vj)).collect()).collect();
    let f = (0..q.len())
        .map(|i| {
            let mut terms = vec![d.diff(l, &q[i]), d.diff(&p[i], &t).neg()];
            for j in 0..q.len() {
                terms.push(d.diff(&p[i], &q[j]).times(&Expr::sym(v[j].clone())).neg());
            }
            expand(&Expr::add(terms))
        })
        .collect();
    (w, f)
}

/// A hand-written right-hand side.
pub type HandRhs = Box<dyn Fn(f64, &[f64], &mut [f64]) + Sync + Send>;

/// A benchmark system: its Lagrangian, coordinates, parameters and hand-written RHS.
pub struct System {
    pub name: &'static str,
    pub lagrangian: Expr,
    pub coords: Vec<String>,
    pub params: Vec<(&'static str, f64)>,
    /// `y' = f(t, y)` written by hand, state `(q, q')`.
    pub hand: HandRhs,
}

impl System {
    pub fn coords(&self) -> Vec<&str> {
        self.coords.iter().map(String::as_str).collect()
    }
    pub fn dim(&self) -> usize {
        2 * self.coords.len()
    }
    pub fn compile(&self) -> lagrangian::compile::LagrangianRhs {
        let (w, f) = mass_matrix_split(&self.lagrangian, &self.coords());
        lagrangian::compile::LagrangianRhs::new(&w, &f, &self.coords(), &self.params)
            .expect("benchmark systems compile")
    }
}

fn parse(s: &str) -> Expr {
    lagrangian::parse(s).expect("test Lagrangians parse")
}

/// `L = ½ m x'² − ½ k x²`: `x'' = −(k/m) x`.
pub fn oscillator() -> System {
    const M: f64 = 1.3;
    const K: f64 = 2.7;
    System {
        name: "harmonic oscillator",
        lagrangian: parse("1/2 m x'^2 - 1/2 k x^2"),
        coords: vec!["x".into()],
        params: vec![("m", M), ("k", K)],
        hand: Box::new(|_t, y, dy| {
            dy[0] = y[1];
            dy[1] = -(K / M) * y[0];
        }),
    }
}

/// `L = ½ m l² θ'² + m g l cos θ` (PHYSICS.md 2.27): `θ'' = −(g/l) sin θ` (2.28).
pub fn pendulum() -> System {
    const M: f64 = 1.0;
    const L: f64 = 1.5;
    const G: f64 = 9.81;
    System {
        name: "pendulum",
        lagrangian: parse("1/2 m l^2 θ'^2 + m g l cos(θ)"),
        coords: vec!["θ".into()],
        params: vec![("m", M), ("l", L), ("g", G)],
        hand: Box::new(|_t, y, dy| {
            dy[0] = y[1];
            dy[1] = -(G / L) * y[0].sin();
        }),
    }
}

/// Planar Kepler problem in Cartesian coordinates, `L = ½ (x'² + y'²) + μ / r`:
/// `r'' = −μ r / |r|³`.
pub fn kepler() -> System {
    const MU: f64 = 1.0;
    System {
        name: "Kepler",
        lagrangian: parse("1/2 (x'^2 + y'^2) + mu / sqrt(x^2 + y^2)"),
        coords: vec!["x".into(), "y".into()],
        params: vec![("mu", MU)],
        hand: Box::new(|_t, s, dy| {
            let (x, y) = (s[0], s[1]);
            let r2 = x * x + y * y;
            let k = -MU / (r2 * r2.sqrt());
            dy[0] = s[2];
            dy[1] = s[3];
            dy[2] = k * x;
            dy[3] = k * y;
        }),
    }
}

/// Kepler in polar coordinates, `L = ½ m (r'² + r² φ'²) + μ m / r` (2.33 with V = −μm/r):
/// `r'' = r φ'² − μ/r²`, `φ'' = −2 r' φ' / r` (a position-dependent mass matrix).
pub fn kepler_polar() -> System {
    const M: f64 = 2.0;
    const MU: f64 = 1.0;
    System {
        name: "Kepler (polar)",
        lagrangian: parse("1/2 m (r'^2 + r^2 φ'^2) + mu m / r"),
        coords: vec!["r".into(), "φ".into()],
        params: vec![("m", M), ("mu", MU)],
        hand: Box::new(|_t, s, dy| {
            let (r, rd, pd) = (s[0], s[2], s[3]);
            dy[0] = rd;
            dy[1] = pd;
            dy[2] = r * pd * pd - MU / (r * r);
            dy[3] = -2.0 * rd * pd / r;
        }),
    }
}

/// The double pendulum of `reference/double_pendulum.md`. By hand (Euler–Lagrange):
/// `W = [[(m1+m2) l1², m2 l1 l2 c], [m2 l1 l2 c, m2 l2²]]`, `c = cos(θ1 − θ2)`,
/// `F1 = −m2 l1 l2 s θ2'² − (m1+m2) g l1 sin θ1`, `F2 = m2 l1 l2 s θ1'² − m2 g l2 sin θ2`,
/// `s = sin(θ1 − θ2)`; solved by Cramer's rule.
pub fn double_pendulum() -> System {
    const M1: f64 = 1.0;
    const M2: f64 = 1.0;
    const L1: f64 = 1.0;
    const L2: f64 = 1.0;
    const G: f64 = 9.81;
    System {
        name: "double pendulum",
        lagrangian: parse(
            "1/2 (m1 + m2) l1^2 θ1'^2 + 1/2 m2 l2^2 θ2'^2 + m2 l1 l2 θ1' θ2' cos(θ1 - θ2) \
             + (m1 + m2) g l1 cos(θ1) + m2 g l2 cos(θ2)",
        ),
        coords: vec!["θ1".into(), "θ2".into()],
        params: vec![("m1", M1), ("m2", M2), ("l1", L1), ("l2", L2), ("g", G)],
        hand: Box::new(|_t, y, dy| {
            let (a, b, ad, bd) = (y[0], y[1], y[2], y[3]);
            let (s, c) = (a - b).sin_cos();
            let w11 = (M1 + M2) * L1 * L1;
            let w12 = M2 * L1 * L2 * c;
            let w22 = M2 * L2 * L2;
            let f1 = -M2 * L1 * L2 * s * bd * bd - (M1 + M2) * G * L1 * a.sin();
            let f2 = M2 * L1 * L2 * s * ad * ad - M2 * G * L2 * b.sin();
            let det = w11 * w22 - w12 * w12;
            dy[0] = ad;
            dy[1] = bd;
            dy[2] = (w22 * f1 - w12 * f2) / det;
            dy[3] = (w11 * f2 - w12 * f1) / det;
        }),
    }
}

/// The `n`-link pendulum, unit masses and lengths, angles from the downward vertical.
/// With `M_ij = n − max(i, j)` (masses at or below the lower of links `i`, `j`; 0-based):
/// `L = ½ Σ_ij M_ij cos(θi − θj) θi' θj' + g Σ_i (n − i) cos θi`, and by hand
/// `Σ_j M_ij cos(θi − θj) θj'' = −Σ_j M_ij sin(θi − θj) θj'² − g (n − i) sin θi`,
/// solved by a hand-written Cholesky ([`chain_hand`]).
pub fn chain(n: usize) -> System {
    let th: Vec<Expr> = (1..=n).map(|i| Expr::var(&format!("θ{i}"))).collect();
    let vel: Vec<Expr> = (1..=n).map(|i| Expr::sym(Symbol::new(&format!("θ{i}")).prime())).collect();
    let mut terms = Vec::new();
    for i in 0..n {
        for j in 0..n {
            let mij = Expr::int((n - i.max(j)) as i64);
            let c = Expr::call(lagrangian::Func::Cos, vec![th[i].minus(&th[j])]);
            terms.push(Expr::mul([Expr::frac(1, 2), mij, c, vel[i].clone(), vel[j].clone()]));
        }
        let cos = Expr::call(lagrangian::Func::Cos, vec![th[i].clone()]);
        terms.push(Expr::mul([Expr::var("g"), Expr::int((n - i) as i64), cos]));
    }
    let hand: HandRhs = match n {
        3 => Box::new(|_t, y, dy| chain_hand::<3>(y, dy)),
        5 => Box::new(|_t, y, dy| chain_hand::<5>(y, dy)),
        10 => Box::new(|_t, y, dy| chain_hand::<10>(y, dy)),
        _ => panic!("chain({n}): add a chain_hand::<{n}> arm"),
    };
    System {
        name: match n {
            5 => "5-link pendulum",
            10 => "10-link pendulum",
            _ => "n-link pendulum",
        },
        lagrangian: Expr::add(terms),
        coords: (1..=n).map(|i| format!("θ{i}")).collect(),
        params: vec![("g", CHAIN_G)],
        hand,
    }
}

const CHAIN_G: f64 = 9.81;

/// The n-link chain's right-hand side by hand, the fair baseline: `N` and `g` are compile-time
/// constants (masses and `g` fold into the code), nothing is allocated, and the buffers are
/// exactly `N` long (the previous baseline zeroed a 16 × 16 array and looped to a run-time `n`
/// on every call); only the lower triangle of `W` is formed, as the Cholesky solve reads only it.
fn chain_hand<const N: usize>(y: &[f64], dy: &mut [f64]) {
    let (y, dy) = (&y[..2 * N], &mut dy[..2 * N]);
    let mut s = [0.0f64; N];
    let mut c = [0.0f64; N];
    for i in 0..N {
        (s[i], c[i]) = y[i].sin_cos();
    }
    // Lower triangle of W (overwritten by its Cholesky factor) and F.
    let mut w = [[0.0f64; N]; N];
    let mut f = [0.0f64; N];
    for i in 0..N {
        let mut fi = -CHAIN_G * (N - i) as f64 * s[i];
        for j in 0..N {
            let mij = (N - i.max(j)) as f64;
            // sin and cos of θi − θj from those of θi and θj.
            let sij = s[i] * c[j] - c[i] * s[j];
            if j <= i {
                w[i][j] = mij * (c[i] * c[j] + s[i] * s[j]);
            }
            fi -= mij * sij * y[N + j] * y[N + j];
        }
        f[i] = fi;
    }
    for j in 0..N {
        let mut d = w[j][j];
        for k in 0..j {
            d -= w[j][k] * w[j][k];
        }
        let l = d.sqrt();
        w[j][j] = l;
        for i in j + 1..N {
            let mut x = w[i][j];
            for k in 0..j {
                x -= w[i][k] * w[j][k];
            }
            w[i][j] = x / l;
        }
    }
    for i in 0..N {
        let mut v = f[i];
        for k in 0..i {
            v -= w[i][k] * f[k];
        }
        f[i] = v / w[i][i];
    }
    for i in (0..N).rev() {
        let mut v = f[i];
        for k in i + 1..N {
            v -= w[k][i] * f[k];
        }
        f[i] = v / w[i][i];
    }
    dy[..N].copy_from_slice(&y[N..]);
    dy[N..].copy_from_slice(&f);
}

/// The benchmark systems, in the order of the tables.
pub fn benchmark_systems() -> Vec<System> {
    vec![oscillator(), pendulum(), kepler(), double_pendulum(), chain(5), chain(10)]
}

/// A small deterministic generator (SplitMix64) so tests need no extra crate.
pub struct Rng(pub u64);

impl Rng {
    pub fn next_u64(&mut self) -> u64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^ (z >> 31)
    }
    /// Uniform in `[lo, hi)`.
    pub fn uniform(&mut self, lo: f64, hi: f64) -> f64 {
        lo + (hi - lo) * (self.next_u64() >> 11) as f64 / (1u64 << 53) as f64
    }
}

/// Distance in units in the last place between two finite doubles of the same sign
/// (counting representable values between them); `u64::MAX` when the signs differ.
pub fn ulps(a: f64, b: f64) -> u64 {
    if a == b {
        return 0;
    }
    if a.is_sign_negative() != b.is_sign_negative() {
        return u64::MAX;
    }
    a.abs().to_bits().abs_diff(b.abs().to_bits())
}
