//! The places effects name in a scene: the side of a plane a normal points
//! to, and an axis-aligned box. Each is checked once, with one message, and
//! tested the same way by every effect that uses it (probes, outflow), on a
//! particle's centre of mass.

use glam::DVec3;

/// The open half-space (x − p)·n > 0 past a plane through p with normal n.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct HalfSpace {
    pub point: DVec3,
    pub normal: DVec3,
}

impl HalfSpace {
    /// The half-space of a scene's `point` and `normal`, or why not.
    pub fn of(point: [f64; 3], normal: [f64; 3]) -> Result<HalfSpace, &'static str> {
        let (point, normal) = (DVec3::from_array(point), DVec3::from_array(normal));
        if !point.is_finite() || !normal.is_finite() || normal == DVec3::ZERO {
            return Err("point and normal must be finite, the normal not zero");
        }
        Ok(HalfSpace { point, normal })
    }

    /// Whether `x` lies past the plane, on the normal's side (not on it).
    pub fn holds(&self, x: DVec3) -> bool {
        (x - self.point).dot(self.normal) > 0.0
    }
}

/// The closed box lo ≤ x ≤ hi.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Cuboid {
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Cuboid {
    /// The box of a scene's `lo` and `hi`, or why not.
    pub fn of(lo: [f64; 3], hi: [f64; 3]) -> Result<Cuboid, &'static str> {
        let (lo, hi) = (DVec3::from_array(lo), DVec3::from_array(hi));
        if !lo.is_finite() || !hi.is_finite() || lo.cmpgt(hi).any() {
            return Err("lo and hi must be finite, lo ≤ hi on every axis");
        }
        Ok(Cuboid { lo, hi })
    }

    /// Whether `x` lies in the box, its faces included.
    pub fn holds(&self, x: DVec3) -> bool {
        x.cmpge(self.lo).all() && x.cmple(self.hi).all()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Far from the origin and at any scale, the plane itself is not past
    /// it and the box's faces are in it; bad input is refused.
    #[test]
    fn places_hold_what_they_say_at_any_scale_and_refuse_bad_input() {
        for (scale, far) in [(1e-6, 0.0), (1.0, 1e6), (1e6, 0.0)] {
            let c = DVec3::splat(far);
            let at = |v: DVec3| (c + v * scale).to_array();
            let h = HalfSpace::of(at(DVec3::ZERO), [0.0, 0.0, -1.0]).unwrap();
            assert!(h.holds(c + DVec3::new(0.0, 0.0, -scale)));
            assert!(!h.holds(c) && !h.holds(c + DVec3::new(scale, 0.0, scale)));
            let b = Cuboid::of(at(DVec3::splat(-1.0)), at(DVec3::ONE)).unwrap();
            assert!(b.holds(c) && b.holds(c + DVec3::splat(scale)));
            assert!(!b.holds(c + DVec3::new(0.0, 2.0 * scale, 0.0)));
        }
        assert!(HalfSpace::of([0.0; 3], [0.0; 3]).is_err());
        assert!(HalfSpace::of([f64::NAN, 0.0, 0.0], [1.0, 0.0, 0.0]).is_err());
        assert!(Cuboid::of([0.0, 1.0, 0.0], [1.0, 0.0, 1.0]).is_err());
        assert!(Cuboid::of([0.0; 3], [f64::INFINITY, 1.0, 1.0]).is_err());
    }
}
