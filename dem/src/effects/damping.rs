//! Global viscous damping: F = −γ m v, τ = −γ_rot L (rates in 1/s).

use super::{Declare, Effect, Forces, StepContext};
use crate::ledger::Ledger;
use crate::scene::Scene;
use crate::world::World;
use serde::Deserialize;

/// `damping = { linear = γ, angular = γ_rot }` (1/s, each 0 when left out).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DampingParams {
    #[serde(default)]
    pub linear: f64,
    #[serde(default)]
    pub angular: f64,
}

impl Declare for DampingParams {
    const NAME: &'static str = "damping";
    fn check(&self) -> Result<(), String> {
        let ok = |r: f64| r.is_finite() && r >= 0.0;
        match ok(self.linear) && ok(self.angular) {
            true => Ok(()),
            false => Err("damping rates must be finite and non-negative".into()),
        }
    }
    fn build(&self, _scene: &Scene) -> Option<Box<dyn Effect>> {
        Some(Box::new(DampingEffect {
            linear: self.linear,
            angular: self.angular,
            ledger: Ledger::default(),
        }))
    }
}

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
