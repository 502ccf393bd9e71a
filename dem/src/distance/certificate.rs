//! A cheap, rigorous bound on the error of a candidate answer.
//!
//! Let P be a point of triangle A and Q a point of triangle B. Then
//! d <= |P - Q| for the true distance d. For a lower bound, take any direction
//! m: the triangles are the convex hulls of their vertices, so the projections
//! onto m of A and of B are the intervals spanned by their vertices', and the
//! gap between the two intervals, divided by |m|, is at most d. Hence
//!
//!   |P - Q| - max_m gap(m) / |m|  >=  |P - Q| - d  >=  0
//!
//! bounds the error of reporting |P - Q|, for any set of directions m, with no
//! assumption on how P and Q were found. The direction n = P - Q alone (six
//! dot products) certifies most answers, but its direction is only as accurate
//! as the points: when the distance is tiny against the triangles' size, the
//! rounding of P and Q tilts it and the bound degrades. So the finish also
//! tries the directions of the feature pair it found, which are exact to
//! rounding whatever the distance: the face normals (vertex-face, parallel
//! faces) and the cross product of two edges (edge-edge).
//!
//! The bound is rigorous up to the rounding of the dot products, a few ulps of
//! the pair's scale, far below the tolerances it is compared with (1e-13 L).

use super::lanes::{F, M, V3};
use super::Triangle;
use glam::DVec3;

/// The gap between the projections onto `m` of A = (0, u0, u1) and
/// B = (b0, b0 - u2, b0 - u3) per lane, times |m| (m need not be a unit vector;
/// negative where they overlap).
#[inline(always)]
fn gap_along<const N: usize>(m: V3<N>, u: &[V3<N>; 4], b0: V3<N>) -> F<N> {
    let zero = F::splat(0.0);
    let (a1, a2) = (m.dot(u[0]), m.dot(u[1]));
    let pb0 = m.dot(b0);
    let (pb1, pb2) = (pb0 - m.dot(u[2]), pb0 - m.dot(u[3]));
    let (lo_a, hi_a) = (zero.min(a1).min(a2), zero.max(a1).max(a2));
    let (lo_b, hi_b) = (pb0.min(pb1).min(pb2), pb0.max(pb1).max(pb2));
    (lo_a - hi_b).max(lo_b - hi_a)
}

/// A lower bound on the distance between A and B (as in [`gap_along`]) per
/// lane, from their separation along `m` (0 if the projections overlap or m is
/// zero or not finite).
#[inline(always)]
pub(crate) fn separation_along<const N: usize>(m: V3<N>, u: &[V3<N>; 4], b0: V3<N>) -> F<N> {
    let zero = F::splat(0.0);
    let gap = gap_along(m, u, b0);
    let mm = m.dot(m);
    // A zero direction proves nothing; NaN fails the comparisons.
    (mm.gt(zero) & gap.gt(zero)).select(gap / mm.sqrt(), zero)
}

/// Per lane, whether the separation along `m` proves that the distance
/// between A and B (as in [`gap_along`]) is at least `need`:
/// [`separation_along`] >= need, decided without its square root and division
/// (gap^2 >= need^2 |m|^2 for gap > 0), which are long-latency vector
/// instructions. A need <= 0 holds trivially; NaN never proves anything.
#[inline(always)]
pub(crate) fn separation_proves<const N: usize>(
    m: V3<N>,
    u: &[V3<N>; 4],
    b0: V3<N>,
    need: F<N>,
) -> M<N> {
    let zero = F::splat(0.0);
    let gap = gap_along(m, u, b0);
    need.le(zero) | (gap.gt(zero) & (gap * gap).ge(need * need * m.dot(m)))
}

/// An upper bound on `|P - Q| - d` for points P of `a` and Q of `b`, from the
/// directions P - Q, the two face normals and the nine edge cross products.
/// Infinite when P or Q is not finite.
pub fn certified_error_bound(a: &Triangle, b: &Triangle, p: DVec3, q: DVec3) -> f64 {
    let len = (p - q).length();
    if !len.is_finite() {
        return f64::INFINITY;
    }
    let o = a[0];
    let v = |x: DVec3| V3([F([x.x]), F([x.y]), F([x.z])]);
    let ea = [a[1] - o, a[2] - o, a[2] - a[1]];
    let eb = [b[1] - b[0], b[2] - b[0], b[2] - b[1]];
    let u = [v(ea[0]), v(ea[1]), v(-eb[0]), v(-eb[1])];
    let b0 = v(b[0] - o);
    let mut dirs = vec![p - q, ea[0].cross(ea[1]), eb[0].cross(eb[1])];
    for x in ea {
        for y in eb {
            dirs.push(x.cross(y));
        }
    }
    let lower = dirs
        .into_iter()
        .map(|m| separation_along(v(m), &u, b0).0[0])
        .fold(0.0, f64::max);
    (len - lower).max(0.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn exact_answer_has_zero_bound_and_wrong_one_does_not() {
        let a = [DVec3::ZERO, DVec3::X, DVec3::Y];
        let b = [
            DVec3::new(0.2, 0.2, 1.0),
            DVec3::new(0.2, 0.2, 2.0),
            DVec3::new(0.3, 0.2, 2.0),
        ];
        let p = DVec3::new(0.2, 0.2, 0.0);
        assert_eq!(certified_error_bound(&a, &b, p, b[0]), 0.0);
        // A point of A that is not the closest: the bound must cover the error.
        let p_wrong = DVec3::new(0.9, 0.05, 0.0);
        let err = (p_wrong - b[0]).length() - 1.0;
        let bound = certified_error_bound(&a, &b, p_wrong, b[0]);
        assert!(bound >= err - 1e-15, "bound {bound} < error {err}");
    }

    /// The bound is rigorous: for arbitrary points P of A and Q of B it is at
    /// least their excess over the exact distance (brute force as reference).
    #[test]
    fn bound_covers_the_error_of_any_pair_of_points() {
        let pairs = crate::distance::random_unit_pairs(500, 3);
        let mut w = 0.1f64;
        let mut next = || {
            w = (w * 7919.0 + 0.123).fract();
            w
        };
        for (a, b) in &pairs {
            let d = crate::distance::distance_triangle_triangle(a, b).distance;
            for _ in 0..10 {
                let at = |t: &Triangle, x: f64, y: f64| {
                    let (x, y) = if x + y > 1.0 {
                        (1.0 - x, 1.0 - y)
                    } else {
                        (x, y)
                    };
                    t[0] + (t[1] - t[0]) * x + (t[2] - t[0]) * y
                };
                let p = at(a, next(), next());
                let q = at(b, next(), next());
                let excess = (p - q).length() - d;
                let bound = certified_error_bound(a, b, p, q);
                assert!(bound >= excess - 1e-14, "bound {bound} < excess {excess}");
            }
        }
    }

    #[test]
    fn a_vertex_very_near_a_face_is_certified_at_any_distance() {
        // P - Q is computed with rounding of order 1e-16; at distance 1e-12 its
        // direction is off by 1e-4, but the face normal is exact.
        let a = [
            DVec3::ZERO,
            DVec3::new(1.0, 0.3, 0.0),
            DVec3::new(0.2, 1.0, 0.0),
        ];
        for h in [1e-3, 1e-8, 1e-12] {
            let v = DVec3::new(0.3 + 1e-16, 0.4, h);
            let b = [
                v,
                v + DVec3::new(0.1, 0.2, 1.0),
                v + DVec3::new(-0.3, 0.1, 2.0),
            ];
            let p = DVec3::new(0.3, 0.4, 0.0);
            let bound = certified_error_bound(&a, &b, p, v);
            assert!(bound <= 1e-15, "h = {h}: bound {bound}");
        }
    }
}
