//! Exact minimum distance between two triangles by brute force.
//!
//! The distance between two triangles that do not intersect is attained by one
//! of 15 feature pairs: a vertex of one against the other triangle (6) or an
//! edge of each (9). When the triangles intersect the distance is 0, and either
//! an edge of one pierces the other (found by the segment-plane test below) or,
//! for touching and coplanar overlapping triangles, one of the 15 pairs is
//! already at distance 0.
//!
//! Everything is computed relative to the first vertex of `a`: coordinates far
//! from the origin become small differences, which are exact for nearby floats,
//! so accuracy depends on the pair's own size, not on where it sits.

use super::closest_point_segment_segment::segment_segment_params;
use super::closest_point_triangle::PreparedTriangle;
use super::{Closest, Solver, Triangle};
use glam::DVec3;

/// Minimum distance between triangles `a` and `b`, with closest points `p` on
/// `a` and `q` on `b`. Degenerate triangles (collinear or coincident vertices)
/// are treated as the segment or point they are. Never NaN for finite input.
pub fn distance_triangle_triangle(a: &Triangle, b: &Triangle) -> Closest {
    let o = a[0];
    let ta = [DVec3::ZERO, a[1] - o, a[2] - o];
    let tb = [b[0] - o, b[1] - o, b[2] - o];
    let (p, q) = closest_local(&ta, &tb);
    Closest {
        distance: (p - q).length(),
        p: p + o,
        q: q + o,
        solver: Solver::Brute,
    }
}

/// Closest points of two triangles given in a common local frame.
fn closest_local(ta: &Triangle, tb: &Triangle) -> (DVec3, DVec3) {
    let (pa, pb) = (PreparedTriangle::new(ta), PreparedTriangle::new(tb));
    let mut best = f64::INFINITY;
    let mut pq = (ta[0], tb[0]);
    let mut consider = |p: DVec3, q: DVec3| {
        let d = (p - q).length_squared();
        if d < best {
            best = d;
            pq = (p, q);
        }
    };
    for i in 0..3 {
        for j in 0..3 {
            let (s, t) = segment_segment_params(
                pa.v[i],
                pa.e[i],
                pa.inv_ee[i],
                pb.v[j],
                pb.e[j],
                pb.inv_ee[j],
            );
            consider(pa.v[i] + pa.e[i] * s, pb.v[j] + pb.e[j] * t);
        }
    }
    // A vertex against the other triangle's boundary is already covered by the
    // edge-edge pairs (the vertex ends two edges), so only interior projections
    // are new candidates.
    for &v in ta {
        if let Some(q) = pb.project_inside(v) {
            consider(v, q);
        }
    }
    for &v in tb {
        if let Some(p) = pa.project_inside(v) {
            consider(p, v);
        }
    }
    if best > 0.0 {
        if let Some(x) = edge_piercing(&pa, &pb).or_else(|| edge_piercing(&pb, &pa)) {
            return (x, x);
        }
    }
    pq
}

/// A point where an edge of `s` crosses the interior of triangle `t`, if any.
///
/// Only strict crossings are looked for: an edge end lying on the plane is a
/// vertex-triangle pair, already measured. Near the boundary of `t` the sign
/// tests may go either way, but there an edge-edge pair is at distance zero to
/// rounding, so the answer is the same.
fn edge_piercing(s: &PreparedTriangle, t: &PreparedTriangle) -> Option<DVec3> {
    let (n, _, m) = t.plane?;
    let side = [
        n.dot(s.v[0] - t.v[0]),
        n.dot(s.v[1] - t.v[0]),
        n.dot(s.v[2] - t.v[0]),
    ];
    for i in 0..3 {
        let j = (i + 1) % 3;
        let (h0, h1) = (side[i], side[j]);
        if (h0 > 0.0 && h1 < 0.0) || (h0 < 0.0 && h1 > 0.0) {
            let x = s.v[i] + s.e[i] * (h0 / (h0 - h1));
            if (0..3).all(|k| m[k].dot(x - t.v[k]) >= 0.0) {
                return Some(x);
            }
        }
    }
    None
}
