//! Normal contact: a linear spring per contact, a dashpot per body pair.
//!
//! **Springs.** Each contact i of a body pair (a corner on a face, a corner
//! on a crease or a corner, creases crossing: see `contact::features`) has a
//! depth δ_i > 0 (the overlap of the rounded surfaces), a unit normal n_i and
//! a point p_i. Its spring stores E_i = k δ_i²/2, with k the pair's
//! stiffness (the two materials' springs in series), and pushes with
//! F_i = k δ_i n_i through p_i. The gradient of δ_i with respect to the two
//! poses is exactly n_i acting through p_i, so F_i is minus the gradient of
//! E_i; and a contact appears and leaves with δ_i = 0. The springs therefore
//! conserve energy: what an elastic impact returns does not depend on the
//! step, the mesh or where the kernel found closest points.
//!
//! **Dashpot.** Damping only has to dissipate, and it is chosen so that a
//! pair rebounds with restitution e whether it touches at one corner, along
//! an edge (two corners) or face to face (the corners of the overlap). The
//! pair's n contacts act together as one spring of stiffness K = n k; its
//! dashpot is c = 2 ζ √(m K), ζ = −ln e / √(π² + ln² e), which gives
//! restitution e exactly for a linear spring-dashpot of mass m. Here m is the
//! pair's effective mass along the depth-weighted mean normal n̄ at the
//! depth-weighted centre p̄ of its contacts,
//!   1/m = 1/m_a + 1/m_b + (r_a × n̄)·I_a⁻¹(r_a × n̄) + (r_b × n̄)·I_b⁻¹(r_b × n̄)
//! (r from each centre of mass to p̄; the rotational terms only with the
//! rotation effect), so that a corner hitting off-centre, which turns the
//! body, is damped for the mass it actually moves. Each contact takes an
//! equal share, c_i = c/n, and its normal force is
//!   F_i = k δ_i − c_i v_n,i
//! (v_n,i the normal approach speed at p_i). It may pull at the very end of
//! an impact, as in the linear model whose restitution is exact; friction is
//! told 0 then.

use super::{
    Books, Declare, Effect, Forces, MaterialParam, PairForce, Setting, StepContext, FORCE_GRAIN,
};
use crate::body::Body;
use crate::contact::{Contact, Culling, Detector};
use crate::distance::Options;
use crate::ledger::Ledger;
use crate::material::MaterialPairs;
use crate::mesh::Features;
use crate::world::World;
use glam::DVec3;
use rayon::prelude::*;
use serde::Deserialize;
use std::ops::Range;

/// `contact = {}`, or `contact = { skin = 1e-3 }` to keep a neighbour list
/// (m; 0: the broad phase runs every step); `culling = "boxes"` examines
/// every triangle pair near the other body's box instead of first testing
/// the bodies' hulls ([`Culling`]; the same contacts, for comparison).
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ContactParams {
    #[serde(default)]
    pub skin: f64,
    #[serde(default, deserialize_with = "crate::names::by_name")]
    pub culling: Culling,
}

fn positive(x: f64) -> bool {
    x.is_finite() && x > 0.0
}

impl Declare for ContactParams {
    const NAME: &'static str = "contact";
    const MATERIAL_PARAMS: &'static [MaterialParam] = &[
        MaterialParam {
            name: "stiffness",
            get: |m| m.stiffness,
            must_be: "a positive finite number (N/m)",
            accepts: positive,
        },
        MaterialParam {
            name: "restitution",
            get: |m| m.restitution,
            must_be: "in (0, 1]",
            accepts: |e| e > 0.0 && e <= 1.0,
        },
        MaterialParam {
            name: "halo",
            get: |m| m.halo,
            must_be: "a positive finite number (m)",
            accepts: positive,
        },
    ];
    fn check(&self) -> Result<(), String> {
        match self.skin.is_finite() && self.skin >= 0.0 {
            true => Ok(()),
            false => Err(format!(
                "skin must be a finite length >= 0 (m), got {}",
                self.skin
            )),
        }
    }
    fn build(&self, setting: &Setting) -> Option<Box<dyn Effect>> {
        let rotation = setting.effects.rotate();
        Some(Box::new(ContactEffect::new(
            setting.world,
            setting.kernel,
            Detector::with_skin(self.skin).with_culling(self.culling),
            rotation,
        )))
    }
}

/// The contact effect: detection, then the [`NormalLaw`].
pub struct ContactEffect {
    detector: Detector,
    pub kernel: Options,
    /// Per shape: its faces, creases and corners.
    features: Vec<Features>,
    /// Per body: halo.
    halo: Vec<f64>,
    pub law: NormalLaw,
}

impl ContactEffect {
    pub fn new(world: &World, kernel: Options, detector: Detector, rotation: bool) -> Self {
        ContactEffect {
            detector,
            kernel,
            features: world.shapes.iter().map(Features::of).collect(),
            halo: world.per_body(|m| m.halo),
            law: NormalLaw::new(world, rotation),
        }
    }
}

/// The normal forces of given contacts (see the module doc), with the
/// energy books of its springs and dashpots.
pub struct NormalLaw {
    laws: MaterialPairs,
    /// Whether bodies turn: the dashpot's effective mass counts inertia then.
    rotation: bool,
    /// The springs' energy at the last evaluation, and the work the
    /// dashpots have taken out of the bodies since the start.
    pub ledger: Ledger,
    /// Per body pair in contact: its contacts.
    pairs: Vec<Range<usize>>,
    /// Per contact: the force pair, the normal force, the spring energy and
    /// the dashpot's power.
    per_contact: Vec<(PairForce, f64, f64, f64)>,
}

impl NormalLaw {
    pub fn new(world: &World, rotation: bool) -> NormalLaw {
        NormalLaw {
            laws: MaterialPairs::new(&world.materials),
            rotation,
            ledger: Ledger::default(),
            pairs: Vec::new(),
            per_contact: Vec::new(),
        }
    }

    /// The normal force of each of `ctx.contacts` (grouped by body pair, all
    /// of each pair's contacts present) into `ctx.normal_pairs`, its
    /// magnitude into `ctx.normal_force` and `ctx.contact_force`.
    pub fn apply(&mut self, world: &World, ctx: &mut StepContext) {
        pair_ranges(&ctx.contacts, &mut self.pairs);
        let (laws, rotation, contacts) = (&self.laws, self.rotation, &ctx.contacts);
        self.per_contact.clear();
        self.per_contact.resize(contacts.len(), Default::default());
        // Each body pair writes its own contacts' slots.
        let mut slots = Vec::with_capacity(self.pairs.len());
        let mut rest = self.per_contact.as_mut_slice();
        for r in &self.pairs {
            let (head, tail) = rest.split_at_mut(r.len());
            slots.push((r.clone(), head));
            rest = tail;
        }
        slots
            .into_par_iter()
            .with_min_len(FORCE_GRAIN)
            .for_each(|(range, out)| {
                pair_forces(world, laws, rotation, &contacts[range], out);
            });
        ctx.normal_force.clear();
        ctx.contact_force.clear();
        ctx.normal_pairs.clear();
        self.ledger.begin();
        for (pair, normal_force, energy, power) in &self.per_contact {
            ctx.normal_pairs.push(*pair);
            ctx.normal_force.push(*normal_force);
            ctx.contact_force.push(pair.force);
            self.ledger.store(*energy);
            self.ledger.take(power * ctx.dt);
        }
        ctx.stats.normal_evaluations += ctx.contacts.len() as u64;
    }

    /// The springs' energy and the dashpots' work so far.
    pub fn books(&self) -> Books {
        Books {
            stored: self.ledger.stored().clone(),
            dissipated: self.ledger.taken().clone(),
        }
    }
}

/// The body pairs of `contacts` (grouped by pair, as detection returns them).
pub(crate) fn pair_ranges(contacts: &[Contact], out: &mut Vec<Range<usize>>) {
    out.clear();
    let mut start = 0;
    for group in contacts.chunk_by(|x, y| (x.a, x.b) == (y.a, y.b)) {
        out.push(start..start + group.len());
        start += group.len();
    }
}

/// 1/m for body `b` pushed along `n` at arm `r` from its centre of mass.
fn inverse_mass_along(b: &Body, r: DVec3, n: DVec3, rotation: bool) -> f64 {
    if b.is_static() {
        return 0.0;
    }
    let turn = if rotation {
        let rn = r.cross(n);
        let local = b.q.inverse() * rn;
        rn.dot(b.q * (b.inv_inertia_body * local))
    } else {
        0.0
    };
    b.inv_mass + turn
}

/// The effective mass of a body pair along the depth-weighted mean normal at
/// the depth-weighted centre of its contacts.
pub(crate) fn pair_mass(world: &World, contacts: &[Contact], rotation: bool) -> f64 {
    let (mut centre, mut normal, mut weight) = (DVec3::ZERO, DVec3::ZERO, 0.0);
    for c in contacts {
        let w = c.depth * c.weight;
        centre += c.point * w;
        normal += c.normal * w;
        weight += w;
    }
    let centre = if weight > 0.0 {
        centre / weight
    } else {
        contacts[0].point
    };
    let n = normal.try_normalize().unwrap_or(contacts[0].normal);
    let (ba, bb) = (&world.bodies[contacts[0].a], &world.bodies[contacts[0].b]);
    let inverse = inverse_mass_along(ba, centre - ba.x, n, rotation)
        + inverse_mass_along(bb, centre - bb.x, n, rotation);
    1.0 / inverse
}

impl Effect for ContactEffect {
    fn name(&self) -> &'static str {
        ContactParams::NAME
    }

    fn detects_contacts(&self) -> bool {
        true
    }

    fn apply(&mut self, world: &World, ctx: &mut StepContext, forces: &mut Forces) {
        if !ctx.contacts_found {
            let det = self.detector.detect_moved(
                world,
                &self.features,
                &self.halo,
                &self.kernel,
                ctx.moved,
                &mut ctx.contacts,
            );
            ctx.stats.detection = det;
            ctx.detection_times = self.detector.last_times();
        }
        self.law.apply(world, ctx);
        for (k, pair) in ctx.normal_pairs.iter().enumerate() {
            forces.add_pair(k, pair);
        }
    }

    fn books(&self, _world: &World, _ctx: &StepContext) -> Books {
        self.law.books()
    }

    fn ledger(&self) -> Option<&Ledger> {
        Some(&self.law.ledger)
    }

    fn ledger_mut(&mut self) -> Option<&mut Ledger> {
        Some(&mut self.law.ledger)
    }
}

/// The normal forces of one body pair's contacts (see the module doc).
fn pair_forces(
    world: &World,
    laws: &MaterialPairs,
    rotation: bool,
    contacts: &[Contact],
    out: &mut [(PairForce, f64, f64, f64)],
) {
    let (a, b) = (contacts[0].a, contacts[0].b);
    let (ba, bb) = (&world.bodies[a], &world.bodies[b]);
    let law = laws.get(ba.material, bb.material);
    let k = law.stiffness;
    let weights: f64 = contacts.iter().map(|c| c.weight).sum();
    let m = pair_mass(world, contacts, rotation);
    let damping = if weights > 0.0 {
        2.0 * law.damping_ratio * (m * weights * k).sqrt() / weights
    } else {
        0.0
    };
    for (c, slot) in contacts.iter().zip(out) {
        let v_n = (ba.velocity_at(c.point) - bb.velocity_at(c.point)).dot(c.normal);
        let (spring, dashpot) = (k * c.weight, damping * c.weight);
        let f = spring * c.depth - dashpot * v_n;
        let mut pair = PairForce::new(a, ba.x, b, bb.x, c.point, c.normal * f);
        // The spring's energy k w δ²/2 also changes with the weight w.
        let g = c.gradient;
        let half = -0.5 * k * c.depth * c.depth;
        pair.force += g.force_a * half;
        pair.torque_a += g.torque_a * half;
        pair.torque_b += g.torque_b * half;
        *slot = (
            pair,
            f.max(0.0),
            0.5 * spring * c.depth * c.depth,
            dashpot * v_n * v_n,
        );
    }
}
