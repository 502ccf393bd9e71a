//! The step pipeline: scene -> world -> effects -> integration.

use crate::effects::{
    ContactEffect, DampingEffect, Effect, Forces, FrictionEffect, GravityEffect, StepContext,
    StepStats,
};
use crate::integrate::{drift, half_kick, travel_bound};
use crate::scene::Scene;
use crate::timing::{seconds_since, SectionTimes};
use crate::world::World;
use rayon::prelude::*;
use std::time::Instant;

/// Bodies per parallel task of the integration.
const INTEGRATION_GRAIN: usize = 32;

/// Bodies per parallel task of the closing half kick: a few additions per
/// body, so a scene of fewer bodies keeps it on one thread (cheaper than
/// handing half to another).
const KICK_GRAIN: usize = 1024;

/// A running simulation.
pub struct Simulation {
    /// The bodies move only by [`Simulation::step`]; after moving any by hand,
    /// call [`Simulation::forget_motion`], or a neighbour list would miss it.
    pub world: World,
    pub dt: f64,
    rotation: bool,
    /// Set by `forget_motion`: the next step reports its motion as unknown.
    motion_unknown: bool,
    effects: Vec<Box<dyn Effect>>,
    /// Per shape: the largest distance of a vertex from the body's origin.
    shape_radius: Vec<f64>,
    forces: Forces,
    ctx: StepContext,
    /// Counters summed over all steps so far.
    pub totals: StepStats,
    /// Where the steps so far spent their time.
    pub timings: SectionTimes,
}

impl Simulation {
    /// Builds the pipeline from exactly the effects the scene declares.
    pub fn new(scene: &Scene) -> Simulation {
        let world = scene.world.clone();
        let mut effects: Vec<Box<dyn Effect>> = Vec::new();
        if let Some(g) = scene.effects.gravity {
            effects.push(Box::new(GravityEffect { g }));
        }
        if scene.effects.contact {
            effects.push(Box::new(ContactEffect::new(
                &world,
                scene.kernel,
                scene.effects.contact_skin,
            )));
        }
        if scene.effects.friction {
            effects.push(Box::new(FrictionEffect::new(&world)));
        }
        if let Some((linear, angular)) = scene.effects.damping {
            effects.push(Box::new(DampingEffect { linear, angular }));
        }
        let shape_radius = world
            .shapes
            .iter()
            .map(|m| m.vertices.iter().map(|v| v.length()).fold(0.0, f64::max))
            .collect();
        let mut sim = Simulation {
            world,
            dt: scene.dt,
            rotation: scene.effects.rotation,
            motion_unknown: false,
            shape_radius,
            effects,
            forces: Forces::default(),
            ctx: StepContext {
                dt: scene.dt,
                ..StepContext::default()
            },
            totals: StepStats::default(),
            timings: SectionTimes::default(),
        };
        let names: Vec<_> = sim.effects.iter().map(|e| e.name()).collect();
        sim.timings = SectionTimes::for_effects(names.iter().copied());
        sim.evaluate_forces();
        // Time counts from the first step.
        sim.timings = SectionTimes::for_effects(names);
        sim
    }

    /// Names of the effects in the pipeline, in order (rotation is an integration switch).
    pub fn effect_names(&self) -> Vec<&'static str> {
        let mut v: Vec<&'static str> = self.effects.iter().map(|e| e.name()).collect();
        if self.rotation {
            v.push("rotation");
        }
        v
    }

    fn evaluate_forces(&mut self) {
        self.forces.reset(self.world.bodies.len());
        self.ctx.stats = StepStats::default();
        self.ctx.detection_times = Default::default();
        // Indexed, not zipped: a timing list out of step with the effects must
        // fail loudly, never skip an effect.
        for (k, e) in self.effects.iter_mut().enumerate() {
            let start = Instant::now();
            e.apply(&self.world, &mut self.ctx, &mut self.forces);
            self.timings.effects[k].1 += seconds_since(start);
        }
        self.timings.detection += self.ctx.detection_times;
    }

    /// One velocity-Verlet step.
    pub fn step(&mut self) {
        let (h, rot) = (self.dt, self.rotation);
        let start = Instant::now();
        // Bodies are independent here; small scenes stay on one thread.
        let (forces, radius) = (&self.forces, &self.shape_radius);
        // The largest distance any point of a body moved: the max of exact
        // per-body bounds, the same on any thread count.
        let moved = self
            .world
            .bodies
            .par_iter_mut()
            .enumerate()
            .with_min_len(INTEGRATION_GRAIN)
            .map(|(i, b)| {
                half_kick(b, forces.force[i], forces.torque[i], h, rot);
                let before = (b.x, b.q);
                drift(b, h, rot);
                travel_bound(before, b, radius[b.shape])
            })
            .reduce(|| 0.0, f64::max);
        self.ctx.moved = (!std::mem::take(&mut self.motion_unknown)).then_some(moved);
        self.timings.integration += seconds_since(start);
        self.evaluate_forces();
        let start = Instant::now();
        let forces = &self.forces;
        self.world
            .bodies
            .par_iter_mut()
            .enumerate()
            .with_min_len(KICK_GRAIN)
            .for_each(|(i, b)| {
                half_kick(b, forces.force[i], forces.torque[i], h, rot);
            });
        self.timings.integration += seconds_since(start);
        self.world.time += h;
        self.world.step += 1;
        self.totals += self.ctx.stats;
    }

    /// Bodies were moved other than by [`Simulation::step`]: the next step
    /// rebuilds whatever relied on bounds of their motion (the contact
    /// effect's neighbour list).
    pub fn forget_motion(&mut self) {
        self.motion_unknown = true;
    }

    /// Kinetic plus the potential energy the effects store.
    pub fn total_energy(&self) -> f64 {
        self.world.kinetic_energy()
            + self
                .effects
                .iter()
                .map(|e| e.potential_energy(&self.world, &self.ctx))
                .sum::<f64>()
    }

    /// Contacts of the last force evaluation, per body.
    pub fn contact_counts(&self) -> Vec<u32> {
        let mut c = vec![0u32; self.world.bodies.len()];
        for k in &self.ctx.contacts {
            c[k.a] += 1;
            c[k.b] += 1;
        }
        c
    }

    /// Statistics of the last step.
    pub fn last_stats(&self) -> StepStats {
        self.ctx.stats
    }
}
