//! `tridem distance` and `tridem kernels` as users call them.
mod common;

use common::tridem_with_input as tridem;

fn cases_file() -> String {
    concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../dem/tests/data/triangle-pairs.csv"
    )
    .to_string()
}

/// The hard cases carry a 19th column (the reference): it is ignored as input
/// and used here to check every output line.
#[test]
fn distance_of_the_hard_cases_matches_their_references() {
    let text = std::fs::read_to_string(cases_file()).unwrap();
    let rows: Vec<Vec<f64>> = text
        .lines()
        .filter(|l| !l.trim().is_empty() && !l.starts_with('#'))
        .map(|l| l.split(',').map(|f| f.trim().parse().unwrap()).collect())
        .collect();
    // The hybrid is exact whatever the penalty kernel's finish does; more
    // rounds of the finish only answer more pairs without brute force.
    let mut by_penalty = Vec::new();
    for (method, rounds) in [
        ("brute", "1"),
        ("hybrid", "0"),
        ("hybrid", "1"),
        ("hybrid", "3"),
    ] {
        let (code, out, err) = tridem(
            &[
                "distance",
                "--method",
                method,
                "--finish-rounds",
                rounds,
                &cases_file(),
            ],
            "",
        );
        assert_eq!(code, 0, "{err}");
        if method == "hybrid" {
            by_penalty.push(out.lines().filter(|l| l.ends_with(",penalty")).count());
        }
        let lines: Vec<&str> = out.lines().collect();
        assert_eq!(lines.len(), rows.len());
        for (row, line) in rows.iter().zip(&lines) {
            let f: Vec<&str> = line.split(',').collect();
            assert_eq!(f.len(), 8, "{line}");
            assert!(f[7] == "penalty" || f[7] == "brute", "{line}");
            if method == "brute" {
                assert_eq!(f[7], "brute");
            }
            let d: f64 = f[0].parse().unwrap();
            let (lo, hi) =
                row[..18]
                    .chunks(3)
                    .fold(([f64::MAX; 3], [f64::MIN; 3]), |(mut lo, mut hi), v| {
                        for k in 0..3 {
                            lo[k] = lo[k].min(v[k]);
                            hi[k] = hi[k].max(v[k]);
                        }
                        (lo, hi)
                    });
            let l = ((hi[0] - lo[0]).powi(2) + (hi[1] - lo[1]).powi(2) + (hi[2] - lo[2]).powi(2))
                .sqrt();
            assert!(
                (d - row[18]).abs() <= 1e-12 * l,
                "{method}, {rounds} rounds: {line} vs {}",
                row[18]
            );
        }
    }
    assert!(
        by_penalty[1] < by_penalty[2] && by_penalty[0] < by_penalty[1],
        "pairs answered by the penalty kernel with 0, 1, 3 finish rounds: {by_penalty:?}"
    );
}

#[test]
fn distance_reads_stdin_and_reports_bad_rows_by_line_and_field() {
    let good = "0,0,0,1,0,0,0,1,0,0,0,2,1,0,2,0,1,2\n";
    let (code, out, _) = tridem(
        &["distance", "--method", "penalty"],
        &format!("# c\n{good}"),
    );
    assert_eq!(code, 0);
    let f: Vec<&str> = out.trim().split(',').collect();
    assert_eq!(f[0].parse::<f64>().unwrap(), 2.0);

    let bad = format!("{good}{}", good.replace("1,2\n", "1,oops\n"));
    let (code, out, err) = tridem(&["distance"], &bad);
    assert_eq!(code, 2);
    assert!(out.is_empty(), "no partial output: {out}");
    assert!(
        err.contains("stdin:2: field 18 is not a number: `oops`"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");

    let (code, _, err) = tridem(&["distance", "/nonexistent/pairs.csv"], "");
    assert_eq!(code, 2);
    assert!(err.contains("/nonexistent/pairs.csv"), "{err}");
}

/// Numbers are printed with the fewest digits that read back to the same
/// f64, in exponent form far from 1: two unit triangles 1e300 apart print
/// the distance as `1e300`, not 301 digits; at 1e-300, not 300 zeros.
#[test]
fn distance_prints_numbers_that_read_back_in_few_digits() {
    for s in [1e300, 1e-300, 1.0] {
        let row = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0]
            .iter()
            .map(|x| x * s)
            .chain([0.0, 0.0, 2.0, 1.0, 0.0, 2.0, 0.0, 1.0, 2.0].map(|x| x * s))
            .map(|x| format!("{x:?}"))
            .collect::<Vec<_>>()
            .join(",");
        let (code, out, err) = tridem(&["distance", "--method", "brute"], &format!("{row}\n"));
        assert_eq!(code, 0, "{err}");
        let f: Vec<&str> = out.trim().split(',').collect();
        assert_eq!(f[0].parse::<f64>().unwrap(), 2.0 * s, "{out}");
        assert!(f[..7].iter().all(|x| x.len() <= 24), "{out}");
    }
}

#[test]
fn kernels_json_has_the_documented_fields() {
    let (code, out, err) = tridem(
        &[
            "kernels",
            "--pairs",
            "4000",
            "--repeat",
            "1",
            "--threads",
            "2",
            "--statistic",
            "min",
            "--json",
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    let v: serde_json::Value = serde_json::from_str(&out).unwrap();
    let rows = v.as_array().unwrap();
    for m in ["brute", "penalty", "hybrid"] {
        assert!(rows.iter().any(|r| r["method"] == m), "{m} missing");
    }
    for r in rows {
        for k in ["method", "threads", "schedule", "batch", "ns_per_pair"] {
            assert!(!r[k].is_null(), "{k} missing in {r}");
        }
        assert!(r["ns_per_pair"].as_f64().unwrap() > 0.0);
        assert_eq!(r["statistic"], "min", "{r}");
    }
    let hybrid = rows.iter().find(|r| r["method"] == "hybrid").unwrap();
    let rate = hybrid["fallback_rate"].as_f64().unwrap();
    assert!((0.0..=1.0).contains(&rate));
    // The thread-scaling rows: each hybrid variant also on one thread, where
    // it certifies exactly the same pairs (answers do not depend on threads).
    for variant in ["whole-batch fallback", "failed-pairs fallback"] {
        let at = |t: u64| {
            rows.iter()
                .find(|r| r["method"] == "hybrid" && r["variant"] == variant && r["threads"] == t)
                .unwrap_or_else(|| panic!("{variant} on {t} thread(s) missing"))
        };
        let rate = at(2)["certified_rate"].as_f64().unwrap();
        assert!(rate > 0.5 && rate <= 1.0, "{rate}");
        assert_eq!(at(1)["certified_rate"], at(2)["certified_rate"]);
    }
}

#[test]
fn kernels_refuses_bad_options_without_a_panic() {
    for (args, expect) in [
        (
            &["kernels", "--pairs", "100", "--batch", "3"][..],
            "--batch 3",
        ),
        (&["kernels", "--pairs", "0"][..], "--pairs"),
        (
            &["kernels", "--pairs", "100", "--threads", "0"][..],
            "--threads",
        ),
        (
            &["kernels", "--accuracy", "--pairs", "100", "--batch", "5"][..],
            "--batch 5",
        ),
        (
            &["kernels", "--pairs", "100", "--statistic", "mean"][..],
            "--statistic",
        ),
    ] {
        let (code, out, err) = tridem(args, "");
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(err.contains(expect), "{args:?}: {err}");
        assert!(!err.contains("panicked"), "{args:?}: {err}");
        assert!(out.is_empty(), "{args:?} printed results: {out}");
    }
}

#[test]
fn kernels_accuracy_writes_csv_and_plot() {
    let dir = std::env::temp_dir().join(format!("tridem-acc-{}", std::process::id()));
    let (code, _, err) = tridem(
        &[
            "kernels",
            "--accuracy",
            "--pairs",
            "2000",
            "--repeat",
            "1",
            "--statistic",
            "min",
            "--output",
            dir.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    let csv = std::fs::read_to_string(dir.join("kernels-accuracy.csv")).unwrap();
    let lines: Vec<&str> = csv.lines().collect();
    assert!(lines[0].starts_with("sweep,iterations"));
    assert!(lines.len() > 30);
    // The hybrid keeps the certificate's promise in every setting: its error is
    // within the setting's tolerance (times L) or at rounding.
    for l in &lines[1..] {
        let f: Vec<&str> = l.split(',').collect();
        let tol: f64 = f[3].parse().unwrap();
        let hyb: f64 = f[12].parse().unwrap();
        assert!(hyb <= tol + 1e-13, "{l}");
        // The times say which summary of the repetitions they are.
        assert_eq!(f[13], "min", "{l}");
    }
    // Each further round of the finish starts from the last one's answer and
    // keeps what was certified: the certified rate cannot drop from round 1 on.
    let rounds: Vec<(usize, f64)> = lines[1..]
        .iter()
        .map(|l| l.split(',').collect::<Vec<_>>())
        .filter(|f| f[0] == "finish rounds")
        .map(|f| (f[5].parse().unwrap(), f[10].parse().unwrap()))
        .collect();
    assert_eq!(
        rounds.iter().map(|r| r.0).collect::<Vec<_>>(),
        [0, 1, 2, 3, 4]
    );
    for w in rounds[1..].windows(2) {
        assert!(w[1].1 >= w[0].1, "{rounds:?}");
    }
    let svg = std::fs::read_to_string(dir.join("kernels-accuracy.svg")).unwrap();
    assert!(svg.contains("<svg"));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn partition_plot_reads_json_lines_and_names_bad_lines() {
    let dir = std::env::temp_dir().join(format!("tridem-pplot-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let input = dir.join("runs.jsonl");
    let rec = |w: &str, p: &str, t: f64, g: u64| {
        format!(
            r#"{{"workload":"{w}","partitioner":"{p}","step":0,"partition_s":{t},"ghost_items":{g}}}"#
        )
    };
    let lines = [
        rec("uniform", "rcb", 0.05, 2000),
        rec("uniform", "metis", 3.0, 5000),
        rec("blobs", "rcb", 0.06, 8000),
    ];
    std::fs::write(&input, lines.join("\n")).unwrap();
    let svg = dir.join("p.svg");
    let (code, _, err) = tridem(
        &[
            "partition-plot",
            input.to_str().unwrap(),
            "--output",
            svg.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 0, "{err}");
    let text = std::fs::read_to_string(&svg).unwrap();
    assert!(text.contains("<svg") && text.contains("metis") && text.contains("blobs"));
    std::fs::write(&input, format!("{}\n{{\"workload\":\"x\"}}\n", lines[0])).unwrap();
    let (code, _, err) = tridem(
        &[
            "partition-plot",
            input.to_str().unwrap(),
            "--output",
            svg.to_str().unwrap(),
        ],
        "",
    );
    assert_eq!(code, 2);
    assert!(
        err.contains("runs.jsonl:2: missing field `partitioner`"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(dir);
}
