//! The value type of batch arithmetic: one `f64` for a single run, or [`Lanes<B>`], `B`
//! independent runs side by side (one initial condition per lane). The Taylor interpreter
//! computes with it (`compile/taylor`), and so does the batch Taylor step (`integrate/batch.rs`).
//!
//! Why one generic interpreter rather than a second, vectorised one: every operation of
//! [`Lanes`] is the `f64` operation applied lane by lane, in the same order, so lane `i` of a
//! batch expansion computes exactly the floating-point operations of a scalar expansion from
//! lane `i`'s state, and gets the same bits (the scalar interpreter, in turn, gives the same
//! bits as the native code). The batch is then a pure speed-up: one pass over the tape does
//! the work of `B`, the interpreter's dispatch is paid once for `B` expansions, and the lane
//! loops are what the compiler turns into SIMD instructions. No fused multiply-add is ever
//! formed (Rust does not contract `a * b + c`), so the lanes cannot drift from the scalar path.

// The lane loops index several arrays in step, as the compiler vectorises them best.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, AddAssign, Div, Mul, Neg, Sub, SubAssign};

/// A value of the Taylor interpreter: `f64`, or [`Lanes`] of them.
pub trait Lane:
    Copy
    + Add<Output = Self>
    + Sub<Output = Self>
    + Mul<Output = Self>
    + Div<Output = Self>
    + Neg<Output = Self>
    + AddAssign
    + SubAssign
{
    /// The number of lanes.
    const WIDTH: usize;
    /// Every lane `x`.
    fn splat(x: f64) -> Self;
    /// Lane `i`.
    fn lane(self, i: usize) -> f64;
    /// Sets lane `i`.
    fn set_lane(&mut self, i: usize, x: f64);
    /// `f` applied lane by lane.
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        let mut out = self;
        for i in 0..Self::WIDTH {
            out.set_lane(i, f(self.lane(i)));
        }
        out
    }
    /// `f` applied lane by lane to two values.
    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let mut out = self;
        for i in 0..Self::WIDTH {
            out.set_lane(i, f(self.lane(i), other.lane(i)));
        }
        out
    }
    /// `f` applied lane by lane, with two results.
    #[inline(always)]
    fn map2(self, f: impl Fn(f64) -> (f64, f64)) -> (Self, Self) {
        let (mut a, mut b) = (self, self);
        for i in 0..Self::WIDTH {
            let (x, y) = f(self.lane(i));
            a.set_lane(i, x);
            b.set_lane(i, y);
        }
        (a, b)
    }
}

impl Lane for f64 {
    const WIDTH: usize = 1;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        x
    }
    #[inline(always)]
    fn lane(self, _: usize) -> f64 {
        self
    }
    #[inline(always)]
    fn set_lane(&mut self, _: usize, x: f64) {
        *self = x;
    }
    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        f(self)
    }
    #[inline(always)]
    fn zip(self, other: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        f(self, other)
    }
    #[inline(always)]
    fn map2(self, f: impl Fn(f64) -> (f64, f64)) -> (Self, Self) {
        f(self)
    }
}

/// `B` values, one per lane, operated on lane by lane.
#[derive(Clone, Copy, Debug, PartialEq)]
#[repr(C, align(64))]
pub struct Lanes<const B: usize>(pub [f64; B]);

macro_rules! lanewise {
    ($tr:ident, $f:ident, $assign_tr:ident, $assign_f:ident, $op:tt) => {
        impl<const B: usize> $tr for Lanes<B> {
            type Output = Self;
            #[inline(always)]
            fn $f(self, o: Self) -> Self {
                let mut out = self.0;
                for i in 0..B {
                    out[i] = self.0[i] $op o.0[i];
                }
                Lanes(out)
            }
        }
        impl<const B: usize> $assign_tr for Lanes<B> {
            #[inline(always)]
            fn $assign_f(&mut self, o: Self) {
                for i in 0..B {
                    self.0[i] = self.0[i] $op o.0[i];
                }
            }
        }
    };
}
lanewise!(Add, add, AddAssign, add_assign, +);
lanewise!(Sub, sub, SubAssign, sub_assign, -);

impl<const B: usize> Mul for Lanes<B> {
    type Output = Self;
    #[inline(always)]
    fn mul(self, o: Self) -> Self {
        let mut out = self.0;
        for i in 0..B {
            out[i] = self.0[i] * o.0[i];
        }
        Lanes(out)
    }
}

impl<const B: usize> Div for Lanes<B> {
    type Output = Self;
    #[inline(always)]
    fn div(self, o: Self) -> Self {
        let mut out = self.0;
        for i in 0..B {
            out[i] = self.0[i] / o.0[i];
        }
        Lanes(out)
    }
}

impl<const B: usize> Neg for Lanes<B> {
    type Output = Self;
    #[inline(always)]
    fn neg(self) -> Self {
        let mut out = self.0;
        for x in &mut out {
            *x = -*x;
        }
        Lanes(out)
    }
}

impl<const B: usize> Lane for Lanes<B> {
    const WIDTH: usize = B;
    #[inline(always)]
    fn splat(x: f64) -> Self {
        Lanes([x; B])
    }
    #[inline(always)]
    fn lane(self, i: usize) -> f64 {
        self.0[i]
    }
    #[inline(always)]
    fn set_lane(&mut self, i: usize, x: f64) {
        self.0[i] = x;
    }
}
