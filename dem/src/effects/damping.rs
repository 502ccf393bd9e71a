//! Global viscous damping: F = −γ m v, τ = −γ_rot L (rates in 1/s).

use super::{Effect, Forces, StepContext};
use crate::ledger::Ledger;
use crate::world::World;

pub struct DampingEffect {
    pub linear: f64,
    pub angular: f64,
    /// Work taken out of the bodies since the start.
    pub ledger: Ledger,
}

impl Effect for DampingEffect {
    fn name(&self) -> &'static str {
        "damping"
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        for (i, b) in world.bodies.iter().enumerate() {
            if !b.is_static() {
                let (f, t) = (b.v * (self.linear * b.mass), b.l * self.angular);
                forces.force[i] -= f;
                forces.torque[i] -= t;
                if ctx.books_body(i) {
                    let power = f.dot(b.v) + t.dot(b.omega());
                    self.ledger.step_taken.add(power * ctx.dt);
                }
            }
        }
    }

    fn dissipated(&self) -> f64 {
        self.ledger.taken
    }

    fn ledger_mut(&mut self) -> Option<&mut Ledger> {
        Some(&mut self.ledger)
    }

    /// The work dissipated so far.
    fn state(&self) -> Option<Vec<f64>> {
        Some(vec![self.ledger.taken])
    }

    fn restore(&mut self, values: &[f64], _world: &World) -> Result<(), String> {
        match values {
            [w] if w.is_finite() => {
                self.ledger.taken = *w;
                Ok(())
            }
            _ => Err(format!(
                "the damping effect's state is one finite number (the work dissipated), got {values:?}"
            )),
        }
    }
}
