//! The exact finish of a penalty answer.
//!
//! Newton on the penalty formulation lands near the minimiser with constraint
//! violations of order 1/penalty. What it reliably gives is *which* features
//! are closest: a constraint that is active (violated or nearly so) puts the
//! point on an edge, two put it on a vertex, none leave it inside the face.
//! The closest points of that feature pair are then computed exactly with the
//! same routines brute force uses, and the certificate decides whether the
//! identification was right.

use super::closest_point_triangle::closest_point_triangle;
use super::closest_points_segment_segment;
use super::penalty::{clamp_simplex, point_at, Params4};
use super::Triangle;
use glam::DVec3;

/// A constraint within this much (in barycentric units) of being violated counts as active.
const ACTIVE: f64 = 1e-9;

/// A feature of a triangle: the part the closest point lies on.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Feature {
    Vertex(DVec3),
    Edge(DVec3, DVec3),
    Face,
}

fn feature(t: &Triangle, a: f64, b: f64) -> Feature {
    let on_a0 = a <= ACTIVE; // a = 0: the edge t0-t2
    let on_b0 = b <= ACTIVE; // b = 0: the edge t0-t1
    let on_sum = a + b >= 1.0 - ACTIVE; // a + b = 1: the edge t1-t2
    match (on_a0, on_b0, on_sum) {
        (false, false, false) => Feature::Face,
        (true, false, false) => Feature::Edge(t[0], t[2]),
        (false, true, false) => Feature::Edge(t[0], t[1]),
        (false, false, true) => Feature::Edge(t[1], t[2]),
        (true, true, _) => Feature::Vertex(t[0]),
        (false, true, true) => Feature::Vertex(t[1]),
        (true, false, true) => Feature::Vertex(t[2]),
    }
}

/// Closest point of a feature of `t` to `x`.
fn closest_on(f: Feature, t: &Triangle, x: DVec3) -> DVec3 {
    match f {
        Feature::Vertex(v) => v,
        Feature::Edge(p0, p1) => closest_points_segment_segment(p0, p1, x, x).2,
        Feature::Face => closest_point_triangle(x, t),
    }
}

/// Closest points (P on `ta`, Q on `tb`) of the feature pair that Newton's
/// parameters `s` identify. Both points always lie on their triangles.
pub fn finish_on_features(ta: &Triangle, tb: &Triangle, s: Params4) -> (DVec3, DVec3) {
    let (a, b) = clamp_simplex(s[0], s[1]);
    let (c, d) = clamp_simplex(s[2], s[3]);
    let fa = feature(ta, s[0], s[1]);
    let fb = feature(tb, s[2], s[3]);
    let p0 = point_at(ta, (a, b));
    let q0 = point_at(tb, (c, d));
    match (fa, fb) {
        (Feature::Vertex(p), fb) => (p, closest_on(fb, tb, p)),
        (fa, Feature::Vertex(q)) => (closest_on(fa, ta, q), q),
        (Feature::Edge(a0, a1), Feature::Edge(b0, b1)) => {
            let (_, _, p, q) = closest_points_segment_segment(a0, a1, b0, b1);
            (p, q)
        }
        // A face against an edge or a face: the closest set may be a segment or
        // an area (parallel features). Project from the other side's Newton
        // point, then back, so both points lie on their features.
        (Feature::Face, fb) => {
            let q = closest_on(fb, tb, q0);
            let p = closest_point_triangle(q, ta);
            (p, closest_on(fb, tb, p))
        }
        (fa, Feature::Face) => {
            let p = closest_on(fa, ta, p0);
            let q = closest_point_triangle(p, tb);
            (closest_on(fa, ta, q), q)
        }
    }
}
