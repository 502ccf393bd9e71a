//! Forces on bodies whose terms are computed on more than one rank.
//!
//! One process sums each body's force term by term: effect by effect in
//! pipeline order, within an effect the body terms first, then one term per
//! contact in contact order (by the two bodies' ids, then the contact's place
//! within its pair). Split across ranks, a contact is computed once, on the
//! rank owning its lower particle, so the terms on a particle near a cut are
//! computed partly on its own rank and partly on others. Such particles are
//! *logged* (`dem::effects::Forces::log_bodies`): their terms, wherever
//! computed, are keyed by [`key`] and summed in key order once all have
//! arrived ([`sum_logged`]) — the sum one process computes, to the bit.

use crate::records::{TermKey, TermRecord};
use dem::contact::Contact;
use dem::effects::{ForceTerm, Forces};
use dem::world::World;

/// Each contact's place within its body pair (contacts come grouped by pair).
pub fn places_in_pairs(contacts: &[Contact]) -> Vec<u32> {
    let mut out = Vec::with_capacity(contacts.len());
    let mut at = 0;
    for (k, c) in contacts.iter().enumerate() {
        if k > 0 && (contacts[k - 1].a, contacts[k - 1].b) != (c.a, c.b) {
            at = 0;
        }
        out.push(at);
        at += 1;
    }
    out
}

/// Where `t` falls in its body's sum: [effect, 0, 0, 0, 0] for a term on
/// the body as a whole, [effect, 1, id a, id b, place] for a term at a contact.
pub fn key(t: &ForceTerm, world: &World, contacts: &[Contact], places: &[u32]) -> TermKey {
    let effect = u64::from(t.effect);
    if t.contact == ForceTerm::BODY {
        return [effect, 0, 0, 0, 0];
    }
    let k = t.contact as usize;
    let c = &contacts[k];
    [
        effect,
        1,
        u64::from(world.id(c.a)),
        u64::from(world.id(c.b)),
        u64::from(places[k]),
    ]
}

/// Sums the terms of each logged body in key order into `forces`: `terms`
/// holds (body index, key, term), from this rank (in the order it added
/// them) and from others, in any order. The sort is stable: terms of equal
/// key (several body terms of one effect) keep this rank's order.
pub fn sum_logged(forces: &mut Forces, mut terms: Vec<(usize, TermKey, ForceTerm)>) {
    terms.sort_by_key(|t| (t.0, t.1));
    for group in terms.chunk_by(|x, y| x.0 == y.0) {
        forces.sum_terms(group[0].0, group.iter().map(|t| t.2));
    }
}

/// The received terms, by the index of the body they act on (`index_of` an
/// id; a term for a body this rank does not own is an error).
pub fn arrived(
    records: &[TermRecord],
    index_of: impl Fn(u32) -> Option<usize>,
) -> Result<Vec<(usize, TermKey, ForceTerm)>, String> {
    records
        .iter()
        .map(|r| {
            let id = r.body as u32;
            let i = index_of(id)
                .ok_or_else(|| format!("a force term arrived for body {id}, not owned here"))?;
            Ok((i, r.key, r.term()))
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use dem::effects::PairForce;
    use glam::DVec3;

    /// Terms that each round differently when added in a different order.
    fn f(x: f64) -> DVec3 {
        DVec3::new(x, x * 1e-17, 1.0 / x)
    }

    /// The logged sum of terms split between "ranks" and shuffled is the
    /// running sum one process computes in pipeline and contact order.
    #[test]
    fn logged_terms_sum_to_one_process_bits_in_any_arrival_order() {
        // Body 1's terms: gravity (effect 0), three contacts of the contact
        // effect (1) and of friction (2), damping (3, with a torque).
        let mut one = Forces::default();
        one.reset(3);
        let mut logged = Forces::default();
        logged.reset(3);
        logged.log_bodies(&[false, true, false]);
        let pairs = [
            PairForce {
                a: 0,
                b: 1,
                force: f(0.1),
                torque_a: f(0.2),
                torque_b: f(3.0),
            },
            PairForce {
                a: 1,
                b: 2,
                force: f(1e8),
                torque_a: f(0.3),
                torque_b: f(7.0),
            },
            PairForce {
                a: 1,
                b: 2,
                force: f(-1e8),
                torque_a: f(1e-9),
                torque_b: f(1.0),
            },
        ];
        for forces in [&mut one, &mut logged] {
            forces.begin_effect(0);
            forces.add(1, f(9.81));
            for effect in [1, 2] {
                forces.begin_effect(effect);
                for (k, p) in pairs.iter().enumerate() {
                    forces.add_pair(k, p);
                }
            }
            forces.begin_effect(3);
            forces.add_with_torque(1, f(-0.5), f(0.25));
        }
        // Contacts: (0,1) with one contact, (1,2) with two.
        let ids: Vec<u32> = vec![10, 20, 30];
        let world = World {
            ids,
            ..World::default()
        };
        let contact = |a, b| Contact {
            a,
            b,
            key: dem::contact::FeatureKey {
                kind: dem::contact::FeatureKind::CornerFace,
                on_a: 0,
                on_b: 0,
            },
            point: DVec3::ZERO,
            normal: DVec3::Z,
            depth: 0.0,
            weight: 1.0,
            gradient: Default::default(),
        };
        let contacts = [contact(0, 1), contact(1, 2), contact(1, 2)];
        let places = places_in_pairs(&contacts);
        assert_eq!(places, vec![0, 0, 1]);
        let mut terms: Vec<_> = logged
            .log()
            .iter()
            .map(|&t| (t.body as usize, key(&t, &world, &contacts, &places), t))
            .collect();
        assert_eq!(terms.len(), 8, "every term of body 1 logged");
        // As if the contact terms had come from another rank, reversed.
        terms.reverse();
        let (body, contact_terms): (Vec<_>, Vec<_>) = terms
            .into_iter()
            .partition(|t| t.2.contact == ForceTerm::BODY);
        let mut shuffled = contact_terms;
        shuffled.extend(body);
        sum_logged(&mut logged, shuffled);
        let bits = |v: DVec3| v.to_array().map(f64::to_bits);
        assert_eq!(bits(logged.force(1)), bits(one.force(1)));
        assert_eq!(bits(logged.torque(1)), bits(one.torque(1)));
        // Summed in another order, the bits differ: the order is what matters.
        let mut plain = DVec3::ZERO;
        for x in [f(-0.5), -f(1e8), -f(-1e8), -f(0.1), f(9.81)] {
            plain += x;
        }
        for x in [-f(1e8), -f(-1e8), -f(0.1)] {
            plain += x;
        }
        assert_ne!(bits(plain), bits(one.force(1)), "a test that can fail");
        // The unlogged bodies summed as they went.
        assert_eq!(bits(logged.force(0)), bits(one.force(0)));
    }

    #[test]
    fn a_term_for_a_body_not_held_is_refused() {
        let r = TermRecord {
            body: 5,
            ..TermRecord::default()
        };
        let why = arrived(&[r], |_| None).unwrap_err();
        assert!(why.contains("body 5"), "{why}");
    }
}
