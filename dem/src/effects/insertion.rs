//! Insertion: particles that enter the run during it, in a region, at a
//! rate or all at once (a pour into a hopper, a stream onto a heap).
//!
//! A particle group placed with `placement = { kind = "insert", count,
//! region, rate, start, seed }` declares `count` particles that wait to be
//! inserted ([`Body::pending`](crate::body::Body::pending)): until then they
//! do not move, touch nothing and no effect acts on them. Particle k of the
//! group (k = 0, 1, …) is due at t_k = start + k / rate (all at `start`
//! without a rate). In each step, once the drift has moved the particles
//! to the step's end and before the forces there are evaluated, every
//! particle due by the step's end is tried at [`ATTEMPTS`] random positions
//! in the region, in increasing id. A position is taken when the particle's
//! bounding sphere, grown by its halo, meets no particle in the run (their
//! bounding spheres grown by their halos) and none inserted before it in
//! the same step. A particle that finds no room waits and is tried again at
//! the next step, at new positions.
//!
//! An inserted particle touches nothing, and enters with its group's
//! orientation and velocity, the latter as its half-step velocity: the
//! forces are then evaluated with it in place, and the closing half kick
//! completes its step, so that from its first step on it is integrated as
//! if it had always been there (velocity Verlet needs the force at its
//! position; entered after the evaluation, it would miss half a kick).
//!
//! **The same seed, the same run.** A position is drawn from a counter-based
//! generator, a hash of (seed, the particle's id, the step, the attempt): no
//! generator state runs from step to step, so a checkpoint, which carries
//! the step and which particles still wait, resumes the same draws, and a
//! run split across ranks draws what one process draws.
//!
//! **Split across ranks.** A waiting particle stands at its region's centre,
//! so the partition gives it to the rank that owns that part of the region.
//! On a step where some particle is due, every rank learns every rank's
//! candidates ([`Agree::gather`]), tests them against the particles it owns,
//! and the ranks agree on which are blocked ([`Agree::any`]); each then makes
//! the same choices ([`choose`]), and each owner places its own. The
//! blocking test is a union over ranks of a test per owned particle, so it
//! is what one process finds, to the bit.
//!
//! **Energy.** An inserted particle brings its kinetic energy and gravity's
//! potential −m g·x into the run, as they are at the end of the step it
//! entered in (when it first counts in the books); the effect books them
//! as negative work taken, so that the books' total stays what it was.
//!
//! **Obstacles.** The scene refuses a region that reaches an obstacle (as
//! it stands at the start): the test above is against particles only. A
//! moving wall that enters the region later is not seen by it.

use super::{Books, Declare, Effect, Forces, GravityParams, Setting, StepContext};
use crate::ledger::{ExactSum, Ledger};
use crate::world::World;
use glam::DVec3;
use serde::Deserialize;

/// Random positions tried per due particle and step.
pub const ATTEMPTS: u32 = 4;

/// `insertion = {}`: the particles to insert are the groups placed with
/// `kind = "insert"`, which the scene hands over as [`Stream`]s.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct InsertionParams {
    #[serde(skip)]
    pub streams: Vec<Stream>,
}

/// Where inserted particles enter: a box, or a cylinder from the centre of
/// its base to the centre of its top.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub enum InsertRegion {
    Box {
        lo: [f64; 3],
        hi: [f64; 3],
    },
    Cylinder {
        base: [f64; 3],
        top: [f64; 3],
        radius: f64,
    },
}

/// One group of particles to insert: ids `first..first + count`, all of one
/// shape and material.
#[derive(Debug, Clone, PartialEq)]
pub struct Stream {
    pub first: u32,
    pub count: u32,
    pub shape: usize,
    pub material: usize,
    pub region: InsertRegion,
    /// Particles per second (`None`: all at `start`).
    pub rate: Option<f64>,
    pub start: f64,
    pub seed: u64,
}

impl InsertRegion {
    /// The cause, if the region is not a finite box or cylinder with room.
    pub fn check(&self) -> Result<(), String> {
        let finite = |v: &[f64]| v.iter().all(|c| c.is_finite());
        match self {
            InsertRegion::Box { lo, hi } if !finite(lo) || !finite(hi) => {
                Err("region: lo and hi must be finite".into())
            }
            InsertRegion::Box { lo, hi } if (0..3).any(|k| lo[k] > hi[k]) => {
                Err("region: lo ≤ hi on every axis".into())
            }
            InsertRegion::Cylinder { base, top, radius }
                if !(finite(base) && finite(top) && radius.is_finite() && *radius >= 0.0) =>
            {
                Err("region: base, top and radius must be finite, the radius not negative".into())
            }
            InsertRegion::Cylinder { base, top, .. } if base == top => {
                Err("region: a cylinder's base and top must differ".into())
            }
            _ => Ok(()),
        }
    }

    /// The region's centre: where a particle waits to enter.
    pub fn centre(&self) -> DVec3 {
        match self {
            InsertRegion::Box { lo, hi } => (DVec3::from_array(*lo) + DVec3::from_array(*hi)) / 2.0,
            InsertRegion::Cylinder { base, top, .. } => {
                (DVec3::from_array(*base) + DVec3::from_array(*top)) / 2.0
            }
        }
    }

    /// The smallest box holding the region (a cylinder's end discs reach
    /// r √(1 − e_k²) from their centres along axis k, e its unit axis).
    pub fn bounds(&self) -> (DVec3, DVec3) {
        match self {
            InsertRegion::Box { lo, hi } => (DVec3::from_array(*lo), DVec3::from_array(*hi)),
            InsertRegion::Cylinder { base, top, radius } => {
                let (a, b) = (DVec3::from_array(*base), DVec3::from_array(*top));
                let e = (b - a).normalize();
                let disc = *radius * (DVec3::ONE - e * e).max(DVec3::ZERO).map(f64::sqrt);
                (a.min(b) - disc, a.max(b) + disc)
            }
        }
    }

    /// The point of uniforms `u` (each in [0, 1)) in the region, kept a
    /// distance `r` inside its faces where the region has room for it
    /// (else on its mid-plane across that direction).
    pub fn point(&self, r: f64, u: [f64; 3]) -> DVec3 {
        let within = |lo: f64, hi: f64, u: f64| {
            let room = (hi - lo - 2.0 * r).max(0.0);
            lo + (hi - lo - room) / 2.0 + room * u
        };
        match self {
            InsertRegion::Box { lo, hi } => {
                DVec3::from_array([0, 1, 2].map(|k| within(lo[k], hi[k], u[k])))
            }
            InsertRegion::Cylinder { base, top, radius } => {
                let (a, b) = (DVec3::from_array(*base), DVec3::from_array(*top));
                let axis = (b - a).normalize();
                let (e1, e2) = axis.any_orthonormal_pair();
                let along = within(0.0, (b - a).length(), u[0]);
                let rho = (radius - r).max(0.0) * u[1].sqrt();
                let (s, c) = (std::f64::consts::TAU * u[2]).sin_cos();
                a + axis * along + rho * (c * e1 + s * e2)
            }
        }
    }
}

impl Stream {
    /// When particle `id` of this stream is due.
    fn due(&self, id: u32) -> f64 {
        let k = f64::from(id - self.first);
        match self.rate {
            Some(rate) => self.start + k / rate,
            None => self.start,
        }
    }

    fn holds(&self, id: u32) -> bool {
        (self.first..self.first + self.count).contains(&id)
    }
}

impl Declare for InsertionParams {
    const NAME: &'static str = "insertion";
    fn build(&self, setting: &Setting) -> Option<Box<dyn Effect>> {
        let world = setting.world;
        let g = setting.effects.get::<GravityParams>().map(|p| p.g());
        Some(Box::new(InsertionEffect {
            streams: self.streams.clone(),
            radius: world.shape_radii(),
            halo: (world.materials.iter())
                .map(|m| m.halo.unwrap_or(0.0))
                .collect(),
            g: g.unwrap_or(DVec3::ZERO),
            ledger: Ledger::default(),
            entering: Vec::new(),
        }))
    }
}

/// A position tried for a waiting particle.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Candidate {
    pub id: u32,
    pub attempt: u32,
    pub centre: DVec3,
    /// Its bounding radius grown by its halo.
    pub reach: f64,
}

impl Candidate {
    /// As plain numbers (to send between ranks), and back.
    pub fn to_numbers(self) -> [f64; 6] {
        let [x, y, z] = self.centre.to_array();
        [f64::from(self.id), f64::from(self.attempt), x, y, z, self.reach]
    }

    pub fn from_numbers(n: [f64; 6]) -> Candidate {
        Candidate {
            id: n[0] as u32,
            attempt: n[1] as u32,
            centre: DVec3::new(n[2], n[3], n[4]),
            reach: n[5],
        }
    }

    fn meets(&self, centre: DVec3, reach: f64) -> bool {
        (self.centre - centre).length() < self.reach + reach
    }
}

pub struct InsertionEffect {
    streams: Vec<Stream>,
    /// Per shape, its bounding radius; per material, its halo.
    radius: Vec<f64>,
    halo: Vec<f64>,
    g: DVec3,
    /// Minus the energy the inserted particles brought in, as work taken.
    ledger: Ledger,
    /// The ids of the particles inserted in this step, to book at its end
    /// (by id: split across ranks, a redraw in between renumbers bodies).
    entering: Vec<u32>,
}

impl InsertionEffect {
    fn stream_of(&self, id: u32) -> Option<&Stream> {
        self.streams.iter().find(|s| s.holds(id))
    }

    fn reach_of(&self, world: &World, i: usize) -> f64 {
        let b = &world.bodies[i];
        self.radius[b.shape] + self.halo[b.material]
    }
}

impl Effect for InsertionEffect {
    fn name(&self) -> &'static str {
        InsertionParams::NAME
    }

    fn apply(&mut self, _world: &World, _ctx: &mut StepContext, _forces: &mut Forces) {}

    fn inserts_particles(&self) -> bool {
        true
    }

    /// The positions to try for the waiting particles of `ctx.pending` due
    /// by time `t` (the end of step `step`), in increasing id and attempt.
    fn candidates(&self, world: &World, ctx: &StepContext, t: f64, step: u64) -> Vec<Candidate> {
        let mut out = Vec::new();
        for &i in &ctx.pending {
            let id = world.id(i);
            let Some(s) = self.stream_of(id).filter(|s| s.due(id) <= t) else {
                continue;
            };
            let (r, reach) = (self.radius[s.shape], self.reach_of(world, i));
            for attempt in 0..ATTEMPTS {
                let u = uniforms([s.seed, u64::from(id), step, u64::from(attempt)]);
                out.push(Candidate {
                    id,
                    attempt,
                    centre: s.region.point(r, u),
                    reach,
                });
            }
        }
        out
    }

    /// Per candidate, whether a particle of `ctx.bodies` is in its way.
    fn blocks(&self, world: &World, ctx: &StepContext, candidates: &[Candidate]) -> Vec<bool> {
        let mut blocked = vec![false; candidates.len()];
        let (lo, hi) = (candidates.iter()).fold((DVec3::MAX, DVec3::MIN), |(lo, hi), c| {
            (lo.min(c.centre - c.reach), hi.max(c.centre + c.reach))
        });
        for &i in &ctx.bodies {
            let (x, reach) = (world.bodies[i].x, self.reach_of(world, i));
            if x.cmplt(lo - reach).any() || x.cmpgt(hi + reach).any() {
                continue;
            }
            for (c, b) in candidates.iter().zip(&mut blocked) {
                *b = *b || c.meets(x, reach);
            }
        }
        blocked
    }

    /// Places the particles of `placed` this process holds.
    fn admit(&mut self, world: &mut World, ctx: &mut StepContext, placed: &[Candidate]) {
        let mut entered = Vec::new();
        ctx.pending.retain(|&i| {
            let id = world.id(i);
            let Some(c) = placed.iter().find(|c| c.id == id) else {
                return true;
            };
            let b = &mut world.bodies[i];
            b.x = c.centre;
            b.pending = false;
            entered.push(i);
            false
        });
        if !entered.is_empty() {
            self.entering = entered.iter().map(|&i| world.id(i)).collect();
            ctx.bodies.extend(entered);
            ctx.bodies.sort_unstable();
        }
    }

    /// Books the energy the particles inserted in this step brought.
    fn book_entries(&mut self, world: &World) {
        for id in std::mem::take(&mut self.entering) {
            let i = world.index_of(id).expect("an inserted particle stays where it entered");
            let b = &world.bodies[i];
            let kinetic = 0.5 * b.mass * b.v.length_squared() + 0.5 * b.l.dot(b.omega());
            self.ledger.take(-(kinetic - b.mass * self.g.dot(b.x)));
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

    /// `inserted_count` and `inserted_mass`: the particles inserted so far
    /// (including those an outflow has since taken out).
    fn measures(&self, world: &World, ctx: &StepContext) -> Vec<(String, ExactSum)> {
        let (mut count, mut mass) = (ExactSum::default(), ExactSum::default());
        for &i in ctx.bodies.iter().chain(&ctx.removed) {
            if self.stream_of(world.id(i)).is_some() {
                count.add(1.0);
                mass.add(world.bodies[i].mass);
            }
        }
        vec![
            ("inserted_count".into(), count),
            ("inserted_mass".into(), mass),
        ]
    }
}

/// How the processes of a run share an insertion's decisions.
pub trait Agree {
    /// Every process's candidates, each process's in the order given.
    fn gather(&mut self, mine: &[Candidate]) -> Vec<Candidate>;
    /// Per candidate, whether any process found it blocked.
    fn any(&mut self, mine: &[bool]) -> Vec<bool>;
}

/// One process: nothing to share.
pub struct Alone;

impl Agree for Alone {
    fn gather(&mut self, mine: &[Candidate]) -> Vec<Candidate> {
        mine.to_vec()
    }
    fn any(&mut self, mine: &[bool]) -> Vec<bool> {
        mine.to_vec()
    }
}

/// The candidates taken, from all processes' `candidates` (any order) and
/// whether each is `blocked`: in increasing id, each particle's first
/// attempt that is not blocked and meets no candidate taken before it.
pub fn choose(candidates: &[Candidate], blocked: &[bool]) -> Vec<Candidate> {
    let mut order: Vec<usize> = (0..candidates.len()).collect();
    order.sort_by_key(|&k| (candidates[k].id, candidates[k].attempt));
    let mut taken: Vec<Candidate> = Vec::new();
    for k in order {
        let c = candidates[k];
        let placed = taken.last().is_some_and(|t| t.id == c.id);
        if placed || blocked[k] || taken.iter().any(|t| c.meets(t.centre, t.reach)) {
            continue;
        }
        taken.push(c);
    }
    taken
}

/// Whether an effect has a particle of `ctx.pending` due by time `t`.
pub fn insertion_due(
    world: &World,
    ctx: &StepContext,
    effects: &[Box<dyn Effect>],
    t: f64,
    step: u64,
) -> bool {
    effects.iter().filter(|e| e.inserts_particles()).any(|e| {
        // The first attempt of each is enough to know.
        !e.candidates(world, ctx, t, step).is_empty()
    })
}

/// Inserts the particles due by time `t`, the end of step `step`, where the
/// drift has put the others (see the module doc), sharing the decisions
/// through `agree`; returns how many entered. Every process of a run calls
/// it on the same steps, and [`book_entries`] at the step's end.
pub fn insert_due(
    world: &mut World,
    ctx: &mut StepContext,
    effects: &mut [Box<dyn Effect>],
    (t, step): (f64, u64),
    agree: &mut dyn Agree,
) -> usize {
    let mut entered = 0;
    for e in effects.iter_mut().filter(|e| e.inserts_particles()) {
        let all = agree.gather(&e.candidates(world, ctx, t, step));
        if all.is_empty() {
            continue;
        }
        let blocked = agree.any(&e.blocks(world, ctx, &all));
        let placed = choose(&all, &blocked);
        e.admit(world, ctx, &placed);
        entered += placed.len();
    }
    entered
}

/// At a step's end (after the closing half kick): the effects book the
/// energy the particles inserted in it brought.
pub fn book_entries(world: &World, effects: &mut [Box<dyn Effect>]) {
    for e in effects.iter_mut().filter(|e| e.inserts_particles()) {
        e.book_entries(world);
    }
}

/// Three uniforms in [0, 1) from `key` (SplitMix64's finaliser, chained).
fn uniforms(key: [u64; 4]) -> [f64; 3] {
    let h = key.iter().fold(0x7269_6465_6d5f_696eu64, |h, &k| mix(h ^ mix(k)));
    [1u64, 2, 3].map(|k| (mix(h.wrapping_add(k)) >> 11) as f64 * (1.0 / (1u64 << 53) as f64))
}

fn mix(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn candidate(id: u32, attempt: u32, x: f64) -> Candidate {
        Candidate {
            id,
            attempt,
            centre: DVec3::new(x, 0.0, 0.0),
            reach: 1.0,
        }
    }

    #[test]
    fn each_particle_takes_its_first_free_attempt_clear_of_those_taken_before() {
        // Particle 3's first attempt is blocked; particle 5's first meets
        // particle 3's taken position; in any input order.
        let mut cands = vec![
            candidate(5, 0, 10.5),
            candidate(3, 1, 10.0),
            candidate(3, 0, 0.0),
            candidate(5, 1, 20.0),
            candidate(3, 2, 30.0),
        ];
        let blocked = |c: &[Candidate]| c.iter().map(|c| c.centre.x == 0.0).collect::<Vec<_>>();
        let want = vec![candidate(3, 1, 10.0), candidate(5, 1, 20.0)];
        assert_eq!(choose(&cands, &blocked(&cands)), want);
        cands.reverse();
        assert_eq!(choose(&cands, &blocked(&cands)), want);
    }

    #[test]
    fn positions_fill_the_region_and_keep_the_radius_inside() {
        let cyl = InsertRegion::Cylinder {
            base: [1e6, 0.0, 0.0],
            top: [1e6, 0.0, 2.0],
            radius: 1.0,
        };
        let boxed = InsertRegion::Box {
            lo: [0.0; 3],
            hi: [1.0, 1.0, 0.1],
        };
        let (mut far, mut hi) = (0.0f64, 0.0f64);
        for n in 0..2000u64 {
            let u = uniforms([7, n, 0, 0]);
            assert!(u.iter().all(|&v| (0.0..1.0).contains(&v)));
            let p = cyl.point(0.25, u);
            let rho = (p.x - 1e6).hypot(p.y);
            assert!(rho <= 0.75 * (1.0 + 1e-12) && (0.25..=1.75).contains(&p.z));
            far = far.max(rho);
            let q = boxed.point(0.25, u);
            // Too thin along z for the radius: on its mid-plane.
            assert!((0.25..=0.75).contains(&q.x) && q.z == 0.05);
            hi = hi.max(q.y);
        }
        assert!(far > 0.7 && hi > 0.74, "the draws reach the edges: {far} {hi}");
        assert_ne!(uniforms([1, 2, 3, 4]), uniforms([1, 2, 3, 5]));
    }
}
