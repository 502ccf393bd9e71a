//! `tridem study NAME`: questions a DEM user asks before spending an
//! allocation, answered on real distributed runs of a scene. Each study
//! starts its runs under mpirun (`$MPIRUN`, default `mpirun`, with
//! `$MPIRUN_ARGS`, default `--oversubscribe`; `MPIRUN=srun` inside a SLURM
//! allocation, with `--mpi=pmix` unless `$TRIDEM_SRUN_MPI` says), keeps every run's metrics
//! (`DIR/runs/LABEL.jsonl`), writes one summary CSV and its figures (SVG),
//! and prints a short table.

use crate::cli::{StudyArgs, StudyName};
use crate::error::{create_output_dir, CliError, CliResult};
use crate::plot::{lines, Series};
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// One run of a study.
pub(crate) struct Spec {
    pub label: String,
    /// 1: a run on one node, started directly (no launcher).
    pub ranks: usize,
    pub threads: usize,
    pub args: Vec<String>,
    /// The setting the study varies, as a number for plots (K, ranks, threads).
    pub x: f64,
    /// The series it belongs to in the figures.
    pub series: String,
}

pub(crate) struct Ran {
    pub spec: Spec,
    /// The run's JSON summary.
    pub summary: Value,
    /// Its metrics lines (distributed runs).
    pub lines: Vec<Value>,
}

/// The summary CSV's columns after the run's label, ranks and setting:
/// means over ranks of the per-step metrics.
const MEANS: [&str; 11] = [
    "partition_seconds",
    "migration_seconds",
    "wait_seconds",
    "local_detection_seconds",
    "ghost_detection_seconds",
    "force_seconds",
    "integration_seconds",
    "busy_seconds",
    "migrated_bodies",
    "ghosts_received",
    "contacts",
];

pub fn run(args: &StudyArgs) -> CliResult {
    let dir = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("out/study-{}", args.name.name())));
    if let Some(r) = args
        .ranks
        .iter()
        .find(|&&r| r < 2)
        .filter(|_| args.name.distributed())
    {
        return Err(CliError::input(format!(
            "--ranks {r}: a study compares distributed runs, of 2 ranks or more"
        )));
    }
    if dir.join("summary.csv").exists() && !args.overwrite {
        return Err(CliError::input(format!(
            "{}: holds an earlier study; write to another directory or replace it with --overwrite",
            dir.display()
        )));
    }
    if !args.scene.exists() {
        return Err(CliError::input(format!(
            "{}: no such scene",
            args.scene.display()
        )));
    }
    let specs = if args.name.distributed() {
        specs(args)
    } else {
        crate::study_node::specs(args)?
    };
    create_output_dir(&dir.join("runs"))?;
    let mut ran = Vec::new();
    for (k, spec) in specs.into_iter().enumerate() {
        let start = Instant::now();
        let r = run_one(args, &dir, spec)?;
        eprintln!(
            "[{}] {:<24} {:>7.2} s",
            k + 1,
            r.spec.label,
            start.elapsed().as_secs_f64()
        );
        ran.push(r);
    }
    if !args.name.distributed() {
        return crate::study_node::report(args, &dir, &ran);
    }
    let csv = summary_csv(&ran);
    write(&dir.join("summary.csv"), &csv)?;
    figures(args, &dir, &ran)?;
    print!("{}", table(&ran));
    if args.name == StudyName::RepartitionFrequency {
        let model = cost_model(&ran);
        write(&dir.join("model.csv"), &model.csv)?;
        println!("{}", model.verdict);
    }
    println!("data and figures in {}", dir.display());
    Ok(())
}

pub(crate) fn write(path: &Path, text: &str) -> CliResult {
    std::fs::write(path, text)
        .map_err(|e| CliError::runtime(format!("{}: cannot write: {e}", path.display())))
}

fn specs(args: &StudyArgs) -> Vec<Spec> {
    let s = |v: &[&str]| v.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    let ranks = args.ranks[0];
    let threads = args.threads.first().copied().unwrap_or(1);
    match args.name {
        StudyName::RepartitionFrequency => args
            .every
            .iter()
            .map(|&k| Spec {
                label: if k == 0 {
                    "never".into()
                } else {
                    format!("every-{k}")
                },
                ranks,
                threads,
                args: s(&["--repartition-every", &k.to_string()]),
                x: if k == 0 {
                    args.steps() as f64
                } else {
                    k as f64
                },
                series: "K".into(),
            })
            .collect(),
        StudyName::Partitioners => ["zoltan-rcb", "zoltan-rib", "zoltan-hsfc", "metis", "rcb"]
            .iter()
            .enumerate()
            .map(|(i, p)| Spec {
                label: p.to_string(),
                ranks,
                threads,
                args: s(&[
                    "--partitioner",
                    p,
                    "--repartition-every",
                    &args.repartition_every.to_string(),
                ]),
                x: i as f64,
                series: p.to_string(),
            })
            .collect(),
        StudyName::Exchange => args
            .ranks
            .iter()
            .flat_map(|&r| {
                ["blocking", "nonblocking"].map(|mode| Spec {
                    label: format!("{mode}-{r}"),
                    ranks: r,
                    threads,
                    args: s(&[
                        "--exchange",
                        mode,
                        "--repartition-every",
                        &args.repartition_every.to_string(),
                    ]),
                    x: r as f64,
                    series: mode.to_string(),
                })
            })
            .collect(),
        StudyName::Scheduling | StudyName::Accuracy => unreachable!("runs on one node"),
    }
}

/// Runs one run of a study (under the launcher when distributed, with
/// metrics; on one node directly, keeping its output for its final state)
/// and reads its summary and metrics.
fn run_one(args: &StudyArgs, dir: &Path, spec: Spec) -> CliResult<Ran> {
    let metrics = dir.join("runs").join(format!("{}.jsonl", spec.label));
    let exe = std::env::current_exe().map_err(|e| CliError::runtime(e.to_string()))?;
    let launcher = std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into());
    let mut command = if spec.ranks == 1 {
        let mut c = Command::new(&exe);
        c.arg("run")
            .arg(&args.scene)
            .arg("--output")
            .arg(dir.join("runs").join(&spec.label));
        c
    } else {
        // SLURM's srun takes the task count as -n, needs no oversubscription,
        // and starts Debian's Open MPI through PMIx ($TRIDEM_SRUN_MPI names
        // another plugin).
        let srun = launcher.ends_with("srun");
        let extra = std::env::var("MPIRUN_ARGS").unwrap_or_else(|_| {
            if srun {
                let plugin = std::env::var("TRIDEM_SRUN_MPI").unwrap_or_else(|_| "pmix".into());
                format!("--mpi={plugin}")
            } else {
                "--oversubscribe".into()
            }
        });
        let mut c = Command::new(&launcher);
        c.args(extra.split_whitespace())
            .args([if srun { "-n" } else { "-np" }, &spec.ranks.to_string()])
            .arg(&exe)
            .arg("run")
            .arg(&args.scene)
            .args(["--metrics-every", &args.metrics_every.to_string()])
            .arg("--metrics")
            .arg(&metrics);
        c
    };
    let out = command
        .args(["--steps", &args.steps().to_string()])
        .args(["--threads", &spec.threads.to_string()])
        .args(["--quiet", "--json", "--overwrite"])
        .args(&spec.args)
        .output()
        .map_err(|e| CliError::runtime(format!("cannot start {launcher}: {e}")))?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        return Err(CliError::runtime(format!(
            "run {} failed ({}): {}",
            spec.label,
            out.status,
            stderr.trim()
        )));
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let summary: Value = stdout
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .ok_or_else(|| CliError::runtime(format!("run {}: no summary", spec.label)))?;
    if spec.ranks == 1 {
        return Ok(Ran {
            spec,
            summary,
            lines: Vec::new(),
        });
    }
    let text = std::fs::read_to_string(&metrics)
        .map_err(|e| CliError::runtime(format!("{}: {e}", metrics.display())))?;
    let lines = text
        .lines()
        .map(serde_json::from_str)
        .collect::<Result<Vec<Value>, _>>()
        .map_err(|e| CliError::runtime(format!("{}: {e}", metrics.display())))?;
    Ok(Ran {
        spec,
        summary,
        lines,
    })
}

fn mean(r: &Ran, field: &str) -> f64 {
    r.summary["per_step_over_ranks"][field]["mean"]
        .as_f64()
        .unwrap_or(0.0)
}

/// The mean over the run's metrics lines of an imbalance (max/mean over ranks).
fn mean_of_lines(r: &Ran, field: &str) -> f64 {
    let v: Vec<f64> = r.lines.iter().filter_map(|l| l[field].as_f64()).collect();
    v.iter().sum::<f64>() / v.len().max(1) as f64
}

/// The mean imbalance of the ranks' work (busy seconds): what a rank that
/// keeps its particles between repartitionings drifts into, while their
/// count stays what the partitioner gave.
fn mean_imbalance(r: &Ran) -> f64 {
    mean_of_lines(r, "busy_imbalance")
}

fn summary_csv(ran: &[Ran]) -> String {
    let mut s = String::from(
        "label,ranks,setting,seconds_per_step,triangle_imbalance_mean,busy_imbalance_mean,max_wait_seconds",
    );
    for m in MEANS {
        write!(s, ",{m}").expect("string");
    }
    s.push('\n');
    for r in ran {
        write!(
            s,
            "{},{},{},{:e},{},{},{:e}",
            r.spec.label,
            r.spec.ranks,
            r.spec.x,
            r.summary["seconds_per_step"].as_f64().unwrap_or(0.0),
            mean_of_lines(r, "triangle_imbalance"),
            mean_imbalance(r),
            r.summary["per_step_over_ranks"]["wait_seconds"]["max"]
                .as_f64()
                .unwrap_or(0.0),
        )
        .expect("string");
        for m in MEANS {
            write!(s, ",{:e}", mean(r, m)).expect("string");
        }
        s.push('\n');
    }
    s
}

/// A metrics line's value per step of its interval.
fn per_step(line: &Value, field: &str, every: u64) -> f64 {
    let ranks = line["ranks"].as_f64().unwrap_or(1.0);
    line["sum"][field].as_f64().unwrap_or(0.0) / ranks / every as f64
}

fn figures(args: &StudyArgs, dir: &Path, ran: &[Ran]) -> CliResult {
    let scene = args
        .scene
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().into_owned());
    match args.name {
        StudyName::RepartitionFrequency => repartition_figures(args, dir, ran, &scene),
        StudyName::Partitioners => partitioner_figures(args, dir, ran, &scene),
        StudyName::Exchange => exchange_figures(dir, ran, &scene),
        StudyName::Scheduling | StudyName::Accuracy => unreachable!("runs on one node"),
    }
    .map_err(|e| CliError::runtime(format!("plot: {e}")))
}

type PlotResult = Result<(), Box<dyn std::error::Error>>;

/// A metric of every run over the steps: imbalances as they are, other
/// fields per step and times `scale`.
fn over_steps(ran: &[Ran], field: &str, scale: f64, metrics_every: u64) -> Vec<Series> {
    ran.iter()
        .map(|r| Series {
            name: r.spec.label.clone(),
            points: r
                .lines
                .iter()
                .map(|l| {
                    let v = if field.ends_with("imbalance") {
                        l[field].as_f64().unwrap_or(1.0)
                    } else {
                        scale * per_step(l, field, metrics_every)
                    };
                    (l["step"].as_f64().unwrap_or(0.0), v)
                })
                .collect(),
        })
        .collect()
}

/// Time per step by section against K, and the busy imbalance over the run.
fn repartition_figures(args: &StudyArgs, dir: &Path, ran: &[Ran], scene: &str) -> PlotResult {
    let sections = [
        (
            "partition + migration",
            ["partition_seconds", "migration_seconds"].as_slice(),
        ),
        ("exchange wait", &["wait_seconds"]),
        (
            "detection",
            &["local_detection_seconds", "ghost_detection_seconds"],
        ),
        ("forces", &["force_seconds"]),
        ("integration", &["integration_seconds"]),
    ];
    let mut series: Vec<Series> = sections
        .iter()
        .map(|(name, fields)| Series {
            name: name.to_string(),
            points: ran
                .iter()
                .map(|r| {
                    (
                        r.spec.x,
                        1e3 * fields.iter().map(|f| mean(r, f)).sum::<f64>(),
                    )
                })
                .collect(),
        })
        .collect();
    series.push(Series {
        name: "step (total)".into(),
        points: ran
            .iter()
            .map(|r| {
                (
                    r.spec.x,
                    1e3 * r.summary["seconds_per_step"].as_f64().unwrap_or(0.0),
                )
            })
            .collect(),
    });
    let caption = format!(
        "{scene}, {} ranks: ms per step by section against K (never at K = {})",
        args.ranks[0],
        args.steps()
    );
    lines(
        &dir.join("sections.svg"),
        &caption,
        ("repartition every K steps", "ms per step (mean over ranks)"),
        &series,
        true,
    )?;
    let caption = format!("{scene}: imbalance of the ranks' busy time over the run");
    imbalance_figure(args, dir, ran, &caption)
}

/// Each run's busy imbalance over its steps.
fn imbalance_figure(args: &StudyArgs, dir: &Path, ran: &[Ran], caption: &str) -> PlotResult {
    lines(
        &dir.join("imbalance.svg"),
        caption,
        ("step", "busy imbalance (max/mean)"),
        &over_steps(ran, "busy_imbalance", 1.0, args.metrics_every),
        false,
    )
}

/// The busy imbalance and the time per step of each partitioner over the run.
fn partitioner_figures(args: &StudyArgs, dir: &Path, ran: &[Ran], scene: &str) -> PlotResult {
    let caption = format!(
        "{scene}, {} ranks, repartition every {}: imbalance of the ranks' busy time",
        args.ranks[0], args.repartition_every
    );
    imbalance_figure(args, dir, ran, &caption)?;
    let caption = format!("{scene}, {} ranks: ms per step over the run", args.ranks[0]);
    lines(
        &dir.join("step-time.svg"),
        &caption,
        ("step", "ms per step (mean over ranks)"),
        &over_steps(ran, "step_seconds", 1e3, args.metrics_every),
        false,
    )
}

/// The wait for ghosts and the step time against the ranks, both exchanges.
fn exchange_figures(dir: &Path, ran: &[Ran], scene: &str) -> PlotResult {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut series = Vec::new();
    for mode in ["blocking", "nonblocking"] {
        for (what, field) in [("wait", "wait_seconds"), ("step", "step_seconds")] {
            series.push(Series {
                name: format!("{mode}: {what}"),
                points: ran
                    .iter()
                    .filter(|r| r.spec.series == mode)
                    .map(|r| (r.spec.x, 1e3 * mean(r, field)))
                    .collect(),
            });
        }
    }
    let caption = format!(
        "{scene}: ghost exchange wait per rank ({cores} cores: more ranks are oversubscribed)"
    );
    lines(
        &dir.join("exchange.svg"),
        &caption,
        ("ranks", "ms per step (mean over ranks)"),
        &series,
        false,
    )
}

fn table(ran: &[Ran]) -> String {
    let mut s = format!(
        "{:<24} {:>5} {:>10} {:>10} {:>10} {:>10} {:>9} {:>9}\n",
        "run", "ranks", "ms/step", "part+mig", "wait", "detect", "imbal", "ghosts"
    );
    for r in ran {
        writeln!(
            s,
            "{:<24} {:>5} {:>10.3} {:>10.4} {:>10.4} {:>10.3} {:>9.3} {:>9.0}",
            r.spec.label,
            r.spec.ranks,
            1e3 * r.summary["seconds_per_step"].as_f64().unwrap_or(0.0),
            1e3 * (mean(r, "partition_seconds") + mean(r, "migration_seconds")),
            1e3 * mean(r, "wait_seconds"),
            1e3 * (mean(r, "local_detection_seconds") + mean(r, "ghost_detection_seconds")),
            mean_imbalance(r),
            mean(r, "ghosts_received"),
        )
        .expect("string");
    }
    s
}

struct Model {
    csv: String,
    verdict: String,
}

/// The cost model t(K) = t0 + C/K + β (I(K) − 1): C, the measured seconds
/// of one repartitioning (partition and migration), amortised over K steps;
/// I(K), the measured mean imbalance of the ranks' busy time at that K, costing
/// β seconds per step per unit of imbalance. t0 and β are fitted by least
/// squares to the measured step times; the model's best K is compared with
/// the measured best.
fn cost_model(ran: &[Ran]) -> Model {
    let k_of = |r: &Ran| r.spec.args[1].parse::<f64>().unwrap_or(0.0);
    let repartitioning: Vec<f64> = ran
        .iter()
        .filter(|r| k_of(r) > 0.0)
        .map(|r| (mean(r, "partition_seconds") + mean(r, "migration_seconds")) * k_of(r))
        .collect();
    let c = repartitioning.iter().sum::<f64>() / repartitioning.len().max(1) as f64;
    let inv = |r: &Ran| if k_of(r) > 0.0 { 1.0 / k_of(r) } else { 0.0 };
    // y = t − C/K = t0 + β x, x = I − 1.
    let pts: Vec<(f64, f64)> = ran
        .iter()
        .map(|r| {
            let t = r.summary["seconds_per_step"].as_f64().unwrap_or(0.0);
            (mean_imbalance(r) - 1.0, t - c * inv(r))
        })
        .collect();
    let n = pts.len() as f64;
    let (mx, my) = (
        pts.iter().map(|p| p.0).sum::<f64>() / n,
        pts.iter().map(|p| p.1).sum::<f64>() / n,
    );
    let sxx: f64 = pts.iter().map(|p| (p.0 - mx).powi(2)).sum();
    let sxy: f64 = pts.iter().map(|p| (p.0 - mx) * (p.1 - my)).sum();
    let beta = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let t0 = my - beta * mx;
    let mut csv = String::from(
        "label,K,measured_seconds_per_step,predicted_seconds_per_step,busy_imbalance_mean\n",
    );
    let mut best = (f64::INFINITY, String::new());
    let mut measured_best = (f64::INFINITY, String::new());
    for r in ran {
        let t = r.summary["seconds_per_step"].as_f64().unwrap_or(0.0);
        let p = t0 + c * inv(r) + beta * (mean_imbalance(r) - 1.0);
        writeln!(
            csv,
            "{},{},{t:e},{p:e},{}",
            r.spec.label,
            k_of(r),
            mean_imbalance(r)
        )
        .expect("string");
        if p < best.0 {
            best = (p, r.spec.label.clone());
        }
        if t < measured_best.0 {
            measured_best = (t, r.spec.label.clone());
        }
    }
    let verdict = format!(
        "cost model: one repartitioning costs {:.3} ms, a unit of imbalance {:.3} ms per step (fitted), \
         base {:.3} ms per step; the model recommends {}, the measured best is {}{}",
        1e3 * c,
        1e3 * beta,
        1e3 * t0,
        best.1,
        measured_best.1,
        if best.1 == measured_best.1 { " (they agree)" } else { " (they differ: see model.csv)" }
    );
    Model { csv, verdict }
}
