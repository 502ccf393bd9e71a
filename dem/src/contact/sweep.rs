//! The overlapping pairs between two lists of boxes, by sort and sweep along
//! one axis: O(n log n + m log m + k), where k counts the pairs whose
//! intervals on that axis overlap, against n · m box tests for every pair.
//!
//! Sort both lists by their boxes' low end on the axis. Walk the two lists in
//! merged order; each box met, from either list, is paired with the boxes of
//! the other list not yet met whose low end is within its interval; every
//! pair with overlapping intervals is found exactly once, by whichever of
//! its two boxes starts first (ties: the first list's), and kept if the
//! boxes overlap on the other two axes too. Between two meshes in contact
//! the triangles near the contact lie along a surface, so along the axis
//! across which the two boxes overlap most, k is close to the number of
//! overlapping pairs.

use super::bounds::Bounds;

/// Scratch of [`overlapping_pairs`], kept for its capacity.
#[derive(Debug, Default)]
pub(crate) struct Sweep {
    a: Vec<(f64, u32)>,
    b: Vec<(f64, u32)>,
}

impl Sweep {
    /// Calls `found(p, q)` for every position p of `a` and q of `b` whose
    /// boxes overlap (touching counts, as in [`Bounds::overlaps`]), sweeping
    /// along `axis` (0, 1 or 2). The order of the calls is a function of
    /// the boxes alone.
    pub(crate) fn overlapping_pairs(
        &mut self,
        a: &[Bounds],
        b: &[Bounds],
        axis: usize,
        mut found: impl FnMut(usize, usize),
    ) {
        let sorted = |boxes: &[Bounds], out: &mut Vec<(f64, u32)>| {
            out.clear();
            out.extend(
                boxes
                    .iter()
                    .enumerate()
                    .map(|(k, x)| (x.lo[axis], k as u32)),
            );
            out.sort_unstable_by(|x, y| x.0.total_cmp(&y.0).then(x.1.cmp(&y.1)));
        };
        sorted(a, &mut self.a);
        sorted(b, &mut self.b);
        let (sa, sb) = (&self.a, &self.b);
        let (mut i, mut j) = (0, 0);
        while i < sa.len() && j < sb.len() {
            if sa[i].0 <= sb[j].0 {
                let p = sa[i].1 as usize;
                let hi = a[p].hi[axis];
                for &(_, q) in sb[j..].iter().take_while(|e| e.0 <= hi) {
                    if a[p].overlaps(&b[q as usize]) {
                        found(p, q as usize);
                    }
                }
                i += 1;
            } else {
                let q = sb[j].1 as usize;
                let hi = b[q].hi[axis];
                for &(_, p) in sa[i..].iter().take_while(|e| e.0 <= hi) {
                    if a[p as usize].overlaps(&b[q]) {
                        found(p as usize, q);
                    }
                }
                j += 1;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DVec3;

    fn boxes(n: usize, seed: u64) -> Vec<Bounds> {
        let mut s = seed;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64) / ((1u64 << 53) as f64)
        };
        (0..n)
            .map(|_| {
                let lo = DVec3::new(next(), next(), next());
                let size = DVec3::new(next(), next(), next()) * 0.2;
                Bounds { lo, hi: lo + size }
            })
            .collect()
    }

    /// The sweep finds exactly the pairs the n · m test finds, on every
    /// axis, with ties and touching boxes included.
    #[test]
    fn finds_exactly_the_overlapping_pairs() {
        let mut sweep = Sweep::default();
        for seed in 0..20 {
            let a = boxes(40 + seed as usize, seed);
            let mut b = boxes(30, seed + 100);
            // A box touching one of a's, and one sharing its low end.
            b.push(Bounds {
                lo: a[0].hi,
                hi: a[0].hi + DVec3::splat(0.1),
            });
            b.push(a[1]);
            let mut want = Vec::new();
            for (p, x) in a.iter().enumerate() {
                for (q, y) in b.iter().enumerate() {
                    if x.overlaps(y) {
                        want.push((p, q));
                    }
                }
            }
            want.sort();
            // At least the copy of a[1] and the box touching a[0].
            assert!(want.len() >= 2, "seed {seed}: a test with pairs");
            for axis in 0..3 {
                let mut got = Vec::new();
                sweep.overlapping_pairs(&a, &b, axis, |p, q| got.push((p, q)));
                got.sort();
                assert_eq!(got, want, "seed {seed}, axis {axis}");
            }
        }
    }
}
