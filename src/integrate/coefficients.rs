//! Every scheme as coefficient data, with its literature reference.
//!
//! Composition and splitting coefficients are stored to 40 significant digits, derived by
//! `scripts/integrator_coefficients.py` (Newton's method on the Baker–Campbell–Hausdorff order
//! conditions in 50-digit arithmetic, started from the published 15-digit values; the script
//! prints how far the published values were from an exact solution). Rust rounds each literal
//! to the nearest double, so the stored doubles are the correctly rounded exact coefficients;
//! the long literals document where they came from. Runge–Kutta tableaux that have closed
//! forms (RK4, Gauss–Legendre) are computed from them; DOP853 is Hairer's published data.
#![allow(clippy::excessive_precision)] // the digits are the provenance, see above

/// How a splitting scheme is built.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SplittingKind {
    /// A symmetric composition `S(w_m h) … S(w_1 h) S(w_0 h) S(w_1 h) … S(w_m h)` of the
    /// Störmer–Verlet step `S` (half kick, drift, half kick). `weights` lists the full
    /// palindromic sequence.
    VerletComposition {
        /// The step-size factors of the Verlet sub-steps, in order.
        weights: &'static [f64],
    },
    /// An explicit sequence of flows: `kick(b_0 h) drift(a_0 h) kick(b_1 h) drift(a_1 h) …`,
    /// ending with a kick when `kicks.len() == drifts.len() + 1`.
    KickDrift {
        /// Kick coefficients `b_i`.
        kicks: &'static [f64],
        /// Drift coefficients `a_i`.
        drifts: &'static [f64],
    },
}

/// A splitting method for separable Hamiltonians, as data.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SplittingScheme {
    /// Short name used in tables and plots.
    pub name: &'static str,
    /// Classical order of accuracy.
    pub order: u32,
    /// `true` when the step map is symmetric (time-reversible): `Φ_{-h} = Φ_h^{-1}`.
    pub symmetric: bool,
    /// The coefficients.
    pub kind: SplittingKind,
    /// Where the coefficients come from.
    pub reference: &'static str,
}

/// Symplectic Euler, `p ← p − h ∂V/∂q(q)`, then `q ← q + h ∂T/∂p(p)` (PHYSICS.md §4.7.2).
pub const SYMPLECTIC_EULER: SplittingScheme = SplittingScheme {
    name: "symplectic Euler",
    order: 1,
    symmetric: false,
    kind: SplittingKind::KickDrift { kicks: &[1.0], drifts: &[1.0] },
    reference: "Hairer, Lubich, Wanner, Geometric Numerical Integration (2006), Thm. VI.3.3",
};

/// Störmer–Verlet / leapfrog, kick–drift–kick form.
pub const LEAPFROG: SplittingScheme = SplittingScheme {
    name: "leapfrog",
    order: 2,
    symmetric: true,
    kind: SplittingKind::VerletComposition { weights: &[1.0] },
    reference: "Verlet, Phys. Rev. 159 (1967) 98; Hairer, Lubich, Wanner, Acta Numerica 12 (2003) 399",
};

/// Yoshida's 4th order "triple jump": `w_1 = 1/(2 − 2^{1/3})`, `w_0 = −2^{1/3} w_1`.
pub const YOSHIDA4_W1: f64 = 1.351207191959657634047687808971460826922;
/// The central weight of [`YOSHIDA4`].
pub const YOSHIDA4_W0: f64 = -1.702414383919315268095375617942921653844;

/// Yoshida's 4th-order composition (closed form, see [`YOSHIDA4_W1`]).
pub const YOSHIDA4: SplittingScheme = SplittingScheme {
    name: "Yoshida 4",
    order: 4,
    symmetric: true,
    kind: SplittingKind::VerletComposition { weights: &[YOSHIDA4_W1, YOSHIDA4_W0, YOSHIDA4_W1] },
    reference: "Yoshida, Phys. Lett. A 150 (1990) 262, eq. (4.10); Forest & Ruth, Physica D 43 (1990) 105",
};

const Y6_W1: f64 = -1.177679984178871006946415680964315734639;
const Y6_W2: f64 = 0.2355732133593581336847931829785346016865;
const Y6_W3: f64 = 0.7845136104775572638194976338663498757768;
const Y6_W0: f64 = 1.315186320683911218884249728238862514352;

/// Yoshida's 6th-order composition, 7 Verlet stages, solution A of Table 1.
pub const YOSHIDA6: SplittingScheme = SplittingScheme {
    name: "Yoshida 6",
    order: 6,
    symmetric: true,
    kind: SplittingKind::VerletComposition { weights: &[Y6_W3, Y6_W2, Y6_W1, Y6_W0, Y6_W1, Y6_W2, Y6_W3] },
    reference: "Yoshida, Phys. Lett. A 150 (1990) 262, Table 1, solution A (polished to 40 digits)",
};

const Y8_W1: f64 = 0.102799849391796440698115131601225862911;
const Y8_W2: f64 = -1.960610232975310807607633376399663640792;
const Y8_W3: f64 = 1.938139137622525986579186487443641760954;
const Y8_W4: f64 = -0.1582406353680501752040667767597542477554;
const Y8_W5: f64 = -1.444852236860605157694730657537390354956;
const Y8_W6: f64 = 0.2536933365662113541461460206899420760977;
const Y8_W7: f64 = 0.9148442462297915667487934898475096045181;
const Y8_W0: f64 = 1.708453070787281584668379362228977878047;

/// Yoshida's 8th-order composition, 15 Verlet stages, solution D of Table 2 (of Yoshida's
/// five 15-stage solutions the one with the smallest error: on Kepler e = 0.9 it is ~10⁴
/// times more accurate than solution A at equal step, see BENCHMARKS.md). The
/// published 15-digit values violate the order conditions by 3e-12; these are the exact
/// solution next to them.
pub const YOSHIDA8: SplittingScheme = SplittingScheme {
    name: "Yoshida 8",
    order: 8,
    symmetric: true,
    kind: SplittingKind::VerletComposition {
        weights: &[
            Y8_W7, Y8_W6, Y8_W5, Y8_W4, Y8_W3, Y8_W2, Y8_W1, Y8_W0, Y8_W1, Y8_W2, Y8_W3, Y8_W4, Y8_W5, Y8_W6, Y8_W7,
        ],
    },
    reference: "Yoshida, Phys. Lett. A 150 (1990) 262, Table 2, solution D (polished to 40 digits)",
};

const BM_A1: f64 = 0.245298957184271;
const BM_A2: f64 = 0.604872665711094423109328512782106074715;
const BM_A3: f64 = -0.350171622895365423109328512782106074715;
const BM_B1: f64 = 0.0829844064174052;
const BM_B2: f64 = 0.396309801498368;
const BM_B3: f64 = -0.03905630492234584477961967727001231562165;
const BM_B4: f64 = 0.1195241940131452895592393545400246312433;

/// Blanes & Moan's optimised 4th-order symmetric splitting with six force evaluations per
/// step (`SRKN_6^b`, kick first). `a_1, b_1, b_2` are the published optimised values; `a_2`,
/// `b_3` solve the order conditions exactly (they differ from the published ones by 1e-14);
/// `a_3 = 1/2 − a_1 − a_2`, `b_4 = 1 − 2(b_1 + b_2 + b_3)`.
pub const BLANES_MOAN4: SplittingScheme = SplittingScheme {
    name: "Blanes-Moan 4",
    order: 4,
    symmetric: true,
    kind: SplittingKind::KickDrift {
        kicks: &[BM_B1, BM_B2, BM_B3, BM_B4, BM_B3, BM_B2, BM_B1],
        drifts: &[BM_A1, BM_A2, BM_A3, BM_A3, BM_A2, BM_A1],
    },
    reference: "Blanes & Moan, J. Comput. Appl. Math. 142 (2002) 313, method SRKN_6^b",
};

const KL6_G1: f64 = 0.39216144400731413927925056;
const KL6_G2: f64 = 0.33259913678935943859974864;
const KL6_G3: f64 = -0.70624617255763935980996482;
const KL6_G4: f64 = 0.08221359629355080023149045;
const KL6_G5: f64 = 0.79854399093482996339895035;

/// Kahan & Li's 6th-order symmetric composition of Verlet with 9 stages (`s9odr6a`): two
/// stages more than Yoshida's 6th order, with coefficients chosen to make the error constant small
/// (Hairer, Lubich, Wanner, Geometric Numerical Integration (2006), §V.3.2, eq. (3.11)).
pub const KAHAN_LI6: SplittingScheme = SplittingScheme {
    name: "Kahan-Li 6",
    order: 6,
    symmetric: true,
    kind: SplittingKind::VerletComposition {
        weights: &[KL6_G1, KL6_G2, KL6_G3, KL6_G4, KL6_G5, KL6_G4, KL6_G3, KL6_G2, KL6_G1],
    },
    reference: "Kahan & Li, Math. Comp. 66 (1997) 1089, s9odr6a; Hairer, Lubich, Wanner (2006) eq. V.3.11",
};

// Kahan & Li's `s15odr8` weights, as tabulated by Hairer, Lubich & Wanner (2006), §V.3.2:
// γ1 … γ7 and the middle γ8; the rest mirror them.
const KL8_G: [f64; 8] = [
    0.74167036435061295344822780,
    -0.40910082580003159399730010,
    0.19075471029623837995387626,
    -0.57386247111608226665638773,
    0.29906418130365592384446354,
    0.33462491824529818378495798,
    0.31529309239676659663205666,
    -0.79688793935291635401978884,
];

/// Kahan & Li's 8th-order symmetric composition of Verlet with 15 stages (`s15odr8`): two
/// stages more than Yoshida's 8th order, bought back by a much smaller error constant
/// (Hairer, Lubich, Wanner, Geometric Numerical Integration (2006), §V.3.2).
pub const KAHAN_LI8: SplittingScheme = SplittingScheme {
    name: "Kahan-Li 8",
    order: 8,
    symmetric: true,
    kind: SplittingKind::VerletComposition {
        weights: &[
            KL8_G[0], KL8_G[1], KL8_G[2], KL8_G[3], KL8_G[4], KL8_G[5], KL8_G[6], KL8_G[7], KL8_G[6], KL8_G[5],
            KL8_G[4], KL8_G[3], KL8_G[2], KL8_G[1], KL8_G[0],
        ],
    },
    reference: "Kahan & Li, Math. Comp. 66 (1997) 1089, s15odr8; Hairer, Lubich, Wanner (2006) §V.3.2",
};

/// All splitting schemes, for tests and benchmarks.
pub const SPLITTING_SCHEMES: [&SplittingScheme; 8] =
    [&SYMPLECTIC_EULER, &LEAPFROG, &YOSHIDA4, &BLANES_MOAN4, &YOSHIDA6, &KAHAN_LI6, &YOSHIDA8, &KAHAN_LI8];

/// A Butcher tableau `(A, b, c)` with `s` stages, row-major `a[i * s + j]`.
#[derive(Debug, Clone, PartialEq)]
pub struct Tableau {
    /// Short name.
    pub name: &'static str,
    /// Classical order.
    pub order: u32,
    /// Number of stages `s`.
    pub stages: usize,
    /// The `s × s` matrix `A`, row-major.
    pub a: Vec<f64>,
    /// The weights `b`.
    pub b: Vec<f64>,
    /// The nodes `c`.
    pub c: Vec<f64>,
    /// `true` for a symplectic (`b_i a_ij + b_j a_ji = b_i b_j`) method.
    pub symplectic: bool,
    /// `true` for a symmetric method.
    pub symmetric: bool,
    /// Where it comes from.
    pub reference: &'static str,
}

impl Tableau {
    /// Name, order and properties of the fixed-step method this tableau defines.
    pub fn info(&self) -> super::MethodInfo {
        super::MethodInfo {
            name: self.name,
            order: self.order,
            symplectic: self.symplectic,
            symmetric: self.symmetric,
            adaptive: false,
        }
    }

    /// Forward Euler.
    pub fn euler() -> Tableau {
        Tableau {
            name: "Euler",
            order: 1,
            stages: 1,
            a: vec![0.0],
            b: vec![1.0],
            c: vec![0.0],
            symplectic: false,
            symmetric: false,
            reference: "Euler, Institutiones calculi integralis (1768)",
        }
    }

    /// The classical 4th-order Runge–Kutta method.
    pub fn rk4() -> Tableau {
        #[rustfmt::skip]
        let a = vec![
            0.0, 0.0, 0.0, 0.0,
            0.5, 0.0, 0.0, 0.0,
            0.0, 0.5, 0.0, 0.0,
            0.0, 0.0, 1.0, 0.0,
        ];
        Tableau {
            name: "RK4",
            order: 4,
            stages: 4,
            a,
            b: vec![1.0 / 6.0, 1.0 / 3.0, 1.0 / 3.0, 1.0 / 6.0],
            c: vec![0.0, 0.5, 0.5, 1.0],
            symplectic: false,
            symmetric: false,
            reference: "Kutta, Z. Math. Phys. 46 (1901) 435",
        }
    }

    /// The implicit midpoint rule (one-stage Gauss–Legendre collocation).
    pub fn implicit_midpoint() -> Tableau {
        Tableau {
            name: "implicit midpoint",
            order: 2,
            stages: 1,
            a: vec![0.5],
            b: vec![1.0],
            c: vec![0.5],
            symplectic: true,
            symmetric: true,
            reference: "Hairer, Lubich, Wanner, Geometric Numerical Integration (2006), II.1.1",
        }
    }

    /// Two-stage Gauss–Legendre collocation, order 4 (closed form with `√3`).
    pub fn gauss4() -> Tableau {
        let r = 3f64.sqrt() / 6.0;
        Tableau {
            name: "Gauss 4",
            order: 4,
            stages: 2,
            a: vec![0.25, 0.25 - r, 0.25 + r, 0.25],
            b: vec![0.5, 0.5],
            c: vec![0.5 - r, 0.5 + r],
            symplectic: true,
            symmetric: true,
            reference: "Butcher, Math. Comp. 18 (1964) 50; Hairer & Wanner, Solving ODEs II, Table IV.5.2",
        }
    }

    /// Three-stage Gauss–Legendre collocation, order 6 (closed form with `√15`).
    pub fn gauss6() -> Tableau {
        let s = 15f64.sqrt();
        #[rustfmt::skip]
        let a = vec![
            5.0 / 36.0,            2.0 / 9.0 - s / 15.0, 5.0 / 36.0 - s / 30.0,
            5.0 / 36.0 + s / 24.0, 2.0 / 9.0,            5.0 / 36.0 - s / 24.0,
            5.0 / 36.0 + s / 30.0, 2.0 / 9.0 + s / 15.0, 5.0 / 36.0,
        ];
        Tableau {
            name: "Gauss 6",
            order: 6,
            stages: 3,
            a,
            b: vec![5.0 / 18.0, 4.0 / 9.0, 5.0 / 18.0],
            c: vec![0.5 - s / 10.0, 0.5, 0.5 + s / 10.0],
            symplectic: true,
            symmetric: true,
            reference: "Butcher, Math. Comp. 18 (1964) 50; Hairer & Wanner, Solving ODEs II, Table IV.5.3",
        }
    }

    /// Entry `a_ij`.
    pub fn a(&self, i: usize, j: usize) -> f64 {
        self.a[i * self.stages + j]
    }
}

/// Dormand–Prince 8(5,3), the coefficients of Hairer's `dop853.f` (version of 2004; Hairer,
/// Nørsett, Wanner, *Solving Ordinary Differential Equations I*, 2nd ed., Springer 1993,
/// Sect. II.10; the method of Dormand & Prince, J. Comput. Appl. Math. 6 (1980) 19, with
/// Hairer's 5th- and 3rd-order error estimators and 7th-order dense output).
///
/// Stages are numbered from 0: stages 0–11 form the step, stage 12 is `f(t + h, y_{n+1})`
/// (reused as stage 0 of the next step), stages 13–15 are evaluated only for dense output.
/// Row `i` of [`dop853::A`] lists the non-zero `(j, a_ij)`; row 12 is the weight vector `b`.
pub mod dop853 {
    /// Nodes `c_i`.
    pub const C: [f64; 16] = [
        0.0,
        0.526001519587677318785587544488e-01,
        0.789002279381515978178381316732e-01,
        0.118350341907227396726757197510,
        0.281649658092772603273242802490,
        0.333333333333333333333333333333,
        0.25,
        0.307692307692307692307692307692,
        0.651282051282051282051282051282,
        0.6,
        0.857142857142857142857142857142,
        1.0,
        1.0,
        0.1,
        0.2,
        0.777777777777777777777777777778,
    ];

    /// The stage matrix, sparse rows `(j, a_ij)`.
    pub const A: [&[(usize, f64)]; 16] = [
        &[],
        &[(0, 5.26001519587677318785587544488e-2)],
        &[(0, 1.97250569845378994544595329183e-2), (1, 5.91751709536136983633785987549e-2)],
        &[(0, 2.95875854768068491816892993775e-2), (2, 8.87627564304205475450678981324e-2)],
        &[
            (0, 2.41365134159266685502369798665e-1),
            (2, -8.84549479328286085344864962717e-1),
            (3, 9.24834003261792003115737966543e-1),
        ],
        &[
            (0, 3.7037037037037037037037037037e-2),
            (3, 1.70828608729473871279604482173e-1),
            (4, 1.25467687566822425016691814123e-1),
        ],
        &[
            (0, 3.7109375e-2),
            (3, 1.70252211019544039314978060272e-1),
            (4, 6.02165389804559606850219397283e-2),
            (5, -1.7578125e-2),
        ],
        &[
            (0, 3.70920001185047927108779319836e-2),
            (3, 1.70383925712239993810214054705e-1),
            (4, 1.07262030446373284651809199168e-1),
            (5, -1.53194377486244017527936158236e-2),
            (6, 8.27378916381402288758473766002e-3),
        ],
        &[
            (0, 6.24110958716075717114429577812e-1),
            (3, -3.36089262944694129406857109825),
            (4, -8.68219346841726006818189891453e-1),
            (5, 2.75920996994467083049415600797e1),
            (6, 2.01540675504778934086186788979e1),
            (7, -4.34898841810699588477366255144e1),
        ],
        &[
            (0, 4.77662536438264365890433908527e-1),
            (3, -2.48811461997166764192642586468),
            (4, -5.90290826836842996371446475743e-1),
            (5, 2.12300514481811942347288949897e1),
            (6, 1.52792336328824235832596922938e1),
            (7, -3.32882109689848629194453265587e1),
            (8, -2.03312017085086261358222928593e-2),
        ],
        &[
            (0, -9.3714243008598732571704021658e-1),
            (3, 5.18637242884406370830023853209),
            (4, 1.09143734899672957818500254654),
            (5, -8.14978701074692612513997267357),
            (6, -1.85200656599969598641566180701e1),
            (7, 2.27394870993505042818970056734e1),
            (8, 2.49360555267965238987089396762),
            (9, -3.0467644718982195003823669022),
        ],
        &[
            (0, 2.27331014751653820792359768449),
            (3, -1.05344954667372501984066689879e1),
            (4, -2.00087205822486249909675718444),
            (5, -1.79589318631187989172765950534e1),
            (6, 2.79488845294199600508499808837e1),
            (7, -2.85899827713502369474065508674),
            (8, -8.87285693353062954433549289258),
            (9, 1.23605671757943030647266201528e1),
            (10, 6.43392746015763530355970484046e-1),
        ],
        &[
            (0, 5.42937341165687622380535766363e-2),
            (5, 4.45031289275240888144113950566),
            (6, 1.89151789931450038304281599044),
            (7, -5.8012039600105847814672114227),
            (8, 3.1116436695781989440891606237e-1),
            (9, -1.52160949662516078556178806805e-1),
            (10, 2.01365400804030348374776537501e-1),
            (11, 4.47106157277725905176885569043e-2),
        ],
        &[
            (0, 5.61675022830479523392909219681e-2),
            (6, 2.53500210216624811088794765333e-1),
            (7, -2.46239037470802489917441475441e-1),
            (8, -1.24191423263816360469010140626e-1),
            (9, 1.5329179827876569731206322685e-1),
            (10, 8.20105229563468988491666602057e-3),
            (11, 7.56789766054569976138603589584e-3),
            (12, -8.298e-3),
        ],
        &[
            (0, 3.18346481635021405060768473261e-2),
            (5, 2.83009096723667755288322961402e-2),
            (6, 5.35419883074385676223797384372e-2),
            (7, -5.49237485713909884646569340306e-2),
            (10, -1.08347328697249322858509316994e-4),
            (11, 3.82571090835658412954920192323e-4),
            (12, -3.40465008687404560802977114492e-4),
            (13, 1.41312443674632500278074618366e-1),
        ],
        &[
            (0, -4.28896301583791923408573538692e-1),
            (5, -4.69762141536116384314449447206),
            (6, 7.68342119606259904184240953878),
            (7, 4.06898981839711007970213554331),
            (8, 3.56727187455281109270669543021e-1),
            (12, -1.39902416515901462129418009734e-3),
            (13, 2.9475147891527723389556272149),
            (14, -9.15095847217987001081870187138),
        ],
    ];

    /// Weights of the embedded 3rd-order solution (`bhh1`, `bhh2`, `bhh3` on stages 0, 8, 11).
    pub const BHH: [(usize, f64); 3] = [
        (0, 0.244094488188976377952755905512),
        (8, 0.733846688281611857341361741547),
        (11, 0.220588235294117647058823529412e-1),
    ];

    /// The 5th-order error estimator `er_i` (the difference of the 8th- and a 5th-order
    /// solution, so the entries sum to zero).
    pub const ER: [(usize, f64); 8] = [
        (0, 0.1312004499419488073250102996e-1),
        (5, -0.1225156446376204440720569753e1),
        (6, -0.4957589496572501915214079952),
        (7, 0.1664377182454986536961530415e1),
        (8, -0.3503288487499736816886487290),
        (9, 0.3341791187130174790297318841),
        (10, 0.8192320648511571246570742613e-1),
        (11, -0.2235530786388629525884427845e-1),
    ];

    /// Dense-output rows `d4`–`d7` over stages 0–15 (columns 1–4 are zero).
    pub const D: [[f64; 16]; 4] = [
        [
            -0.84289382761090128651353491142e1,
            0.0,
            0.0,
            0.0,
            0.0,
            0.56671495351937776962531783590,
            -0.30689499459498916912797304727e1,
            0.23846676565120698287728149680e1,
            0.21170345824450282767155149946e1,
            -0.87139158377797299206789907490,
            0.22404374302607882758541771650e1,
            0.63157877876946881815570249290,
            -0.88990336451333310820698117400e-1,
            0.18148505520854727256656404962e2,
            -0.91946323924783554000451984436e1,
            -0.44360363875948939664310572000e1,
        ],
        [
            0.10427508642579134603413151009e2,
            0.0,
            0.0,
            0.0,
            0.0,
            0.24228349177525818288430175319e3,
            0.16520045171727028198505394887e3,
            -0.37454675472269020279518312152e3,
            -0.22113666853125306036270938578e2,
            0.77334326684722638389603898808e1,
            -0.30674084731089398182061213626e2,
            -0.93321305264302278729567221706e1,
            0.15697238121770843886131091075e2,
            -0.31139403219565177677282850411e2,
            -0.93529243588444783865713862664e1,
            0.35816841486394083752465898540e2,
        ],
        [
            0.19985053242002433820987653617e2,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.38703730874935176555105901742e3,
            -0.18917813819516756882830838328e3,
            0.52780815920542364900561016686e3,
            -0.11573902539959630126141871134e2,
            0.68812326946963000169666922661e1,
            -0.10006050966910838403183860980e1,
            0.77771377980534432092869265740,
            -0.27782057523535084065932004339e1,
            -0.60196695231264120758267380846e2,
            0.84320405506677161018159903784e2,
            0.11992291136182789328035130030e2,
        ],
        [
            -0.25693933462703749003312586129e2,
            0.0,
            0.0,
            0.0,
            0.0,
            -0.15418974869023643374053993627e3,
            -0.23152937917604549567536039109e3,
            0.35763911791061412378285349910e3,
            0.93405324183624310003907691704e2,
            -0.37458323136451633156875139351e2,
            0.10409964950896230045147246184e3,
            0.29840293426660503123344363579e2,
            -0.43533456590011143754432175058e2,
            0.96324553959188282948394950600e2,
            -0.39177261675615439165231486172e2,
            -0.14972683625798562581422125276e3,
        ],
    ];
}
