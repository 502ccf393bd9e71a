//! Moving walls: obstacles driven at a prescribed velocity and angular
//! velocity, and the work they do on the particles.
//!
//! An obstacle of the scene may move (`velocity`, `angular_velocity` on its
//! `[[obstacles]]` entry, about its frame's origin `position`, each constant
//! or a piecewise-linear table in time, `velocity_table` and
//! `angular_velocity_table`): its pose at time t is
//! x(t) = x₀ + ∫₀ᵗ v, q(t) = exp(∫₀ᵗ ω) q₀ ([`crate::drive`]), set by the
//! integrator at every step, whatever the forces on it. Contacts
//! see its surface move (their dashpots and friction use its velocity), and
//! this effect books the power it feeds into the particles: at a contact, the
//! force F and torque τ (about the wall's origin) the particle puts on the
//! wall give the wall's power P = −(F·v + τ·ω). Over a step, P dt is entered
//! as negative work taken out, so that kinetic plus stored plus dissipated
//! energy stays constant: the books balance, to the integrator's order, as
//! they do for fixed walls.
//!
//! Only declared with moving obstacles, and refused without: a scene whose
//! obstacles stand still runs none of this.

use super::{Books, Declare, Effect, Forces, PairForce, Setting, StepContext};
use crate::body::Body;
use crate::ledger::Ledger;
use crate::world::World;
use glam::DVec3;
use serde::Deserialize;

/// `wall_motion = {}`: the motions are the obstacles'.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct WallMotionParams {}

impl Declare for WallMotionParams {
    const NAME: &'static str = "wall_motion";
    /// Walls push through contacts.
    const NEEDS: &'static [&'static str] = &["contact"];
    fn build(&self, _: &Setting) -> Option<Box<dyn Effect>> {
        Some(Box::new(WallMotionEffect::default()))
    }
}

#[derive(Default)]
pub struct WallMotionEffect {
    /// Minus the work the walls have done on the particles since the start.
    ledger: Ledger,
}

/// The power a driven wall feeds into the particle of `pair` (zero when
/// neither body is a driven wall): −(F·v + τ·ω) of the force and torque on
/// the wall.
fn wall_power(world: &World, pair: &PairForce) -> f64 {
    let on = |b: &Body, force: DVec3, torque: DVec3| match &b.drive {
        // The wall's velocities where it was placed for this step.
        Some(_) => -(force.dot(b.v) + torque.dot(b.omega())),
        None => 0.0,
    };
    on(&world.bodies[pair.a], pair.force, pair.torque_a)
        + on(&world.bodies[pair.b], -pair.force, pair.torque_b)
}

impl Effect for WallMotionEffect {
    fn name(&self) -> &'static str {
        WallMotionParams::NAME
    }

    /// Adds no force: the walls' forces are the contacts'. Books their power.
    fn apply(&mut self, world: &World, ctx: &mut StepContext, _forces: &mut Forces) {
        for pair in ctx.normal_pairs.iter().chain(&ctx.tangential_pairs) {
            let p = wall_power(world, pair);
            if p != 0.0 {
                self.ledger.take(-p * ctx.dt);
            }
        }
    }

    fn books(&self, _world: &World, _ctx: &StepContext) -> Books {
        Books::taken_by(&self.ledger)
    }

    fn ledger(&self) -> Option<&Ledger> {
        Some(&self.ledger)
    }

    fn ledger_mut(&mut self) -> Option<&mut Ledger> {
        Some(&mut self.ledger)
    }
}
