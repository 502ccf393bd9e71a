//! Multi-rank tests of every backend through the mpirun harness.
use mpi_harness::{example_binary, MpiRun, RunOutput};

/// Every backend, by the names the command line reads.
fn backends() -> impl Iterator<Item = &'static str> {
    partition::Backend::ALL.into_iter().map(|b| b.name())
}

fn run(
    backend: &str,
    workload: &str,
    items: u64,
    halo: f64,
    ranks: usize,
    shift: f64,
) -> RunOutput {
    MpiRun::new(example_binary("partition_check"))
        .ranks(ranks)
        .args([
            backend.to_string(),
            workload.into(),
            items.to_string(),
            halo.to_string(),
            shift.to_string(),
        ])
        .run()
        .unwrap_or_else(|e| panic!("{backend} on {ranks} ranks: {e}"))
}

fn sum<T: std::str::FromStr + std::iter::Sum>(run: &RunOutput, key: &str) -> T {
    run.reports.iter().map(|r| r.parse::<T>(key)).sum()
}

/// Every item on exactly one rank (count and checksums of ids), payloads
/// intact, queries consistent with the partition, ghosts complete; imbalance
/// within 1.05 on the uniform workload.
#[test]
fn every_backend_on_1_to_4_ranks() {
    let n = 6000u64;
    let halo = 0.01;
    let id_sum: u64 = (0..n).sum();
    let id_sq: f64 = (0..n).map(|i| (i * i) as f64).sum();
    let weight: f64 = (0..n).map(|i| if i % 3 == 0 { 3.0 } else { 1.0 }).sum();
    for backend in backends() {
        for ranks in [1, 2, 3, 4] {
            let r = run(backend, "uniform", n, halo, ranks, 0.0);
            let ctx = format!("{backend} on {ranks} ranks");
            assert_eq!(
                sum::<usize>(&r, "local_items"),
                n as usize,
                "{ctx}: item count"
            );
            assert_eq!(sum::<u64>(&r, "id_sum"), id_sum, "{ctx}: id checksum");
            assert_eq!(
                sum::<f64>(&r, "id_sq_sum"),
                id_sq,
                "{ctx}: id square checksum"
            );
            assert!(
                (sum::<f64>(&r, "weight") - weight).abs() < 1e-9,
                "{ctx}: weights"
            );
            for rep in &r.reports {
                assert_eq!(rep.value("payload_ok"), Some("true"), "{ctx}: payload");
                assert_eq!(rep.parse::<u64>("owner_mismatch"), 0, "{ctx}: owner(point)");
                assert_eq!(
                    rep.parse::<u64>("box_mismatch"),
                    0,
                    "{ctx}: ranks_overlapping"
                );
                assert_eq!(
                    rep.parse::<u64>("ghosts_missing"),
                    0,
                    "{ctx}: ghost completeness"
                );
                assert_eq!(
                    rep.value("overlapped_ghosts_equal"),
                    Some("true"),
                    "{ctx}: non-blocking ghost exchange"
                );
            }
            if backend == "zoltan-rcb" {
                for rep in &r.reports {
                    assert_eq!(rep.parse::<u64>("rcb_box_outside"), 0, "{ctx}: RCB box");
                    assert_eq!(
                        rep.value("rcb_box_inside_domain"),
                        Some("true"),
                        "{ctx}: RCB box clamped"
                    );
                    assert!(rep.parse::<u64>("rcb_stay") > 0, "{ctx}");
                }
            }
            let imb: f64 = r.reports[0].parse("imbalance");
            assert!(imb <= 1.05, "{ctx}: imbalance {imb}");
            if ranks == 1 {
                assert_eq!(r.reports[0].parse::<u64>("ghost_items"), 0);
            } else {
                assert!(
                    r.reports[0].parse::<u64>("ghost_items") > 0,
                    "{ctx}: no ghosts at all?"
                );
            }
        }
    }
}

/// Clustered items: every item still placed once and ghosts complete.
#[test]
fn blobs_keep_items_and_ghosts() {
    for backend in backends() {
        let r = run(backend, "blobs", 4000, 0.005, 3, 0.0);
        assert_eq!(sum::<usize>(&r, "local_items"), 4000, "{backend}");
        for rep in &r.reports {
            assert_eq!(rep.parse::<u64>("ghosts_missing"), 0, "{backend}");
            assert_eq!(rep.parse::<u64>("owner_mismatch"), 0, "{backend}");
            assert_eq!(
                rep.value("overlapped_ghosts_equal"),
                Some("true"),
                "{backend}"
            );
            assert!(rep.parse::<u64>("owned_pairs") > 0, "{backend}: work ran");
        }
    }
}

/// The native RCB matches Zoltan's RCB in quality on the same input.
#[test]
fn native_rcb_matches_zoltan_rcb_quality() {
    for ranks in [2, 3, 4] {
        let ours = run("rcb", "uniform", 20000, 0.005, ranks, 0.0);
        let zol = run("zoltan-rcb", "uniform", 20000, 0.005, ranks, 0.0);
        let (i1, i2): (f64, f64) = (
            ours.reports[0].parse("imbalance"),
            zol.reports[0].parse("imbalance"),
        );
        assert!(
            i1 <= 1.05 && (i1 - i2).abs() <= 0.1 * i2,
            "{ranks} ranks: imbalance {i1} vs {i2}"
        );
        let (g1, g2): (f64, f64) = (
            ours.reports[0].parse("ghost_items"),
            zol.reports[0].parse("ghost_items"),
        );
        assert!(
            (g1 - g2).abs() <= 0.1 * g2,
            "{ranks} ranks: ghosts {g1} vs {g2}"
        );
    }
}

/// Repartitioning after a small move (hopper drift, reused cuts) migrates few items.
#[test]
fn repartition_after_small_move_migrates_few() {
    let n = 8000u64;
    for backend in ["rcb", "zoltan-rcb"] {
        let r = run(backend, "hopper", n, 0.005, 4, 0.002);
        let first: u64 = r.reports[0].parse("migrated_items");
        let again: u64 = r.reports[0].parse("remigrated_items");
        assert_eq!(sum::<usize>(&r, "local_items_after"), n as usize);
        assert!(
            first > n / 2,
            "{backend}: first partition moved only {first}"
        );
        assert!(
            again * 20 < n,
            "{backend}: repartition moved {again} of {n}"
        );
    }
}

/// A domain whose longest axis turns while its items hardly move: building
/// on the previous partition (kept cut axes, parts renumbered to the old
/// owners) moves few items, where a partition from scratch cuts along the
/// new axis and moves about half of them.
#[test]
fn reuse_follows_the_drift_when_the_domain_changes_shape() {
    let n = 6000u64;
    let moved = |backend: &str, mode: &str| -> u64 {
        let r = MpiRun::new(example_binary("partition_check"))
            .ranks(2)
            .args([backend, "spreading", &n.to_string(), "0.005", "0.04", mode])
            .run()
            .unwrap_or_else(|e| panic!("{backend} {mode}: {e}"));
        assert_eq!(sum::<usize>(&r, "local_items_after"), n as usize);
        r.reports[0].parse("remigrated_items")
    };
    for backend in ["rcb", "zoltan-rcb"] {
        let (reused, fresh) = (moved(backend, "reuse"), moved(backend, "fresh"));
        assert!(reused * 20 < n, "{backend}: reusing moved {reused} of {n}");
        assert!(
            fresh * 3 > n,
            "{backend}: from scratch moved only {fresh} of {n}"
        );
    }
    // METIS cuts the graph anew (here along the new long axis too); on two
    // parts the renumbering is the best matching, so it never moves more.
    let (reused, fresh) = (moved("metis", "reuse"), moved("metis", "fresh"));
    assert!(
        reused <= fresh,
        "metis: renumbered {reused}, afresh {fresh}"
    );
}

/// The native RCB's hysteresis: a reused cut stays where it is while each
/// side's weight is within its slack of the target, so a small shift of the
/// work moves no item; a shift beyond the slack moves the cut. Either way the
/// weight imbalance left is within the slack's bound over the whole tree,
/// 1 + 2 `reuse_slack` (plus one item's weight of granularity).
#[test]
fn a_reused_cut_stays_within_its_slack_and_follows_work_beyond_it() {
    let n = 8000u64;
    let slack = partition::rcb::Rcb::default().reuse_slack;
    let bound = 1.0 + 2.0 * slack + 0.005;
    // An item costs `skew` times more for each coordinate below 0.5, so a
    // cut's low side holds skew / (1 + skew) of its group's weight.
    let repartition = |ranks: usize, skew: f64| -> (u64, f64) {
        let r = MpiRun::new(example_binary("partition_check"))
            .ranks(ranks)
            .args(["rcb", "uniform", &n.to_string(), "0.005", "0.01", "reuse"])
            .args([skew.to_string()])
            .run()
            .unwrap_or_else(|e| panic!("{ranks} ranks, skew {skew}: {e}"));
        assert_eq!(sum::<usize>(&r, "local_items_after"), n as usize);
        let rep = &r.reports[0];
        (rep.parse("remigrated_items"), rep.parse("imbalance_after"))
    };
    for ranks in [2, 3, 4] {
        // Each low side's share grows by slack / 8 of its group: within the
        // allowance of slack / 2 at the top cut and slack / 4 below it.
        let (moved, imbalance) = repartition(ranks, 1.0 + 0.5 * slack);
        assert_eq!(moved, 0, "{ranks} ranks: a cut within its slack moved");
        assert!(imbalance <= bound, "{ranks} ranks: kept at {imbalance}");
        // The low side holds 0.6 of the whole: the cut follows the work.
        let (moved, imbalance) = repartition(ranks, 1.5);
        assert!(moved > 0, "{ranks} ranks: the cut stayed");
        assert!(imbalance <= bound, "{ranks} ranks: moved to {imbalance}");
    }
}

/// A cut the work has shifted beyond its slack moves only back to the
/// slack's edge, not to the median (as Zoltan's RCB stops once within its
/// tolerance): on 2 ranks the one cut leaves the weight imbalance its
/// slack allows, 1 + `reuse_slack`, where a partition from scratch balances,
/// and moves fewer items than that partition does.
#[test]
fn a_cut_beyond_its_slack_moves_back_to_its_edge_only() {
    let n = 8000u64;
    let slack = partition::rcb::Rcb::default().reuse_slack;
    let repartition = |mode: &str| -> (u64, f64) {
        let r = MpiRun::new(example_binary("partition_check"))
            .ranks(2)
            .args([
                "rcb",
                "uniform",
                &n.to_string(),
                "0.005",
                "0.01",
                mode,
                "1.5",
            ])
            .run()
            .unwrap_or_else(|e| panic!("{mode}: {e}"));
        assert_eq!(sum::<usize>(&r, "local_items_after"), n as usize);
        let rep = &r.reports[0];
        (rep.parse("remigrated_items"), rep.parse("imbalance_after"))
    };
    let (reused, at_edge) = repartition("reuse");
    let (fresh, balanced) = repartition("fresh");
    // One item's weight of granularity either way.
    let grain = 0.002;
    assert!(
        (at_edge - (1.0 + slack)).abs() <= grain,
        "reused: imbalance {at_edge}, the slack's edge {}",
        1.0 + slack
    );
    assert!(
        balanced <= 1.0 + grain,
        "from scratch: imbalance {balanced}"
    );
    assert!(
        reused < fresh,
        "reused moved {reused}, from scratch {fresh}"
    );
}

/// Items that drift across a cut together (a column settling towards its
/// floor, crossing the cut's height in order) move nowhere when the cut
/// follows them: the least-moving cut within the slack sits between the same
/// items as before, so a repartitioning moves next to none of the items
/// that keeping the cut would move, and leaves the imbalance within the
/// slack's bound.
#[test]
fn a_cut_follows_items_that_drifted_across_it_together() {
    let n = 8000u64;
    let slack = partition::rcb::Rcb::default().reuse_slack;
    for ranks in [2, 4] {
        let r = MpiRun::new(example_binary("partition_check"))
            .ranks(ranks)
            .args(["rcb", "settling", &n.to_string(), "0.005", "0.2", "reuse"])
            .run()
            .unwrap_or_else(|e| panic!("{ranks} ranks: {e}"));
        assert_eq!(sum::<usize>(&r, "local_items_after"), n as usize);
        let rep = &r.reports[0];
        let drifted: u64 = rep.parse("drifted_items");
        let moved: u64 = rep.parse("remigrated_items");
        let imbalance: f64 = rep.parse("imbalance_after");
        // Heights shrink by 2%, so the items within 2% of the first cut's
        // height above it cross it: about n / 100.
        assert!(drifted * 200 > n, "{ranks} ranks: only {drifted} drifted");
        assert!(
            moved * 10 <= drifted,
            "{ranks} ranks: moved {moved} where keeping the cuts moves {drifted}"
        );
        assert!(
            imbalance <= 1.0 + 2.0 * slack + 0.005,
            "{ranks} ranks: imbalance {imbalance}"
        );
    }
}

/// Byte exchanges in which some ranks send or receive nothing: an empty
/// byte buffer's dangling pointer is Open MPI's MPI_IN_PLACE, which once made
/// a migration abort (found when METIS gave every item to one rank).
#[test]
fn varcount_exchanges_of_bytes_with_empty_ranks() {
    for ranks in [1, 2, 3] {
        let r = MpiRun::new(example_binary("comm_check"))
            .ranks(ranks)
            .run()
            .unwrap_or_else(|e| panic!("{ranks} ranks: {e}"));
        for rep in &r.reports {
            assert_eq!(
                rep.value("all_to_all_v_bytes_ok"),
                Some("true"),
                "{ranks} ranks"
            );
            assert_eq!(
                rep.value("all_gather_v_bytes_ok"),
                Some("true"),
                "{ranks} ranks"
            );
        }
    }
}
