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
//! (by 2x2 blocks, see `solve_spd4.rs`): the matrix is symmetric positive definite thanks
//! to delta, which also regularises G, singular for every pair (four edge
//! vectors in three dimensions) and doubly so for parallel faces.
//!
//! The penalty answer is then *finished* exactly on the feature pair it
//! identifies and *certified* (`penalty_finish.rs`): a pair is reported as
//! converged only when its answer is proven within `tol * L` of the true
//! distance, L the diagonal of the pair's bounding box. Every stage is a loop
//! over the lanes of the batch, so the whole kernel runs in SIMD registers.
//! All parameters are relative, so results do not depend on the size or
//! position of the triangles.

use super::isa::{Isa, Supported};
use super::lanes::{F, V3};
use super::pair_lanes::{load_pairs, store_answers_on, AnswerLanes, PairLanes};
#[cfg(target_arch = "x86_64")]
use super::pair_lanes::{load_pairs_avx2, load_pairs_avx512};
use super::pair_source::{chunk_ranges, PairSource, Window};
use super::penalty_finish::{finish_lanes, Finished};
use super::solve_spd4::{solve_spd4_by_blocks, Sym4, SYM4_INDEX};
use super::{Closest, Solver, Triangle};

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
    /// Rounds of the exact finish on the identified feature pair (0: clamp
    /// Newton's answer and certify it). Default 1: a further round runs on the
    /// whole batch whenever one of its lanes is uncertified and certifies
    /// about 1.5% more random pairs, fewer than the hybrid's brute force
    /// handles in the same time (`tridem kernels --accuracy`, docs/distance.md).
    pub finish_rounds: usize,
}

impl Default for PenaltyParams {
    fn default() -> Self {
        PenaltyParams {
            max_iterations: 4,
            penalty: 1e6,
            regularisation: 1e-2,
            regularisation_decay: 1e-4,
            tol: 1e-13,
            finish_rounds: 1,
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

/// Batch sizes the kernel accepts (above 16, run as 16-lane blocks).
pub const BATCH_SIZES: [usize; 7] = [1, 2, 4, 8, 16, 32, 64];

/// Structure-of-arrays input of one batch of `N` pairs, in each pair's local
/// frame (origin at its first vertex, A0).
#[derive(Clone, Copy)]
pub(crate) struct Batch<const N: usize> {
    /// A0 - B0.
    pub w: V3<N>,
    /// A1 - A0, A2 - A0, B0 - B1, B0 - B2.
    pub u: [V3<N>; 4],
}

impl<const N: usize> Batch<N> {
    /// The pairs' vectors in each pair's local frame, subtracted lane by lane
    /// in vector registers (the same roundings as pair by pair).
    #[inline(always)]
    fn from_lanes(v: &PairLanes<N>) -> Self {
        let vertex = |i: usize| V3([F(v[i][0]), F(v[i][1]), F(v[i][2])]);
        let (a0, a1, a2) = (vertex(0), vertex(1), vertex(2));
        let (b0, b1, b2) = (vertex(3), vertex(4), vertex(5));
        Batch {
            w: a0 - b0,
            u: [a1 - a0, a2 - a0, b0 - b1, b0 - b2],
        }
    }
}

/// The scale every relative parameter multiplies: trace(G) / 4, the mean
/// squared edge length (1 for a pair of points, to keep systems solvable).
#[inline(always)]
fn gram_scale<const N: usize>(g: &Sym4<N>) -> F<N> {
    let scale = 0.25 * (g[0] + g[4] + g[7] + g[9]);
    scale.gt(F::splat(0.0)).select(scale, F::splat(1.0))
}

/// Newton's iterates of one batch: per lane the parameters (a, b, c, d), the
/// scale trace(G) / 4 and the step count.
///
/// The gradient is taken as g = G s + h with h_i = u_i . w rather than through
/// the residual r = w + sum s_i u_i: 16 multiply-adds instead of 24, and the
/// loop then keeps only G, h and s live (18 vectors instead of 29), so less
/// spills out of the 32 vector registers. Forming
/// G s + h loses absolute accuracy of order eps L^2 near the minimiser, where
/// g -> 0; Newton only has to find the active features, and the finish
/// recomputes the residual exactly.
#[inline(always)]
fn newton_lanes<const N: usize>(
    batch: &Batch<N>,
    prm: &PenaltyParams,
) -> ([F<N>; 4], F<N>, [u8; N]) {
    let (w, u) = (batch.w, &batch.u);
    let mut g: Sym4<N> = [F::splat(0.0); 10];
    for (k, &(i, j)) in SYM4_INDEX.iter().enumerate() {
        g[k] = u[i].dot(u[j]);
    }
    let scale = gram_scale(&g);
    // Newton runs on G / scale and h / scale (the step is unchanged): entries
    // of order one, which the one-division solver needs.
    let inv_scale = 1.0 / scale;
    for gk in &mut g {
        *gk = *gk * inv_scale;
    }
    let h = [u[0].dot(w), u[1].dot(w), u[2].dot(w), u[3].dot(w)].map(|hi| hi * inv_scale);
    let rho = F::splat(prm.penalty);
    let mut delta = F::splat(prm.regularisation);
    // Keep the system numerically positive definite: G is singular and a
    // vanishing delta would let rounding make it indefinite.
    let delta_min = F::splat(MIN_REGULARISATION);
    let zero = F::splat(0.0);
    let mut s = [F::splat(1.0 / 3.0); 4];
    // Per lane, the step after which Newton's step became negligible (as f64:
    // bookkeeping in vector registers, no per-lane branches).
    let mut settled_after = F::splat(prm.max_iterations as f64);
    for it in 0..prm.max_iterations {
        let [a, b, c, d] = s;
        // Constraint violations and active masks (selects, not branches).
        let v = [(-a).max(zero), (-b).max(zero), (a + b - 1.0).max(zero)];
        let vv = [(-c).max(zero), (-d).max(zero), (c + d - 1.0).max(zero)];
        let m = |x: F<N>| x.gt(zero).select(rho, zero);
        // Written out: a closure here is not inlined into the
        // `#[target_feature]` callers and runs without their vector width.
        let grad = [
            g[0] * a + g[1] * b + g[2] * c + g[3] * d + h[0] + rho * (v[2] - v[0]),
            g[1] * a + g[4] * b + g[5] * c + g[6] * d + h[1] + rho * (v[2] - v[1]),
            g[2] * a + g[5] * b + g[7] * c + g[8] * d + h[2] + rho * (vv[2] - vv[0]),
            g[3] * a + g[6] * b + g[8] * c + g[9] * d + h[3] + rho * (vv[2] - vv[1]),
        ];
        let (m2, mm2) = (m(v[2]), m(vv[2]));
        let hess = [
            g[0] + m(v[0]) + m2 + delta,
            g[1] + m2,
            g[2],
            g[3],
            g[4] + m(v[1]) + m2 + delta,
            g[5],
            g[6],
            g[7] + m(vv[0]) + mm2 + delta,
            g[8] + mm2,
            g[9] + m(vv[1]) + mm2 + delta,
        ];
        let x = solve_spd4_by_blocks(&hess, [-grad[0], -grad[1], -grad[2], -grad[3]]);
        s = [a + x[0], b + x[1], c + x[2], d + x[3]];
        let step_max = x[0].abs().max(x[1].abs()).max(x[2].abs()).max(x[3].abs());
        delta = (delta * prm.regularisation_decay).max(delta_min);
        let step = F::splat((it + 1) as f64);
        let settled = step_max.le(F::splat(STEP_TOL));
        settled_after = (settled & settled_after.gt(step)).select(step, settled_after);
        if settled_after.le(step).all() {
            break;
        }
    }
    let iters = settled_after.0.map(|n| n as u8);
    (s, scale, iters)
}

/// Floor of the regularisation, relative to trace(G) / 4.
const MIN_REGULARISATION: f64 = 1e-12;

/// Newton steps below this (in barycentric units) count as settled.
const STEP_TOL: f64 = 1e-12;

/// Newton, then finish and certificate: the whole kernel on one batch. It
/// runs in each pair's local frame; the closest points come back to the
/// pairs' own coordinates at the end.
#[inline(always)]
fn kernel<const N: usize>(lanes: &PairLanes<N>, prm: &PenaltyParams) -> (Finished<N>, [u8; N]) {
    let batch = Batch::from_lanes(lanes);
    let (s, scale, iters) = newton_lanes(&batch, prm);
    let mut f = finish_lanes(&batch, s, scale, prm);
    let origin = V3([F(lanes[0][0]), F(lanes[0][1]), F(lanes[0][2])]);
    f.p = f.p + origin;
    f.q = f.q + origin;
    (f, iters)
}

// The answers are stored by the caller, outside these wrappers: stored
// inside, the kernel's loops came out as 128- and 256-bit and scalar code
// (penalty 52 -> 96 ns/pair).

/// # Safety
/// The CPU must have AVX-512F/DQ/VL, AVX2 and FMA (a `Supported` of `Isa::Avx512`).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx512f,avx512dq,avx512vl,avx2,fma")]
unsafe fn kernel_avx512<const N: usize, P: PairSource + ?Sized>(
    pairs: &P,
    prm: &PenaltyParams,
) -> (Finished<N>, [u8; N]) {
    // SAFETY: this function's caller guarantees AVX-512F.
    kernel(&unsafe { load_pairs_avx512(pairs) }, prm)
}

/// # Safety
/// The CPU must have AVX2 and FMA (a `Supported` of `Isa::Avx2` or above).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2,fma")]
unsafe fn kernel_avx2<const N: usize, P: PairSource + ?Sized>(
    pairs: &P,
    prm: &PenaltyParams,
) -> (Finished<N>, [u8; N]) {
    // SAFETY: this function's caller guarantees AVX2.
    kernel(&unsafe { load_pairs_avx2(pairs) }, prm)
}

fn kernel_on<const N: usize, P: PairSource + ?Sized>(
    pairs: &P,
    prm: &PenaltyParams,
    isa: Supported,
) -> (Finished<N>, [u8; N]) {
    match isa.isa() {
        // SAFETY: a `Supported` proves these features on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { kernel_avx512(pairs, prm) },
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { kernel_avx2(pairs, prm) },
        _ => kernel(&load_pairs(pairs), prm),
    }
}

/// Runs the penalty kernel on up to `N` pairs (one SIMD batch) and writes the
/// answers and per-pair statistics, on an instruction set this CPU runs.
pub(crate) fn penalty_batch_on<const N: usize, P: PairSource + ?Sized>(
    pairs: &P,
    prm: &PenaltyParams,
    isa: Supported,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) {
    // Two or four lanes fill at most a 256-bit register, and the AVX-512
    // build of the kernel for them came out slower than the AVX2 one (batch
    // 4: 121 against 66 ns/pair on one AVX-512 machine, 90 against 54 on another;
    // docs/distance.md); AVX-512 CPUs have AVX2 and FMA too. Answers are the
    // same on every instruction set.
    let isa = match N {
        2 | 4 => isa.at_most(Isa::Avx2),
        _ => isa,
    };
    let (f, iters) = kernel_on::<N, _>(pairs, prm, isa);
    let answers = AnswerLanes {
        distance: &f.distance.0,
        p: [&f.p.0[0].0, &f.p.0[1].0, &f.p.0[2].0],
        q: [&f.q.0[0].0, &f.q.0[1].0, &f.q.0[2].0],
    };
    store_answers_on(&answers, Solver::Penalty, isa, out);
    for lane in 0..pairs.len() {
        stats[lane] = PenaltyStats {
            converged: f.certified.lane(lane),
            iterations: iters[lane],
        };
    }
}

/// Computes the penalty answer for each pair, in batches of `batch` pairs
/// (one of [`BATCH_SIZES`]), using the best instruction set of this CPU.
///
/// Returns an error for an unsupported batch size.
pub fn penalty_many<P: PairSource + ?Sized>(
    pairs: &P,
    batch: usize,
    prm: &PenaltyParams,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) -> Result<(), UnsupportedBatch> {
    penalty_many_on(pairs, batch, prm, Isa::detect(), out, stats)
}

/// Like [`penalty_many`] on a chosen instruction set (never above what the CPU has:
/// a higher one is lowered to the detected one).
pub fn penalty_many_on<P: PairSource + ?Sized>(
    pairs: &P,
    batch: usize,
    prm: &PenaltyParams,
    isa: Isa,
    out: &mut [Closest],
    stats: &mut [PenaltyStats],
) -> Result<(), UnsupportedBatch> {
    let isa = isa.supported();
    assert_eq!(pairs.len(), out.len());
    assert_eq!(pairs.len(), stats.len());
    macro_rules! run {
        ($n:literal) => {
            for r in chunk_ranges(pairs.len(), $n) {
                let window = Window::new(pairs, r.clone());
                penalty_batch_on::<$n, _>(&window, prm, isa, &mut out[r.clone()], &mut stats[r]);
            }
        };
    }
    match batch {
        1 => run!(1),
        2 => run!(2),
        4 => run!(4),
        8 => run!(8),
        16 => run!(16),
        // Wider batches run as 16-lane blocks: no register file holds 32 or 64
        // lanes, the full-width kernel spilled and measured slower (32: 483 ns
        // against 213 ns at 16), and compiling it tripled the crate's build
        // time. Answers do not depend on the blocking; what the batch size
        // still decides is the hybrid's fallback unit (see `hybrid`).
        32 | 64 => run!(16),
        _ => return Err(UnsupportedBatch(batch)),
    }
    Ok(())
}

/// Penalty on one pair with scalar code: the reference the SIMD speed-up is
/// measured against (same algorithm, one pair at a time, baseline instructions).
pub fn penalty_scalar(a: &Triangle, b: &Triangle, prm: &PenaltyParams) -> (Closest, PenaltyStats) {
    let mut out = [Closest::UNSET];
    let mut stats = [PenaltyStats::default()];
    penalty_batch_on::<1, _>(
        &[(*a, *b)][..],
        prm,
        Isa::Baseline.supported(),
        &mut out,
        &mut stats,
    );
    (out[0], stats[0])
}

/// A batch size the kernel is not compiled for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
#[error("batch size {0} is not supported; use one of 1, 2, 4, 8, 16, 32, 64")]
pub struct UnsupportedBatch(pub usize);
