//! Coulomb friction with a tangential spring and history, one per body pair.
//!
//! A body pair in contact carries an elastic tangential displacement ξ at the
//! depth-weighted centre c of its contact points, with the depth-weighted mean
//! normal n. Every step ξ is turned into the current tangent plane and grows by
//! v_t dt (v_t: tangential relative velocity at c); the force is F_t = −k_t ξ
//! − c_t v_t with k_t = (2/7) k, the usual ratio for a linear spring model,
//! and c_t = 2 ζ √(m* k_t) damped like the normal spring (ζ from the
//! restitution), so that a resting contact does not ring. When
//! |F_t| > μ F_n (F_n: the pair's total normal force) the pair slides: F_t is
//! cut to μ F_n and ξ set to match it, ξ = −(F_t + c_t v_t)/k_t. Keeping the history per pair, not per
//! triangle pair, makes static friction hold on flat contacts, whose contact
//! points the triangle kernel places anywhere on the shared face. A pair that
//! separates forgets its history.

use super::{Effect, Forces, PairForce, StepContext, FORCE_GRAIN};
use crate::contact::Contact;
use crate::material::MaterialPairs;
use crate::world::World;
use glam::DVec3;
use rayon::prelude::*;
use std::ops::Range;

pub struct FrictionEffect {
    laws: MaterialPairs,
    /// ξ per body pair in contact at the last step, sorted by pair, as the
    /// contacts come: looked up by one merge-walk per step, no hashing.
    history: Vec<((usize, usize), DVec3)>,
    next: Vec<((usize, usize), DVec3)>,
    /// This step's pairs in contact: their contacts and carried displacement.
    pairs: Vec<(Range<usize>, DVec3)>,
    results: Vec<Option<(PairForce, DVec3)>>,
}

impl FrictionEffect {
    pub fn new(world: &World) -> Self {
        FrictionEffect {
            laws: MaterialPairs::new(&world.materials),
            history: Vec::new(),
            next: Vec::new(),
            pairs: Vec::new(),
            results: Vec::new(),
        }
    }
}

impl Effect for FrictionEffect {
    fn name(&self) -> &'static str {
        "friction"
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        // Body pairs in contact, each with the displacement it carried from
        // the last step: one walk along both lists, both sorted by pair.
        // Contacts come grouped by body pair, pairs in increasing order (`body_contacts`).
        self.pairs.clear();
        let mut old = self.history.iter().peekable();
        let mut start = 0;
        for group in ctx.contacts.chunk_by(|x, y| (x.a, x.b) == (y.a, y.b)) {
            let key = (group[0].a, group[0].b);
            while old.next_if(|h| h.0 < key).is_some() {}
            let xi = old.next_if(|h| h.0 == key).map_or(DVec3::ZERO, |h| h.1);
            self.pairs.push((start..start + group.len(), xi));
            start += group.len();
        }
        let (laws, dt) = (&self.laws, ctx.dt);
        let (contacts, normal_force) = (&ctx.contacts, &ctx.normal_force);
        self.results.clear();
        self.pairs
            .par_iter()
            .with_min_len(FORCE_GRAIN)
            .map(|(range, xi)| {
                pair_friction(
                    world,
                    laws,
                    &contacts[range.clone()],
                    &normal_force[range.clone()],
                    *xi,
                    dt,
                )
            })
            .collect_into_vec(&mut self.results);
        self.next.clear();
        for (force, xi) in self.results.iter().flatten() {
            forces.add_pair(force);
            self.next.push(((force.a, force.b), *xi));
            ctx.stats.tangential_evaluations += 1;
        }
        std::mem::swap(&mut self.history, &mut self.next);
    }

    /// The tangential springs: per body pair in contact, a, b and ξ.
    fn state(&self) -> Option<Vec<f64>> {
        let entry =
            |&((a, b), xi): &((usize, usize), DVec3)| [a as f64, b as f64, xi.x, xi.y, xi.z];
        Some(self.history.iter().flat_map(entry).collect())
    }

    fn restore(&mut self, values: &[f64], world: &World) -> Result<(), String> {
        if !values.len().is_multiple_of(5) {
            return Err(format!(
                "the friction effect's state holds 5 numbers per body pair (a, b, ξ), got {}",
                values.len()
            ));
        }
        let n = world.bodies.len();
        let index = |v: f64| (v >= 0.0 && v.fract() == 0.0 && v < n as f64).then_some(v as usize);
        self.history.clear();
        for (k, e) in values.chunks_exact(5).enumerate() {
            let xi = DVec3::new(e[2], e[3], e[4]);
            let pair = index(e[0]).zip(index(e[1]));
            match pair {
                Some((a, b))
                    if a < b
                        && xi.is_finite()
                        && self.history.last().is_none_or(|last| last.0 < (a, b)) =>
                {
                    self.history.push(((a, b), xi))
                }
                _ => {
                    return Err(format!(
                        "friction state, body pair {k}: {e:?} is not a pair of bodies a < b \
                         (of {n}), in increasing order, with a finite displacement"
                    ))
                }
            }
        }
        Ok(())
    }
}

/// The friction force of one body pair in contact, from its contacts, their
/// normal forces and the displacement `xi` it carried, with the displacement
/// it carries on; `None` when the contacts give no normal (no depth).
fn pair_friction(
    world: &World,
    laws: &MaterialPairs,
    contacts: &[Contact],
    normal_force: &[f64],
    mut xi: DVec3,
    dt: f64,
) -> Option<(PairForce, DVec3)> {
    let (a, b) = (contacts[0].a, contacts[0].b);
    let (mut c, mut n, mut w, mut f_n) = (DVec3::ZERO, DVec3::ZERO, 0.0, 0.0);
    for (k, f) in contacts.iter().zip(normal_force) {
        c += k.point * k.depth;
        n += k.normal * k.depth;
        w += k.depth;
        f_n += f;
    }
    let n = n.try_normalize()?;
    if w <= 0.0 {
        return None;
    }
    let c = c / w;
    let (ba, bb) = (&world.bodies[a], &world.bodies[b]);
    let v_rel = ba.velocity_at(c) - bb.velocity_at(c);
    let v_t = v_rel - n * v_rel.dot(n);
    // Turn the stored displacement into the current tangent plane, keeping its length.
    let len = xi.length();
    xi -= n * xi.dot(n);
    if let Some(dir) = xi.try_normalize() {
        xi = dir * len;
    }
    xi += v_t * dt;
    let law = laws.get(ba.material, bb.material);
    let k_t = (2.0 / 7.0) * law.stiffness;
    let mu = law.friction;
    let m = 1.0 / (ba.inv_mass + bb.inv_mass);
    let c_t = 2.0 * law.damping_ratio * (m * k_t).sqrt();
    let mut f_t = -xi * k_t - v_t * c_t;
    let cap = mu * f_n;
    let mag = f_t.length();
    if mag > cap {
        f_t *= if mag > 0.0 { cap / mag } else { 0.0 };
        xi = -(f_t + v_t * c_t) / k_t;
    }
    Some((PairForce::new(a, ba.x, b, bb.x, c, f_t), xi))
}
