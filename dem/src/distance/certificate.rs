//! A cheap, rigorous bound on the error of a candidate answer.
//!
//! Let P be a point of triangle A, Q a point of triangle B, n = P - Q. Every
//! point of A lies on P's side of the plane through P normal to n up to tA (the
//! largest amount a vertex of A lies beyond it), every point of B on Q's side of
//! the parallel plane through Q up to tB: the triangles are convex hulls of
//! their vertices. Then the true distance d satisfies
//!
//!   |P - Q| - tA - tB  <=  d  <=  |P - Q|,
//!
//! the right inequality because P and Q are points of the triangles. So
//! tA + tB bounds the error of reporting |P - Q|: six dot products. When P = Q
//! (touching or crossing triangles) the bound is |P - Q| itself.

use super::Triangle;
use glam::DVec3;

/// An upper bound on `|P - Q| - d` for points P of `a` and Q of `b` (all in the
/// same frame, preferably local to the pair). Infinite when P or Q is not finite.
pub fn certified_error_bound(a: &Triangle, b: &Triangle, p: DVec3, q: DVec3) -> f64 {
    let n = p - q;
    let len = n.length();
    if !len.is_finite() {
        return f64::INFINITY;
    }
    if len == 0.0 {
        return 0.0;
    }
    let mut ta = 0.0f64;
    for v in a {
        ta = ta.max(n.dot(p - *v));
    }
    let mut tb = 0.0f64;
    for v in b {
        tb = tb.max(n.dot(*v - q));
    }
    // The bound can never exceed |P - Q| itself (d >= 0).
    ((ta + tb) / len).min(len)
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
}
