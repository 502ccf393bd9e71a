//! Normal contact: a linear spring-dashpot per body pair.
//!
//! For a body pair with stiffness k (springs of the two materials in series),
//! reduced mass m* = 1/(1/m_a + 1/m_b) and restitution e (mean of the two),
//! the pair's damping is c = 2 ζ √(m* k) with ζ = −ln e / √(π² + ln² e), which
//! gives restitution e exactly for a head-on impact. The pair's n contacts
//! (after merging) share it: each applies
//!   F = (k δ − c v_n) / n   along the normal,
//! so the pair acts like one spring-dashpot whatever the triangulation (a face
//! on a face gives several contact points at one depth). The force may pull
//! (tension) at the end of an impact, as in the linear model whose restitution
//! is exact; it is reported as 0 to friction.

use super::{Effect, Forces, PairForce, StepContext, FORCE_GRAIN};
use crate::contact::Detector;
use crate::distance::Options;
use crate::material::MaterialPairs;
use crate::world::World;
use rayon::prelude::*;

pub struct ContactEffect {
    detector: Detector,
    pub kernel: Options,
    /// Per body: halo.
    halo: Vec<f64>,
    laws: MaterialPairs,
    /// Spring energy of the last evaluation (for energy checks).
    energy: f64,
    /// Per contact: the force pair, the normal force, the spring energy.
    per_contact: Vec<(PairForce, f64, f64)>,
}

impl ContactEffect {
    /// `skin`: the detector's neighbour-list skin (0: none).
    pub fn new(world: &World, kernel: Options, skin: f64) -> Self {
        ContactEffect {
            detector: Detector::with_skin(skin),
            kernel,
            halo: world.per_body(|m| m.halo),
            laws: MaterialPairs::new(&world.materials),
            energy: 0.0,
            per_contact: Vec::new(),
        }
    }
}

impl Effect for ContactEffect {
    fn name(&self) -> &'static str {
        "contact"
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        let det = self.detector.detect_moved(
            world,
            &self.halo,
            &self.kernel,
            ctx.moved,
            &mut ctx.contacts,
        );
        ctx.stats.detection = det;
        ctx.detection_times = self.detector.last_times();
        let laws = &self.laws;
        ctx.contacts
            .par_iter()
            .with_min_len(FORCE_GRAIN)
            .map(|c| {
                let (ba, bb) = (&world.bodies[c.a], &world.bodies[c.b]);
                let law = laws.get(ba.material, bb.material);
                let k = law.stiffness;
                let m = 1.0 / (ba.inv_mass + bb.inv_mass);
                let damping = 2.0 * law.damping_ratio * (m * k).sqrt();
                let v_n = (ba.velocity_at(c.point) - bb.velocity_at(c.point)).dot(c.normal);
                let n = c.share as f64;
                let f = (k * c.depth - damping * v_n) / n;
                let pair = PairForce::new(c.a, ba.x, c.b, bb.x, c.point, c.normal * f);
                (pair, f.max(0.0), 0.5 * k * c.depth * c.depth / n)
            })
            .collect_into_vec(&mut self.per_contact);
        ctx.normal_force.clear();
        self.energy = 0.0;
        for (pair, normal_force, energy) in &self.per_contact {
            forces.add_pair(pair);
            ctx.normal_force.push(*normal_force);
            self.energy += energy;
        }
        ctx.stats.normal_evaluations += ctx.contacts.len() as u64;
    }

    fn potential_energy(&self, _world: &World, _ctx: &StepContext) -> f64 {
        self.energy
    }

    /// The springs' energy only, for [`Effect::potential_energy`]: contacts
    /// are found afresh every step.
    fn state(&self) -> Option<Vec<f64>> {
        Some(vec![self.energy])
    }

    fn restore(&mut self, values: &[f64], _world: &World) -> Result<(), String> {
        match values {
            [energy] if energy.is_finite() => {
                self.energy = *energy;
                Ok(())
            }
            _ => Err(format!(
                "the contact effect's state is one finite number (the springs' energy), got {values:?}"
            )),
        }
    }
}
