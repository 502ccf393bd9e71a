//! How far the bodies have moved since the neighbour list was drawn, in the
//! terms the list's validity needs.
//!
//! The list holds the body pairs whose boxes, each moving body's grown by
//! the pad p (half the skin s), overlapped when it was drawn; a fixed
//! obstacle's box is not grown. The list stays valid while no pair outside
//! it can have come to overlap without the pad. Boxes are axis-aligned: a
//! pair outside the list was apart along some axis k by more than its pads.
//! Since the list was drawn, every point of body a moved along axis k by
//! Δx_a,k ± c_a, with Δx_a its centre's displacement and c_a the chord of its
//! turn, 2 r_a |sin(θ_a/2)| (r_a its farthest vertex from the centre), plus
//! the rounding margins of `integrate::travel_bound`. So:
//!
//! - **two moving bodies** apart along k by more than 2p = s can overlap
//!   only once |Δx_a,k − Δx_b,k| + c_a + c_b ≥ s. Over all pairs this is at
//!   most max (Δx_·,k + c) − min (Δx_·,k − c): how far any point went up
//!   along k plus how far any went down, the spread of the displacements,
//!   not their size. Grains that fall or flow together spread little
//!   however far they go;
//! - **a moving body and a fixed obstacle** apart along their most
//!   separating axis by g (> p, or the pair would be listed) can overlap
//!   only once max_k |Δx_a,k| + c_a ≥ g. Each moving body keeps the least g
//!   over the fixed obstacles it is not listed with: a grain far from every
//!   wall may travel far.
//!
//! The rule every body moving at most p (the sum of each step's largest
//! travel) implies both, and is the cheaper test while it holds.
//! [`ListMotion`] carries the terms as numbers to take the maximum of, so
//! that ranks, each measuring its own particles, agree on them with one
//! all-reduce.

use super::triangle_set::BodyGroup;
use crate::body::Body;
use crate::world::World;
use glam::{DQuat, DVec3};

/// At most this many fixed obstacles are measured against each moving body
/// when a list is drawn (O(bodies · obstacles)); with more, a moving body
/// keeps the pad as its clearance from them (the rule of every body moving
/// at most the pad).
const CLEARANCES_UP_TO: usize = 64;

/// The poses of a world's bodies when the neighbour list was drawn, and each
/// moving body's clearance from the fixed obstacles it is not listed with.
#[derive(Debug, Clone, Default)]
pub(crate) struct ListPoses {
    poses: Vec<(DVec3, DQuat)>,
    /// Per particle: its least separation from a fixed obstacle outside its
    /// pairs (infinite: none, and for obstacles).
    clearance: Vec<f64>,
}

impl ListPoses {
    /// Records `world`'s poses and, from the boxes the broad phase read
    /// (`groups`, a moving body's grown by `pad`), the moving bodies'
    /// clearances.
    pub(crate) fn record(&mut self, world: &World, groups: &[BodyGroup], pad: f64) {
        self.poses.clear();
        self.poses.extend(world.bodies.iter().map(|b| (b.x, b.q)));
        self.clearance.clear();
        self.clearance.resize(world.bodies.len(), f64::INFINITY);
        let fixed: Vec<&BodyGroup> = (groups.iter())
            .filter(|g| world.bodies[g.body as usize].is_fixed() && !g.owned.is_empty())
            .collect();
        if fixed.len() > CLEARANCES_UP_TO {
            self.clearance.fill(pad);
            return;
        }
        // Particles only: a driven obstacle meets no fixed one.
        for g in groups.iter().filter(|g| !g.owned.is_empty()) {
            if world.bodies[g.body as usize].is_static() {
                continue;
            }
            let grown = g.owned_box.inflated(pad);
            let apart = |f: &&&BodyGroup| !grown.overlaps(&f.owned_box);
            let separation = |f: &&BodyGroup| {
                let (a, b) = (&g.owned_box, &f.owned_box);
                (b.lo - a.hi).max(a.lo - b.hi).max_element()
            };
            let least = fixed.iter().filter(apart).map(separation);
            self.clearance[g.body as usize] = least.fold(f64::INFINITY, f64::min);
        }
    }

    /// The motion since [`Self::record`] of the bodies `ids` (indices into
    /// the same world, which must be laid out as then), taking part in
    /// contacts; fixed obstacles are skipped. `radii`: per shape, its
    /// farthest vertex from the body's centre.
    pub(crate) fn motion(
        &self,
        bodies: &[Body],
        radii: &[f64],
        ids: impl Iterator<Item = usize>,
    ) -> ListMotion {
        let mut m = ListMotion::NONE;
        for i in ids {
            let b = &bodies[i];
            if b.is_fixed() || b.is_out() {
                continue;
            }
            let Some(&(x, q)) = self.poses.get(i) else {
                return ListMotion::UNKNOWN;
            };
            let r = radii.get(b.shape).copied().unwrap_or(f64::INFINITY);
            let shift = b.x - x;
            let turn = 2.0 * r * (b.q * q.conjugate()).xyz().length();
            // The margins of `integrate::travel_bound`: rounding of the
            // vertices placed at either pose.
            let c = turn * (1.0 + 1e-12) + 16.0 * f64::EPSILON * (b.x.length() + r);
            m.note(shift, c, self.clearance[i]);
        }
        m
    }
}

/// The terms of the list's validity over some bodies, each a maximum (see
/// the module doc): per axis k, the largest Δx_k + c and the largest
/// −(Δx_k − c) (the farthest any point went up and down along k), and the
/// largest excess of a particle's travel over its clearance from the fixed
/// obstacles. A value that is not a number is carried as infinite, which
/// redraws the list.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ListMotion(pub [f64; ListMotion::LEN]);

impl ListMotion {
    /// How many numbers the terms are.
    pub const LEN: usize = 7;
    /// No body: every term the identity of the maximum.
    pub const NONE: ListMotion = ListMotion([f64::NEG_INFINITY; ListMotion::LEN]);
    /// Motion not known (bodies placed by hand, a world laid out anew).
    pub const UNKNOWN: ListMotion = ListMotion([f64::INFINITY; ListMotion::LEN]);

    fn note(&mut self, shift: DVec3, chord: f64, clearance: f64) {
        let v = &mut self.0;
        let finite = |x: f64| if x.is_nan() { f64::INFINITY } else { x };
        for k in 0..3 {
            v[k] = v[k].max(finite(shift[k] + chord));
            v[3 + k] = v[3 + k].max(finite(chord - shift[k]));
        }
        let travel = shift.abs().max_element() + chord;
        v[6] = v[6].max(finite(travel * (1.0 + 1e-12) - clearance * (1.0 - 1e-12)));
    }

    /// The terms of two sets of bodies together.
    pub fn merge(self, o: ListMotion) -> ListMotion {
        ListMotion(std::array::from_fn(|k| self.0[k].max(o.0[k])))
    }

    /// Whether a list drawn with this skin still holds every pair whose
    /// boxes can overlap: for bodies a and b, |Δx_a,k − Δx_b,k| + c_a + c_b
    /// is at most the farthest any point went up along k plus the farthest
    /// any went down.
    pub fn keeps(&self, skin: f64) -> bool {
        let v = &self.0;
        let spread = (0..3)
            .map(|k| v[k] + v[3 + k])
            // An infinite shift makes ∞ − ∞ here; `f64::max` would drop it.
            .map(|x| if x.is_nan() { f64::INFINITY } else { x })
            .fold(f64::NEG_INFINITY, f64::max);
        // NaN compares as neither, and never keeps.
        let below = |x: f64, bound: f64| x.partial_cmp(&bound) == Some(std::cmp::Ordering::Less);
        below(spread * (1.0 + 1e-12), skin) && below(v[6], 0.0)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A body's terms: its displacement both ways per axis, its chord, and
    /// its travel less its clearance.
    fn one(shift: DVec3, chord: f64, clearance: f64) -> ListMotion {
        let mut m = ListMotion::NONE;
        m.note(shift, chord, clearance);
        m
    }

    /// Bodies moved together by far more than the skin keep the list; moved
    /// apart by the skin, or one by its clearance from a wall, they do not.
    #[test]
    fn the_spread_and_the_clearances_decide_not_the_distance() {
        let skin = 1e-3;
        let down = DVec3::new(0.0, 0.0, -0.5);
        let together = one(down, 1e-5, 1.0).merge(one(down + DVec3::X * 1e-4, 1e-5, 1.0));
        assert!(together.keeps(skin));
        let apart = one(down, 1e-5, 1.0).merge(one(down + DVec3::X * 1e-3, 1e-5, 1.0));
        assert!(!apart.keeps(skin));
        // Two bodies that turn may each sweep a point towards the other.
        let turning = one(DVec3::ZERO, 0.45e-3, 1.0).merge(one(DVec3::ZERO, 0.45e-3, 1.0));
        assert!(turning.keeps(skin));
        let turning_more = one(DVec3::ZERO, 0.55e-3, 1.0).merge(one(DVec3::ZERO, 0.5e-3, 1.0));
        assert!(!turning_more.keeps(skin));
        // A turn and a shift add up only along the axis they share.
        let up = DVec3::Z * 0.6e-3;
        assert!(!one(up, 0.0, 1.0)
            .merge(one(DVec3::ZERO, 0.45e-3, 1.0))
            .keeps(skin));
        assert!(one(DVec3::X * 0.6e-3, 0.0, 1.0)
            .merge(one(DVec3::X * 0.6e-3, 0.45e-3, 1.0))
            .keeps(skin));
        // Near a wall, travel is measured against the clearance from it.
        assert!(one(down * 1e-3, 0.0, 0.6e-3).keeps(skin));
        assert!(!one(down * 1e-3, 0.0, 0.4e-3).keeps(skin));
        // No body keeps; nothing known, or NaN, does not.
        assert!(ListMotion::NONE.keeps(skin));
        assert!(!ListMotion::UNKNOWN.keeps(skin));
        assert!(!one(DVec3::new(f64::NAN, 0.0, 0.0), 0.0, 1.0).keeps(skin));
        assert!(!one(DVec3::ZERO, f64::NAN, 1.0).keeps(skin));
        assert!(!one(DVec3::X * f64::INFINITY, 0.0, f64::INFINITY).keeps(skin));
    }
}
