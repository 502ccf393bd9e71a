//! The effects a scene can declare, each its own unit of the step pipeline.
//!
//! Only declared effects are constructed, so an undeclared effect costs
//! nothing and cannot act. Each effect's file holds its parameters (what
//! the scene writes), their checks, the material parameters it needs, and
//! its force law; one line of the `register!` list below declares the file
//! and registers the effect in [`KINDS`] (see `declare.rs`). Each effect
//! adds forces and torques; effects that need what another found (friction
//! needs the contacts and their normal forces) read it from the
//! [`StepContext`].

mod declare;
pub mod places;

/// Declares each effect's file and registers its parameter type in
/// [`KINDS`], in the order given: an effect is its file plus its line in
/// the list below.
macro_rules! register {
    ($($file:ident :: $params:ident),* $(,)?) => {
        $(mod $file;)*
        /// Every effect a scene can declare, in the order of the step
        /// pipeline.
        pub static KINDS: &[Kind] = &[$(declare::kind::<$file::$params>()),*];
    };
}

// The order of the pipeline: friction reads the normal forces the contact
// effect found; moving walls book the power of both.
register! {
    gravity::GravityParams,
    contact::ContactParams,
    friction::FrictionParams,
    wall_motion::WallMotionParams,
    damping::DampingParams,
    rotation::RotationParams,
    probes::ProbesParams,
    outflow::OutflowParams,
    insertion::InsertionParams,
}

pub use contact::{ContactEffect, ContactParams, NormalLaw};
pub use damping::{DampingEffect, DampingParams};
pub use declare::{kind, kind_of, Declare, Declared, Effects, Kind, MaterialParam, Setting};
pub use friction::{FrictionEffect, FrictionParams};
pub use gravity::{GravityEffect, GravityParams};
pub use insertion::{
    book_entries, choose, insert_due, insertion_due, Agree, Alone, Candidate, InsertRegion,
    InsertionEffect, InsertionParams, Stream,
};
pub use outflow::{OutflowEffect, OutflowParams, SinkBox, SinkPlane};
pub use probes::{Plane, ProbesEffect, ProbesParams, Region};
pub use rotation::RotationParams;
pub use wall_motion::{WallMotionEffect, WallMotionParams};

use crate::contact::{Contact, DetectionStats};
use crate::ledger::{ExactSum, Ledger};
use crate::timing::DetectionTimes;
use crate::world::World;
use glam::DVec3;

/// Force and torque on every body, accumulated by the effects.
///
/// Each body's force is a sum whose terms come in a fixed order: effect by
/// effect in pipeline order, and within an effect in the order it adds them
/// (body terms, then one per contact in contact order). Split across ranks,
/// the terms of a body near a cut are computed on more than one rank; those
/// bodies are *logged* ([`Forces::log_bodies`]): their terms are kept as
/// [`ForceTerm`]s, to be summed in that order once all have arrived
/// ([`Forces::sum_terms`]), which gives the bits one process's running sum
/// gives.
#[derive(Debug, Clone, Default)]
pub struct Forces {
    force: Vec<DVec3>,
    torque: Vec<DVec3>,
    /// The effect now adding terms (its place in the pipeline).
    effect: u32,
    /// Per body, whether its terms are logged (empty: none is).
    logged: Vec<bool>,
    log: Vec<ForceTerm>,
}

/// One term of a logged body's force and torque.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct ForceTerm {
    pub body: u32,
    /// The effect that added it (its place in the pipeline).
    pub effect: u32,
    /// The contact it acts at (an index into the evaluation's contacts), or
    /// [`ForceTerm::BODY`] for a term on the body as a whole.
    pub contact: u32,
    pub force: DVec3,
    /// `None`: the term leaves the torque untouched (adding a zero would
    /// turn a torque of -0.0 into +0.0).
    pub torque: Option<DVec3>,
}

impl ForceTerm {
    pub const BODY: u32 = u32::MAX;
}

impl Forces {
    /// Zero force and torque on `n` bodies, none logged.
    pub fn reset(&mut self, n: usize) {
        self.force.clear();
        self.force.resize(n, DVec3::ZERO);
        self.torque.clear();
        self.torque.resize(n, DVec3::ZERO);
        self.logged.clear();
        self.log.clear();
        self.effect = 0;
    }

    /// Logs the terms of the bodies `logged` marks (one flag per body).
    pub fn log_bodies(&mut self, logged: &[bool]) {
        assert_eq!(logged.len(), self.force.len(), "a flag per body");
        self.logged.clear();
        self.logged.extend_from_slice(logged);
    }

    /// The terms that follow are the effect at `position` in the pipeline's.
    pub fn begin_effect(&mut self, position: usize) {
        self.effect = position as u32;
    }

    #[inline]
    fn is_logged(&self, i: usize) -> bool {
        !self.logged.is_empty() && self.logged[i]
    }

    #[inline]
    fn term(&mut self, i: usize, contact: u32, force: DVec3, torque: Option<DVec3>) {
        if self.is_logged(i) {
            self.log.push(ForceTerm {
                body: i as u32,
                effect: self.effect,
                contact,
                force,
                torque,
            });
            return;
        }
        self.force[i] += force;
        if let Some(t) = torque {
            self.torque[i] += t;
        }
    }

    /// Adds force `f` to body `i` (no torque).
    pub fn add(&mut self, i: usize, f: DVec3) {
        self.term(i, ForceTerm::BODY, f, None);
    }

    /// Adds force `f` and torque `t` to body `i`.
    pub fn add_with_torque(&mut self, i: usize, f: DVec3, t: DVec3) {
        self.term(i, ForceTerm::BODY, f, Some(t));
    }

    /// Adds the [`PairForce`] of contact `k`: the terms on a, then on b.
    pub fn add_pair(&mut self, k: usize, f: &PairForce) {
        self.term(f.a, k as u32, f.force, Some(f.torque_a));
        self.term(f.b, k as u32, -f.force, Some(f.torque_b));
    }

    pub fn force(&self, i: usize) -> DVec3 {
        self.force[i]
    }

    pub fn torque(&self, i: usize) -> DVec3 {
        self.torque[i]
    }

    /// Every body's force and torque (of a logged body: those of its terms
    /// summed so far).
    pub fn all(&self) -> (&[DVec3], &[DVec3]) {
        (&self.force, &self.torque)
    }

    /// Sets body `i`'s force and torque (a checkpoint's, or a migrated body's).
    pub fn set(&mut self, i: usize, force: DVec3, torque: DVec3) {
        self.force[i] = force;
        self.torque[i] = torque;
    }

    /// The terms logged since the last [`Forces::reset`] (which empties the
    /// log and keeps its room for the next evaluation).
    pub fn log(&self) -> &[ForceTerm] {
        &self.log
    }

    /// Sums a logged body's terms, given in the order one process adds them,
    /// into its force and torque, from zero.
    pub fn sum_terms(&mut self, i: usize, terms: impl IntoIterator<Item = ForceTerm>) {
        let (mut f, mut t) = (DVec3::ZERO, DVec3::ZERO);
        for term in terms {
            f += term.force;
            if let Some(x) = term.torque {
                t += x;
            }
        }
        self.force[i] = f;
        self.torque[i] = t;
    }
}

/// A force on body a at a point, its opposite on body b, and their torques.
/// Contact laws compute these in parallel (reading both bodies' states is
/// most of their cost) and add them in contact order, so sums do not depend
/// on the thread count.
#[derive(Debug, Clone, Copy, Default)]
pub struct PairForce {
    pub a: usize,
    pub b: usize,
    pub force: DVec3,
    pub torque_a: DVec3,
    pub torque_b: DVec3,
}

impl PairForce {
    /// `f` on a (centre `xa`) at `p`, −f on b (centre `xb`).
    pub fn new(a: usize, xa: DVec3, b: usize, xb: DVec3, p: DVec3, f: DVec3) -> PairForce {
        PairForce {
            a,
            b,
            force: f,
            torque_a: (p - xa).cross(f),
            torque_b: (p - xb).cross(-f),
        }
    }
}

/// Contacts (or body pairs in contact) per parallel task of a contact law: a
/// few dozen nanoseconds of arithmetic each, so small scenes stay on one thread.
pub(crate) const FORCE_GRAIN: usize = 16;

/// What the effects of one step share and count.
#[derive(Debug, Default)]
pub struct StepContext {
    pub dt: f64,
    /// The particles this process moves, in increasing index: the bodies the
    /// effects act on and book. On one node every particle; split across
    /// ranks, the rank's own (the others are copies, moved by their owners).
    pub bodies: Vec<usize>,
    /// The particles this process moved that an outflow took out, in
    /// increasing index (their state is that at which they left).
    pub removed: Vec<usize>,
    /// The particles this process holds that wait to be inserted, in
    /// increasing index.
    pub pending: Vec<usize>,
    /// This evaluation's contacts, grouped by body pair in increasing order;
    /// split across ranks, those this rank computes (each contact on one rank).
    pub contacts: Vec<Contact>,
    /// Normal force magnitude of each contact (0 where the spring is in tension).
    pub normal_force: Vec<f64>,
    /// The force on body a of each contact, summed over the effects that act
    /// at contacts (normal, then tangential).
    pub contact_force: Vec<DVec3>,
    /// Per contact: its normal force, and its tangential force (friction),
    /// as force pairs on its two bodies.
    pub normal_pairs: Vec<PairForce>,
    pub tangential_pairs: Vec<PairForce>,
    /// Per contact: whether its friction slides (held at μ times its normal
    /// force); empty without friction.
    pub sliding: Vec<bool>,
    /// Whether the caller found this evaluation's contacts (split across
    /// ranks, where detection needs other ranks' bodies): the contact effect
    /// then applies its law to `contacts` as they are.
    pub contacts_found: bool,
    pub stats: StepStats,
    /// Where this step's contact detection spent its time.
    pub detection_times: DetectionTimes,
    /// A bound on how far any point of any body moved since the previous
    /// force evaluation (`None`: unknown, as before the first step).
    pub moved: Option<f64>,
}

/// Counters of one step, summed over a run by the caller.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct StepStats {
    pub detection: DetectionStats,
    pub normal_evaluations: u64,
    pub tangential_evaluations: u64,
}

impl std::ops::AddAssign for StepStats {
    fn add_assign(&mut self, o: StepStats) {
        self.detection += o.detection;
        self.normal_evaluations += o.normal_evaluations;
        self.tangential_evaluations += o.tangential_evaluations;
    }
}

/// An effect's energy books at one evaluation, as exact sums over this
/// process's bodies and contacts (merged across ranks before rounding).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct Books {
    /// Energy the effect stores now (gravity's potential, the springs).
    pub stored: ExactSum,
    /// Work it has taken out of the bodies since the start and not stored
    /// (dashpots, sliding, damping).
    pub dissipated: ExactSum,
}

impl Books {
    /// The books of an effect that stores nothing: what `ledger` took out.
    pub fn taken_by(ledger: &Ledger) -> Books {
        Books {
            stored: Default::default(),
            dissipated: ledger.taken().clone(),
        }
    }

    pub fn merge(&mut self, o: &Books) {
        self.stored.merge(&o.stored);
        self.dissipated.merge(&o.dissipated);
    }
}

/// Per-contact state an effect carries from step to step (friction's
/// tangential springs), as rows of plain numbers: each row starts with the
/// contact's two body ids (a < b), as numbers. Through it the state moves
/// with its contacts between ranks, and is checkpointed, without anyone but
/// the effect knowing what the rest of a row means.
pub trait ContactHistory {
    /// Numbers per row, the two body ids included.
    fn row_len(&self) -> usize;
    /// Every row, in the effect's order.
    fn rows(&self) -> Vec<f64>;
    /// Removes the rows of the body pairs for which `leaves(a, b)` holds, and
    /// returns them.
    fn take_rows(&mut self, leaves: &mut dyn FnMut(u32, u32) -> bool) -> Vec<f64>;
    /// Adds rows (of pairs this process has no rows of), in any order;
    /// `bodies` is the number of bodies in the whole scene. Refused, naming
    /// the row, unless each is a row this effect could have written.
    fn add_rows(&mut self, rows: &[f64], bodies: usize) -> Result<(), String>;
}

/// One effect of the step pipeline.
pub trait Effect: Send {
    /// The name of the effect's parameters ([`Declare::NAME`]).
    fn name(&self) -> &'static str;
    /// Adds the effect's forces: on `ctx.bodies`, and at `ctx.contacts`
    /// (through [`Forces::add_pair`], in contact order).
    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces);
    /// Whether the effect finds the contacts (its time includes detection).
    fn detects_contacts(&self) -> bool {
        false
    }
    /// The effect's energy books for `ctx.bodies` and `ctx.contacts` (zero
    /// for an effect that stores and dissipates nothing).
    fn books(&self, _world: &World, _ctx: &StepContext) -> Books {
        Books::default()
    }
    /// What the effect measures of `ctx.bodies` at an output step (a
    /// probe's counts and masses), named, as exact sums that merge across
    /// ranks: empty for an effect that measures nothing.
    fn measures(&self, _world: &World, _ctx: &StepContext) -> Vec<(String, ExactSum)> {
        Vec::new()
    }
    /// Whether the effect takes particles out of the run (an outflow): the
    /// pipeline then asks [`Effect::removes`] of each particle at each
    /// step's end (and not at all when no effect does).
    fn removes_particles(&self) -> bool {
        false
    }
    /// Whether particle `b`, as it stands at a step's end, leaves the run.
    fn removes(&self, _b: &crate::body::Body) -> bool {
        false
    }
    /// Whether the effect inserts particles: the pipeline then offers it the
    /// waiting ones at each step's end (see `insertion`), and not at all
    /// when no effect does.
    fn inserts_particles(&self) -> bool {
        false
    }
    /// The positions to try for the particles of `ctx.pending` due by time
    /// `t`, the end of step `step`.
    fn candidates(
        &self,
        _world: &World,
        _ctx: &StepContext,
        _t: f64,
        _step: u64,
    ) -> Vec<Candidate> {
        Vec::new()
    }
    /// Per candidate, whether a particle of `ctx.bodies` is in its way.
    fn blocks(&self, _world: &World, _ctx: &StepContext, candidates: &[Candidate]) -> Vec<bool> {
        vec![false; candidates.len()]
    }
    /// Puts the particles of `placed` this process holds into the run.
    fn admit(&mut self, _world: &mut World, _ctx: &mut StepContext, _placed: &[Candidate]) {}
    /// At the step's end: books what the particles it put in brought.
    fn book_entries(&mut self, _world: &World) {}
    /// The books the effect keeps from step to step, if any: a checkpoint
    /// holds them, and split across ranks each rank keeps its terms' share.
    fn ledger(&self) -> Option<&Ledger> {
        None
    }
    fn ledger_mut(&mut self) -> Option<&mut Ledger> {
        None
    }
    /// The effect's per-contact state, if it keeps any.
    fn history(&self) -> Option<&dyn ContactHistory> {
        None
    }
    fn history_mut(&mut self) -> Option<&mut dyn ContactHistory> {
        None
    }
}
