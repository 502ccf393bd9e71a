//! The distributed step (the paper's Algorithm 1, with a neighbour list).
//!
//! **What a rank holds.** Its particles, ghosts of other ranks' particles
//! within contact reach of its own, and the obstacles within reach
//! ([`Local`]); the scene's shapes and materials (one per kind of particle
//! and per obstacle). Never the whole scene's bodies or triangles, at the
//! start neither: each rank loads the scene keeping only the particles
//! dealt to it (k-th particle to rank k mod P, `dem::scene::Deal`), and
//! what needs the whole scene reads its census; the partitioner then moves
//! the particles to their owners.
//!
//! **Who computes what.** The unit of the partition is the particle (a body
//! of a few dozen triangles), weighted by its triangle count: a body pair's
//! contacts are built from the features of both bodies and all their
//! triangle contacts together, so its triangles must meet on one rank. A
//! pair is computed once, on the rank owning its lower particle (the
//! particle, for a pair with an obstacle); the force terms it puts on a
//! ghost go back to the ghost's owner.
//!
//! **A step.**
//! 1. every K steps: partition, migrate particles with their last force
//!    and their contacts' history (through `dem::effects::ContactHistory`);
//! 2. owners: half kick, drift; one all-reduce of the travel, the stop
//!    flag and the failure flags;
//! 3. once some particle's centre may have moved [`GHOST_SKINS`] half
//!    skins since the ghost lists were drawn (or after a migration; turning
//!    moves no ghost box, a sphere about the centre): draw them anew, ghosts
//!    sent whole, the rank's world rebuilt, the broad phase run; once any
//!    point of a body may have moved half the skin since the neighbour list
//!    was drawn: the
//!    ghosts' motions exchanged first, the broad phase run on them;
//!    otherwise the neighbour list is kept and:
//! 4. the ghosts' motions are posted (non-blocking);
//! 5. detection among owned bodies and obstacles, testing the posted
//!    requests between pieces, so that the motions move meanwhile;
//! 6. wait; the ghosts' motions in; detection of owned bodies with ghosts;
//! 7. the effects' forces; terms on ghosts sent to their owners, which sum
//!    the terms of their bodies near a cut in one process's order
//!    (`forces`); owners: half kick.
//!
//! **Why the results do not depend on the rank count.** Ghosts are exact
//! copies of their owners' bits; a rank's bodies are in id order, so its
//! body pairs, contacts and force terms come in one process's order; each
//! body's force is summed in that order, term by term; the energy books are
//! exact sums (`dem::ledger`), merged only when they are read. The triangle
//! kernel's answer for a pair does not depend on the other pairs of its
//! batch (brute force; the hybrid recomputing only uncertified pairs, its
//! default), so a pair examined on any rank gives the same bits. (The
//! published kernel's whole-batch fallback recomputes a batch when one pair
//! failed: runs with it agree across rank counts to rounding, not to the bit.)

use crate::forces::{arrived, key, places_in_pairs, sum_logged};
use crate::ghosts::{self, exchange_motions, return_terms, Exchange, GhostLists, Mailboxes};
use crate::history;
use crate::local::{Entry, Local};
use crate::metrics::StepMetrics;
use crate::records::{BodyRecord, ContactRecord, Motion, StateRecord, TermKey, TermRecord};
use dem::body::Body;
use dem::checkpoint::{BodyState, Checkpoint, CheckpointError, CheckpointShare, EffectState};
use dem::contact::{Bounds, Contact, Detector, ListMotion, Role, Share};
use dem::distance::Options;
use dem::effects::{
    book_entries, insert_due, insertion_due, Agree, Candidate, ContactParams, Effect, ForceTerm,
    Forces, StepContext, StepStats,
};
use dem::frame::{EnergyBooks, Frame};
use dem::integrate::{centre_travel_bound, drift_many, half_kick, travel_bound};
use dem::ledger::ExactSum;
use dem::mesh::Features;
use dem::scene::{Deal, Scene};
use dem::simulation::{
    build_effects, check_share, energy_books, frame_contacts, shape_radii, split_out, take_out,
    NonFinite,
};
use glam::{DQuat, DVec3};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use partition::comm::{all_gather_v, all_to_all_v, gather_v};
use partition::{Aabb, Backend, Item, Partitioner};
use std::time::Instant;

/// Steps between the checks of `Settings::repartition_when` (each check
/// is two small all-reduces).
pub const CHECK_EVERY: u64 = 20;

/// The ghost lists' pad, in half skins: drawing them is collective and
/// rebuilds the rank's world, so they are drawn with a wider pad than the
/// neighbour list, which is redrawn alone in between from the ghosts'
/// current motions.
pub const GHOST_SKINS: f64 = 6.0;

/// The numbers of a step's one all-reduce (a maximum over the ranks): the
/// largest travel, the stop, non-finite, deep-contact and insertion flags,
/// the busy seconds of the step before, the largest centre travel, the
/// modelled work of the step before, and the terms of the neighbour list's
/// validity ([`ListMotion`]).
const FLAGS: usize = 8 + ListMotion::LEN;

/// What a step draws anew before its detection.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Redraw {
    /// Both lists hold.
    Keep,
    /// The neighbour list, from the ghosts' current motions.
    List,
    /// The ghost lists (the ghosts sent whole), then the neighbour list.
    Ghosts,
}

/// How a run is split.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Settings {
    pub partitioner: Backend,
    /// Repartition every this many steps (`None`: only at the start).
    pub repartition_every: Option<u64>,
    /// Repartition once the ranks' busy time over the last
    /// [`CHECK_EVERY`] steps is more imbalanced (max/mean) than this.
    pub repartition_when: Option<f64>,
    pub exchange: Exchange,
    /// The skin of the neighbour list, drawn anew once some body may have
    /// moved half of it, and of the ghost lists, drawn anew once some body
    /// may have moved `GHOST_SKINS` halves of it (0: both every step).
    pub skin: f64,
    /// What a particle weighs for the partitioner.
    pub weights: crate::Weights,
    /// Repartitionings build on the previous partition (see
    /// [`partition::Setup::reuse`]); off, each starts from scratch.
    pub reuse: bool,
}

/// Where a run starts: the scene's initial state, or a checkpoint of it.
pub enum Start<'a> {
    Fresh,
    Resume(&'a CheckpointShare),
}

/// A simulation stepped on every rank of a communicator.
pub struct DistributedSimulation<'c> {
    comm: &'c SimpleCommunicator,
    part: Box<dyn Partitioner + 'c>,
    settings: Settings,
    local: Local,
    /// Every obstacle of the scene (id, body, box with its halo): few, and
    /// each rank takes in those within its reach.
    obstacles: Vec<(u32, Body, Bounds)>,
    /// Bodies and particles in the whole scene.
    bodies: usize,
    particles: usize,
    fingerprint: u64,
    dt: f64,
    rotation: bool,
    effects: Vec<Box<dyn Effect>>,
    detects: bool,
    features: Vec<Features>,
    shape_radius: Vec<f64>,
    kernel: Options,
    detector: Detector,
    forces: Forces,
    ctx: StepContext,
    lists: GhostLists,
    mail: Mailboxes,
    /// Per body: whether its force terms are logged (ghosts, and owned
    /// bodies that are ghosts elsewhere).
    logged: Vec<bool>,
    /// The ranks force terms go to and come from, for the neighbour list's life.
    term_peers: (Vec<i32>, Vec<i32>),
    lists_stale: bool,
    /// How far any body may have moved since the neighbour list was drawn,
    /// and since the ghost lists were.
    travel: f64,
    ghost_travel: f64,
    /// The largest travel of the step before (every rank's).
    last_moved: f64,
    steps_run: u64,
    /// Steps in a row, up to the one before the last, in which some rank
    /// found a contact deeper than the halos.
    deep_steps: u64,
    metrics: StepMetrics,
    /// Counters summed over this rank's steps.
    pub totals: StepStats,
    found: [Vec<Contact>; 2],
    /// Steps and busy seconds since the last partitioning (for the weights).
    since_partition: (u64, f64),
    /// Busy seconds since the last imbalance check, and whether the last
    /// check asked for a repartitioning.
    since_check: f64,
    imbalance_due: bool,
}

fn fail<T>(why: impl Into<String>) -> Result<T, String> {
    Err(why.into())
}

impl<'c> DistributedSimulation<'c> {
    /// Splits `scene`, from its start or a checkpoint of it, across the
    /// ranks of `comm` (collective). A fresh run evaluates its initial
    /// forces, as one process does.
    ///
    /// `scene` is this rank's share of it (loaded with the [`Deal`] of
    /// this rank of `comm`); its bodies are taken out of it.
    pub fn new(
        comm: &'c SimpleCommunicator,
        scene: &mut Scene,
        start: Start,
        settings: Settings,
    ) -> Result<Self, String> {
        let (me, size) = (comm.rank(), comm.size());
        let share = Deal {
            rank: me as u32,
            ranks: size as u32,
        };
        if scene.deal != share {
            return fail(format!(
                "the scene was loaded for rank {} of {}, not {me} of {size}",
                scene.deal.rank, scene.deal.ranks
            ));
        }
        let census = &scene.census;
        let (bodies, particles) = (census.bodies(), census.particles());
        if let Start::Resume(c) = start {
            if c.deal != share {
                return fail(format!(
                    "the checkpoint was read for rank {} of {}, not {me} of {size}",
                    c.deal.rank, c.deal.ranks
                ));
            }
            check_share(scene, c).map_err(|e| e.to_string())?;
        }
        let fingerprint = scene.fingerprint();
        let materials = &scene.world.materials;
        let max_halo = census
            .runs()
            .iter()
            .map(|r| materials[r.material].halo.unwrap_or(0.0))
            .fold(0.0, f64::max);
        let (entries, obstacles) = dealt(scene, start_state(&start), me);
        scene.world.bodies = Vec::new();
        scene.world.ids = Vec::new();
        let mut effects = build_effects(scene);
        if let Start::Resume(c) = start {
            restore_share(&mut effects, c, me, bodies)?;
        }
        let part = settings
            .partitioner
            .create(
                comm,
                partition::Setup {
                    halo: max_halo,
                    reuse: settings.reuse,
                },
            )
            .map_err(|e| e.to_string())?;
        let world = &scene.world;
        let mut local = Local::new(world.shapes.clone(), world.materials.clone());
        let loads = local.merge(vec![entries])?;
        let mut s = DistributedSimulation {
            comm,
            part,
            settings,
            bodies,
            particles,
            fingerprint,
            dt: scene.dt,
            rotation: scene.effects.rotate(),
            detects: effects.iter().any(|e| e.detects_contacts()),
            effects,
            features: world.shapes.iter().map(Features::of).collect(),
            shape_radius: shape_radii(world),
            kernel: scene.kernel,
            detector: {
                let culling = scene.effects.get::<ContactParams>().map(|c| c.culling);
                let mut d =
                    Detector::with_skin(settings.skin).with_culling(culling.unwrap_or_default());
                d.count_work();
                d
            },
            forces: Forces::default(),
            ctx: StepContext {
                dt: scene.dt,
                ..StepContext::default()
            },
            lists: GhostLists::default(),
            mail: Mailboxes::default(),
            logged: Vec::new(),
            term_peers: Default::default(),
            lists_stale: true,
            travel: 0.0,
            ghost_travel: 0.0,
            last_moved: 0.0,
            steps_run: 0,
            deep_steps: 0,
            metrics: StepMetrics::default(),
            totals: StepStats::default(),
            found: Default::default(),
            since_partition: (0, 0.0),
            since_check: 0.0,
            imbalance_due: false,
            obstacles,
            local,
        };
        s.set_loads(&loads);
        s.local.world.time = start_time(&start).0;
        s.local.world.step = start_time(&start).1;
        // Moving walls stand where their drives put them at the start's time.
        let t = s.local.world.time;
        s.obstacles.iter_mut().for_each(|o| o.1.follow_drive(t));
        s.repartition()?;
        if let Start::Fresh = start {
            s.evaluate(Redraw::Ghosts, false)?;
        }
        Ok(s)
    }

    /// An invariant of the split broke on this rank (a bug, not bad input):
    /// the other ranks would wait for this one forever, so every rank ends
    /// here.
    fn broken(&self, why: &str) -> ! {
        eprintln!("tridem: internal error on rank {}: {why}", self.comm.rank());
        self.comm.abort(70)
    }

    /// Keeps the bodies `keep` marks in place and merges in `streams` (each
    /// in increasing id, with the forces they carry); the kept keep their
    /// forces when `carry_forces`, else zero.
    fn admit(&mut self, keep: &[bool], carry_forces: bool, streams: Vec<Vec<Entry>>) {
        let (force, torque) = match carry_forces {
            true => self.forces.all(),
            false => (&[][..], &[][..]),
        };
        match self.local.admit(|i| keep[i], (force, torque), streams) {
            Ok(loads) => self.set_loads(&loads),
            Err(why) => self.broken(&why),
        }
    }

    /// The forces of this rank's bodies, as `loads` (by index) say.
    fn set_loads(&mut self, loads: &[(DVec3, DVec3)]) {
        self.forces.reset(loads.len());
        for (i, &(f, t)) in loads.iter().enumerate() {
            self.forces.set(i, f, t);
        }
        let owned = self.local.owned.clone();
        split_out(&self.local.world, owned, &mut self.ctx);
    }

    /// Time and step of the run.
    pub fn time(&self) -> f64 {
        self.local.world.time
    }

    pub fn step_number(&self) -> u64 {
        self.local.world.step
    }

    /// Particles in the whole scene.
    pub fn particles(&self) -> usize {
        self.particles
    }

    /// The ids of the particles this rank owns, in increasing order.
    pub fn owned(&self) -> Vec<u32> {
        let l = &self.local;
        l.owned.iter().map(|&i| l.world.id(i)).collect()
    }

    /// This rank's world: its own particles, ghosts and obstacles within reach.
    pub fn local(&self) -> &Local {
        &self.local
    }

    /// Steps in a row, up to the one before the last, in which some rank
    /// found a contact deeper than the halos (the same on every rank).
    pub fn deep_steps_in_a_row(&self) -> u64 {
        self.deep_steps
    }

    /// What this rank measured in the last step.
    pub fn metrics(&self) -> &StepMetrics {
        &self.metrics
    }

    pub fn rank(&self) -> i32 {
        self.comm.rank()
    }

    /// One velocity-Verlet step on every rank (collective). `stop`: this
    /// rank was asked to stop (a signal); returns whether any rank was, so
    /// that all stop after the same step.
    pub fn step(&mut self, stop: bool) -> Result<bool, String> {
        let step_start = Instant::now();
        let previous_busy = self.metrics.busy_seconds;
        let previous_work = self.metrics.modelled_work_ns;
        // The first step carries what the start's partitioning cost.
        let carried = if self.steps_run == 0 {
            self.metrics
        } else {
            StepMetrics::default()
        };
        self.metrics = StepMetrics {
            step: self.local.world.step + 1,
            ..carried
        };
        self.steps_run += 1;
        let due = self
            .settings
            .repartition_every
            .is_some_and(|k| k > 0 && self.steps_run > 1 && (self.steps_run - 1).is_multiple_of(k));
        if due || std::mem::take(&mut self.imbalance_due) {
            self.repartition()?;
        }
        let start = Instant::now();
        let (moved, shifted, finite) = self.kick_and_drift();
        let motion = self.list_motion();
        self.metrics.integration_seconds += start.elapsed().as_secs_f64();
        let start = Instant::now();
        let h = self.dt;
        let end = (self.local.world.time + h, self.local.world.step + 1);
        let due = insertion_due(&self.local.world, &self.ctx, &self.effects, end.0, end.1);
        let head = [
            moved,
            f64::from(u8::from(stop)),
            f64::from(u8::from(!finite)),
            f64::from(u8::from(self.ctx.stats.detection.deep_contacts > 0)),
            f64::from(u8::from(due)),
            previous_busy,
            shifted,
            previous_work as f64,
        ];
        let mut flags = [0.0; FLAGS];
        flags[..head.len()].copy_from_slice(&head);
        flags[head.len()..].copy_from_slice(&motion.0);
        let mut global = [0.0; FLAGS];
        self.comm
            .all_reduce_into(&flags[..], &mut global[..], SystemOperation::max());
        let motion = ListMotion(std::array::from_fn(|k| global[FLAGS - ListMotion::LEN + k]));
        self.metrics.reduce_seconds += start.elapsed().as_secs_f64();
        self.metrics.counted_busy_seconds = previous_busy;
        self.metrics.slowest_busy_seconds = global[5];
        self.metrics.counted_work_ns = previous_work;
        self.metrics.most_work_ns = global[7] as u64;
        if global[2] > 0.0 {
            let at = NonFinite {
                step: self.local.world.step + 1,
                time: self.local.world.time + h,
            };
            return fail(at.to_string());
        }
        self.deep_steps = if global[3] > 0.0 {
            self.deep_steps + 1
        } else {
            0
        };
        if global[4] > 0.0 {
            let start = Instant::now();
            let mut share = RankShare(self.comm);
            let (world, ctx) = (&mut self.local.world, &mut self.ctx);
            if insert_due(world, ctx, &mut self.effects, end, &mut share) > 0 {
                // Every rank made the same choices: all redraw together.
                self.lists_stale = true;
            }
            self.metrics.reduce_seconds += start.elapsed().as_secs_f64();
        }
        // NaN travel (a body's state gone bad) redraws too.
        self.travel += global[0];
        self.last_moved = global[0];
        self.ghost_travel += global[6];
        let within = |travel: f64, pad: f64| travel <= pad;
        let redraw = if self.lists_stale || !within(self.ghost_travel, self.ghost_pad()) {
            Redraw::Ghosts
        } else if !within(self.travel, 0.5 * self.settings.skin)
            && !motion.keeps(self.settings.skin)
        {
            Redraw::List
        } else {
            Redraw::Keep
        };
        self.evaluate(redraw, true)?;
        let start = Instant::now();
        book_entries(&self.local.world, &mut self.effects);
        take_out(&mut self.local.world, &mut self.ctx, &self.effects);
        self.metrics.integration_seconds += start.elapsed().as_secs_f64();
        self.local.world.time += h;
        self.local.world.step += 1;
        self.totals += self.ctx.stats;
        // Bodies out of the run (waiting, or taken out) cost nothing per step.
        let (owned, bodies) = (&self.local.owned, &self.local.world.bodies);
        let present = owned.iter().filter(|&&i| !bodies[i].is_out()).count() as u64;
        let m = &mut self.metrics;
        m.owned_bodies = self.local.owned.len() as u64;
        m.owned_triangles = self.local.owned_triangles();
        m.local_bodies = self.local.world.bodies.len() as u64;
        m.local_triangles = self.local.triangles();
        m.neighbours = self.lists.send.len().max(self.lists.recv.len()) as u64;
        m.present_bodies = present;
        m.modelled_work_ns =
            crate::weights::rank_cost(present, m.body_pairs, m.triangle_pairs).round() as u64;
        // The first step also carries the start's sections (see above).
        m.step_seconds = step_start.elapsed().as_secs_f64() + carried.sections();
        m.busy_seconds =
            (m.step_seconds - m.reduce_seconds - m.wait_seconds - m.return_wait_seconds).max(0.0);
        self.since_partition.0 += 1;
        self.since_partition.1 += m.busy_seconds;
        self.since_check += m.busy_seconds;
        if let Some(tau) = self.settings.repartition_when {
            if self.steps_run.is_multiple_of(CHECK_EVERY) {
                let busy = std::mem::take(&mut self.since_check);
                self.imbalance_due = self.imbalance_over(busy) > tau;
            }
        }
        Ok(global[1] > 0.0)
    }

    /// The max/mean over ranks of `busy` (collective).
    fn imbalance_over(&self, busy: f64) -> f64 {
        let (mut max, mut sum) = (0.0, 0.0);
        self.comm
            .all_reduce_into(&busy, &mut max, SystemOperation::max());
        self.comm
            .all_reduce_into(&busy, &mut sum, SystemOperation::sum());
        let mean = sum / f64::from(self.comm.size());
        if mean > 0.0 {
            max / mean
        } else {
            1.0
        }
    }

    /// Owners: half kick and drift; every rank: the moving walls to their
    /// place at the step's end. Returns the farthest any point of an owned
    /// body or a moving wall moved (what the neighbour list's skin bounds),
    /// the farthest an owned particle's centre moved (what the ghost lists'
    /// pad bounds: their boxes are spheres about the centres, which turning
    /// does not move), and whether every owned body's state is finite
    /// (checked here, where the drift touches it last).
    fn kick_and_drift(&mut self) -> (f64, f64, bool) {
        let (h, rot) = (self.dt, self.rotation);
        let (force, torque) = self.forces.all();
        let (mut moved, mut shifted): (f64, f64) = (0.0, 0.0);
        let mut finite = true;
        let (ids, bodies) = (&self.ctx.bodies, &mut self.local.world.bodies);
        for &i in ids {
            half_kick(&mut bodies[i], force[i], torque[i], h, rot);
        }
        let before: Vec<(DVec3, DQuat)> = ids.iter().map(|&i| (bodies[i].x, bodies[i].q)).collect();
        drift_many(bodies, ids, h, rot);
        for (&i, before) in ids.iter().zip(before) {
            let b = &bodies[i];
            let radius = self.shape_radius[b.shape];
            moved = moved.max(travel_bound(before, b, radius));
            shifted = shifted.max(centre_travel_bound(before.0, b, radius));
            finite &= b.is_finite();
        }
        let t_next = self.local.world.time + h;
        for (id, body, _) in self.obstacles.iter_mut().filter(|o| o.1.drive.is_some()) {
            let before = (body.x, body.q);
            body.follow_drive(t_next);
            moved = moved.max(travel_bound(before, body, self.shape_radius[body.shape]));
            if let Some(i) = self.local.index_of(*id) {
                self.local.world.bodies[i].follow_drive(t_next);
            }
        }
        (moved, shifted, finite)
    }

    /// This rank's share of how the bodies moved since the neighbour list
    /// was drawn: its particles and the driven obstacles it holds (every
    /// rank holds the fixed ones it pairs with). Unknown once its world has
    /// been laid out anew (a migration), which draws the lists anew anyway.
    ///
    /// Measured only once the list may be about to outlive half the skin:
    /// while the travel so far and twice the step before's are within it
    /// (every rank decides alike, on the all-reduce's numbers), the step's
    /// own travel almost surely keeps the list without it. Should the
    /// step travel farther, the unknown motion redraws the list: never a
    /// wrong list, at worst one redrawn early.
    fn list_motion(&self) -> ListMotion {
        let soon = self.travel + 2.0 * self.last_moved > 0.5 * self.settings.skin;
        if self.lists_stale || !soon {
            return ListMotion::UNKNOWN;
        }
        let (world, ctx) = (&self.local.world, &self.ctx);
        let held = |o: &(u32, Body, Bounds)| o.1.drive.as_ref().and(self.local.index_of(o.0));
        let driven = self.obstacles.iter().filter_map(held);
        let ids = ctx.bodies.iter().copied().chain(driven);
        self.detector.list_motion(world, ids)
    }

    /// How far a body may move before the ghost lists are drawn anew: the
    /// pad of the boxes they are drawn with.
    fn ghost_pad(&self) -> f64 {
        GHOST_SKINS * 0.5 * self.settings.skin
    }

    /// Contacts and forces of the current state, with the lists `redraw`
    /// names drawn anew first; with `kick`, the owners' closing half kick.
    fn evaluate(&mut self, redraw: Redraw, kick: bool) -> Result<(), String> {
        match redraw {
            Redraw::Ghosts => {
                let start = Instant::now();
                self.redraw();
                self.metrics.lists_seconds += start.elapsed().as_secs_f64();
            }
            Redraw::List => self.travel = 0.0,
            Redraw::Keep => {}
        }
        self.ctx.contacts.clear();
        self.ctx.stats = StepStats::default();
        if self.detects {
            self.detect(redraw);
        }
        let start = Instant::now();
        let n = self.local.world.bodies.len();
        self.forces.reset(n);
        self.forces.log_bodies(&self.logged);
        self.ctx.contacts_found = true;
        for (k, e) in self.effects.iter_mut().enumerate() {
            self.forces.begin_effect(k);
            e.apply(&self.local.world, &mut self.ctx, &mut self.forces);
        }
        self.metrics.contacts = self.ctx.contacts.len() as u64;
        self.metrics.force_seconds += start.elapsed().as_secs_f64();
        let start = Instant::now();
        self.return_forces(kick);
        self.metrics.force_return_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// The ghosts' motions, exchanged before anything else: a neighbour list
    /// drawn anew reads where the ghosts are now.
    fn receive_motions(&mut self) {
        let start = Instant::now();
        let none = |_: &mut dyn FnMut() -> bool| ();
        let lists = &self.lists;
        let received = exchange_motions(
            self.comm,
            lists,
            &self.local.world,
            &mut self.mail,
            Exchange::Blocking,
            none,
        );
        put_motions(&mut self.local.world, &lists.recv, self.mail.received());
        self.metrics.wait_seconds += received.wait;
        self.metrics.post_seconds += (start.elapsed().as_secs_f64() - received.wait).max(0.0);
    }

    /// Finds this rank's contacts into `ctx.contacts` (see the module doc).
    fn detect(&mut self, redraw: Redraw) {
        if redraw == Redraw::List {
            self.receive_motions();
        }
        let keep = redraw == Redraw::Keep;
        let start = Instant::now();
        let local = &self.local;
        let mut stats = self
            .detector
            .prepare(&local.world, &local.halos, &local.roles, keep);
        if !keep {
            self.metrics.neighbour_lists_drawn = 1;
            let ours = self.detector.share(Share::Ghost);
            self.term_peers = ghosts::term_peers(ours, self.detector.theirs(), &local.owner);
        }
        let [mut near, mut far] = std::mem::take(&mut self.found);
        near.clear();
        far.clear();
        let (detector, features, kernel) = (&mut self.detector, &self.features, &self.kernel);
        // Just drawn, the lists brought the ghosts whole; with the neighbour
        // list just drawn, their motions came before: nothing to exchange.
        let mode = self.settings.exchange;
        let none = GhostLists::default();
        let lists = if keep { &self.lists } else { &none };
        let work_start = Instant::now();
        let mail = &mut self.mail;
        let received = exchange_motions(self.comm, lists, &local.world, mail, mode, |progress| {
            let t = Instant::now();
            let s = detector.detect_share(
                &local.world,
                features,
                &local.halos,
                kernel,
                Share::Local,
                Some(progress),
                &mut near,
            );
            (s, t.elapsed().as_secs_f64())
        });
        let (local_stats, local_secs) = received.work;
        stats += local_stats;
        let m = &mut self.metrics;
        m.wait_seconds += received.wait;
        m.local_detection_seconds += local_secs + (work_start - start).as_secs_f64();
        // Packing and posting, and the exchange's own bookkeeping: what it
        // spent outside the work and the wait.
        let around = work_start.elapsed().as_secs_f64() - local_secs - received.wait;
        m.post_seconds += around.max(0.0);
        let start = Instant::now();
        put_motions(&mut self.local.world, &lists.recv, self.mail.received());
        let (sent, got) = (self.lists.sent() as u64, self.lists.received() as u64);
        let bytes = std::mem::size_of::<Motion>() as u64;
        m.ghosts_sent = sent;
        m.ghosts_received = got;
        m.ghost_bytes_sent = sent * bytes;
        m.ghost_bytes_received = got * bytes;
        let local = &self.local;
        stats += self.detector.detect_share(
            &local.world,
            &self.features,
            &local.halos,
            &self.kernel,
            Share::Ghost,
            None,
            &mut far,
        );
        merge_by_pair(&near, &far, &mut self.ctx.contacts);
        // What each particle's contacts cost here: its rank pays for the
        // pairs it is the home particle of.
        for (i, w) in self.detector.take_work().into_iter().enumerate() {
            if self.local.roles[i] == Role::Own {
                self.local.work[i][0] += w[0] as f64;
                self.local.work[i][1] += w[1] as f64;
            }
        }
        self.found = [near, far];
        self.ctx.stats.detection = stats;
        self.metrics.body_pairs = stats.body_pairs;
        self.metrics.triangle_pairs = stats.triangle_pairs;
        self.metrics.ghost_detection_seconds += start.elapsed().as_secs_f64();
    }

    /// Sends the terms on ghosts to their owners and sums the terms of this
    /// rank's logged bodies in one process's order; with `kick`, the closing
    /// half kick, of the bodies whose force is known first while the terms
    /// travel.
    fn return_forces(&mut self, kick: bool) {
        let log = self.forces.log();
        let places = places_in_pairs(&self.ctx.contacts);
        let world = &self.local.world;
        let (to, from) = &self.term_peers;
        let mut outgoing: Vec<(i32, Vec<TermRecord>)> =
            to.iter().map(|&r| (r, Vec::new())).collect();
        let mut mine: Vec<(usize, TermKey, ForceTerm)> = Vec::with_capacity(log.len());
        for &t in log {
            let i = t.body as usize;
            let k = key(&t, world, &self.ctx.contacts, &places);
            match self.local.roles[i] {
                Role::Ghost => {
                    let owner = self.local.owner[i];
                    match to.binary_search(&owner) {
                        Ok(slot) => outgoing[slot].1.push(TermRecord::new(world.id(i), k, &t)),
                        Err(_) => self.broken(&format!(
                            "a force term on body {}, whose owner {owner} pairs with none here",
                            world.id(i)
                        )),
                    }
                }
                Role::Own => mine.push((i, k, t)),
                Role::Obstacle => {}
            }
        }
        let sent: u64 = outgoing.iter().map(|o| o.1.len() as u64).sum();
        self.metrics.terms_sent = sent;
        self.metrics.term_bytes_sent = sent * std::mem::size_of::<TermRecord>() as u64;
        let (h, rot) = (self.dt, self.rotation);
        let (local, forces, logged) = (&mut self.local, &mut self.forces, &self.logged);
        let kick_where = |local: &mut Local, forces: &Forces, want: bool| {
            let (force, torque) = forces.all();
            for &i in &local.owned {
                if logged[i] == want && !local.world.bodies[i].is_out() {
                    half_kick(&mut local.world.bodies[i], force[i], torque[i], h, rot);
                }
            }
        };
        let (received, wait) = return_terms(self.comm, &outgoing, from, || {
            if kick {
                kick_where(local, forces, false);
            }
        });
        self.metrics.return_wait_seconds += wait;
        let owned_index = |id: u32| local.index_of(id).filter(|&i| local.roles[i] == Role::Own);
        match received.and_then(|r| arrived(&r, owned_index)) {
            Ok(terms) => mine.extend(terms),
            Err(why) => {
                eprintln!("tridem: internal error on rank {}: {why}", self.comm.rank());
                self.comm.abort(70)
            }
        }
        sum_logged(forces, mine);
        if kick {
            kick_where(local, forces, true);
        }
    }

    /// Draws the ghost lists anew and rebuilds this rank's world: its
    /// particles, the ghosts that arrived, the obstacles within its reach
    /// (collective).
    fn redraw(&mut self) {
        let pad = self.ghost_pad();
        let l = &self.local;
        // Particles out of the run touch nothing: they neither reach nor go
        // as ghosts (an insertion redraws the lists at once).
        let present: Vec<usize> = (l.owned.iter().copied())
            .filter(|&i| !l.world.bodies[i].is_out())
            .collect();
        let drawn = ghosts::draw(
            self.comm,
            &l.world,
            &self.shape_radius,
            &l.halos,
            &present,
            pad,
        );
        // Streams in increasing id: each neighbour's ghosts, the obstacles
        // within reach; the own bodies stay where they are.
        let mut streams = Vec::with_capacity(drawn.arrived.len() + 1);
        for (r, records) in &drawn.arrived {
            streams.push(
                records
                    .iter()
                    .map(|rec| Entry {
                        id: rec.id as u32,
                        body: rec.body(),
                        role: Role::Ghost,
                        owner: *r,
                        force: DVec3::ZERO,
                        torque: DVec3::ZERO,
                        work: [0.0; 2],
                    })
                    .collect(),
            );
        }
        // Moving walls are few and go where they please: every rank keeps them.
        let near = |b: &Bounds| drawn.reach.overlaps(b);
        streams.push(
            self.obstacles
                .iter()
                .filter(|o| o.1.drive.is_some() || near(&o.2))
                .map(|(id, body, _)| Entry {
                    id: *id,
                    body: body.clone(),
                    role: Role::Obstacle,
                    owner: -1,
                    force: DVec3::ZERO,
                    torque: DVec3::ZERO,
                    work: [0.0; 2],
                })
                .collect(),
        );
        let own: Vec<bool> = self.local.roles.iter().map(|&r| r == Role::Own).collect();
        self.admit(&own, false, streams);
        let local = &self.local;
        let index = |id: u32| local.index_of(id).expect("a body just taken in");
        let send = drawn
            .send
            .iter()
            .map(|(r, ids)| (*r, ids.iter().map(|&id| index(id)).collect()))
            .collect();
        let recv = drawn
            .arrived
            .iter()
            .map(|(r, recs)| (*r, recs.iter().map(|rec| index(rec.id as u32)).collect()))
            .collect();
        self.lists = GhostLists { send, recv };
        self.logged = local.roles.iter().map(|&r| r == Role::Ghost).collect();
        for (_, ids) in &self.lists.send {
            ids.iter().for_each(|&i| self.logged[i] = true);
        }
        self.travel = 0.0;
        self.ghost_travel = 0.0;
        self.lists_stale = false;
        self.metrics.lists_drawn = 1;
    }

    /// Load balancing and migration (collective; see the module doc).
    fn repartition(&mut self) -> Result<(), String> {
        let start = Instant::now();
        let me = self.comm.rank();
        let l = &self.local;
        let pad = 0.5 * self.settings.skin;
        let w = &l.world;
        let triangles: Vec<f64> = l
            .owned
            .iter()
            .map(|&i| w.shapes[w.bodies[i].shape].triangles.len() as f64)
            .collect();
        let work: Vec<[f64; 2]> = l.owned.iter().map(|&i| l.work[i]).collect();
        let (steps, busy) = self.since_partition;
        let weights = crate::weights::of(self.settings.weights, &triangles, &work, steps, busy);
        let out: Vec<bool> = l.owned.iter().map(|&i| w.bodies[i].is_out()).collect();
        let weights = crate::weights::held(weights, &out);
        let items: Vec<Item> = l
            .owned
            .iter()
            .zip(&weights)
            .map(|(&i, &weight)| {
                let b = ghosts::body_box(w, &self.shape_radius, i, l.halos[i] + pad);
                Item {
                    id: u64::from(w.id(i)),
                    point: w.bodies[i].x.to_array(),
                    weight,
                    bbox: Aabb::new(b.lo.to_array(), b.hi.to_array()),
                    payload_bytes: std::mem::size_of::<BodyRecord>() as u32,
                }
            })
            .collect();
        self.since_partition = (0, 0.0);
        // The partitioning at the start (or at a resume) has no regions
        // before it for a body to leave.
        if self.steps_run > 0 {
            let left = |it: &&Item| self.part.owner(it.point).is_ok_and(|r| r != me);
            self.metrics.drifted_bodies += items.iter().filter(left).count() as u64;
        }
        let placed = self.part.partition(self.comm, &items);
        // Every rank learns whether any failed before any returns.
        let ok = i32::from(placed.is_ok());
        let mut all_ok = 0;
        self.comm
            .all_reduce_into(&ok, &mut all_ok, SystemOperation::min());
        let new_owner = match placed {
            Ok(o) if all_ok == 1 => o,
            Ok(_) => return fail("partitioning failed on another rank"),
            Err(e) => return fail(format!("partitioning: {e}")),
        };
        self.metrics.partition_seconds += start.elapsed().as_secs_f64();
        let start = Instant::now();
        let size = self.comm.size() as usize;
        let mut outbox: Vec<Vec<BodyRecord>> = vec![Vec::new(); size];
        let owner_of: Vec<(u32, i32)> = l
            .owned
            .iter()
            .zip(&new_owner)
            .map(|(&i, &r)| (l.world.id(i), r))
            .collect();
        let (force, torque) = self.forces.all();
        let mut stays = vec![false; l.world.bodies.len()];
        for (&i, &r) in l.owned.iter().zip(&new_owner) {
            if r == me {
                stays[i] = true;
            } else {
                let rec = BodyRecord::of(l.world.id(i), &l.world.bodies[i], force[i], torque[i]);
                outbox[r as usize].push(rec);
            }
        }
        let sent: usize = outbox.iter().map(Vec::len).sum();
        self.metrics.migrated_bodies += sent as u64;
        self.metrics.migrated_bytes += (sent * std::mem::size_of::<BodyRecord>()) as u64;
        let counts: Vec<Count> = outbox.iter().map(|v| v.len() as Count).collect();
        let flat: Vec<BodyRecord> = outbox.into_iter().flatten().collect();
        let (arrived, arrived_counts) = all_to_all_v(self.comm, &flat, &counts);
        // Each sender's bodies in increasing id: one stream per sender.
        let mut streams = Vec::with_capacity(size + 1);
        let mut rest = &arrived[..];
        for &c in &arrived_counts {
            let (head, tail) = rest.split_at(c as usize);
            rest = tail;
            streams.push(
                head.iter()
                    .map(|r| Entry {
                        id: r.id as u32,
                        body: r.body(),
                        role: Role::Own,
                        owner: me,
                        force: DVec3::from_array(r.force),
                        torque: DVec3::from_array(r.torque),
                        work: [0.0; 2],
                    })
                    .collect::<Vec<_>>(),
            );
        }
        let kept = stays.iter().filter(|&&k| k).count();
        let owned = (kept + arrived.len()) as u64;
        let mut all = 0u64;
        self.comm
            .all_reduce_into(&owned, &mut all, SystemOperation::sum());
        if all != self.particles as u64 {
            return fail(format!(
                "after migration the ranks own {all} particles of {}",
                self.particles
            ));
        }
        if let Err(why) = self.migrate_history(&owner_of) {
            self.broken(&why);
        }
        self.admit(&stays, true, streams);
        self.local.work.iter_mut().for_each(|w| *w = [0.0; 2]);
        self.lists = GhostLists::default();
        self.logged = vec![false; self.local.world.bodies.len()];
        self.lists_stale = true;
        self.metrics.migration_seconds += start.elapsed().as_secs_f64();
        Ok(())
    }

    /// Moves each contact's history to the new owner of its home particle
    /// (`owner_of`: this rank's particles and their new owners, by id).
    fn migrate_history(&mut self, owner_of: &[(u32, i32)]) -> Result<(), String> {
        let me = self.comm.rank();
        let size = self.comm.size() as usize;
        let obstacles = &self.obstacles;
        let is_obstacle = |id: u32| obstacles.binary_search_by_key(&id, |o| o.0).is_ok();
        let new_owner = |id: u32| {
            owner_of
                .binary_search_by_key(&id, |o| o.0)
                .ok()
                .map(|k| owner_of[k].1)
        };
        for e in self.effects.iter_mut() {
            let Some(history) = e.history_mut() else {
                continue;
            };
            let outbox = history::leaving(history, me, size, is_obstacle, new_owner)?;
            let counts: Vec<Count> = outbox.iter().map(|v| v.len() as Count).collect();
            let flat: Vec<f64> = outbox.into_iter().flatten().collect();
            let (arrived, _) = all_to_all_v(self.comm, &flat, &counts);
            history.add_rows(&arrived, self.bodies)?;
        }
        Ok(())
    }

    /// The run's state on rank 0, as a checkpoint (collective; `None` on
    /// the other ranks).
    fn checkpoint(&self) -> Option<Checkpoint> {
        let l = &self.local;
        let (force, torque) = self.forces.all();
        let states: Vec<StateRecord> = l
            .owned
            .iter()
            .map(|&i| StateRecord {
                id: u64::from(l.world.id(i)),
                motion: Motion::of(&l.world.bodies[i]),
                force: force[i].to_array(),
                torque: torque[i].to_array(),
            })
            .collect();
        let states = gather_v(self.comm, 0, &states);
        let effects = self.gather_effect_states();
        let states = states?;
        let n = self.bodies;
        let mut bodies = vec![None; n];
        let (mut force, mut torque) = (vec![DVec3::ZERO; n], vec![DVec3::ZERO; n]);
        for (id, body, _) in &self.obstacles {
            bodies[*id as usize] = Some(BodyState::of(body));
        }
        for r in &states {
            let i = r.id as usize;
            bodies[i] = Some(r.motion.state());
            force[i] = DVec3::from_array(r.force);
            torque[i] = DVec3::from_array(r.torque);
        }
        Some(Checkpoint {
            time: l.world.time,
            step: l.world.step,
            dt: self.dt,
            fingerprint: self.fingerprint,
            bodies: bodies
                .into_iter()
                .map(|b| b.expect("every body gathered"))
                .collect(),
            force,
            torque,
            effects: effects?,
        })
    }

    /// Every effect's books and history, merged on rank 0 (collective).
    fn gather_effect_states(&self) -> Option<Vec<EffectState>> {
        let mut out = Some(Vec::new());
        for e in self.effects.iter() {
            if e.ledger().is_none() && e.history().is_none() {
                continue;
            }
            let (stored, taken) = match e.ledger() {
                Some(l) => {
                    let (s, t) = (l.stored().parts(), l.taken().parts());
                    let s = merge_sums(self.comm, &s);
                    let t = merge_sums(self.comm, &t);
                    (
                        s.map(|s| s.canonical_parts()),
                        t.map(|t| t.canonical_parts()),
                    )
                }
                None => (Some(Vec::new()), Some(Vec::new())),
            };
            let row = e.history().map_or(0, |h| h.row_len());
            let rows = e.history().map(|h| h.rows()).unwrap_or_default();
            let rows = gather_v(self.comm, 0, &rows).map(|r| history::sorted_rows(r, row));
            if let (Some(v), Some(stored), Some(taken), Some(history)) =
                (out.as_mut(), stored, taken, rows)
            {
                v.push(EffectState {
                    effect: e.name().to_string(),
                    stored,
                    taken,
                    row,
                    history,
                });
            } else {
                out = None;
            }
        }
        out
    }

    /// The run's state on rank 0 (collective; `None` on the other ranks):
    /// a checkpoint, and with `frame`, what the output step it shows adds.
    pub fn gather(&self, frame: bool) -> Option<Gathered> {
        let shown = frame.then(|| self.gather_frame_parts());
        let checkpoint = self.checkpoint()?;
        let shown = match shown {
            Some(parts) => Some(parts?),
            None => None,
        };
        Some(Gathered { checkpoint, shown })
    }

    /// The contacts and energy books of every rank, on rank 0 (collective).
    fn gather_frame_parts(&self) -> Option<FrameParts> {
        let l = &self.local;
        let contacts: Vec<ContactRecord> = frame_contacts(&l.world, &self.ctx)
            .iter()
            .zip(places_in_pairs(&self.ctx.contacts))
            .map(|(c, place)| ContactRecord::new(c, place as usize))
            .collect();
        let contacts = gather_v(self.comm, 0, &contacts);
        let books = self.gather_books();
        let (mut contacts, books) = (contacts?, books?);
        contacts.sort_unstable_by_key(ContactRecord::order);
        Some(FrameParts { contacts, books })
    }

    /// The effects' measures (a probe's count and mass, what an outflow
    /// took out, what an insertion brought in), summed over the ranks in
    /// rank order, on rank 0 (collective).
    pub fn measures(&self) -> Option<Vec<(String, f64)>> {
        Some(self.gather_books()?.rounded().measures)
    }

    /// The energy books and measures of every rank, merged on rank 0
    /// (collective).
    fn gather_books(&self) -> Option<EnergyBooks> {
        let books = energy_books(&self.local.world, &self.ctx, &self.effects);
        let numbers = books.numbers();
        let parts = gather_v(self.comm, 0, &numbers);
        let counts = gather_v(self.comm, 0, &[numbers.len() as u64]);
        let (parts, counts) = (parts?, counts?);
        let mut merged = EnergyBooks {
            effects: books
                .effects
                .iter()
                .map(|(n, _)| (*n, Default::default()))
                .collect(),
            measures: books
                .measures
                .iter()
                .map(|(n, _)| (n.clone(), Default::default()))
                .collect(),
            ..EnergyBooks::default()
        };
        let mut at = 0;
        for &n in &counts {
            merged.merge(&books.from_numbers(&parts[at..at + n as usize]));
            at += n as usize;
        }
        Some(merged)
    }

    /// Body pairs whose surfaces cross in the last evaluation (a contact
    /// deeper than the two halos), each with its deepest crossing, by id, in
    /// pair order; on rank 0 (collective).
    pub fn crossed_pairs(&self) -> Option<Vec<(u32, u32, f64)>> {
        let l = &self.local;
        let mut mine: Vec<[f64; 3]> = Vec::new();
        for c in &self.ctx.contacts {
            let over = c.depth - (l.halos[c.a] + l.halos[c.b]);
            if over <= 0.0 {
                continue;
            }
            let (a, b) = (f64::from(l.world.id(c.a)), f64::from(l.world.id(c.b)));
            match mine.last_mut() {
                Some(last) if (last[0], last[1]) == (a, b) => last[2] = last[2].max(over),
                _ => mine.push([a, b, over]),
            }
        }
        let flat: Vec<f64> = mine.into_iter().flatten().collect();
        let all = gather_v(self.comm, 0, &flat)?;
        let mut out: Vec<(u32, u32, f64)> = all
            .chunks_exact(3)
            .map(|c| (c[0] as u32, c[1] as u32, c[2]))
            .collect();
        out.sort_by_key(|p| (p.0, p.1));
        Some(out)
    }

    /// Pairs (inner, outer) of bodies of which the first lies wholly inside
    /// the second, by id, on rank 0 (collective): each rank looks among its
    /// particles and what is within their reach.
    pub fn enclosed_pairs(&self) -> Option<Vec<(u32, u32)>> {
        let l = &self.local;
        let mine: Vec<u64> = l
            .world
            .enclosed_pairs()
            .into_iter()
            .filter(|&(x, y)| l.roles[x] == Role::Own || l.roles[y] == Role::Own)
            .flat_map(|(x, y)| [u64::from(l.world.id(x)), u64::from(l.world.id(y))])
            .collect();
        let all = gather_v(self.comm, 0, &mine)?;
        let mut out: Vec<(u32, u32)> = all
            .chunks_exact(2)
            .map(|c| (c[0] as u32, c[1] as u32))
            .collect();
        out.sort_unstable();
        out.dedup();
        Some(out)
    }
}

/// What an output step shows beyond the bodies' states, gathered on rank 0.
struct FrameParts {
    contacts: Vec<ContactRecord>,
    books: EnergyBooks,
}

/// The run's state gathered on rank 0 ([`DistributedSimulation::gather`]).
pub struct Gathered {
    pub checkpoint: Checkpoint,
    shown: Option<FrameParts>,
}

impl Gathered {
    /// `f` of the output step gathered (`None` if none was): a frame of the
    /// checkpoint's bodies, which it lends and takes back rather than
    /// copies, so that rank 0 holds the bodies' states once.
    pub fn show<R>(&mut self, f: impl FnOnce(&Frame) -> R) -> Option<R> {
        let parts = self.shown.as_ref()?;
        let c = &mut self.checkpoint;
        let frame = Frame {
            time: c.time,
            step: c.step,
            bodies: std::mem::take(&mut c.bodies),
            contacts: parts.contacts.iter().map(ContactRecord::contact).collect(),
            energies: parts.books.rounded(),
        };
        let r = f(&frame);
        c.bodies = frame.bodies;
        Some(r)
    }
}

/// The particles the scene dealt to this rank (`me`), in the scene's state
/// or `state`'s, and every obstacle with its box (inflated by its halo; a
/// moving wall's box is that of its start, and not used).
fn dealt(
    scene: &Scene,
    state: Option<&CheckpointShare>,
    me: i32,
) -> (Vec<Entry>, Vec<(u32, Body, Bounds)>) {
    let world = &scene.world;
    let (mut entries, mut obstacles) = (Vec::new(), Vec::new());
    for (i, b) in world.bodies.iter().enumerate() {
        let id = world.id(i);
        if b.is_static() {
            let (lo, hi) = world.world_bounds(i);
            let halo = world.materials[b.material].halo.unwrap_or(0.0);
            let bounds = Bounds { lo, hi }.inflated(halo);
            obstacles.push((id, b.clone(), bounds));
            continue;
        }
        let mut body = b.clone();
        let (mut force, mut torque) = (DVec3::ZERO, DVec3::ZERO);
        if let Some((s, f, t)) = state.and_then(|c| c.state(id as usize)) {
            (body.x, body.q, body.v, body.l) = (s.x, s.q, s.v, s.l);
            (body.removed, body.pending) = (s.removed, s.pending);
            (force, torque) = (f, t);
        }
        entries.push(Entry {
            id,
            body,
            role: Role::Own,
            owner: me,
            force,
            torque,
            work: [0.0; 2],
        });
    }
    (entries, obstacles)
}

/// The ranks of a run share an insertion's decisions (collective).
struct RankShare<'a>(&'a SimpleCommunicator);

impl Agree for RankShare<'_> {
    fn gather(&mut self, mine: &[Candidate]) -> Vec<Candidate> {
        let numbers: Vec<f64> = mine.iter().flat_map(|c| c.to_numbers()).collect();
        let all = all_gather_v(self.0, &numbers);
        (all.chunks_exact(6))
            .map(|n| Candidate::from_numbers(n.try_into().expect("six numbers")))
            .collect()
    }

    fn any(&mut self, mine: &[bool]) -> Vec<bool> {
        let mine: Vec<u8> = mine.iter().map(|&b| u8::from(b)).collect();
        let mut all = vec![0u8; mine.len()];
        self.0
            .all_reduce_into(&mine[..], &mut all[..], SystemOperation::max());
        all.into_iter().map(|b| b == 1).collect()
    }
}

fn start_state<'a>(start: &Start<'a>) -> Option<&'a CheckpointShare> {
    match start {
        Start::Fresh => None,
        Start::Resume(c) => Some(c),
    }
}

fn start_time(start: &Start) -> (f64, u64) {
    match start {
        Start::Fresh => (0.0, 0),
        Start::Resume(c) => (c.time, c.step),
    }
}

/// Restores this rank's share of the effects' states: the books on rank 0
/// (exact sums: the others' share is zero), and the history rows the share
/// holds (of a scene of `bodies` bodies).
fn restore_share(
    effects: &mut [Box<dyn Effect>],
    share: &CheckpointShare,
    me: i32,
    bodies: usize,
) -> Result<(), String> {
    let states: Vec<EffectState> = share
        .effects
        .iter()
        .map(|s| {
            let mut s = s.clone();
            if me != 0 {
                s.stored = ExactSum::default().parts();
                s.taken = ExactSum::default().parts();
            }
            s
        })
        .collect();
    dem::simulation::restore_effects(effects, &states, bodies)
        .map_err(|e: CheckpointError| e.to_string())
}

/// An exact sum's parts from every rank, merged on rank 0 (collective).
fn merge_sums(comm: &SimpleCommunicator, parts: &[f64]) -> Option<ExactSum> {
    let counts = gather_v(comm, 0, &[parts.len() as u64]);
    let all = gather_v(comm, 0, parts);
    let (counts, all) = (counts?, all?);
    let mut sum = ExactSum::default();
    let mut at = 0;
    for &n in &counts {
        sum.merge(&ExactSum::from_parts(&all[at..at + n as usize]));
        at += n as usize;
    }
    Some(sum)
}

/// Puts the `motions` that arrived from each neighbour of `recv` on its ghosts.
fn put_motions(world: &mut dem::world::World, recv: &[(i32, Vec<usize>)], motions: &[Vec<Motion>]) {
    for ((_, ids), motions) in recv.iter().zip(motions) {
        for (&i, motion) in ids.iter().zip(motions) {
            motion.put(&mut world.bodies[i]);
        }
    }
}

/// `near` and `far` (each grouped by body pair, in pair order, no pair in
/// both) merged into `out` in pair order.
pub fn merge_by_pair(near: &[Contact], far: &[Contact], out: &mut Vec<Contact>) {
    out.clear();
    out.reserve(near.len() + far.len());
    let (mut i, mut j) = (0, 0);
    while i < near.len() || j < far.len() {
        let take_near =
            j == far.len() || (i < near.len() && (near[i].a, near[i].b) < (far[j].a, far[j].b));
        if take_near {
            out.push(near[i]);
            i += 1;
        } else {
            out.push(far[j]);
            j += 1;
        }
    }
}
