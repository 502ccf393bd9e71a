//! Where the kernels read their triangle pairs from.
//!
//! A slice of `(Triangle, Triangle)` is the simple case. Contact detection
//! keeps its triangles in a set and finds pairs as indices into it; copying
//! every culled pair into a slice before the kernels pack it again into
//! SIMD batches cost some 10% of a hopper run (memmove and the copy loop,
//! profiled). The kernels read through this trait instead, so they pack
//! straight from wherever the triangles are.

use super::Triangle;
use std::ops::Range;

/// An indexed sequence of triangle pairs.
pub trait PairSource: Sync {
    fn len(&self) -> usize;

    fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Pair `k`, for `k < len()`.
    fn pair(&self, k: usize) -> (&Triangle, &Triangle);
}

impl PairSource for [(Triangle, Triangle)] {
    #[inline]
    fn len(&self) -> usize {
        <[_]>::len(self)
    }

    #[inline]
    fn pair(&self, k: usize) -> (&Triangle, &Triangle) {
        let (a, b) = &self[k];
        (a, b)
    }
}

impl PairSource for Vec<(Triangle, Triangle)> {
    #[inline]
    fn len(&self) -> usize {
        Vec::len(self)
    }

    #[inline]
    fn pair(&self, k: usize) -> (&Triangle, &Triangle) {
        self.as_slice().pair(k)
    }
}

/// The pairs `range` of a source, numbered from 0.
pub(crate) struct Window<'a, P: ?Sized> {
    src: &'a P,
    start: usize,
    len: usize,
}

impl<'a, P: PairSource + ?Sized> Window<'a, P> {
    pub(crate) fn new(src: &'a P, range: Range<usize>) -> Self {
        assert!(range.start <= range.end && range.end <= src.len());
        Window {
            src,
            start: range.start,
            len: range.len(),
        }
    }
}

impl<P: PairSource + ?Sized> PairSource for Window<'_, P> {
    #[inline]
    fn len(&self) -> usize {
        self.len
    }

    #[inline]
    fn pair(&self, k: usize) -> (&Triangle, &Triangle) {
        debug_assert!(k < self.len);
        self.src.pair(self.start + k)
    }
}

/// The windows of `chunk` pairs (the last one shorter) covering `0..len`.
pub(crate) fn chunk_ranges(len: usize, chunk: usize) -> impl Iterator<Item = Range<usize>> {
    (0..len)
        .step_by(chunk.max(1))
        .map(move |s| s..(s + chunk).min(len))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    #[test]
    fn windows_read_the_pairs_they_cover() {
        let t = |x: f64| [DVec3::splat(x); 3];
        let pairs: Vec<(Triangle, Triangle)> =
            (0..10).map(|i| (t(i as f64), t(-(i as f64)))).collect();
        let ranges: Vec<_> = chunk_ranges(10, 4).collect();
        assert_eq!(ranges, vec![0..4, 4..8, 8..10]);
        let w = Window::new(&pairs, 4..8);
        let inner = Window::new(&w, 1..3);
        assert_eq!(inner.len(), 2);
        assert_eq!(inner.pair(1).0[0].x, 6.0);
        assert_eq!(inner.pair(0).1[2].x, -5.0);
        assert!(Window::new(&pairs, 3..3).is_empty());
    }
}
