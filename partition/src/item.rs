//! What gets partitioned: items with a point, a weight, a box and a payload.

use crate::Aabb;
use mpi::traits::Equivalence;

/// One unit of work to place on a rank (in tridem: a triangle).
#[derive(Debug, Clone, Copy, PartialEq, Default, Equivalence)]
pub struct Item {
    /// Globally unique id.
    pub id: u64,
    /// Where the item is for partitioning (e.g. the triangle's centroid).
    pub point: [f64; 3],
    /// Work it costs (contact checks, say).
    pub weight: f64,
    /// Its bounding box, for ghost search.
    pub bbox: Aabb,
    /// Bytes of data that travel with it when it migrates (besides this record).
    pub payload_bytes: u32,
}

impl Item {
    /// Bytes moved when this item migrates or is sent as a ghost.
    pub fn wire_bytes(&self) -> u64 {
        std::mem::size_of::<Item>() as u64 + self.payload_bytes as u64
    }
}

/// The items a rank owns, with their payloads stored back to back.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LocalItems {
    pub items: Vec<Item>,
    /// Concatenated payloads, `items[i].payload_bytes` each, in item order.
    pub payload: Vec<u8>,
}

impl LocalItems {
    pub fn new(items: Vec<Item>, payload: Vec<u8>) -> Self {
        let expected: usize = items.iter().map(|i| i.payload_bytes as usize).sum();
        assert_eq!(
            expected,
            payload.len(),
            "payload length does not match the items"
        );
        LocalItems { items, payload }
    }

    /// Items with payloads filled from their ids (checkable after migration).
    pub fn with_id_payloads(items: Vec<Item>) -> Self {
        let payload = items
            .iter()
            .flat_map(|i| id_payload(i.id, i.payload_bytes))
            .collect();
        LocalItems { items, payload }
    }

    pub fn len(&self) -> usize {
        self.items.len()
    }

    pub fn is_empty(&self) -> bool {
        self.items.is_empty()
    }

    /// Whether every payload still holds the bytes derived from its id.
    pub fn payloads_match_ids(&self) -> bool {
        let mut at = 0;
        self.items.iter().all(|i| {
            let n = i.payload_bytes as usize;
            let ok = self.payload[at..at + n] == id_payload(i.id, i.payload_bytes)[..];
            at += n;
            ok
        })
    }
}

fn id_payload(id: u64, n: u32) -> Vec<u8> {
    let bytes = id.to_le_bytes();
    (0..n as usize).map(|k| bytes[k % 8] ^ (k as u8)).collect()
}
