//! Multi-rank tests of the raw bindings, run through mpirun by the harness.
use mpi_harness::{example_binary, MpiRun};

#[test]
fn initialize_create_destroy_on_1_2_4_ranks() {
    for ranks in [1, 2, 4] {
        let run = MpiRun::new(example_binary("zoltan_smoke"))
            .ranks(ranks)
            .run()
            .unwrap_or_else(|e| panic!("{ranks} ranks: {e}"));
        for r in &run.reports {
            assert_eq!(r.parse::<i32>("initialize_rc"), zoltan_sys::ZOLTAN_OK);
            let version: f32 = r.parse("zoltan_version");
            assert!(version >= 3.0, "Zoltan version {version}");
            assert_eq!(
                r.parse::<usize>("library_id_size"),
                r.parse::<usize>("bindings_id_size"),
                "library and bindings disagree on ZOLTAN_ID_TYPE"
            );
            assert_eq!(r.value("created"), Some("true"));
            assert_eq!(r.parse::<i32>("set_param_rc"), zoltan_sys::ZOLTAN_OK);
            assert_ne!(
                r.parse::<i32>("bad_param_rc"),
                zoltan_sys::ZOLTAN_OK,
                "an unknown parameter must not be accepted silently"
            );
            assert_eq!(r.value("destroyed_to_null"), Some("true"));
            assert_eq!(r.parse::<usize>("ranks"), ranks);
        }
    }
}

/// Points at x = 0..N on a line, dealt round-robin to the ranks: RCB must give
/// every rank N/P of them, as one contiguous interval of x.
#[test]
fn tiny_rcb_partition_on_2_and_4_ranks() {
    for ranks in [2, 4] {
        let run = MpiRun::new(example_binary("rcb_tiny"))
            .ranks(ranks)
            .run()
            .unwrap_or_else(|e| panic!("{ranks} ranks: {e}"));
        let total: usize = run.reports[0].parse("total");
        let mut seen = vec![None; total];
        for r in &run.reports {
            assert_eq!(r.parse::<i32>("partition_rc"), zoltan_sys::ZOLTAN_OK);
            for line in r.lines.iter().filter_map(|l| l.strip_prefix("obj=")) {
                let f: Vec<&str> = line.split(',').collect();
                let gid: usize = f[0].parse().unwrap();
                let x: f64 = f[1].parse().unwrap();
                let part: usize = f[2].parse().unwrap();
                assert_eq!(x, gid as f64);
                assert!(part < ranks, "part {part} out of range");
                assert!(seen[gid].is_none(), "gid {gid} reported twice");
                seen[gid] = Some(part);
            }
        }
        let parts: Vec<usize> = seen
            .iter()
            .enumerate()
            .map(|(g, p)| p.unwrap_or_else(|| panic!("gid {g} missing")))
            .collect();
        for p in 0..ranks {
            let xs: Vec<usize> = (0..total).filter(|&g| parts[g] == p).collect();
            assert_eq!(xs.len(), total / ranks, "part {p} size, parts {parts:?}");
            assert_eq!(
                xs.last().unwrap() - xs[0] + 1,
                xs.len(),
                "part {p} is not one interval of x: {parts:?}"
            );
        }
        // Something must have moved: the initial distribution was round-robin.
        let exported: i32 = run
            .reports
            .iter()
            .map(|r| r.parse::<i32>("num_export"))
            .sum();
        assert!(exported > 0);
    }
}
