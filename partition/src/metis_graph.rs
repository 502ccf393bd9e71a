//! METIS on the proximity graph of the items.
//!
//! Vertices are items; an edge joins two items whose boxes, each inflated by
//! the halo, overlap: the pairs that may come into contact. METIS is serial, so
//! the items are gathered on rank 0, the graph is built there with a cell grid,
//! partitioned with `METIS_PartGraphKway`, and the owners are scattered back;
//! the measured partition time is that whole round trip.
//!
//! METIS returns no geometric cuts, so regions are cells: the grid cells holding
//! item points, each given wholly to the rank with most of its weight (items of
//! a cell follow it, which keeps `owner(point)` consistent with the partition
//! and costs little balance, cells being about one item wide). Every rank
//! receives the cell owners (a dense grid over the items' bounding box) for
//! point and box queries; a point in an empty cell belongs to the owner of
//! the nearest occupied cell.

use crate::comm::displacements;
use crate::{Aabb, Item, PartitionError, Partitioner};
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;

/// The graph halo is at least this fraction of the mean item spacing: about a
/// dozen neighbours per item for items half a spacing wide, enough for a
/// connected graph, few enough to keep the serial graph build and METIS cheap.
const GRAPH_SPACING: f64 = 0.35;

/// Nearest neighbours kept per item besides its contact pairs.
const MAX_NEIGHBOURS: usize = 10;

/// Cells per item at most: the grid is dense, so its size is bounded by the items.
const MAX_CELLS_PER_ITEM: f64 = 4.0;

#[derive(Debug, Clone, Default)]
pub struct MetisPartitioner {
    /// Contact halo: items whose boxes inflated by it overlap are always joined
    /// in the graph (whose halo is at least a fraction of the mean item spacing).
    pub halo: f64,
    /// Renumber the parts to overlap the items' current owners most (METIS
    /// numbers its parts afresh each time).
    pub remap: bool,
    grid: Option<Grid>,
}

/// A dense grid over the items' points; `owner[c]` is -1 for an empty cell.
#[derive(Debug, Clone, Default)]
struct Grid {
    origin: [f64; 3],
    size: f64,
    dims: [usize; 3],
    owner: Vec<i32>,
}

impl Grid {
    fn new(domain: &Aabb, size: f64) -> Grid {
        let dims =
            [0, 1, 2].map(|k| (((domain.hi[k] - domain.lo[k]) / size).floor() as usize + 1).max(1));
        Grid {
            origin: domain.lo,
            size,
            dims,
            owner: Vec::new(),
        }
    }

    /// Integer cell coordinates, clamped to the grid.
    fn coords(&self, p: [f64; 3]) -> [usize; 3] {
        [0, 1, 2].map(|k| {
            let c = ((p[k] - self.origin[k]) / self.size).floor();
            c.clamp(0.0, (self.dims[k] - 1) as f64) as usize
        })
    }

    fn index(&self, c: [usize; 3]) -> usize {
        (c[2] * self.dims[1] + c[1]) * self.dims[0] + c[0]
    }

    /// The coordinates of cell `index` (the inverse of [`Grid::index`]).
    fn coords_of(&self, index: usize) -> [usize; 3] {
        let [nx, ny, _] = self.dims;
        [index % nx, (index / nx) % ny, index / (nx * ny)]
    }

    fn len(&self) -> usize {
        self.dims.iter().product()
    }
}

impl MetisPartitioner {
    pub fn with_halo(halo: f64) -> Self {
        MetisPartitioner {
            halo,
            remap: true,
            grid: None,
        }
    }
}

/// Builds the graph, partitions it and makes the result cell-consistent.
/// Returns (owner per item, grid with the cell owners).
fn partition_on_root(
    items: &[Item],
    nparts: i32,
    halo: f64,
) -> Result<(Vec<i32>, Grid), PartitionError> {
    let n = items.len();
    let (mut grid, graph_halo) = graph_grid(items, halo);
    let cells = CellSort::of(items, &grid);
    let mut owners = vec![0i32; n];
    if nparts > 1 && n > 0 {
        let edges = graph_edges(items, &grid, &cells, halo, graph_halo);
        owners = metis_parts(items, nparts, &edges)?;
    }
    whole_cells(items, &mut grid, &cells, &mut owners, nparts);
    Ok((owners, grid))
}

/// The grid the graph is built on, and the graph's halo: at least the
/// contact halo, and wide enough that items have neighbours where they are
/// sparse.
fn graph_grid(items: &[Item], halo: f64) -> (Grid, f64) {
    let n = items.len();
    let mut domain = Aabb::EMPTY;
    let mut reach = 0.0f64;
    for it in items {
        domain.grow(it.point);
        for k in 0..3 {
            reach = reach
                .max((it.point[k] - it.bbox.lo[k]).abs())
                .max((it.bbox.hi[k] - it.point[k]).abs());
        }
    }
    if n == 0 {
        domain = Aabb::new([0.0; 3], [0.0; 3]);
    }
    let ext = domain.extent();
    let extent = ext.into_iter().fold(0.0, f64::max);
    let volume: f64 = ext.iter().map(|e| e.max(extent * 1e-3)).product();
    let spacing = (volume / n.max(1) as f64).cbrt();
    let graph_halo = halo.max(GRAPH_SPACING * spacing);
    // Items whose inflated boxes overlap have points within 2 (reach + halo) per
    // axis, so they are in the same or adjacent cells.
    let mut size = (2.0 * (reach + graph_halo))
        .max(extent * 1e-6)
        .max(f64::MIN_POSITIVE);
    let mut grid = Grid::new(&domain, size);
    while grid.len() as f64 > MAX_CELLS_PER_ITEM * n.max(1) as f64 {
        size *= 1.25;
        grid = Grid::new(&domain, size);
    }
    (grid, graph_halo)
}

/// Items sorted by cell (a counting sort): cell c holds
/// `by_cell[start[c]..start[c + 1]]`.
struct CellSort {
    by_cell: Vec<u32>,
    start: Vec<usize>,
}

impl CellSort {
    fn of(items: &[Item], grid: &Grid) -> CellSort {
        let cell_of: Vec<usize> = items
            .iter()
            .map(|it| grid.index(grid.coords(it.point)))
            .collect();
        let mut start = vec![0usize; grid.len() + 1];
        for &c in &cell_of {
            start[c + 1] += 1;
        }
        for c in 0..grid.len() {
            start[c + 1] += start[c];
        }
        let mut fill = start.clone();
        let mut by_cell = vec![0u32; items.len()];
        for (i, &c) in cell_of.iter().enumerate() {
            by_cell[fill[c]] = i as u32;
            fill[c] += 1;
        }
        CellSort { by_cell, start }
    }
}

/// The graph's edges, sorted, each once per direction: all contact pairs
/// (found from both ends), plus up to MAX_NEIGHBOURS nearest within the
/// graph halo (dense regions would otherwise get hundreds per item), made
/// symmetric as METIS requires. Items are visited in cell order, so that
/// neighbouring cells are neighbours in memory.
fn graph_edges(
    items: &[Item],
    grid: &Grid,
    cells: &CellSort,
    halo: f64,
    graph_halo: f64,
) -> Vec<(u32, u32)> {
    let (by_cell, start) = (&cells.by_cell, &cells.start);
    let pts: Vec<[f64; 3]> = by_cell.iter().map(|&i| items[i as usize].point).collect();
    let boxes = |pad: f64| -> Vec<Aabb> {
        by_cell
            .iter()
            .map(|&i| items[i as usize].bbox.inflated(pad))
            .collect()
    };
    let (contact_boxes, graph_boxes) = (boxes(halo), boxes(graph_halo));
    let mut edges: Vec<(u32, u32)> = Vec::with_capacity(items.len() * MAX_NEIGHBOURS);
    let mut near: Vec<(f64, u32)> = Vec::new();
    for cell in 0..grid.len() {
        let c = grid.coords_of(cell);
        let lo = c.map(|x| x.saturating_sub(1));
        let hi = [0, 1, 2].map(|k| (c[k] + 1).min(grid.dims[k] - 1));
        for k in start[cell]..start[cell + 1] {
            near.clear();
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    let row0 = grid.index([lo[0], y, z]);
                    let row1 = grid.index([hi[0], y, z]);
                    // Cells lo[0]..=hi[0] of a row are contiguous: one range.
                    for k2 in (start[row0]..start[row1 + 1]).filter(|&k2| k2 != k) {
                        if contact_boxes[k].overlaps(&contact_boxes[k2]) {
                            edges.push((by_cell[k], by_cell[k2]));
                        } else if graph_boxes[k].overlaps(&graph_boxes[k2]) {
                            let d: f64 = (0..3).map(|a| (pts[k2][a] - pts[k][a]).powi(2)).sum();
                            near.push((d, by_cell[k2]));
                        }
                    }
                }
            }
            if near.len() > MAX_NEIGHBOURS {
                near.select_nth_unstable_by(MAX_NEIGHBOURS, |a, b| a.0.total_cmp(&b.0));
                near.truncate(MAX_NEIGHBOURS);
            }
            let i = by_cell[k];
            for &(_, j) in &near {
                edges.push((i, j));
                edges.push((j, i));
            }
        }
    }
    edges.sort_unstable();
    edges.dedup();
    edges
}

/// METIS k-way on the graph of `edges` (sorted), with the items' weights
/// scaled to integers around 100.
fn metis_parts(
    items: &[Item],
    nparts: i32,
    edges: &[(u32, u32)],
) -> Result<Vec<i32>, PartitionError> {
    let n = items.len();
    let mut xadj: Vec<metis::Idx> = Vec::with_capacity(n + 1);
    let mut adjncy: Vec<metis::Idx> = Vec::with_capacity(edges.len());
    xadj.push(0);
    let mut e = 0;
    for i in 0..n as u32 {
        while e < edges.len() && edges[e].0 == i {
            adjncy.push(edges[e].1 as metis::Idx);
            e += 1;
        }
        xadj.push(adjncy.len() as metis::Idx);
    }
    let mean = items.iter().map(|i| i.weight).sum::<f64>() / n as f64;
    let scale = if mean > 0.0 { 100.0 / mean } else { 1.0 };
    let vwgt: Vec<metis::Idx> = items
        .iter()
        .map(|i| ((i.weight * scale).round() as metis::Idx).max(1))
        .collect();
    let mut part = vec![0 as metis::Idx; n];
    metis::Graph::new(1, nparts, &xadj, &adjncy)
        .map_err(|e| PartitionError::Metis(format!("{e:?}")))?
        .set_vwgt(&vwgt)
        .part_kway(&mut part)
        .map_err(|e| PartitionError::Metis(format!("{e:?}")))?;
    Ok(part)
}

/// Each occupied cell goes wholly to the rank holding most of its weight.
fn whole_cells(items: &[Item], grid: &mut Grid, cells: &CellSort, owners: &mut [i32], nparts: i32) {
    grid.owner = vec![-1; grid.len()];
    let mut weight_of = vec![0.0f64; nparts.max(1) as usize];
    for c in 0..grid.len() {
        let members = &cells.by_cell[cells.start[c]..cells.start[c + 1]];
        if members.is_empty() {
            continue;
        }
        for &i in members {
            weight_of[owners[i as usize] as usize] +=
                items[i as usize].weight.max(f64::MIN_POSITIVE);
        }
        let mut best = 0usize;
        for r in 0..weight_of.len() {
            if weight_of[r] > weight_of[best] {
                best = r;
            }
        }
        for &i in members {
            weight_of[owners[i as usize] as usize] = 0.0;
            owners[i as usize] = best as i32;
        }
        grid.owner[c] = best as i32;
    }
}

/// The rank each gathered item came from, in gather order.
fn senders(counts: &[Count]) -> Vec<i32> {
    (0..counts.len() as i32)
        .flat_map(|r| std::iter::repeat_n(r, counts[r as usize] as usize))
        .collect()
}

/// A renumbering of the new parts (`map[part]` is its rank) that keeps as
/// much weight as possible where it is: the pairs (new part, old rank) are
/// taken greedily by the weight they share, heaviest first, then the parts
/// left over take the ranks left over in order. Greedy matching is what
/// Zoltan's `REMAP` does too; it is within a factor of two of the best.
fn overlap_map(old: &[i32], new: &[i32], items: &[Item], parts: usize) -> Vec<i32> {
    let mut shared = vec![0.0f64; parts * parts];
    for ((&o, &n), it) in old.iter().zip(new).zip(items) {
        shared[n as usize * parts + o as usize] += it.weight;
    }
    let mut pairs: Vec<usize> = (0..shared.len()).filter(|&k| shared[k] > 0.0).collect();
    pairs.sort_by(|&a, &b| shared[b].total_cmp(&shared[a]).then(a.cmp(&b)));
    let mut map = vec![-1i32; parts];
    let mut taken = vec![false; parts];
    for k in pairs {
        let (n, o) = (k / parts, k % parts);
        if map[n] < 0 && !taken[o] {
            map[n] = o as i32;
            taken[o] = true;
        }
    }
    let mut free = (0..parts).filter(|&r| !taken[r]);
    for m in map.iter_mut().filter(|m| **m < 0) {
        *m = free.next().unwrap_or(0) as i32;
    }
    map
}

impl Partitioner for MetisPartitioner {
    fn name(&self) -> &'static str {
        "metis"
    }

    fn partition(
        &mut self,
        comm: &SimpleCommunicator,
        items: &[Item],
    ) -> Result<Vec<i32>, PartitionError> {
        let root = comm.process_at_rank(0);
        let size = comm.size();
        let n = items.len() as Count;
        // Gather the items on rank 0.
        let mut counts = vec![0 as Count; size as usize];
        if comm.rank() == 0 {
            root.gather_into_root(&n, &mut counts[..]);
        } else {
            root.gather_into(&n);
        }
        let displs = displacements(&counts);
        let mut result = Vec::new();
        let mut status = 0i32;
        let mut message = String::new();
        let mut grid = Grid::default();
        // origin, size, dims
        let mut header = [0.0f64; 7];
        if comm.rank() == 0 {
            let mut all = vec![Item::default(); counts.iter().sum::<Count>() as usize];
            {
                let mut r = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
                root.gather_varcount_into_root(items, &mut r);
            }
            // Sort by id so the graph, and METIS's answer, do not depend on
            // where the items happen to be stored.
            let mut order: Vec<usize> = (0..all.len()).collect();
            order.sort_unstable_by_key(|&i| all[i].id);
            let sorted: Vec<Item> = order.iter().map(|&i| all[i]).collect();
            match partition_on_root(&sorted, size, self.halo) {
                Ok((mut owners, mut g)) => {
                    if self.remap {
                        let from = senders(&counts);
                        let old: Vec<i32> = order.iter().map(|&i| from[i]).collect();
                        let map = overlap_map(&old, &owners, &sorted, size as usize);
                        for o in owners.iter_mut().chain(g.owner.iter_mut()) {
                            if *o >= 0 {
                                *o = map[*o as usize];
                            }
                        }
                    }
                    result = vec![0; all.len()];
                    for (k, &i) in order.iter().enumerate() {
                        result[i] = owners[k];
                    }
                    header = [
                        g.origin[0],
                        g.origin[1],
                        g.origin[2],
                        g.size,
                        g.dims[0] as f64,
                        g.dims[1] as f64,
                        g.dims[2] as f64,
                    ];
                    grid = g;
                }
                Err(e) => {
                    status = 1;
                    message = e.to_string();
                }
            }
        } else {
            root.gather_varcount_into(items);
        }
        // Every rank learns the outcome before anything else moves.
        root.broadcast_into(&mut status);
        if status != 0 {
            return Err(PartitionError::Metis(if message.is_empty() {
                "failed on rank 0".into()
            } else {
                message
            }));
        }
        root.broadcast_into(&mut header[..]);
        if comm.rank() != 0 {
            grid = Grid {
                origin: [header[0], header[1], header[2]],
                size: header[3],
                dims: [header[4] as usize, header[5] as usize, header[6] as usize],
                owner: Vec::new(),
            };
            grid.owner = vec![-1; grid.len()];
        }
        root.broadcast_into(&mut grid.owner[..]);
        self.grid = Some(grid);
        // Scatter the owners back in gather order.
        let mut mine = vec![0i32; items.len()];
        if comm.rank() == 0 {
            let s = Partition::new(&result[..], &counts[..], &displs[..]);
            root.scatter_varcount_into_root(&s, &mut mine[..]);
        } else {
            root.scatter_varcount_into(&mut mine[..]);
        }
        Ok(mine)
    }

    fn owner(&self, p: [f64; 3]) -> Result<i32, PartitionError> {
        let Some(g) = &self.grid else { return Ok(0) };
        let c = g.coords(p);
        let r = g.owner[g.index(c)];
        if r >= 0 {
            return Ok(r);
        }
        // An empty cell: the owner of the nearest occupied cell, in growing shells.
        let max_radius = g.dims.iter().copied().max().unwrap_or(1);
        for radius in 1..=max_radius {
            let lo = c.map(|x| x.saturating_sub(radius));
            let hi = [0, 1, 2].map(|k| (c[k] + radius).min(g.dims[k] - 1));
            let mut best: Option<(usize, i32)> = None;
            for z in lo[2]..=hi[2] {
                for y in lo[1]..=hi[1] {
                    for x in lo[0]..=hi[0] {
                        let r = g.owner[g.index([x, y, z])];
                        if r >= 0 {
                            let d2 = [x.abs_diff(c[0]), y.abs_diff(c[1]), z.abs_diff(c[2])]
                                .iter()
                                .map(|d| d * d)
                                .sum::<usize>();
                            if best.is_none_or(|b| (d2, r) < b) {
                                best = Some((d2, r));
                            }
                        }
                    }
                }
            }
            if let Some((_, r)) = best {
                return Ok(r);
            }
        }
        Ok(0)
    }

    fn ranks_overlapping(&self, b: &Aabb, out: &mut Vec<i32>) -> Result<(), PartitionError> {
        let Some(g) = &self.grid else {
            out.push(0);
            return Ok(());
        };
        let (lo, hi) = (g.coords(b.lo), g.coords(b.hi));
        let start = out.len();
        for z in lo[2]..=hi[2] {
            for y in lo[1]..=hi[1] {
                for x in lo[0]..=hi[0] {
                    let r = g.owner[g.index([x, y, z])];
                    if r >= 0 && !out[start..].contains(&r) {
                        out.push(r);
                    }
                }
            }
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn items(n: usize) -> Vec<Item> {
        (0..n)
            .map(|i| Item {
                id: i as u64,
                weight: 1.0 + (i % 3) as f64,
                ..Item::default()
            })
            .collect()
    }

    /// Parts numbered by a permutation of the old owners are numbered back:
    /// nothing moves.
    #[test]
    fn a_renumbered_partition_is_mapped_back_to_its_owners() {
        let items = items(60);
        let old: Vec<i32> = (0..60).map(|i| i / 15).collect();
        let perm = [2, 0, 3, 1];
        let new: Vec<i32> = old.iter().map(|&o| perm[o as usize]).collect();
        let map = overlap_map(&old, &new, &items, 4);
        for (o, n) in old.iter().zip(&new) {
            assert_eq!(map[*n as usize], *o);
        }
    }

    /// Each part goes to the rank it shares most weight with, every rank
    /// gets one part, and a part sharing nothing takes the rank left over.
    #[test]
    fn parts_go_where_most_of_their_weight_is() {
        let items = items(9);
        // Part 0 holds most of rank 1's items, part 1 most of rank 0's; part 2
        // only rank 0's leftovers, so it takes rank 2 (no items of its own).
        let old = [0, 0, 0, 0, 1, 1, 1, 1, 0];
        let new = [1, 1, 1, 2, 0, 0, 0, 0, 1];
        let map = overlap_map(&old, &new, &items, 3);
        assert_eq!(map, vec![1, 0, 2]);
    }
}
