//! Arithmetic on `N` lanes at once: the vector type the SIMD kernels are
//! written in.
//!
//! `F<N>` holds one f64 per lane (one triangle pair per lane); every operation
//! is a loop over the lanes with nothing else in it, which the compiler turns
//! into vector instructions reliably (one per register width) inside the
//! `#[target_feature]` wrappers of each kernel. Long loop bodies written lane
//! by lane do not vectorise reliably; kernels written on `F<N>` read like the
//! scalar math and vectorise operation by operation. `F<1>` is the scalar
//! version of the same code, which the benchmarks compare against.

// Index loops over the lanes are the shape the vectoriser recognises best.
#![allow(clippy::needless_range_loop)]

use std::ops::{Add, BitAnd, BitOr, Div, Mul, Neg, Not, Sub};

/// One f64 per lane.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct F<const N: usize>(pub [f64; N]);

/// One flag per lane, as a full-width integer: all ones (set) or zero.
///
/// Not `[bool; N]`: LLVM packs eight bools into one 64-bit integer and then
/// computes mask logic with scalar bit tricks and shuffles (profiled: a third
/// of the penalty kernel's time went there). Lanes of the same width as `F`'s
/// become vector compares, `vpand`/`vpor` and blends (or AVX-512 mask registers).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct M<const N: usize>([u64; N]);

impl<const N: usize> F<N> {
    #[inline(always)]
    pub fn splat(x: f64) -> Self {
        F([x; N])
    }

    #[inline(always)]
    fn map(self, f: impl Fn(f64) -> f64) -> Self {
        let mut r = [0.0; N];
        for i in 0..N {
            r[i] = f(self.0[i]);
        }
        F(r)
    }

    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(f64, f64) -> f64) -> Self {
        let mut r = [0.0; N];
        for i in 0..N {
            r[i] = f(self.0[i], o.0[i]);
        }
        F(r)
    }

    #[inline(always)]
    fn test(self, o: Self, f: impl Fn(f64, f64) -> bool) -> M<N> {
        let mut r = [0; N];
        for i in 0..N {
            r[i] = if f(self.0[i], o.0[i]) { SET } else { 0 };
        }
        M(r)
    }

    #[inline(always)]
    pub fn max(self, o: Self) -> Self {
        self.zip(o, f64::max)
    }

    #[inline(always)]
    pub fn min(self, o: Self) -> Self {
        self.zip(o, f64::min)
    }

    #[inline(always)]
    pub fn abs(self) -> Self {
        self.map(f64::abs)
    }

    #[inline(always)]
    pub fn sqrt(self) -> Self {
        self.map(f64::sqrt)
    }

    #[inline(always)]
    pub fn lt(self, o: Self) -> M<N> {
        self.test(o, |a, b| a < b)
    }

    #[inline(always)]
    pub fn le(self, o: Self) -> M<N> {
        self.test(o, |a, b| a <= b)
    }

    #[inline(always)]
    pub fn gt(self, o: Self) -> M<N> {
        self.test(o, |a, b| a > b)
    }

    #[inline(always)]
    pub fn ge(self, o: Self) -> M<N> {
        self.test(o, |a, b| a >= b)
    }

    /// Finite (neither infinite nor NaN).
    #[inline(always)]
    pub fn finite(self) -> M<N> {
        // |x| < inf is false for NaN and infinities, and is one comparison.
        self.abs().lt(F::splat(f64::INFINITY))
    }
}

/// The bit pattern of a set lane of [`M`].
const SET: u64 = u64::MAX;

impl<const N: usize> M<N> {
    /// From one flag per lane.
    #[inline(always)]
    pub fn from_flags(flags: [bool; N]) -> Self {
        M(flags.map(|b| if b { SET } else { 0 }))
    }

    /// Whether lane `i` is set.
    #[inline(always)]
    pub fn lane(self, i: usize) -> bool {
        self.0[i] != 0
    }

    /// Every lane set.
    #[inline(always)]
    pub fn all(self) -> bool {
        let mut r = SET;
        for i in 0..N {
            r &= self.0[i];
        }
        r != 0
    }

    #[inline(always)]
    fn zip(self, o: Self, f: impl Fn(u64, u64) -> u64) -> Self {
        let mut r = [0; N];
        for i in 0..N {
            r[i] = f(self.0[i], o.0[i]);
        }
        M(r)
    }

    /// `a` where set, `b` elsewhere.
    #[inline(always)]
    pub fn select(self, a: F<N>, b: F<N>) -> F<N> {
        let mut r = [0.0; N];
        for i in 0..N {
            r[i] = if self.0[i] != 0 { a.0[i] } else { b.0[i] };
        }
        F(r)
    }

    /// 1 where set, 0 elsewhere.
    #[inline(always)]
    pub fn to_f(self) -> F<N> {
        self.select(F::splat(1.0), F::splat(0.0))
    }
}

macro_rules! binary {
    ($tr:ident, $f:ident, $op:tt) => {
        impl<const N: usize> $tr for F<N> {
            type Output = F<N>;
            #[inline(always)]
            fn $f(self, o: F<N>) -> F<N> {
                self.zip(o, |a, b| a $op b)
            }
        }
        impl<const N: usize> $tr<f64> for F<N> {
            type Output = F<N>;
            #[inline(always)]
            fn $f(self, o: f64) -> F<N> {
                self.map(|a| a $op o)
            }
        }
        impl<const N: usize> $tr<F<N>> for f64 {
            type Output = F<N>;
            #[inline(always)]
            fn $f(self, o: F<N>) -> F<N> {
                o.map(|b| self $op b)
            }
        }
    };
}
binary!(Add, add, +);
binary!(Sub, sub, -);
binary!(Mul, mul, *);
binary!(Div, div, /);

impl<const N: usize> Neg for F<N> {
    type Output = F<N>;
    #[inline(always)]
    fn neg(self) -> F<N> {
        self.map(|a| -a)
    }
}

impl<const N: usize> BitAnd for M<N> {
    type Output = M<N>;
    #[inline(always)]
    fn bitand(self, o: M<N>) -> M<N> {
        self.zip(o, |a, b| a & b)
    }
}

impl<const N: usize> BitOr for M<N> {
    type Output = M<N>;
    #[inline(always)]
    fn bitor(self, o: M<N>) -> M<N> {
        self.zip(o, |a, b| a | b)
    }
}

impl<const N: usize> Not for M<N> {
    type Output = M<N>;
    #[inline(always)]
    fn not(self) -> M<N> {
        let mut r = [0; N];
        for i in 0..N {
            r[i] = !self.0[i];
        }
        M(r)
    }
}

/// A 3-vector per lane.
#[derive(Clone, Copy, Debug)]
pub struct V3<const N: usize>(pub [F<N>; 3]);

impl<const N: usize> V3<N> {
    #[inline(always)]
    pub fn dot(self, o: Self) -> F<N> {
        self.0[0] * o.0[0] + self.0[1] * o.0[1] + self.0[2] * o.0[2]
    }

    #[inline(always)]
    pub fn cross(self, o: Self) -> Self {
        let [x, y, z] = self.0;
        let [a, b, c] = o.0;
        V3([y * c - z * b, z * a - x * c, x * b - y * a])
    }

    #[inline(always)]
    pub fn scale(self, s: F<N>) -> Self {
        V3([self.0[0] * s, self.0[1] * s, self.0[2] * s])
    }
}

impl<const N: usize> Add for V3<N> {
    type Output = V3<N>;
    #[inline(always)]
    fn add(self, o: V3<N>) -> V3<N> {
        V3([self.0[0] + o.0[0], self.0[1] + o.0[1], self.0[2] + o.0[2]])
    }
}

impl<const N: usize> Sub for V3<N> {
    type Output = V3<N>;
    #[inline(always)]
    fn sub(self, o: V3<N>) -> V3<N> {
        V3([self.0[0] - o.0[0], self.0[1] - o.0[1], self.0[2] - o.0[2]])
    }
}

impl<const N: usize> Neg for V3<N> {
    type Output = V3<N>;
    #[inline(always)]
    fn neg(self) -> V3<N> {
        V3([-self.0[0], -self.0[1], -self.0[2]])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lanes_compute_what_scalars_do() {
        let a = F([1.0, -2.0, 0.5, f64::NAN]);
        let b = F([3.0, 4.0, -0.25, 1.0]);
        assert_eq!((a + b).0[..3], [4.0, 2.0, 0.25]);
        assert_eq!((a * b).0[..3], [3.0, -8.0, -0.125]);
        assert_eq!(a.lt(b), M::from_flags([true, true, false, false]));
        assert!(!a.lt(b).all() && a.lt(b).lane(1));
        assert_eq!(a.finite(), M::from_flags([true, true, true, false]));
        assert_eq!(a.lt(b).select(a, b).0[..3], [1.0, -2.0, -0.25]);
        let x = V3([F([1.0]), F([0.0]), F([0.0])]);
        let y = V3([F([0.0]), F([1.0]), F([0.0])]);
        assert_eq!(x.cross(y).0[2].0, [1.0]);
    }
}
