//! Global viscous damping: F = −γ m v, τ = −γ_rot L (rates in 1/s).

use super::{Books, Declare, Effect, Forces, Setting, StepContext};
use crate::ledger::Ledger;
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
    fn build(&self, _: &Setting) -> Option<Box<dyn Effect>> {
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
        DampingParams::NAME
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        for &i in &ctx.bodies {
            let b = &world.bodies[i];
            let (f, t) = (b.v * (self.linear * b.mass), b.l * self.angular);
            // a - b is a + (-b) in IEEE arithmetic: the same bits as subtracting.
            forces.add_with_torque(i, -f, -t);
            let power = f.dot(b.v) + t.dot(b.omega());
            self.ledger.take(power * ctx.dt);
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
