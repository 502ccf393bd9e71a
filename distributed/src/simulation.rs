//! The distributed step.
//!
//! **Who owns what.** The unit of the partition is the particle (a body of
//! a few dozen triangles), weighted by its triangle count: the contact model
//! builds each body pair's contacts from the features of both bodies and
//! all their triangle contacts together (`dem::contact::features`), so the
//! triangles of a pair must meet on one rank whatever the unit; with bodies
//! as the unit they do, and no triangle contact, no body state and no force
//! has to be routed between a triangle's rank and its body's. Each particle
//! has one owner, which integrates it. Obstacles are on every rank (they do
//! not move, and as items one wall spanning the scene would reach every rank).
//!
//! **What travels when.**
//! - At the start and every K steps: the partitioner assigns the particles;
//!   a particle that changes rank takes its motion and last force with it
//!   (blocking), and the friction history of each contact goes from its
//!   *home* (the owner of its first particle) to the new owners of both
//!   bodies. An owner table, gathered on every rank, is checked: every
//!   particle has exactly one owner.
//! - Every step: owners integrate their particles; the motions of the
//!   particles near another rank go there as ghosts (non-blocking, during
//!   the detection among owned bodies and obstacles); then the detection
//!   between owned and ghost bodies.
//!
//! **Why the results do not depend on the rank count.** A body pair across a
//! cut is computed on both ranks, from the same bits (ghosts are exact copies,
//! and a pair's contacts depend on its two bodies alone), and each rank acts
//! on its own body: no force travels back. A rank's contacts are those of its
//! own bodies, in the order of one process's (by body pair), so the effects
//! add each body's forces in the same order; the contact effect applies its
//! law to these contacts exactly as on one process. The energy books are
//! exact sums (`dem::ledger`), whose terms each rank enters for its own
//! bodies and the contacts whose home it is, merged every step.

use crate::ghosts::{exchange_motions_during, Exchange, GhostLists};
use crate::metrics::StepMetrics;
use crate::records::{BodyRecord, ContactRecord, HistoryRow, Motion, Ownership};
use dem::checkpoint::{BodyState, Checkpoint, EffectState};
use dem::contact::{
    body_contacts, body_triangles, Contact, DetectionStats, Detector, Phase, TriangleContact,
    TriangleKey, TriangleSet,
};
use dem::distance::{Options, Triangle};
use dem::effects::{
    Declare, Effect, Forces, FrictionEffect, FrictionParams, StepContext, StepStats,
};
use dem::integrate::{drift, half_kick, travel_bound};
use dem::ledger::ExactSum;
use dem::mesh::Features;
use dem::scene::Scene;
use dem::simulation::Simulation;
use dem::world::World;
use glam::DVec3;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use partition::comm::{all_gather_v, all_to_all_v};
use partition::{Aabb, Backend, Item, Partitioner};
use std::time::Instant;

/// How a run is split.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    pub partitioner: Backend,
    /// Repartition every this many steps (`None`: only at the start).
    pub repartition_every: Option<u64>,
    pub exchange: Exchange,
    /// The ghost lists' skin: they are drawn anew once some body may have
    /// moved half of it (0: every step).
    pub skin: f64,
}

/// A run's state gathered on rank 0: what a checkpoint holds, and the
/// contacts of the last evaluation with the force on body a of each.
pub struct Gathered {
    pub checkpoint: Checkpoint,
    pub contacts: Vec<Contact>,
    pub contact_forces: Vec<DVec3>,
}

/// A simulation stepped on every rank of a communicator.
pub struct DistributedSimulation<'c> {
    comm: &'c SimpleCommunicator,
    part: Box<dyn Partitioner + 'c>,
    settings: Settings,
    /// Every body; current are the owned ones, the ghosts and the obstacles.
    pub world: World,
    dt: f64,
    rotation: bool,
    effects: Vec<Box<dyn Effect>>,
    /// Index of the friction effect, whose history moves with the bodies.
    friction: Option<usize>,
    contact: bool,
    shape_radius: Vec<f64>,
    forces: Forces,
    ctx: StepContext,
    features: Vec<Features>,
    halos: Vec<f64>,
    kernel: Options,
    detector: Detector,
    /// The obstacles' triangles, in world space once and for all.
    obstacles: Vec<(TriangleKey, Triangle)>,
    /// Per body: the rank owning it (-1: an obstacle, on every rank).
    owner: Vec<i32>,
    owned: Vec<usize>,
    is_owned: Vec<bool>,
    lists: GhostLists,
    lists_stale: bool,
    /// How far any body may have moved since the lists were drawn.
    travel: f64,
    steps_run: u64,
    /// Steps in a row, up to the last one, in which some rank found a
    /// contact deeper than the halos.
    deep_steps: u64,
    metrics: StepMetrics,
    /// Counters summed over this rank's steps (contacts: those it books).
    pub totals: StepStats,
    found: Vec<TriangleContact>,
    /// This rank's triangles, kept between steps for their storage.
    set: TriangleSet,
    owned_triangles: Vec<(TriangleKey, Triangle)>,
}

fn fail<T>(why: impl Into<String>) -> Result<T, String> {
    Err(why.into())
}

impl<'c> DistributedSimulation<'c> {
    /// Splits `sim` (the same on every rank: new, or resumed from a
    /// checkpoint, of `scene`) across the ranks of `comm`. Collective.
    pub fn new(
        comm: &'c SimpleCommunicator,
        scene: &Scene,
        sim: Simulation,
        settings: Settings,
    ) -> Result<Self, String> {
        let parts = sim.into_parts();
        let world = parts.world;
        let halos = world.per_body(|m| m.halo);
        let max_halo = halos.iter().copied().fold(0.0, f64::max);
        let part = settings
            .partitioner
            .create(comm, max_halo)
            .map_err(|e| e.to_string())?;
        let mut obstacles = Vec::new();
        for (i, b) in world.bodies.iter().enumerate() {
            if b.is_static() {
                body_triangles(&world, i, &mut obstacles);
            }
        }
        // Dealt out in turn until the partitioner has placed them.
        let size = comm.size();
        let mut dealt = 0;
        let owner: Vec<i32> = world
            .bodies
            .iter()
            .map(|b| {
                if b.is_static() {
                    -1
                } else {
                    dealt += 1;
                    (dealt - 1) % size
                }
            })
            .collect();
        let me = comm.rank();
        let owned: Vec<usize> = (0..owner.len()).filter(|&i| owner[i] == me).collect();
        let mut is_owned = vec![false; owner.len()];
        owned.iter().for_each(|&i| is_owned[i] = true);
        let friction = parts
            .effects
            .iter()
            .position(|e| e.name() == <FrictionParams as Declare>::NAME);
        let mut s = DistributedSimulation {
            comm,
            part,
            settings,
            features: world.shapes.iter().map(Features::of).collect(),
            dt: parts.dt,
            rotation: parts.rotation,
            effects: parts.effects,
            friction,
            contact: scene.effects.has::<dem::effects::ContactParams>(),
            shape_radius: parts.shape_radius,
            forces: parts.forces,
            ctx: StepContext {
                dt: parts.dt,
                ..StepContext::default()
            },
            halos,
            kernel: scene.kernel,
            detector: Detector::default(),
            obstacles,
            owner,
            owned,
            is_owned,
            lists: GhostLists::default(),
            lists_stale: true,
            travel: 0.0,
            steps_run: 0,
            deep_steps: 0,
            metrics: StepMetrics::default(),
            totals: StepStats::default(),
            found: Vec::new(),
            set: TriangleSet::default(),
            owned_triangles: Vec::new(),
            world,
        };
        s.repartition()?;
        Ok(s)
    }

    /// Steps in a row, up to the one before the last, in which some rank
    /// found a contact deeper than the halos (the same on every rank).
    pub fn deep_steps_in_a_row(&self) -> u64 {
        self.deep_steps
    }

    /// The particles this rank owns, in increasing id.
    pub fn owned(&self) -> &[usize] {
        &self.owned
    }

    /// The contacts of the last evaluation that this rank books (each
    /// contact of the run is booked on one rank).
    pub fn booked_contacts(&self) -> impl Iterator<Item = &Contact> {
        let ctx = &self.ctx;
        ctx.contacts
            .iter()
            .enumerate()
            .filter(|&(k, _)| ctx.books_contact(k))
            .map(|(_, c)| c)
    }

    /// What this rank measured in the last step.
    pub fn metrics(&self) -> &StepMetrics {
        &self.metrics
    }

    pub fn rank(&self) -> i32 {
        self.comm.rank()
    }

    /// The rank that books a contact of bodies a < b: the owner of its first particle.
    fn home(&self, a: usize, b: usize) -> i32 {
        if self.owner[a] >= 0 {
            self.owner[a]
        } else {
            self.owner[b]
        }
    }

    /// Load balancing and migration (collective; see the module doc).
    fn repartition(&mut self) -> Result<(), String> {
        let start = Instant::now();
        let me = self.comm.rank();
        let world = &self.world;
        let items: Vec<Item> = self
            .owned
            .iter()
            .map(|&i| {
                let b = crate::ghosts::body_box(world, &self.shape_radius, i, self.halos[i]);
                Item {
                    id: i as u64,
                    point: world.bodies[i].x.to_array(),
                    weight: world.shapes[world.bodies[i].shape].triangles.len() as f64,
                    bbox: Aabb::new(b.lo.to_array(), b.hi.to_array()),
                    payload_bytes: std::mem::size_of::<BodyRecord>() as u32,
                }
            })
            .collect();
        let placed = self.part.partition(self.comm, &items);
        // Every rank learns whether any failed before any returns.
        let ok = i32::from(placed.is_ok());
        let mut all_ok = 0;
        self.comm
            .all_reduce_into(&ok, &mut all_ok, SystemOperation::min());
        let new_owner_of_item = match placed {
            Ok(o) if all_ok == 1 => o,
            Ok(_) => return fail("partitioning failed on another rank"),
            Err(e) => return fail(format!("partitioning: {e}")),
        };
        self.metrics.partition_seconds += start.elapsed().as_secs_f64();
        let start = Instant::now();
        let size = self.comm.size() as usize;
        let mut outbox: Vec<Vec<BodyRecord>> = vec![Vec::new(); size];
        let mut kept = Vec::new();
        for (&i, &r) in self.owned.iter().zip(&new_owner_of_item) {
            if r == me {
                kept.push(i);
            } else {
                outbox[r as usize].push(BodyRecord {
                    id: i as u64,
                    motion: Motion::of(&self.world.bodies[i]),
                    force: self.forces.force[i].to_array(),
                    torque: self.forces.torque[i].to_array(),
                });
            }
        }
        let sent: usize = outbox.iter().map(Vec::len).sum();
        self.metrics.migrated_bodies += sent as u64;
        self.metrics.migrated_bytes += (sent * std::mem::size_of::<BodyRecord>()) as u64;
        let counts: Vec<Count> = outbox.iter().map(|v| v.len() as Count).collect();
        let flat: Vec<BodyRecord> = outbox.into_iter().flatten().collect();
        let (arrived, _) = all_to_all_v(self.comm, &flat, &counts);
        for r in &arrived {
            let i = r.id as usize;
            r.motion.put(&mut self.world.bodies[i]);
            self.forces.force[i] = DVec3::from_array(r.force);
            self.forces.torque[i] = DVec3::from_array(r.torque);
            kept.push(i);
        }
        kept.sort_unstable();
        let new_owner = self.owner_table(&kept)?;
        self.migrate_history(&new_owner)?;
        self.owner = new_owner;
        self.is_owned.iter_mut().for_each(|o| *o = false);
        kept.iter().for_each(|&i| self.is_owned[i] = true);
        self.owned = kept;
        self.lists_stale = true;
        self.metrics.migration_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// Every rank's owned particles, as an owner per body (collective);
    /// refused unless each particle has exactly one owner.
    fn owner_table(&self, owned: &[usize]) -> Result<Vec<i32>, String> {
        let me = self.comm.rank() as u64;
        let mine: Vec<Ownership> = owned
            .iter()
            .map(|&i| Ownership {
                body: i as u64,
                rank: me,
            })
            .collect();
        let all = all_gather_v(self.comm, &mine);
        let mut owner: Vec<i32> = self
            .world
            .bodies
            .iter()
            .map(|b| if b.is_static() { -1 } else { -2 })
            .collect();
        for Ownership { body: i, rank: r } in all {
            let slot = &mut owner[i as usize];
            if *slot != -2 {
                return fail(format!(
                    "after migration body {i} is owned twice (ranks {slot} and {r})"
                ));
            }
            *slot = r as i32;
        }
        if let Some(i) = owner.iter().position(|&o| o == -2) {
            return fail(format!("after migration body {i} has no owner"));
        }
        Ok(owner)
    }

    /// Sends each friction contact from its home (under the old owners) to
    /// the new owners of its bodies; each rank's history becomes what it received.
    fn migrate_history(&mut self, new_owner: &[i32]) -> Result<(), String> {
        let Some(k) = self.friction else {
            return Ok(());
        };
        let me = self.comm.rank();
        let values = self.effects[k].state().unwrap_or_default();
        let (head, rows) = values.split_at(FrictionEffect::STATE_HEAD.min(values.len()));
        let size = self.comm.size() as usize;
        let mut outbox: Vec<Vec<HistoryRow>> = vec![Vec::new(); size];
        for row in rows.chunks_exact(FrictionEffect::STATE_ROW) {
            let r = HistoryRow {
                row: row.try_into().expect("rows of 8"),
            };
            let (a, b) = r.pair();
            if self.home(a, b) != me {
                continue;
            }
            let mut to = [new_owner[a], new_owner[b]];
            if to[1] == to[0] {
                to[1] = -1;
            }
            for t in to.into_iter().filter(|&t| t >= 0) {
                outbox[t as usize].push(r);
            }
        }
        let counts: Vec<Count> = outbox.iter().map(|v| v.len() as Count).collect();
        let flat: Vec<HistoryRow> = outbox.into_iter().flatten().collect();
        let (mut arrived, _) = all_to_all_v(self.comm, &flat, &counts);
        arrived.sort_unstable_by_key(HistoryRow::key);
        let mut restored = head.to_vec();
        arrived.iter().for_each(|r| restored.extend(r.row));
        self.effects[k].restore(&restored, &self.world)
    }

    /// One velocity-Verlet step on every rank (collective). `stop`: this
    /// rank was asked to stop (a signal); returns whether any rank was, so
    /// that all stop after the same step.
    pub fn step(&mut self, stop: bool) -> Result<bool, String> {
        let step_start = Instant::now();
        // The first step carries what the initial partitioning cost.
        let carried = if self.steps_run == 0 {
            self.metrics
        } else {
            StepMetrics::default()
        };
        self.metrics = StepMetrics {
            step: self.world.step + 1,
            ..carried
        };
        self.steps_run += 1;
        let due = self
            .settings
            .repartition_every
            .is_some_and(|k| k > 0 && self.steps_run > 1 && (self.steps_run - 1).is_multiple_of(k));
        if due {
            self.repartition()?;
        }
        let start = Instant::now();
        let (h, rot) = (self.dt, self.rotation);
        let mut moved: f64 = 0.0;
        for &i in &self.owned {
            let b = &mut self.world.bodies[i];
            half_kick(b, self.forces.force[i], self.forces.torque[i], h, rot);
            let before = (b.x, b.q);
            drift(b, h, rot);
            moved = moved.max(travel_bound(before, b, self.shape_radius[b.shape]));
        }
        self.metrics.integration_seconds += start.elapsed().as_secs_f64();
        let mut waited = Instant::now();
        // Any state gone non-finite ends the run on every rank.
        let finite = self.owned.iter().all(|&i| {
            let b = &self.world.bodies[i];
            b.x.is_finite() && b.v.is_finite() && b.q.is_finite() && b.l.is_finite()
        });
        let local = [
            moved,
            f64::from(u8::from(stop)),
            f64::from(u8::from(!finite)),
            f64::from(u8::from(self.ctx.stats.detection.deep_contacts > 0)),
        ];
        let mut global = [0.0; 4];
        self.comm
            .all_reduce_into(&local[..], &mut global[..], SystemOperation::max());
        let mut wait = waited.elapsed().as_secs_f64();
        if global[2] > 0.0 {
            return fail(format!(
                "the simulation became non-finite at step {} (t = {:e} s): the time step is \
                 too large for this scene, or its input holds a non-finite value",
                self.world.step + 1,
                self.world.time + h
            ));
        }
        self.deep_steps = if global[3] > 0.0 {
            self.deep_steps + 1
        } else {
            0
        };
        // NaN (a body's state gone bad) redraws too.
        self.travel += global[0];
        let within = self.travel <= 0.5 * self.settings.skin;
        if self.lists_stale || !within {
            self.lists = GhostLists::draw(
                self.comm,
                &self.world,
                &self.shape_radius,
                &self.halos,
                &self.owned,
                0.5 * self.settings.skin,
            );
            self.travel = 0.0;
            self.lists_stale = false;
            self.metrics.lists_drawn = 1;
        }
        wait += self.evaluate_forces();
        let start = Instant::now();
        for &i in &self.owned {
            let b = &mut self.world.bodies[i];
            half_kick(b, self.forces.force[i], self.forces.torque[i], h, rot);
        }
        self.world.time += h;
        self.world.step += 1;
        self.totals += self.ctx.stats;
        self.metrics.integration_seconds += start.elapsed().as_secs_f64();
        waited = step_start;
        let m = &mut self.metrics;
        m.owned_bodies = self.owned.len() as u64;
        m.owned_triangles = self
            .owned
            .iter()
            .map(|&i| {
                self.world.shapes[self.world.bodies[i].shape]
                    .triangles
                    .len() as u64
            })
            .sum();
        m.step_seconds = waited.elapsed().as_secs_f64();
        m.busy_seconds = (m.step_seconds - wait).max(0.0);
        Ok(global[1] > 0.0)
    }

    /// Contacts and forces of the current state; returns the seconds spent
    /// waiting for other ranks.
    fn evaluate_forces(&mut self) -> f64 {
        let mut wait = 0.0;
        self.ctx.contacts.clear();
        self.ctx.stats = StepStats::default();
        if self.contact {
            wait += self.find_contacts();
        }
        let start = Instant::now();
        let me = self.comm.rank();
        let booked: Vec<bool> = self
            .ctx
            .contacts
            .iter()
            .map(|c| self.home(c.a, c.b) == me)
            .collect();
        self.ctx.stats.detection.contacts = booked.iter().filter(|&&b| b).count() as u64;
        self.metrics.contacts = self.ctx.stats.detection.contacts;
        self.ctx.booked_contacts = booked;
        self.ctx.booked_bodies.clone_from(&self.is_owned);
        self.ctx.contacts_found = true;
        self.forces.reset(self.world.bodies.len());
        for e in &mut self.effects {
            e.apply(&self.world, &mut self.ctx, &mut self.forces);
        }
        self.metrics.force_seconds += start.elapsed().as_secs_f64();
        let start = Instant::now();
        self.close_books();
        wait + start.elapsed().as_secs_f64()
    }

    /// Finds the contacts of the owned bodies into `ctx.contacts`: the ghost
    /// exchange around the detection among owned bodies and obstacles, then
    /// the detection between owned and ghost bodies. Returns the wait.
    fn find_contacts(&mut self) -> f64 {
        let start = Instant::now();
        // In key order when the obstacles are numbered last (scenes number
        // them so); `set_owned` sorts otherwise.
        let mut owned = std::mem::take(&mut self.owned_triangles);
        owned.clear();
        for &i in &self.owned {
            body_triangles(&self.world, i, &mut owned);
        }
        owned.extend_from_slice(&self.obstacles);
        let mut set = std::mem::take(&mut self.set);
        set.set_owned(&mut owned, &self.halos);
        self.owned_triangles = owned;
        self.found.clear();
        let (world, halos, kernel) = (&self.world, &self.halos, &self.kernel);
        let (detector, found) = (&mut self.detector, &mut self.found);
        let received = exchange_motions_during(
            self.comm,
            &self.lists,
            world,
            self.settings.exchange,
            || {
                let start = Instant::now();
                let stats = detector.triangle_contacts(
                    world,
                    &set,
                    halos,
                    kernel,
                    Phase::LocalLocal,
                    found,
                );
                (stats, start.elapsed().as_secs_f64())
            },
        );
        let (local_stats, local_secs) = received.work;
        self.metrics.local_local_seconds += local_secs;
        self.metrics.wait_seconds += received.wait;
        let start_ghosts = Instant::now();
        let mut ghosts = Vec::new();
        for (ids, motions) in self.lists.receive.iter().zip(&received.motions) {
            for (&i, m) in ids.iter().zip(motions) {
                m.put(&mut self.world.bodies[i]);
                body_triangles(&self.world, i, &mut ghosts);
            }
        }
        let (sent, got) = (self.lists.sent(), self.lists.received());
        let bytes = std::mem::size_of::<Motion>() as u64;
        self.metrics.ghosts_sent = sent as u64;
        self.metrics.ghosts_received = got as u64;
        self.metrics.ghost_bytes_sent = sent as u64 * bytes;
        self.metrics.ghost_bytes_received = got as u64 * bytes;
        set.set_ghosts(ghosts, &self.halos);
        let across = self.detector.triangle_contacts(
            &self.world,
            &set,
            &self.halos,
            &self.kernel,
            Phase::Across,
            &mut self.found,
        );
        self.set = set;
        self.metrics.local_ghost_seconds += start_ghosts.elapsed().as_secs_f64();
        let start_build = Instant::now();
        let is_owned = &self.is_owned;
        self.found
            .retain(|t| is_owned[t.a.body as usize] || is_owned[t.b.body as usize]);
        let (_, deep) = body_contacts(
            &mut self.found,
            &self.world,
            &self.features,
            &self.halos,
            &mut self.ctx.contacts,
        );
        let mut stats = local_stats;
        stats += across;
        stats.deep_contacts = deep;
        self.ctx.stats.detection = DetectionStats { ..stats };
        self.metrics.force_seconds += start_build.elapsed().as_secs_f64();
        let _ = start;
        received.wait
    }

    /// Merges the ranks' terms of every effect's books and closes them
    /// (collective).
    fn close_books(&mut self) {
        let mut mine = Vec::new();
        for e in &mut self.effects {
            if let Some(l) = e.ledger_mut() {
                for sum in [&l.step_stored, &l.step_taken] {
                    let parts = sum.parts();
                    mine.push(parts.len() as f64);
                    mine.extend(parts);
                }
            }
        }
        let all = all_gather_v(self.comm, &mine);
        let per_rank = 2 * self
            .effects
            .iter_mut()
            .filter_map(|e| e.ledger_mut())
            .count();
        let mut merged = vec![ExactSum::default(); per_rank];
        let mut at = 0;
        // Each rank's block: the same sums in the same order, each its
        // number of parts, then the parts.
        while at < all.len() {
            for sum in &mut merged {
                let n = all[at] as usize;
                sum.merge(&ExactSum::from_parts(&all[at + 1..at + 1 + n]));
                at += 1 + n;
            }
        }
        let mut sums = merged.into_iter();
        for e in &mut self.effects {
            if let Some(l) = e.ledger_mut() {
                l.step_stored = sums.next().unwrap_or_default();
                l.step_taken = sums.next().unwrap_or_default();
                l.close();
            }
        }
    }

    /// The run's state on rank 0 (collective; `None` on the other ranks).
    pub fn gather(&self) -> Option<Gathered> {
        let me = self.comm.rank();
        let records: Vec<BodyRecord> = self
            .owned
            .iter()
            .map(|&i| BodyRecord {
                id: i as u64,
                motion: Motion::of(&self.world.bodies[i]),
                force: self.forces.force[i].to_array(),
                torque: self.forces.torque[i].to_array(),
            })
            .collect();
        let records = all_gather_v(self.comm, &records);
        let mut rows = Vec::new();
        if let Some(k) = self.friction {
            let values = self.effects[k].state().unwrap_or_default();
            let start = FrictionEffect::STATE_HEAD.min(values.len());
            for row in values[start..].chunks_exact(FrictionEffect::STATE_ROW) {
                let r = HistoryRow {
                    row: row.try_into().expect("rows of 8"),
                };
                let (a, b) = r.pair();
                if self.home(a, b) == me {
                    rows.push(r);
                }
            }
        }
        let mut rows = all_gather_v(self.comm, &rows);
        let mut index = 0;
        let mut contacts = Vec::new();
        for (k, c) in self.ctx.contacts.iter().enumerate() {
            let first = k == 0 || {
                let p = &self.ctx.contacts[k - 1];
                (p.a, p.b) != (c.a, c.b)
            };
            index = if first { 0 } else { index + 1 };
            if self.ctx.books_contact(k) {
                contacts.push(ContactRecord::new(c, index, self.ctx.contact_force[k]));
            }
        }
        let mut contacts = all_gather_v(self.comm, &contacts);
        if me != 0 {
            return None;
        }
        let n = self.world.bodies.len();
        let mut bodies: Vec<BodyState> = self.world.bodies.iter().map(BodyState::of).collect();
        let (mut force, mut torque) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
        for r in &records {
            let i = r.id as usize;
            bodies[i] = r.motion.state();
            force[i] = DVec3::from_array(r.force);
            torque[i] = DVec3::from_array(r.torque);
        }
        rows.sort_unstable_by_key(HistoryRow::key);
        let effects = self
            .effects
            .iter()
            .enumerate()
            .filter_map(|(k, e)| {
                let mut values = e.state()?;
                if Some(k) == self.friction {
                    values.truncate(FrictionEffect::STATE_HEAD);
                    rows.iter().for_each(|r| values.extend(r.row));
                }
                Some(EffectState {
                    effect: e.name().to_string(),
                    values,
                })
            })
            .collect();
        contacts.sort_unstable_by_key(ContactRecord::order);
        Some(Gathered {
            checkpoint: Checkpoint {
                time: self.world.time,
                step: self.world.step,
                dt: self.dt,
                fingerprint: self.world.fingerprint(),
                bodies,
                force,
                torque,
                effects,
            },
            contact_forces: contacts
                .iter()
                .map(|c| DVec3::from_array(c.force))
                .collect(),
            contacts: contacts.iter().map(ContactRecord::contact).collect(),
        })
    }
}
