//! The studies of distributed runs: their settings, summary CSV, figures,
//! table and, for the repartition frequency, the cost model.

use super::common::{finding, noise_floor, seconds_per_step, write, Group, Ran, Spec};
use crate::cli::{StudyArgs, StudyName};
use crate::error::{CliError, CliResult};
use crate::plot::{bars, lines, BarSeries, Look, Series};
use distributed::Exchange;
use serde_json::Value;
use std::fmt::Write as _;
use std::path::Path;

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

pub(super) fn specs(args: &StudyArgs) -> Vec<Spec> {
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

/// A per-step metric's mean over ranks in a run's summary.
pub(super) fn mean(r: &Ran, field: &str) -> f64 {
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
pub(super) fn busy_imbalance(r: &Ran) -> f64 {
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

/// The distributed studies' report: the summary CSV, the figures, the
/// table with the noise floor and the finding, and for the repartition
/// frequency, the cost model.
pub(super) fn report(args: &StudyArgs, dir: &Path, groups: &[Group]) -> CliResult {
    write(&dir.join("summary.csv"), &summary_csv(groups))?;
    figures(args, dir, groups)?;
    print!("{}", table(groups));
    if let Some(floor) = noise_floor(groups, seconds_per_step) {
        println!(
            "noise floor: {:.1}% of the time per step (the same setting under two labels)",
            100.0 * floor
        );
        println!("{}", finding(groups, seconds_per_step, floor));
    }
    if args.name == StudyName::RepartitionFrequency {
        let model = super::model::fit(groups, args.steps() as f64, k_of);
        write(&dir.join("model.csv"), &model.csv)?;
        println!("{}", model.verdict);
    }
    println!("data and figures in {}", dir.display());
    Ok(())
}
