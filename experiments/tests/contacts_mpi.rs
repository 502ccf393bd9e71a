//! Contact detection split across real MPI ranks (the `contacts_mpi`
//! example): particle triangles placed by a partitioner and migrated with
//! their vertices, owned contacts found while ghost triangles travel, and the
//! union over ranks exactly the contacts one node finds.
use mpi_harness::{example_binary, MpiRun};

#[test]
fn ranks_together_find_exactly_the_one_node_contacts() {
    // At its end (step 7,000) the hopper's grains lie piled on the floor,
    // against its walls and each other.
    for (backend, ranks) in [("rcb", 2), ("rcb", 3), ("zoltan-rcb", 2), ("metis", 2)] {
        let run = MpiRun::new(example_binary("contacts_mpi"))
            .ranks(ranks)
            .args([backend, "7000"])
            .run()
            .unwrap_or_else(|e| panic!("{backend} on {ranks} ranks: {e}"));
        let ctx = format!("{backend} on {ranks} ranks");
        let sum = |k: &str| run.reports.iter().map(|r| r.parse::<u64>(k)).sum::<u64>();
        let reference = run.reports[0].parse::<u64>("one_node_contacts");
        assert!(reference > 500, "{ctx}: {reference} contacts to find");
        for r in &run.reports {
            for k in ["missing", "extra", "duplicates", "distances_differ"] {
                assert_eq!(r.parse::<u64>(k), 0, "{ctx}: {k}");
            }
            assert_eq!(r.parse::<u64>("union_contacts"), reference, "{ctx}");
            assert!(r.parse::<u64>("owned_particle_triangles") > 0, "{ctx}");
        }
        assert_eq!(
            sum("local_local_contacts") + sum("local_ghost_contacts"),
            reference,
            "{ctx}"
        );
        // The cuts run through the pile: some contacts need ghosts.
        assert!(sum("local_ghost_contacts") > 0, "{ctx}");
        assert_eq!(sum("ghosts_received"), sum("ghosts_sent"), "{ctx}");
        // Ghosts are the triangles near a cut, not everything: the 100
        // particles have 2,000 triangles.
        assert!(sum("ghosts_received") < 1000, "{ctx}");
    }
}
