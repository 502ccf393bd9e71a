//! The step pipeline: scene -> world -> effects -> integration.

use crate::checkpoint::{BodyState, Checkpoint, CheckpointError, EffectState};
use crate::effects::{Effect, Forces, RotationParams, StepContext, StepStats};
use crate::integrate::{drift, half_kick, travel_bound};
use crate::scene::Scene;
use crate::timing::{seconds_since, SectionTimes};
use crate::world::World;
use glam::DVec3;
use rayon::prelude::*;
use std::time::Instant;

/// Bodies per parallel task of the integration.
const INTEGRATION_GRAIN: usize = 32;

/// Bodies per parallel task of the closing half kick: a few additions per
/// body, so a scene of fewer bodies keeps it on one thread (cheaper than
/// handing half to another).
const KICK_GRAIN: usize = 1024;

/// Where a run's energy is (J).
#[derive(Debug, Clone, PartialEq)]
pub struct Energies {
    /// Kinetic energy of the particles' translation and rotation.
    pub translation: f64,
    pub rotation: f64,
    /// Per effect, in pipeline order: what it stores now (gravity's
    /// potential, the springs) and what it has dissipated since the start.
    pub effects: Vec<EffectEnergy>,
}

#[derive(Debug, Clone, PartialEq)]
pub struct EffectEnergy {
    pub effect: &'static str,
    pub stored: f64,
    pub dissipated: f64,
}

impl Energies {
    /// Kinetic plus stored plus dissipated: constant up to the integrator's
    /// error when the effects' books are right.
    pub fn total(&self) -> f64 {
        let effects: f64 = self.effects.iter().map(|e| e.stored + e.dissipated).sum();
        self.translation + self.rotation + effects
    }
}

/// A simulation taken apart ([`Simulation::into_parts`]), for a caller that
/// steps it in its own way (split across ranks).
pub struct Parts {
    pub world: World,
    pub dt: f64,
    pub rotation: bool,
    /// The declared effects, in pipeline order.
    pub effects: Vec<Box<dyn Effect>>,
    /// Per shape: the largest distance of a vertex from the body's origin.
    pub shape_radius: Vec<f64>,
    /// The forces of the last evaluation.
    pub forces: Forces,
}

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
    /// Builds the pipeline from exactly the effects the scene declares, and
    /// evaluates the forces of the scene's initial state.
    pub fn new(scene: &Scene) -> Simulation {
        let mut sim = Simulation::pipeline(scene);
        sim.evaluate_forces();
        // Time counts from the first step.
        sim.timings = SectionTimes::for_effects(&sim.effects);
        sim
    }

    /// Goes on from `checkpoint`, taken of a run of `scene` by
    /// [`Simulation::checkpoint`]: the steps that follow give what the run
    /// would have given had it not stopped, bit for bit. The effects and
    /// their parameters are the scene's; refused when the checkpoint's bodies,
    /// time step or effects' states do not fit it.
    pub fn resume(scene: &Scene, checkpoint: &Checkpoint) -> Result<Simulation, CheckpointError> {
        let fail = |why: String| Err(CheckpointError(why));
        let mut sim = Simulation::pipeline(scene);
        let n = sim.world.bodies.len();
        if checkpoint.fingerprint != sim.world.fingerprint() {
            return fail(
                "the checkpoint was taken of another scene (materials, shapes, bodies or obstacles differ)"
                    .into(),
            );
        }
        if checkpoint.dt.to_bits() != scene.dt.to_bits() {
            return fail(format!(
                "the checkpoint's run stepped by dt = {:e} s, the scene by {:e} s",
                checkpoint.dt, scene.dt
            ));
        }
        let counts = [
            checkpoint.bodies.len(),
            checkpoint.force.len(),
            checkpoint.torque.len(),
        ];
        if counts != [n; 3] {
            return fail(format!(
                "the scene has {n} bodies, the checkpoint {} bodies, {} forces and {} torques",
                counts[0], counts[1], counts[2]
            ));
        }
        let finite = |s: &BodyState| {
            s.x.is_finite() && s.q.is_finite() && s.v.is_finite() && s.l.is_finite()
        };
        if let Some(i) = checkpoint.bodies.iter().position(|s| !finite(s)) {
            return fail(format!("body {i}'s state in the checkpoint is not finite"));
        }
        let loads = checkpoint.force.iter().zip(&checkpoint.torque);
        if let Some(i) = loads
            .clone()
            .position(|(f, t)| !f.is_finite() || !t.is_finite())
        {
            return fail(format!(
                "the force on body {i} in the checkpoint is not finite"
            ));
        }
        if !(checkpoint.time.is_finite()) {
            return fail(format!(
                "the checkpoint's time {} is not finite",
                checkpoint.time
            ));
        }
        for (b, s) in sim.world.bodies.iter_mut().zip(&checkpoint.bodies) {
            (b.x, b.q, b.v, b.l) = (s.x, s.q, s.v, s.l);
        }
        sim.world.time = checkpoint.time;
        sim.world.step = checkpoint.step;
        sim.forces.force.clone_from(&checkpoint.force);
        sim.forces.torque.clone_from(&checkpoint.torque);
        let mut states = checkpoint.effects.iter();
        for e in &mut sim.effects {
            if e.state().is_none() {
                continue;
            }
            let Some(state) = states.next().filter(|s| s.effect == e.name()) else {
                return fail(format!(
                    "the scene declares the {} effect, whose state the checkpoint lacks",
                    e.name()
                ));
            };
            e.restore(&state.values, &sim.world)
                .map_err(CheckpointError)?;
        }
        if let Some(extra) = states.next() {
            return fail(format!(
                "the checkpoint holds the state of the {} effect, which the scene does not declare (or not in this order)",
                extra.effect
            ));
        }
        // Neighbour lists and caches are rebuilt from the restored bodies.
        sim.forget_motion();
        Ok(sim)
    }

    /// The state [`Simulation::resume`] goes on from.
    pub fn checkpoint(&self) -> Checkpoint {
        let effects = self.effects.iter().filter_map(|e| {
            let values = e.state()?;
            Some(EffectState {
                effect: e.name().to_string(),
                values,
            })
        });
        Checkpoint {
            time: self.world.time,
            step: self.world.step,
            dt: self.dt,
            fingerprint: self.world.fingerprint(),
            bodies: self.world.bodies.iter().map(BodyState::of).collect(),
            // Obstacles do not move: what pushes on them is no part of the
            // state (and split across ranks, no one rank sums it).
            force: self.loads(&self.forces.force),
            torque: self.loads(&self.forces.torque),
            effects: effects.collect(),
        }
    }

    /// Per body, `of` for particles and zero for obstacles.
    fn loads(&self, of: &[DVec3]) -> Vec<DVec3> {
        let bodies = self.world.bodies.iter();
        of.iter()
            .zip(bodies)
            .map(|(f, b)| if b.is_static() { DVec3::ZERO } else { *f })
            .collect()
    }

    /// The effects the scene declares, on the scene's world; forces not yet evaluated.
    fn pipeline(scene: &Scene) -> Simulation {
        let world = scene.world.clone();
        let effects: Vec<Box<dyn Effect>> = scene
            .effects
            .iter()
            .filter_map(|e| e.build(scene))
            .collect();
        let shape_radius = world
            .shapes
            .iter()
            .map(|m| m.vertices.iter().map(|v| v.length()).fold(0.0, f64::max))
            .collect();
        let mut sim = Simulation {
            world,
            dt: scene.dt,
            rotation: scene.effects.has::<RotationParams>(),
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
        sim.timings = SectionTimes::for_effects(&sim.effects);
        sim
    }

    /// The simulation's parts: its world, effects (with their state) and
    /// the forces of its last evaluation.
    pub fn into_parts(self) -> Parts {
        Parts {
            world: self.world,
            dt: self.dt,
            rotation: self.rotation,
            effects: self.effects,
            shape_radius: self.shape_radius,
            forces: self.forces,
        }
    }

    /// Makes `contacts`, with the force on body a of each, the last
    /// evaluation's (for output of a run stepped elsewhere, whose state this
    /// simulation was resumed from).
    pub fn show_contacts(&mut self, contacts: Vec<crate::contact::Contact>, forces: Vec<DVec3>) {
        assert_eq!(contacts.len(), forces.len(), "a force per contact");
        self.ctx.contacts = contacts;
        self.ctx.contact_force = forces;
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
            if let Some(ledger) = e.ledger_mut() {
                ledger.close();
            }
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

    /// Where the run's energy is: kinetic, stored by each effect, and
    /// dissipated by each effect since the start.
    pub fn energies(&self) -> Energies {
        let (mut translation, mut rotation) = (0.0, 0.0);
        for b in self.world.bodies.iter().filter(|b| !b.is_static()) {
            translation += 0.5 * b.mass * b.v.length_squared();
            rotation += 0.5 * b.l.dot(b.omega());
        }
        let effects = self.effects.iter().map(|e| EffectEnergy {
            effect: e.name(),
            stored: e.potential_energy(&self.world, &self.ctx),
            dissipated: e.dissipated(),
        });
        Energies {
            translation,
            rotation,
            effects: effects.collect(),
        }
    }

    /// Each contact of the last force evaluation: its point and the force
    /// on its body a (normal and tangential; b takes the opposite).
    pub fn contact_forces(&self) -> impl Iterator<Item = (&crate::contact::Contact, DVec3)> {
        self.ctx
            .contacts
            .iter()
            .zip(&self.ctx.contact_force)
            .map(|(c, f)| (c, *f))
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

    /// The contacts of the last force evaluation.
    pub fn contacts(&self) -> &[crate::contact::Contact] {
        &self.ctx.contacts
    }

    /// Statistics of the last step.
    pub fn last_stats(&self) -> StepStats {
        self.ctx.stats
    }

    /// Body pairs whose surfaces cross in the last force evaluation (a
    /// contact deeper than the two halos), each with its deepest crossing
    /// (m), in pair order: overlapping bodies at the start, or a contact
    /// that failed to hold the bodies apart.
    pub fn crossed_pairs(&self) -> Vec<(usize, usize, f64)> {
        let halo = |i: usize| {
            let b = &self.world.bodies[i];
            self.world.materials[b.material].halo.unwrap_or(0.0)
        };
        let mut out: Vec<(usize, usize, f64)> = Vec::new();
        for c in &self.ctx.contacts {
            let over = c.depth - (halo(c.a) + halo(c.b));
            if over <= 0.0 {
                continue;
            }
            match out.last_mut() {
                Some(last) if (last.0, last.1) == (c.a, c.b) => last.2 = last.2.max(over),
                _ => out.push((c.a, c.b, over)),
            }
        }
        out
    }
}
