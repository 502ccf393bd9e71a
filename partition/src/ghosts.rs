//! Ghost items: copies of items near a rank's region, sent to that rank so it
//! can find every contact that crosses a cut.
//!
//! Two items interact when their boxes, each inflated by the halo h, overlap.
//! A rank's region holds its items' *points*, and an item's box reaches at
//! most `reach` from its point, so item i must go to every rank whose region
//! overlaps i's box inflated by 2h + reach (reach: the largest point-to-box
//! distance of any item, agreed on by all ranks).

use crate::comm::all_to_all_v;
use crate::{Item, LocalItems, PartitionError, Partitioner};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use mpi::Count;

/// Ghosts received by this rank, and what sending them cost.
#[derive(Debug, Clone, Default)]
pub struct Ghosts {
    pub received: Vec<Item>,
    /// Items sent, counted once per receiving rank.
    pub items_sent: u64,
    pub bytes_sent: u64,
    /// Ranks this rank sent ghosts to.
    pub neighbours: Vec<i32>,
}

/// The largest distance from an item's point to the far corner of its box, over all ranks.
pub fn global_reach(comm: &SimpleCommunicator, items: &[Item]) -> f64 {
    let local = items
        .iter()
        .map(|i| {
            (0..3)
                .map(|k| {
                    (i.point[k] - i.bbox.lo[k])
                        .abs()
                        .max((i.bbox.hi[k] - i.point[k]).abs())
                })
                .fold(0.0, f64::max)
        })
        .fold(0.0, f64::max);
    let mut global = 0.0;
    comm.all_reduce_into(&local, &mut global, SystemOperation::max());
    global
}

/// For each local item, the other ranks that need it as a ghost.
pub fn ghost_destinations(
    part: &dyn Partitioner,
    me: i32,
    items: &[Item],
    halo: f64,
    reach: f64,
) -> Result<Vec<Vec<i32>>, PartitionError> {
    let mut buf = Vec::new();
    items
        .iter()
        .map(|it| {
            buf.clear();
            part.ranks_overlapping(&it.bbox.inflated(2.0 * halo + reach), &mut buf)?;
            buf.sort_unstable();
            buf.dedup();
            Ok(buf.iter().copied().filter(|&r| r != me).collect())
        })
        .collect()
}

/// Sends ghosts (records only; payloads are not needed for contact search).
pub fn exchange_ghosts(
    comm: &SimpleCommunicator,
    part: &dyn Partitioner,
    local: &LocalItems,
    halo: f64,
) -> Result<Ghosts, PartitionError> {
    let size = comm.size() as usize;
    let me = comm.rank();
    let reach = global_reach(comm, &local.items);
    // Every rank must reach the exchange below, so a query error is only
    // returned after it (with nothing sent from this rank).
    let dests = ghost_destinations(part, me, &local.items, halo, reach);
    let (dests, error) = match dests {
        Ok(d) => (d, None),
        Err(e) => (vec![Vec::new(); local.items.len()], Some(e)),
    };
    let mut per_rank: Vec<Vec<Item>> = vec![Vec::new(); size];
    let mut g = Ghosts::default();
    for (it, ds) in local.items.iter().zip(&dests) {
        for &r in ds {
            per_rank[r as usize].push(*it);
            g.items_sent += 1;
            g.bytes_sent += it.wire_bytes();
        }
    }
    g.neighbours = (0..size as i32)
        .filter(|&r| !per_rank[r as usize].is_empty())
        .collect();
    let counts: Vec<Count> = per_rank.iter().map(|v| v.len() as Count).collect();
    let send: Vec<Item> = per_rank.into_iter().flatten().collect();
    let (received, _) = all_to_all_v(comm, &send, &counts);
    g.received = received;
    match error {
        Some(e) => Err(e),
        None => Ok(g),
    }
}
