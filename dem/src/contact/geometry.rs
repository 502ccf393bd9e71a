//! The world-space geometry of each body that contact detection works on:
//! triangles, their face planes and their boxes inflated by the halo.

use crate::body::Body;
use crate::distance::Triangle;
use crate::mesh::TriMesh;
use glam::{DMat3, DQuat, DVec3};

/// Axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Bounds {
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds::EMPTY
    }
}

impl Bounds {
    pub const EMPTY: Bounds = Bounds {
        lo: DVec3::INFINITY,
        hi: DVec3::NEG_INFINITY,
    };

    pub fn of(t: &Triangle, pad: f64) -> Bounds {
        Bounds {
            lo: t[0].min(t[1]).min(t[2]) - DVec3::splat(pad),
            hi: t[0].max(t[1]).max(t[2]) + DVec3::splat(pad),
        }
    }

    pub fn overlaps(&self, o: &Bounds) -> bool {
        self.lo.cmple(o.hi).all() && o.lo.cmple(self.hi).all()
    }

    pub fn union(&self, o: &Bounds) -> Bounds {
        Bounds {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }
}

/// One body's triangles in world space, recomputed only when its pose (or
/// halo) changed: static obstacles, often the largest meshes, are computed once.
#[derive(Debug, Clone, Default)]
pub(crate) struct BodyGeometry {
    /// The pose and halo everything below was computed for.
    key: Option<(DVec3, DQuat, f64)>,
    vertices: Vec<DVec3>,
    pub triangles: Vec<Triangle>,
    /// Unit normal and offset (n · v0) of every triangle; zero normal if degenerate.
    pub planes: Vec<(DVec3, f64)>,
    /// Box of every triangle, inflated by the halo.
    pub bounds: Vec<Bounds>,
    /// Union of `bounds`.
    pub bbox: Bounds,
}

impl BodyGeometry {
    pub fn update(&mut self, body: &Body, mesh: &TriMesh, halo: f64) {
        let key = (body.x, body.q, halo);
        if self.key == Some(key) {
            return;
        }
        // Each vertex once, by the rotation matrix: a mesh has about half as
        // many vertices as triangles, each triangle three.
        let r = DMat3::from_quat(body.q);
        self.vertices.clear();
        self.vertices
            .extend(mesh.vertices.iter().map(|&v| body.x + r * v));
        let v = &self.vertices;
        self.triangles.clear();
        self.planes.clear();
        self.bounds.clear();
        let mut bbox = Bounds::EMPTY;
        for t in &mesh.triangles {
            let tri = [v[t[0] as usize], v[t[1] as usize], v[t[2] as usize]];
            let n = (tri[1] - tri[0]).cross(tri[2] - tri[0]).normalize_or_zero();
            let b = Bounds::of(&tri, halo);
            bbox = bbox.union(&b);
            self.triangles.push(tri);
            self.planes.push((n, n.dot(tri[0])));
            self.bounds.push(b);
        }
        self.bbox = bbox;
        self.key = Some(key);
    }
}
