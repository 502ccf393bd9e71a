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

    /// A digest of what a run cannot change: materials, shapes, which body
    /// has which shape, material and mass, and where the obstacles stand.
    /// A checkpoint carries it, so that it is resumed only with its own
    /// scene. FNV-1a over the values' bits: stable across builds and
    /// platforms, unlike `std`'s hasher.
    pub fn fingerprint(&self) -> u64 {
        let mut h = Fnv1a::default();
        for m in &self.materials {
            h.bytes(m.name.as_bytes());
            h.f64(m.density);
            for p in [m.stiffness, m.restitution, m.halo, m.friction] {
                h.f64(p.unwrap_or(f64::NAN));
            }
        }
        for s in &self.shapes {
            s.vertices
                .iter()
                .flat_map(|v| v.to_array())
                .for_each(|c| h.f64(c));
            s.triangles
                .iter()
                .flatten()
                .for_each(|&i| h.u64(u64::from(i)));
        }
        for b in &self.bodies {
            h.u64(b.shape as u64);
            h.u64(b.material as u64);
            h.f64(b.mass);
            if b.is_static() {
                b.x.to_array().into_iter().for_each(|c| h.f64(c));
                b.q.to_array().into_iter().for_each(|c| h.f64(c));
            }
        }
        h.0
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

/// The 64-bit FNV-1a hash.
pub(crate) struct Fnv1a(pub(crate) u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    pub(crate) fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }

    pub(crate) fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }

    pub(crate) fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
}
