//! `tridem study NAME`: questions a DEM user asks before spending an
//! allocation, answered on real distributed runs of a scene. Each study
//! starts its runs under mpirun (`$MPIRUN`, default `mpirun`, with
//! `$MPIRUN_ARGS`, default `--oversubscribe`; `MPIRUN=srun` inside a SLURM
//! allocation, with `--mpi=pmix` unless `$TRIDEM_SRUN_MPI` says), keeps every run's metrics
//! (`DIR/runs/LABEL-rN.jsonl`), writes one summary CSV and its figures (SVG
//! and PNG), and prints a short table.
//!
//! Every setting runs `--repeat` times, the settings taken in turn (ABCABC:
//! a drift of the machine spreads over all of them); the tables give the
//! median and the least and most, the figures error bars. Each timing study
//! runs its first setting twice under two labels: the difference between the
//! two is its *noise floor*, and a difference between settings inside it is
//! reported as none.

use crate::cli::{StudyArgs, StudyName};
use crate::error::{create_output_dir, CliError, CliResult};
use crate::plot::{bars, lines, Bar, BarSeries, Look, Series};
use distributed::Exchange;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

/// One setting of a study.
#[derive(Debug, Clone)]
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

/// A setting's runs.
pub(crate) struct Group {
    pub spec: Spec,
    pub runs: Vec<Ran>,
}

/// The median of a setting's runs, with the least and the most.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Stat {
    pub median: f64,
    pub lo: f64,
    pub hi: f64,
}

impl Stat {
    pub fn of(mut v: Vec<f64>) -> Stat {
        v.sort_by(f64::total_cmp);
        let n = v.len();
        let median = match n {
            0 => 0.0,
            _ if n % 2 == 1 => v[n / 2],
            _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
        };
        Stat {
            median,
            lo: v.first().copied().unwrap_or(0.0),
            hi: v.last().copied().unwrap_or(0.0),
        }
    }

    pub fn bar(&self, x: f64, scale: f64) -> Bar {
        Bar {
            x,
            median: scale * self.median,
            lo: scale * self.lo,
            hi: scale * self.hi,
        }
    }
}

impl Group {
    pub fn stat(&self, value: impl Fn(&Ran) -> f64) -> Stat {
        Stat::of(self.runs.iter().map(value).collect())
    }
}

/// The label of the setting that repeats the first one, for the noise floor.
pub(crate) fn again(label: &str) -> String {
    format!("{label}-again")
}

/// The noise floor of a timing study: how far apart two groups of the same
/// setting measured (the relative difference of their medians), at least
/// half the relative spread of either.
pub(crate) fn noise_floor(groups: &[Group], value: impl Fn(&Ran) -> f64) -> Option<f64> {
    let first = groups.first()?;
    let twin = groups
        .iter()
        .find(|g| g.spec.label == again(&first.spec.label))?;
    Some(floor_between(first, twin, value))
}

/// The noise floor of two settings that do the same work: the gap between
/// their medians, or half the spread of either's runs, relative to the
/// first's median, whichever is largest.
pub(crate) fn floor_between(first: &Group, twin: &Group, value: impl Fn(&Ran) -> f64) -> f64 {
    let (a, b) = (first.stat(&value), twin.stat(&value));
    let rel = |s: &Stat| (s.hi - s.lo) / (2.0 * s.median);
    ((a.median - b.median).abs() / a.median)
        .max(rel(&a))
        .max(rel(&b))
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
    let scene = args.scene();
    if !scene.exists() {
        return Err(CliError::input(format!(
            "{}: no such scene",
            scene.display()
        )));
    }
    let mut specs = if args.name.distributed() {
        specs(args)
    } else {
        crate::study_node::specs(args)?
    };
    if args.name != StudyName::Accuracy {
        // The first setting again, under another label: the noise floor.
        let mut twin = specs[0].clone();
        twin.label = again(&twin.label);
        twin.series = "noise floor".into();
        specs.push(twin);
    }
    create_output_dir(&dir.join("runs"))?;
    let resume_from = settle(args, &dir)?;
    let mut groups: Vec<Group> = specs
        .iter()
        .map(|s| Group {
            spec: s.clone(),
            runs: Vec::new(),
        })
        .collect();
    let total = args.repeat as usize * specs.len();
    for rep in 0..args.repeat as usize {
        for (k, spec) in specs.iter().enumerate() {
            let start = Instant::now();
            let r = run_one(args, &dir, spec.clone(), rep, resume_from.as_deref())?;
            eprintln!(
                "[{}/{total}] {:<24} {:>7.2} s",
                rep * specs.len() + k + 1,
                r.spec.label,
                start.elapsed().as_secs_f64()
            );
            groups[k].runs.push(r);
        }
    }
    if !args.name.distributed() {
        return crate::study_node::report(args, &dir, &groups);
    }
    write(&dir.join("summary.csv"), &summary_csv(&groups))?;
    figures(args, &dir, &groups)?;
    print!("{}", table(&groups));
    if let Some(floor) = noise_floor(&groups, seconds_per_step) {
        println!(
            "noise floor: {:.1}% of the time per step (the same setting under two labels)",
            100.0 * floor
        );
        println!("{}", finding(&groups, seconds_per_step, floor));
    }
    if args.name == StudyName::RepartitionFrequency {
        let model = cost_model(args, &groups);
        write(&dir.join("model.csv"), &model.csv)?;
        println!("{}", model.verdict);
    }
    println!("data and figures in {}", dir.display());
    Ok(())
}

/// What a timing study found, in a sentence: the fastest setting (by
/// median), the settings within the noise floor of it (no difference), and
/// how much slower the others are.
pub(crate) fn finding(groups: &[Group], time: impl Fn(&Ran) -> f64, floor: f64) -> String {
    let settings: Vec<(&Group, f64)> = groups
        .iter()
        .filter(|g| g.spec.series != "noise floor")
        .map(|g| (g, g.stat(&time).median))
        .collect();
    let Some(&(best, t)) = settings.iter().min_by(|a, b| a.1.total_cmp(&b.1)) else {
        return String::new();
    };
    let (mut same, mut slower) = (Vec::new(), Vec::new());
    for &(g, u) in &settings {
        if std::ptr::eq(g, best) {
            continue;
        }
        let gap = (u - t) / t;
        if gap <= floor {
            same.push(g.spec.label.clone());
        } else {
            slower.push(format!("{} +{:.0}%", g.spec.label, 100.0 * gap));
        }
    }
    let list = |v: &[String]| {
        if v.is_empty() {
            "none".into()
        } else {
            v.join(", ")
        }
    };
    format!(
        "found: fastest {} ({:.3} ms per step, median of {} runs); no difference beyond the \
         noise floor ({:.1}%): {}; slower: {}",
        best.spec.label,
        1e3 * t,
        best.runs.len(),
        100.0 * floor,
        list(&same),
        list(&slower)
    )
}

pub(crate) fn seconds_per_step(r: &Ran) -> f64 {
    r.summary["seconds_per_step"].as_f64().unwrap_or(0.0)
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
                series: "every K steps".into(),
            })
            .chain(args.when.iter().map(|&tau| Spec {
                label: format!("when-{tau}"),
                ranks,
                threads,
                args: s(&[
                    "--repartition-every",
                    "0",
                    "--repartition-when",
                    &tau.to_string(),
                ]),
                x: tau,
                series: "when imbalanced".into(),
            }))
            .collect(),
        StudyName::Partitioners => partition::Backend::ALL
            .iter()
            .map(|b| b.name())
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
                Exchange::ALL.iter().map(move |&(_, mode)| Spec {
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

/// With --settle: runs the scene that many steps once, with brute force on
/// every core, into DIR/settled, and returns the checkpoint every run of
/// the study resumes from.
fn settle(args: &StudyArgs, dir: &Path) -> CliResult<Option<PathBuf>> {
    let steps = args.settle();
    if steps == 0 {
        return Ok(None);
    }
    let out = dir.join("settled");
    let exe = std::env::current_exe().map_err(|e| CliError::runtime(e.to_string()))?;
    let started = Instant::now();
    let done = Command::new(exe)
        .arg("run")
        .arg(args.scene())
        .args(["--steps", &steps.to_string(), "--quiet", "--overwrite"])
        .args(["--set", "kernel.method=brute", "--output"])
        .arg(&out)
        .output()
        .map_err(|e| CliError::runtime(format!("cannot start the settling run: {e}")))?;
    if !done.status.success() {
        return Err(CliError::runtime(format!(
            "the settling run ({steps} steps) failed ({}): {}",
            done.status,
            String::from_utf8_lossy(&done.stderr).trim()
        )));
    }
    eprintln!(
        "settled: {steps} steps in {:.1} s; every run resumes from {}",
        started.elapsed().as_secs_f64(),
        out.join("checkpoint.h5").display()
    );
    Ok(Some(out.join("checkpoint.h5")))
}

/// Runs one run of a study (under the launcher when distributed, with
/// metrics; on one node directly, keeping its output for its final state)
/// and reads its summary and metrics. With `start`, the run resumes from
/// that checkpoint into a directory of its own, made afresh.
fn run_one(
    args: &StudyArgs,
    dir: &Path,
    spec: Spec,
    rep: usize,
    start: Option<&Path>,
) -> CliResult<Ran> {
    let metrics = dir
        .join("runs")
        .join(format!("{}-r{rep}.jsonl", spec.label));
    let scene = args.scene();
    let exe = std::env::current_exe().map_err(|e| CliError::runtime(e.to_string()))?;
    let launcher = std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into());
    let own = dir.join("runs").join(&spec.label);
    let mut command = if spec.ranks == 1 {
        let mut c = Command::new(&exe);
        c.arg("run").arg(&scene).arg("--output").arg(&own);
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
            .arg(&scene)
            .args(["--metrics-every", &args.metrics_every.to_string()])
            .arg("--metrics")
            .arg(&metrics);
        c
    };
    if let Some(from) = start {
        // A resumed run appends to the output in its directory: each
        // repeat starts from an empty one.
        if own.exists() {
            std::fs::remove_dir_all(&own)
                .map_err(|e| CliError::runtime(format!("{}: {e}", own.display())))?;
        }
        if spec.ranks > 1 {
            command.arg("--output").arg(&own);
        }
        command.arg("--resume").arg(from);
    }
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

/// A per-step metric's mean over ranks in a run's summary.
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

/// The mean imbalance of the ranks' busy seconds over the run's intervals:
/// what a rank that keeps its particles between repartitionings drifts
/// into (the imbalance of the whole run's sums would let intervals where
/// different ranks are busier cancel).
fn busy_imbalance(r: &Ran) -> f64 {
    mean_of_lines(r, "busy_imbalance")
}

/// The settings of the "every K steps" series, with their K (never: 0).
fn k_of(g: &Group) -> Option<u64> {
    let a = &g.spec.args;
    let k = a.iter().position(|x| x == "--repartition-every")?;
    if a.iter().any(|x| x == "--repartition-when") {
        return None;
    }
    a.get(k + 1)?.parse().ok()
}

fn summary_csv(groups: &[Group]) -> String {
    let mut s = String::from(
        "label,series,ranks,setting,repeats,seconds_per_step_median,seconds_per_step_min,\
         seconds_per_step_max,busy_imbalance_median,busy_imbalance_min,busy_imbalance_max,\
         triangle_imbalance_median,max_wait_seconds_median",
    );
    for m in MEANS {
        write!(s, ",{m}_median").expect("string");
    }
    s.push('\n');
    for g in groups {
        let t = g.stat(seconds_per_step);
        let b = g.stat(busy_imbalance);
        let wait = g.stat(|r| {
            r.summary["per_step_over_ranks"]["wait_seconds"]["max"]
                .as_f64()
                .unwrap_or(0.0)
        });
        write!(
            s,
            "{},{},{},{},{},{:e},{:e},{:e},{},{},{},{},{:e}",
            g.spec.label,
            g.spec.series,
            g.spec.ranks,
            g.spec.x,
            g.runs.len(),
            t.median,
            t.lo,
            t.hi,
            b.median,
            b.lo,
            b.hi,
            g.stat(|r| mean_of_lines(r, "triangle_imbalance")).median,
            wait.median,
        )
        .expect("string");
        for m in MEANS {
            write!(s, ",{:e}", g.stat(|r| mean(r, m)).median).expect("string");
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

type PlotResult = Result<(), Box<dyn std::error::Error>>;

fn figures(args: &StudyArgs, dir: &Path, groups: &[Group]) -> CliResult {
    let scene = args
        .scene()
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().into_owned());
    match args.name {
        StudyName::RepartitionFrequency => repartition_figures(args, dir, groups, &scene),
        StudyName::Partitioners => partitioner_figures(args, dir, groups, &scene),
        StudyName::Exchange => exchange_figures(args, dir, groups, &scene),
        StudyName::Scheduling | StudyName::Accuracy => unreachable!("runs on one node"),
    }
    .map_err(|e| CliError::runtime(format!("plot: {e}")))
}

/// One bar series per setting, at x = its place among `groups` (the
/// figure's ticks name them).
fn per_setting(groups: &[Group], value: impl Fn(&Ran) -> f64, scale: f64) -> Vec<BarSeries> {
    groups
        .iter()
        .enumerate()
        .map(|(k, g)| BarSeries {
            name: g.spec.label.clone(),
            bars: vec![g.stat(&value).bar(k as f64, scale)],
        })
        .collect()
}

/// A metric over the steps of each setting's first run: imbalances as they
/// are, other fields per step and times `scale`.
fn over_steps(groups: &[Group], field: &str, scale: f64, metrics_every: u64) -> Vec<Series> {
    groups
        .iter()
        .filter_map(|g| g.runs.first())
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
            errors: Vec::new(),
        })
        .collect()
}

/// The figures every distributed timing study draws, one bar per setting:
/// time per step, busy imbalance, particles migrated; and the busy
/// imbalance over the steps.
fn setting_figures(args: &StudyArgs, dir: &Path, groups: &[Group], what: &str) -> PlotResult {
    let x = "setting (legend)";
    bars(
        &dir.join("step-time.svg"),
        &format!(
            "{what}: ms per step, median of {} runs, min-max",
            args.repeat
        ),
        (x, "ms per step"),
        &per_setting(groups, seconds_per_step, 1e3),
        Look::default(),
    )?;
    bars(
        &dir.join("busy-imbalance.svg"),
        &format!("{what}: busy imbalance, mean over the run's intervals"),
        (x, "busy imbalance (max/mean)"),
        &per_setting(groups, busy_imbalance, 1.0),
        Look {
            y_from: Some(1.0),
            ..Look::default()
        },
    )?;
    bars(
        &dir.join("migration.svg"),
        &format!("{what}: particles migrated per step"),
        (x, "particles migrated per step (sum over ranks)"),
        &per_setting(groups, |r| mean(r, "migrated_bodies") * ranks(r), 1.0),
        Look::default(),
    )?;
    lines(
        &dir.join("imbalance.svg"),
        &format!("{what}: busy imbalance over the run (first run of each setting)"),
        ("step", "busy imbalance (max/mean)"),
        &over_steps(groups, "busy_imbalance", 1.0, args.metrics_every),
        Look {
            y_from: Some(1.0),
            ..Look::default()
        },
    )
}

fn ranks(r: &Ran) -> f64 {
    r.summary["ranks"].as_f64().unwrap_or(1.0)
}

/// The setting figures, and time per step by section against K.
fn repartition_figures(args: &StudyArgs, dir: &Path, groups: &[Group], scene: &str) -> PlotResult {
    let what = format!("{scene}, {} ranks", args.ranks[0]);
    setting_figures(args, dir, groups, &what)?;
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
        (
            "waits for other ranks",
            &["reduce_seconds", "return_wait_seconds"],
        ),
    ];
    let every: Vec<&Group> = groups
        .iter()
        .filter(|g| k_of(g).is_some() && g.spec.series != "noise floor")
        .collect();
    let series: Vec<BarSeries> = sections
        .iter()
        .map(|(name, fields)| BarSeries {
            name: name.to_string(),
            bars: every
                .iter()
                .map(|g| {
                    g.stat(|r| fields.iter().map(|f| mean(r, f)).sum::<f64>())
                        .bar(g.spec.x, 1e3)
                })
                .collect(),
        })
        .collect();
    bars(
        &dir.join("sections.svg"),
        &format!(
            "{what}: ms per step by section against K (never at K = {})",
            args.steps()
        ),
        ("repartition every K steps", "ms per step (mean over ranks)"),
        &series,
        Look {
            log_x: true,
            ..Look::default()
        },
    )
}

fn partitioner_figures(args: &StudyArgs, dir: &Path, groups: &[Group], scene: &str) -> PlotResult {
    let what = format!(
        "{scene}, {} ranks, repartition every {}",
        args.ranks[0], args.repartition_every
    );
    setting_figures(args, dir, groups, &what)
}

/// The wait for ghosts and the step time against the ranks, both exchanges.
fn exchange_figures(args: &StudyArgs, dir: &Path, groups: &[Group], scene: &str) -> PlotResult {
    let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
    let mut series = Vec::new();
    for &(_, mode) in Exchange::ALL {
        for (what, field) in [("wait", "wait_seconds"), ("step", "step_seconds")] {
            series.push(BarSeries {
                name: format!("{mode}: {what}"),
                bars: groups
                    .iter()
                    .filter(|g| g.spec.series == mode)
                    .map(|g| g.stat(|r| mean(r, field)).bar(g.spec.x, 1e3))
                    .collect(),
            });
        }
    }
    let caption = format!(
        "{scene}: ghost exchange, median of {} runs ({cores} cores: more ranks are oversubscribed)",
        args.repeat
    );
    bars(
        &dir.join("exchange.svg"),
        &caption,
        ("ranks", "ms per step (mean over ranks)"),
        &series,
        Look::default(),
    )
}

fn table(groups: &[Group]) -> String {
    let mut s = format!(
        "{:<24} {:>5} {:>24} {:>10} {:>10} {:>10} {:>18} {:>9}\n",
        "run",
        "ranks",
        "ms/step [min, max]",
        "part+mig",
        "wait",
        "detect",
        "busy imbalance",
        "ghosts"
    );
    for g in groups {
        let t = g.stat(seconds_per_step);
        let b = g.stat(busy_imbalance);
        writeln!(
            s,
            "{:<24} {:>5} {:>8.3} [{:.3}, {:.3}] {:>10.4} {:>10.4} {:>10.3} {:>6.3} [{:.2}, {:.2}] {:>9.0}",
            g.spec.label,
            g.spec.ranks,
            1e3 * t.median,
            1e3 * t.lo,
            1e3 * t.hi,
            1e3 * g.stat(|r| mean(r, "partition_seconds") + mean(r, "migration_seconds")).median,
            1e3 * g.stat(|r| mean(r, "wait_seconds")).median,
            1e3 * g
                .stat(|r| mean(r, "local_detection_seconds") + mean(r, "ghost_detection_seconds"))
                .median,
            b.median,
            b.lo,
            b.hi,
            g.stat(|r| mean(r, "ghosts_received")).median,
        )
        .expect("string");
    }
    s
}

struct Model {
    csv: String,
    verdict: String,
}

/// A model of the time per step against the repartitioning interval K,
/// fitted to the two extremes (every step, never) and asked about the
/// settings between, which it was not fitted to:
///
///   t(K) = t0 + c/K + β r K/2
///
/// c: the measured cost of one repartitioning at K = the smallest K;
/// t0 = t(smallest K) − c/K: a step with the ranks balanced; r: how fast
/// the busy imbalance grows after a repartitioning, per step, from the
/// never-repartitioned run (its mean imbalance over S steps, 1 + r S/2);
/// β: what a unit of imbalance costs per step, from the same run. Every
/// rate is fitted as non-negative. Its best K, √(2c/(β r)), is compared with
/// the measured best: within the noise floor, or not.
fn cost_model(args: &StudyArgs, groups: &[Group]) -> Model {
    let every: Vec<&Group> = groups
        .iter()
        .filter(|g| k_of(g).is_some() && g.spec.series != "noise floor")
        .collect();
    let first = every
        .iter()
        .filter(|g| k_of(g) > Some(0))
        .min_by_key(|g| k_of(g));
    let never = every.iter().find(|g| k_of(g) == Some(0));
    let (Some(first), Some(never)) = (first, never) else {
        return Model {
            csv: String::new(),
            verdict: "cost model: needs a K > 0 and never (0) among --every".into(),
        };
    };
    let k1 = k_of(first).unwrap_or(1) as f64;
    let steps = args.steps() as f64;
    let per_repartition = |g: &Group, k: f64| {
        g.stat(|r| (mean(r, "partition_seconds") + mean(r, "migration_seconds")) * k)
            .median
    };
    let c = per_repartition(first, k1).max(0.0);
    let t0 = (first.stat(seconds_per_step).median - c / k1).max(0.0);
    let i_never = never.stat(busy_imbalance).median;
    let t_never = never.stat(seconds_per_step).median;
    let r = (2.0 * (i_never - 1.0) / steps).max(0.0);
    let beta = if i_never > 1.0 {
        ((t_never - t0) / (i_never - 1.0)).max(0.0)
    } else {
        0.0
    };
    let predict = |k: f64| {
        if k <= 0.0 || k >= steps {
            t0 + beta * (i_never - 1.0)
        } else {
            t0 + c / k + beta * r * k / 2.0
        }
    };
    let floor = noise_floor(groups, seconds_per_step).unwrap_or(0.0);
    let mut csv = String::from(
        "label,K,measured_median,measured_min,measured_max,predicted,\
         per_repartition_seconds,busy_imbalance_median,fitted_to\n",
    );
    for g in &every {
        let k = k_of(g).unwrap_or(0) as f64;
        let t = g.stat(seconds_per_step);
        let fitted = std::ptr::eq(*g, *first) || std::ptr::eq(*g, *never);
        writeln!(
            csv,
            "{},{k},{:e},{:e},{:e},{:e},{:e},{},{}",
            g.spec.label,
            t.median,
            t.lo,
            t.hi,
            predict(k),
            if k > 0.0 { per_repartition(g, k) } else { 0.0 },
            g.stat(busy_imbalance).median,
            fitted
        )
        .expect("string");
    }
    let by = |f: &dyn Fn(&Group) -> f64| {
        every
            .iter()
            .min_by(|a, b| f(a).total_cmp(&f(b)))
            .copied()
            .expect("settings")
    };
    let model_best = by(&|g| predict(k_of(g).unwrap_or(0) as f64));
    let measured_best = by(&|g| g.stat(seconds_per_step).median);
    let (tm, tb) = (
        model_best.stat(seconds_per_step).median,
        measured_best.stat(seconds_per_step).median,
    );
    let gap = (tm - tb) / tb;
    let k_star = if beta * r > 0.0 {
        format!("{:.0}", (2.0 * c / (beta * r)).sqrt())
    } else {
        "none (imbalance costs nothing measurable)".into()
    };
    let verdict = format!(
        "cost model (fitted to {} and never, predicting the others): one repartitioning \
         {:.3} ms, a balanced step {:.3} ms, imbalance growing {:.2e} per step, costing \
         {:.3} ms per step per unit; its best K is {k_star}, among the settings {}; measured \
         best {}. {}",
        first.spec.label,
        1e3 * c,
        1e3 * t0,
        r,
        1e3 * beta,
        model_best.spec.label,
        measured_best.spec.label,
        if gap <= floor {
            format!(
                "The model's choice is within the noise floor ({:.1}%) of the measured best: it predicts.",
                100.0 * floor
            )
        } else {
            format!(
                "The model's choice is {:.1}% slower than the measured best, beyond the noise floor \
                 ({:.1}%): it does not predict the best setting.",
                100.0 * gap,
                100.0 * floor
            )
        }
    );
    Model { csv, verdict }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A setting whose runs took `times` milliseconds per step.
    fn group(label: &str, series: &str, times: &[f64]) -> Group {
        let spec = Spec {
            label: label.into(),
            ranks: 2,
            threads: 1,
            args: Vec::new(),
            x: 0.0,
            series: series.into(),
        };
        let runs = times
            .iter()
            .map(|&t| Ran {
                spec: spec.clone(),
                summary: serde_json::json!({ "seconds_per_step": 1e-3 * t }),
                lines: Vec::new(),
            })
            .collect();
        Group { spec, runs }
    }

    #[test]
    fn the_floor_is_the_gap_between_twins_or_their_spread() {
        // Medians 1.00 and 1.03 (3% apart); spreads 2% and 1% of the median.
        let groups = [
            group("a", "s", &[0.98, 1.0, 1.02]),
            group("b", "s", &[2.0, 2.0, 2.0]),
            group("a-again", "noise floor", &[1.02, 1.03, 1.04]),
        ];
        let floor = noise_floor(&groups, seconds_per_step).unwrap();
        assert!((floor - 0.03).abs() < 1e-12, "{floor}");
        // Wide spread dominates a small gap.
        let groups = [
            group("a", "s", &[0.5, 1.0, 1.5]),
            group("a-again", "noise floor", &[1.0, 1.0, 1.0]),
        ];
        assert!((noise_floor(&groups, seconds_per_step).unwrap() - 0.5).abs() < 1e-12);
    }

    #[test]
    fn a_finding_separates_settings_within_the_floor_from_slower_ones() {
        let groups = [
            group("a", "s", &[1.00, 1.00, 1.00]),
            group("b", "s", &[1.02, 1.02, 1.02]),
            group("c", "s", &[1.50, 1.50, 1.50]),
            group("a-again", "noise floor", &[0.90, 0.90, 0.90]),
        ];
        let text = finding(&groups, seconds_per_step, 0.03);
        assert!(text.starts_with("found: fastest a (1.000 ms"), "{text}");
        assert!(text.contains("noise floor (3.0%): b;"), "{text}");
        assert!(text.contains("slower: c +50%"), "{text}");
        // The twin measures the floor; it is not a setting.
        assert!(!text.contains("a-again"), "{text}");
    }
}
