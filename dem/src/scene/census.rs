//! What the whole scene is made of, in a few lines whatever its size: one
//! run of bodies per `[[particles]]` entry (same shape, material and mass,
//! consecutive ids) and one per obstacle (with where it stands).
//!
//! A scene loaded for one rank of a split run ([`super::Deal`]) holds only
//! that rank's particles; what needs the whole scene (its counts, the
//! fingerprint a checkpoint carries, the line that placed a body, the
//! output's layout, the stable step) reads the census instead, so that no
//! rank keeps a list of every body.

use crate::body::Drive;
use crate::fingerprint::{hash_body, Fnv1a};
use glam::{DMat3, DQuat, DVec3};
use std::ops::Range;

/// Consecutive bodies alike in all a run cannot change.
#[derive(Debug, Clone, PartialEq)]
pub struct Run {
    /// Their ids in the whole scene.
    pub ids: Range<u32>,
    pub shape: usize,
    pub material: usize,
    /// Each body's mass (infinite for an obstacle).
    pub mass: f64,
    /// Each body's inverse inertia tensor in body axes (zero for an obstacle).
    pub inv_inertia: DMat3,
    /// The line of the scene file that placed them.
    pub line: usize,
    /// An obstacle's position and orientation at time 0 (`None`: particles).
    pub fixed: Option<(DVec3, DQuat)>,
    /// A moving obstacle's motion.
    pub drive: Option<Drive>,
}

/// The runs of a scene, in id order: the particles' first, then the
/// obstacles'.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Census {
    runs: Vec<Run>,
}

impl Census {
    /// Appends a run (its ids next in line; particles before obstacles).
    pub(super) fn push(&mut self, run: Run) {
        debug_assert_eq!(run.ids.start as usize, self.bodies());
        debug_assert!(
            run.fixed.is_some() || self.obstacles() == 0,
            "particles come before obstacles"
        );
        if !run.ids.is_empty() {
            self.runs.push(run);
        }
    }

    pub fn runs(&self) -> &[Run] {
        &self.runs
    }

    /// Bodies in the whole scene.
    pub fn bodies(&self) -> usize {
        self.runs.last().map_or(0, |r| r.ids.end as usize)
    }

    /// Particles in the whole scene: ids `0..particles()`.
    pub fn particles(&self) -> usize {
        self.particle_runs().map(|r| r.ids.len()).sum()
    }

    pub fn obstacles(&self) -> usize {
        self.bodies() - self.particles()
    }

    pub(crate) fn particle_runs(&self) -> impl Iterator<Item = &Run> {
        self.runs.iter().filter(|r| r.fixed.is_none())
    }

    /// Triangles of all particles, given the scene's shapes' triangle counts.
    pub fn particle_triangles(&self, triangles: impl Fn(usize) -> usize) -> usize {
        self.particle_runs()
            .map(|r| r.ids.len() * triangles(r.shape))
            .sum()
    }

    /// The run body `id` belongs to.
    pub fn run_of(&self, id: usize) -> Option<&Run> {
        let k = self.runs.partition_point(|r| (r.ids.end as usize) <= id);
        self.runs.get(k)
    }

    /// Per body, in id order: its shape.
    pub fn shapes(&self) -> impl Iterator<Item = usize> + '_ {
        self.runs
            .iter()
            .flat_map(|r| std::iter::repeat_n(r.shape, r.ids.len()))
    }

    /// The materials some body is made of, and whether a particle is.
    pub fn materials_used(&self, materials: usize) -> (Vec<bool>, Vec<bool>) {
        let (mut used, mut by_particles) = (vec![false; materials], vec![false; materials]);
        for r in &self.runs {
            used[r.material] = true;
            by_particles[r.material] |= r.fixed.is_none();
        }
        (used, by_particles)
    }

    /// The lightest particle's mass (infinite without particles).
    pub fn lightest(&self) -> f64 {
        self.particle_runs()
            .map(|r| r.mass)
            .fold(f64::INFINITY, f64::min)
    }

    /// Feeds, body by body in id order, what [`crate::world::World::fingerprint`]
    /// hashes of each.
    pub(crate) fn hash_bodies(&self, h: &mut Fnv1a) {
        for r in &self.runs {
            for _ in r.ids.clone() {
                hash_body(h, r.shape, r.material, r.mass, r.fixed, r.drive.as_ref());
            }
        }
    }
}
