//! The broad phase's uniform grid: O(n) pairs of moving boxes in a dense
//! scene, where a sweep along one axis compares each box with every box of
//! its slab across the other two (a silo's layer of grains: hundreds).
//!
//! Each box no wider than a cell lives in the one cell that holds its lower
//! corner. Two such boxes that overlap have lower corners less than a cell
//! apart on every axis, so their cells are the same or neighbours: each box
//! is tested against the boxes after it in its own cell and against those in
//! the 13 neighbouring cells that come after its cell (every pair of
//! neighbouring cells once). The cell is the widest box but for the few more
//! than twice the median width (a boulder among grains, a paddle), which are
//! tested against every box instead, as the static boxes are.
//!
//! Cells are numbered densely over the lower corners' box. A scene whose
//! slabs along its widest span hold few boxes (a hopper's stream, grains
//! falling in a tall column) gets no grid, nor one whose cells would
//! outnumber its boxes many times: the sweep is cheap there.
//!
//! The cell is widened by a millionth over the widest box: the cell of a
//! corner is computed with rounding, at most a few units in the last place of
//! the corner's distance from the grid's origin counted in cells, and the
//! grid holds at most [`MAX_CELLS`] cells, so two corners less than a box
//! width apart always land in the same or neighbouring cells, at any scale
//! and any distance from the origin.

use crate::contact::Bounds;

/// Cells at most this many times the boxes: beyond, the scene is sparse and
/// the sweep is used.
const CELLS_PER_BOX: usize = 8;

/// The grid is laid only where a sweep would compare a box with more than
/// this many others: n boxes of median width w over a span L along the
/// sweep's axis put about n w / L in a slab. The grid compares a box with
/// the boxes of 14 cells, a few tens in a dense scene, and costs its
/// counting sort at each call. Measured on one thread (the broad phase's
/// section, three alternating runs each): the 400-grain hopper (about 20
/// per slab) swept its pairs in two thirds of the grid's time, the
/// 1,000-grain silo (about 90) in 0.94 of it, the 10,000-grain silo (about
/// 380) in 2.5 times the grid's.
const MIN_CROWD: f64 = 128.0;

/// The most cells a grid numbers (see the module doc on rounding).
const MAX_CELLS: usize = 1 << 26;

/// A box is tested against every box, not placed in a cell, when it is
/// wider than this many times the median width.
const LARGE: f64 = 2.0;

/// The neighbours of a cell that come after it, as (dx, dy, dz): with the
/// cell itself, each pair of neighbouring cells is visited once.
const FORWARD: [(i64, i64, i64); 13] = [
    (1, 0, 0),
    (-1, 1, 0),
    (0, 1, 0),
    (1, 1, 0),
    (-1, -1, 1),
    (0, -1, 1),
    (1, -1, 1),
    (-1, 0, 1),
    (0, 0, 1),
    (1, 0, 1),
    (-1, 1, 1),
    (0, 1, 1),
    (1, 1, 1),
];

/// A grid over one call's moving boxes, with its buffers kept between calls.
#[derive(Debug, Default)]
pub(super) struct Grid {
    /// Per box: its cell, or `u32::MAX` for a large box.
    cell: Vec<u32>,
    /// Per box in a cell: its place among the cell's boxes.
    place: Vec<u32>,
    /// Boxes by cell: those of cell c are `order[start[c]..start[c + 1]]`.
    start: Vec<u32>,
    order: Vec<u32>,
    large: Vec<u32>,
    widths: Vec<f64>,
    dims: [usize; 3],
}

impl Grid {
    /// Lays the grid over `boxes`; false when the scene is too sparse for
    /// one (or a box is not finite), and the caller sweeps instead.
    pub(super) fn build(&mut self, boxes: impl ExactSizeIterator<Item = Bounds> + Clone) -> bool {
        let n = boxes.len();
        self.widths.clear();
        self.widths
            .extend(boxes.clone().map(|b| (b.hi - b.lo).max_element()));
        if n == 0 || !self.widths.iter().all(|w| w.is_finite() && *w >= 0.0) {
            return false;
        }
        let mut sorted = self.widths.clone();
        let (_, &mut median, _) = sorted.select_nth_unstable_by(n / 2, f64::total_cmp);
        let limit = LARGE * median;
        let widest = self
            .widths
            .iter()
            .copied()
            .filter(|&w| w <= limit)
            .fold(0.0, f64::max);
        let size = widest * (1.0 + 1e-6);
        if size.is_nan() || size <= 0.0 {
            return false;
        }
        let small = |w: f64| w <= limit;
        let (mut lo, mut hi) = ([f64::INFINITY; 3], [f64::NEG_INFINITY; 3]);
        for (b, &w) in boxes.clone().zip(&self.widths) {
            if small(w) {
                for k in 0..3 {
                    lo[k] = lo[k].min(b.lo[k]);
                    hi[k] = hi[k].max(b.lo[k]);
                }
            }
        }
        let span = (0..3).map(|k| hi[k] - lo[k]).fold(0.0, f64::max);
        if n as f64 * median <= MIN_CROWD * span || span.is_nan() {
            return false;
        }
        let mut cells = 1usize;
        for k in 0..3 {
            let span = ((hi[k] - lo[k]) / size).floor();
            if span.is_nan() || span >= MAX_CELLS as f64 {
                return false;
            }
            self.dims[k] = span as usize + 1;
            cells = cells.saturating_mul(self.dims[k]);
        }
        if cells > MAX_CELLS || cells > CELLS_PER_BOX * n {
            return false;
        }
        let dims = self.dims;
        let at = |x: f64, k: usize| (((x - lo[k]) / size).floor() as usize).min(dims[k] - 1);
        self.cell.clear();
        self.large.clear();
        for (i, (b, &w)) in boxes.zip(&self.widths).enumerate() {
            if small(w) {
                let c = at(b.lo.x, 0) + dims[0] * (at(b.lo.y, 1) + dims[1] * at(b.lo.z, 2));
                self.cell.push(c as u32);
            } else {
                self.cell.push(u32::MAX);
                self.large.push(i as u32);
            }
        }
        // Counting sort of the boxes by cell, each cell's in box order.
        self.start.clear();
        self.start.resize(cells + 1, 0);
        for &c in &self.cell {
            if c != u32::MAX {
                self.start[c as usize + 1] += 1;
            }
        }
        for c in 1..=cells {
            self.start[c] += self.start[c - 1];
        }
        self.order.clear();
        self.order.resize(self.start[cells] as usize, 0);
        let mut next = self.start.clone();
        self.place.clear();
        for (i, &c) in self.cell.iter().enumerate() {
            let mut place = 0;
            if c != u32::MAX {
                let at = &mut next[c as usize];
                self.order[*at as usize] = i as u32;
                place = *at - self.start[c as usize];
                *at += 1;
            }
            self.place.push(place);
        }
        true
    }

    /// Calls `meet(i, j)` for each pair of boxes that may overlap and that
    /// box `i` is to test: for a box in a cell, the boxes after it in its
    /// cell and in the cells after it around; for a large box, every box
    /// that is not a large box before it. Together, each pair once.
    pub(super) fn candidates_of(&self, i: usize, mut meet: impl FnMut(usize)) {
        let c = self.cell[i];
        if c == u32::MAX {
            for (j, &cj) in self.cell.iter().enumerate() {
                if j != i && (cj != u32::MAX || j > i) {
                    meet(j);
                }
            }
            return;
        }
        let c = c as usize;
        let [nx, ny, nz] = self.dims;
        let after = self.start[c] + self.place[i] + 1;
        for &j in &self.order[after as usize..self.start[c + 1] as usize] {
            meet(j as usize);
        }
        let (x, y, z) = (
            (c % nx) as i64,
            ((c / nx) % ny) as i64,
            (c / (nx * ny)) as i64,
        );
        for (dx, dy, dz) in FORWARD {
            let (u, v, w) = (x + dx, y + dy, z + dz);
            if u < 0 || v < 0 || w < 0 || u >= nx as i64 || v >= ny as i64 || w >= nz as i64 {
                continue;
            }
            let d = u as usize + nx * (v as usize + ny * w as usize);
            for &j in &self.order[self.start[d] as usize..self.start[d + 1] as usize] {
                meet(j as usize);
            }
        }
    }
}
