//! Whether two sets of points are farther apart than a reach: the body-pair
//! cull that runs before any triangle pair of the two is examined.
//!
//! # The certificate
//!
//! For point sets A and B and any direction d ≠ 0, let
//!
//!   gap(d) = min_{b ∈ B} d · b − max_{a ∈ A} d · a.
//!
//! The slab between the two support planes normal to d separates conv A from
//! conv B, so gap(d) / |d| is a lower bound on their distance, and hence on
//! the distance between any triangle with corners in A and any with corners
//! in B (a triangle lies in the hull of its corners). If
//! gap(d) > reach · |d| + rounding, no triangle pair of the two bodies is
//! within reach, and skipping the body pair changes no contact: culling is
//! exact, not a heuristic. The verdict "apart" rests only on this
//! certificate, computed from the points themselves.
//!
//! The rounding term bounds the error of the dot products (taken relative to
//! a point near the bodies, so that it scales with their size, not with their
//! distance from the origin) and the distance kernel's own tolerance
//! (1e-13 of a pair's scale, see `distance::certificate`), with six orders of
//! magnitude to spare: [`MARGIN`] of the bodies' extent.
//!
//! # Clearance: how long a verdict lasts
//!
//! Along the direction d of a verdict "apart", the same slab over all the
//! bodies' triangles gives their clearance c = gap(d) / |d| − reach (less
//! the rounding allowance below). If from then on A's points move by at most
//! δ_A and B's by at most δ_B, the slab narrows by at most δ_A + δ_B, so
//! the bodies stay farther apart than the reach while δ_A + δ_B < c: the
//! detector leaves the pair out meanwhile, without looking at a triangle.
//!
//! # Finding the direction: GJK
//!
//! The direction comes from the Gilbert–Johnson–Keerthi distance algorithm
//! (Gilbert, Johnson and Keerthi, IEEE J. Robotics and Automation 4(2), 1988)
//! on the Minkowski difference D = A − B, whose point nearest the origin is
//! the hulls' distance. Each iteration keeps a simplex of up to four points
//! of D and its point v nearest the origin; the support point w of D in
//! direction −v gives the lower bound v · w / |v| (the certificate above with
//! d = −v) and |v| is an upper bound. The search stops when
//!
//! - the lower bound clears the reach: apart;
//! - the upper bound is within the reach, or the simplex holds the origin:
//!   the hulls are within reach, and the triangles must tell;
//! - the bounds meet, or [`MAX_ITERATIONS`] pass: the triangles must tell.
//!
//! GJK's rounding can only cost culling (a pair examined that need not be),
//! never a contact. For two convex bodies the hull distance is the bodies'
//! distance, so every body pair culled by a box but not by this test has a
//! contact within reach, up to the bounds' gap; for non-convex meshes the
//! hull is a looser bound and more pairs go on to the triangles.

use crate::distance::Triangle;
use glam::{DMat3, DVec3};

/// Relative size of the rounding allowance (see the module doc).
pub(crate) const MARGIN: f64 = 1e-9;

/// GJK iterations before the triangles are left to decide; a few suffice for
/// the 10-100 points of a particle (each adds a support point, and the
/// search ends when none is new).
pub(crate) const MAX_ITERATIONS: usize = 24;

/// Whether conv `a` and conv `b` are certainly farther apart than `reach`
/// (see the module doc). Empty sets are apart from everything. `extent`
/// bounds the distance between any two of the points (it scales the
/// rounding allowance).
///
/// `hint` is a direction from A towards B to try first (zero: none); it is
/// left holding the search's last direction, which for bodies that have
/// moved little since is again a separating one, or nearly (temporal
/// coherence: one certificate instead of a search).
pub(crate) fn apart(a: &[DVec3], b: &[DVec3], reach: f64, extent: f64, hint: &mut DVec3) -> bool {
    let (Some(&origin), Some(_)) = (a.first(), b.first()) else {
        return true;
    };
    // Coordinates relative to a point of A: dot products then round
    // relative to the bodies' size.
    let reach = reach + MARGIN * (extent + reach);
    if *hint != DVec3::ZERO && certified(a, b, *hint, origin, reach) {
        return true;
    }
    // Without a hint, from the difference of the centroids: for bodies well
    // apart the first support point then settles it.
    let start = if *hint != DVec3::ZERO {
        -*hint
    } else {
        let centroid = |p: &[DVec3]| p.iter().map(|q| *q - origin).sum::<DVec3>() / p.len() as f64;
        centroid(a) - centroid(b)
    };
    let (verdict, v) = search(a, b, origin, reach, start);
    if v.is_finite() && v != DVec3::ZERO {
        *hint = -v;
    }
    verdict
}

/// How much farther apart than `reach` conv A and conv B certainly are, as
/// the slab normal to `d` shows: gap(d) / |d| − reach, less the rounding
/// allowance of [`apart`] (`extent` as there), from `hi_a`, the largest
/// d · (a − origin) over A, and `lo_b`, the smallest d · (b − origin) over B
/// (each from [`Extreme`], with its own rounding already allowed for; the
/// origin a point near both); zero or less when the slab shows no
/// clearance. Two bodies that have moved, together, less than this since are
/// still farther apart than `reach`: each point moved at most its body's
/// travel, and the slab between them narrowed by at most the sum.
pub(crate) fn clearance(hi_a: f64, lo_b: f64, d: DVec3, reach: f64, extent: f64) -> f64 {
    let length = d.length();
    if !(length > 0.0 && length.is_finite()) {
        return 0.0;
    }
    let clearance = (lo_b - hi_a) / length - (reach + MARGIN * (extent + reach));
    if clearance.is_finite() {
        clearance
    } else {
        0.0
    }
}

/// One side of the slab of [`clearance`]: the extreme of d · (p − origin)
/// over a body's points, the largest (`upper`) or the smallest.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Extreme {
    pub d: DVec3,
    pub origin: DVec3,
    pub upper: bool,
}

impl Extreme {
    /// Over the corners of `triangles`.
    pub(crate) fn of_triangles<'t>(&self, triangles: impl Iterator<Item = &'t Triangle>) -> f64 {
        let (d, origin) = (self.d, self.origin);
        // One running extreme per corner: three chains the loop need not
        // wait on.
        let mut x = [if self.upper {
            f64::NEG_INFINITY
        } else {
            f64::INFINITY
        }; 3];
        for t in triangles {
            for k in 0..3 {
                let h = d.dot(t[k] - origin);
                x[k] = if self.upper { x[k].max(h) } else { x[k].min(h) };
            }
        }
        if self.upper {
            x[0].max(x[1]).max(x[2])
        } else {
            x[0].min(x[1]).min(x[2])
        }
    }

    /// Over the world points `position + rotation v` of a rigid body's
    /// vertices `local` (each at most `radius` from its origin), as d ·
    /// (position − origin) + (rotationᵀ d) · v: each vertex once, where the
    /// triangles have each about six times. The points the triangle set
    /// holds are those sums rounded, so the result is widened by a bound on
    /// the difference: 32 ε |d| (|position| + |position − origin| +
    /// 2 radius), twice the sum of the sums' and the dot products' own
    /// rounding.
    pub(crate) fn of_posed(
        &self,
        local: &[DVec3],
        position: DVec3,
        rotation: DMat3,
        radius: f64,
    ) -> f64 {
        let (d, upper) = (self.d, self.upper);
        let along = rotation.transpose() * d;
        let mut x = [if upper {
            f64::NEG_INFINITY
        } else {
            f64::INFINITY
        }; 4];
        let mut chunks = local.chunks_exact(4);
        for c in &mut chunks {
            for k in 0..4 {
                let h = along.dot(c[k]);
                x[k] = if upper { x[k].max(h) } else { x[k].min(h) };
            }
        }
        for v in chunks.remainder() {
            let h = along.dot(*v);
            x[0] = if upper { x[0].max(h) } else { x[0].min(h) };
        }
        let rel = position - self.origin;
        let slack =
            32.0 * f64::EPSILON * d.length() * (position.length() + rel.length() + 2.0 * radius);
        if upper {
            d.dot(rel) + x[0].max(x[1]).max(x[2].max(x[3])) + slack
        } else {
            d.dot(rel) + x[0].min(x[1]).min(x[2].min(x[3])) - slack
        }
    }
}

/// GJK from direction `v` (a point of A − B, or near one): the verdict, and
/// the last direction.
fn search(a: &[DVec3], b: &[DVec3], origin: DVec3, reach: f64, mut v: DVec3) -> (bool, DVec3) {
    let mut simplex = Simplex::default();
    for _ in 0..MAX_ITERATIONS {
        let vv = v.length_squared();
        if vv.is_nan() || vv <= 0.0 {
            return (false, v); // touching or overlapping (or not finite)
        }
        // The point of A − B least along v: its projection is the lower
        // bound gap(−v) (module doc).
        let w = farthest(a, -v, origin) - farthest(b, v, origin);
        let length = vv.sqrt();
        let lower = v.dot(w);
        if lower > reach * length {
            return (certified(a, b, -v, origin, reach), v);
        }
        // Upper bound |v|: within reach, or no progress left to make.
        if length <= reach || vv - lower <= 1e-12 * vv || simplex.holds(w) {
            return (false, v);
        }
        simplex.push(w);
        match simplex.nearest_to_origin() {
            Some(next) => v = next,
            None => return (false, v),
        }
    }
    (false, v)
}

/// The certificate of the module doc for direction `d`, recomputed from the
/// points: a verdict "apart" stands only if the points themselves confirm
/// it. Four running extremes each, so that the loops do not wait on one.
fn certified(a: &[DVec3], b: &[DVec3], d: DVec3, origin: DVec3, reach: f64) -> bool {
    let along = |p: &DVec3| d.dot(*p - origin);
    let hi_a = extreme(a, along, f64::NEG_INFINITY, f64::max);
    let lo_b = extreme(b, along, f64::INFINITY, f64::min);
    lo_b - hi_a > reach * d.length()
}

/// `pick` over `f` of all `points`, in four independent chains.
#[inline]
fn extreme(
    points: &[DVec3],
    f: impl Fn(&DVec3) -> f64,
    start: f64,
    pick: fn(f64, f64) -> f64,
) -> f64 {
    let mut acc = [start; 4];
    let chunks = points.chunks_exact(4);
    let rest = chunks.remainder();
    for c in chunks {
        for k in 0..4 {
            acc[k] = pick(acc[k], f(&c[k]));
        }
    }
    for p in rest {
        acc[0] = pick(acc[0], f(p));
    }
    pick(pick(acc[0], acc[1]), pick(acc[2], acc[3]))
}

/// The point of `points` farthest along `d`, relative to `origin`.
#[inline]
fn farthest(points: &[DVec3], d: DVec3, origin: DVec3) -> DVec3 {
    let mut best = points[0] - origin;
    let mut best_dot = d.dot(best);
    for p in &points[1..] {
        let q = *p - origin;
        let s = d.dot(q);
        if s > best_dot {
            best = q;
            best_dot = s;
        }
    }
    best
}

/// Up to four points of the Minkowski difference.
#[derive(Default)]
struct Simplex {
    points: [DVec3; 4],
    len: usize,
}

impl Simplex {
    fn holds(&self, w: DVec3) -> bool {
        self.points[..self.len].contains(&w)
    }

    fn push(&mut self, w: DVec3) {
        self.points[self.len] = w;
        self.len += 1;
    }

    /// Reduces the simplex to the smallest face holding its point nearest
    /// the origin and returns that point; `None` if the origin is inside (or
    /// the simplex is degenerate beyond repair).
    fn nearest_to_origin(&mut self) -> Option<DVec3> {
        let p = self.points;
        let (kept, point) = match self.len {
            1 => (vec_of(&[0]), p[0]),
            2 => segment(p[0], p[1]),
            3 => triangle(p[0], p[1], p[2]),
            _ => tetrahedron(p)?,
        };
        let mut next = [DVec3::ZERO; 4];
        for (slot, &k) in next.iter_mut().zip(&kept.0[..kept.1]) {
            *slot = p[k];
        }
        self.points = next;
        self.len = kept.1;
        point.is_finite().then_some(point)
    }
}

/// Indices of the kept points, and how many.
type Kept = ([usize; 4], usize);

fn vec_of(ids: &[usize]) -> Kept {
    let mut k = [0; 4];
    k[..ids.len()].copy_from_slice(ids);
    (k, ids.len())
}

/// Nearest point to the origin on segment ab.
fn segment(a: DVec3, b: DVec3) -> (Kept, DVec3) {
    let ab = b - a;
    let t = -a.dot(ab);
    if t <= 0.0 {
        return (vec_of(&[0]), a);
    }
    let len2 = ab.length_squared();
    if t >= len2 {
        return (vec_of(&[1]), b);
    }
    (vec_of(&[0, 1]), a + ab * (t / len2))
}

/// Nearest point to the origin on triangle abc (Ericson, Real-Time Collision
/// Detection, 5.1.5, with p at the origin).
fn triangle(a: DVec3, b: DVec3, c: DVec3) -> (Kept, DVec3) {
    let (ab, ac, ap) = (b - a, c - a, -a);
    let (d1, d2) = (ab.dot(ap), ac.dot(ap));
    if d1 <= 0.0 && d2 <= 0.0 {
        return (vec_of(&[0]), a);
    }
    let bp = -b;
    let (d3, d4) = (ab.dot(bp), ac.dot(bp));
    if d3 >= 0.0 && d4 <= d3 {
        return (vec_of(&[1]), b);
    }
    let vc = d1 * d4 - d3 * d2;
    if vc <= 0.0 && d1 >= 0.0 && d3 <= 0.0 {
        let t = d1 / (d1 - d3);
        return (vec_of(&[0, 1]), a + ab * t);
    }
    let cp = -c;
    let (d5, d6) = (ab.dot(cp), ac.dot(cp));
    if d6 >= 0.0 && d5 <= d6 {
        return (vec_of(&[2]), c);
    }
    let vb = d5 * d2 - d1 * d6;
    if vb <= 0.0 && d2 >= 0.0 && d6 <= 0.0 {
        let t = d2 / (d2 - d6);
        return (vec_of(&[0, 2]), a + ac * t);
    }
    let va = d3 * d6 - d5 * d4;
    if va <= 0.0 && (d4 - d3) >= 0.0 && (d5 - d6) >= 0.0 {
        let t = (d4 - d3) / ((d4 - d3) + (d5 - d6));
        return (vec_of(&[1, 2]), b + (c - b) * t);
    }
    let denom = 1.0 / (va + vb + vc);
    let (v, w) = (vb * denom, vc * denom);
    (vec_of(&[0, 1, 2]), a + ab * v + ac * w)
}

/// Nearest point to the origin on tetrahedron p; `None` if the origin is
/// inside.
fn tetrahedron(p: [DVec3; 4]) -> Option<(Kept, DVec3)> {
    // Faces with the vertex opposite each: the origin is outside a face if
    // it lies on the other side of the face's plane from that vertex.
    const FACES: [([usize; 3], usize); 4] = [
        ([0, 1, 2], 3),
        ([0, 1, 3], 2),
        ([0, 2, 3], 1),
        ([1, 2, 3], 0),
    ];
    let mut best: Option<(Kept, DVec3)> = None;
    for (face, opposite) in FACES {
        let [i, j, k] = face;
        let n = (p[j] - p[i]).cross(p[k] - p[i]);
        let origin_side = n.dot(-p[i]);
        let vertex_side = n.dot(p[opposite] - p[i]);
        if origin_side * vertex_side >= 0.0 {
            continue; // the origin is on the tetrahedron's side of this face
        }
        let ((ids, len), q) = triangle(p[i], p[j], p[k]);
        if best.is_none_or(|(_, b)| q.length_squared() < b.length_squared()) {
            let mut kept = [0; 4];
            for (slot, &m) in kept.iter_mut().zip(&ids[..len]) {
                *slot = face[m];
            }
            best = Some(((kept, len), q));
        }
    }
    best
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::{distance_triangle_triangle, Triangle};

    /// A search with no direction to start from.
    fn no_hint() -> DVec3 {
        DVec3::ZERO
    }

    fn extent(a: &[DVec3], b: &[DVec3]) -> f64 {
        let all: Vec<DVec3> = a.iter().chain(b).copied().collect();
        let lo = all.iter().fold(DVec3::INFINITY, |m, p| m.min(*p));
        let hi = all.iter().fold(DVec3::NEG_INFINITY, |m, p| m.max(*p));
        (hi - lo).length()
    }

    /// A cloud of points around `centre`: a deterministic jittered sphere.
    fn cloud(centre: DVec3, radius: f64, n: usize, seed: u64) -> Vec<DVec3> {
        let mut s = seed.wrapping_mul(6364136223846793005).wrapping_add(1);
        let mut next = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64) / ((1u64 << 53) as f64) * 2.0 - 1.0
        };
        (0..n)
            .map(|_| {
                let d = DVec3::new(next(), next(), next());
                centre + d * radius
            })
            .collect()
    }

    /// The distance between two clouds' hulls, from below: the largest of
    /// the triangle-triangle distances is not it, but the smallest over all
    /// triangles of corners is an upper bound, and the hull distance of two
    /// clouds is at most that. An independent lower bound comes from a
    /// dense sweep of directions.
    fn brute_bounds(a: &[DVec3], b: &[DVec3]) -> (f64, f64) {
        let mut upper = f64::INFINITY;
        let (ta, tb) = (triangles_of(a), triangles_of(b));
        for x in &ta {
            for y in &tb {
                upper = upper.min(distance_triangle_triangle(x, y).distance);
            }
        }
        let mut lower = 0.0f64;
        let steps = 60;
        for i in 0..steps {
            for j in 0..2 * steps {
                let (th, ph) = (
                    std::f64::consts::PI * (i as f64 + 0.5) / steps as f64,
                    std::f64::consts::PI * j as f64 / steps as f64,
                );
                let d = DVec3::new(th.sin() * ph.cos(), th.sin() * ph.sin(), th.cos());
                let hi_a = a.iter().map(|p| d.dot(*p)).fold(f64::MIN, f64::max);
                let lo_b = b.iter().map(|p| d.dot(*p)).fold(f64::MAX, f64::min);
                lower = lower.max(lo_b - hi_a);
            }
        }
        (lower, upper)
    }

    /// The verdict agrees with independent bounds on the hulls' distance:
    /// never "apart" when some triangle pair is within reach, always "apart"
    /// when a direction sweep proves the gap clearly larger than the reach.
    #[test]
    fn verdicts_agree_with_brute_force_bounds() {
        let mut apart_seen = 0;
        let mut near_seen = 0;
        for seed in 0..60u64 {
            let a = cloud(DVec3::ZERO, 1.0, 7, seed);
            let offset = DVec3::new(
                1.5 + (seed % 7) as f64 * 0.1,
                (seed % 3) as f64 * 0.3,
                -((seed % 5) as f64) * 0.2,
            );
            let b = cloud(offset, 1.0, 7, seed + 1000);
            let (lower, upper) = brute_bounds(&a, &b);
            for reach in [0.0, 0.05, 0.2] {
                let verdict = apart(&a, &b, reach, extent(&a, &b), &mut no_hint());
                assert!(
                    !(verdict && upper < reach),
                    "seed {seed}: culled a pair {upper} apart at reach {reach}"
                );
                if lower > reach * 1.01 + 1e-12 {
                    assert!(verdict, "seed {seed}: {lower} apart, reach {reach}");
                    apart_seen += 1;
                }
                if upper < reach {
                    near_seen += 1;
                }
            }
        }
        assert!(apart_seen > 20 && near_seen > 5, "{apart_seen} {near_seen}");
    }

    /// Scale and place do not matter: the same configuration from 1e-6 to
    /// 1e6, far from the origin, gets the same verdicts.
    #[test]
    fn verdicts_hold_at_every_scale_and_place() {
        let a = cloud(DVec3::ZERO, 1.0, 12, 3);
        let b = cloud(DVec3::new(2.2, 0.3, 0.1), 1.0, 12, 4);
        let (lower, upper) = brute_bounds(&a, &b);
        assert!(lower > 0.0);
        for scale in [1e-6, 1e-3, 1.0, 1e3, 1e6] {
            for far in [0.0, 1e3] {
                let shift = DVec3::new(far, -far, far) * scale;
                let map = |p: &Vec<DVec3>| -> Vec<DVec3> {
                    p.iter().map(|q| *q * scale + shift).collect()
                };
                let (sa, sb) = (map(&a), map(&b));
                assert!(
                    apart(
                        &sa,
                        &sb,
                        0.5 * lower * scale,
                        extent(&sa, &sb),
                        &mut no_hint()
                    ),
                    "{scale} {far}"
                );
                assert!(
                    !apart(
                        &sa,
                        &sb,
                        1.01 * upper * scale,
                        extent(&sa, &sb),
                        &mut no_hint()
                    ),
                    "{scale} {far}"
                );
            }
        }
    }

    /// All triangles with corners among the points.
    fn triangles_of(p: &[DVec3]) -> Vec<Triangle> {
        let mut out = Vec::new();
        for i in 0..p.len() {
            for j in i + 1..p.len() {
                for k in j + 1..p.len() {
                    out.push([p[i], p[j], p[k]]);
                }
            }
        }
        out
    }

    /// The smallest distance between a triangle of `a` and one of `b`,
    /// by the exact kernel on every pair.
    fn nearest(a: &[Triangle], b: &[Triangle]) -> f64 {
        let pairs = a.iter().flat_map(|x| b.iter().map(move |y| (x, y)));
        pairs
            .map(|(x, y)| distance_triangle_triangle(x, y).distance)
            .fold(f64::INFINITY, f64::min)
    }

    /// The clearance after a verdict "apart" is a true one, at every scale
    /// and far from the origin: B moved towards A along the slab's normal
    /// (the way that uses it up fastest) by 0.999 of it stays farther than
    /// the reach from A by the exact kernel; and it is no more than the
    /// bodies' distance less the reach.
    #[test]
    fn clearance_is_never_more_than_the_bodies_have() {
        let mut shown = 0;
        for seed in 0..20u64 {
            let a = cloud(DVec3::ZERO, 1.0, 6, seed);
            let b = cloud(
                DVec3::new(2.4, 0.2 * (seed % 3) as f64, 0.1),
                1.0,
                6,
                seed + 50,
            );
            for (scale, far) in [(1.0, 0.0), (1e-6, 1e3), (1e6, 1e3)] {
                let map = |p: &[DVec3]| -> Vec<DVec3> {
                    p.iter().map(|q| (*q + DVec3::splat(far)) * scale).collect()
                };
                let (sa, sb) = (map(&a), map(&b));
                let (ta, tb) = (triangles_of(&sa), triangles_of(&sb));
                let reach = 0.05 * scale;
                let mut d = DVec3::ZERO;
                if !apart(&sa, &sb, reach, extent(&sa, &sb), &mut d) {
                    continue;
                }
                let side = |upper| Extreme {
                    d,
                    origin: sa[0],
                    upper,
                };
                let (hi_a, lo_b) = (
                    side(true).of_triangles(ta.iter()),
                    side(false).of_triangles(tb.iter()),
                );
                let c = clearance(hi_a, lo_b, d, reach, extent(&sa, &sb));
                let gap = nearest(&ta, &tb);
                assert!(c <= gap - reach, "seed {seed} scale {scale}: {c} of {gap}");
                if c <= 0.0 {
                    continue;
                }
                let step = -d.normalize() * (0.999 * c);
                let moved: Vec<Triangle> = tb.iter().map(|t| t.map(|p| p + step)).collect();
                let now = nearest(&ta, &moved);
                assert!(
                    now > reach,
                    "seed {seed} scale {scale}: {now} within {reach}"
                );
                shown += 1;
            }
        }
        assert!(shown > 30, "{shown}");
    }

    /// A rigid body's extreme along a direction from its local vertices and
    /// pose bounds the extreme over its world points as the triangle set
    /// rounds them (x + R v), on the right side, and is within a few units
    /// of rounding of it: at every scale, turned, and far from the origin.
    #[test]
    fn a_posed_extreme_bounds_the_rounded_world_points_and_is_tight() {
        for seed in 0..30u64 {
            let local = cloud(DVec3::ZERO, 1.0, 40, seed);
            let radius = local.iter().map(|v| v.length()).fold(0.0, f64::max);
            let q = glam::DQuat::from_axis_angle(
                DVec3::new(1.0, 0.3 * seed as f64, -0.7).normalize(),
                0.37 * seed as f64,
            );
            let rotation = DMat3::from_quat(q);
            for (scale, far) in [(1.0, 0.0), (1e-6, 1e4), (1e6, 1e4), (1.0, 1e7)] {
                let local: Vec<DVec3> = local.iter().map(|v| *v * scale).collect();
                let position = DVec3::new(far, -0.5 * far, 0.25 * far) * scale;
                let world: Vec<DVec3> = local.iter().map(|v| position + rotation * *v).collect();
                let origin = world[(seed % 40) as usize] + DVec3::splat(0.1 * scale);
                let d = DVec3::new(0.2, -1.0, 0.4 + 0.1 * seed as f64) * (seed as f64 + 0.5);
                for upper in [true, false] {
                    let side = Extreme { d, origin, upper };
                    let posed = side.of_posed(&local, position, rotation, radius * scale);
                    let dots = world.iter().map(|p| d.dot(*p - origin));
                    let exact = if upper {
                        dots.fold(f64::NEG_INFINITY, f64::max)
                    } else {
                        dots.fold(f64::INFINITY, f64::min)
                    };
                    let wider = if upper {
                        posed >= exact
                    } else {
                        posed <= exact
                    };
                    let unit = f64::EPSILON * d.length() * (position.length() + radius * scale);
                    assert!(
                        wider,
                        "seed {seed} scale {scale} far {far}: {posed} vs {exact}"
                    );
                    assert!(
                        (posed - exact).abs() <= 200.0 * unit,
                        "seed {seed} scale {scale} far {far}: {posed} vs {exact}, unit {unit}"
                    );
                }
            }
        }
    }

    /// Touching and overlapping hulls are never apart, at any reach.
    #[test]
    fn overlapping_hulls_are_never_apart() {
        let a = cloud(DVec3::ZERO, 1.0, 10, 5);
        for (k, shift) in [0.0, 0.5, 1.0, 1.9].into_iter().enumerate() {
            // B holds a point of A's hull (A's centroid): the hulls overlap.
            let mut b = cloud(DVec3::new(shift, 0.0, 0.0), 1.0, 10, 6 + k as u64);
            b.push(a.iter().sum::<DVec3>() / a.len() as f64);
            assert!(
                !apart(&a, &b, 0.0, extent(&a, &b), &mut no_hint()),
                "shift {shift}"
            );
        }
        let corner = vec![DVec3::new(1.0, 1.0, 1.0)];
        let cube: Vec<DVec3> = (0..8)
            .map(|i| DVec3::new((i & 1) as f64, ((i >> 1) & 1) as f64, (i >> 2) as f64))
            .collect();
        assert!(
            !apart(&cube, &corner, 0.0, extent(&cube, &corner), &mut no_hint()),
            "a shared corner touches"
        );
    }
}
