//! The world: shapes, materials, bodies and time.

use crate::body::Body;
use crate::material::Material;
use crate::mesh::TriMesh;

/// Everything that is simulated. Shapes are meshes in body coordinates (centre
/// of mass at the origin for particles; obstacles keep their own frame).
#[derive(Debug, Clone, Default)]
pub struct World {
    pub shapes: Vec<TriMesh>,
    pub materials: Vec<Material>,
    pub bodies: Vec<Body>,
    pub time: f64,
    pub step: u64,
}

impl World {
    /// A material parameter for every body (0 where the material lacks it;
    /// the scene has checked that declared effects find what they need).
    pub fn per_body(&self, param: fn(&Material) -> Option<f64>) -> Vec<f64> {
        self.bodies
            .iter()
            .map(|b| param(&self.materials[b.material]).unwrap_or(0.0))
            .collect()
    }

    pub fn kinetic_energy(&self) -> f64 {
        self.bodies.iter().map(Body::kinetic_energy).sum()
    }

    pub fn dynamic_count(&self) -> usize {
        self.bodies.iter().filter(|b| !b.is_static()).count()
    }

    /// Triangles of all dynamic bodies.
    pub fn particle_triangles(&self) -> usize {
        self.bodies
            .iter()
            .filter(|b| !b.is_static())
            .map(|b| self.shapes[b.shape].triangles.len())
            .sum()
    }
}
