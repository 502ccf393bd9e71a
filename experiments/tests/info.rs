//! `tridem info` under mpirun: rank 0 alone prints the four library versions.
use mpi_harness::MpiRun;

#[test]
fn info_on_two_ranks_prints_versions_once() {
    let run = MpiRun::new(env!("CARGO_BIN_EXE_tridem"))
        .ranks(2)
        .arg("info")
        .expect_reports(false)
        .run()
        .unwrap_or_else(|e| panic!("{e}"));
    let out = &run.stdout;
    for key in ["Zoltan ", "MPI library ", "HDF5 ", "METIS "] {
        assert_eq!(out.matches(key).count(), 1, "`{key}` once in:\n{out}");
    }
    assert!(out.contains("Open MPI") || out.contains("MPICH"), "{out}");
    let ranks_line = out.lines().find(|l| l.starts_with("ranks")).unwrap();
    assert_eq!(ranks_line.split_whitespace().last(), Some("2"));
}

#[test]
fn info_json_is_parseable() {
    let run = MpiRun::new(env!("CARGO_BIN_EXE_tridem"))
        .ranks(1)
        .args(["info", "--json"])
        .expect_reports(false)
        .run()
        .unwrap_or_else(|e| panic!("{e}"));
    let v: serde_json::Value = serde_json::from_str(run.stdout.trim()).expect("JSON");
    for key in ["zoltan", "mpi_library", "hdf5", "metis"] {
        let s = v[key]
            .as_str()
            .unwrap_or_else(|| panic!("{key} missing: {v}"));
        assert!(
            s.chars().next().unwrap().is_ascii_alphanumeric(),
            "{key}={s}"
        );
    }
    assert_eq!(v["ranks"], 1);
}

#[test]
fn help_lists_subcommands() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tridem"))
        .arg("--help")
        .output()
        .unwrap();
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(out.status.success());
    for sub in [
        "info",
        "run",
        "distance",
        "kernels",
        "partition",
        "partition-plot",
    ] {
        assert!(
            text.lines()
                .any(|l| l.trim_start().starts_with(&format!("{sub} "))),
            "`{sub}` missing from --help:\n{text}"
        );
    }
}

#[test]
fn partition_json_on_two_ranks_has_the_documented_fields() {
    for partitioner in ["rcb", "zoltan-rcb", "metis"] {
        let run = MpiRun::new(env!("CARGO_BIN_EXE_tridem"))
            .ranks(2)
            .args([
                "partition",
                "--partitioner",
                partitioner,
                "--workload",
                "hopper",
                "--items",
                "5000",
                "--steps",
                "4",
                "--every",
                "2",
                "--json",
            ])
            .expect_reports(false)
            .run()
            .unwrap_or_else(|e| panic!("{e}"));
        let rows: Vec<serde_json::Value> = run
            .stdout
            .lines()
            .map(|l| serde_json::from_str(l).unwrap_or_else(|e| panic!("{e}: {l}")))
            .collect();
        assert_eq!(rows.len(), 2, "steps 0 and 2 partition: {}", run.stdout);
        for r in &rows {
            for k in [
                "step",
                "partitioner",
                "ranks",
                "items",
                "imbalance",
                "partition_s",
                "migrated_items",
                "migrated_bytes",
                "ghost_items",
                "ghost_bytes",
            ] {
                assert!(!r[k].is_null(), "{k} missing in {r}");
            }
            // The ghost exchange, the owned items' contact candidates, and
            // both overlapped, each timed on the slowest rank.
            for k in ["ghost_exchange_s", "owned_pairs_s", "overlapped_s"] {
                assert!(r[k].as_f64().is_some_and(|t| t > 0.0), "{k} in {r}");
            }
            assert!(r["owned_pairs"].as_u64().unwrap() > 0, "{r}");
            assert_eq!(r["items"], 5000);
            assert_eq!(r["ranks"], 2);
            assert_eq!(r["partitioner"], partitioner);
        }
        // Items start dealt by id, so the first partitioning moves about half.
        assert!(rows[0]["migrated_items"].as_u64().unwrap() > 1000);
    }
}

#[test]
fn partition_rejects_bad_arguments_without_a_panic() {
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_tridem"))
        .args(["partition", "--partitioner", "nonsense"])
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    let err = String::from_utf8_lossy(&out.stderr);
    // The refusal names the value and lists the possible ones.
    assert!(
        err.contains("'nonsense'")
            && err.contains("zoltan-rcb, zoltan-rib, zoltan-hsfc, metis, rcb"),
        "{err}"
    );
}

#[test]
fn slurm_job_templates_parse() {
    let dir = concat!(env!("CARGO_MANIFEST_DIR"), "/../jobs");
    let mut n = 0;
    for entry in std::fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.extension().is_some_and(|e| e == "sbatch") {
            let out = std::process::Command::new("bash")
                .arg("-n")
                .arg(&path)
                .output()
                .unwrap();
            assert!(
                out.status.success(),
                "{}: {}",
                path.display(),
                String::from_utf8_lossy(&out.stderr)
            );
            let text = std::fs::read_to_string(&path).unwrap();
            assert!(text.contains("#SBATCH --job-name"), "{}", path.display());
            n += 1;
        }
    }
    assert!(n >= 4);
}
