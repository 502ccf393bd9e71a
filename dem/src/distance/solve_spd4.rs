//! Solving a 4x4 symmetric positive definite system, unrolled, two ways.
//!
//! LDL^T (four divisions in a chain) where accuracy matters. For speed, by 2x2
//! blocks, one per triangle: with H = [[A, C], [C^T, B]], eliminate the first
//! triangle's unknowns through A's adjugate, solve the Schur complement, then
//! substitute back, with one division and no square roots: divisions are the
//! slowest vector instructions in the Newton step and an LDL^T factorisation
//! needs four, in a chain. Both blocks of an SPD matrix are SPD, so the
//! determinants are positive. Straight-line code on lanes, so it vectorises.

use super::lanes::F;

/// The upper triangle of a symmetric 4x4 matrix per lane, row by row:
/// (0,0) (0,1) (0,2) (0,3) (1,1) (1,2) (1,3) (2,2) (2,3) (3,3).
pub type Sym4<const N: usize> = [F<N>; 10];

/// Index pairs of [`Sym4`]'s entries.
pub const SYM4_INDEX: [(usize, usize); 10] = [
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

/// x with H x = rhs in each lane, for H symmetric positive definite, by an
/// LDL^T factorisation: four divisions, backward stable.
#[inline(always)]
pub fn solve_spd4<const N: usize>(h: &Sym4<N>, rhs: [F<N>; 4]) -> [F<N>; 4] {
    let [h00, h01, h02, h03, h11, h12, h13, h22, h23, h33] = *h;
    // H = L D L^T with unit lower-triangular L; e_ij = l_ij d_j.
    let i0 = 1.0 / h00;
    let (l10, l20, l30) = (h01 * i0, h02 * i0, h03 * i0);
    let d1 = h11 - l10 * h01;
    let i1 = 1.0 / d1;
    let e21 = h12 - l20 * h01;
    let e31 = h13 - l30 * h01;
    let (l21, l31) = (e21 * i1, e31 * i1);
    let d2 = h22 - l20 * h02 - l21 * e21;
    let i2 = 1.0 / d2;
    let e32 = h23 - l30 * h02 - l31 * e21;
    let l32 = e32 * i2;
    let d3 = h33 - l30 * h03 - l31 * e31 - l32 * e32;
    let i3 = 1.0 / d3;
    // L z = rhs, then L^T x = D^-1 z.
    let z0 = rhs[0];
    let z1 = rhs[1] - l10 * z0;
    let z2 = rhs[2] - l20 * z0 - l21 * z1;
    let z3 = rhs[3] - l30 * z0 - l31 * z1 - l32 * z2;
    let x3 = z3 * i3;
    let x2 = z2 * i2 - l32 * x3;
    let x1 = z1 * i1 - l21 * x2 - l31 * x3;
    let x0 = z0 * i0 - l10 * x1 - l20 * x2 - l30 * x3;
    [x0, x1, x2, x3]
}

/// x with H x = rhs in each lane, for H symmetric positive definite, by 2x2
/// blocks and a single division. Less accurate than [`solve_spd4`] when a
/// block is nearly singular (a sliver triangle): good for Newton's steps, which
/// only need to head the right way, not for the finish.
///
/// With H = [[A, C], [C^T, B]], the Schur complement is kept multiplied by
/// det A, S' = det A B - C^T adj(A) C, so that S' x_B = det A rhs_B -
/// C^T adj(A) rhs_A needs no 1/det A, and x_A = (adj(A) rhs_A - adj(A) C x_B)
/// / det A. Both reciprocals come from one division, 1 / (det A det S'):
/// divisions are the slowest vector instructions and Newton's step is a chain
/// of dependent operations, so each division saved shortens the chain. The
/// products of determinants reach the 8th power of H's entries: H must be
/// scaled to entries of order one (the callers divide by trace(G) / 4).
#[inline(always)]
pub fn solve_spd4_by_blocks<const N: usize>(h: &Sym4<N>, rhs: [F<N>; 4]) -> [F<N>; 4] {
    let [h00, h01, h02, h03, h11, h12, h13, h22, h23, h33] = *h;
    let det_a = h00 * h11 - h01 * h01;
    // Y = adj(A) C with A = [[h00, h01], [h01, h11]], C = [[h02, h03], [h12, h13]].
    let y00 = h11 * h02 - h01 * h12;
    let y01 = h11 * h03 - h01 * h13;
    let y10 = h00 * h12 - h01 * h02;
    let y11 = h00 * h13 - h01 * h03;
    // S' = det A B - C^T Y.
    let s00 = det_a * h22 - (h02 * y00 + h12 * y10);
    let s01 = det_a * h23 - (h02 * y01 + h12 * y11);
    let s11 = det_a * h33 - (h03 * y01 + h13 * y11);
    let det_s = s00 * s11 - s01 * s01;
    let inv = 1.0 / (det_a * det_s);
    let (inv_a, inv_s) = (det_s * inv, det_a * inv);
    // z = adj(A) rhs_A; S' x_B = det A rhs_B - C^T z; x_A = (z - Y x_B) / det A.
    let z0 = h11 * rhs[0] - h01 * rhs[1];
    let z1 = h00 * rhs[1] - h01 * rhs[0];
    let r2 = det_a * rhs[2] - (h02 * z0 + h12 * z1);
    let r3 = det_a * rhs[3] - (h03 * z0 + h13 * z1);
    let x2 = (s11 * r2 - s01 * r3) * inv_s;
    let x3 = (s00 * r3 - s01 * r2) * inv_s;
    let x0 = (z0 - (y00 * x2 + y01 * x3)) * inv_a;
    let x1 = (z1 - (y10 * x2 + y11 * x3)) * inv_a;
    [x0, x1, x2, x3]
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Against Gaussian elimination with partial pivoting on the full matrix.
    fn reference(h: &[f64; 10], rhs: [f64; 4]) -> [f64; 4] {
        let mut m = [[0.0; 5]; 4];
        for (k, &(i, j)) in SYM4_INDEX.iter().enumerate() {
            m[i][j] = h[k];
            m[j][i] = h[k];
        }
        for (i, row) in m.iter_mut().enumerate() {
            row[4] = rhs[i];
        }
        for c in 0..4 {
            let p = (c..4)
                .max_by(|&a, &b| m[a][c].abs().total_cmp(&m[b][c].abs()))
                .unwrap();
            m.swap(c, p);
            let pivot = m[c];
            for row in m.iter_mut().skip(c + 1) {
                let f = row[c] / pivot[c];
                for (x, y) in row.iter_mut().zip(&pivot).skip(c) {
                    *x -= f * y;
                }
            }
        }
        let mut x = [0.0; 4];
        for i in (0..4).rev() {
            let s: f64 = (i + 1..4).map(|k| m[i][k] * x[k]).sum();
            x[i] = (m[i][4] - s) / m[i][i];
        }
        x
    }

    #[test]
    fn agrees_with_gaussian_elimination_on_gram_matrices() {
        // H = A^T A + I for a fixed, unstructured A: SPD with condition ~ 1e2.
        let a = [
            [0.3, -1.2, 2.0, 0.7],
            [1.1, 0.4, -0.5, 2.2],
            [-0.8, 1.9, 0.6, -1.3],
            [0.2, 0.9, 1.4, 0.1],
        ];
        let mut h = [0.0; 10];
        for (k, &(i, j)) in SYM4_INDEX.iter().enumerate() {
            h[k] = (0..4).map(|r| a[r][i] * a[r][j]).sum::<f64>() + if i == j { 1.0 } else { 0.0 };
        }
        let rhs = [1.0, -2.0, 0.5, 3.0];
        let y = reference(&h, rhs);
        let (hl, rl) = (h.map(|v| F([v])), rhs.map(|v| F([v])));
        for x in [solve_spd4(&hl, rl), solve_spd4_by_blocks(&hl, rl)] {
            for k in 0..4 {
                assert!(
                    (x[k].0[0] - y[k]).abs() <= 1e-13 * y[k].abs().max(1.0),
                    "{x:?} vs {y:?}"
                );
            }
        }
    }
}
