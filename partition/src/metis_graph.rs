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
//! receives the cell map for point and box queries.

use crate::comm::displacements;
use crate::{Aabb, Item, PartitionError, Partitioner};
use mpi::datatype::{Partition, PartitionMut};
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;
use std::collections::HashMap;

type Cell = [i64; 3];

#[derive(Debug, Clone, Default)]
pub struct MetisPartitioner {
    /// Items whose boxes inflated by `halo` overlap are joined in the graph.
    pub halo: f64,
    grid: Option<Grid>,
}

#[derive(Debug, Clone)]
struct Grid {
    origin: [f64; 3],
    size: f64,
    owner: HashMap<Cell, i32>,
}

impl Grid {
    fn cell(&self, p: [f64; 3]) -> Cell {
        [0, 1, 2].map(|k| ((p[k] - self.origin[k]) / self.size).floor() as i64)
    }
}

impl MetisPartitioner {
    pub fn with_halo(halo: f64) -> Self {
        MetisPartitioner { halo, grid: None }
    }
}

/// Builds the graph, partitions it and makes the result cell-consistent.
/// Returns (owner per item, grid with the cell map).
fn partition_on_root(
    items: &[Item],
    nparts: i32,
    halo: f64,
) -> Result<(Vec<i32>, Grid), PartitionError> {
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
    // Items whose inflated boxes overlap have points within 2 (reach + halo) per axis.
    let extent = domain.extent().into_iter().fold(0.0, f64::max);
    let size = (2.0 * (reach + halo))
        .max(extent * 1e-6)
        .max(f64::MIN_POSITIVE);
    let origin = if domain.is_empty() {
        [0.0; 3]
    } else {
        domain.lo
    };
    let mut grid = Grid {
        origin,
        size,
        owner: HashMap::new(),
    };
    let mut cells: HashMap<Cell, Vec<u32>> = HashMap::new();
    for (i, it) in items.iter().enumerate() {
        cells.entry(grid.cell(it.point)).or_default().push(i as u32);
    }
    let n = items.len();
    let mut owners = vec![0i32; n];
    if nparts > 1 && n > 0 {
        let mut xadj: Vec<metis::Idx> = Vec::with_capacity(n + 1);
        let mut adjncy: Vec<metis::Idx> = Vec::new();
        xadj.push(0);
        for it in items {
            let c = grid.cell(it.point);
            let b = it.bbox.inflated(halo);
            let me = it as *const Item;
            for dx in -1..=1 {
                for dy in -1..=1 {
                    for dz in -1..=1 {
                        if let Some(v) = cells.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                            for &j in v {
                                let o = &items[j as usize];
                                if !std::ptr::eq(o, me) && b.overlaps(&o.bbox.inflated(halo)) {
                                    adjncy.push(j as metis::Idx);
                                }
                            }
                        }
                    }
                }
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
        owners = part;
    }
    // Each cell goes wholly to the rank holding most of its weight.
    for (c, members) in &cells {
        let mut w: HashMap<i32, f64> = HashMap::new();
        for &i in members {
            *w.entry(owners[i as usize]).or_default() +=
                items[i as usize].weight.max(f64::MIN_POSITIVE);
        }
        let best = w
            .into_iter()
            .max_by(|a, b| a.1.total_cmp(&b.1).then(b.0.cmp(&a.0)))
            .map_or(0, |(r, _)| r);
        grid.owner.insert(*c, best);
        for &i in members {
            owners[i as usize] = best;
        }
    }
    Ok((owners, grid))
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
        let mut all = vec![Item::default(); counts.iter().sum::<Count>() as usize];
        let (mut result, mut status) = (Vec::new(), 0i32);
        let mut message = String::new();
        let mut cellmap: Vec<i64> = Vec::new();
        let mut header = [0.0f64; 4];
        if comm.rank() == 0 {
            {
                let mut r = PartitionMut::new(&mut all[..], &counts[..], &displs[..]);
                root.gather_varcount_into_root(items, &mut r);
            }
            match partition_on_root(&all, size, self.halo) {
                Ok((owners, grid)) => {
                    result = owners;
                    header = [grid.origin[0], grid.origin[1], grid.origin[2], grid.size];
                    for (c, r) in &grid.owner {
                        cellmap.extend_from_slice(&[c[0], c[1], c[2], *r as i64]);
                    }
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
        let mut ncells = cellmap.len() as u64;
        root.broadcast_into(&mut ncells);
        cellmap.resize(ncells as usize, 0);
        root.broadcast_into(&mut cellmap[..]);
        let mut owner = HashMap::with_capacity(cellmap.len() / 4);
        for c in cellmap.chunks_exact(4) {
            owner.insert([c[0], c[1], c[2]], c[3] as i32);
        }
        self.grid = Some(Grid {
            origin: [header[0], header[1], header[2]],
            size: header[3],
            owner,
        });
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
        let c = g.cell(p);
        if let Some(&r) = g.owner.get(&c) {
            return Ok(r);
        }
        // An empty cell: the owner of the nearest occupied cell in growing shells.
        for radius in 1..=4i64 {
            let mut best: Option<(i64, i32)> = None;
            for dx in -radius..=radius {
                for dy in -radius..=radius {
                    for dz in -radius..=radius {
                        if dx.abs().max(dy.abs()).max(dz.abs()) != radius {
                            continue;
                        }
                        if let Some(&r) = g.owner.get(&[c[0] + dx, c[1] + dy, c[2] + dz]) {
                            let d2 = dx * dx + dy * dy + dz * dz;
                            if best.is_none_or(|(bd, br)| (d2, r) < (bd, br)) {
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
        let (lo, hi) = (g.cell(b.lo), g.cell(b.hi));
        let span: i64 = (0..3).map(|k| hi[k] - lo[k] + 1).product();
        let start = out.len();
        if span as usize > g.owner.len() {
            // A box larger than the occupied grid: scan the map instead.
            for (c, &r) in &g.owner {
                if (0..3).all(|k| lo[k] <= c[k] && c[k] <= hi[k]) {
                    out.push(r);
                }
            }
        } else {
            for x in lo[0]..=hi[0] {
                for y in lo[1]..=hi[1] {
                    for z in lo[2]..=hi[2] {
                        if let Some(&r) = g.owner.get(&[x, y, z]) {
                            out.push(r);
                        }
                    }
                }
            }
        }
        let mut mine: Vec<i32> = out.split_off(start);
        mine.sort_unstable();
        mine.dedup();
        out.extend(mine);
        Ok(())
    }
}
