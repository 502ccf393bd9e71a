//! Coulomb friction with a tangential spring per contact.
//!
//! Each contact (named by its body pair and features, see
//! `contact::features`) carries an elastic tangential displacement ξ from
//! step to step. Every step ξ is turned into the contact's current tangent
//! plane, keeping its length, and grows by v_t dt (v_t: the tangential
//! relative velocity at the contact point). The force is
//!   F_t = −k_t ξ − c_t v_t,  k_t = (2/7) k,
//! the usual ratio for linear springs, with a dashpot shared over the pair's
//! n contacts like the normal one, c_t = 2 ζ √(m* n k_t) / n (m* the pair's
//! reduced mass), so that a resting contact does not ring. When
//! |F_t| > μ F_n,i (the contact's own normal force) the contact slides: F_t
//! is cut to μ F_n,i and ξ set to match it, ξ = −(F_t + c_t v_t)/k_t.
//!
//! Contacts at distinct points of a pair (a face resting on a face touches at
//! the corners of the overlap) resist both sliding and twisting about the
//! normal; a single point does not resist twisting, as a point contact
//! should not. A contact whose name changes while its corner stays in touch
//! (a corner sliding off a face onto a crease) keeps its displacement; a
//! contact that ends forgets it.
//!
//! Work: the tangential forces' work on the bodies is counted each step;
//! what the springs do not hold has been dissipated by sliding and damping.

use super::contact::pair_ranges;
use super::{
    Books, ContactHistory, Declare, Effect, Forces, MaterialParam, PairForce, Setting, StepContext,
    FORCE_GRAIN,
};
use crate::contact::{Contact, FeatureKey, FeatureKind};
use crate::ledger::Ledger;
use crate::material::MaterialPairs;
use crate::world::World;
use glam::DVec3;
use rayon::prelude::*;
use serde::Deserialize;
use std::ops::Range;

/// `friction = {}`: the coefficients are the materials'.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct FrictionParams {}

impl Declare for FrictionParams {
    const NAME: &'static str = "friction";
    /// Friction acts at the contacts the contact effect finds, with their
    /// normal forces.
    const NEEDS: &'static [&'static str] = &["contact"];
    const MATERIAL_PARAMS: &'static [MaterialParam] = &[MaterialParam {
        name: "friction",
        get: |m| m.friction,
        must_be: "finite and non-negative",
        accepts: |mu| mu.is_finite() && mu >= 0.0,
    }];
    fn build(&self, setting: &Setting) -> Option<Box<dyn Effect>> {
        Some(Box::new(FrictionEffect::new(setting.world)))
    }
}

/// A contact's name over the whole scene: its bodies' ids (`World::id`)
/// and features. Ids, not indices: a rank's world holds some of the bodies,
/// renumbered as they come and go, and a contact keeps its name throughout.
type Key = (u32, u32, FeatureKey);

pub struct FrictionEffect {
    laws: MaterialPairs,
    /// ξ per contact of the last step, sorted by key, as the contacts come:
    /// looked up by one merge-walk per step, no hashing.
    history: Vec<(Key, DVec3)>,
    next: Vec<(Key, DVec3)>,
    /// This step's body pairs in contact, and their entries in `history`.
    pairs: Vec<Range<usize>>,
    carried: Vec<Range<usize>>,
    /// Per contact: the force pair, the displacement carried on, the
    /// tangential force's power, and whether it slides.
    results: Vec<(PairForce, DVec3, f64, bool)>,
    /// The tangential springs' energy now, and the work the tangential
    /// forces have taken out of the bodies since the start.
    ledger: Ledger,
}

impl FrictionEffect {
    /// Numbers per row of [`ContactHistory::rows`]: a, b, the feature kind
    /// and indices, and ξ.
    pub const ROW: usize = 8;

    pub fn new(world: &World) -> Self {
        FrictionEffect {
            laws: MaterialPairs::new(&world.materials),
            history: Vec::new(),
            next: Vec::new(),
            pairs: Vec::new(),
            carried: Vec::new(),
            results: Vec::new(),
            ledger: Ledger::default(),
        }
    }
}

/// The ratio of tangential to normal stiffness.
const TANGENTIAL_RATIO: f64 = 2.0 / 7.0;

impl Effect for FrictionEffect {
    fn name(&self) -> &'static str {
        FrictionParams::NAME
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        self.tangential(world, ctx);
        for (k, pair) in ctx.tangential_pairs.iter().enumerate() {
            forces.add_pair(k, pair);
        }
    }

    /// The springs' energy; dissipated: the work taken out of the bodies
    /// less what the springs hold.
    fn books(&self, _world: &World, _ctx: &StepContext) -> Books {
        let mut dissipated = self.ledger.taken().clone();
        dissipated.merge(&self.ledger.stored().negated());
        Books {
            stored: self.ledger.stored().clone(),
            dissipated,
        }
    }

    fn ledger(&self) -> Option<&Ledger> {
        Some(&self.ledger)
    }

    fn ledger_mut(&mut self) -> Option<&mut Ledger> {
        Some(&mut self.ledger)
    }

    fn history(&self) -> Option<&dyn ContactHistory> {
        Some(self)
    }

    fn history_mut(&mut self) -> Option<&mut dyn ContactHistory> {
        Some(self)
    }
}

impl FrictionEffect {
    /// The friction force of each of `ctx.contacts` (grouped by body pair,
    /// all of each pair's contacts present, with `ctx.normal_force`) into
    /// `ctx.tangential_pairs`, added to `ctx.contact_force`; the history
    /// goes on with these contacts.
    pub fn tangential(&mut self, world: &World, ctx: &mut StepContext) {
        pair_ranges(&ctx.contacts, &mut self.pairs);
        // Each pair's entries in the history: one walk along both lists,
        // both sorted by body pair.
        self.carried.clear();
        let mut at = 0;
        let id = |i: usize| world.id(i);
        for r in &self.pairs {
            let c = &ctx.contacts[r.start];
            let pair = (id(c.a), id(c.b));
            while at < self.history.len() && (self.history[at].0 .0, self.history[at].0 .1) < pair {
                at += 1;
            }
            let start = at;
            while at < self.history.len() && (self.history[at].0 .0, self.history[at].0 .1) == pair
            {
                at += 1;
            }
            self.carried.push(start..at);
        }
        let (laws, dt, history) = (&self.laws, ctx.dt, &self.history);
        let (contacts, normal_force) = (&ctx.contacts, &ctx.normal_force);
        self.results.clear();
        self.results.resize(contacts.len(), Default::default());
        let mut slots = Vec::with_capacity(self.pairs.len());
        let mut rest = self.results.as_mut_slice();
        for (r, old) in self.pairs.iter().zip(&self.carried) {
            let (head, tail) = rest.split_at_mut(r.len());
            slots.push((r.clone(), &history[old.clone()], head));
            rest = tail;
        }
        slots
            .into_par_iter()
            .with_min_len(FORCE_GRAIN)
            .for_each(|(range, old, out)| {
                let (c, f) = (&contacts[range.clone()], &normal_force[range]);
                pair_friction(world, laws, c, f, old, dt, out);
            });
        self.next.clear();
        ctx.tangential_pairs.clear();
        ctx.sliding.clear();
        self.ledger.begin();
        for (k, (c, (force, xi, power, slides))) in
            ctx.contacts.iter().zip(&self.results).enumerate()
        {
            ctx.tangential_pairs.push(*force);
            ctx.sliding.push(*slides);
            ctx.contact_force[k] += force.force;
            self.next.push(((id(c.a), id(c.b), c.key), *xi));
            let law = self
                .laws
                .get(world.bodies[c.a].material, world.bodies[c.b].material);
            let stored = 0.5 * TANGENTIAL_RATIO * law.stiffness * xi.length_squared();
            self.ledger.store(stored);
            self.ledger.take(-power * dt);
        }
        ctx.stats.tangential_evaluations += ctx.contacts.len() as u64;
        std::mem::swap(&mut self.history, &mut self.next);
    }
}

impl ContactHistory for FrictionEffect {
    fn row_len(&self) -> usize {
        Self::ROW
    }

    fn rows(&self) -> Vec<f64> {
        self.history.iter().flat_map(row_of).collect()
    }

    fn take_rows(&mut self, leaves: &mut dyn FnMut(u32, u32) -> bool) -> Vec<f64> {
        let mut out = Vec::new();
        self.history.retain(|e| {
            let (a, b, _) = e.0;
            let go = leaves(a, b);
            if go {
                out.extend(row_of(e));
            }
            !go
        });
        out
    }

    fn add_rows(&mut self, rows: &[f64], bodies: usize) -> Result<(), String> {
        if !rows.len().is_multiple_of(Self::ROW) {
            return Err(format!(
                "the friction effect's history holds 8 numbers per contact (a, b, feature \
                 kind and indices, ξ), got {} numbers",
                rows.len()
            ));
        }
        let at = self.history.len();
        for (i, row) in rows.chunks_exact(Self::ROW).enumerate() {
            let entry = entry_of(row, bodies).ok_or_else(|| {
                format!(
                    "friction history, contact {i}: {row:?} is not a contact of bodies a < b \
                     (of {bodies}) with a known feature kind and a finite displacement"
                )
            })?;
            self.history.push(entry);
        }
        self.history.sort_unstable_by_key(|e| e.0);
        let twice = self.history.windows(2).position(|w| w[0].0 == w[1].0);
        if let Some(k) = twice {
            let ((a, b, key), _) = self.history[k];
            self.history.truncate(at);
            return Err(format!(
                "friction history: contact {key:?} of bodies {a} and {b} is given twice"
            ));
        }
        Ok(())
    }
}

/// A history entry as a row of plain numbers.
fn row_of(&((a, b, k), xi): &(Key, DVec3)) -> [f64; FrictionEffect::ROW] {
    [
        a as f64,
        b as f64,
        k.kind as u8 as f64,
        k.on_a as f64,
        k.on_b as f64,
        xi.x,
        xi.y,
        xi.z,
    ]
}

/// The entry a row names, if it is one [`row_of`] could have written in a
/// scene of `bodies` bodies.
fn entry_of(e: &[f64], bodies: usize) -> Option<(Key, DVec3)> {
    let index =
        |v: f64, below: u64| (v >= 0.0 && v.fract() == 0.0 && v < below as f64).then_some(v as u32);
    let n = (bodies as u64).min(u32::MAX as u64);
    let xi = DVec3::new(e[5], e[6], e[7]);
    let kind = index(e[2], 256).and_then(|k| FeatureKind::from_index(k as u8))?;
    let (on_a, on_b) = (index(e[3], u32::MAX as u64)?, index(e[4], u32::MAX as u64)?);
    let (a, b) = (index(e[0], n)?, index(e[1], n)?);
    (a < b && xi.is_finite()).then_some(((a, b, FeatureKey { kind, on_a, on_b }), xi))
}

/// The corner a contact hangs on, to carry its displacement over when the
/// feature it touches changes: (side, vertex).
fn anchor(k: &FeatureKey) -> Option<(u8, u32)> {
    match k.kind {
        FeatureKind::CornerFace | FeatureKind::CornerCrease | FeatureKind::CornerCorner => {
            Some((0, k.on_a))
        }
        FeatureKind::FaceCorner | FeatureKind::CreaseCorner => Some((1, k.on_b)),
        FeatureKind::CreaseCrease => None,
    }
}

/// The displacement contact `key` carried from the last step: its own, or
/// that of a contact of the same corner.
fn carried(old: &[(Key, DVec3)], key: &FeatureKey) -> DVec3 {
    if let Ok(i) = old.binary_search_by(|e| e.0 .2.cmp(key)) {
        return old[i].1;
    }
    let Some(corner) = anchor(key) else {
        return DVec3::ZERO;
    };
    old.iter()
        .find(|e| anchor(&e.0 .2) == Some(corner))
        .map_or(DVec3::ZERO, |e| e.1)
}

/// The friction forces of one body pair's contacts, from their normal forces
/// and the pair's entries of the last step's history (see the module doc).
fn pair_friction(
    world: &World,
    laws: &MaterialPairs,
    contacts: &[Contact],
    normal_force: &[f64],
    old: &[(Key, DVec3)],
    dt: f64,
    out: &mut [(PairForce, DVec3, f64, bool)],
) {
    let (a, b) = (contacts[0].a, contacts[0].b);
    let (ba, bb) = (&world.bodies[a], &world.bodies[b]);
    let law = laws.get(ba.material, bb.material);
    let k_t = TANGENTIAL_RATIO * law.stiffness;
    let n = contacts.len() as f64;
    let m = 1.0 / (ba.inv_mass + bb.inv_mass);
    let c_t = 2.0 * law.damping_ratio * (m * n * k_t).sqrt() / n;
    for ((c, &f_n), slot) in contacts.iter().zip(normal_force).zip(out) {
        let v_rel = ba.velocity_at(c.point) - bb.velocity_at(c.point);
        let v_t = v_rel - c.normal * v_rel.dot(c.normal);
        // Turn the carried displacement into the current tangent plane, keeping its length.
        let mut xi = carried(old, &c.key);
        let len = xi.length();
        xi -= c.normal * xi.dot(c.normal);
        if let Some(dir) = xi.try_normalize() {
            xi = dir * len;
        }
        xi += v_t * dt;
        let mut f_t = -xi * k_t - v_t * c_t;
        let cap = law.friction * f_n;
        let mag = f_t.length();
        if mag > cap {
            f_t *= if mag > 0.0 { cap / mag } else { 0.0 };
            xi = -(f_t + v_t * c_t) / k_t;
        }
        let pair = PairForce::new(a, ba.x, b, bb.x, c.point, f_t);
        // Sliding where friction acts at all: a spring in tension holds none.
        let slides = mag > cap && cap > 0.0;
        *slot = (pair, xi, f_t.dot(v_t), slides);
    }
}
