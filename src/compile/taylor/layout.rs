//! Where a batch expansion keeps its values: one buffer of [`Lanes`](crate::lanes::Lanes) that the
//! interpreter's lanes and the wide code (`wide.rs`) share.

/// Where a batch expansion keeps its values, all in one buffer of [`Lanes`] so that the wide
/// code (`wide.rs`) reaches every one from one address: the tape's `rows` rows of `stride`
/// coefficients, then the accelerations' rows of a `W q'' = F` system (`n` rows, the same
/// stride), `W₀`'s factor (`n²` entries, row-major), its diagonal's reciprocals (`n`) and the
/// right-hand side of one order's solve (`n`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) struct BatchLayout {
    pub(super) rows: usize,
    pub(super) n: usize,
    pub(super) stride: usize,
}

impl BatchLayout {
    /// The row of acceleration `l`.
    pub(super) fn acc_row(&self, l: usize) -> usize {
        self.rows + l
    }
    /// Order `j` of acceleration `l`.
    pub(super) fn acc(&self, l: usize, j: usize) -> usize {
        self.acc_row(l) * self.stride + j
    }
    /// Entry `e` of `W₀`'s factor.
    pub(super) fn factor(&self, e: usize) -> usize {
        (self.rows + self.n) * self.stride + e
    }
    /// The reciprocal of the factor's diagonal entry `i`.
    pub(super) fn inv(&self, i: usize) -> usize {
        self.factor(self.n * self.n) + i
    }
    /// Entry `i` of the solve's right-hand side.
    pub(super) fn rhs(&self, i: usize) -> usize {
        self.inv(self.n) + i
    }
    /// The buffer's length.
    pub(super) fn len(&self) -> usize {
        self.rhs(self.n)
    }
}
