//! Time integration: velocity Verlet for translation, and for rotation an
//! implicit-midpoint update of the orientation driven by the angular momentum.
//!
//! Translation: v ← v + (F/m) h/2; x ← x + v h; forces; v ← v + (F/m) h/2.
//! Exact for constant force (free fall), second order, symplectic.
//!
//! Rotation: the world angular momentum L takes the same half kicks from the
//! torque, so a torque-free body keeps L to the last bit. The orientation
//! advances by q ← exp(ω̄ h) q with ω̄ the angular velocity at the midpoint
//! orientation q̄ = exp(ω̄ h/2) q, found by fixed-point iteration; the
//! quaternion exponential exp(θ) = (cos |θ|/2, sin(|θ|/2) θ/|θ|) is exact at
//! every angle (the published map had an index bug, see the tests). The
//! midpoint rule keeps the rotational energy bounded.

use crate::body::Body;
use crate::exp_map::exp_map;
use glam::{DMat3, DQuat, DVec3};

/// Midpoint-rule orientation update over `h` with constant `l`.
///
/// Solved in the body axes of the start orientation q, where it needs no
/// renormalisation between rounds: with L_b = q⁻¹ L and the midpoint
/// q̄ = q e, e = exp(ω̄_b h/2), the midpoint angular velocity in those axes
/// is ω̄_b = e I⁻¹ (e⁻¹ L_b), and the step ends at q exp(ω̄_b h). The
/// rounds start from the second-order estimate ω_b + (h/2) I⁻¹ (L_b × ω_b)
/// (Euler's equations for a torque-free body), so each round of the
/// fixed point, which contracts by about |ω| h / 2, starts two orders in.
pub fn advance_orientation(b: &Body, h: f64) -> DQuat {
    match Turning::start(b, h) {
        Err(q) => q,
        Ok(mut t) => {
            while !t.round(h) {}
            t.end(h)
        }
    }
}

/// Bodies whose orientation updates [`drift_many`] interleaves: the rounds
/// of one body are a chain of dependent operations (square roots, Horner
/// series, rotations), so a core left with one chain idles on its
/// latencies; several independent ones fill the gaps.
pub const LANES: usize = 4;

/// One body's midpoint rounds under way (see [`advance_orientation`]).
#[derive(Clone, Copy)]
struct Turning {
    q: DQuat,
    inv: DMat3,
    /// L in the body axes of q, and the midpoint angular velocity so far.
    lb: DVec3,
    mid: DVec3,
    rounds: usize,
}

impl Turning {
    /// What an idle lane holds: no turn.
    const IDLE: Turning = Turning {
        q: DQuat::IDENTITY,
        inv: DMat3::ZERO,
        lb: DVec3::ZERO,
        mid: DVec3::ZERO,
        rounds: 0,
    };

    /// The rounds' start; `Err` with the new orientation for a body that
    /// needs none (static, or not turning).
    #[inline]
    fn start(b: &Body, h: f64) -> Result<Turning, DQuat> {
        if b.is_static() {
            return Err(b.q);
        }
        // What the lines below give a body at rest, without the rotations:
        // ω is then zero to the bit.
        if b.l == DVec3::ZERO {
            return Err(b.q.normalize());
        }
        let inv = b.inv_inertia_body;
        let lb = b.q.conjugate() * b.l;
        let w = inv * lb;
        if w == DVec3::ZERO {
            return Err(b.q.normalize());
        }
        Ok(Turning {
            q: b.q,
            inv,
            lb,
            mid: w + (0.5 * h) * (inv * lb.cross(w)),
            rounds: 0,
        })
    }

    /// One round of the fixed point; whether the rounds are over.
    #[inline]
    fn round(&mut self, h: f64) -> bool {
        let e = exp_map(self.mid * (0.5 * h));
        let next = e * (self.inv * (e.conjugate() * self.lb));
        let change = (next - self.mid).length_squared();
        self.mid = next;
        self.rounds += 1;
        // The round contracts the error by about |ω| h / 2, so what is left
        // after it is about |Δω| h / 2 relative: at rounding, stop.
        change * (h * h) <= CONVERGED * CONVERGED || self.rounds == MIDPOINT_ROUNDS
    }

    #[inline]
    fn end(&self, h: f64) -> DQuat {
        (self.q * exp_map(self.mid * h)).normalize()
    }
}

/// [`drift`] of the bodies `ids` (distinct indices into `bodies`), each to
/// the bit as `drift` moves it: the orientations are updated [`LANES`]
/// bodies at a time, round by round, each body with the operations of
/// [`advance_orientation`] in their order. A lane whose body is done takes
/// the next body that turns, so that no lane runs rounds for a body already
/// done (bodies need one to four rounds, by how fast they
/// spin), and bodies that do not turn take no lane.
pub fn drift_many(bodies: &mut [Body], ids: &[usize], h: f64, rotation: bool) {
    for &i in ids {
        let b = &mut bodies[i];
        if !b.is_static() {
            b.x += b.v * h;
        }
    }
    if !rotation {
        return;
    }
    let mut queue = ids.iter();
    // The next body that turns; those that do not get their orientation here.
    let mut next = |bodies: &mut [Body]| {
        for &i in queue.by_ref() {
            match Turning::start(&bodies[i], h) {
                Ok(t) => return Some((i, t)),
                Err(q) => bodies[i].q = q,
            }
        }
        None
    };
    let mut lanes = [(usize::MAX, Turning::IDLE); LANES];
    let mut busy = [false; LANES];
    loop {
        for (lane, busy) in lanes.iter_mut().zip(&mut busy) {
            if !*busy {
                if let Some(body) = next(bodies) {
                    (*lane, *busy) = (body, true);
                }
            }
        }
        if !busy.contains(&true) {
            return;
        }
        // Every lane's round, then the ends: the chains stay in flight
        // together (an idle lane's round, at the queue's end, is dropped).
        let over: [bool; LANES] = std::array::from_fn(|k| lanes[k].1.round(h));
        for k in 0..LANES {
            if busy[k] && over[k] {
                bodies[lanes[k].0].q = lanes[k].1.end(h);
                busy[k] = false;
            }
        }
    }
}
/// Rounds of the midpoint fixed point at most. From the second-order start,
/// four leave a relative error of about (|ω| h / 2)⁶: about 1e-12 at
/// |ω| h = 0.02, a rotation of a degree per step.
const MIDPOINT_ROUNDS: usize = 4;

/// The relative error, in units of rounding, at which the rounds stop.
const CONVERGED: f64 = 8.0 * f64::EPSILON;

/// Half kick: v and L take half a step of force and torque.
pub fn half_kick(b: &mut Body, force: DVec3, torque: DVec3, h: f64, rotation: bool) {
    if b.is_static() {
        return;
    }
    b.v += force * (b.inv_mass * 0.5 * h);
    if rotation {
        b.l += torque * (0.5 * h);
    }
}

/// A bound on how far any point of `after`'s shape moved from its pose
/// `before` (position, orientation), for a shape whose vertices lie within
/// `radius` of the body's origin. A point at r from the origin moves by
/// |Δx| + |ΔR r| at most, and a rotation by θ moves it by the chord
/// 2 |r| sin(θ/2) = 2 |r| |v| for v the vector part of the relative
/// quaternion. The margins cover the rounding of these terms and of the
/// world vertices computed at either pose.
#[inline]
pub fn travel_bound(before: (DVec3, DQuat), after: &Body, radius: f64) -> f64 {
    let (x, q) = before;
    let turn = after.q * q.conjugate();
    let exact = (after.x - x).length() + 2.0 * radius * turn.xyz().length();
    with_rounding(exact, after, radius)
}

/// A bound on how far any point of body `after[0]` moved relative to any
/// point of `after[1]` since their poses `before`: what the distance
/// between two of their points (and between any two of their triangles)
/// can have changed by. A translation of both leaves it unchanged, so the
/// bodies' displacements enter as their difference: for points
/// p = x + R v of the first and p' = x' + R' v' of the second,
/// |Δ(p − p')| ≤ |Δx − Δx'| + |ΔR v| + |ΔR' v'|, the last two the chords of
/// [`travel_bound`]. Grains that fall or flow together move little relative
/// to one another however far they go. The margins are those of both
/// bodies' [`travel_bound`]s.
#[inline]
pub fn relative_travel_bound(
    before: [(DVec3, DQuat); 2],
    after: [&Body; 2],
    radii: [f64; 2],
) -> f64 {
    let chord = |k: usize| 2.0 * radii[k] * (after[k].q * before[k].1.conjugate()).xyz().length();
    let shift = (after[0].x - before[0].0) - (after[1].x - before[1].0);
    let exact = shift.length() + chord(0) + chord(1);
    with_rounding(exact, after[0], radii[0]) + with_rounding(0.0, after[1], radii[1])
}

/// A bound on how far `after`'s centre of mass moved from `before`, with
/// the margins of [`travel_bound`]: what bounds the motion of a sphere of
/// `radius` about the centre, which turning leaves where it is.
#[inline]
pub fn centre_travel_bound(before: DVec3, after: &Body, radius: f64) -> f64 {
    with_rounding((after.x - before).length(), after, radius)
}

#[inline]
fn with_rounding(exact: f64, after: &Body, radius: f64) -> f64 {
    exact * (1.0 + 1e-12) + 16.0 * f64::EPSILON * (after.x.length() + radius)
}

/// Drift: positions (and orientations when rotation is on) over a full step.
pub fn drift(b: &mut Body, h: f64, rotation: bool) {
    if b.is_static() {
        return;
    }
    b.x += b.v * h;
    if rotation {
        b.q = advance_orientation(b, h);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    /// A tumbling asymmetric body at |ω| h from 1e-6 to 0.02.
    fn spinning(omega_h: f64, h: f64) -> Body {
        let inertia = DMat3::from_diagonal(DVec3::new(1.0, 2.5, 4.0));
        let q = exp_map(DVec3::new(0.4, -1.1, 0.7));
        let w = DVec3::new(0.3, 1.0, -0.6).normalize() * (omega_h / h);
        Body {
            shape: 0,
            material: 0,
            x: DVec3::ZERO,
            q,
            v: DVec3::ZERO,
            l: q * (inertia * (q.conjugate() * w)),
            inv_mass: 1.0,
            mass: 1.0,
            inv_inertia_body: inertia.inverse(),
            inertia_body: inertia,
            drive: None,
            removed: false,
            pending: false,
        }
    }

    /// The rotation vector of a unit quaternion (the inverse of `exp_map`).
    fn log_map(q: DQuat) -> DVec3 {
        let q = if q.w < 0.0 { -q } else { q };
        let v = q.xyz();
        let s = v.length();
        v * (2.0 * s.atan2(q.w) / s)
    }

    /// The update solves the implicit midpoint rule it claims: with ω̄ read
    /// back from the step (exp(ω̄ h) = q' q⁻¹), the angular velocity of the
    /// midpoint orientation exp(ω̄ h/2) q, computed in world axes by
    /// `omega_of`, is ω̄ again, to 1e-11 relative, at every rate a DEM
    /// step meets (plus the rounding of reading ω̄ back from q' q⁻¹, whose
    /// vector part is only |ω| h / 2 long).
    #[test]
    fn orientation_update_solves_the_midpoint_rule() {
        let h = 1e-4;
        for omega_h in [1e-6, 1e-3, 5e-3, 0.02] {
            let b = spinning(omega_h, h);
            let q1 = advance_orientation(&b, h);
            let mid = log_map(q1 * b.q.conjugate()) / h;
            let q_mid = exp_map(mid * (0.5 * h)) * b.q;
            let again = crate::body::omega_of(q_mid, b.inv_inertia_body, b.l);
            let err = (again - mid).length() / mid.length();
            let readback = 32.0 * f64::EPSILON / omega_h;
            assert!(
                err <= 1e-11 + readback,
                "|w|h = {omega_h}: relative residual {err}"
            );
            assert!((q1.length() - 1.0).abs() < 4.0 * f64::EPSILON);
        }
    }

    /// The interleaved update gives each body the bits of the one-body
    /// update, whatever its neighbours in the lanes: rates from rest to a
    /// tenth of a radian per step, a body with no angular momentum, an
    /// obstacle, and a short last chunk.
    #[test]
    fn interleaved_update_is_the_one_body_update_to_the_bit() {
        let h = 1e-4;
        let mut bodies: Vec<Body> = [0.0, 1e-9, 1e-6, 1e-3, 5e-3, 0.02, 0.1, 2e-4, 7e-3]
            .iter()
            .enumerate()
            .map(|(k, &omega_h)| {
                let mut b = spinning(omega_h, h);
                b.q = exp_map(DVec3::new(0.3 * k as f64, -0.2, 1.0 - 0.1 * k as f64));
                b.v = DVec3::new(k as f64, 1.0, -2.0);
                b
            })
            .collect();
        bodies[0].l = DVec3::ZERO;
        bodies[3].inv_mass = 0.0;
        let expected: Vec<Body> = bodies
            .iter()
            .map(|b| {
                let mut b = b.clone();
                drift(&mut b, h, true);
                b
            })
            .collect();
        let ids: Vec<usize> = (0..bodies.len()).rev().collect();
        drift_many(&mut bodies, &ids, h, true);
        for (k, (got, want)) in bodies.iter().zip(&expected).enumerate() {
            let bits = |b: &Body| {
                (
                    b.x.to_array().map(f64::to_bits),
                    b.q.to_array().map(f64::to_bits),
                )
            };
            assert_eq!(bits(got), bits(want), "body {k}");
        }
    }

    /// The relative bound holds every pair of points of two moved bodies,
    /// placed as the triangle set places them (x + R v, rounded), at sizes
    /// from 1e-6 to 1e6 and far from the origin; and grains that move
    /// together by far more than their size get a bound of their turns
    /// alone, where the bodies' own travel bounds add up to the distance.
    #[test]
    fn relative_travel_bounds_every_pair_of_points() {
        use rand::{Rng, SeedableRng};
        let mut rng = rand_xoshiro::Xoshiro256PlusPlus::seed_from_u64(7);
        let unit = |rng: &mut rand_xoshiro::Xoshiro256PlusPlus| {
            DVec3::new(rng.random(), rng.random(), rng.random()) * 2.0 - DVec3::ONE
        };
        for scale in [1e-6, 1e-3, 1.0, 1e3, 1e6] {
            for far in [0.0, 1e4 * scale, 1e8 * scale] {
                for _ in 0..200 {
                    let points = |rng: &mut _| -> Vec<DVec3> {
                        (0..8).map(|_| unit(rng) * (0.5 * scale)).collect()
                    };
                    let (va, vb) = (points(&mut rng), points(&mut rng));
                    let radius = |v: &[DVec3]| v.iter().map(|p| p.length()).fold(0.0, f64::max);
                    let pose = |rng: &mut _| {
                        let x = DVec3::splat(far) + unit(rng) * scale;
                        (x, exp_map(unit(rng) * 3.0))
                    };
                    let before = [pose(&mut rng), pose(&mut rng)];
                    let common = unit(&mut rng) * (50.0 * scale);
                    let moved = |(x, q): (DVec3, DQuat), rng: &mut _| {
                        let mut b = spinning(0.0, 1.0);
                        b.x = x + common + unit(rng) * (0.01 * scale);
                        b.q = exp_map(unit(rng) * 0.01) * q;
                        b
                    };
                    let after = [moved(before[0], &mut rng), moved(before[1], &mut rng)];
                    let radii = [radius(&va), radius(&vb)];
                    let bound = relative_travel_bound(before, [&after[0], &after[1]], radii);
                    let place = |(x, q): (DVec3, DQuat), v: DVec3| x + DMat3::from_quat(q) * v;
                    let now = |b: &Body| (b.x, b.q);
                    for &a in &va {
                        for &b in &vb {
                            let was = place(before[0], a) - place(before[1], b);
                            let is = place(now(&after[0]), a) - place(now(&after[1]), b);
                            assert!((is - was).length() <= bound, "scale {scale}, far {far}");
                        }
                    }
                    let apart = travel_bound(before[0], &after[0], radii[0])
                        + travel_bound(before[1], &after[1], radii[1]);
                    assert!(
                        bound < 0.25 * apart,
                        "scale {scale}: {bound} against {apart}"
                    );
                }
            }
        }
    }

    /// A body with no angular momentum keeps its orientation.
    #[test]
    fn no_angular_momentum_no_turn() {
        let mut b = spinning(1e-3, 1e-4);
        b.l = DVec3::ZERO;
        assert_eq!(advance_orientation(&b, 1e-4), b.q.normalize());
    }
}
