//! Gravity: F = m g on every particle.

use super::{Declare, Effect, Forces, StepContext};
use crate::scene::Scene;
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
    fn build(&self, _scene: &Scene) -> Option<Box<dyn Effect>> {
        Some(Box::new(GravityEffect { g: self.g() }))
    }
}

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
