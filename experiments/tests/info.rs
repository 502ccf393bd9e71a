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
    assert!(text.contains("info"), "{text}");
}
