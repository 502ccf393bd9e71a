//! The step pipeline: scene -> world -> effects -> integration.

use crate::body::Body;
use crate::checkpoint::{BodyState, Checkpoint, CheckpointError, CheckpointShare, EffectState};
use crate::effects::{
    book_entries, insert_due, Alone, Effect, Forces, Setting, StepContext, StepStats,
};
use crate::frame::{EnergyBooks, Frame, FrameContact};
use crate::integrate::{drift_many, half_kick, travel_bound};
use crate::scene::Scene;
use crate::timing::{seconds_since, SectionTimes};
use crate::world::World;
use glam::{DQuat, DVec3};
use rayon::prelude::*;
use std::time::Instant;

pub use crate::frame::{EffectEnergy, Energies};

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
    /// Whether every body's state was finite at the end of the last step.
    finite: bool,
    /// See [`Simulation::deep_steps_in_a_row`].
    deep_steps: u64,
}

/// A state gone non-finite: the step that made it, and its time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NonFinite {
    pub step: u64,
    pub time: f64,
}

impl std::fmt::Display for NonFinite {
    fn fmt(&self, f: &mut std::fmt::Formatter) -> std::fmt::Result {
        write!(
            f,
            "the simulation became non-finite at step {} (t = {:e} s): the time step is too \
             large for this scene, or its input holds a non-finite value",
            self.step, self.time
        )
    }
}

impl Simulation {
    /// Builds the pipeline from exactly the effects the scene declares, and
    /// evaluates the forces of the scene's initial state.
    pub fn new(scene: &Scene) -> Simulation {
        let mut sim = Simulation::pipeline(scene);
        sim.evaluate_forces();
        // Time counts from the first step.
        sim.timings = section_times(&sim.effects);
        sim
    }

    /// Goes on from `checkpoint`, taken of a run of `scene` by
    /// [`Simulation::checkpoint`]: the steps that follow give what the run
    /// would have given had it not stopped, bit for bit. The effects and
    /// their parameters are the scene's; refused when the checkpoint's bodies,
    /// time step or effects' states do not fit it.
    pub fn resume(scene: &Scene, checkpoint: &Checkpoint) -> Result<Simulation, CheckpointError> {
        check_checkpoint(scene, checkpoint)?;
        let mut sim = Simulation::pipeline(scene);
        let n = sim.world.bodies.len();
        sim.forces.reset(n);
        for (b, s) in sim.world.bodies.iter_mut().zip(&checkpoint.bodies) {
            (b.x, b.q, b.v, b.l) = (s.x, s.q, s.v, s.l);
            (b.removed, b.pending) = (s.removed, s.pending);
            // A driven wall's pose is the time's (the same bits), and its
            // angular velocity too, which the checkpoint does not hold.
            b.follow_drive(checkpoint.time);
        }
        sim.world.time = checkpoint.time;
        sim.world.step = checkpoint.step;
        for (i, (f, t)) in checkpoint.force.iter().zip(&checkpoint.torque).enumerate() {
            sim.forces.set(i, *f, *t);
        }
        let particles = (0..n)
            .filter(|&i| !sim.world.bodies[i].is_static())
            .collect();
        split_out(&sim.world, particles, &mut sim.ctx);
        restore_effects(&mut sim.effects, &checkpoint.effects, n)?;
        // Neighbour lists and caches are rebuilt from the restored bodies.
        sim.forget_motion();
        Ok(sim)
    }

    /// The state [`Simulation::resume`] goes on from.
    pub fn checkpoint(&self) -> Checkpoint {
        let (force, torque) = self.forces.all();
        Checkpoint {
            time: self.world.time,
            step: self.world.step,
            dt: self.dt,
            fingerprint: self.world.fingerprint(),
            bodies: self.world.bodies.iter().map(BodyState::of).collect(),
            // Obstacles do not move: what pushes on them is no part of the
            // state (and split across ranks, no one rank sums it).
            force: self.loads(force),
            torque: self.loads(torque),
            effects: effect_states(&self.effects),
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
        let effects = build_effects(scene);
        let shape_radius = shape_radii(&world);
        let mut sim = Simulation {
            world,
            dt: scene.dt,
            rotation: scene.effects.rotate(),
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
            finite: true,
            deep_steps: 0,
        };
        let particles = (0..scene.world.bodies.len())
            .filter(|&i| !scene.world.bodies[i].is_static())
            .collect();
        split_out(&sim.world, particles, &mut sim.ctx);
        sim.timings = section_times(&sim.effects);
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

    /// Whether an effect takes particles out of the run (an outflow): the
    /// scene then says where particles leave, and one below every obstacle
    /// may be on its way there.
    pub fn removes_particles(&self) -> bool {
        self.effects.iter().any(|e| e.removes_particles())
    }

    fn evaluate_forces(&mut self) {
        self.forces.reset(self.world.bodies.len());
        self.ctx.stats = StepStats::default();
        self.ctx.detection_times = Default::default();
        // Indexed, not zipped: a timing list out of step with the effects must
        // fail loudly, never skip an effect.
        for (k, e) in self.effects.iter_mut().enumerate() {
            let start = Instant::now();
            self.forces.begin_effect(k);
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
        let ((force, torque), radius) = (self.forces.all(), &self.shape_radius);
        // Driven obstacles go where their drive puts them at the step's end.
        let t_next = self.world.time + h;
        // The largest distance any point of a body moved: the max of exact
        // per-body bounds, the same on any thread count.
        let moved = self
            .world
            .bodies
            .par_chunks_mut(INTEGRATION_GRAIN)
            .enumerate()
            .map(|(c, chunk)| {
                let base = c * INTEGRATION_GRAIN;
                // On the stack: a chunk is small, and a heap list per chunk
                // cost about half as much as the drift of its bodies.
                let mut ids = [0; INTEGRATION_GRAIN];
                let mut before = [(DVec3::ZERO, DQuat::IDENTITY); INTEGRATION_GRAIN];
                let mut n = 0;
                for (k, b) in chunk.iter_mut().enumerate().filter(|(_, b)| !b.is_out()) {
                    half_kick(b, force[base + k], torque[base + k], h, rot);
                    (ids[n], before[n]) = (k, (b.x, b.q));
                    n += 1;
                }
                drift_many(chunk, &ids[..n], h, rot);
                let bound = |(&k, &before): (&usize, _)| {
                    let b: &mut Body = &mut chunk[k];
                    b.follow_drive(t_next);
                    travel_bound(before, b, radius[b.shape])
                };
                ids[..n]
                    .iter()
                    .zip(&before[..n])
                    .map(bound)
                    .fold(0.0, f64::max)
            })
            .reduce(|| 0.0, f64::max);
        self.ctx.moved = (!std::mem::take(&mut self.motion_unknown)).then_some(moved);
        let end = (t_next, self.world.step + 1);
        if insert_due(
            &mut self.world,
            &mut self.ctx,
            &mut self.effects,
            end,
            &mut Alone,
        ) > 0
        {
            // The inserted particles jumped to their places.
            self.ctx.moved = None;
        }
        self.timings.integration += seconds_since(start);
        self.evaluate_forces();
        let start = Instant::now();
        let (force, torque) = self.forces.all();
        // The step's state is checked where the kick touches it last.
        self.finite = self
            .world
            .bodies
            .par_iter_mut()
            .enumerate()
            .with_min_len(KICK_GRAIN)
            .map(|(i, b)| {
                if !b.is_out() {
                    half_kick(b, force[i], torque[i], h, rot);
                }
                b.is_finite()
            })
            .reduce(|| true, |a, b| a && b);
        book_entries(&self.world, &mut self.effects);
        take_out(&mut self.world, &mut self.ctx, &self.effects);
        self.timings.integration += seconds_since(start);
        self.world.time += h;
        self.world.step += 1;
        self.totals += self.ctx.stats;
        self.deep_steps = match self.ctx.stats.detection.deep_contacts {
            0 => 0,
            _ => self.deep_steps + 1,
        };
    }

    /// Checks the state the last step reached: an error when a body's state
    /// is no longer finite (the step is too large for the scene, or the
    /// input held a non-finite value).
    pub fn check(&self) -> Result<(), NonFinite> {
        match self.finite {
            true => Ok(()),
            false => Err(NonFinite {
                step: self.world.step,
                time: self.world.time,
            }),
        }
    }

    /// Steps in a row, up to the last, that found a contact deeper than the
    /// halos (a contact that stays crossed is not holding its bodies apart).
    pub fn deep_steps_in_a_row(&self) -> u64 {
        self.deep_steps
    }

    /// Bodies were moved other than by [`Simulation::step`]: the next step
    /// rebuilds whatever relied on bounds of their motion (the contact
    /// effect's neighbour list).
    pub fn forget_motion(&mut self) {
        self.motion_unknown = true;
    }

    /// Kinetic plus the energy the effects store.
    pub fn total_energy(&self) -> f64 {
        let e = self.energies();
        e.translation + e.rotation + e.effects.iter().map(|x| x.stored).sum::<f64>()
    }

    /// Where the run's energy is: kinetic, stored by each effect, and
    /// dissipated by each effect since the start.
    pub fn energies(&self) -> Energies {
        energy_books(&self.world, &self.ctx, &self.effects).rounded()
    }

    /// The present value of the measure `name` of an effect (a probe's
    /// count, mass or momentum), if the pipeline has one of that name.
    pub fn measure(&self, name: &str) -> Option<f64> {
        let measures = self.energies().measures;
        measures.into_iter().find(|(n, _)| n == name).map(|m| m.1)
    }

    /// The present state as the output shows it.
    pub fn frame(&self) -> Frame {
        let world = &self.world;
        Frame {
            time: world.time,
            step: world.step,
            bodies: world.bodies.iter().map(BodyState::of).collect(),
            contacts: frame_contacts(world, &self.ctx),
            energies: self.energies(),
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

/// The effects' states for a checkpoint: those that keep books or history.
pub fn effect_states(effects: &[Box<dyn Effect>]) -> Vec<EffectState> {
    effects
        .iter()
        .filter(|e| e.ledger().is_some() || e.history().is_some())
        .map(|e| {
            let (stored, taken) = e.ledger().map(|l| l.state()).unwrap_or_default();
            EffectState {
                effect: e.name().to_string(),
                stored,
                taken,
                row: e.history().map_or(0, |h| h.row_len()),
                history: e.history().map(|h| h.rows()).unwrap_or_default(),
            }
        })
        .collect()
}

/// Restores `effects` from a checkpoint's states of a scene of `bodies`
/// bodies: each stateful effect in pipeline order, refused when a state is
/// missing, extra or does not fit.
pub fn restore_effects(
    effects: &mut [Box<dyn Effect>],
    states: &[EffectState],
    bodies: usize,
) -> Result<(), CheckpointError> {
    let fail = |why: String| Err(CheckpointError(why));
    let mut states = states.iter();
    for e in effects.iter_mut() {
        if e.ledger().is_none() && e.history().is_none() {
            continue;
        }
        let Some(state) = states.next().filter(|s| s.effect == e.name()) else {
            return fail(format!(
                "the scene declares the {} effect, whose state the checkpoint lacks",
                e.name()
            ));
        };
        let name = e.name();
        let within = |why: String| CheckpointError(format!("the {name} effect's state: {why}"));
        match e.ledger_mut() {
            Some(l) => l.restore(&state.stored, &state.taken).map_err(within)?,
            None if state.stored.is_empty() && state.taken.is_empty() => {}
            None => return fail(format!("the {name} effect keeps no books")),
        }
        match e.history_mut() {
            Some(h) if state.row == h.row_len() => {
                h.take_rows(&mut |_, _| true);
                h.add_rows(&state.history, bodies).map_err(within)?;
            }
            Some(h) => {
                return fail(format!(
                    "the {name} effect's history has rows of {} numbers, the checkpoint's {}",
                    h.row_len(),
                    state.row
                ))
            }
            None if state.history.is_empty() => {}
            None => return fail(format!("the {name} effect keeps no history")),
        }
    }
    if let Some(extra) = states.next() {
        return fail(format!(
            "the checkpoint holds the state of the {} effect, which the scene does not declare (or not in this order)",
            extra.effect
        ));
    }
    Ok(())
}

/// At a step's end, takes out of the run the particles of `ctx.bodies`
/// that an effect removes (an outflow), moving them to `ctx.removed`
/// (nothing to do, and no loop, when no effect removes particles).
pub fn take_out(world: &mut World, ctx: &mut StepContext, effects: &[Box<dyn Effect>]) {
    if !effects.iter().any(|e| e.removes_particles()) {
        return;
    }
    let mut left = Vec::new();
    ctx.bodies.retain(|&i| {
        let b = &mut world.bodies[i];
        b.removed = effects.iter().any(|e| e.removes(b));
        if b.removed {
            left.push(i);
        }
        !b.removed
    });
    if !left.is_empty() {
        ctx.removed.extend(left);
        ctx.removed.sort_unstable();
    }
}

/// `particles` split into `ctx.bodies`, those in the run, `ctx.removed`,
/// those an outflow took out, and `ctx.pending`, those waiting to be
/// inserted (each in the order given).
pub fn split_out(world: &World, particles: Vec<usize>, ctx: &mut StepContext) {
    let (out, bodies): (Vec<usize>, Vec<usize>) =
        (particles.into_iter()).partition(|&i| world.bodies[i].is_out());
    ctx.bodies = bodies;
    (ctx.removed, ctx.pending) = out.into_iter().partition(|&i| world.bodies[i].removed);
}

/// The energy books of `ctx.bodies` and of the effects' share of the
/// contacts: exact sums, merged across ranks before they are rounded.
pub fn energy_books(world: &World, ctx: &StepContext, effects: &[Box<dyn Effect>]) -> EnergyBooks {
    let mut books = EnergyBooks::default();
    for &i in &ctx.bodies {
        let b = &world.bodies[i];
        books.translation.add(0.5 * b.mass * b.v.length_squared());
        books.rotation.add(0.5 * b.l.dot(b.omega()));
    }
    books.effects = effects
        .iter()
        .map(|e| (e.name(), e.books(world, ctx)))
        .collect();
    books.measures = effects
        .iter()
        .flat_map(|e| e.measures(world, ctx))
        .collect();
    books
}

/// The contacts of the last evaluation as the output shows them (bodies by id).
pub fn frame_contacts(world: &World, ctx: &StepContext) -> Vec<FrameContact> {
    let force = |pairs: &[crate::effects::PairForce], k: usize| {
        pairs.get(k).map_or(DVec3::ZERO, |p| p.force)
    };
    ctx.contacts
        .iter()
        .enumerate()
        .map(|(k, c)| FrameContact {
            a: world.id(c.a),
            b: world.id(c.b),
            point: c.point,
            normal: c.normal,
            depth: c.depth,
            normal_force: force(&ctx.normal_pairs, k),
            tangential_force: force(&ctx.tangential_pairs, k),
            slides: ctx.sliding.get(k).copied().unwrap_or(false),
        })
        .collect()
}

/// Whether `checkpoint` was taken of a run of `scene` and holds a state to go
/// on from: the same scene (fingerprint), time step and bodies, every number
/// finite. The effects' states are checked as they are restored.
pub fn check_checkpoint(scene: &Scene, checkpoint: &Checkpoint) -> Result<(), CheckpointError> {
    let c = checkpoint;
    let counts = [c.bodies.len(), c.force.len(), c.torque.len()];
    check_run(scene, c.fingerprint, c.dt, c.time, counts)?;
    let held = c.bodies.iter().zip(&c.force).zip(&c.torque);
    check_finite(held.enumerate().map(|(i, ((s, f), t))| (i, s, f, t)))
}

/// [`check_checkpoint`] of the share of a checkpoint one rank holds: the
/// whole run's header and counts, the finite numbers of its own bodies.
pub fn check_share(scene: &Scene, share: &CheckpointShare) -> Result<(), CheckpointError> {
    check_run(scene, share.fingerprint, share.dt, share.time, share.counts)?;
    check_finite(share.held())
}

/// The run a checkpoint continues: `scene`'s, stepped by its `dt`, with one
/// state, force and torque per body (`counts`).
fn check_run(
    scene: &Scene,
    fingerprint: u64,
    dt: f64,
    time: f64,
    counts: [usize; 3],
) -> Result<(), CheckpointError> {
    let fail = |why: String| Err(CheckpointError(why));
    let n = scene.census.bodies();
    if fingerprint != scene.fingerprint() {
        return fail(
            "the checkpoint was taken of another scene (materials, shapes, bodies or obstacles differ)"
                .into(),
        );
    }
    if dt.to_bits() != scene.dt.to_bits() {
        return fail(format!(
            "the checkpoint's run stepped by dt = {dt:e} s, the scene by {:e} s",
            scene.dt
        ));
    }
    if counts != [n; 3] {
        return fail(format!(
            "the scene has {n} bodies, the checkpoint {} bodies, {} forces and {} torques",
            counts[0], counts[1], counts[2]
        ));
    }
    if !time.is_finite() {
        return fail(format!("the checkpoint's time {time} is not finite"));
    }
    Ok(())
}

/// Every body's state and load finite, by id: the first that is not named.
fn check_finite<'a>(
    held: impl Iterator<Item = (usize, &'a BodyState, &'a DVec3, &'a DVec3)>,
) -> Result<(), CheckpointError> {
    let finite =
        |s: &BodyState| s.x.is_finite() && s.q.is_finite() && s.v.is_finite() && s.l.is_finite();
    for (i, s, f, t) in held {
        if !finite(s) {
            return Err(CheckpointError(format!(
                "body {i}'s state in the checkpoint is not finite"
            )));
        }
        if !f.is_finite() || !t.is_finite() {
            return Err(CheckpointError(format!(
                "the force on body {i} in the checkpoint is not finite"
            )));
        }
    }
    Ok(())
}

/// The effects `scene` declares, in pipeline order, with no state yet.
pub fn build_effects(scene: &Scene) -> Vec<Box<dyn Effect>> {
    let setting = Setting {
        world: &scene.world,
        kernel: scene.kernel,
        effects: &scene.effects,
    };
    scene
        .effects
        .iter()
        .filter_map(|e| e.build(&setting))
        .collect()
}

/// Zero time for each effect of the pipeline `effects`.
fn section_times(effects: &[Box<dyn Effect>]) -> SectionTimes {
    SectionTimes {
        effects: effects.iter().map(|e| (e.name(), 0.0)).collect(),
        detecting_effect: effects
            .iter()
            .find(|e| e.detects_contacts())
            .map(|e| e.name()),
        ..SectionTimes::default()
    }
}

/// Per shape: the largest distance of a vertex from the body's origin.
pub fn shape_radii(world: &World) -> Vec<f64> {
    world.shape_radii()
}
