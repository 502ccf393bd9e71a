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
    let d1 = q1 - p1;
    let d2 = q2 - p2;
    let r = p1 - p2;
    let a = d1.dot(d1);
    let e = d2.dot(d2);
    let f = d2.dot(r);
    let (s, t);
    if a == 0.0 && e == 0.0 {
        return (0.0, 0.0, p1, p2);
    }
    if a == 0.0 {
        s = 0.0;
        t = (f / e).clamp(0.0, 1.0);
    } else {
        let c = d1.dot(r);
        if e == 0.0 {
            t = 0.0;
            s = (-c / a).clamp(0.0, 1.0);
        } else {
            let b = d1.dot(d2);
            // |d1 x d2|^2 rather than a e - b^2: no cancellation for near-parallel pairs.
            let denom = d1.cross(d2).length_squared();
            let s0 = if denom > 0.0 {
                ((b * f - c * e) / denom).clamp(0.0, 1.0)
            } else {
                0.0
            };
            let t0 = (b * s0 + f) / e;
            if t0 < 0.0 {
                t = 0.0;
                s = (-c / a).clamp(0.0, 1.0);
            } else if t0 > 1.0 {
                t = 1.0;
                s = ((b - c) / a).clamp(0.0, 1.0);
            } else {
                t = t0;
                s = s0;
            }
        }
    }
    (s, t, p1 + d1 * s, p2 + d2 * t)
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
