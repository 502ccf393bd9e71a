//! The world: shapes, materials, bodies and time.

use crate::body::Body;
use crate::fingerprint::{hash_body, Fnv1a};
use crate::material::Material;
use crate::mesh::TriMesh;
use glam::DVec3;

/// Everything that is simulated. Shapes are meshes in body coordinates (centre
/// of mass at the origin for particles; obstacles keep their own frame).
#[derive(Debug, Clone, Default)]
pub struct World {
    pub shapes: Vec<TriMesh>,
    pub materials: Vec<Material>,
    pub bodies: Vec<Body>,
    /// Each body's id in the whole scene, increasing (empty: a body's id is
    /// its index). A rank of a split run holds some of the scene's bodies,
    /// in the scene's order; what outlives a step (a contact's name, the
    /// output) names bodies by id.
    pub ids: Vec<u32>,
    pub time: f64,
    pub step: u64,
}

impl World {
    /// Body `i`'s id in the whole scene.
    #[inline]
    /// Per shape: the largest distance of a vertex from the body's origin.
    pub fn shape_radii(&self) -> Vec<f64> {
        self.shapes.iter().map(TriMesh::reach).collect()
    }

    /// The index of the body of id `id`, if this world holds it.
    pub fn index_of(&self, id: u32) -> Option<usize> {
        match self.ids.is_empty() {
            true => ((id as usize) < self.bodies.len()).then_some(id as usize),
            false => self.ids.binary_search(&id).ok(),
        }
    }

    pub fn id(&self, i: usize) -> u32 {
        if self.ids.is_empty() {
            i as u32
        } else {
            self.ids[i]
        }
    }

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
        let mut h = self.fingerprint_head();
        for b in &self.bodies {
            let drive = b.drive.as_deref();
            let at_start = drive.map_or((b.x, b.q), |d| d.pose(0.0));
            let fixed = b.is_static().then_some(at_start);
            hash_body(&mut h, b.shape, b.material, b.mass, fixed, drive);
        }
        h.0
    }

    /// The fingerprint's hash of the materials and shapes, to which the
    /// bodies' part is fed (here, or from a scene's census).
    pub(crate) fn fingerprint_head(&self) -> Fnv1a {
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
        h
    }

    /// Pairs (inner, outer) of bodies of which the first lies wholly inside
    /// the second: their surfaces need not cross, so no contact sees them.
    ///
    /// Only a body whose box lies within another's can be inside it; such
    /// pairs are found by sweeping the moving bodies' boxes along the axis
    /// on which their centres spread most, and testing each obstacle against
    /// every moving body (as the broad phase does). For each, one vertex of
    /// the inner body is tested against the outer mesh by its winding number:
    /// when the surfaces do not cross, one vertex inside means all are.
    pub fn enclosed_pairs(&self) -> Vec<(usize, usize)> {
        let boxes: Vec<(DVec3, DVec3)> = (0..self.bodies.len())
            .map(|i| self.world_bounds(i))
            .collect();
        // Particles out of the run (waiting to be inserted) enclose nothing.
        let (fixed, mut moving): (Vec<usize>, Vec<usize>) = (0..self.bodies.len())
            .filter(|&i| !self.bodies[i].is_out())
            .partition(|&i| self.bodies[i].is_static());
        let axis = spread_axis(moving.iter().map(|&i| 0.5 * (boxes[i].0 + boxes[i].1)));
        moving.sort_by(|&a, &b| {
            boxes[a].0[axis]
                .total_cmp(&boxes[b].0[axis])
                .then(a.cmp(&b))
        });
        // Tested as the sweep meets them, not collected first: in a lattice
        // every body of a layer meets every other along the sweep axis.
        let mut out = Vec::new();
        let mut test = |a: usize, b: usize| {
            for (inner, outer) in [(a, b), (b, a)] {
                if within(boxes[inner], boxes[outer]) && self.vertex_inside(inner, outer) {
                    out.push((inner, outer));
                }
            }
        };
        for (k, &a) in moving.iter().enumerate() {
            for &b in moving[k + 1..]
                .iter()
                .take_while(|&&b| boxes[b].0[axis] <= boxes[a].1[axis])
            {
                test(a, b);
            }
            fixed.iter().for_each(|&s| test(a, s));
        }
        out.sort_unstable();
        out
    }

    /// The box around body `i`'s vertices where the body stands.
    pub fn world_bounds(&self, i: usize) -> (DVec3, DVec3) {
        let b = &self.bodies[i];
        self.shapes[b.shape]
            .vertices
            .iter()
            .map(|&v| b.to_world(v))
            .fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
                (lo.min(p), hi.max(p))
            })
    }

    /// Whether the first vertex of body `inner` lies inside body `outer`,
    /// tested in `outer`'s own frame (where its mesh is, and where the
    /// differences are small however far from the origin the bodies stand).
    fn vertex_inside(&self, inner: usize, outer: usize) -> bool {
        let (bi, bo) = (&self.bodies[inner], &self.bodies[outer]);
        let p = bi.to_world(self.shapes[bi.shape].vertices[0]);
        self.shapes[bo.shape].contains(bo.q.inverse() * (p - bo.x))
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

/// Whether box `inner` lies within box `outer`.
fn within(inner: (DVec3, DVec3), outer: (DVec3, DVec3)) -> bool {
    inner.0.cmpge(outer.0).all() && inner.1.cmple(outer.1).all()
}

/// The axis along which the points spread most.
fn spread_axis(points: impl Iterator<Item = DVec3>) -> usize {
    let (lo, hi) = points.fold((DVec3::INFINITY, DVec3::NEG_INFINITY), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    });
    let d = hi - lo;
    if d.x >= d.y && d.x >= d.z {
        0
    } else if d.y >= d.z {
        1
    } else {
        2
    }
}
