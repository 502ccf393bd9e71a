//! Mass, centre of mass and inertia tensor of a closed mesh of uniform density.
//!
//! The solid is the signed sum of the tetrahedra joining a reference point r
//! to each outward triangle (divergence theorem). For a tetrahedron with
//! vertices p0 = 0, p1, p2, p3 relative to r and volume V:
//!   ∫ x dV   = V (p1 + p2 + p3) / 4,
//!   ∫ x xᵀ dV = V/20 (Σ pᵢ pᵢᵀ + (Σ pᵢ)(Σ pᵢ)ᵀ).
//! The inertia tensor about the centroid c is I = ρ (tr(C) E − C) with C the
//! second moment about c. r is the vertex mean, so sums stay well scaled far
//! from the origin.

use super::TriMesh;
use glam::{DMat3, DVec3};

#[derive(Debug, Clone, Copy, PartialEq)]
pub struct MassProperties {
    pub volume: f64,
    pub mass: f64,
    /// Centre of mass in the mesh's coordinates.
    pub centroid: DVec3,
    /// Inertia tensor about the centroid, in the mesh's axes.
    pub inertia: DMat3,
}

impl MassProperties {
    pub fn of(mesh: &TriMesh, density: f64) -> MassProperties {
        let n = mesh.vertices.len() as f64;
        let r = mesh.vertices.iter().copied().sum::<DVec3>() / n;
        let mut vol = 0.0;
        let mut first = DVec3::ZERO;
        let mut second = DMat3::ZERO;
        for t in &mesh.triangles {
            let [a, b, c] = t.map(|i| mesh.vertices[i as usize] - r);
            let v = a.dot(b.cross(c)) / 6.0;
            let s = a + b + c;
            vol += v;
            first += v * s / 4.0;
            let outer = |p: DVec3| DMat3::from_cols(p * p.x, p * p.y, p * p.z);
            second += (outer(a) + outer(b) + outer(c) + outer(s)) * (v / 20.0);
        }
        let c_local = first / vol;
        // Second moment about the centroid: C_c = C_r - V c cᵀ (parallel axis).
        let cc = DMat3::from_cols(
            c_local * c_local.x,
            c_local * c_local.y,
            c_local * c_local.z,
        );
        let c_moment = second - cc * vol;
        let trace = c_moment.x_axis.x + c_moment.y_axis.y + c_moment.z_axis.z;
        let inertia = (DMat3::from_diagonal(DVec3::splat(trace)) - c_moment) * density;
        MassProperties {
            volume: vol,
            mass: vol * density,
            centroid: r + c_local,
            inertia,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::box_mesh;
    use super::*;

    #[test]
    fn box_matches_the_analytic_values_far_from_the_origin() {
        let (a, b, c) = (2.0, 3.0, 5.0);
        let offset = DVec3::new(1e6, -2e6, 3e5);
        let m = box_mesh(DVec3::new(a, b, c)).unwrap().translated(offset);
        let p = MassProperties::of(&m, 7.0);
        let mass = 7.0 * a * b * c;
        assert!((p.volume - a * b * c).abs() < 1e-9 * a * b * c);
        assert!((p.mass - mass).abs() < 1e-9 * mass);
        assert!((p.centroid - offset).length() < 1e-9);
        let expect = DVec3::new(b * b + c * c, a * a + c * c, a * a + b * b) * (mass / 12.0);
        let diag = DVec3::new(p.inertia.x_axis.x, p.inertia.y_axis.y, p.inertia.z_axis.z);
        assert!(
            (diag - expect).length() < 1e-9 * expect.length(),
            "{diag} vs {expect}"
        );
        assert!(p.inertia.x_axis.y.abs() < 1e-9 * expect.length());
    }
}
