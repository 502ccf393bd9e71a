//! The scene's fingerprint hash: what a checkpoint is checked against, so
//! that a run resumes only with the scene it was taken of. The world hashes
//! its bodies with it, and a rank that holds a part of the scene hashes the
//! whole from its census, to the same value.

use crate::drive::{Drive, Profile};
use glam::{DQuat, DVec3};

/// The 64-bit FNV-1a hash.
pub(crate) struct Fnv1a(pub(crate) u64);

impl Default for Fnv1a {
    fn default() -> Self {
        Fnv1a(0xcbf2_9ce4_8422_2325)
    }
}

impl Fnv1a {
    pub(crate) fn bytes(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.0 = (self.0 ^ u64::from(b)).wrapping_mul(0x0100_0000_01b3);
        }
    }

    pub(crate) fn u64(&mut self, v: u64) {
        self.bytes(&v.to_le_bytes());
    }

    pub(crate) fn f64(&mut self, v: f64) {
        self.u64(v.to_bits());
    }
}

/// What a body contributes to the fingerprint: its shape, material and mass,
/// an obstacle's pose at time 0, and a moving obstacle's velocities.
pub(crate) fn hash_body(
    h: &mut Fnv1a,
    shape: usize,
    material: usize,
    mass: f64,
    fixed: Option<(DVec3, DQuat)>,
    drive: Option<&Drive>,
) {
    h.u64(shape as u64);
    h.u64(material as u64);
    h.f64(mass);
    if let Some((x, q)) = fixed {
        x.to_array().into_iter().for_each(|c| h.f64(c));
        q.to_array().into_iter().for_each(|c| h.f64(c));
    }
    if let Some(d) = drive {
        // Constant velocities hash as their values alone; a table as its
        // length and knots after them.
        let profiles = [&d.velocity, &d.angular_velocity];
        for p in profiles {
            if let Profile::Constant(v) = p {
                v.to_array().into_iter().for_each(|c| h.f64(c));
            }
        }
        for p in profiles {
            if let Profile::Table(knots) = p {
                h.u64(knots.len() as u64);
                for (t, v) in knots {
                    h.f64(*t);
                    v.to_array().into_iter().for_each(|c| h.f64(c));
                }
            }
        }
        if let Some(t) = d.removed_at {
            h.f64(t);
        }
    }
}
