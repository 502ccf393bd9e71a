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

/// Which local items this rank sends as ghosts, as indices per destination
/// rank, with the counts of [`Ghosts`] filled in; and the query error, if
/// any, to return once every rank has passed the exchange (with nothing sent
/// from this rank).
fn outgoing(
    comm: &SimpleCommunicator,
    part: &dyn Partitioner,
    local: &LocalItems,
    halo: f64,
) -> (Vec<Vec<usize>>, Ghosts, Option<PartitionError>) {
    let size = comm.size() as usize;
    let me = comm.rank();
    let reach = global_reach(comm, &local.items);
    let mut per_rank: Vec<Vec<usize>> = vec![Vec::new(); size];
    let mut g = Ghosts::default();
    // One query buffer for all items, filled straight into the per-rank
    // lists: most items go nowhere, and a list per item cost an allocation each.
    let mut ranks = Vec::new();
    for (i, it) in local.items.iter().enumerate() {
        ranks.clear();
        let reached = it.bbox.inflated(2.0 * halo + reach);
        if let Err(e) = part.ranks_overlapping(&reached, &mut ranks) {
            return (vec![Vec::new(); size], Ghosts::default(), Some(e));
        }
        ranks.sort_unstable();
        ranks.dedup();
        for &r in ranks.iter().filter(|&&r| r != me) {
            per_rank[r as usize].push(i);
            g.items_sent += 1;
            g.bytes_sent += it.wire_bytes();
        }
    }
    g.neighbours = (0..size as i32)
        .filter(|&r| !per_rank[r as usize].is_empty())
        .collect();
    (per_rank, g, None)
}

/// Sends ghosts (records only; payloads are not needed for contact search).
pub fn exchange_ghosts(
    comm: &SimpleCommunicator,
    part: &dyn Partitioner,
    local: &LocalItems,
    halo: f64,
) -> Result<Ghosts, PartitionError> {
    let (per_rank, mut g, error) = outgoing(comm, part, local, halo);
    let counts: Vec<Count> = per_rank.iter().map(|v| v.len() as Count).collect();
    let send: Vec<Item> = per_rank.iter().flatten().map(|&i| local.items[i]).collect();
    let (received, _) = all_to_all_v(comm, &send, &counts);
    g.received = received;
    match error {
        Some(e) => Err(e),
        None => Ok(g),
    }
}

/// Tag of the ghost messages of [`exchange_ghosts_during`].
const GHOST_TAG: i32 = 0x6705;

/// Sends ghosts as [`exchange_ghosts`] does, but with non-blocking
/// point-to-point messages to and from the neighbour ranks only, and runs
/// `work` (the contacts among owned items, which need no ghosts) while they
/// are in flight. Returns the ghosts, in the same order as
/// [`exchange_ghosts`], and what `work` returned.
///
/// The counts go first, in a blocking all-to-all of one integer per rank:
/// receive buffers must be sized before receives are posted. The requests
/// live in an rsmpi scope, which ends only once each has completed, so no
/// buffer can be freed or read while MPI still writes it. Without an MPI
/// progress thread, a message larger than the eager limit may advance only
/// in the final wait; the overlap gained is what `tridem partition`
/// measures, not what this function promises.
pub fn exchange_ghosts_during<R>(
    comm: &SimpleCommunicator,
    part: &dyn Partitioner,
    local: &LocalItems,
    halo: f64,
    work: impl FnOnce() -> R,
) -> Result<(Ghosts, R), PartitionError> {
    let (mut g, received, out) =
        exchange_ghost_records_during(comm, part, local, halo, |i| local.items[i], work)?;
    g.received = received;
    Ok((g, out))
}

/// As [`exchange_ghosts_during`], but what travels for a ghost is
/// `record(i)` of local item i, whatever the caller needs of it on the other
/// rank (a triangle's vertices, say), rather than the item. Returns the
/// records received, in rank order (`Ghosts::received` stays empty).
pub fn exchange_ghost_records_during<T, R>(
    comm: &SimpleCommunicator,
    part: &dyn Partitioner,
    local: &LocalItems,
    halo: f64,
    record: impl Fn(usize) -> T,
    work: impl FnOnce() -> R,
) -> Result<(Ghosts, Vec<T>, R), PartitionError>
where
    T: Equivalence + Clone + Default,
{
    let (per_rank, g, error) = outgoing(comm, part, local, halo);
    let outbox: Vec<Vec<T>> = per_rank
        .iter()
        .map(|ids| ids.iter().map(|&i| record(i)).collect())
        .collect();
    let counts: Vec<Count> = outbox.iter().map(|v| v.len() as Count).collect();
    let mut recv_counts = vec![0 as Count; counts.len()];
    comm.all_to_all_into(&counts[..], &mut recv_counts[..]);
    let mut inbox: Vec<Vec<T>> = recv_counts
        .iter()
        .map(|&c| vec![T::default(); c as usize])
        .collect();
    let out = mpi::request::scope(|scope| {
        let receives: Vec<_> = inbox
            .iter_mut()
            .enumerate()
            .filter(|(_, b)| !b.is_empty())
            .map(|(r, b)| {
                comm.process_at_rank(r as i32)
                    .immediate_receive_into_with_tag(scope, &mut b[..], GHOST_TAG)
            })
            .collect();
        let sends: Vec<_> = outbox
            .iter()
            .enumerate()
            .filter(|(_, b)| !b.is_empty())
            .map(|(r, b)| {
                comm.process_at_rank(r as i32)
                    .immediate_send_with_tag(scope, &b[..], GHOST_TAG)
            })
            .collect();
        let out = work();
        receives.into_iter().for_each(|r| {
            r.wait();
        });
        sends.into_iter().for_each(|r| {
            r.wait();
        });
        out
    });
    match error {
        Some(e) => Err(e),
        None => Ok((g, inbox.into_iter().flatten().collect(), out)),
    }
}
