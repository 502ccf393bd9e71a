//! What travels between ranks, as typed MPI records.

use dem::body::Body;
use dem::contact::{Contact, FeatureKey, FeatureKind};
use glam::{DQuat, DVec3};
use mpi::traits::Equivalence;

/// A body's motion: what a ghost copy needs each step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct Motion {
    pub x: [f64; 3],
    pub q: [f64; 4],
    pub v: [f64; 3],
    pub l: [f64; 3],
}

impl Motion {
    pub fn of(b: &Body) -> Motion {
        Motion {
            x: b.x.to_array(),
            q: b.q.to_array(),
            v: b.v.to_array(),
            l: b.l.to_array(),
        }
    }

    pub fn state(&self) -> dem::checkpoint::BodyState {
        dem::checkpoint::BodyState {
            x: DVec3::from_array(self.x),
            q: DQuat::from_array(self.q),
            v: DVec3::from_array(self.v),
            l: DVec3::from_array(self.l),
        }
    }

    /// Sets `b`'s motion to this one, to the bit.
    pub fn put(&self, b: &mut Body) {
        b.x = DVec3::from_array(self.x);
        b.q = DQuat::from_array(self.q);
        b.v = DVec3::from_array(self.v);
        b.l = DVec3::from_array(self.l);
    }
}

/// A body moving to a new owner: its motion and the force and torque of the
/// last evaluation (the next half kick needs them).
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct BodyRecord {
    pub id: u64,
    pub motion: Motion,
    pub force: [f64; 3],
    pub torque: [f64; 3],
}

/// One row of the friction effect's state (a contact's name and its
/// tangential displacement; `FrictionEffect::values`).
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct HistoryRow {
    pub row: [f64; 8],
}

impl HistoryRow {
    /// The row's body pair.
    pub fn pair(&self) -> (usize, usize) {
        (self.row[0] as usize, self.row[1] as usize)
    }

    /// The order of the rows in the state: by body pair, then feature key.
    pub fn key(&self) -> [u64; 5] {
        [0, 1, 2, 3, 4].map(|k| self.row[k] as u64)
    }
}

/// A body and the rank that owns it.
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct Ownership {
    pub body: u64,
    pub rank: u64,
}

/// A contact as rank 0 gathers it for output, with its position in the
/// contact order (body pair, then index within the pair).
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct ContactRecord {
    pub a: u64,
    pub b: u64,
    pub index: u64,
    pub key: [u32; 3],
    pub point: [f64; 3],
    pub normal: [f64; 3],
    pub depth: f64,
    pub weight: f64,
    /// The force on body a (normal and tangential).
    pub force: [f64; 3],
}

impl ContactRecord {
    pub fn new(c: &Contact, index: usize, force: DVec3) -> ContactRecord {
        ContactRecord {
            a: c.a as u64,
            b: c.b as u64,
            index: index as u64,
            key: [c.key.kind as u32, c.key.on_a, c.key.on_b],
            point: c.point.to_array(),
            normal: c.normal.to_array(),
            depth: c.depth,
            weight: c.weight,
            force: force.to_array(),
        }
    }

    pub fn order(&self) -> (u64, u64, u64) {
        (self.a, self.b, self.index)
    }

    /// The contact (without its weight's gradient, which output does not show).
    pub fn contact(&self) -> Contact {
        Contact {
            a: self.a as usize,
            b: self.b as usize,
            key: FeatureKey {
                kind: FeatureKind::from_index(self.key[0] as u8).expect("a kind sent as such"),
                on_a: self.key[1],
                on_b: self.key[2],
            },
            point: DVec3::from_array(self.point),
            normal: DVec3::from_array(self.normal),
            depth: self.depth,
            weight: self.weight,
            gradient: Default::default(),
        }
    }
}
