//! What a particle weighs when the partitioner balances the ranks.
//!
//! - `triangles`: its triangle count (what it costs to hold).
//! - `pairs`: what its contacts cost: the body pairs and triangle pairs
//!   examined with it as the home particle over the last interval, per
//!   step, plus what every body costs per step, in nanoseconds of this
//!   machine ([`COST`]).
//! - `time`: the rank's measured busy seconds over the last interval,
//!   shared among its particles in proportion to their `pairs` weight: a
//!   rank that runs slower per pair (its cache, its core) sheds particles.
//!
//! The first partitioning, with no interval behind it, weighs triangles.
//!
//! A particle out of the run (waiting to be inserted, or taken out by an
//! outflow) costs nothing per step: it weighs [`OUT_SHARE`] of what it
//! would, so that it does not pull a cut, yet a partition of particles all
//! out (an insertion scene at its start) still has weights to split.

/// What a particle out of the run weighs, as a share of its weight in it.
pub const OUT_SHARE: f64 = 1e-3;

/// The cost model of `pairs`, in nanoseconds: per body and step (the kicks,
/// the drift, moving its triangles, the broad phase), per body pair examined
/// (culling its triangle pairs), per triangle pair (the kernel, the
/// contacts). Fitted with rates >= 0 to each rank's busy time, interval by
/// interval, of 2-rank runs of the hopper and the 1,000-particle silo, and
/// checked on scenes it was not fitted to (`scripts/weights-fit.sh`;
/// docs/distributed.md, "Weights").
pub struct Cost {
    pub body_step: f64,
    pub body_pair: f64,
    pub triangle_pair: f64,
}

pub const COST: Cost = Cost {
    body_step: 110.0,
    body_pair: 801.0,
    triangle_pair: 226.0,
};

/// How particles are weighed (see the module doc).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Weights {
    Triangles,
    Pairs,
    Time,
}

dem::named_enum!(
    Weights,
    "weights",
    [(Triangles, "triangles"), (Pairs, "pairs"), (Time, "time")]
);

/// The cost (ns per step) of a particle's contacts: `work` body pairs and
/// triangle pairs examined over `steps` steps, plus its own per-step cost.
pub fn pair_cost(work: [f64; 2], steps: u64) -> f64 {
    let per = |x: f64| x / steps.max(1) as f64;
    COST.body_step + COST.body_pair * per(work[0]) + COST.triangle_pair * per(work[1])
}

/// What the cost model says a rank's step costs (ns): `owned` bodies, and
/// the `body_pairs` and `triangle_pairs` it examined, each pair on the rank
/// of its home particle. The sum of its particles' `pairs` weights over one
/// step: what the partitioner balances.
pub fn rank_cost(owned: u64, body_pairs: u64, triangle_pairs: u64) -> f64 {
    COST.body_step * owned as f64
        + COST.body_pair * body_pairs as f64
        + COST.triangle_pair * triangle_pairs as f64
}

/// Each particle's weight under `weights`: `triangles` its triangle count,
/// `work` its contacts' counts over the last `steps` steps, `busy` the
/// rank's busy seconds over them (`steps` 0: no interval yet, triangles).
pub fn of(
    weights: Weights,
    triangles: &[f64],
    work: &[[f64; 2]],
    steps: u64,
    busy: f64,
) -> Vec<f64> {
    if steps == 0 || weights == Weights::Triangles {
        return triangles.to_vec();
    }
    let cost: Vec<f64> = work.iter().map(|&w| pair_cost(w, steps)).collect();
    if weights == Weights::Pairs {
        return cost;
    }
    let total: f64 = cost.iter().sum();
    // Seconds per step, as nanoseconds, shared as the costs are.
    let busy_ns = 1e9 * busy / steps as f64;
    cost.iter()
        .map(|c| {
            if total > 0.0 {
                busy_ns * c / total
            } else {
                0.0
            }
        })
        .collect()
}

/// [`of`]'s weights with those of the particles out of the run (`out`)
/// scaled by [`OUT_SHARE`].
pub fn held(mut weights: Vec<f64>, out: &[bool]) -> Vec<f64> {
    for (w, _) in weights.iter_mut().zip(out).filter(|(_, &o)| o) {
        *w *= OUT_SHARE;
    }
    weights
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn names_read_back_and_unknown_ones_are_refused_with_the_list() {
        for &(w, n) in Weights::ALL {
            assert_eq!(n.parse::<Weights>(), Ok(w));
            assert_eq!(w.name(), n);
        }
        let why = "pair".parse::<Weights>().unwrap_err();
        assert!(why.contains("triangles, pairs, time"), "{why}");
    }

    /// Pairs weigh what the cost model says; time shares the rank's busy
    /// time in the same proportions; with no interval, triangles.
    #[test]
    fn weights_follow_the_cost_of_each_particles_contacts() {
        let tri = [20.0, 20.0];
        // Over 10 steps: no contacts, and 5 body pairs / 200 triangle pairs.
        let work = [[0.0, 0.0], [50.0, 2000.0]];
        let p = of(Weights::Pairs, &tri, &work, 10, 0.0);
        assert_eq!(p[0], COST.body_step);
        assert_eq!(
            p[1],
            COST.body_step + 5.0 * COST.body_pair + 200.0 * COST.triangle_pair
        );
        let t = of(Weights::Time, &tri, &work, 10, 1e-3);
        assert!(
            (t[0] + t[1] - 1e5).abs() < 1e-6,
            "1 ms over 10 steps: 1e5 ns per step"
        );
        assert!((t[1] / t[0] - p[1] / p[0]).abs() < 1e-9);
        assert_eq!(of(Weights::Pairs, &tri, &work, 0, 0.0), tri.to_vec());
        assert_eq!(of(Weights::Triangles, &tri, &work, 10, 1.0), tri.to_vec());
    }

    /// Particles out of the run weigh a thousandth of the same particles in
    /// it, under every weighing; those in it keep their weight.
    #[test]
    fn particles_out_of_the_run_weigh_next_to_nothing() {
        let tri = [20.0, 20.0, 2000.0];
        let work = [[5.0, 90.0], [5.0, 90.0], [0.0, 0.0]];
        let out = [false, true, true];
        for &(w, _) in Weights::ALL {
            for steps in [0, 10] {
                let full = of(w, &tri, &work, steps, 1e-3);
                let h = held(full.clone(), &out);
                assert_eq!(h[0], full[0], "{w:?}");
                for k in 1..3 {
                    assert!(h[k] > 0.0 && h[k] == full[k] * OUT_SHARE, "{w:?} {k}");
                }
            }
        }
    }

    /// A rank's modelled cost is its particles' `pairs` weights summed.
    #[test]
    fn a_ranks_cost_is_the_sum_of_its_particles_weights() {
        let tri = [20.0; 3];
        let work = [[0.0, 0.0], [3.0, 40.0], [7.0, 130.0]];
        let sum: f64 = of(Weights::Pairs, &tri, &work, 1, 0.0).iter().sum();
        let rank = rank_cost(3, 10, 170);
        assert!((rank - sum).abs() <= 1e-12 * sum, "{rank} against {sum}");
    }
}
