//! Closest point of a triangle to a point.

use super::closest_point_segment_segment::inverse_or_zero;
use super::closest_points_segment_segment;
use glam::DVec3;

/// The point of triangle `t` closest to `p`.
///
/// Projects onto the plane and keeps the projection when it falls inside (sign
/// tests on the sub-triangle areas); otherwise the closest point lies on the
/// boundary, and the nearest of the three edges gives it. A triangle whose
/// vertices are collinear to rounding is the union of its edges, which the
/// boundary branch already handles, so degenerate input never divides by zero.
#[inline]
pub fn closest_point_triangle(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    project_inside(p, t, usable_normal(t)).unwrap_or_else(|| closest_on_boundary(p, t))
}

/// The triangle's normal when it carries information, `None` for a triangle
/// that is flat to rounding (then only its edges matter).
#[inline]
pub fn usable_normal(t: &[DVec3; 3]) -> Option<DVec3> {
    let n = normal(t);
    let nn = n.length_squared();
    (nn > 0.0 && !is_flat(t, nn)).then_some(n)
}

/// The projection of `p` onto the plane of `t` if it falls inside `t`.
#[inline]
pub fn project_inside(p: DVec3, t: &[DVec3; 3], n: Option<DVec3>) -> Option<DVec3> {
    let n = n?;
    let inside = (0..3).all(|i| {
        let (a, b) = (t[i], t[(i + 1) % 3]);
        n.dot((b - a).cross(p - a)) >= 0.0
    });
    inside.then(|| p - n * (n.dot(p - t[0]) / n.length_squared()))
}

/// The point of the triangle's boundary (its three edges) closest to `p`.
#[inline]
pub fn closest_on_boundary(p: DVec3, t: &[DVec3; 3]) -> DVec3 {
    let mut best = t[0];
    let mut best_d = f64::INFINITY;
    for i in 0..3 {
        let (_, _, c, _) = closest_points_segment_segment(t[i], t[(i + 1) % 3], p, p);
        let d = (c - p).length_squared();
        if d < best_d {
            best_d = d;
            best = c;
        }
    }
    best
}

/// A triangle with what every query against it needs, computed once: edges,
/// their squared lengths, and, unless it is flat, the normal and the inward
/// edge normals n x e_i that make the inside test three dot products.
pub(crate) struct PreparedTriangle {
    pub v: [DVec3; 3],
    /// e_i = v_{i+1} - v_i.
    pub e: [DVec3; 3],
    /// 1/|e_i|^2, or 0 for a zero-length edge.
    pub inv_ee: [f64; 3],
    /// (n, n.n, inward edge normals), `None` when flat to rounding.
    pub plane: Option<(DVec3, f64, [DVec3; 3])>,
}

impl PreparedTriangle {
    #[inline]
    pub fn new(t: &[DVec3; 3]) -> Self {
        let e = [t[1] - t[0], t[2] - t[1], t[0] - t[2]];
        let inv_ee = [0, 1, 2].map(|i| inverse_or_zero(e[i].length_squared()));
        let plane = usable_normal(t).map(|n| {
            (
                n,
                n.length_squared(),
                [n.cross(e[0]), n.cross(e[1]), n.cross(e[2])],
            )
        });
        PreparedTriangle {
            v: *t,
            e,
            inv_ee,
            plane,
        }
    }

    /// The projection of `p` onto the plane if it falls inside the triangle.
    #[inline]
    pub fn project_inside(&self, p: DVec3) -> Option<DVec3> {
        let (n, nn, m) = self.plane?;
        let inside = (0..3).all(|i| m[i].dot(p - self.v[i]) >= 0.0);
        inside.then(|| p - n * (n.dot(p - self.v[0]) / nn))
    }
}

/// Normal of the triangle from the two edges at its largest angle: the
/// best-conditioned cross product of the three.
#[inline]
pub fn normal(t: &[DVec3; 3]) -> DVec3 {
    let e0 = t[1] - t[0];
    let e1 = t[2] - t[1];
    let e2 = t[0] - t[2];
    let (l0, l1, l2) = (
        e0.length_squared(),
        e1.length_squared(),
        e2.length_squared(),
    );
    // The largest angle is opposite the longest edge; use the other two.
    if l0 >= l1 && l0 >= l2 {
        e1.cross(e2)
    } else if l1 >= l2 {
        e2.cross(e0)
    } else {
        e0.cross(e1)
    }
}

/// Whether the triangle is flat to rounding: |sin| of its largest angle below a
/// few ulps, so that its normal carries no information.
#[inline]
fn is_flat(t: &[DVec3; 3], nn: f64) -> bool {
    let l0 = (t[1] - t[0]).length_squared();
    let l1 = (t[2] - t[1]).length_squared();
    let l2 = (t[0] - t[2]).length_squared();
    // nn = (|u||v| sin)^2 for the two shorter edges u, v.
    let longest = l0.max(l1).max(l2);
    let uv = (l0 * l1 * l2) / longest;
    const FLAT: f64 = 64.0 * f64::EPSILON;
    nn <= FLAT * FLAT * uv
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tri() -> [DVec3; 3] {
        [DVec3::ZERO, DVec3::X, DVec3::Y]
    }

    #[test]
    fn regions() {
        let t = tri();
        assert_eq!(
            closest_point_triangle(DVec3::new(0.2, 0.2, 3.0), &t),
            DVec3::new(0.2, 0.2, 0.0)
        );
        assert_eq!(
            closest_point_triangle(DVec3::new(-1.0, -1.0, 1.0), &t),
            DVec3::ZERO
        );
        assert_eq!(
            closest_point_triangle(DVec3::new(0.5, -2.0, 0.0), &t),
            DVec3::new(0.5, 0.0, 0.0)
        );
        let c = closest_point_triangle(DVec3::new(1.0, 1.0, 0.0), &t);
        assert!((c - DVec3::new(0.5, 0.5, 0.0)).length() < 1e-15);
    }

    #[test]
    fn collinear_triangle_is_a_segment() {
        let t = [DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        let c = closest_point_triangle(DVec3::new(1.5, 1.0, 0.0), &t);
        assert_eq!(c, DVec3::new(1.5, 0.0, 0.0));
        let all_same = [DVec3::ONE; 3];
        assert_eq!(closest_point_triangle(DVec3::ZERO, &all_same), DVec3::ONE);
    }
}
