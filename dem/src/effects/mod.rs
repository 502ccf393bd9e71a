//! The effects a scene can declare, each its own unit of the step pipeline.
//!
//! Only declared effects are constructed, so an undeclared effect costs
//! nothing and cannot act. Each effect's file holds its parameters (what
//! the scene writes), their checks, the material parameters it needs, and
//! its force law; [`KINDS`] registers it in one line (see `declare.rs`). Each effect adds forces and torques; effects that
//! need what another found (friction needs the contacts and their normal
//! forces) read it from the [`StepContext`].

mod contact;
mod damping;
mod declare;
mod friction;
mod gravity;
mod rotation;

pub use contact::{ContactEffect, ContactParams, NormalLaw};
pub use damping::{DampingEffect, DampingParams};
pub use declare::{kind, kind_of, Declare, Declared, Effects, Kind, MaterialParam, KINDS};
pub use friction::{FrictionEffect, FrictionParams};
pub use gravity::{GravityEffect, GravityParams};
pub use rotation::RotationParams;

use crate::contact::{Contact, DetectionStats};
use crate::ledger::Ledger;
use crate::timing::DetectionTimes;
use crate::world::World;
use glam::DVec3;

/// Force and torque on every body, accumulated by the effects.
#[derive(Debug, Clone, Default)]
pub struct Forces {
    pub force: Vec<DVec3>,
    pub torque: Vec<DVec3>,
}

impl Forces {
    pub fn reset(&mut self, n: usize) {
        self.force.clear();
        self.force.resize(n, DVec3::ZERO);
        self.torque.clear();
        self.torque.resize(n, DVec3::ZERO);
    }

    /// Applies `f` at world point `p` on body `i` (centre of mass `x`).
    pub fn add_at(&mut self, i: usize, x: DVec3, p: DVec3, f: DVec3) {
        self.force[i] += f;
        self.torque[i] += (p - x).cross(f);
    }

    /// Adds a [`PairForce`]: the same sums as `add_at` on a, then on b.
    pub fn add_pair(&mut self, f: &PairForce) {
        self.force[f.a] += f.force;
        self.torque[f.a] += f.torque_a;
        self.force[f.b] += -f.force;
        self.torque[f.b] += f.torque_b;
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
    /// Split across ranks: whose terms this rank enters in the effects'
    /// books, per body and per contact (empty: all). A rank holds copies of
    /// other ranks' bodies, and a contact across a cut is computed on both
    /// sides; each term is booked on one rank only.
    pub booked_bodies: Vec<bool>,
    pub booked_contacts: Vec<bool>,
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

impl StepContext {
    /// Whether body i's terms are booked here.
    pub fn books_body(&self, i: usize) -> bool {
        self.booked_bodies.get(i).copied().unwrap_or(true)
    }

    /// Whether contact k's terms are booked here.
    pub fn books_contact(&self, k: usize) -> bool {
        self.booked_contacts.get(k).copied().unwrap_or(true)
    }
}

impl std::ops::AddAssign for StepStats {
    fn add_assign(&mut self, o: StepStats) {
        self.detection += o.detection;
        self.normal_evaluations += o.normal_evaluations;
        self.tangential_evaluations += o.tangential_evaluations;
    }
}

/// One effect of the step pipeline.
pub trait Effect: Send {
    fn name(&self) -> &'static str;
    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces);
    /// Whether the effect finds the contacts (its time includes detection).
    fn detects_contacts(&self) -> bool {
        false
    }
    /// Potential energy the effect stores (gravity, springs), for energy checks.
    fn potential_energy(&self, _world: &World, _ctx: &StepContext) -> f64 {
        0.0
    }
    /// Work the effect has taken out of the bodies and not stored, since the
    /// start of the run (dashpots, sliding): for energy bookkeeping.
    fn dissipated(&self) -> f64 {
        0.0
    }
    /// The effect's energy books, whose terms each evaluation enters and the
    /// caller closes (after merging the ranks' terms, split across ranks).
    fn ledger_mut(&mut self) -> Option<&mut Ledger> {
        None
    }
    /// What the effect carries from one step to the next, for a checkpoint
    /// (`None`: nothing, each step starts afresh).
    fn state(&self) -> Option<Vec<f64>> {
        None
    }
    /// Takes back what [`Effect::state`] gave, in a simulation of `world`.
    fn restore(&mut self, values: &[f64], _world: &World) -> Result<(), String> {
        match values {
            [] => Ok(()),
            _ => Err(format!("the {} effect keeps no state", self.name())),
        }
    }
}
