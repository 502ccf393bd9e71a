//! What an output step shows, as plain data: the bodies, the contacts with
//! their forces, and the energy books. One process and a run split across
//! ranks build the same [`Frame`] (the latter gathered on one rank), and the
//! output writes it, so the two cannot write different things.

use crate::checkpoint::BodyState;
use crate::effects::Books;
use crate::ledger::ExactSum;
use glam::DVec3;

/// One output step.
#[derive(Debug, Clone, PartialEq)]
pub struct Frame {
    pub time: f64,
    pub step: u64,
    /// Every body's state, by id (obstacles included).
    pub bodies: Vec<BodyState>,
    /// The contacts, in contact order (by body pair, then within the pair).
    pub contacts: Vec<FrameContact>,
    pub energies: Energies,
}

/// A contact as the output shows it; forces act on body a (b takes the
/// opposite).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct FrameContact {
    /// The bodies' ids, a < b.
    pub a: u32,
    pub b: u32,
    pub point: DVec3,
    /// Unit normal, from b to a.
    pub normal: DVec3,
    /// Overlap of the rounded surfaces (m).
    pub depth: f64,
    /// The normal and the tangential (friction) force on a.
    pub normal_force: DVec3,
    pub tangential_force: DVec3,
    /// Whether the friction slides (its force held at μ times the normal
    /// force); false without friction.
    pub slides: bool,
}

impl FrameContact {
    /// The whole force on body a.
    pub fn force(&self) -> DVec3 {
        self.normal_force + self.tangential_force
    }
}

impl Frame {
    /// Contacts per body.
    pub fn contact_counts(&self) -> Vec<u32> {
        let mut c = vec![0u32; self.bodies.len()];
        for k in &self.contacts {
            c[k.a as usize] += 1;
            c[k.b as usize] += 1;
        }
        c
    }
}

/// Where a run's energy is (J).
#[derive(Debug, Clone, PartialEq)]
pub struct Energies {
    /// Kinetic energy of the particles' translation and rotation.
    pub translation: f64,
    pub rotation: f64,
    /// Per effect, in pipeline order: what it stores now (gravity's
    /// potential, the springs) and what it has dissipated since the start.
    pub effects: Vec<EffectEnergy>,
    /// What the effects measure (the probes), named, in pipeline order.
    pub measures: Vec<(String, f64)>,
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

/// [`Energies`] before rounding: exact sums over some of the bodies and
/// contacts, which merge across ranks into the whole run's, to the bit.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EnergyBooks {
    pub translation: ExactSum,
    pub rotation: ExactSum,
    pub effects: Vec<(&'static str, Books)>,
    pub measures: Vec<(String, ExactSum)>,
}

impl EnergyBooks {
    /// Adds another share of the same run's books (the same effects).
    pub fn merge(&mut self, o: &EnergyBooks) {
        self.translation.merge(&o.translation);
        self.rotation.merge(&o.rotation);
        for ((_, mine), (_, theirs)) in self.effects.iter_mut().zip(&o.effects) {
            mine.merge(theirs);
        }
        for ((_, mine), (_, theirs)) in self.measures.iter_mut().zip(&o.measures) {
            mine.merge(theirs);
        }
    }

    /// The books as plain numbers: the parts of each sum, each prefixed by
    /// its count (see [`EnergyBooks::from_numbers`]).
    pub fn numbers(&self) -> Vec<f64> {
        let mut out = Vec::new();
        let mut put = |s: &ExactSum| {
            let parts = s.parts();
            out.push(parts.len() as f64);
            out.extend(parts);
        };
        put(&self.translation);
        put(&self.rotation);
        for (_, b) in &self.effects {
            put(&b.stored);
            put(&b.dissipated);
        }
        self.measures.iter().for_each(|(_, s)| put(s));
        out
    }

    /// Books of `self`'s effects from [`EnergyBooks::numbers`] of a process
    /// with the same effects.
    pub fn from_numbers(&self, numbers: &[f64]) -> EnergyBooks {
        let mut at = 0;
        let mut take = || {
            let n = numbers[at] as usize;
            let s = ExactSum::from_parts(&numbers[at + 1..at + 1 + n]);
            at += 1 + n;
            s
        };
        let translation = take();
        let rotation = take();
        let effects = self
            .effects
            .iter()
            .map(|(name, _)| {
                let stored = take();
                let dissipated = take();
                (*name, Books { stored, dissipated })
            })
            .collect();
        let measures = self
            .measures
            .iter()
            .map(|(name, _)| (name.clone(), take()))
            .collect();
        EnergyBooks {
            translation,
            rotation,
            effects,
            measures,
        }
    }

    /// The energies, each sum rounded once.
    pub fn rounded(&self) -> Energies {
        Energies {
            translation: self.translation.value(),
            rotation: self.rotation.value(),
            effects: self
                .effects
                .iter()
                .map(|(effect, b)| EffectEnergy {
                    effect,
                    stored: b.stored.value(),
                    dissipated: b.dissipated.value(),
                })
                .collect(),
            measures: self
                .measures
                .iter()
                .map(|(name, s)| (name.clone(), s.value()))
                .collect(),
        }
    }
}
