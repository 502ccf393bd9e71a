//! Moving items to their new owners: counts first, then records and payloads.

use crate::comm::all_to_all_v;
use crate::{Item, LocalItems};
use mpi::traits::*;
use mpi::Count;

/// What one migration moved off this rank.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct MigrationStats {
    pub items_sent: u64,
    pub bytes_sent: u64,
}

/// Sends every item to `owners[i]` (collective). Items that stay are kept
/// in place of the exchange; afterwards each item lives on exactly one rank.
pub fn migrate<C: Communicator>(
    comm: &C,
    local: LocalItems,
    owners: &[i32],
) -> (LocalItems, MigrationStats) {
    let size = comm.size() as usize;
    let me = comm.rank();
    assert_eq!(owners.len(), local.items.len());
    // Bucket by destination, keeping the order within each bucket.
    let mut order: Vec<usize> = (0..owners.len()).collect();
    order.sort_by_key(|&i| owners[i]);
    let offsets: Vec<usize> = local
        .items
        .iter()
        .scan(0usize, |acc, it| {
            let o = *acc;
            *acc += it.payload_bytes as usize;
            Some(o)
        })
        .collect();
    let mut item_counts = vec![0 as Count; size];
    let mut byte_counts = vec![0 as Count; size];
    let mut send_items = Vec::with_capacity(order.len());
    let mut send_bytes = Vec::with_capacity(local.payload.len());
    let mut stats = MigrationStats::default();
    for &i in &order {
        let dest = owners[i];
        assert!(
            dest >= 0 && (dest as usize) < size,
            "owner {dest} out of range"
        );
        let it = local.items[i];
        item_counts[dest as usize] += 1;
        byte_counts[dest as usize] += it.payload_bytes as Count;
        send_items.push(it);
        send_bytes
            .extend_from_slice(&local.payload[offsets[i]..offsets[i] + it.payload_bytes as usize]);
        if dest != me {
            stats.items_sent += 1;
            stats.bytes_sent += it.wire_bytes();
        }
    }
    let (items, _) = all_to_all_v::<C, Item>(comm, &send_items, &item_counts);
    let (payload, _) = all_to_all_v::<C, u8>(comm, &send_bytes, &byte_counts);
    (LocalItems::new(items, payload), stats)
}
