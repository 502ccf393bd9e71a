//! Triangle pairs into SIMD lanes, and their answers out: between one pair
//! (or one [`Closest`]) after another in memory and structure-of-arrays, one
//! coordinate per vector and one pair per lane.
//!
//! Lane by lane, loading is 18 scalar loads and 18 scalar stores per pair and
//! storing the answers 7 of each; the kernels' profiles put the two at a
//! fifth of their time. With AVX-512, eight rows (the first eight coordinates
//! of eight triangles, or eight answers) are transposed in registers with 24
//! shuffles, so each row moves with one vector load or store; only the ninth
//! coordinate of a triangle (its last vertex's z) still goes lane by lane.
//! With AVX2 the same is done four lanes at a time: two 4x4 transposes of 8
//! shuffles each per triangle (coordinates 0-3 and 4-7), and two for the
//! answers (distance and P, then Q).

// Index loops over the lanes are the shape the vectoriser recognises best.
#![allow(clippy::needless_range_loop)]

use super::isa::{Isa, Supported};
use super::pair_source::PairSource;
use super::{Closest, Solver, Triangle};
use glam::DVec3;

/// The coordinates of `N` pairs: `[vertex][axis][lane]`, the vertices in the
/// order A0, A1, A2, B0, B1, B2.
pub(crate) type PairLanes<const N: usize> = [[[f64; N]; 3]; 6];

/// Loads up to `N` pairs lane by lane; missing lanes repeat the last pair
/// (kernels ignore their results).
#[inline(always)]
pub(crate) fn load_pairs<const N: usize, P: PairSource + ?Sized>(pairs: &P) -> PairLanes<N> {
    let mut out = [[[0.0; N]; 3]; 6];
    for lane in 0..N {
        let (a, b) = pairs.pair(lane.min(pairs.len() - 1));
        for v in 0..3 {
            for k in 0..3 {
                out[v][k][lane] = a[v][k];
                out[3 + v][k][lane] = b[v][k];
            }
        }
    }
    out
}

// The vector loads read a triangle as nine consecutive f64 (glam's `DVec3` is
// `repr(C)` with three f64 fields).
const _: () = assert!(std::mem::size_of::<Triangle>() == 9 * std::mem::size_of::<f64>());

/// [`load_pairs`] with AVX-512 vector loads and an in-register transpose, for
/// batches of a multiple of 8 pairs that are full; anything else goes lane by lane.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f")]
pub(crate) unsafe fn load_pairs_avx512<const N: usize, P: PairSource + ?Sized>(
    pairs: &P,
) -> PairLanes<N> {
    use std::arch::x86_64::*;
    if !N.is_multiple_of(8) || pairs.len() != N {
        return load_pairs(pairs);
    }
    let mut out = [[[0.0; N]; 3]; 6];
    for group in (0..N).step_by(8) {
        let mut rows_a = [_mm512_setzero_pd(); 8];
        let mut rows_b = [_mm512_setzero_pd(); 8];
        let mut last_a = [0.0; 8];
        let mut last_b = [0.0; 8];
        for lane in 0..8 {
            let (a, b) = pairs.pair(group + lane);
            // SAFETY: a triangle is nine consecutive f64 (asserted above), so
            // its first eight can be read as one unaligned vector.
            unsafe {
                rows_a[lane] = _mm512_loadu_pd(a.as_ptr().cast::<f64>());
                rows_b[lane] = _mm512_loadu_pd(b.as_ptr().cast::<f64>());
            }
            last_a[lane] = a[2].z;
            last_b[lane] = b[2].z;
        }
        // Columns 0..8 of the rows: A0x A0y A0z A1x A1y A1z A2x A2y.
        let (cols_a, cols_b) = (transpose_8x8(rows_a), transpose_8x8(rows_b));
        for c in 0..8 {
            let (v, k) = (c / 3, c % 3);
            // SAFETY: `group + 8 <= N`, so each store stays inside its row.
            unsafe {
                _mm512_storeu_pd(out[v][k][group..].as_mut_ptr(), cols_a[c]);
                _mm512_storeu_pd(out[3 + v][k][group..].as_mut_ptr(), cols_b[c]);
            }
        }
        out[2][2][group..group + 8].copy_from_slice(&last_a);
        out[5][2][group..group + 8].copy_from_slice(&last_b);
    }
    out
}

/// [`load_pairs`] with AVX vector loads and 4x4 transposes in registers, for
/// batches of a multiple of 4 pairs that are full; anything else goes lane by lane.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn load_pairs_avx2<const N: usize, P: PairSource + ?Sized>(
    pairs: &P,
) -> PairLanes<N> {
    use std::arch::x86_64::*;
    if !N.is_multiple_of(4) || pairs.len() != N {
        return load_pairs(pairs);
    }
    let mut out = [[[0.0; N]; 3]; 6];
    for group in (0..N).step_by(4) {
        // Per triangle (a, b) and half (coordinates 0-3, 4-7): four rows.
        let mut rows = [[[_mm256_setzero_pd(); 4]; 2]; 2];
        let mut last = [[0.0; 4]; 2];
        for lane in 0..4 {
            let (a, b) = pairs.pair(group + lane);
            for (t, tri) in [a, b].into_iter().enumerate() {
                let ptr = tri.as_ptr().cast::<f64>();
                // SAFETY: a triangle is nine consecutive f64 (asserted above),
                // so f64 0-3 and 4-7 are inside it.
                unsafe {
                    rows[t][0][lane] = _mm256_loadu_pd(ptr);
                    rows[t][1][lane] = _mm256_loadu_pd(ptr.add(4));
                }
                last[t][lane] = tri[2].z;
            }
        }
        for t in 0..2 {
            for half in 0..2 {
                let cols = transpose_4x4(rows[t][half]);
                for (j, col) in cols.into_iter().enumerate() {
                    let c = 4 * half + j;
                    let (v, k) = (3 * t + c / 3, c % 3);
                    // SAFETY: `group + 4 <= N`, so each store stays inside its row.
                    unsafe { _mm256_storeu_pd(out[v][k][group..].as_mut_ptr(), col) };
                }
            }
            out[3 * t + 2][2][group..group + 4].copy_from_slice(&last[t]);
        }
    }
    out
}

/// Answers of `N` lanes, where the kernel left them: distance and closest
/// points (in the pairs' own coordinates), one coordinate per row.
pub(crate) struct AnswerLanes<'a, const N: usize> {
    pub distance: &'a [f64; N],
    pub p: [&'a [f64; N]; 3],
    pub q: [&'a [f64; N]; 3],
}

/// Writes the answers of the first `out.len()` lanes, lane by lane.
#[inline(always)]
pub(crate) fn store_answers<const N: usize>(
    ans: &AnswerLanes<'_, N>,
    solver: Solver,
    out: &mut [Closest],
) {
    for (lane, o) in out.iter_mut().enumerate() {
        *o = Closest {
            distance: ans.distance[lane],
            p: DVec3::new(ans.p[0][lane], ans.p[1][lane], ans.p[2][lane]),
            q: DVec3::new(ans.q[0][lane], ans.q[1][lane], ans.q[2][lane]),
            solver,
        };
    }
}

// The vector stores write an answer's distance and points as seven
// consecutive f64 (`Closest` is `repr(C)`).
const _: () = {
    assert!(std::mem::offset_of!(Closest, distance) == 0);
    assert!(std::mem::offset_of!(Closest, p) == 8);
    assert!(std::mem::offset_of!(Closest, q) == 32);
};

/// [`store_answers`] with an in-register transpose and one masked vector
/// store per answer, for a multiple of 8 lanes all written; anything else
/// goes lane by lane.
///
/// # Safety
/// The CPU must support AVX-512F.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f")]
pub(crate) unsafe fn store_answers_avx512<const N: usize>(
    ans: &AnswerLanes<'_, N>,
    solver: Solver,
    out: &mut [Closest],
) {
    use std::arch::x86_64::*;
    if !N.is_multiple_of(8) || out.len() != N {
        return store_answers(ans, solver, out);
    }
    for group in (0..N).step_by(8) {
        // SAFETY: `group + 8 <= N`, so each load stays inside its row.
        let load = |row: &[f64; N]| unsafe { _mm512_loadu_pd(row[group..].as_ptr()) };
        let d = load(ans.distance);
        let cols = [
            d,
            load(ans.p[0]),
            load(ans.p[1]),
            load(ans.p[2]),
            load(ans.q[0]),
            load(ans.q[1]),
            load(ans.q[2]),
            d,
        ];
        let rows = transpose_8x8(cols);
        for (lane, row) in rows.into_iter().enumerate() {
            let o = &mut out[group + lane];
            // SAFETY: the first seven f64 of a `Closest` are its distance and
            // points (asserted above); the mask leaves the solver alone.
            unsafe { _mm512_mask_storeu_pd((o as *mut Closest).cast::<f64>(), 0x7f, row) };
            o.solver = solver;
        }
    }
}

/// [`store_answers`] with 4x4 transposes in registers and two vector
/// stores per answer, for a multiple of 4 lanes all written; anything else
/// goes lane by lane.
///
/// # Safety
/// The CPU must support AVX2.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
pub(crate) unsafe fn store_answers_avx2<const N: usize>(
    ans: &AnswerLanes<'_, N>,
    solver: Solver,
    out: &mut [Closest],
) {
    use std::arch::x86_64::*;
    if !N.is_multiple_of(4) || out.len() != N {
        return store_answers(ans, solver, out);
    }
    // The first three lanes of a 4-wide store: Q without what follows it.
    let three = _mm256_set_epi64x(0, -1, -1, -1);
    for group in (0..N).step_by(4) {
        // SAFETY: `group + 4 <= N`, so each load stays inside its row.
        let load = |row: &[f64; N]| unsafe { _mm256_loadu_pd(row[group..].as_ptr()) };
        let d = load(ans.distance);
        let dp = transpose_4x4([d, load(ans.p[0]), load(ans.p[1]), load(ans.p[2])]);
        let q = transpose_4x4([load(ans.q[0]), load(ans.q[1]), load(ans.q[2]), d]);
        for lane in 0..4 {
            let o = &mut out[group + lane];
            let ptr = (o as *mut Closest).cast::<f64>();
            // SAFETY: a `Closest` starts with its distance, P and Q, seven
            // f64 (asserted above); the mask leaves what follows Q alone.
            unsafe {
                _mm256_storeu_pd(ptr, dp[lane]);
                _mm256_maskstore_pd(ptr.add(4), three, q[lane]);
            }
            o.solver = solver;
        }
    }
}

/// [`store_answers_avx512`] or [`store_answers_avx2`] where the CPU is
/// proved to have the instructions, [`store_answers`] otherwise.
#[inline]
pub(crate) fn store_answers_on<const N: usize>(
    ans: &AnswerLanes<'_, N>,
    solver: Solver,
    isa: Supported,
    out: &mut [Closest],
) {
    match isa.isa() {
        // SAFETY: a `Supported` proves AVX-512F on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx512 => unsafe { store_answers_avx512(ans, solver, out) },
        // SAFETY: a `Supported` proves AVX2 on this CPU.
        #[cfg(target_arch = "x86_64")]
        Isa::Avx2 => unsafe { store_answers_avx2(ans, solver, out) },
        _ => store_answers(ans, solver, out),
    }
}

/// Transposes the 4x4 matrix whose rows are `r`: pairs of rows interleaved,
/// then the 128-bit halves of those exchanged.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx2")]
fn transpose_4x4(r: [std::arch::x86_64::__m256d; 4]) -> [std::arch::x86_64::__m256d; 4] {
    use std::arch::x86_64::*;
    // (r0[0], r1[0], r0[2], r1[2]) and (r0[1], r1[1], r0[3], r1[3]); then rows 2, 3.
    let t0 = _mm256_unpacklo_pd(r[0], r[1]);
    let t1 = _mm256_unpackhi_pd(r[0], r[1]);
    let t2 = _mm256_unpacklo_pd(r[2], r[3]);
    let t3 = _mm256_unpackhi_pd(r[2], r[3]);
    [
        _mm256_permute2f128_pd::<0x20>(t0, t2),
        _mm256_permute2f128_pd::<0x20>(t1, t3),
        _mm256_permute2f128_pd::<0x31>(t0, t2),
        _mm256_permute2f128_pd::<0x31>(t1, t3),
    ]
}

/// Transposes the 8x8 matrix whose rows are `r`: three rounds of shuffles,
/// each interleaving blocks of twice the size of the round before.
#[cfg(target_arch = "x86_64")]
#[inline]
#[target_feature(enable = "avx512f")]
fn transpose_8x8(r: [std::arch::x86_64::__m512d; 8]) -> [std::arch::x86_64::__m512d; 8] {
    use std::arch::x86_64::*;
    // Pairs: t[2i] = (r[2i][0], r[2i+1][0], r[2i][2], r[2i+1][2], ...), t[2i+1] the odd columns.
    let mut t = [_mm512_setzero_pd(); 8];
    for i in 0..4 {
        t[2 * i] = _mm512_unpacklo_pd(r[2 * i], r[2 * i + 1]);
        t[2 * i + 1] = _mm512_unpackhi_pd(r[2 * i], r[2 * i + 1]);
    }
    // Quads: columns {c, c + 4} of four rows, for c = 0..4.
    let lo = _mm512_set_epi64(13, 12, 5, 4, 9, 8, 1, 0);
    let hi = _mm512_set_epi64(15, 14, 7, 6, 11, 10, 3, 2);
    let mut q = [_mm512_setzero_pd(); 8];
    for half in 0..2 {
        let (t0, t1, t2, t3) = (
            t[4 * half],
            t[4 * half + 1],
            t[4 * half + 2],
            t[4 * half + 3],
        );
        q[4 * half] = _mm512_permutex2var_pd(t0, lo, t2);
        q[4 * half + 1] = _mm512_permutex2var_pd(t1, lo, t3);
        q[4 * half + 2] = _mm512_permutex2var_pd(t0, hi, t2);
        q[4 * half + 3] = _mm512_permutex2var_pd(t1, hi, t3);
    }
    // Whole columns: the low 256 bits of rows 0..4's quad, then rows 4..8's.
    let mut c = [_mm512_setzero_pd(); 8];
    for k in 0..4 {
        c[k] = _mm512_shuffle_f64x2::<0b01_00_01_00>(q[k], q[4 + k]);
        c[4 + k] = _mm512_shuffle_f64x2::<0b11_10_11_10>(q[k], q[4 + k]);
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::distance::random_unit_pairs;

    fn check<const N: usize>(pairs: &[(Triangle, Triangle)]) {
        let lanes = load_pairs::<N, _>(pairs);
        for lane in 0..N {
            let (a, b) = &pairs[lane.min(pairs.len() - 1)];
            for v in 0..3 {
                for k in 0..3 {
                    assert_eq!(lanes[v][k][lane], a[v][k]);
                    assert_eq!(lanes[3 + v][k][lane], b[v][k]);
                }
            }
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx512f") {
            // SAFETY: checked just above.
            let fast = unsafe { load_pairs_avx512::<N, _>(pairs) };
            assert_eq!(fast, lanes);
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            // SAFETY: checked just above.
            let fast = unsafe { load_pairs_avx2::<N, _>(pairs) };
            assert_eq!(fast, lanes);
        }
    }

    #[test]
    fn lanes_hold_the_pairs_coordinates() {
        let pairs = random_unit_pairs(16, 7);
        check::<8>(&pairs[..8]);
        check::<16>(&pairs);
        check::<8>(&pairs[..5]);
        check::<4>(&pairs[..4]);
        check::<1>(&pairs[..1]);
    }

    fn check_store<const N: usize>(n: usize) {
        let rows: [[f64; N]; 7] =
            std::array::from_fn(|k| std::array::from_fn(|l| (100 * k + l) as f64));
        let ans = AnswerLanes {
            distance: &rows[0],
            p: [&rows[1], &rows[2], &rows[3]],
            q: [&rows[4], &rows[5], &rows[6]],
        };
        let blank = Closest::UNSET;
        let mut out = vec![blank; n];
        store_answers(&ans, Solver::Brute, &mut out);
        for (l, o) in out.iter().enumerate() {
            assert_eq!(o.distance, l as f64);
            assert_eq!(o.p, DVec3::new(100.0, 200.0, 300.0) + l as f64);
            assert_eq!(o.q, DVec3::new(400.0, 500.0, 600.0) + l as f64);
            assert_eq!(o.solver, Solver::Brute);
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx512f") {
            let mut fast = vec![blank; n];
            // SAFETY: checked just above.
            unsafe { store_answers_avx512(&ans, Solver::Brute, &mut fast) };
            assert_eq!(fast, out);
        }
        #[cfg(target_arch = "x86_64")]
        if std::is_x86_feature_detected!("avx2") {
            let mut fast = vec![blank; n];
            // SAFETY: checked just above.
            unsafe { store_answers_avx2(&ans, Solver::Brute, &mut fast) };
            assert_eq!(fast, out);
        }
    }

    #[test]
    fn answers_land_in_their_pairs() {
        check_store::<8>(8);
        check_store::<16>(16);
        check_store::<8>(3);
        check_store::<4>(4);
    }
}
