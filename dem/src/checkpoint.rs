//! The complete state of a running simulation, to stop a run and resume it
//! later with the same answers, bit for bit, as if it had not stopped.
//!
//! Velocity Verlet carries the forces of the last evaluation into the next
//! step's opening half kick, and those forces were evaluated at the half-step
//! velocities: they cannot be recomputed from the positions and velocities an
//! output step holds. Friction carries each contact's tangential spring. So a
//! checkpoint holds, besides the bodies, the forces and every effect's own
//! state. What is derived (neighbour lists, triangle caches) is rebuilt.

use crate::scene::Deal;
use glam::{DQuat, DVec3};

/// The moving state of one body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BodyState {
    pub x: DVec3,
    pub q: DQuat,
    pub v: DVec3,
    pub l: DVec3,
    /// Taken out of the run by an outflow ([`Body::removed`](crate::body::Body::removed)).
    pub removed: bool,
    /// Waiting to be inserted ([`Body::pending`](crate::body::Body::pending)).
    pub pending: bool,
}

impl BodyState {
    /// The moving state of `b`.
    pub fn of(b: &crate::body::Body) -> BodyState {
        BodyState {
            x: b.x,
            q: b.q,
            v: b.v,
            l: b.l,
            removed: b.removed,
            pending: b.pending,
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
        let mut d = Digest::new(self.time, self.step, self.dt, self.fingerprint);
        d.count(self.bodies.len());
        self.bodies.iter().for_each(|b| d.body(b));
        self.force
            .iter()
            .chain(&self.torque)
            .for_each(|&v| d.vector(v));
        for e in &self.effects {
            d.effect(&e.effect, e.row);
            for part in [&e.stored, &e.taken, &e.history] {
                d.count(part.len());
                part.iter().for_each(|&v| d.number(v));
            }
        }
        d.finish()
    }
}

/// [`Checkpoint::checksum`] fed piece by piece, in the order it reads a
/// checkpoint, so that a file too large to hold at once can be checked as
/// it streams by: the header, the body count, every body's state, every
/// force then every torque, and per effect its name and row length followed
/// by each part's length and numbers.
pub struct Digest(crate::fingerprint::Fnv1a);

impl Digest {
    pub fn new(time: f64, step: u64, dt: f64, fingerprint: u64) -> Digest {
        let mut h = crate::fingerprint::Fnv1a::default();
        h.f64(time);
        h.u64(step);
        h.f64(dt);
        h.u64(fingerprint);
        Digest(h)
    }

    pub fn count(&mut self, n: usize) {
        self.0.u64(n as u64);
    }

    pub fn body(&mut self, b: &BodyState) {
        let numbers = [b.x.to_array(), b.v.to_array(), b.l.to_array()];
        numbers.iter().flatten().for_each(|&c| self.0.f64(c));
        b.q.to_array().into_iter().for_each(|c| self.0.f64(c));
        // Only a removed body adds to the digest: a run without an outflow
        // digests as it did before bodies could be removed.
        if b.removed {
            self.0.u64(1);
        }
        // Likewise a body waiting to be inserted.
        if b.pending {
            self.0.u64(2);
        }
    }

    pub fn vector(&mut self, v: DVec3) {
        v.to_array().into_iter().for_each(|c| self.0.f64(c));
    }

    pub fn effect(&mut self, name: &str, row: usize) {
        self.0.bytes(name.as_bytes());
        self.0.u64(row as u64);
    }

    pub fn number(&mut self, v: f64) {
        self.0.f64(v);
    }

    pub fn finish(self) -> u64 {
        self.0 .0
    }
}

/// What one rank of a distributed run keeps of a checkpoint: the run's
/// header, the state, force and torque of each particle the scene deals to
/// it ([`Deal`]: ids `deal.rank`, `deal.rank + deal.ranks`, ... below the
/// particle count), and the effects' states with only the history rows it
/// restores ([`Deal::keeps_row`]). Obstacles do not move: their state is the
/// scene's. A rank never holds the whole checkpoint, however large the run.
#[derive(Debug, Clone, PartialEq)]
pub struct CheckpointShare {
    pub time: f64,
    pub step: u64,
    pub dt: f64,
    pub fingerprint: u64,
    /// Rows in the whole checkpoint of states, forces and torques.
    pub counts: [usize; 3],
    pub deal: Deal,
    pub bodies: Vec<BodyState>,
    pub force: Vec<DVec3>,
    pub torque: Vec<DVec3>,
    pub effects: Vec<EffectState>,
}

impl CheckpointShare {
    /// The share of `c` that `deal` gives one rank, of a scene of
    /// `particles` particles.
    pub fn of(c: &Checkpoint, deal: Deal, particles: usize) -> CheckpointShare {
        let ids = Deal::ids(deal, particles.min(c.bodies.len()));
        let pick = |v: &[DVec3]| ids.clone().filter_map(|i| v.get(i).copied()).collect();
        CheckpointShare {
            time: c.time,
            step: c.step,
            dt: c.dt,
            fingerprint: c.fingerprint,
            counts: [c.bodies.len(), c.force.len(), c.torque.len()],
            deal,
            bodies: ids.clone().map(|i| c.bodies[i]).collect(),
            force: pick(&c.force),
            torque: pick(&c.torque),
            effects: c
                .effects
                .iter()
                .map(|e| EffectState {
                    history: deal.rows_kept(&e.history, e.row, particles),
                    ..e.clone()
                })
                .collect(),
        }
    }

    /// Particle `id`'s state, force and torque, when this share holds it.
    pub fn state(&self, id: usize) -> Option<(BodyState, DVec3, DVec3)> {
        let ranks = self.deal.ranks as usize;
        if id % ranks != self.deal.rank as usize {
            return None;
        }
        let k = id / ranks;
        Some((
            *self.bodies.get(k)?,
            *self.force.get(k)?,
            *self.torque.get(k)?,
        ))
    }

    /// The ids of the particles held, with their states, forces and torques.
    pub fn held(&self) -> impl Iterator<Item = (usize, &BodyState, &DVec3, &DVec3)> {
        let (rank, ranks) = (self.deal.rank as usize, self.deal.ranks as usize);
        (0..self
            .bodies
            .len()
            .min(self.force.len())
            .min(self.torque.len()))
            .map(move |k| {
                (
                    rank + k * ranks,
                    &self.bodies[k],
                    &self.force[k],
                    &self.torque[k],
                )
            })
    }
}

impl Deal {
    /// The ids dealt to this rank among the first `particles`.
    pub fn ids(self, particles: usize) -> impl Iterator<Item = usize> + Clone {
        (self.rank as usize..particles).step_by(self.ranks.max(1) as usize)
    }

    /// Whether this rank restores the history row naming bodies `a` and `b`
    /// (the row's first two numbers) of a scene of `particles` particles:
    /// the rank the contact's home is dealt to, the home being `a`, or `b`
    /// when `a` is an obstacle. Rank 0 also keeps a row whose home is no
    /// particle, so that restoring it refuses it as one process would.
    pub fn keeps_row(self, a: f64, b: f64, particles: usize) -> bool {
        let particle = |v: f64| (v >= 0.0 && v.fract() == 0.0 && v < particles as f64).then_some(v);
        let home = match particle(a) {
            Some(a) => Some(a),
            None if a.fract() == 0.0 && a >= particles as f64 => particle(b),
            None => None,
        };
        match home {
            Some(h) => self.keeps(h as u32),
            None => self.rank == 0,
        }
    }

    /// The rows of `history` (rows of `row` numbers) this rank restores; a
    /// history not made of whole rows is kept whole by rank 0, to be refused.
    pub fn rows_kept(self, history: &[f64], row: usize, particles: usize) -> Vec<f64> {
        if row < 2 || !history.len().is_multiple_of(row) {
            return if self.rank == 0 {
                history.to_vec()
            } else {
                Vec::new()
            };
        }
        history
            .chunks_exact(row)
            .filter(|r| self.keeps_row(r[0], r[1], particles))
            .flatten()
            .copied()
            .collect()
    }
}

/// Why a checkpoint does not fit the scene it is resumed with.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[error("{0}")]
pub struct CheckpointError(pub String);
