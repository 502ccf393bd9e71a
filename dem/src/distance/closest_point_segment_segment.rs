//! Closest points between two segments (Ericson, *Real-Time Collision
//! Detection*, 5.1.9), with exact handling of zero-length segments and of
//! parallel ones.

use glam::DVec3;

/// Closest points between segments [p1, q1] and [p2, q2]: returns
/// `(s, t, c1, c2)` with `c1 = p1 + s (q1 - p1)` and `c2 = p2 + t (q2 - p2)`.
///
/// No absolute epsilon: a segment is degenerate only when its length is exactly
/// zero, and parallel only when the cross product of the directions is exactly
/// zero. Near-parallel segments go through the general branch, whose clamping
/// keeps both points on their segments; the distance is then insensitive to the
/// rounding in `s`.
#[inline]
pub fn closest_points_segment_segment(
    p1: DVec3,
    q1: DVec3,
    p2: DVec3,
    q2: DVec3,
) -> (f64, f64, DVec3, DVec3) {
    let (d1, d2) = (q1 - p1, q2 - p2);
    let (s, t) = segment_segment_params(
        p1,
        d1,
        inverse_or_zero(d1.dot(d1)),
        p2,
        d2,
        inverse_or_zero(d2.dot(d2)),
    );
    (s, t, p1 + d1 * s, p2 + d2 * t)
}

/// 1/x, or 0 for a zero-length segment (whose parameter then stays 0).
#[inline]
pub(crate) fn inverse_or_zero(x: f64) -> f64 {
    if x > 0.0 {
        1.0 / x
    } else {
        0.0
    }
}

/// The parameters (s, t) of the closest points of segments p1 + s d1 and
/// p2 + t d2, given `inv_a = 1/|d1|^2` and `inv_e = 1/|d2|^2` (0 for a
/// zero-length segment); callers testing many pairs of the same edges compute
/// them once.
///
/// Branch-free form of Ericson's clamping: s from the lines' closest points
/// (0 if parallel), t as the closest to that s, then s again as the closest to
/// that t. Each step can only bring the points closer, and the last two are
/// exactly Ericson's clamped branches, so the result is his, without the
/// mispredicted branches random pairs cause. A zero-length segment has
/// inv = 0 and b = c = 0 (or f = 0), which pins its parameter at 0.
#[inline]
pub(crate) fn segment_segment_params(
    p1: DVec3,
    d1: DVec3,
    inv_a: f64,
    p2: DVec3,
    d2: DVec3,
    inv_e: f64,
) -> (f64, f64) {
    let r = p1 - p2;
    let f = d2.dot(r);
    let c = d1.dot(r);
    let b = d1.dot(d2);
    // |d1 x d2|^2 rather than a e - b^2: no cancellation for near-parallel pairs.
    let denom = d1.cross(d2).length_squared();
    let e = d2.dot(d2);
    let s0 = if denom > 0.0 {
        ((b * f - c * e) / denom).clamp(0.0, 1.0)
    } else {
        0.0
    };
    let t = ((b * s0 + f) * inv_e).clamp(0.0, 1.0);
    let s = ((b * t - c) * inv_a).clamp(0.0, 1.0);
    (s, t)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn crossing_segments_meet() {
        let (s, t, c1, c2) = closest_points_segment_segment(
            DVec3::new(-1.0, 0.0, 0.0),
            DVec3::new(1.0, 0.0, 0.0),
            DVec3::new(0.0, -1.0, 1.0),
            DVec3::new(0.0, 1.0, 1.0),
        );
        assert_eq!((s, t), (0.5, 0.5));
        assert_eq!((c1 - c2).length(), 1.0);
    }

    #[test]
    fn parallel_disjoint_segments_give_end_points() {
        let (_, _, c1, c2) = closest_points_segment_segment(
            DVec3::ZERO,
            DVec3::X,
            DVec3::new(5.0, 1.0, 0.0),
            DVec3::new(6.0, 1.0, 0.0),
        );
        assert_eq!(c1, DVec3::X);
        assert_eq!(c2, DVec3::new(5.0, 1.0, 0.0));
    }

    #[test]
    fn degenerate_segments_are_points() {
        let p = DVec3::new(1.0, 2.0, 3.0);
        let (_, _, c1, c2) = closest_points_segment_segment(p, p, DVec3::ZERO, DVec3::Z * 10.0);
        assert_eq!(c1, p);
        assert_eq!(c2, DVec3::new(0.0, 0.0, 3.0));
    }
}
