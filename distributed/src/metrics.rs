//! What one rank measured in one step: the research data of a distributed
//! run (`tridem run --metrics FILE.jsonl`).

use mpi::traits::Equivalence;

/// Declares [`StepMetrics`] from one list of its counts and seconds: the
/// struct, its names in a fixed order, and the sums of steps.
macro_rules! step_metrics {
    (counts { $($(#[$cd:meta])* $c:ident),* $(,)? }
     seconds { $($(#[$sd:meta])* $s:ident),* $(,)? }) => {
        /// One rank's counts and seconds for one step.
        ///
        /// The sections (the seconds but `return_wait`, which is part of
        /// `force_return`, and `busy` and `step`) follow each other through
        /// the step: they add up to `step_seconds` ([`StepMetrics::sections`]).
        #[derive(Debug, Clone, Copy, Default, PartialEq, Equivalence)]
        pub struct StepMetrics {
            pub step: u64,
            $($(#[$cd])* pub $c: u64,)*
            $($(#[$sd])* pub $s: f64,)*
        }

        impl StepMetrics {
            /// Names and values, in a fixed order, for tables and JSON (the
            /// step number not among them).
            pub fn fields(&self) -> Vec<(&'static str, f64)> {
                vec![
                    $((stringify!($c), self.$c as f64),)*
                    $((stringify!($s), self.$s),)*
                ]
            }

            /// Adds another step's counts and seconds (the step number is kept).
            pub fn accumulate(&mut self, o: &StepMetrics) {
                $(self.$c += o.$c;)*
                $(self.$s += o.$s;)*
            }
        }
    };
}

step_metrics! {
    counts {
        owned_bodies,
        owned_triangles,
        /// Bodies (owned, ghosts and obstacles) and their triangles in this
        /// rank's world.
        local_bodies,
        local_triangles,
        /// Bodies and bytes that left this rank at a repartitioning.
        migrated_bodies,
        migrated_bytes,
        /// At a repartitioning, the owned bodies that had left this rank's
        /// region of the previous partition: what a partition keeping every
        /// cut where it was would have moved.
        drifted_bodies,
        /// Ghosts sent (one per body and receiving rank) and received, and
        /// their bytes.
        ghosts_sent,
        ghosts_received,
        ghost_bytes_sent,
        ghost_bytes_received,
        /// Ranks this rank exchanges ghosts with.
        neighbours,
        /// Force terms sent back to the owners of ghosts, and their bytes.
        terms_sent,
        term_bytes_sent,
        /// Whether the ghost lists were drawn anew.
        lists_drawn,
        /// Whether the neighbour list was drawn anew: with the ghost lists,
        /// or alone from the ghosts' current motions.
        neighbour_lists_drawn,
        /// Contacts this rank computed (each contact of the run on one rank).
        contacts,
        /// Owned bodies in the run (not waiting, not taken out): what the
        /// per-body cost is paid for; over an interval, body-steps.
        present_bodies,
        /// Body pairs and triangle pairs the detection examined.
        body_pairs,
        triangle_pairs,
        /// What the `pairs` weight's cost model says the step costs here
        /// (ns, `weights::rank_cost`): the work the partitioner balances.
        modelled_work_ns,
        /// The modelled work of the step before, of this rank and of the
        /// rank with the most (carried by the step's all-reduce): their sums
        /// give the imbalance of the work itself step by step
        /// ([`per_step_work_imbalance`]), which no core's speed moves.
        counted_work_ns,
        most_work_ns,
    }
    seconds {
        partition_seconds,
        migration_seconds,
        /// The kicks and the drift of the owned bodies.
        integration_seconds,
        /// The one all-reduce of a step (travel, stop and failure flags),
        /// waiting for the slowest rank included.
        reduce_seconds,
        /// Drawing the ghost lists and rebuilding this rank's world.
        lists_seconds,
        /// Packing and posting the ghosts' motions.
        post_seconds,
        /// Detection among owned bodies and obstacles, while the motions travel.
        local_detection_seconds,
        /// Inside the call that completes the ghost exchange: the same
        /// measure with either exchange.
        wait_seconds,
        /// Taking in the ghosts' motions, and the detection between owned
        /// bodies and ghosts.
        ghost_detection_seconds,
        /// The effects' forces.
        force_seconds,
        /// Sending the terms on ghosts to their owners, receiving and summing
        /// the terms on this rank's bodies near a cut.
        force_return_seconds,
        /// Of which waiting for the terms to arrive.
        return_wait_seconds,
        /// The step less its waits for other ranks (reduce, wait, return wait).
        busy_seconds,
        step_seconds,
        /// The busy seconds of the step before, of this rank and of the
        /// slowest rank (carried by the step's all-reduce): their sums give
        /// the imbalance step by step ([`per_step_imbalance`]), which the
        /// ranks' totals hide when the slower rank changes during a run.
        counted_busy_seconds,
        slowest_busy_seconds,
    }
}

impl StepMetrics {
    /// The sections of the step, summed: `step_seconds`, up to the few
    /// instructions between them.
    pub fn sections(&self) -> f64 {
        self.partition_seconds
            + self.migration_seconds
            + self.integration_seconds
            + self.reduce_seconds
            + self.lists_seconds
            + self.post_seconds
            + self.local_detection_seconds
            + self.wait_seconds
            + self.ghost_detection_seconds
            + self.force_seconds
            + self.force_return_seconds
    }

    /// Takes in the next step of an interval: its counts and seconds add
    /// up; the sizes (owned and local bodies and triangles, neighbours) are the step's,
    /// as is the step number.
    pub fn extend_interval(&mut self, o: &StepMetrics) {
        self.accumulate(o);
        self.owned_bodies = o.owned_bodies;
        self.owned_triangles = o.owned_triangles;
        self.local_bodies = o.local_bodies;
        self.local_triangles = o.local_triangles;
        self.neighbours = o.neighbours;
        self.step = o.step;
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

/// The busy imbalance step by step: the slowest rank's busy time summed
/// over the steps, over the mean rank's (1 with no steps). Each step the
/// others wait for the slowest, so this, not the imbalance of the ranks'
/// totals, is what the imbalance costs: a run whose two halves each have a
/// different slow rank has totals in balance and a per-step imbalance
/// above 1.
pub fn per_step_imbalance(ranks: &[StepMetrics]) -> f64 {
    carried_imbalance(ranks, |m| (m.slowest_busy_seconds, m.counted_busy_seconds))
}

/// The modelled work's imbalance step by step: the largest rank's
/// `modelled_work_ns` summed over the steps, over the mean rank's (1 with
/// no work). What [`per_step_imbalance`] would be on cores of equal and
/// steady speed: the part of the waits that the work's split causes,
/// whatever the machine does.
pub fn per_step_work_imbalance(ranks: &[StepMetrics]) -> f64 {
    carried_imbalance(ranks, |m| (m.most_work_ns as f64, m.counted_work_ns as f64))
}

/// The largest rank's value summed step by step over the mean rank's, from
/// what the step's all-reduce carried: `carried` gives (the largest rank's
/// sum, the same on every rank; this rank's sum). 1 when all are zero.
fn carried_imbalance(ranks: &[StepMetrics], carried: impl Fn(&StepMetrics) -> (f64, f64)) -> f64 {
    let n = ranks.len().max(1) as f64;
    let mean = ranks.iter().map(|m| carried(m).1).sum::<f64>() / n;
    let largest = ranks.first().map_or(0.0, |m| carried(m).0);
    if mean > 0.0 {
        largest / mean
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
    let rows: Vec<_> = ranks.iter().map(StepMetrics::fields).collect();
    for (k, (name, _)) in StepMetrics::default().fields().into_iter().enumerate() {
        let column: Vec<f64> = rows.iter().map(|row| row[k].1).collect();
        sum.insert(name.into(), column.iter().sum::<f64>().into());
        per_rank.insert(name.into(), column.into());
    }
    serde_json::json!({
        "step": ranks.first().map_or(0, |m| m.step),
        "ranks": ranks.len(),
        "triangle_imbalance": imbalance(ranks.iter().map(|m| m.owned_triangles as f64)),
        "busy_imbalance": imbalance(ranks.iter().map(|m| m.busy_seconds)),
        "busy_imbalance_per_step": per_step_imbalance(ranks),
        "work_imbalance_per_step": per_step_work_imbalance(ranks),
        "sum": sum,
        "per_rank": per_rank,
    })
}
