//! Generated shapes: boxes, tetrahedra, tubes (a rotating drum's shell), and
//! the published granulate: the convex hull of random points on a sphere.
//!
//! Each returns the mesh, or the [`MeshError`] its triangles give at the
//! size asked: lengths so small that a triangle's area underflows, or so
//! large that a product overflows, make a degenerate or non-finite mesh.

use super::{MeshError, TriMesh};
use glam::DVec3;
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use std::collections::HashMap;

/// An axis-aligned box of the given size centred on the origin.
pub fn box_mesh(size: DVec3) -> Result<TriMesh, MeshError> {
    let h = size * 0.5;
    let v: Vec<DVec3> = (0..8)
        .map(|i| {
            DVec3::new(
                if i & 1 == 0 { -h.x } else { h.x },
                if i & 2 == 0 { -h.y } else { h.y },
                if i & 4 == 0 { -h.z } else { h.z },
            )
        })
        .collect();
    let t = vec![
        [0, 2, 1],
        [1, 2, 3], // z-
        [4, 5, 6],
        [5, 7, 6], // z+
        [0, 1, 4],
        [1, 5, 4], // y-
        [2, 6, 3],
        [3, 6, 7], // y+
        [0, 4, 2],
        [2, 4, 6], // x-
        [1, 3, 5],
        [3, 7, 5], // x+
    ];
    TriMesh::new(v, t)
}

/// `m` with each triangle split into four at its edges' midpoints, `times`
/// times over: the same shape, with 4^times as many triangles.
pub fn subdivided(m: &TriMesh, times: usize) -> Result<TriMesh, MeshError> {
    let mut m = m.clone();
    for _ in 0..times {
        let mut vertices = m.vertices.clone();
        let mut mid: HashMap<(u32, u32), u32> = HashMap::new();
        let mut at = |i: u32, j: u32, v: &mut Vec<DVec3>| {
            *mid.entry((i.min(j), i.max(j))).or_insert_with(|| {
                v.push((v[i as usize] + v[j as usize]) * 0.5);
                (v.len() - 1) as u32
            })
        };
        let mut triangles = Vec::with_capacity(4 * m.triangles.len());
        for &[a, b, c] in &m.triangles {
            let ab = at(a, b, &mut vertices);
            let bc = at(b, c, &mut vertices);
            let ca = at(c, a, &mut vertices);
            triangles.extend([[a, ab, ca], [ab, b, bc], [ca, bc, c], [ab, bc, ca]]);
        }
        m = TriMesh::new(vertices, triangles)?;
    }
    Ok(m)
}

/// A regular tetrahedron with circumradius `r`, centred on the origin.
pub fn tetrahedron(r: f64) -> Result<TriMesh, MeshError> {
    let s = r / 3f64.sqrt();
    let v = vec![
        DVec3::new(s, s, s),
        DVec3::new(s, -s, -s),
        DVec3::new(-s, s, -s),
        DVec3::new(-s, -s, s),
    ];
    TriMesh::new(v, vec![[0, 1, 2], [0, 3, 1], [0, 2, 3], [1, 3, 2]])
}

/// A tube along y centred on the origin: the shell between two coaxial
/// prisms of `segments` sides, the inner one inscribed in a circle of radius
/// `inner_radius`, the outer one `thickness` further out, `length` long and
/// closed by flat rings at y = ±length/2. Its inside faces the axis: the
/// shell of a rotating drum, whose ends are closed by plates of their own.
/// With `end_inner_radius` other than `inner_radius` the inner radius at
/// y = +length/2 is that one (the outer stays `thickness` further out): the
/// shell of a truncated pyramid, a funnel. Each side of a prism and each
/// ring's sector is a flat quadrilateral of two triangles (8 × `segments`
/// triangles in all).
pub fn tube(
    inner_radius: f64,
    end_inner_radius: f64,
    thickness: f64,
    length: f64,
    segments: usize,
) -> Result<TriMesh, MeshError> {
    let n = segments.max(3);
    let half = 0.5 * length;
    let (r0, r1) = (inner_radius, end_inner_radius);
    let radial = |k: usize| {
        let phi = std::f64::consts::TAU * (k % n) as f64 / n as f64;
        DVec3::new(phi.cos(), 0.0, phi.sin())
    };
    // Per segment k: inner and outer vertices at y = -half and +half.
    let mut vertices = Vec::with_capacity(4 * n);
    for k in 0..n {
        let u = radial(k);
        for (r, y) in [
            (r0, -half),
            (r1, half),
            (r0 + thickness, -half),
            (r1 + thickness, half),
        ] {
            vertices.push(DVec3::new(u.x * r, y, u.z * r));
        }
    }
    let at = |k: usize, corner: usize| (4 * (k % n) + corner) as u32;
    let mut triangles = Vec::with_capacity(8 * n);
    for k in 0..n {
        let mid = (radial(k) + radial(k + 1)).normalize();
        // Each quad by its corners in order around it, with the side its
        // outward normal points to.
        let quads = [
            ([at(k, 0), at(k, 1), at(k + 1, 1), at(k + 1, 0)], -mid),
            ([at(k, 2), at(k, 3), at(k + 1, 3), at(k + 1, 2)], mid),
            ([at(k, 0), at(k, 2), at(k + 1, 2), at(k + 1, 0)], -DVec3::Y),
            ([at(k, 1), at(k, 3), at(k + 1, 3), at(k + 1, 1)], DVec3::Y),
        ];
        for ([a, b, c, d], out) in quads {
            for t in [[a, b, c], [a, c, d]] {
                let [p, q, r] = t.map(|i| vertices[i as usize]);
                let facing = (q - p).cross(r - p).dot(out) > 0.0;
                triangles.push(if facing { t } else { [t[0], t[2], t[1]] });
            }
        }
    }
    TriMesh::new(vertices, triangles)
}

/// Convex hull of random points on a sphere of radius `r`, with `triangles`
/// faces (even, at least 4: a hull of V points in general position has 2V - 4).
pub fn sphere_hull(triangles: usize, r: f64, seed: u64) -> Result<TriMesh, MeshError> {
    let points = (triangles.max(4) + 4) / 2;
    let mut rng = Xoshiro256PlusPlus::seed_from_u64(seed);
    for _attempt in 0..64 {
        let pts: Vec<parry3d_f64::math::Vector> = (0..points)
            .map(|_| {
                // Uniform on the sphere: normalised Gaussian vectors.
                let g = |rng: &mut Xoshiro256PlusPlus| {
                    let u1: f64 = rng.random::<f64>().max(1e-300);
                    let u2: f64 = rng.random();
                    (-2.0 * u1.ln()).sqrt() * (2.0 * std::f64::consts::PI * u2).cos()
                };
                let d = DVec3::new(g(&mut rng), g(&mut rng), g(&mut rng)).normalize() * r;
                parry3d_f64::math::Vector::new(d.x, d.y, d.z)
            })
            .collect();
        // No hull (points parry cannot tell apart at this scale): try anew.
        let Ok((v, t)) = parry3d_f64::transformation::try_convex_hull(&pts) else {
            continue;
        };
        let vertices: Vec<DVec3> = v.iter().map(|p| DVec3::new(p.x, p.y, p.z)).collect();
        if let Ok(mesh) = TriMesh::new(vertices, t) {
            if mesh.triangles.len() == 2 * points - 4 {
                // Centre the mesh on its centre of mass.
                let c = super::MassProperties::of(&mesh, 1.0).centroid;
                return Ok(mesh.translated(-c));
            }
        }
    }
    // Points in degenerate position 64 times in a row: fall back to a tetrahedron.
    tetrahedron(r)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hull_has_the_requested_triangles_and_is_convex() {
        for n in [4, 8, 20, 60] {
            let m = sphere_hull(n, 0.01, 3).unwrap();
            assert_eq!(m.triangles.len(), n);
            // Convex: every vertex on the inner side of every face plane.
            for i in 0..m.triangles.len() {
                let [a, b, c] = m.triangle(i);
                let nrm = (b - a).cross(c - a);
                for v in &m.vertices {
                    assert!(nrm.dot(*v - a) <= 1e-12 * nrm.length() * 0.01);
                }
            }
        }
    }

    /// The polygonal shell's volume, n/2 sin(2π/n) (R² − r²) L, and a drum's
    /// inside: every inner face's outward normal points at the axis.
    #[test]
    fn tube_is_a_closed_shell_whose_inside_faces_the_axis() {
        // (inner radius, at the +y end, thickness, length, sides): drums,
        // and funnels (a radius growing or shrinking along y).
        for (r, r1, t, l, n) in [
            (0.07, 0.07, 0.005, 0.045, 48),
            (1e-6, 1e-6, 1e-7, 3e-6, 3),
            (2e5, 2e5, 1e4, 5e4, 7),
            (0.02, 0.06, 0.003, 0.07, 24),
            (3e4, 1e4, 2e3, 5e4, 5),
        ] {
            let m = tube(r, r1, t, l, n).unwrap();
            assert_eq!(m.triangles.len(), 8 * n);
            let sector = 0.5 * n as f64 * (std::f64::consts::TAU / n as f64).sin();
            // ∫ ((r(y) + t)² − r(y)²) dy over the length, r linear in y.
            let volume = sector * (2.0 * t * 0.5 * (r + r1) + t * t) * l;
            let got = m.signed_volume();
            assert!(
                (got - volume).abs() <= 1e-12 * volume,
                "{got} against {volume}"
            );
            let mut inner = 0;
            for i in 0..m.triangles.len() {
                let [a, b, c] = m.triangle(i);
                let normal = (b - a).cross(c - a).normalize();
                let centre = (a + b + c) / 3.0;
                let radial = DVec3::new(centre.x, 0.0, centre.z);
                // The inner faces: all corners on the inner surface.
                let inner_at = |y: f64| r + (r1 - r) * (y / l + 0.5);
                if [a, b, c].iter().all(|p| {
                    let ri = inner_at(p.y);
                    (DVec3::new(p.x, 0.0, p.z).length() - ri).abs() <= 1e-12 * ri
                }) {
                    inner += 1;
                    assert!(
                        normal.dot(radial) < 0.0,
                        "inner face {i} faces away from the axis"
                    );
                }
            }
            assert_eq!(inner, 2 * n);
        }
    }
}
