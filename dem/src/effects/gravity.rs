//! Gravity: F = m g on every particle.

use super::{Books, Declare, Effect, Forces, Setting, StepContext};
use crate::world::World;
use glam::DVec3;
use serde::Deserialize;

/// `gravity = { g = [gx, gy, gz] }` (m/s²).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct GravityParams {
    pub g: [f64; 3],
}

impl GravityParams {
    pub fn g(&self) -> DVec3 {
        DVec3::from_array(self.g)
    }
}

impl Declare for GravityParams {
    const NAME: &'static str = "gravity";
    fn check(&self) -> Result<(), String> {
        match self.g().is_finite() {
            true => Ok(()),
            false => Err("g must be finite".into()),
        }
    }
    fn build(&self, _: &Setting) -> Option<Box<dyn Effect>> {
        Some(Box::new(GravityEffect { g: self.g() }))
    }
}

pub struct GravityEffect {
    pub g: DVec3,
}

impl Effect for GravityEffect {
    fn name(&self) -> &'static str {
        GravityParams::NAME
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        for &i in &ctx.bodies {
            forces.add(i, self.g * world.bodies[i].mass);
        }
    }

    /// The potential energy −m g·x of the bodies, computed when asked (at
    /// output steps), not every step.
    fn books(&self, world: &World, ctx: &StepContext) -> Books {
        let mut books = Books::default();
        for &i in &ctx.bodies {
            let b = &world.bodies[i];
            books.stored.add(-b.mass * self.g.dot(b.x));
        }
        books
    }
}
