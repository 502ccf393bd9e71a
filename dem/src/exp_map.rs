//! The quaternion exponential: the rotation by a rotation vector θ (axis ·
//! angle) is exp(θ) = (cos |θ|/2, sin(|θ|/2) θ/|θ|), exact at every angle
//! (the published code's map had an index bug; see the test). The
//! integrator turns bodies by it, and driven walls and the scene's initial
//! rotations are placed by it.

use glam::{DQuat, DVec3};

/// Rotation by the rotation vector `theta` (axis · angle) as a unit quaternion.
pub fn exp_map(theta: DVec3) -> DQuat {
    let angle = theta.length();
    if angle == 0.0 {
        return DQuat::IDENTITY;
    }
    let half = 0.5 * angle;
    let (s, c) = if half < SERIES_BELOW {
        half_angle_series(half * half)
    } else {
        (half.sin() / angle, half.cos())
    };
    DQuat::from_xyzw(theta.x * s, theta.y * s, theta.z * s, c)
}

/// Half-angles below this take the Taylor series of [`half_angle_series`]:
/// its first omitted term, x¹⁴/14!, is below 1e-22 here, far under
/// rounding, and a step's rotation is almost always this small.
const SERIES_BELOW: f64 = 0.125;

/// (sin(x)/(2x), cos x) from y = x², by Horner in y: no division and no
/// call to the library's sin and cos, exact to rounding for x < 0.125.
fn half_angle_series(y: f64) -> (f64, f64) {
    const S: [f64; 7] = [
        1.0,
        -1.0 / 6.0,
        1.0 / 120.0,
        -1.0 / 5040.0,
        1.0 / 362_880.0,
        -1.0 / 39_916_800.0,
        1.0 / 6_227_020_800.0,
    ];
    const C: [f64; 7] = [
        1.0,
        -1.0 / 2.0,
        1.0 / 24.0,
        -1.0 / 720.0,
        1.0 / 40_320.0,
        -1.0 / 3_628_800.0,
        1.0 / 479_001_600.0,
    ];
    let horner = |k: &[f64; 7]| k.iter().rev().fold(0.0, |acc, &a| acc * y + a);
    (0.5 * horner(&S), horner(&C))
}

#[cfg(test)]
mod tests {
    use super::*;
    use glam::DMat3;

    /// The exponential map against Rodrigues' formula, entry by entry, at
    /// small, moderate and large angles (a wrong index in one entry, as in the
    /// published code, breaks this for axes with two non-zero components).
    #[test]
    fn exp_map_matches_rodrigues() {
        for &(x, y, z) in &[
            (0.3, -0.2, 0.7),
            (1e-7, 2e-7, -3e-7),
            (2.0, 1.0, -1.5),
            (0.0, 0.0, 3.0),
            // The series' range, its edge, and just past it.
            (0.05, -0.1, 0.15),
            (0.2, 0.1, -0.1),
            (0.25, 0.0, 0.0),
            (0.0, -0.2500001, 0.0),
        ] {
            let t = DVec3::new(x, y, z);
            let a = t.length();
            let k = t / a;
            let kx = DMat3::from_cols(
                DVec3::new(0.0, k.z, -k.y),
                DVec3::new(-k.z, 0.0, k.x),
                DVec3::new(k.y, -k.x, 0.0),
            );
            let r = DMat3::IDENTITY + kx * a.sin() + kx * kx * (1.0 - a.cos());
            let m = DMat3::from_quat(exp_map(t));
            for c in 0..3 {
                for rr in 0..3 {
                    let (u, v) = (m.col(c)[rr], r.col(c)[rr]);
                    assert!((u - v).abs() < 1e-14, "entry ({rr},{c}) at {t}: {u} vs {v}");
                }
            }
        }
    }
}
