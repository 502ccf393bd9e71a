//! Prescribed motion of an obstacle: a velocity of its frame's origin and an
//! angular velocity about it, each constant or piecewise linear in time.
//!
//! The pose at time t is a closed form of t alone,
//!
//!   x(t) = x₀ + ∫₀ᵗ v(s) ds,   q(t) = exp(∫₀ᵗ ω(s) ds) q₀,
//!
//! so every process that knows the time places the obstacle to the same bits,
//! whatever it did before (a resumed run, any rank). For a piecewise-linear
//! v the integral is exact: a sum of trapezoids over the knots passed, in
//! time order. The exponential of the integrated angular velocity is the
//! rotation only when ω keeps its axis, so a table of angular velocities
//! must keep one axis (its rows parallel; the scene refuses others): a drum
//! spun up, held and stopped, say. Before the first knot a table holds the
//! first row's value, after the last the last row's.
//!
//! An obstacle may also be removed at a time (a gate pulled out of a silo's
//! outlet): from then on it takes part in no contact. Whether it is there is
//! a function of the time too.

use glam::{DQuat, DVec3};

/// A velocity (or angular velocity) against time.
#[derive(Debug, Clone, PartialEq)]
pub enum Profile {
    Constant(DVec3),
    /// Knots (t, value), times strictly increasing; linear between them.
    Table(Vec<(f64, DVec3)>),
}

impl Profile {
    /// The value at time `t`.
    pub fn at(&self, t: f64) -> DVec3 {
        match self {
            Profile::Constant(v) => *v,
            Profile::Table(knots) => value_at(knots, t),
        }
    }

    /// ∫₀ᵗ of the value, for t ≥ 0 (exact for a table: trapezoids between
    /// the knots, summed in time order).
    pub fn integral(&self, t: f64) -> DVec3 {
        match self {
            Profile::Constant(v) => *v * t,
            Profile::Table(knots) => {
                // The breakpoints within (0, t), then each piece's trapezoid.
                let mut sum = DVec3::ZERO;
                let mut from = 0.0;
                for &(k, _) in knots.iter().filter(|&&(k, _)| k > 0.0 && k < t) {
                    sum += (k - from) * 0.5 * (value_at(knots, from) + value_at(knots, k));
                    from = k;
                }
                if t > from {
                    sum += (t - from) * 0.5 * (value_at(knots, from) + value_at(knots, t));
                }
                sum
            }
        }
    }

    /// The largest magnitude the value takes at any time (at a knot, for a
    /// table: the value is linear between them).
    pub fn largest(&self) -> f64 {
        match self {
            Profile::Constant(v) => v.length(),
            Profile::Table(knots) => knots.iter().map(|k| k.1.length()).fold(0.0, f64::max),
        }
    }

    /// Zero at every time.
    pub fn is_zero(&self) -> bool {
        self.largest() == 0.0
    }

    /// Whether every value is parallel to one direction (zero counts), to
    /// rounding: the condition for exp(∫ω) to be the rotation.
    pub fn keeps_one_axis(&self) -> bool {
        let Profile::Table(knots) = self else {
            return true;
        };
        let mut values = knots.iter().map(|k| k.1);
        let Some(widest) = values
            .clone()
            .max_by(|a, b| a.length().total_cmp(&b.length()))
        else {
            return true;
        };
        values.all(|v| v.cross(widest).length() <= 1e-12 * v.length() * widest.length())
    }
}

/// A table's value at `t`: linear between the knots around it, held beyond
/// the ends.
fn value_at(knots: &[(f64, DVec3)], t: f64) -> DVec3 {
    let after = knots.partition_point(|k| k.0 <= t);
    match (after.checked_sub(1).map(|i| knots[i]), knots.get(after)) {
        (Some((t0, v0)), Some(&(t1, v1))) => v0 + (v1 - v0) * ((t - t0) / (t1 - t0)),
        (Some((_, v)), None) | (None, Some(&(_, v))) => v,
        (None, None) => DVec3::ZERO,
    }
}

/// The prescribed motion of an obstacle, from its pose at time 0 (see the
/// module doc).
#[derive(Debug, Clone, PartialEq)]
pub struct Drive {
    /// The pose at time 0.
    pub x0: DVec3,
    pub q0: DQuat,
    pub velocity: Profile,
    /// World axes, rad/s.
    pub angular_velocity: Profile,
    /// The time from which the obstacle is gone (`None`: never).
    pub removed_at: Option<f64>,
    /// The angular velocity at the time the obstacle was last placed
    /// ([`Drive::place`]): what contacts see of its turning.
    omega: DVec3,
    /// Whether it was there at the time last placed.
    present: bool,
}

impl Drive {
    /// A drive from the pose at time 0, placed at time 0.
    pub fn new(x0: DVec3, q0: DQuat, velocity: Profile, angular_velocity: Profile) -> Drive {
        let omega = angular_velocity.at(0.0);
        Drive {
            x0,
            q0,
            velocity,
            angular_velocity,
            removed_at: None,
            omega,
            present: true,
        }
    }

    /// The same drive, the obstacle gone from time `t` on.
    pub fn removed_at(self, t: f64) -> Drive {
        Drive {
            removed_at: Some(t),
            present: t > 0.0,
            ..self
        }
    }

    /// Whether the obstacle moves at all (a drive may only remove it).
    pub fn moves(&self) -> bool {
        !(self.velocity.is_zero() && self.angular_velocity.is_zero())
    }

    /// Whether the obstacle was there at the time last placed.
    pub fn present(&self) -> bool {
        self.present
    }

    /// The pose and velocity at time `t`, and the angular velocity kept for
    /// [`Drive::omega`].
    pub fn place(&mut self, t: f64) -> (DVec3, DQuat, DVec3) {
        self.omega = self.angular_velocity.at(t);
        self.present = self.removed_at.is_none_or(|r| t < r);
        let (x, q) = self.pose(t);
        (x, q, self.velocity.at(t))
    }

    /// The angular velocity at the time last placed.
    pub fn omega(&self) -> DVec3 {
        self.omega
    }

    /// Position and orientation at time `t`.
    pub fn pose(&self, t: f64) -> (DVec3, DQuat) {
        let turn = crate::exp_map::exp_map(self.angular_velocity.integral(t));
        (
            self.x0 + self.velocity.integral(t),
            (turn * self.q0).normalize(),
        )
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A table's integral against the closed form of a ramp and a hold:
    /// v = a t up to t₁, then a t₁: x = a t²/2, then a t₁²/2 + a t₁ (t − t₁);
    /// before the first knot at t₀ > 0 the first value holds.
    #[test]
    fn a_tables_integral_is_the_exact_area() {
        let a = DVec3::new(2.0, -1.0, 0.5);
        let ramp = Profile::Table(vec![(0.0, DVec3::ZERO), (1.5, 1.5 * a)]);
        for t in [0.0, 0.25, 1.0, 1.5, 2.0, 10.0] {
            let want = if t <= 1.5 {
                a * (t * t / 2.0)
            } else {
                a * (1.5 * 1.5 / 2.0 + 1.5 * (t - 1.5))
            };
            let got = ramp.integral(t);
            assert!(
                (got - want).length() <= 1e-14 * want.length().max(1.0),
                "t {t}"
            );
            assert_eq!(ramp.at(t), a * t.min(1.5), "t {t}");
        }
        let late = Profile::Table(vec![(1.0, a), (2.0, 3.0 * a)]);
        assert_eq!(late.at(0.5), a);
        assert_eq!(late.integral(0.5), a * 0.5);
        // 1 (held) + 2 (trapezoid of a and 3a over a second).
        assert!((late.integral(2.0) - a * 3.0).length() <= 1e-14);
        assert_eq!(late.largest(), 3.0 * a.length());
    }

    /// A constant profile is the constant-velocity drive: x₀ + v t, to the bit.
    #[test]
    fn a_constant_profile_moves_at_its_velocity() {
        let v = DVec3::new(0.1, 0.2, -0.3);
        let d = Drive::new(
            DVec3::new(1.0, 2.0, 3.0),
            DQuat::IDENTITY,
            Profile::Constant(v),
            Profile::Constant(DVec3::ZERO),
        );
        assert_eq!(d.pose(0.7).0, DVec3::new(1.0, 2.0, 3.0) + v * 0.7);
        assert_eq!(d.velocity.at(5.0), v);
    }

    /// A drum spun up about z for a second at 2π rad/s², then held: its
    /// angle is π after the ramp, and a whole turn more every second after.
    #[test]
    fn a_spun_up_drum_turns_by_the_integrated_angle() {
        let tau = std::f64::consts::TAU;
        let d = Drive::new(
            DVec3::ZERO,
            DQuat::IDENTITY,
            Profile::Constant(DVec3::ZERO),
            Profile::Table(vec![(0.0, DVec3::ZERO), (1.0, DVec3::Z * tau)]),
        );
        for (t, angle) in [(1.0, std::f64::consts::PI), (2.0, std::f64::consts::PI)] {
            let want = DQuat::from_rotation_z(angle);
            assert!((d.pose(t).1.dot(want).abs() - 1.0).abs() <= 1e-14, "t {t}");
        }
        let (_, q) = d.pose(0.5);
        // Angle at 0.5 s: 2π 0.5²/2 = π/4.
        let want = DQuat::from_rotation_z(std::f64::consts::FRAC_PI_4);
        assert!((q.dot(want).abs() - 1.0).abs() <= 1e-14);
    }
}
