//! Global viscous damping: F = −γ m v, τ = −γ_rot L (rates in 1/s).

use super::{Effect, Forces, StepContext};
use crate::world::World;

pub struct DampingEffect {
    pub linear: f64,
    pub angular: f64,
}

impl Effect for DampingEffect {
    fn name(&self) -> &'static str {
        "damping"
    }

    fn apply(&mut self, world: &World, _ctx: &mut StepContext, forces: &mut Forces) {
        for (i, b) in world.bodies.iter().enumerate() {
            if !b.is_static() {
                forces.force[i] -= b.v * (self.linear * b.mass);
                forces.torque[i] -= b.l * self.angular;
            }
        }
    }
}
