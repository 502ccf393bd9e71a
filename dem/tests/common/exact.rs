//! Exact rational arithmetic for the checks that double precision cannot make
//! on the hardest cases (points on slivers): an independent reference.

use dem::distance::Triangle;
use glam::DVec3;
use num_bigint::BigInt;
use num_rational::BigRational;
use num_traits::{ToPrimitive, Zero};

type Q = BigRational;
type V = [Q; 3];

fn q(x: f64) -> Q {
    BigRational::from_float(x).expect("finite coordinate")
}

fn v(p: DVec3) -> V {
    [q(p.x), q(p.y), q(p.z)]
}

fn sub(a: &V, b: &V) -> V {
    [&a[0] - &b[0], &a[1] - &b[1], &a[2] - &b[2]]
}

fn dot(a: &V, b: &V) -> Q {
    &a[0] * &b[0] + &a[1] * &b[1] + &a[2] * &b[2]
}

fn axpy(p: &V, t: &Q, d: &V) -> V {
    [&p[0] + t * &d[0], &p[1] + t * &d[1], &p[2] + t * &d[2]]
}

/// Squared distance from x to the segment p0-p1, exactly.
fn seg_dist2(x: &V, p0: &V, p1: &V) -> Q {
    let d = sub(p1, p0);
    let dd = dot(&d, &d);
    let r = sub(x, p0);
    let mut t = if dd.is_zero() {
        Q::zero()
    } else {
        dot(&r, &d) / &dd
    };
    let one = Q::from_integer(BigInt::from(1));
    if t < Q::zero() {
        t = Q::zero();
    }
    if t > one {
        t = one;
    }
    let c = axpy(p0, &t, &d);
    let e = sub(x, &c);
    dot(&e, &e)
}

/// Distance from `p` to triangle `t`, exact up to the final rounding to f64.
///
/// The closest point is the projection onto the plane when that lies inside
/// (all barycentric coordinates >= 0), else the closest point of an edge.
pub fn exact_offset_from_triangle(p: DVec3, t: &Triangle) -> f64 {
    let x = v(p);
    let a = [v(t[0]), v(t[1]), v(t[2])];
    let e1 = sub(&a[1], &a[0]);
    let e2 = sub(&a[2], &a[0]);
    let r = sub(&x, &a[0]);
    let (d11, d12, d22) = (dot(&e1, &e1), dot(&e1, &e2), dot(&e2, &e2));
    let (b1, b2) = (dot(&r, &e1), dot(&r, &e2));
    let den = &d11 * &d22 - &d12 * &d12;
    let mut best: Option<Q> = None;
    if !den.is_zero() {
        let s = (&d22 * &b1 - &d12 * &b2) / &den;
        let u = (&d11 * &b2 - &d12 * &b1) / &den;
        let one = Q::from_integer(BigInt::from(1));
        if s >= Q::zero() && u >= Q::zero() && &s + &u <= one {
            let c = axpy(&axpy(&a[0], &s, &e1), &u, &e2);
            let e = sub(&x, &c);
            best = Some(dot(&e, &e));
        }
    }
    let best = best.unwrap_or_else(|| {
        (0..3)
            .map(|i| seg_dist2(&x, &a[i], &a[(i + 1) % 3]))
            .min()
            .expect("three edges")
    });
    best.to_f64().expect("representable").sqrt()
}
