//! The studies that run on one node, started directly: thread scheduling
//! and what the kernel's accuracy costs. Each run keeps its output
//! (`DIR/runs/LABEL/`), whose final checkpoint gives the state compared
//! with the study's reference run.

use super::common::{finding, floor_between, noise_floor, write, Group, Ran, Spec, Stat};
use crate::checkpoint_file;
use crate::cli::{StudyArgs, StudyName};
use crate::error::{CliError, CliResult};
use crate::plot::{bars, labelled_points, BarSeries, Labelled, Look};
use dem::distance::Schedule;
use dem::effects::GravityParams;
use dem::scene::Scene;
use std::fmt::Write as _;
use std::path::Path;

/// The two fallbacks of the hybrid kernel: the published one (the whole
/// batch of a pair Newton did not certify) and only the failed pairs.
const FALLBACKS: [(&str, &str); 2] = [("whole-batch", "false"), ("failed-pairs", "true")];

pub(super) fn specs(args: &StudyArgs) -> CliResult<Vec<Spec>> {
    let set = |v: &[String]| {
        v.iter()
            .flat_map(|o| ["--set".to_string(), o.clone()])
            .collect()
    };
    Ok(match args.name {
        StudyName::Scheduling => {
            let cores = std::thread::available_parallelism().map_or(1, |n| n.get());
            let threads = if args.threads.is_empty() {
                (1..=cores).collect()
            } else {
                args.threads.clone()
            };
            let mut specs = Vec::new();
            for (fallback, failed_pairs) in FALLBACKS {
                for &(_, schedule) in Schedule::ALL {
                    for &t in &threads {
                        specs.push(Spec {
                            label: format!("{schedule}-{fallback}-{t}"),
                            ranks: 1,
                            threads: t,
                            args: set(&[
                                "kernel.method=hybrid".into(),
                                format!("kernel.schedule={schedule}"),
                                format!("kernel.fallback_failed_pairs={failed_pairs}"),
                            ]),
                            x: t as f64,
                            series: format!("{schedule}, {fallback}"),
                        });
                    }
                }
            }
            specs
        }
        StudyName::Accuracy => {
            let scene = Scene::load(&args.scene()).map_err(|e| CliError::input(e.to_string()))?;
            let threads = args.threads.first().copied().unwrap_or(1);
            // Fifty output steps or so, for the energy books' drift.
            let every = format!("simulation.output_every={}", (args.steps() / 50).max(1));
            accuracy_settings(&scene)
                .into_iter()
                .map(|(label, mut sets)| Spec {
                    label: label.to_string(),
                    ranks: 1,
                    threads,
                    args: set(&{
                        sets.push(every.clone());
                        sets
                    }),
                    x: 0.0,
                    series: label.to_string(),
                })
                .collect()
        }
        _ => unreachable!("distributed studies"),
    })
}

/// The kernel settings of the accuracy study, the reference first. The
/// second run is the reference with gravity (or, in a scene without it, the
/// time step, which a resumed run cannot change) scaled by 1 + 1e-14: how
/// far trajectories part from a change at the level of rounding alone, the
/// floor under which no kernel's error can be told from chaos.
fn accuracy_settings(scene: &Scene) -> Vec<(&'static str, Vec<String>)> {
    let v = |x: &[&str]| x.iter().map(|s| format!("kernel.{s}")).collect::<Vec<_>>();
    let mut floor = v(&["method=brute"]);
    let scaled = 1.0 + 1e-14;
    let label = match scene.effects.get::<GravityParams>() {
        Some(g) => {
            let g = g.g.map(|c| format!("{:?}", c * scaled)).join(", ");
            floor.push(format!("effects.gravity={{ g = [{g}] }}"));
            "brute-g+1e-14"
        }
        None => {
            floor.push(format!("simulation.dt={:?}", scene.dt * scaled));
            "brute-dt+1e-14"
        }
    };
    vec![
        ("brute", v(&["method=brute"])),
        (label, floor),
        (
            "penalty-1it",
            v(&["method=penalty", "iterations=1", "finish_rounds=0"]),
        ),
        (
            "penalty-2it",
            v(&["method=penalty", "iterations=2", "finish_rounds=0"]),
        ),
        (
            "penalty-4it",
            v(&["method=penalty", "iterations=4", "finish_rounds=0"]),
        ),
        (
            "penalty-4it-finish",
            v(&["method=penalty", "iterations=4", "finish_rounds=1"]),
        ),
        (
            "hybrid-whole-batch",
            v(&["method=hybrid", "fallback_failed_pairs=false"]),
        ),
        (
            "hybrid-failed-pairs",
            v(&["method=hybrid", "fallback_failed_pairs=true"]),
        ),
        (
            "hybrid-batch4",
            v(&["method=hybrid", "fallback_failed_pairs=true", "batch=4"]),
        ),
        (
            "hybrid-batch16",
            v(&["method=hybrid", "fallback_failed_pairs=true", "batch=16"]),
        ),
        (
            "hybrid-2it",
            v(&[
                "method=hybrid",
                "fallback_failed_pairs=true",
                "iterations=2",
            ]),
        ),
        (
            "hybrid-tol1e-8",
            v(&[
                "method=hybrid",
                "fallback_failed_pairs=true",
                "tolerance=1e-8",
            ]),
        ),
        (
            "hybrid-tol1e-4",
            v(&[
                "method=hybrid",
                "fallback_failed_pairs=true",
                "tolerance=1e-4",
            ]),
        ),
    ]
}

/// What one setting measured, against the study's reference setting: its
/// first run's state, all its runs' times.
struct Row<'a> {
    ran: &'a Ran,
    repeats: usize,
    seconds_per_step: Stat,
    narrow_idle: f64,
    /// Root mean square and largest distance of the particles' final
    /// positions from the reference run's.
    rms: f64,
    max: f64,
    identical: bool,
    /// The energy books' drift over the run, against its largest kinetic
    /// energy ([`books_drift`](crate::plot_cmd::books_drift)).
    drift: f64,
    /// Contacts deeper than the halos, summed over the steps.
    deep: u64,
}

/// A run's time per step (stepping only).
fn stepping(r: &Ran) -> f64 {
    let s = &r.summary;
    let steps = s["steps"].as_f64().unwrap_or(1.0).max(1.0);
    s["stepping_seconds"].as_f64().unwrap_or(0.0) / steps
}

fn rows<'a>(
    args: &StudyArgs,
    dir: &Path,
    groups: &'a [Group],
    reference: &dyn Fn(&Group) -> &'a Group,
) -> CliResult<Vec<Row<'a>>> {
    let scene = Scene::load(&args.scene()).map_err(|e| CliError::input(e.to_string()))?;
    let moves: Vec<bool> = scene.world.bodies.iter().map(|b| !b.is_static()).collect();
    let state = |r: &Ran| {
        checkpoint_file::read(&dir.join("runs").join(&r.spec.label).join("checkpoint.h5"))
    };
    groups
        .iter()
        .map(|g| {
            let r = &g.runs[0];
            let (a, b) = (state(r)?, state(&reference(g).runs[0])?);
            let moving: Vec<f64> = a
                .bodies
                .iter()
                .zip(&b.bodies)
                .zip(&moves)
                .filter(|(_, &m)| m)
                .map(|((x, y), _)| (x.x - y.x).length())
                .collect();
            let n = moving.len().max(1) as f64;
            let drift = crate::plot_cmd::books_drift(&dir.join("runs").join(&r.spec.label))?;
            let s = &r.summary;
            let narrow = s["section_seconds"]["narrow_phase"].as_f64().unwrap_or(0.0);
            let busy = s["narrow_phase_busy_thread_seconds"]
                .as_f64()
                .unwrap_or(0.0);
            let threads = s["threads"].as_f64().unwrap_or(1.0);
            Ok(Row {
                ran: r,
                repeats: g.runs.len(),
                seconds_per_step: g.stat(stepping),
                narrow_idle: if narrow > 0.0 {
                    1.0 - busy / (threads * narrow)
                } else {
                    0.0
                },
                rms: (moving.iter().map(|d| d * d).sum::<f64>() / n).sqrt(),
                max: moving.iter().copied().fold(0.0, f64::max),
                identical: a.bodies == b.bodies,
                drift,
                deep: s["deep_contacts"].as_u64().unwrap_or(0),
            })
        })
        .collect()
}

pub(super) fn report(args: &StudyArgs, dir: &Path, groups: &[Group]) -> CliResult {
    let first = &groups[0];
    let rows = match args.name {
        // Each schedule against one thread of the same fallback: are the
        // answers independent of the threads?
        StudyName::Scheduling => rows(args, dir, groups, &|g: &Group| {
            let fallback = g.spec.series.split(", ").nth(1).unwrap_or("");
            groups
                .iter()
                .find(|q| q.spec.series.ends_with(fallback))
                .unwrap_or(first)
        })?,
        _ => rows(args, dir, groups, &|_: &Group| first)?,
    };
    write(&dir.join("summary.csv"), &csv(&rows))?;
    let plot_err = |e: Box<dyn std::error::Error>| CliError::runtime(format!("plot: {e}"));
    let scene = args
        .scene()
        .file_name()
        .map_or(String::new(), |n| n.to_string_lossy().into_owned());
    match args.name {
        StudyName::Scheduling => scheduling_figures(dir, &scene, &rows).map_err(plot_err)?,
        _ => {
            let reference = rows[0].seconds_per_step.median;
            let points: Vec<Labelled> = rows
                .iter()
                .skip(1)
                .map(|r| Labelled {
                    label: r.ran.spec.label.clone(),
                    x: 1e3 * r.seconds_per_step.median,
                    y: r.rms,
                })
                .collect();
            let caption = format!(
                "{scene}, steps {} to {}: deviation from brute force ({:.2} ms per step) against cost",
                args.settle(),
                args.settle() + args.steps(),
                1e3 * reference
            );
            labelled_points(
                &dir.join("accuracy.svg"),
                &caption,
                (
                    "ms per step",
                    "RMS distance of final positions from the brute-force run (m)",
                ),
                &points,
                "on the bottom line: identical to brute force",
            )
            .map_err(plot_err)?;
        }
    }
    print!("{}", table(&rows));
    // The accuracy study's chaos-floor run does brute force's work: the two
    // brute-force runs' times are its noise floor.
    let floor = match (args.name, groups) {
        (StudyName::Accuracy, [brute, twin, ..]) => Some(floor_between(brute, twin, stepping)),
        _ => noise_floor(groups, stepping),
    };
    if let Some(floor) = floor {
        let how = match args.name {
            StudyName::Accuracy => "brute force's two runs",
            _ => "the same setting under two labels",
        };
        println!(
            "noise floor: {:.1}% of the time per step ({how})",
            100.0 * floor
        );
        match args.name {
            StudyName::Accuracy => println!("{}", accuracy_finding(&rows, floor)),
            _ => println!("{}", finding(groups, stepping, floor)),
        }
    }
    if args.name == StudyName::Accuracy {
        println!("{}", exactness(&rows));
    }
    println!("data and figures in {}", dir.display());
    Ok(())
}

/// A run's contacts per step.
fn contacts_per_step(r: &Ran) -> f64 {
    let s = &r.summary;
    s["contacts"].as_f64().unwrap_or(0.0) / s["steps"].as_f64().unwrap_or(1.0).max(1.0)
}

/// What the accuracy study found, in a sentence. A setting that is faster
/// because it misses contacts is no cheaper way to the same answer, so the
/// finding leads with the fastest exact setting (brute force's trajectories
/// bit for bit) against brute force itself, then names each approximate
/// setting faster than it beyond the noise floor `floor`, with what it
/// gives up: the contacts per step it finds of brute force's (the first
/// row), its contacts deeper than the halos, and its deviation in chaos
/// floors (the second row's deviation).
fn accuracy_finding(rows: &[Row], floor: f64) -> String {
    let (Some(brute), Some(chaos)) = (rows.first(), rows.get(1)) else {
        return String::new();
    };
    let time = |r: &Row| r.seconds_per_step.median;
    let Some(best) = rows
        .iter()
        .filter(|r| r.identical)
        .min_by(|a, b| time(a).total_cmp(&time(b)))
    else {
        return "found: no setting gives brute force's trajectories".into();
    };
    let t = time(best);
    let against_brute = if std::ptr::eq(best, brute) {
        "brute force itself".to_string()
    } else {
        let gap = (time(brute) - t) / t;
        if gap <= floor {
            format!(
                "no faster than brute force ({:.3} ms) beyond the noise floor",
                1e3 * time(brute)
            )
        } else {
            format!("brute force takes {:+.0}%", 100.0 * gap)
        }
    };
    let others = other_exact_settings(rows, best, floor);
    let reference = contacts_per_step(brute.ran);
    let faster: Vec<String> = rows
        .iter()
        .skip(2)
        .filter(|r| !r.identical && (t - time(r)) / t > floor)
        .map(|r| {
            format!(
                "{} {:+.0}% ({:.0} of brute force's {:.0} contacts per step, {} deep, {:.1e} chaos \
                 floors of deviation)",
                r.ran.spec.label,
                100.0 * (time(r) - t) / t,
                contacts_per_step(r.ran),
                reference,
                r.deep,
                r.rms / chaos.rms.max(f64::MIN_POSITIVE)
            )
        })
        .collect();
    let faster = if faster.is_empty() {
        "no approximate setting is faster beyond it".to_string()
    } else {
        format!("faster, by giving up contacts: {}", faster.join(", "))
    };
    format!(
        "found: the fastest exact setting is {} ({:.3} ms per step, median of {} runs), \
         {against_brute}{others}; noise floor {:.1}%; {faster}",
        best.ran.spec.label,
        1e3 * t,
        best.repeats,
        100.0 * floor
    )
}

/// The exact settings other than `best`, each with how much longer than it
/// a step takes, or "within the floor" when the gap is inside the noise.
fn other_exact_settings(rows: &[Row], best: &Row, floor: f64) -> String {
    let t = best.seconds_per_step.median;
    let others: Vec<String> = rows
        .iter()
        .filter(|r| r.identical && !std::ptr::eq(*r, best))
        .map(|r| {
            let gap = (r.seconds_per_step.median - t) / t;
            if gap <= floor {
                format!("{} within the floor", r.ran.spec.label)
            } else {
                format!("{} {:+.0}%", r.ran.spec.label, 100.0 * gap)
            }
        })
        .collect();
    if others.is_empty() {
        String::new()
    } else {
        format!("; the other exact settings: {}", others.join(", "))
    }
}

/// What exactness costs, in a sentence: the settings that give brute
/// force's trajectories bit for bit, and of the others the one whose
/// deviation is least, against the chaos floor (the second row).
fn exactness(rows: &[Row]) -> String {
    let exact: Vec<&str> = rows
        .iter()
        .filter(|r| r.identical)
        .map(|r| r.ran.spec.label.as_str())
        .collect();
    let floor = rows.get(1).map_or(0.0, |r| r.rms);
    let closest = rows
        .iter()
        .skip(2)
        .filter(|r| !r.identical)
        .min_by(|a, b| a.rms.total_cmp(&b.rms));
    let approximate = match closest {
        Some(r) => format!(
            "the closest approximate setting, {}, deviates {:.1e} m (RMS), {:.1e} times the chaos \
             floor, with {} deep contacts and books' drift {:.2e}",
            r.ran.spec.label,
            r.rms,
            r.rms / floor.max(f64::MIN_POSITIVE),
            r.deep,
            r.drift
        ),
        None => "no setting is approximate".into(),
    };
    format!(
        "exact (brute force's trajectories bit for bit): {}; {approximate}",
        exact.join(", ")
    )
}

fn csv(rows: &[Row]) -> String {
    let mut s = String::from(
        "label,threads,repeats,seconds_per_step_median,seconds_per_step_min,seconds_per_step_max,\
         narrow_phase_idle_fraction,fallback_rate,\
         task_fallback_least,task_fallback_most,contacts,rms_deviation_m,max_deviation_m,identical_to_reference,\
         books_drift_over_max_kinetic,deep_contacts\n",
    );
    for r in rows {
        let j = &r.ran.summary;
        writeln!(
            s,
            "{},{},{},{:e},{:e},{:e},{},{},{},{},{},{:e},{:e},{},{:e},{}",
            r.ran.spec.label,
            r.ran.spec.threads,
            r.repeats,
            r.seconds_per_step.median,
            r.seconds_per_step.lo,
            r.seconds_per_step.hi,
            r.narrow_idle,
            j["fallback_rate"].as_f64().unwrap_or(0.0),
            j["task_fallback_rate"]["least"].as_f64().unwrap_or(0.0),
            j["task_fallback_rate"]["most"].as_f64().unwrap_or(0.0),
            j["contacts"].as_u64().unwrap_or(0),
            r.rms,
            r.max,
            r.identical,
            r.drift,
            r.deep,
        )
        .expect("string");
    }
    s
}

fn scheduling_figures(
    dir: &Path,
    scene: &str,
    rows: &[Row],
) -> Result<(), Box<dyn std::error::Error>> {
    let mut names: Vec<&str> = rows.iter().map(|r| r.ran.spec.series.as_str()).collect();
    names.dedup();
    // Medians (time: with the min-max of the repeats), as points: two
    // thread counts are no trend to draw a line through.
    let by = |value: &dyn Fn(&Row) -> Stat| -> Vec<BarSeries> {
        names
            .iter()
            .map(|n| BarSeries {
                name: n.to_string(),
                bars: rows
                    .iter()
                    .filter(|r| r.ran.spec.series == *n)
                    .map(|r| value(r).bar(r.ran.spec.x, 1.0))
                    .collect(),
            })
            .collect()
    };
    let one = |v: f64| Stat {
        median: v,
        lo: v,
        hi: v,
    };
    bars(
        &dir.join("step-time.svg"),
        &format!("{scene}: ms per step against threads (median, min-max)"),
        ("threads", "ms per step"),
        &by(&|r| {
            let s = r.seconds_per_step;
            Stat {
                median: 1e3 * s.median,
                lo: 1e3 * s.lo,
                hi: 1e3 * s.hi,
            }
        }),
        Look::default(),
    )?;
    bars(
        &dir.join("idle.svg"),
        &format!("{scene}: narrow phase, share of thread time spent idle"),
        ("threads", "idle / (threads x narrow-phase time)"),
        &by(&|r| one(r.narrow_idle)),
        Look::default(),
    )?;
    bars(
        &dir.join("task-fallback.svg"),
        &format!("{scene}: fallback rate of the most minus the least falling-back task"),
        (
            "threads",
            "fallback-rate spread over tasks (mean over passes)",
        ),
        &by(&|r| {
            let t = &r.ran.summary["task_fallback_rate"];
            one(t["most"].as_f64().unwrap_or(0.0) - t["least"].as_f64().unwrap_or(0.0))
        }),
        Look::default(),
    )?;
    Ok(())
}

fn table(rows: &[Row]) -> String {
    let mut s = format!(
        "{:<26} {:>7} {:>24} {:>7} {:>9} {:>9} {:>10} {:>10} {:>9} {:>9} {:>6}\n",
        "run",
        "threads",
        "ms/step [min, max]",
        "idle",
        "fallback",
        "contacts",
        "rms dev m",
        "max dev m",
        "identical",
        "drift",
        "deep"
    );
    for r in rows {
        let j = &r.ran.summary;
        let per_step = contacts_per_step(r.ran);
        writeln!(
            s,
            "{:<26} {:>7} {:>8.3} [{:.3}, {:.3}] {:>6.1}% {:>8.2}% {:>9.0} {:>10.2e} {:>10.2e} {:>9} {:>9.2e} {:>6}",
            r.ran.spec.label,
            r.ran.spec.threads,
            1e3 * r.seconds_per_step.median,
            1e3 * r.seconds_per_step.lo,
            1e3 * r.seconds_per_step.hi,
            100.0 * r.narrow_idle,
            100.0 * j["fallback_rate"].as_f64().unwrap_or(0.0),
            per_step,
            r.rms,
            r.max,
            if r.identical { "yes" } else { "no" },
            r.drift,
            r.deep,
        )
        .expect("string");
    }
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs of one setting as the accuracy table reads them.
    fn ran(label: &str, contacts_per_step: f64) -> Ran {
        Ran {
            spec: Spec {
                label: label.into(),
                ranks: 1,
                threads: 1,
                args: Vec::new(),
                x: 0.0,
                series: String::new(),
            },
            summary: serde_json::json!({ "contacts": 100.0 * contacts_per_step, "steps": 100 }),
            lines: Vec::new(),
        }
    }

    fn row(ran: &Ran, ms: f64, rms: f64, identical: bool, deep: u64) -> Row<'_> {
        Row {
            ran,
            repeats: 3,
            seconds_per_step: Stat {
                median: 1e-3 * ms,
                lo: 1e-3 * ms,
                hi: 1e-3 * ms,
            },
            narrow_idle: 0.0,
            rms,
            max: rms,
            identical,
            drift: 0.0,
            deep,
        }
    }

    /// A setting that is fast because it finds few contacts is named with
    /// what it gives up, never as the fastest way to brute force's answer.
    #[test]
    fn the_accuracy_finding_leads_with_the_fastest_exact_setting() {
        let runs = [
            ran("brute", 1254.0),
            ran("chaos", 1253.0),
            ran("penalty-1it", 29.0),
            ran("hybrid", 1254.0),
            ran("penalty-4it-finish", 1246.0),
        ];
        let rows = [
            row(&runs[0], 4.1, 0.0, true, 0),
            row(&runs[1], 4.5, 1e-5, false, 0),
            row(&runs[2], 1.7, 5e-2, false, 658),
            row(&runs[3], 4.6, 0.0, true, 0),
            row(&runs[4], 4.0, 2.7e-5, false, 0),
        ];
        let text = accuracy_finding(&rows, 0.1);
        assert!(
            text.starts_with("found: the fastest exact setting is brute (4.100 ms"),
            "{text}"
        );
        assert!(text.contains("brute force itself"), "{text}");
        assert!(
            text.contains("penalty-1it -59% (29 of brute force's 1254 contacts per step, 658 deep, 5.0e3 chaos floors"),
            "{text}"
        );
        // Within the floor of the fastest exact setting: not faster.
        assert!(!text.contains("penalty-4it-finish"), "{text}");
        // The other exact setting, with its cost beyond the floor.
        assert!(
            text.contains("the other exact settings: hybrid +12%"),
            "{text}"
        );
        // The exact hybrid, slower than brute force beyond the floor, leads
        // once brute force is slower still.
        // Brute force, chaos and the exact hybrid at these ms per step.
        let three = |brute: f64, chaos: f64, hybrid: f64| {
            let rows = [
                row(&runs[0], brute, 0.0, true, 0),
                row(&runs[1], chaos, 1e-5, false, 0),
                row(&runs[3], hybrid, 0.0, true, 0),
            ];
            accuracy_finding(&rows, 0.1)
        };
        let text = three(6.0, 6.1, 4.6);
        assert!(
            text.contains("fastest exact setting is hybrid (4.600 ms"),
            "{text}"
        );
        assert!(text.contains("brute force takes +30%"), "{text}");
        assert!(text.contains("no approximate setting is faster"), "{text}");
        // An exact setting inside the floor is said to be so, not ranked.
        let text = three(4.2, 4.3, 4.0);
        assert!(
            text.contains("the other exact settings: brute within the floor"),
            "{text}"
        );
    }
}
