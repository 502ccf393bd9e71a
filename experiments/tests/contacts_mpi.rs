//! Contact detection split across real MPI ranks (the `contacts_mpi`
//! example): triangles placed by a partitioner and migrated with their
//! vertices, owned contacts found while ghost triangles travel, and the union
//! over ranks exactly the contacts one node finds.
use mpi_harness::{example_binary, MpiRun};

#[test]
fn ranks_together_find_exactly_the_one_node_contacts() {
    // By step 3,000 the hopper's grains lie on its walls and on each other.
    // METIS places every triangle on one rank here: its cell grid is sized by
    // the largest item, and a hopper wall spans the scene (docs/partition.md);
    // the other rank, empty, must still take part in every exchange.
    for (backend, ranks, splits) in [
        ("rcb", 2, true),
        ("rcb", 3, true),
        ("zoltan-rcb", 2, true),
        ("metis", 2, false),
    ] {
        let run = MpiRun::new(example_binary("contacts_mpi"))
            .ranks(ranks)
            .args([backend, "3000"])
            .run()
            .unwrap_or_else(|e| panic!("{backend} on {ranks} ranks: {e}"));
        let ctx = format!("{backend} on {ranks} ranks");
        let sum = |k: &str| run.reports.iter().map(|r| r.parse::<u64>(k)).sum::<u64>();
        let reference = run.reports[0].parse::<u64>("one_node_contacts");
        assert!(reference > 50, "{ctx}: {reference} contacts to find");
        for r in &run.reports {
            for k in ["missing", "extra", "duplicates", "distances_differ"] {
                assert_eq!(r.parse::<u64>(k), 0, "{ctx}: {k}");
            }
            assert_eq!(r.parse::<u64>("union_contacts"), reference, "{ctx}");
        }
        let owning = run
            .reports
            .iter()
            .filter(|r| r.parse::<u64>("owned_triangles") > 0)
            .count();
        assert_eq!(owning, if splits { ranks } else { 1 }, "{ctx}");
        assert_eq!(
            sum("local_local_contacts") + sum("local_ghost_contacts"),
            reference,
            "{ctx}"
        );
        // The cut runs through the pile: some contacts need ghosts.
        assert_eq!(sum("local_ghost_contacts") > 0, splits, "{ctx}");
        assert_eq!(sum("ghosts_received"), sum("ghosts_sent"), "{ctx}");
    }
}
