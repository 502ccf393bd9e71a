//! Axis-aligned boxes: the currency of the broad phase and of triangle culling.

use crate::distance::Triangle;
use glam::DVec3;

/// Axis-aligned box.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Bounds {
    pub lo: DVec3,
    pub hi: DVec3,
}

impl Default for Bounds {
    fn default() -> Self {
        Bounds::EMPTY
    }
}

impl Bounds {
    /// The box that contains nothing and is the identity of `union`.
    pub const EMPTY: Bounds = Bounds {
        lo: DVec3::INFINITY,
        hi: DVec3::NEG_INFINITY,
    };

    /// Box of a triangle, inflated by `pad` on every side.
    pub fn of(t: &Triangle, pad: f64) -> Bounds {
        Bounds {
            lo: t[0].min(t[1]).min(t[2]) - DVec3::splat(pad),
            hi: t[0].max(t[1]).max(t[2]) + DVec3::splat(pad),
        }
    }

    /// Closed boxes overlap (touching counts). Six comparisons joined with
    /// `&`, not `&&`: culling and the broad phase test boxes of which a
    /// large fraction overlap, where short-circuit branches mispredict.
    #[inline]
    pub fn overlaps(&self, o: &Bounds) -> bool {
        (self.lo.x <= o.hi.x)
            & (self.lo.y <= o.hi.y)
            & (self.lo.z <= o.hi.z)
            & (o.lo.x <= self.hi.x)
            & (o.lo.y <= self.hi.y)
            & (o.lo.z <= self.hi.z)
    }

    /// The box grown by `pad` on every side (itself for `pad` = 0).
    pub fn inflated(&self, pad: f64) -> Bounds {
        if pad == 0.0 {
            return *self;
        }
        Bounds {
            lo: self.lo - DVec3::splat(pad),
            hi: self.hi + DVec3::splat(pad),
        }
    }

    pub fn union(&self, o: &Bounds) -> Bounds {
        Bounds {
            lo: self.lo.min(o.lo),
            hi: self.hi.max(o.hi),
        }
    }

    /// The box common to both (empty if they do not overlap).
    pub fn intersection(&self, o: &Bounds) -> Bounds {
        Bounds {
            lo: self.lo.max(o.lo),
            hi: self.hi.min(o.hi),
        }
    }

    pub fn is_empty(&self) -> bool {
        self.lo.cmpgt(self.hi).any()
    }
}
