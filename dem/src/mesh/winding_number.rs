//! Whether a point lies inside a closed mesh, by its winding number.
//!
//! The winding number of a closed, outward-facing mesh about a point p is the
//! sum of the signed solid angles its triangles subtend at p, over 4π: 1
//! inside, 0 outside. Each triangle's solid angle has the closed form of Van
//! Oosterom and Strackee (1983): with a, b, c its vertices relative to p,
//!
//!   tan(Ω/2) = a·(b×c) / (|a||b||c| + (a·b)|c| + (b·c)|a| + (c·a)|b|).
//!
//! `atan2` takes the quadrant from the signs, so Ω covers (−2π, 2π). Unlike
//! a ray-parity count, the sum has no degenerate rays (along an edge, through
//! a vertex), and it is a ratio of lengths: it holds at any scale. Near the
//! surface (closer than rounding can resolve), the answer may go either way;
//! callers that care use a distance query there.

use super::TriMesh;
use glam::DVec3;
use std::f64::consts::PI;

impl TriMesh {
    /// Sum of the solid angles the triangles subtend at `p`, over 4π: 1 inside
    /// an outward-facing closed mesh, 0 outside.
    pub fn winding_number(&self, p: DVec3) -> f64 {
        let total: f64 = self
            .triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize] - p);
                let (la, lb, lc) = (a.length(), b.length(), c.length());
                let det = a.dot(b.cross(c));
                let den = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
                2.0 * det.atan2(den)
            })
            .sum();
        total / (4.0 * PI)
    }

    /// Whether `p` lies inside the mesh (winding number above one half).
    pub fn contains(&self, p: DVec3) -> bool {
        self.winding_number(p) > 0.5
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::mesh::{box_mesh, sphere_hull, subdivided};
    use glam::DQuat;

    #[test]
    fn winding_number_is_one_inside_and_zero_outside_at_every_scale() {
        for scale in [1e-6, 1.0, 1e6] {
            let far = DVec3::new(3e5, -7e5, 1e6) * scale;
            let m = subdivided(&box_mesh(DVec3::new(2.0, 1.0, 0.5)).unwrap(), 1)
                .unwrap()
                .scaled(scale)
                .translated(far);
            for (p, inside) in [
                (DVec3::ZERO, true),
                (DVec3::new(0.99, 0.49, 0.24), true),
                (DVec3::new(-0.99, -0.49, -0.24), true),
                (DVec3::new(1.01, 0.0, 0.0), false),
                (DVec3::new(0.0, 0.0, 0.26), false),
                (DVec3::new(5.0, 5.0, 5.0), false),
            ] {
                let w = m.winding_number(far + p * scale);
                let want = if inside { 1.0 } else { 0.0 };
                assert!((w - want).abs() < 1e-9, "scale {scale}, {p}: {w}");
                assert_eq!(m.contains(far + p * scale), inside);
            }
        }
    }

    /// Against a second method: a point is inside a convex hull exactly when
    /// it lies behind every face plane.
    #[test]
    fn contains_agrees_with_the_face_planes_of_a_convex_hull() {
        let m = sphere_hull(60, 1.0, 7).unwrap();
        let rot = DQuat::from_rotation_y(0.3);
        let mut s = 12345_u64;
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (s >> 11) as f64 / (1u64 << 53) as f64 * 2.4 - 1.2
        };
        let mut inside = 0;
        for _ in 0..2000 {
            let p = rot * DVec3::new(next(), next(), next());
            let behind_all = (0..m.triangles.len()).all(|i| {
                let [a, b, c] = m.triangle(i);
                (b - a).cross(c - a).dot(p - a) < 0.0
            });
            // Points within rounding of a face may go either way.
            let margin = (0..m.triangles.len())
                .map(|i| {
                    let [a, b, c] = m.triangle(i);
                    let n = (b - a).cross(c - a).normalize();
                    n.dot(p - a).abs()
                })
                .fold(f64::INFINITY, f64::min);
            if margin > 1e-9 {
                assert_eq!(m.contains(p), behind_all, "{p}");
                inside += usize::from(behind_all);
            }
        }
        assert!(
            inside > 100,
            "only {inside} points inside: the test saw too few"
        );
    }
}
