//! Newton's method on the penalty formulation of the triangle distance, on
//! batches of pairs in structure-of-arrays layout, one pair per SIMD lane.
//!
//! Points of the triangles are x(a,b) = A0 + a (A1-A0) + b (A2-A0) and
//! y(c,d) = B0 + c (B1-B0) + d (B2-B0). With u = (e1, e2, -e3, -e4) the four edge
//! vectors and w = A0 - B0, the residual is r = w + sum_i s_i u_i for
//! s = (a,b,c,d), and half the squared distance is f = |r|^2 / 2 with constant
//! Hessian G_ij = u_i . u_j and gradient g_i = u_i . r. The six constraints
//! -a, -b, a+b-1, -c, -d, c+d-1 <= 0 are penalised by (rho/2) sum max(0, c_k)^2.
//! Each Newton step solves (G + rho J_act^T J_act + delta I) ds = -(g + rho J^T max(0,c))
//! by an unrolled Cholesky factorisation: the matrix is symmetric positive
//! definite thanks to delta, which also regularises the parallel case, where G
//! is singular.
//!
//! The penalty answer is then *finished* on the feature pair it identifies
//! (vertex, edge or face of each triangle, from the active constraints) and
//! *certified* (see [`super::certified_error_bound`]): a pair is reported as
//! converged only when its answer is proven within `tol * L` of the true distance,
//! L the diagonal of the pair's bounding box. All parameters are relative, so
//! results do not depend on the size or position of the triangles.

use super::certificate::certified_error_bound;
use super::finish::finish_on_features;
use super::{pair_scale, Closest, Solver, Triangle};
use glam::DVec3;

/// Parameters of the penalty Newton solver. All are dimensionless.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PenaltyParams {
    /// Newton iterations at most (the published kernel: exactly 4).
    pub max_iterations: usize,
    /// Penalty weight relative to trace(G) / 4.
    pub penalty: f64,
    /// Diagonal regularisation of the first step, relative to trace(G) / 4.
    pub regularisation: f64,
    /// Factor applied to the regularisation after each step.
    pub regularisation_decay: f64,
    /// A pair converged when its certified error bound is at most `tol * L`.
    pub tol: f64,
    /// Finish exactly on the identified feature pair (else: clamp and certify).
    pub exact_finish: bool,
}

impl Default for PenaltyParams {
    fn default() -> Self {
        PenaltyParams {
            max_iterations: 4,
            penalty: 1e6,
            regularisation: 1e-2,
            regularisation_decay: 1e-4,
            tol: 1e-13,
            exact_finish: true,
        }
    }
}

/// What the penalty solver reports per pair besides the answer.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct PenaltyStats {
    /// Certified to `tol * L`.
    pub converged: bool,
    /// Newton steps taken before the step became negligible (or the maximum).
    pub iterations: u8,
}

/// Barycentric parameters (a, b, c, d) after Newton, per pair.
pub type Params4 = [f64; 4];

/// Batch sizes the kernel is compiled for.
pub const BATCH_SIZES: [usize; 7] = [1, 2, 4, 8, 16, 32, 64];

/// Structure-of-arrays input of one batch of `N` pairs, in each pair's local
/// frame (origin at its first vertex, A0).
#[derive(Clone, Copy)]
struct Batch<const N: usize> {
    w: [[f64; N]; 3],
    u: [[[f64; N]; 3]; 4],
}

impl<const N: usize> Batch<N> {
    /// Packs up to N pairs; missing lanes repeat the last pair (their results are ignored).
    fn pack(pairs: &[(Triangle, Triangle)]) -> Self {
        let mut w = [[0.0; N]; 3];
        let mut u = [[[0.0; N]; 3]; 4];
        for lane in 0..N {
            let (a, b) = &pairs[lane.min(pairs.len() - 1)];
            let o = a[0];
            // w = A0 - B0 and u = (A1-A0, A2-A0, -(B1-B0), -(B2-B0)) in the local frame.
            let ws = o - b[0];
            let us = [a[1] - o, a[2] - o, b[0] - b[1], b[0] - b[2]];
            for k in 0..3 {
                w[k][lane] = ws[k];
                for (i, ui) in us.iter().enumerate() {
                    u[i][k][lane] = ui[k];
                }
            }
        }
        Batch { w, u }
    }
}

/// Newton on one batch; returns per lane the parameters and the step count.
///
/// Written as straight-line scalar code inside loops over the lanes, with
/// `max`/`min` instead of branches, so that the compiler vectorises each loop
/// across lanes (one pair per SIMD lane). `#[inline(always)]` lets the
/// target-feature wrappers below compile it for AVX2 and AVX-512.
#[inline(always)]
fn newton_batch<const N: usize>(batch: &Batch<N>, prm: &PenaltyParams) -> ([[f64; N]; 4], [u8; N]) {
    let u = &batch.u;
    let w = &batch.w;
    // Gram matrix G (symmetric, 10 entries) and scale per lane.
    let mut g = [[0.0f64; N]; 10];
    let mut rho = [0.0f64; N];
    let mut delta = [0.0f64; N];
    const IJ: [(usize, usize); 10] = [
        (0, 0),
        (0, 1),
        (0, 2),
        (0, 3),
        (1, 1),
        (1, 2),
        (1, 3),
        (2, 2),
        (2, 3),
        (3, 3),
    ];
    for l in 0..N {
        for (k, &(i, j)) in IJ.iter().enumerate() {
            g[k][l] = u[i][0][l] * u[j][0][l] + u[i][1][l] * u[j][1][l] + u[i][2][l] * u[j][2][l];
        }
        let scale = 0.25 * (g[0][l] + g[4][l] + g[7][l] + g[9][l]);
        // A pair of points (all edges zero) has scale 0: keep the system solvable.
        let scale = if scale > 0.0 { scale } else { 1.0 };
        rho[l] = prm.penalty * scale;
        delta[l] = prm.regularisation * scale;
    }
    let third = 1.0 / 3.0;
    let mut s = [[third; N]; 4];
    let mut iters = [prm.max_iterations as u8; N];
    for it in 0..prm.max_iterations {
        let mut step_max = [0.0f64; N];
        for l in 0..N {
            let (a, b, c, d) = (s[0][l], s[1][l], s[2][l], s[3][l]);
            // Residual r = w + sum s_i u_i and gradient g_i = u_i . r.
            let mut r = [0.0; 3];
            for (k, rk) in r.iter_mut().enumerate() {
                *rk = w[k][l] + a * u[0][k][l] + b * u[1][k][l] + c * u[2][k][l] + d * u[3][k][l];
            }
            let mut grad = [0.0; 4];
            for (i, gi) in grad.iter_mut().enumerate() {
                *gi = u[i][0][l] * r[0] + u[i][1][l] * r[1] + u[i][2][l] * r[2];
            }
            // Constraint violations and active masks (branch-free).
            let v = [(-a).max(0.0), (-b).max(0.0), (a + b - 1.0).max(0.0)];
            let vv = [(-c).max(0.0), (-d).max(0.0), (c + d - 1.0).max(0.0)];
            let m = |x: f64| if x > 0.0 { 1.0 } else { 0.0 };
            let p = rho[l];
            grad[0] += p * (v[2] - v[0]);
            grad[1] += p * (v[2] - v[1]);
            grad[2] += p * (vv[2] - vv[0]);
            grad[3] += p * (vv[2] - vv[1]);
            let dl = delta[l];
            let h00 = g[0][l] + p * (m(v[0]) + m(v[2])) + dl;
            let h01 = g[1][l] + p * m(v[2]);
            let h11 = g[4][l] + p * (m(v[1]) + m(v[2])) + dl;
            let h22 = g[7][l] + p * (m(vv[0]) + m(vv[2])) + dl;
            let h23 = g[8][l] + p * m(vv[2]);
            let h33 = g[9][l] + p * (m(vv[1]) + m(vv[2])) + dl;
            let (h02, h03, h12, h13) = (g[2][l], g[3][l], g[5][l], g[6][l]);
            // Cholesky H = L L^T, unrolled; one division per pivot, then products.
            let l00 = h00.sqrt();
            let i00 = 1.0 / l00;
            let l10 = h01 * i00;
            let l20 = h02 * i00;
            let l30 = h03 * i00;
            let l11 = (h11 - l10 * l10).sqrt();
            let i11 = 1.0 / l11;
            let l21 = (h12 - l20 * l10) * i11;
            let l31 = (h13 - l30 * l10) * i11;
            let l22 = (h22 - l20 * l20 - l21 * l21).sqrt();
            let i22 = 1.0 / l22;
            let l32 = (h23 - l30 * l20 - l31 * l21) * i22;
            let l33 = (h33 - l30 * l30 - l31 * l31 - l32 * l32).sqrt();
            let i33 = 1.0 / l33;
            // Forward then backward substitution for -grad.
            let y0 = -grad[0] * i00;
            let y1 = (-grad[1] - l10 * y0) * i11;
            let y2 = (-grad[2] - l20 * y0 - l21 * y1) * i22;
            let y3 = (-grad[3] - l30 * y0 - l31 * y1 - l32 * y2) * i33;
            let x3 = y3 * i33;
            let x2 = (y2 - l32 * x3) * i22;
            let x1 = (y1 - l21 * x2 - l31 * x3) * i11;
            let x0 = (y0 - l10 * x1 - l20 * x2 - l30 * x3) * i00;
            s[0][l] = a + x0;
            s[1][l] = b + x1;
            s[2][l] = c + x2;
            s[3][l] = d + x3;
            step_max[l] = x0.abs().max(x1.abs()).max(x2.abs()).max(x3.abs());
            // Keep the system numerically positive definite: in the parallel case G
            // is singular and a vanishing delta would let rounding make it indefinite.
            delta[l] =
                (dl * prm.regularisation_decay).max(MIN_REGULARISATION * rho[l] / prm.penalty);
        }
        // Bookkeeping outside the vectorised loop: when did each lane settle?
        let mut all_done = true;
        for l in 0..N {
            if step_max[l] <= STEP_TOL && iters[l] as usize > it + 1 {
                iters[l] = (it + 1) as u8;
            }
            all_done &= (iters[l] as usize) <= it + 1;
        }
        if all_done {
            break;
        }
    }
    (s, iters)
}

/// Floor of the regularisation, relative to trace(G) / 4.
const MIN_REGULARISATION: f64 = 1e-12;

/// Newton steps below this (in barycentric units) count as settled.
const STEP_TOL: f64 = 1e-12;

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
unsafe fn newton_batch_avx512<const N: usize>(
    b: &Batch<N>,
    p: &PenaltyParams,
) -> ([[f64; N]; 4], [u8; N]) {
    newton_batch(b, p)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn newton_batch_avx2<const N: usize>(
    b: &Batch<N>,
    p: &PenaltyParams,
) -> ([[f64; N]; 4], [u8; N]) {
    newton_batch(b, p)
}

/// Instruction sets the kernel can run on, best first.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Isa {
    Avx512,
    Avx2,
    /// Whatever the build's baseline target has (SSE2 on x86_64).
    Baseline,
}

impl Isa {
    /// The best instruction set this CPU supports.
    pub fn detect() -> Isa {
        #[cfg(target_arch = "x86_64")]
        {
            if std::is_x86_feature_detected!("avx512f")
                && std::is_x86_feature_detected!("avx512dq")
                && std::is_x86_feature_detected!("avx512vl")
            {
                return Isa::Avx512;
            }
            if std::is_x86_feature_detected!("avx2") && std::is_x86_feature_detected!("fma") {
                return Isa::Avx2;
            }
        }
        Isa::Baseline
    }

    pub fn name(self) -> &'static str {
        match self {
            Isa::Avx512 => "avx512",
            Isa::Avx2 => "avx2",
            Isa::Baseline => "baseline",
        }
    }
}

fn newton_dispatch<const N: usize>(
    b: &Batch<N>,
    p: &PenaltyParams,
    isa: Isa,
) -> ([[f64; N]; 4], [u8; N]) {
    match isa {
        // SAFETY: `Isa::detect` checked these features on this CPU; the caller
        // may pass a lower Isa but never a higher one (see `penalty_batch`).
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { newton_batch_avx512(b, p) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { newton_batch_avx2(b, p) },
        _ => newton_batch(b, p),
    }
}

/// Runs the penalty kernel on up to `N` pairs (one SIMD batch) and writes the
/// answers and per-pair statistics.
fn penalty_batch_n<const N: usize>(
    pairs: &[(Triangle, Triangle)],
    prm: &PenaltyParams,
    isa: Isa,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) {
    let batch = Batch::<N>::pack(pairs);
    let (s, iters) = newton_dispatch(&batch, prm, isa);
    for (lane, (a, b)) in pairs.iter().enumerate() {
        let params = [s[0][lane], s[1][lane], s[2][lane], s[3][lane]];
        let (closest, converged) = answer_from_params(a, b, params, prm);
        out[lane] = closest;
        stats[lane] = PenaltyStats {
            converged,
            iterations: iters[lane],
        };
    }
}

/// From Newton's parameters to closest points, a distance and a verdict.
fn answer_from_params(
    a: &Triangle,
    b: &Triangle,
    s: Params4,
    prm: &PenaltyParams,
) -> (Closest, bool) {
    let o = a[0];
    let ta = [DVec3::ZERO, a[1] - o, a[2] - o];
    let tb = [b[0] - o, b[1] - o, b[2] - o];
    // Newton cannot produce NaN from finite input with delta > 0, but a
    // degenerate pair (all vertices equal) must not turn into NaN points.
    let s = if s.iter().all(|x| x.is_finite()) {
        s
    } else {
        [1.0 / 3.0; 4]
    };
    let (p, q) = if prm.exact_finish {
        finish_on_features(&ta, &tb, s)
    } else {
        (
            point_at(&ta, clamp_simplex(s[0], s[1])),
            point_at(&tb, clamp_simplex(s[2], s[3])),
        )
    };
    let l = pair_scale(&ta, &tb);
    let bound = certified_error_bound(&ta, &tb, p, q);
    let converged = bound.is_finite() && bound <= prm.tol * l;
    let distance = (p - q).length();
    let closest = Closest {
        distance: if distance.is_finite() {
            distance
        } else {
            f64::NAN
        },
        p: p + o,
        q: q + o,
        solver: Solver::Penalty,
    };
    (closest, converged && distance.is_finite())
}

/// Projects barycentric parameters onto the simplex a, b >= 0, a + b <= 1.
pub(crate) fn clamp_simplex(a: f64, b: f64) -> (f64, f64) {
    let (a, b) = (a.max(0.0), b.max(0.0));
    let sum = a + b;
    if sum > 1.0 {
        (a / sum, b / sum)
    } else {
        (a, b)
    }
}

pub(crate) fn point_at(t: &Triangle, (a, b): (f64, f64)) -> DVec3 {
    t[0] + (t[1] - t[0]) * a + (t[2] - t[0]) * b
}

/// Computes the penalty answer for each pair, in batches of `batch` pairs
/// (one of [`BATCH_SIZES`]), using the best instruction set of this CPU.
///
/// Returns an error for an unsupported batch size.
pub fn penalty_many(
    pairs: &[(Triangle, Triangle)],
    batch: usize,
    prm: &PenaltyParams,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) -> Result<(), UnsupportedBatch> {
    penalty_many_on(pairs, batch, prm, Isa::detect(), out, stats)
}

/// Like [`penalty_many`] on a chosen instruction set (never above what the CPU has:
/// a higher one is lowered to the detected one).
pub fn penalty_many_on(
    pairs: &[(Triangle, Triangle)],
    batch: usize,
    prm: &PenaltyParams,
    isa: Isa,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) -> Result<(), UnsupportedBatch> {
    let isa = lower_to_available(isa);
    assert_eq!(pairs.len(), out.len());
    assert_eq!(pairs.len(), stats.len());
    macro_rules! run {
        ($n:literal) => {
            for ((p, o), s) in pairs
                .chunks($n)
                .zip(out.chunks_mut($n))
                .zip(stats.chunks_mut($n))
            {
                penalty_batch_n::<$n>(p, prm, isa, o, s);
            }
        };
    }
    match batch {
        1 => run!(1),
        2 => run!(2),
        4 => run!(4),
        8 => run!(8),
        16 => run!(16),
        32 => run!(32),
        64 => run!(64),
        _ => return Err(UnsupportedBatch(batch)),
    }
    Ok(())
}

fn lower_to_available(isa: Isa) -> Isa {
    let have = Isa::detect();
    let rank = |i: Isa| match i {
        Isa::Avx512 => 2,
        Isa::Avx2 => 1,
        Isa::Baseline => 0,
    };
    if rank(isa) > rank(have) {
        have
    } else {
        isa
    }
}

/// Penalty on one pair with scalar code: the reference the SIMD speed-up is
/// measured against (same algorithm, one pair at a time, baseline instructions).
pub fn penalty_scalar(a: &Triangle, b: &Triangle, prm: &PenaltyParams) -> (Closest, PenaltyStats) {
    let mut out = [dummy_closest()];
    let mut stats = [PenaltyStats::default()];
    penalty_batch_n::<1>(&[(*a, *b)], prm, Isa::Baseline, &mut out, &mut stats);
    (out[0], stats[0])
}

pub(crate) fn dummy_closest() -> Closest {
    Closest {
        distance: f64::NAN,
        p: DVec3::ZERO,
        q: DVec3::ZERO,
        solver: Solver::Penalty,
    }
}

/// A batch size the kernel is not compiled for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("batch size {0} is not supported; use one of 1, 2, 4, 8, 16, 32, 64")]
pub struct UnsupportedBatch(pub usize);
