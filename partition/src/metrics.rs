//! What one partitioning step measured, reduced over all ranks.

use crate::ghosts::Ghosts;
use crate::migrate::MigrationStats;
use crate::LocalItems;
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use serde::Serialize;

#[derive(Debug, Clone, Serialize)]
pub struct StepMetrics {
    pub step: usize,
    pub partitioner: String,
    pub ranks: i32,
    pub items: u64,
    /// Max over mean of the ranks' total weights.
    pub imbalance: f64,
    /// Wall time of the partitioning call (slowest rank).
    pub partition_s: f64,
    /// Wall time of the migration (slowest rank).
    pub migrate_s: f64,
    pub migrated_items: u64,
    pub migrated_bytes: u64,
    pub ghost_items: u64,
    pub ghost_bytes: u64,
    pub neighbours_max: u64,
    pub neighbours_mean: f64,
}

/// Reduces the per-rank numbers of one step (collective).
#[allow(clippy::too_many_arguments)]
pub fn collect(
    comm: &SimpleCommunicator,
    step: usize,
    partitioner: &str,
    local: &LocalItems,
    partition_s: f64,
    migrate_s: f64,
    migration: &MigrationStats,
    ghosts: &Ghosts,
) -> StepMetrics {
    let weight: f64 = local.items.iter().map(|i| i.weight).sum();
    let sum_f = |x: f64| {
        let mut y = 0.0;
        comm.all_reduce_into(&x, &mut y, SystemOperation::sum());
        y
    };
    let max_f = |x: f64| {
        let mut y = 0.0;
        comm.all_reduce_into(&x, &mut y, SystemOperation::max());
        y
    };
    let sum_u = |x: u64| {
        let mut y = 0u64;
        comm.all_reduce_into(&x, &mut y, SystemOperation::sum());
        y
    };
    let ranks = comm.size();
    let total_w = sum_f(weight);
    let max_w = max_f(weight);
    let neighbours = ghosts.neighbours.len() as u64;
    let mut neighbours_max = 0u64;
    comm.all_reduce_into(&neighbours, &mut neighbours_max, SystemOperation::max());
    StepMetrics {
        step,
        partitioner: partitioner.to_string(),
        ranks,
        items: sum_u(local.items.len() as u64),
        imbalance: if total_w > 0.0 {
            max_w / (total_w / ranks as f64)
        } else {
            1.0
        },
        partition_s: max_f(partition_s),
        migrate_s: max_f(migrate_s),
        migrated_items: sum_u(migration.items_sent),
        migrated_bytes: sum_u(migration.bytes_sent),
        ghost_items: sum_u(ghosts.items_sent),
        ghost_bytes: sum_u(ghosts.bytes_sent),
        neighbours_max,
        neighbours_mean: sum_u(neighbours) as f64 / ranks as f64,
    }
}
