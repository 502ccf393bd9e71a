//! The complete state of a running simulation, to stop a run and resume it
//! later with the same answers, bit for bit, as if it had not stopped.
//!
//! Velocity Verlet carries the forces of the last evaluation into the next
//! step's opening half kick, and those forces were evaluated at the half-step
//! velocities: they cannot be recomputed from the positions and velocities an
//! output step holds. Friction carries each contact's tangential spring. So a
//! checkpoint holds, besides the bodies, the forces and every effect's own
//! state. What is derived (neighbour lists, triangle caches) is rebuilt.

use glam::{DQuat, DVec3};

/// The moving state of one body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyState {
    pub x: DVec3,
    pub q: DQuat,
    pub v: DVec3,
    pub l: DVec3,
}

impl BodyState {
    /// The moving state of `b`.
    pub fn of(b: &crate::body::Body) -> BodyState {
        BodyState {
            x: b.x,
            q: b.q,
            v: b.v,
            l: b.l,
        }
    }
}

/// What one effect of the pipeline carries from step to step, as numbers.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EffectState {
    /// The effect's name in the scene (`friction`, ...).
    pub effect: String,
    /// Its books ([`Ledger::state`](crate::ledger::Ledger::state)): the
    /// parts of the exact sums of the energy it stores and of the work it
    /// has taken (both empty when it keeps no books).
    pub stored: Vec<f64>,
    pub taken: Vec<f64>,
    /// Its per-contact history, rows of `row` numbers
    /// ([`ContactHistory`](crate::effects::ContactHistory); `row` 0: none).
    pub row: usize,
    pub history: Vec<f64>,
}

/// Everything a [`Simulation`](crate::simulation::Simulation) needs to go on
/// from where it was, given the scene it was built from.
#[derive(Debug, Clone, PartialEq)]
pub struct Checkpoint {
    pub time: f64,
    pub step: u64,
    /// The time step the run used: resuming with another would not continue it.
    pub dt: f64,
    /// [`World::fingerprint`](crate::world::World::fingerprint) of the run's
    /// scene.
    pub fingerprint: u64,
    pub bodies: Vec<BodyState>,
    /// The last force evaluation, per body.
    pub force: Vec<DVec3>,
    pub torque: Vec<DVec3>,
    /// One entry per effect of the pipeline that has state, in pipeline order.
    pub effects: Vec<EffectState>,
}

impl Checkpoint {
    /// A digest of every number and name the checkpoint holds (FNV-1a over
    /// their bits): stored with it on disk, so that a damaged file (one
    /// flipped bit) is refused rather than resumed from garbage.
    pub fn checksum(&self) -> u64 {
        let mut h = crate::world::Fnv1a::default();
        h.f64(self.time);
        h.u64(self.step);
        h.f64(self.dt);
        h.u64(self.fingerprint);
        h.u64(self.bodies.len() as u64);
        for b in &self.bodies {
            let numbers = [b.x.to_array(), b.v.to_array(), b.l.to_array()];
            numbers.iter().flatten().for_each(|&c| h.f64(c));
            b.q.to_array().into_iter().for_each(|c| h.f64(c));
        }
        for v in self.force.iter().chain(&self.torque) {
            v.to_array().into_iter().for_each(|c| h.f64(c));
        }
        for e in &self.effects {
            h.bytes(e.effect.as_bytes());
            h.u64(e.row as u64);
            for part in [&e.stored, &e.taken, &e.history] {
                h.u64(part.len() as u64);
                part.iter().for_each(|&v| h.f64(v));
            }
        }
        h.0
    }
}

/// Why a checkpoint does not fit the scene it is resumed with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct CheckpointError(pub String);
