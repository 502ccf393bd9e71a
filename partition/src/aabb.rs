//! Axis-aligned bounding boxes.

use mpi::traits::Equivalence;

/// A closed axis-aligned box [lo, hi].
#[derive(Debug, Clone, Copy, PartialEq, Default, Equivalence)]
pub struct Aabb {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl Aabb {
    pub const EMPTY: Aabb = Aabb {
        lo: [f64::INFINITY; 3],
        hi: [f64::NEG_INFINITY; 3],
    };

    pub fn new(lo: [f64; 3], hi: [f64; 3]) -> Self {
        Aabb { lo, hi }
    }

    /// The box grown by `h` on every side.
    pub fn inflated(&self, h: f64) -> Aabb {
        Aabb {
            lo: self.lo.map(|x| x - h),
            hi: self.hi.map(|x| x + h),
        }
    }

    /// Closed boxes: touching counts as overlapping.
    pub fn overlaps(&self, o: &Aabb) -> bool {
        (0..3).all(|k| self.lo[k] <= o.hi[k] && o.lo[k] <= self.hi[k])
    }

    pub fn contains(&self, p: [f64; 3]) -> bool {
        (0..3).all(|k| self.lo[k] <= p[k] && p[k] <= self.hi[k])
    }

    pub fn grow(&mut self, p: [f64; 3]) {
        for (k, x) in p.into_iter().enumerate() {
            self.lo[k] = self.lo[k].min(x);
            self.hi[k] = self.hi[k].max(x);
        }
    }

    pub fn union(&self, o: &Aabb) -> Aabb {
        let mut b = *self;
        b.grow(o.lo);
        b.grow(o.hi);
        b
    }

    pub fn is_empty(&self) -> bool {
        (0..3).any(|k| self.lo[k] > self.hi[k])
    }

    pub fn extent(&self) -> [f64; 3] {
        [0, 1, 2].map(|k| (self.hi[k] - self.lo[k]).max(0.0))
    }

    /// The box clamped to `domain`.
    pub fn clamped_to(&self, domain: &Aabb) -> Aabb {
        Aabb {
            lo: [0, 1, 2].map(|k| self.lo[k].max(domain.lo[k])),
            hi: [0, 1, 2].map(|k| self.hi[k].min(domain.hi[k])),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn overlap_is_closed_and_symmetric() {
        let a = Aabb::new([0.0; 3], [1.0; 3]);
        let b = Aabb::new([1.0, 0.5, 0.5], [2.0; 3]);
        let c = Aabb::new([1.0 + 1e-12, 0.0, 0.0], [2.0; 3]);
        assert!(a.overlaps(&b) && b.overlaps(&a));
        assert!(!a.overlaps(&c) && !c.overlaps(&a));
        assert!(a.inflated(1e-9).overlaps(&c));
        assert!(Aabb::EMPTY.is_empty());
    }
}
