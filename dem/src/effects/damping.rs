//! Global viscous damping: F = −γ m v, τ = −γ_rot L (rates in 1/s).

use super::{Effect, Forces, StepContext};
use crate::world::World;

pub struct DampingEffect {
    pub linear: f64,
    pub angular: f64,
    /// Work taken out of the bodies since the start.
    pub dissipated: f64,
}

impl Effect for DampingEffect {
    fn name(&self) -> &'static str {
        "damping"
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        let mut power = 0.0;
        for (i, b) in world.bodies.iter().enumerate() {
            if !b.is_static() {
                let (f, t) = (b.v * (self.linear * b.mass), b.l * self.angular);
                forces.force[i] -= f;
                forces.torque[i] -= t;
                power += f.dot(b.v) + t.dot(b.omega());
            }
        }
        self.dissipated += power * ctx.dt;
    }

    fn dissipated(&self) -> f64 {
        self.dissipated
    }

    /// The work dissipated so far.
    fn state(&self) -> Option<Vec<f64>> {
        Some(vec![self.dissipated])
    }

    fn restore(&mut self, values: &[f64], _world: &World) -> Result<(), String> {
        match values {
            [w] if w.is_finite() => {
                self.dissipated = *w;
                Ok(())
            }
            _ => Err(format!(
                "the damping effect's state is one finite number (the work dissipated), got {values:?}"
            )),
        }
    }
}
