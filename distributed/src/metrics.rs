//! What one rank measured in one step: the research data of a distributed
//! run (`tridem run --metrics FILE.jsonl`).

use mpi::traits::Equivalence;

/// One rank's counts and seconds for one step.
#[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
pub struct StepMetrics {
    pub step: u64,
    pub owned_bodies: u64,
    pub owned_triangles: u64,
    /// Bodies and bytes that left this rank at a repartitioning.
    pub migrated_bodies: u64,
    pub migrated_bytes: u64,
    /// Ghost bodies sent (one per receiving rank) and received, and their bytes.
    pub ghosts_sent: u64,
    pub ghosts_received: u64,
    pub ghost_bytes_sent: u64,
    pub ghost_bytes_received: u64,
    /// Whether the ghost lists were drawn anew this step.
    pub lists_drawn: u64,
    /// Contacts this rank books (each contact of the run on one rank).
    pub contacts: u64,
    pub partition_seconds: f64,
    pub migration_seconds: f64,
    /// Waiting for the ghosts after (nonblocking) or before (blocking) the
    /// detection among owned bodies.
    pub wait_seconds: f64,
    pub local_local_seconds: f64,
    pub local_ghost_seconds: f64,
    /// Building the contacts and the effects' forces.
    pub force_seconds: f64,
    pub integration_seconds: f64,
    /// The step less its waits for other ranks (ghosts, books, travel).
    pub busy_seconds: f64,
    pub step_seconds: f64,
}

impl StepMetrics {
    /// Names and values, in a fixed order, for tables and JSON.
    pub fn fields(&self) -> [(&'static str, f64); 20] {
        [
            ("owned_bodies", self.owned_bodies as f64),
            ("owned_triangles", self.owned_triangles as f64),
            ("migrated_bodies", self.migrated_bodies as f64),
            ("migrated_bytes", self.migrated_bytes as f64),
            ("ghosts_sent", self.ghosts_sent as f64),
            ("ghosts_received", self.ghosts_received as f64),
            ("ghost_bytes_sent", self.ghost_bytes_sent as f64),
            ("ghost_bytes_received", self.ghost_bytes_received as f64),
            ("lists_drawn", self.lists_drawn as f64),
            ("contacts", self.contacts as f64),
            ("partition_seconds", self.partition_seconds),
            ("migration_seconds", self.migration_seconds),
            ("wait_seconds", self.wait_seconds),
            ("local_local_seconds", self.local_local_seconds),
            ("local_ghost_seconds", self.local_ghost_seconds),
            ("force_seconds", self.force_seconds),
            ("integration_seconds", self.integration_seconds),
            ("busy_seconds", self.busy_seconds),
            ("step_seconds", self.step_seconds),
            ("step", self.step as f64),
        ]
    }

    /// Takes in the next step of an interval: its counts and seconds add
    /// up, the owned bodies and triangles are the step's, as is the step number.
    pub fn extend_interval(&mut self, o: &StepMetrics) {
        self.accumulate(o);
        self.owned_bodies = o.owned_bodies;
        self.owned_triangles = o.owned_triangles;
        self.step = o.step;
    }

    /// Adds another step's counts and seconds (the step number is kept).
    pub fn accumulate(&mut self, o: &StepMetrics) {
        self.owned_bodies += o.owned_bodies;
        self.owned_triangles += o.owned_triangles;
        self.migrated_bodies += o.migrated_bodies;
        self.migrated_bytes += o.migrated_bytes;
        self.ghosts_sent += o.ghosts_sent;
        self.ghosts_received += o.ghosts_received;
        self.ghost_bytes_sent += o.ghost_bytes_sent;
        self.ghost_bytes_received += o.ghost_bytes_received;
        self.lists_drawn += o.lists_drawn;
        self.contacts += o.contacts;
        self.partition_seconds += o.partition_seconds;
        self.migration_seconds += o.migration_seconds;
        self.wait_seconds += o.wait_seconds;
        self.local_local_seconds += o.local_local_seconds;
        self.local_ghost_seconds += o.local_ghost_seconds;
        self.force_seconds += o.force_seconds;
        self.integration_seconds += o.integration_seconds;
        self.busy_seconds += o.busy_seconds;
        self.step_seconds += o.step_seconds;
    }
}

/// max / mean of `values` (1 for an even split; 1 when all are zero).
pub fn imbalance(values: impl Iterator<Item = f64> + Clone) -> f64 {
    let n = values.clone().count() as f64;
    let max = values.clone().fold(0.0, f64::max);
    let mean = values.sum::<f64>() / n;
    if mean > 0.0 {
        max / mean
    } else {
        1.0
    }
}

/// One JSON line of an interval's metrics on all ranks (see
/// [`StepMetrics::extend_interval`]): per rank, summed, and the imbalances
/// of owned triangles and busy seconds.
pub fn json_line(ranks: &[StepMetrics]) -> serde_json::Value {
    let mut per_rank = serde_json::Map::new();
    let mut sum = serde_json::Map::new();
    for (name, _) in StepMetrics::default().fields() {
        if name == "step" {
            continue;
        }
        let column: Vec<f64> = ranks
            .iter()
            .map(|m| m.fields().iter().find(|f| f.0 == name).map_or(0.0, |f| f.1))
            .collect();
        sum.insert(name.into(), column.iter().sum::<f64>().into());
        per_rank.insert(name.into(), column.into());
    }
    serde_json::json!({
        "step": ranks.first().map_or(0, |m| m.step),
        "ranks": ranks.len(),
        "triangle_imbalance": imbalance(ranks.iter().map(|m| m.owned_triangles as f64)),
        "busy_imbalance": imbalance(ranks.iter().map(|m| m.busy_seconds)),
        "sum": sum,
        "per_rank": per_rank,
    })
}
