//! `tridem study NAME` at a tiny size: every run's metrics as JSON lines,
//! the summary CSV with its documented columns (medians and the least and
//! most over the repeats), the noise floor of the first setting run twice,
//! non-empty figures, and the repartitioning cost model fitted from the data.
use mpi_harness::open_mpi_local_env;
use std::path::{Path, PathBuf};
use std::process::Command;

fn study(name: &str, extra: &[&str]) -> (PathBuf, String) {
    study_of(name, "30", extra)
}

/// A study of `steps` steps per run.
fn study_of(name: &str, steps: &str, extra: &[&str]) -> (PathBuf, String) {
    let dir = std::env::temp_dir().join(format!("tridem-study-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/silo-1000.toml");
    let out = Command::new(env!("CARGO_BIN_EXE_tridem"))
        .args([
            "study",
            name,
            "--steps",
            steps,
            "--metrics-every",
            "5",
            "--repeat",
            "2",
        ])
        .arg("--scene")
        .arg(&scene)
        .arg("--output")
        .arg(&dir)
        .args(extra)
        .envs(open_mpi_local_env())
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "{name}: {}\n{stdout}",
        String::from_utf8_lossy(&out.stderr)
    );
    (dir, stdout)
}

type Row = std::collections::HashMap<String, String>;

/// The summary's rows as maps from column to value, after checking that it
/// has the documented `columns`.
fn summary_rows(dir: &Path, columns: &[&str]) -> Vec<Row> {
    let text = std::fs::read_to_string(dir.join("summary.csv")).unwrap();
    let mut lines = text.lines();
    let head: Vec<String> = lines.next().unwrap().split(',').map(String::from).collect();
    for column in columns {
        assert!(head.iter().any(|h| h == column), "no column {column}");
    }
    let rows: Vec<Row> = lines
        .map(|l| {
            head.iter()
                .cloned()
                .zip(l.split(',').map(String::from))
                .collect()
        })
        .collect();
    // Each time is the median of its repeats, within their least and most.
    for r in &rows {
        let t = |c: &str| num(r, &format!("seconds_per_step_{c}"));
        assert!(t("min") <= t("median") && t("median") <= t("max"), "{r:?}");
        assert!(t("min") > 0.0, "{r:?}");
    }
    rows
}

/// A distributed study's summary.
fn rows(dir: &Path) -> Vec<Row> {
    summary_rows(
        dir,
        &[
            "label",
            "ranks",
            "repeats",
            "seconds_per_step_median",
            "seconds_per_step_min",
            "seconds_per_step_max",
            "busy_imbalance_median",
            "triangle_imbalance_median",
            "partition_seconds_median",
            "migration_seconds_median",
            "wait_seconds_median",
            "ghosts_received_median",
        ],
    )
}

/// The figure `name` (SVG) draws something, and its PNG twin is a PNG.
fn figure(dir: &Path, name: &str) {
    let svg = std::fs::read_to_string(dir.join(name)).unwrap();
    assert!(
        svg.contains("<svg") && (svg.contains("<polyline") || svg.contains("<circle")),
        "{name} draws no line and no point"
    );
    let png = std::fs::read(dir.join(name).with_extension("png")).unwrap();
    assert!(
        png.starts_with(b"\x89PNG\r\n\x1a\n") && png.len() > 5_000,
        "{name}: no PNG beside it"
    );
}

/// A one-node study's summary.
fn node_rows(dir: &Path) -> Vec<Row> {
    summary_rows(
        dir,
        &[
            "label",
            "threads",
            "repeats",
            "seconds_per_step_median",
            "seconds_per_step_min",
            "seconds_per_step_max",
            "narrow_phase_idle_fraction",
            "fallback_rate",
            "task_fallback_least",
            "task_fallback_most",
            "rms_deviation_m",
            "identical_to_reference",
        ],
    )
}

fn num(row: &Row, column: &str) -> f64 {
    row[column].parse().unwrap()
}

#[test]
fn scheduling_study_finds_the_answers_independent_of_threads_and_schedule() {
    // Long enough for the grains to settle onto the floor: pairs to fall back on.
    let (dir, out) = study_of("scheduling", "300", &["--threads", "1,2"]);
    let rows = node_rows(&dir);
    assert_eq!(
        rows.len(),
        13,
        "3 schedules x 2 fallbacks x 2 thread counts, and the first again"
    );
    assert_eq!(rows[12]["label"], "static-whole-batch-1-again");
    assert!(out.contains("noise floor:"), "{out}");
    for r in &rows {
        assert_eq!(r["repeats"], "2");
        let idle = num(r, "narrow_phase_idle_fraction");
        assert!((0.0..1.0).contains(&idle), "{idle}");
        assert!(num(r, "task_fallback_most") >= num(r, "task_fallback_least"));
        // The hybrid kernel's answers are exact: the final state at any
        // thread count and schedule is the one-thread static run's, bit for bit.
        assert_eq!(r["identical_to_reference"], "true", "{}", r["label"]);
    }
    // Only the pairs Newton failed on fall back, whatever the batch
    // around them: fewer fallbacks than the whole batch's.
    let rate = |label: &str| {
        num(
            rows.iter().find(|r| r["label"] == label).unwrap(),
            "fallback_rate",
        )
    };
    assert!(rate("static-failed-pairs-1") < rate("static-whole-batch-1"));
    for f in ["step-time.svg", "idle.svg", "task-fallback.svg"] {
        figure(&dir, f);
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn accuracy_study_measures_deviation_from_brute_force() {
    // Settled first, so that the runs step a pile of hundreds of contacts.
    let (dir, out) = study_of("accuracy", "100", &["--settle", "3500"]);
    let rows = node_rows(&dir);
    let row = |label: &str| rows.iter().find(|r| r["label"] == label).unwrap();
    let brute = row("brute");
    assert_eq!(brute["identical_to_reference"], "true");
    assert_eq!(num(brute, "rms_deviation_m"), 0.0);
    assert!(
        num(brute, "contacts") / 100.0 > 100.0,
        "a dense phase: {out}"
    );
    // Gravity changed by 1e-14 parts the trajectories by rounding alone:
    // the floor, far under a kernel's own error.
    let floor = num(row("brute-g+1e-14"), "rms_deviation_m");
    assert!(floor > 0.0, "{out}");
    assert!(
        num(row("penalty-4it"), "rms_deviation_m") > 100.0 * floor,
        "{out}"
    );
    // One Newton iteration without the exact finish misses most contacts:
    // grains sink into each other and the energy books stop closing.
    let one = row("penalty-1it");
    assert!(num(one, "deep_contacts") > 0.0, "{out}");
    assert!(
        num(one, "books_drift_over_max_kinetic")
            > 10.0 * num(brute, "books_drift_over_max_kinetic"),
        "{out}"
    );
    // The hybrid certifies or falls back: brute force's answers.
    assert_eq!(row("hybrid-failed-pairs")["identical_to_reference"], "true");
    // The finding leads with an exact setting, whatever is faster by
    // missing contacts.
    let lead = out
        .split("found: the fastest exact setting is ")
        .nth(1)
        .and_then(|t| t.split(" (").next())
        .unwrap_or_else(|| panic!("no finding: {out}"));
    assert_eq!(row(lead)["identical_to_reference"], "true", "{out}");
    figure(&dir, "accuracy.svg");
    let _ = std::fs::remove_dir_all(&dir);
}

/// The metrics of a setting's first run.
fn metrics(dir: &Path, label: &str) -> Vec<serde_json::Value> {
    let file = dir.join("runs").join(format!("{label}-r0.jsonl"));
    let text = std::fs::read_to_string(file).unwrap();
    text.lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

#[test]
fn repartition_frequency_fits_its_cost_model_to_the_runs() {
    let (dir, out) = study(
        "repartition-frequency",
        &["--every", "5,0", "--when", "1.2"],
    );
    let rows = rows(&dir);
    let labels: Vec<&str> = rows.iter().map(|r| r["label"].as_str()).collect();
    assert_eq!(labels, ["every-5", "never", "when-1.2", "every-5-again"]);
    for r in &rows {
        assert!(num(r, "triangle_imbalance_median") >= 1.0);
        assert!(num(r, "busy_imbalance_min") >= 1.0);
    }
    // The setting each run varies: K, "never" drawn at the run's length, τ.
    assert_eq!(rows[0]["setting"], "5");
    assert_eq!(rows[1]["setting"], "30");
    assert_eq!(rows[2]["setting"], "1.2");
    assert_eq!(metrics(&dir, "every-5").len(), 6);
    for f in [
        "sections.svg",
        "imbalance.svg",
        "step-time.svg",
        "busy-imbalance.svg",
        "migration.svg",
    ] {
        figure(&dir, f);
    }
    // The model's prediction is in model.csv, one row per K; its verdict
    // says whether it picked the measured best within the noise floor.
    let model = std::fs::read_to_string(dir.join("model.csv")).unwrap();
    assert_eq!(model.lines().count(), 3, "{model}");
    assert!(
        out.contains("cost model (fitted to every-5 and never"),
        "{out}"
    );
    assert!(out.contains("predict"), "{out}");
    assert!(out.contains("noise floor:"), "{out}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn partitioners_and_exchange_studies_write_their_data_and_figures() {
    let (dir, _) = study("partitioners", &["--repartition-every", "10"]);
    assert_eq!(
        rows(&dir).len(),
        partition::Backend::ALL.len() + 1,
        "every partitioner, and the first again"
    );
    for p in partition::Backend::ALL.map(|b| b.name()) {
        let m = metrics(&dir, p);
        assert_eq!(m.len(), 6, "{p}");
        assert_eq!(m[0]["sum"]["owned_bodies"], 1000.0, "{p}");
    }
    figure(&dir, "imbalance.svg");
    figure(&dir, "step-time.svg");
    let _ = std::fs::remove_dir_all(&dir);

    let (dir, _) = study("exchange", &["--ranks", "2,3"]);
    let rows = rows(&dir);
    let labels: Vec<&str> = rows.iter().map(|r| r["label"].as_str()).collect();
    assert_eq!(
        labels,
        [
            "blocking-2",
            "nonblocking-2",
            "blocking-3",
            "nonblocking-3",
            "blocking-2-again"
        ]
    );
    figure(&dir, "exchange.svg");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_study_refuses_one_rank_and_writes_nothing() {
    let dir = std::env::temp_dir().join(format!("tridem-study-{}-refused", std::process::id()));
    let out = Command::new(env!("CARGO_BIN_EXE_tridem"))
        .args(["study", "exchange", "--ranks", "1,2", "--output"])
        .arg(&dir)
        .output()
        .unwrap();
    assert_eq!(out.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&out.stderr).contains("--ranks 1"));
    assert!(!dir.exists());
}
