//! The contacts of the DEM split across real MPI ranks (the `contacts_mpi`
//! example): particles placed by a partitioner and migrated, ghost bodies
//! exchanged while the contacts among owned bodies are found, each contact
//! computed on one rank, and together exactly those one process finds, with
//! the same forces, to the bit.
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
        let root = &run.reports[0];
        let reference = root.parse::<u64>("one_node_contacts");
        assert!(reference > 200, "{ctx}: {reference} contacts to find");
        assert_eq!(root.parse::<u64>("gathered_contacts"), reference, "{ctx}");
        assert_eq!(root.parse::<u64>("contacts_differ"), 0, "{ctx}");
        // Each contact computed on one rank.
        assert_eq!(sum("last_contacts"), reference, "{ctx}");
        assert_eq!(sum("owned_particles"), 100, "{ctx}");
        for r in &run.reports {
            assert!(r.parse::<u64>("owned_particles") > 0, "{ctx}");
        }
        // The cuts run through the pile: ghosts are needed, but only the
        // particles near a cut travel, not all 100.
        assert_eq!(sum("ghosts_received"), sum("ghosts_sent"), "{ctx}");
        assert!(sum("ghosts_received") > 0, "{ctx}");
        assert!(sum("ghosts_received") < 100, "{ctx}");
    }
}
