//! The exact finish and the certificate of a batch of penalty answers.
//!
//! Newton on the penalty formulation lands near the minimiser with constraint
//! violations of order 1/penalty. What it reliably gives is *which* features
//! are closest: a constraint that is active (violated or nearly so) puts the
//! point on an edge, two put it on a vertex, none leave it inside the face.
//!
//! The finish makes those constraints equalities and minimises exactly on the
//! feature pair: each triangle's point becomes x = beta + t1 c1 + t2 c2 in its
//! barycentric parameters, with beta a vertex and c1, c2 the free directions of
//! the feature (both for a face, one for an edge, none for a vertex; a fixed
//! direction is a zero column). The reduced least-squares problem
//! min |r(t)|^2 + delta |t - t_newton|^2 is one solve of the same 4x4 kind as a
//! Newton step; delta (1e-12 of the scale) only picks Newton's point among
//! equally close ones where the minimiser is not unique (parallel features,
//! crossing faces). A second round from the first's result corrects the
//! features when Newton's were slightly off. The parameters are then clamped
//! onto the triangles, so both points always lie on them.
//!
//! The certificate ([`super::certified_error_bound`], here for lanes, with the
//! directions of the feature pair) then bounds the error of |P - Q| rigorously;
//! the pair counts as converged when the bound is within `tol * L`.

use super::certificate::separation_proves;
use super::lanes::{F, M, V3};
use super::penalty::{Batch, PenaltyParams};
use super::solve_spd4::{solve_spd4, Sym4, SYM4_INDEX};

/// A constraint within this much (in barycentric units) of being violated counts as active.
const ACTIVE: f64 = 1e-9;

/// Regularisation of the finish towards Newton's point, relative to the scale.
const FINISH_REGULARISATION: f64 = 1e-12;

/// Per lane: closest points in the local frame, distance, verdict.
pub(crate) struct Finished<const N: usize> {
    pub p: V3<N>,
    pub q: V3<N>,
    pub distance: F<N>,
    pub certified: M<N>,
}

/// The feature the parameters (x, y) of a triangle point to, as an affine map
/// (x, y) = beta + t1 c1 + t2 c2 of the free parameters t = (x, y), with
/// c1 = (k1, 0) and c2 = (c2x, k2).
struct FeatureMap<const N: usize> {
    beta: [F<N>; 2],
    k1: F<N>,
    c2x: F<N>,
    k2: F<N>,
}

impl<const N: usize> FeatureMap<N> {
    #[inline(always)]
    fn of(x: F<N>, y: F<N>) -> Self {
        let on_x0 = x.le(F::splat(ACTIVE)); // x = 0: edge v0-v2
        let on_y0 = y.le(F::splat(ACTIVE)); // y = 0: edge v0-v1
        let on_sum = (x + y).ge(F::splat(1.0 - ACTIVE)); // x + y = 1: edge v1-v2
                                                         // x is free on the face and on the edge y = 0.
        let k1 = (!on_x0 & !on_sum).to_f();
        // y is free on the face and on the edges x = 0 and x + y = 1 (x = 1 - y there).
        let k2 = (!on_y0 & !(on_x0 & on_sum)).to_f();
        let c2x = -(k2 * on_sum.to_f());
        // The base: vertex v1 = (1, 0) for the edge v1-v2 or the vertex v1; v2 = (0, 1).
        let beta = [(on_sum & !on_x0).to_f(), (on_sum & on_x0 & !on_y0).to_f()];
        FeatureMap { beta, k1, c2x, k2 }
    }

    /// (x, y) at free parameters (t1, t2).
    #[inline(always)]
    fn at(&self, t1: F<N>, t2: F<N>) -> [F<N>; 2] {
        [
            self.beta[0] + self.k1 * t1 + self.c2x * t2,
            self.beta[1] + self.k2 * t2,
        ]
    }

    /// The point's derivatives along t1 and t2, for edge vectors e1, e2.
    #[inline(always)]
    fn columns(&self, e1: V3<N>, e2: V3<N>) -> [V3<N>; 2] {
        [e1.scale(self.k1), e1.scale(self.c2x) + e2.scale(self.k2)]
    }
}

/// Minimises exactly on the feature pair that the parameters `t0` point to,
/// regularised towards `t0`; returns the new (unclamped) parameters.
#[inline(always)]
fn solve_on_features<const N: usize>(batch: &Batch<N>, t0: [F<N>; 4], delta: F<N>) -> [F<N>; 4] {
    let u = &batch.u;
    let fa = FeatureMap::of(t0[0], t0[1]);
    let fb = FeatureMap::of(t0[2], t0[3]);
    let [ca1, ca2] = fa.columns(u[0], u[1]);
    let [cb1, cb2] = fb.columns(u[2], u[3]);
    let cols = [ca1, ca2, cb1, cb2];
    // The residual at t0's image on the features.
    let [x0, y0] = fa.at(t0[0], t0[1]);
    let [z0, v0] = fb.at(t0[2], t0[3]);
    let r = batch.w + u[0].scale(x0) + u[1].scale(y0) + u[2].scale(z0) + u[3].scale(v0);
    let mut g: Sym4<N> = [F::splat(0.0); 10];
    for (k, &(i, j)) in SYM4_INDEX.iter().enumerate() {
        g[k] = cols[i].dot(cols[j]);
    }
    for k in [0, 4, 7, 9] {
        g[k] = g[k] + delta;
    }
    let rhs = [
        -cols[0].dot(r),
        -cols[1].dot(r),
        -cols[2].dot(r),
        -cols[3].dot(r),
    ];
    let dt = solve_spd4(&g, rhs);
    let [x, y] = fa.at(t0[0] + dt[0], t0[1] + dt[1]);
    let [z, v] = fb.at(t0[2] + dt[2], t0[3] + dt[3]);
    [x, y, z, v]
}

/// The direction of the edge the parameters (x, y) point to (for a face or a
/// vertex some other vector: any direction gives a valid bound).
#[inline(always)]
fn feature_edge<const N: usize>(x: F<N>, y: F<N>, e1: V3<N>, e2: V3<N>) -> V3<N> {
    let [c1, c2] = FeatureMap::of(x, y).columns(e1, e2);
    c1 + c2
}

/// A candidate answer: the points of the clamped parameters and their distance.
struct Candidate<const N: usize> {
    t: [F<N>; 4],
    p: V3<N>,
    q: V3<N>,
    distance: F<N>,
    certified: M<N>,
}

impl<const N: usize> Candidate<N> {
    /// The points at parameters `t` (clamped onto the triangles), certified by
    /// the direction P - Q alone.
    #[inline(always)]
    fn at(batch: &Batch<N>, t: [F<N>; 4], tol: F<N>) -> Self {
        let u = &batch.u;
        let [a, b] = clamp_simplex(t[0], t[1]);
        let [c, d] = clamp_simplex(t[2], t[3]);
        // P = a u0 + b u1 (A0 is the origin); Q = B0 + c (B1-B0) + d (B2-B0).
        let b0 = -batch.w;
        let p = u[0].scale(a) + u[1].scale(b);
        let q = b0 - u[2].scale(c) - u[3].scale(d);
        let n = p - q;
        let distance = n.dot(n).sqrt();
        // NaN anywhere makes the comparison false.
        let certified = separation_proves(n, u, b0, distance - tol) & distance.finite();
        Candidate {
            t,
            p,
            q,
            distance,
            certified,
        }
    }

    /// Tries the directions of the feature pair: both face normals and the
    /// cross product of the two features' edge directions.
    #[inline(always)]
    fn certify_by_features(&mut self, batch: &Batch<N>, tol: F<N>) {
        let (u, b0, t) = (&batch.u, -batch.w, self.t);
        let ea = feature_edge(t[0], t[1], u[0], u[1]);
        let eb = feature_edge(t[2], t[3], u[2], u[3]);
        let need = self.distance - tol;
        let proven = separation_proves(u[0].cross(u[1]), u, b0, need)
            | separation_proves(u[2].cross(u[3]), u, b0, need)
            | separation_proves(ea.cross(eb), u, b0, need);
        self.certified = self.certified | (proven & self.distance.finite());
    }

    #[inline(always)]
    fn all_certified(&self) -> bool {
        self.certified.all()
    }

    /// Per lane, `other` where this one is not certified and `other` is
    /// certified or closer (both are pairs of points on the triangles, so the
    /// smaller distance is the better answer).
    #[inline(always)]
    fn improve_with(&mut self, other: &Candidate<N>) {
        let take = !self.certified & (other.certified | other.distance.lt(self.distance));
        for k in 0..3 {
            self.p.0[k] = take.select(other.p.0[k], self.p.0[k]);
            self.q.0[k] = take.select(other.q.0[k], self.q.0[k]);
        }
        self.distance = take.select(other.distance, self.distance);
        self.certified = self.certified | other.certified;
    }
}

/// Finish and certify Newton's parameters `s`; `scale` is trace(G) / 4.
///
/// The cheap certificate (direction P - Q) settles most lanes; the feature
/// directions and the second round of the finish are computed only for
/// batches that still have uncertified lanes, and change only those lanes, so
/// a pair's answer never depends on the other pairs of its batch.
#[inline(always)]
pub(crate) fn finish_lanes<const N: usize>(
    batch: &Batch<N>,
    s: [F<N>; 4],
    scale: F<N>,
    prm: &PenaltyParams,
) -> Finished<N> {
    // Newton cannot produce NaN from finite input with delta > 0, but
    // overflowing input must not turn into NaN points.
    let finite = s[0].finite() & s[1].finite() & s[2].finite() & s[3].finite();
    let third = F::splat(1.0 / 3.0);
    let mut t = [
        finite.select(s[0], third),
        finite.select(s[1], third),
        finite.select(s[2], third),
        finite.select(s[3], third),
    ];
    let tol = pair_scale(batch.w, &batch.u) * prm.tol;
    let delta = scale * FINISH_REGULARISATION;
    if prm.finish_rounds > 0 {
        t = solve_on_features(batch, t, delta);
    }
    let mut best = Candidate::at(batch, t, tol);
    if !best.all_certified() {
        best.certify_by_features(batch, tol);
    }
    for _ in 1..prm.finish_rounds {
        if best.all_certified() {
            break;
        }
        t = solve_on_features(batch, t, delta);
        let mut next = Candidate::at(batch, t, tol);
        if !next.all_certified() {
            next.certify_by_features(batch, tol);
        }
        best.improve_with(&next);
    }
    Finished {
        p: best.p,
        q: best.q,
        distance: best.distance,
        certified: best.certified,
    }
}

/// Projects barycentric parameters onto the simplex a, b >= 0, a + b <= 1.
#[inline(always)]
fn clamp_simplex<const N: usize>(a: F<N>, b: F<N>) -> [F<N>; 2] {
    let zero = F::splat(0.0);
    let (a, b) = (a.max(zero), b.max(zero));
    let sum = a + b;
    let inv = sum.gt(F::splat(1.0)).select(1.0 / sum, F::splat(1.0));
    [a * inv, b * inv]
}

/// The diagonal of the bounding box of the six vertices: 0, u0, u1 (A) and
/// -w, -w - u2, -w - u3 (B).
#[inline(always)]
fn pair_scale<const N: usize>(w: V3<N>, u: &[V3<N>; 4]) -> F<N> {
    let mut ss = F::splat(0.0);
    for k in 0..3 {
        let b0 = -w.0[k];
        let (b1, b2) = (b0 - u[2].0[k], b0 - u[3].0[k]);
        let zero = F::splat(0.0);
        let lo = zero.min(u[0].0[k]).min(u[1].0[k]).min(b0).min(b1).min(b2);
        let hi = zero.max(u[0].0[k]).max(u[1].0[k]).max(b0).max(b1).max(b2);
        ss = ss + (hi - lo) * (hi - lo);
    }
    ss.sqrt()
}
