//! Gravity: F = m g on every particle.

use super::{Effect, Forces, StepContext};
use crate::world::World;
use glam::DVec3;

pub struct GravityEffect {
    pub g: DVec3,
}

impl Effect for GravityEffect {
    fn name(&self) -> &'static str {
        "gravity"
    }

    fn apply(&mut self, world: &World, _ctx: &mut StepContext, forces: &mut Forces) {
        for (i, b) in world.bodies.iter().enumerate() {
            if !b.is_static() {
                forces.force[i] += self.g * b.mass;
            }
        }
    }

    fn potential_energy(&self, world: &World, _ctx: &StepContext) -> f64 {
        world
            .bodies
            .iter()
            .filter(|b| !b.is_static())
            .map(|b| -b.mass * self.g.dot(b.x))
            .sum()
    }
}
