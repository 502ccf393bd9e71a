//! Closed triangle meshes: the shapes of particles and obstacles.
//!
//! A mesh is accepted only when it is closed (every edge shared by exactly two
//! triangles), consistently oriented (each shared edge traversed once in each
//! direction) and free of degenerate triangles; otherwise [`MeshError`] says
//! which triangle or edge is at fault. A consistently inward-facing mesh is
//! turned outward.

mod features;
mod generate;
mod load;
mod mass_properties;
mod validate;
mod winding_number;

pub use features::{Crease, Face, Features, FLAT_ANGLE, NO_CREASE};
pub use generate::{box_mesh, sphere_hull, subdivided, tetrahedron, tube};
pub use load::load_mesh;
pub use mass_properties::MassProperties;

use glam::DVec3;

/// A triangle mesh by shared vertices, outward-facing after validation.
#[derive(Debug, Clone, PartialEq)]
pub struct TriMesh {
    pub vertices: Vec<DVec3>,
    pub triangles: Vec<[u32; 3]>,
}

/// Why a mesh was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum MeshError {
    #[error("mesh has {0} triangles; a closed mesh needs at least 4")]
    TooFewTriangles(usize),
    #[error("triangle {triangle} refers to vertex {vertex}, but there are only {count} vertices")]
    BadIndex {
        triangle: usize,
        vertex: u32,
        count: usize,
    },
    #[error("vertex {0} has a non-finite coordinate")]
    NonFinite(usize),
    #[error("triangle {0} is degenerate (its vertices are collinear or coincide)")]
    Degenerate(usize),
    #[error(
        "mesh is open: edge ({0}, {1}) belongs to {2} triangle(s), a closed mesh has exactly 2"
    )]
    Open(u32, u32, usize),
    #[error(
        "mesh is inconsistently oriented: edge ({0}, {1}) is traversed twice in the same direction"
    )]
    Inconsistent(u32, u32),
    #[error("mesh encloses no volume")]
    NoVolume,
    #[error("{path}: {cause}")]
    Load { path: String, cause: String },
}

impl TriMesh {
    /// Validates and returns the mesh, turned outward if it was inward-facing.
    pub fn new(vertices: Vec<DVec3>, triangles: Vec<[u32; 3]>) -> Result<Self, MeshError> {
        let mut m = TriMesh {
            vertices,
            triangles,
        };
        validate::validate(&m)?;
        if m.signed_volume() < 0.0 {
            for t in &mut m.triangles {
                t.swap(1, 2);
            }
        }
        Ok(m)
    }

    /// The vertices of triangle `i`.
    pub fn triangle(&self, i: usize) -> [DVec3; 3] {
        let t = self.triangles[i];
        [
            self.vertices[t[0] as usize],
            self.vertices[t[1] as usize],
            self.vertices[t[2] as usize],
        ]
    }

    /// Enclosed volume, positive for an outward-facing mesh.
    pub fn signed_volume(&self) -> f64 {
        let o = self.vertices.first().copied().unwrap_or_default();
        self.triangles
            .iter()
            .map(|t| {
                let [a, b, c] = t.map(|i| self.vertices[i as usize] - o);
                a.dot(b.cross(c)) / 6.0
            })
            .sum()
    }

    /// The mesh moved by `offset`.
    pub fn translated(&self, offset: DVec3) -> TriMesh {
        TriMesh {
            vertices: self.vertices.iter().map(|v| *v + offset).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// The mesh scaled by `s` about the origin.
    pub fn scaled(&self, s: f64) -> TriMesh {
        TriMesh {
            vertices: self.vertices.iter().map(|v| *v * s).collect(),
            triangles: self.triangles.clone(),
        }
    }

    /// The largest distance of a vertex from the mesh's origin: how far any
    /// point of a body of this shape is from the body's centre.
    pub fn reach(&self) -> f64 {
        self.vertices.iter().map(|v| v.length()).fold(0.0, f64::max)
    }

    /// Smallest box around the vertices.
    pub fn bounds(&self) -> (DVec3, DVec3) {
        let mut lo = DVec3::splat(f64::INFINITY);
        let mut hi = DVec3::splat(f64::NEG_INFINITY);
        for v in &self.vertices {
            lo = lo.min(*v);
            hi = hi.max(*v);
        }
        (lo, hi)
    }
}
