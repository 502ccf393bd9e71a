//! What travels between ranks, as typed MPI records.
//!
//! The records of every step (a ghost's [`Motion`], a [`TermRecord`]) travel
//! as their bytes ([`bytes`], [`bytes_mut`], [`from_bytes`]): they are plain
//! data, `#[repr(C)]` with no padding (`bytemuck::Pod`, checked when the
//! crate compiles), so a message is one contiguous block that MPI copies as
//! it is. Sent as MPI struct types, the same messages went through Open
//! MPI's element-by-element packing on both sides, at every step. The ranks
//! of one run share a byte order (MPI does not convert bytes): the same
//! binary on one cluster's nodes.

use bytemuck::{Pod, Zeroable};
use dem::body::Body;
use dem::checkpoint::BodyState;
use dem::effects::ForceTerm;
use dem::frame::FrameContact;
use glam::{DMat3, DQuat, DVec3};
use mpi::traits::Equivalence;

/// The bytes of `records`, to send as one contiguous message.
pub fn bytes<T: Pod>(records: &[T]) -> &[u8] {
    bytemuck::cast_slice(records)
}

/// The bytes of `records`, to receive into.
pub fn bytes_mut<T: Pod>(records: &mut [T]) -> &mut [u8] {
    bytemuck::cast_slice_mut(records)
}

/// The records of a received message, or `None` if its length is not a
/// whole number of them (a message of another kind: a bug).
pub fn from_bytes<T: Pod>(message: &[u8]) -> Option<Vec<T>> {
    message
        .len()
        .is_multiple_of(std::mem::size_of::<T>())
        .then(|| bytemuck::pod_collect_to_vec(message))
}

/// A body's motion: what a ghost copy needs each step.
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence, Pod, Zeroable)]
pub struct Motion {
    pub x: [f64; 3],
    pub q: [f64; 4],
    pub v: [f64; 3],
    pub l: [f64; 3],
    /// Bit 0: an outflow has taken the body out ([`Body::removed`]); bit 1:
    /// it waits to be inserted ([`Body::pending`]).
    pub out: u64,
}

impl Motion {
    pub fn of(b: &Body) -> Motion {
        Motion {
            x: b.x.to_array(),
            q: b.q.to_array(),
            v: b.v.to_array(),
            l: b.l.to_array(),
            out: u64::from(b.removed) | (u64::from(b.pending) << 1),
        }
    }

    pub fn state(&self) -> BodyState {
        BodyState {
            x: DVec3::from_array(self.x),
            q: DQuat::from_array(self.q),
            v: DVec3::from_array(self.v),
            l: DVec3::from_array(self.l),
            removed: self.out & 1 == 1,
            pending: self.out & 2 == 2,
        }
    }

    /// Sets `b`'s motion to this one, to the bit.
    pub fn put(&self, b: &mut Body) {
        b.x = DVec3::from_array(self.x);
        b.q = DQuat::from_array(self.q);
        b.v = DVec3::from_array(self.v);
        b.l = DVec3::from_array(self.l);
        b.removed = self.out & 1 == 1;
        b.pending = self.out & 2 == 2;
    }
}

/// A whole body with its id: what a new ghost, or a particle moving to a new
/// owner, carries. The force and torque are those of the last evaluation
/// (the next half kick needs them; zero for a ghost).
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct BodyRecord {
    pub id: u64,
    pub shape: u64,
    pub material: u64,
    pub motion: Motion,
    pub mass: f64,
    pub inv_mass: f64,
    pub inertia: [f64; 9],
    pub inv_inertia: [f64; 9],
    pub force: [f64; 3],
    pub torque: [f64; 3],
}

impl BodyRecord {
    pub fn of(id: u32, b: &Body, force: DVec3, torque: DVec3) -> BodyRecord {
        BodyRecord {
            id: u64::from(id),
            shape: b.shape as u64,
            material: b.material as u64,
            motion: Motion::of(b),
            mass: b.mass,
            inv_mass: b.inv_mass,
            inertia: b.inertia_body.to_cols_array(),
            inv_inertia: b.inv_inertia_body.to_cols_array(),
            force: force.to_array(),
            torque: torque.to_array(),
        }
    }

    /// The body, to the bit.
    pub fn body(&self) -> Body {
        let mut b = Body {
            shape: self.shape as usize,
            material: self.material as usize,
            x: DVec3::ZERO,
            q: DQuat::IDENTITY,
            v: DVec3::ZERO,
            l: DVec3::ZERO,
            inv_mass: self.inv_mass,
            mass: self.mass,
            inv_inertia_body: DMat3::from_cols_array(&self.inv_inertia),
            inertia_body: DMat3::from_cols_array(&self.inertia),
            drive: None,
            removed: false,
            pending: false,
        };
        self.motion.put(&mut b);
        b
    }
}

/// Where a term falls in the order one process sums a body's force:
/// by effect, then body terms before contact terms, then the contact's body
/// ids and its place within its pair.
pub type TermKey = [u64; 5];

/// One term of the force on a body owned by the receiving rank, computed
/// where the contact it acts at was (see `forces`).
#[repr(C)]
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence, Pod, Zeroable)]
pub struct TermRecord {
    /// The body's id.
    pub body: u64,
    pub key: [u64; 5],
    pub force: [f64; 3],
    pub torque: [f64; 3],
    /// Whether the term touches the torque (see [`ForceTerm::torque`]).
    pub with_torque: u64,
}

impl TermRecord {
    pub fn new(body: u32, key: TermKey, t: &ForceTerm) -> TermRecord {
        TermRecord {
            body: u64::from(body),
            key,
            force: t.force.to_array(),
            torque: t.torque.unwrap_or(DVec3::ZERO).to_array(),
            with_torque: u64::from(t.torque.is_some()),
        }
    }

    /// The term (its body and contact left to the receiver).
    pub fn term(&self) -> ForceTerm {
        ForceTerm {
            body: 0,
            effect: self.key[0] as u32,
            contact: ForceTerm::BODY,
            force: DVec3::from_array(self.force),
            torque: (self.with_torque != 0).then(|| DVec3::from_array(self.torque)),
        }
    }
}

/// A body's state as a checkpoint holds it, with its id: what rank 0
/// gathers for output and checkpoints.
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct StateRecord {
    pub id: u64,
    pub motion: Motion,
    pub force: [f64; 3],
    pub torque: [f64; 3],
}

/// A contact as rank 0 gathers it for output, with its place in the
/// contact order (body pair, then index within the pair).
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct ContactRecord {
    pub a: u64,
    pub b: u64,
    pub index: u64,
    pub point: [f64; 3],
    pub normal: [f64; 3],
    pub depth: f64,
    pub normal_force: [f64; 3],
    pub tangential_force: [f64; 3],
    /// 1: the contact's friction slides.
    pub slides: u64,
}

impl ContactRecord {
    pub fn new(c: &FrameContact, index: usize) -> ContactRecord {
        ContactRecord {
            a: u64::from(c.a),
            b: u64::from(c.b),
            index: index as u64,
            point: c.point.to_array(),
            normal: c.normal.to_array(),
            depth: c.depth,
            normal_force: c.normal_force.to_array(),
            tangential_force: c.tangential_force.to_array(),
            slides: u64::from(c.slides),
        }
    }

    pub fn order(&self) -> (u64, u64, u64) {
        (self.a, self.b, self.index)
    }

    pub fn contact(&self) -> FrameContact {
        FrameContact {
            a: self.a as u32,
            b: self.b as u32,
            point: DVec3::from_array(self.point),
            normal: DVec3::from_array(self.normal),
            depth: self.depth,
            normal_force: DVec3::from_array(self.normal_force),
            tangential_force: DVec3::from_array(self.tangential_force),
            slides: self.slides == 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn records_read_back_from_their_bytes_to_the_bit_and_a_torn_message_is_refused() {
        let motions = [
            Motion {
                x: [0.1, -2.0, 1e-300],
                q: [0.1, 0.2, 0.3, -0.0],
                v: [f64::MIN_POSITIVE, 5e-7, -3.0],
                l: [1e-9, f64::MAX, -4.0],
                out: 2,
            },
            Motion::default(),
        ];
        let sent = bytes(&motions[..]).to_vec();
        assert_eq!(sent.len(), 2 * 112, "13 numbers and the flags, no padding");
        let back: Vec<Motion> = from_bytes(&sent).expect("whole records");
        let bits = |m: &Motion| {
            let mut v: Vec<u64> = [m.x.as_slice(), &m.q, &m.v, &m.l]
                .concat()
                .iter()
                .map(|x| x.to_bits())
                .collect();
            v.push(m.out);
            v
        };
        assert_eq!(
            back.iter().map(bits).collect::<Vec<_>>(),
            motions.iter().map(bits).collect::<Vec<_>>()
        );
        let mut into = [Motion::default(); 2];
        bytes_mut(&mut into[..]).copy_from_slice(&sent);
        assert_eq!(into, motions);
        assert!(from_bytes::<Motion>(&sent[..sent.len() - 8]).is_none());
        assert!(
            from_bytes::<TermRecord>(&sent).is_none(),
            "224 bytes are no whole term records"
        );
        assert_eq!(from_bytes::<TermRecord>(&[]), Some(Vec::new()));
    }

    #[test]
    fn a_body_record_gives_back_the_body_to_the_bit() {
        let b = Body {
            shape: 3,
            material: 1,
            x: DVec3::new(0.1, -2.0, 1e-300),
            q: DQuat::from_xyzw(0.1, 0.2, 0.3, 0.9).normalize(),
            v: DVec3::new(-0.0, 5e-7, 3.0),
            l: DVec3::new(1e-9, 0.0, -4.0),
            inv_mass: 1.0 / 3.0,
            mass: 3.0,
            inv_inertia_body: DMat3::from_cols_array(&[1., 2., 3., 4., 5., 6., 7., 8., 9.]),
            inertia_body: DMat3::from_cols_array(&[9., 8., 7., 6., 5., 4., 3., 2., 1.]),
            drive: None,
            removed: false,
            pending: false,
        };
        let r = BodyRecord::of(7, &b, DVec3::X, DVec3::NEG_Y);
        let back = r.body();
        let bits = |b: &Body| {
            let mut v: Vec<u64> = [b.x, b.v, b.l]
                .iter()
                .flat_map(|x| x.to_array())
                .chain(b.q.to_array())
                .chain([b.mass, b.inv_mass])
                .chain(b.inertia_body.to_cols_array())
                .chain(b.inv_inertia_body.to_cols_array())
                .map(f64::to_bits)
                .collect();
            v.extend([b.shape as u64, b.material as u64]);
            v
        };
        assert_eq!(bits(&back), bits(&b));
        assert_eq!((r.id, r.force, r.torque), (7, [1., 0., 0.], [0., -1., 0.]));
    }
}
