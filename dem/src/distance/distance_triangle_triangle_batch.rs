//! Brute force on SIMD batches of pairs: the same computation as
//! [`super::distance_triangle_triangle`], in the same order, for `LANES` pairs
//! at once, one pair per SIMD lane.
//!
//! Every branch of the scalar version becomes a select, and every feature test
//! is its own loop over the lanes (structure of arrays), which the compiler
//! vectorises; the loops are compiled for AVX-512, AVX2 and the baseline and
//! the best one is chosen at run time, as for the penalty kernel. Ties are
//! broken as in the scalar code (first strict minimum in the same order), and
//! no operation is contracted or reordered, so answers agree with the scalar
//! brute force bit for bit on the same machine (the tests check it).

// Index loops over the lanes are the shape the vectoriser recognises best.
#![allow(clippy::needless_range_loop)]

use super::isa::{Isa, Supported};
use super::pair_lanes::{load_pairs, store_answers, AnswerLanes, PairLanes};
#[cfg(target_arch = "x86_64")]
use super::pair_lanes::{
    load_pairs_avx2, load_pairs_avx512, store_answers_avx2, store_answers_avx512,
};
use super::pair_source::{chunk_ranges, PairSource, Window};
use super::{Closest, Solver};

/// Pairs per SIMD batch of the brute force.
pub const LANES: usize = 8;

type L = [f64; LANES];
type V3 = [L; 3];

/// The three vertices, local to the pair (first vertex of A at the origin).
struct Packed {
    a: [V3; 3],
    b: [V3; 3],
}

/// Per lane and triangle: normal, |n|², inward edge normals, usability mask.
struct Plane {
    n: V3,
    nn: L,
    m: [V3; 3],
    /// All ones where usable: not `[bool; LANES]`, which LLVM packs into one
    /// integer and tests with scalar bit tricks instead of vector masks.
    usable: [u64; LANES],
}

#[inline(always)]
fn sub(p: &V3, q: &V3, l: usize) -> [f64; 3] {
    [p[0][l] - q[0][l], p[1][l] - q[1][l], p[2][l] - q[2][l]]
}

#[inline(always)]
fn dot(x: [f64; 3], y: [f64; 3]) -> f64 {
    x[0] * y[0] + x[1] * y[1] + x[2] * y[2]
}

#[inline(always)]
fn cross(x: [f64; 3], y: [f64; 3]) -> [f64; 3] {
    [
        x[1] * y[2] - x[2] * y[1],
        x[2] * y[0] - x[0] * y[2],
        x[0] * y[1] - x[1] * y[0],
    ]
}

#[inline(always)]
fn get(v: &V3, l: usize) -> [f64; 3] {
    [v[0][l], v[1][l], v[2][l]]
}

#[inline(always)]
fn plane_of(t: &[V3; 3]) -> Plane {
    let mut p = Plane {
        n: [[0.0; LANES]; 3],
        nn: [0.0; LANES],
        m: [[[0.0; LANES]; 3]; 3],
        usable: [0; LANES],
    };
    for l in 0..LANES {
        let e0 = sub(&t[1], &t[0], l);
        let e1 = sub(&t[2], &t[1], l);
        let e2 = sub(&t[0], &t[2], l);
        let (l0, l1, l2) = (dot(e0, e0), dot(e1, e1), dot(e2, e2));
        // The two edges at the largest angle (opposite the longest edge).
        let n = if l0 >= l1 && l0 >= l2 {
            cross(e1, e2)
        } else if l1 >= l2 {
            cross(e2, e0)
        } else {
            cross(e0, e1)
        };
        let nn = dot(n, n);
        let longest = l0.max(l1).max(l2);
        let uv = (l0 * l1 * l2) / longest;
        const FLAT: f64 = 64.0 * f64::EPSILON;
        // Same test as the scalar `usable_normal`: not flat to rounding.
        let usable = nn > 0.0 && nn > FLAT * FLAT * uv;
        let e = [e0, e1, e2];
        for k in 0..3 {
            p.n[k][l] = n[k];
            for (i, ei) in e.iter().enumerate() {
                p.m[i][k][l] = cross(n, *ei)[k];
            }
        }
        p.nn[l] = nn;
        p.usable[l] = if usable { u64::MAX } else { 0 };
    }
    p
}

struct Best {
    d: L,
    p: V3,
    q: V3,
}

#[inline(always)]
fn consider(best: &mut Best, l: usize, p: [f64; 3], q: [f64; 3], ok: bool) {
    let d = [p[0] - q[0], p[1] - q[1], p[2] - q[2]];
    let dd = dot(d, d);
    let take = ok & (dd < best.d[l]);
    if take {
        best.d[l] = dd;
        for k in 0..3 {
            best.p[k][l] = p[k];
            best.q[k][l] = q[k];
        }
    }
}

// One function on purpose, though long: the fifteen feature tests are
// inlined into one loop body per lane set, which is what lets the compiler
// keep the lanes in vector registers across them (split into calls, it
// spills between them).
#[inline(always)]
fn batch(pk: &Packed) -> (V3, V3) {
    let mut best = Best {
        d: [f64::INFINITY; LANES],
        p: pk.a[0],
        q: pk.b[0],
    };
    // 1 / |edge|^2 of the six edges, once rather than once per edge pair:
    // divisions are the slowest vector instructions (the same quotients as
    // the scalar code, so answers stay bit-identical).
    let inv_len2 = |t: &[V3; 3]| {
        let mut r = [[0.0; LANES]; 3];
        for (i, ri) in r.iter_mut().enumerate() {
            for l in 0..LANES {
                let d = sub(&t[(i + 1) % 3], &t[i], l);
                let a = dot(d, d);
                ri[l] = if a > 0.0 { 1.0 / a } else { 0.0 };
            }
        }
        r
    };
    let (inv_a_all, inv_e_all) = (inv_len2(&pk.a), inv_len2(&pk.b));
    // 9 edge pairs, branch-free Ericson clamping (see closest_point_segment_segment.rs).
    for i in 0..3 {
        for j in 0..3 {
            let (i1, j1) = ((i + 1) % 3, (j + 1) % 3);
            for l in 0..LANES {
                let p1 = get(&pk.a[i], l);
                let d1 = sub(&pk.a[i1], &pk.a[i], l);
                let p2 = get(&pk.b[j], l);
                let d2 = sub(&pk.b[j1], &pk.b[j], l);
                let e = dot(d2, d2);
                let (inv_a, inv_e) = (inv_a_all[i][l], inv_e_all[j][l]);
                let r = [p1[0] - p2[0], p1[1] - p2[1], p1[2] - p2[2]];
                let f = dot(d2, r);
                let c = dot(d1, r);
                let b = dot(d1, d2);
                let cr = cross(d1, d2);
                let denom = dot(cr, cr);
                let s0 = if denom > 0.0 {
                    ((b * f - c * e) / denom).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                let t = ((b * s0 + f) * inv_e).clamp(0.0, 1.0);
                let s = ((b * t - c) * inv_a).clamp(0.0, 1.0);
                let p = [p1[0] + d1[0] * s, p1[1] + d1[1] * s, p1[2] + d1[2] * s];
                let q = [p2[0] + d2[0] * t, p2[1] + d2[1] * t, p2[2] + d2[2] * t];
                consider(&mut best, l, p, q, true);
            }
        }
    }
    let (pa, pb) = (plane_of(&pk.a), plane_of(&pk.b));
    // Interior projections of each vertex onto the other triangle.
    for (verts, plane, a_side) in [(&pk.a, &pb, true), (&pk.b, &pa, false)] {
        let tri = if a_side { &pk.b } else { &pk.a };
        for v in verts.iter() {
            for l in 0..LANES {
                let x = get(v, l);
                // `&`, not `&&` or `all`: no short-circuit branches in a lane loop.
                let inside = (dot(get(&plane.m[0], l), sub(v, &tri[0], l)) >= 0.0)
                    & (dot(get(&plane.m[1], l), sub(v, &tri[1], l)) >= 0.0)
                    & (dot(get(&plane.m[2], l), sub(v, &tri[2], l)) >= 0.0);
                let n = get(&plane.n, l);
                let h = dot(n, sub(v, &tri[0], l)) / plane.nn[l];
                let proj = [x[0] - n[0] * h, x[1] - n[1] * h, x[2] - n[2] * h];
                let ok = (plane.usable[l] != 0) & inside;
                if a_side {
                    consider(&mut best, l, x, proj, ok);
                } else {
                    consider(&mut best, l, proj, x, ok);
                }
            }
        }
    }
    // Edges piercing the other triangle: distance 0 at the crossing point.
    let mut pierce = [0u64; LANES];
    let mut px: V3 = [[0.0; LANES]; 3];
    for (s, t, plane) in [(&pk.a, &pk.b, &pb), (&pk.b, &pk.a, &pa)] {
        for i in 0..3 {
            let j = (i + 1) % 3;
            for l in 0..LANES {
                let n = get(&plane.n, l);
                let h0 = dot(n, sub(&s[i], &t[0], l));
                let h1 = dot(n, sub(&s[j], &t[0], l));
                let crosses = ((h0 > 0.0) & (h1 < 0.0)) | ((h0 < 0.0) & (h1 > 0.0));
                let w = if crosses { h0 / (h0 - h1) } else { 0.0 };
                let e = sub(&s[j], &s[i], l);
                let x0 = get(&s[i], l);
                let x = [x0[0] + e[0] * w, x0[1] + e[1] * w, x0[2] + e[2] * w];
                let side = |k: usize| {
                    let tk = get(&t[k], l);
                    dot(
                        get(&plane.m[k], l),
                        [x[0] - tk[0], x[1] - tk[1], x[2] - tk[2]],
                    ) >= 0.0
                };
                let inside = side(0) & side(1) & side(2);
                let hit = (plane.usable[l] != 0)
                    & crosses
                    & inside
                    & (pierce[l] == 0)
                    & (best.d[l] > 0.0);
                if hit {
                    pierce[l] = u64::MAX;
                    for k in 0..3 {
                        px[k][l] = x[k];
                    }
                }
            }
        }
    }
    for l in 0..LANES {
        if pierce[l] != 0 {
            for (k, pxk) in px.iter().enumerate() {
                best.p[k][l] = pxk[l];
                best.q[k][l] = pxk[l];
            }
        }
    }
    (best.p, best.q)
}

/// The brute force on one batch, from the pairs' coordinates to their
/// answers: distances, and closest points in the pairs' own coordinates.
#[inline(always)]
fn batch_from_lanes(lanes: &PairLanes<LANES>) -> (L, V3, V3) {
    // Local frame: the first vertex of A is the origin, exactly zero, as in
    // the scalar version.
    let mut pk = Packed {
        a: [[[0.0; LANES]; 3]; 3],
        b: [[[0.0; LANES]; 3]; 3],
    };
    let origin = &lanes[0];
    for v in 0..3 {
        for k in 0..3 {
            for l in 0..LANES {
                if v > 0 {
                    pk.a[v][k][l] = lanes[v][k][l] - origin[k][l];
                }
                pk.b[v][k][l] = lanes[3 + v][k][l] - origin[k][l];
            }
        }
    }
    let (mut p, mut q) = batch(&pk);
    let mut distance = [0.0; LANES];
    for l in 0..LANES {
        let d = sub(&p, &q, l);
        distance[l] = dot(d, d).sqrt();
    }
    for k in 0..3 {
        for l in 0..LANES {
            p[k][l] += origin[k][l];
            q[k][l] += origin[k][l];
        }
    }
    (distance, p, q)
}

#[inline(always)]
fn answers<'a>((distance, p, q): &'a (L, V3, V3)) -> AnswerLanes<'a, LANES> {
    AnswerLanes {
        distance,
        p: [&p[0], &p[1], &p[2]],
        q: [&q[0], &q[1], &q[2]],
    }
}

/// # Safety
/// The CPU must have AVX-512F/DQ/VL, AVX2 and FMA (a `Supported` of `Isa::Avx512`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
unsafe fn batch_avx512<P: PairSource + ?Sized>(pairs: &P, out: &mut [Closest]) {
    // SAFETY: this function's caller guarantees AVX-512F.
    let found = batch_from_lanes(&unsafe { load_pairs_avx512(pairs) });
    unsafe { store_answers_avx512(&answers(&found), Solver::Brute, out) };
}

/// # Safety
/// The CPU must have AVX2 and FMA (a `Supported` of `Isa::Avx2` or above).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn batch_avx2<P: PairSource + ?Sized>(pairs: &P, out: &mut [Closest]) {
    // SAFETY: this function's caller guarantees AVX2.
    let found = batch_from_lanes(&unsafe { load_pairs_avx2(pairs) });
    unsafe { store_answers_avx2(&answers(&found), Solver::Brute, out) };
}

/// Exact distances of up to `LANES` pairs at once (`out.len() == pairs.len()`),
/// on an instruction set this CPU is proved to run.
pub fn distance_triangle_triangle_batch<P: PairSource + ?Sized>(
    pairs: &P,
    isa: Supported,
    out: &mut [Closest],
) {
    debug_assert!(pairs.len() <= LANES && pairs.len() == out.len());
    if pairs.is_empty() {
        return;
    }
    match isa.isa() {
        // SAFETY: a `Supported` proves these features on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { batch_avx512(pairs, out) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { batch_avx2(pairs, out) },
        _ => {
            let found = batch_from_lanes(&load_pairs(pairs));
            store_answers(&answers(&found), Solver::Brute, out)
        }
    }
}

/// Exact distances of any number of pairs, `LANES` at a time.
pub fn distance_triangle_triangle_many<P: PairSource + ?Sized>(pairs: &P, out: &mut [Closest]) {
    distance_triangle_triangle_many_on(pairs, Isa::detect(), out)
}

/// Like [`distance_triangle_triangle_many`] on a chosen instruction set (never
/// above what the CPU has: a higher one is lowered to the detected one).
pub fn distance_triangle_triangle_many_on<P: PairSource + ?Sized>(
    pairs: &P,
    isa: Isa,
    out: &mut [Closest],
) {
    assert_eq!(pairs.len(), out.len());
    let isa = isa.supported();
    for r in chunk_ranges(pairs.len(), LANES) {
        distance_triangle_triangle_batch(&Window::new(pairs, r.clone()), isa, &mut out[r]);
    }
}
