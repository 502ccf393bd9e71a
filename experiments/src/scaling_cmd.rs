//! `tridem scaling SCENE`: the thread scaling of a DEM run, measured side by
//! side. Rounds alternate between the thread counts, so that a slow minute of
//! a noisy machine hits every count alike; the speed-up is the ratio of the
//! medians (or, with `--statistic min`, of the fastest runs). Each run
//! starts from the scene's initial state, and the final states are compared: a run's result must not depend on its thread count.
//!
//! On a shared machine the speed-up two cores deliver swings from minute to
//! minute (on a 2-core cloud machine, the distance kernel alone on 2 threads
//! measured 1.61x and 1.97x over one in consecutive runs). So next to each
//! run, the same pool times a reference workload with no shared data and no
//! synchronisation: each thread runs the scene's distance kernel on a small
//! set of random pairs.
//! Its speed-up is what the machine gave plain parallel work at that time;
//! the scene's speed-up divided by it is the part the scene's own design is
//! responsible for.

use crate::cli::ScalingArgs;
use crate::error::{CliError, CliResult};
use crate::sections::{label, section_rows};
use crate::stats::{median, Statistic};
use dem::distance::{distance_many_serial, random_unit_pairs, Closest, PenaltyStats, Triangle};
use dem::scene::Scene;
use dem::simulation::Simulation;
use dem::timing::SectionTimes;
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::time::Instant;

/// What one run leaves behind: its wall time, where it went, and the bodies'
/// final positions.
struct RunResult {
    seconds: f64,
    sections: SectionTimes,
    positions: Vec<glam::DVec3>,
}

pub fn run(args: &ScalingArgs) -> CliResult {
    if args.threads.is_empty() || args.threads.contains(&0) {
        return Err(CliError::input(
            "--threads needs thread counts of at least 1",
        ));
    }
    let scene = Scene::load(&args.scene).map_err(|e| CliError::input(e.to_string()))?;
    let steps = args
        .steps
        .unwrap_or_else(|| (scene.end_time / scene.dt).round() as u64);
    if steps == 0 {
        return Err(CliError::input(format!(
            "{}: no steps to time (--steps 0, or end_time below dt)",
            args.scene.display()
        )));
    }
    let pools = args
        .threads
        .iter()
        .map(|&t| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(t)
                .build()
                .map_err(|e| CliError::runtime(e.to_string()))
        })
        .collect::<CliResult<Vec<_>>>()?;
    let reference = Reference::new(args.reference_pairs, &scene);
    let measured = measure(args, &scene, steps, &pools, reference.as_ref());
    let rows = scaling_rows(args, &scene, steps, &measured, reference.as_ref());
    if args.json {
        for r in &rows {
            println!("{}", serde_json::to_string(r).expect("a row is plain data"));
        }
        return Ok(());
    }
    let sections = section_rows(&measured[0].runs[0].sections);
    print_report(args, &scene, steps, &rows, &sections, reference.as_ref());
    Ok(())
}

/// What one thread count measured: its runs and, after each, the reference.
struct Measured {
    runs: Vec<RunResult>,
    reference_seconds: Vec<f64>,
}

/// `--repeat` rounds, each a run (and the reference) per thread count in turn.
fn measure(
    args: &ScalingArgs,
    scene: &Scene,
    steps: u64,
    pools: &[rayon::ThreadPool],
    reference: Option<&Reference>,
) -> Vec<Measured> {
    let bar = ProgressBar::new((args.repeat * pools.len()) as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs {elapsed} eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    let mut measured: Vec<Measured> = pools
        .iter()
        .map(|_| Measured {
            runs: Vec::new(),
            reference_seconds: Vec::new(),
        })
        .collect();
    for _ in 0..args.repeat {
        for (pool, m) in pools.iter().zip(&mut measured) {
            m.runs.push(pool.install(|| one_run(scene, steps)));
            if let Some(r) = reference {
                m.reference_seconds
                    .push(pool.install(|| r.seconds_per_pair()));
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
    measured
}

/// One thread count's line of the report (one JSON object with `--json`).
#[derive(Debug, Serialize)]
struct ScalingRow {
    scene: String,
    steps: u64,
    threads: usize,
    seconds: Vec<f64>,
    statistic: &'static str,
    median_seconds: f64,
    min_seconds: f64,
    seconds_per_particle_step: f64,
    speedup: f64,
    identical_results: bool,
    section_seconds: serde_json::Map<String, serde_json::Value>,
    /// The narrow phase's tasks' thread-seconds, and the threads' time in
    /// the phase outside tasks (a late start, the wait for the last task).
    narrow_phase_busy_thread_seconds: f64,
    narrow_phase_idle_thread_seconds: f64,
    reference_pairs_per_thread: Option<usize>,
    reference_seconds_per_pair: Option<f64>,
    reference_speedup: Option<f64>,
    speedup_relative_to_reference: Option<f64>,
    /// The run time by the statistic, and each section's.
    #[serde(skip)]
    time: f64,
    #[serde(skip)]
    sections: Vec<f64>,
}

/// Each thread count's statistics, speed-ups against the first count, and
/// whether every run ended in the same state.
fn scaling_rows(
    args: &ScalingArgs,
    scene: &Scene,
    steps: u64,
    measured: &[Measured],
    reference: Option<&Reference>,
) -> Vec<ScalingRow> {
    let stat = args.statistic;
    let first_positions = &measured[0].runs[0].positions;
    let identical = measured
        .iter()
        .all(|m| m.runs.iter().all(|r| &r.positions == first_positions));
    let particles = scene.world.dynamic_count() as f64;
    let names = section_rows(&measured[0].runs[0].sections);
    let mut rows: Vec<ScalingRow> = Vec::new();
    for (&t, m) in args.threads.iter().zip(measured) {
        let seconds: Vec<f64> = m.runs.iter().map(|r| r.seconds).collect();
        let time = stat.of(seconds.clone());
        let per_run: Vec<Vec<f64>> = m
            .runs
            .iter()
            .map(|r| {
                section_rows(&r.sections)
                    .iter()
                    .map(|s| s.seconds)
                    .collect()
            })
            .collect();
        let sections: Vec<f64> = (0..names.len())
            .map(|k| stat.of(per_run.iter().map(|v| v[k]).collect()))
            .collect();
        let d = |r: &RunResult| r.sections.detection;
        let busy = stat.of(m.runs.iter().map(|r| d(r).narrow_phase_busy).collect());
        let idle = stat.of(m
            .runs
            .iter()
            .map(|r| t as f64 * d(r).narrow_phase - d(r).narrow_phase_busy)
            .collect());
        let speedup = rows.first().map_or(1.0, |r0| r0.time / time);
        let reference_seconds = reference.map(|_| stat.of(m.reference_seconds.clone()));
        let reference_speedup = match (rows.first(), reference_seconds) {
            (Some(r0), Some(s)) => r0.reference_seconds_per_pair.map(|s0| s0 / s),
            (None, Some(_)) => Some(1.0),
            _ => None,
        };
        rows.push(ScalingRow {
            scene: args.scene.display().to_string(),
            steps,
            threads: t,
            statistic: stat.name(),
            median_seconds: median(seconds.clone()),
            min_seconds: Statistic::Min.of(seconds.clone()),
            seconds,
            seconds_per_particle_step: time / (steps as f64 * particles),
            speedup,
            identical_results: identical,
            section_seconds: names
                .iter()
                .zip(&sections)
                .map(|(r, &s)| (r.key(), s.into()))
                .collect(),
            narrow_phase_busy_thread_seconds: busy,
            narrow_phase_idle_thread_seconds: idle,
            reference_pairs_per_thread: reference.map(Reference::pairs_per_thread),
            reference_seconds_per_pair: reference_seconds,
            reference_speedup,
            speedup_relative_to_reference: reference_speedup.map(|rs| speedup / rs),
            time,
            sections,
        });
    }
    rows
}

/// The report as tables: runs, sections, the narrow phase's idle time, the
/// reference, and whether the results agree.
fn print_report(
    args: &ScalingArgs,
    scene: &Scene,
    steps: u64,
    rows: &[ScalingRow],
    sections: &[crate::sections::SectionRow],
    reference: Option<&Reference>,
) {
    let stat = args.statistic;
    println!(
        "{}: {} particles, {steps} steps, {} runs per thread count, alternating",
        args.scene.display(),
        scene.world.dynamic_count(),
        args.repeat
    );
    println!(
        "{:>7}  {:>10}  {:>14}  {:>8}  runs (s)",
        "threads",
        format!("{} (s)", stat.name()),
        "s/particle-step",
        "speed-up"
    );
    for r in rows {
        let all: Vec<String> = r.seconds.iter().map(|s| format!("{s:.2}")).collect();
        println!(
            "{:>7}  {:>10.3}  {:>14.3e}  {:>7.2}x  {}",
            r.threads,
            r.time,
            r.seconds_per_particle_step,
            r.speedup,
            all.join(" ")
        );
    }
    print_sections(stat, rows, sections);
    print_narrow_phase(rows);
    if let Some(reference) = reference {
        print_reference(rows, reference);
    }
    let identical = rows.iter().all(|r| r.identical_results);
    println!(
        "final states {} across thread counts and runs",
        if identical { "bit-identical" } else { "DIFFER" }
    );
}

/// Seconds by section per thread count, and the speed-ups over the first.
fn print_sections(stat: Statistic, rows: &[ScalingRow], sections: &[crate::sections::SectionRow]) {
    println!(
        "{} seconds by section, and speed-up over {} thread(s)",
        stat.name(),
        rows[0].threads
    );
    print!("  {:<20}", "section");
    for r in rows {
        print!("  {:>8}", format!("{} thr", r.threads));
    }
    for r in &rows[1..] {
        print!("  {:>8}", format!("x{}", r.threads));
    }
    println!();
    for (k, s) in sections.iter().enumerate() {
        print!("  {:<20}", label(s));
        for r in rows {
            print!("  {:>8.3}", r.sections[k]);
        }
        for r in &rows[1..] {
            let ratio = rows[0].sections[k] / r.sections[k];
            if ratio.is_finite() {
                print!("  {:>7.2}x", ratio);
            } else {
                print!("  {:>8}", "-");
            }
        }
        println!();
    }
}

fn print_narrow_phase(rows: &[ScalingRow]) {
    println!(
        "narrow phase: thread-seconds in tasks and outside them (late start, wait for the last task)"
    );
    println!(
        "{:>7}  {:>10}  {:>10}  {:>10}",
        "threads", "busy", "idle", "idle %"
    );
    for r in rows {
        let (busy, idle) = (
            r.narrow_phase_busy_thread_seconds,
            r.narrow_phase_idle_thread_seconds,
        );
        println!(
            "{:>7}  {busy:>10.3}  {idle:>10.3}  {:>9.1}%",
            r.threads,
            100.0 * idle / (busy + idle)
        );
    }
}

fn print_reference(rows: &[ScalingRow], reference: &Reference) {
    println!(
        "reference: each thread runs the scene's distance kernel {} times on {} cached pairs, after each run",
        reference.pairs_per_thread(),
        REFERENCE_SET
    );
    println!(
        "{:>7}  {:>10}  {:>8}  {:>22}",
        "threads", "ns/pair", "speed-up", "scene / reference"
    );
    for r in rows {
        println!(
            "{:>7}  {:>10.2}  {:>7.2}x  {:>22.2}",
            r.threads,
            r.reference_seconds_per_pair.unwrap_or(f64::NAN) * 1e9,
            r.reference_speedup.unwrap_or(f64::NAN),
            r.speedup_relative_to_reference.unwrap_or(f64::NAN)
        );
    }
}

/// The reference workload: every thread of the pool computes the scene's
/// distance kernel on the same small set of random pairs, over and over,
/// into buffers of its own. Small, so that it stays in each core's cache at
/// any thread count; read-only and not shared out, so nothing but the cores
/// themselves limits it. (A large set shared out between the threads would
/// not do: each thread's half fits its core's caches better than the whole
/// set fits one, and the speed-up can exceed the thread count.)
struct Reference {
    pairs: Vec<(Triangle, Triangle)>,
    /// Passes over `pairs` per thread per measurement.
    passes: usize,
    opts: dem::distance::Options,
}

/// Pairs in the reference set: 590 KB, within one core's L2 cache here.
const REFERENCE_SET: usize = 4096;

/// Timings of the reference per run: the fastest of these, each short enough
/// that the fastest is one the machine did not interrupt.
const REFERENCE_REPEATS: usize = 3;

impl Reference {
    /// About `pairs` kernel calls per thread per measurement (0: none).
    fn new(pairs: usize, scene: &Scene) -> Option<Reference> {
        (pairs > 0).then(|| Reference {
            pairs: random_unit_pairs(REFERENCE_SET, 1),
            passes: pairs.div_ceil(REFERENCE_SET),
            opts: scene.kernel,
        })
    }

    /// Kernel calls per thread per measurement.
    fn pairs_per_thread(&self) -> usize {
        self.passes * self.pairs.len()
    }

    /// Seconds per kernel call on the current pool: wall time over all the
    /// threads' calls.
    fn seconds_per_pair(&self) -> f64 {
        let threads = rayon::current_num_threads();
        (0..REFERENCE_REPEATS)
            .map(|_| {
                let start = Instant::now();
                rayon::broadcast(|_| {
                    let mut out = vec![Closest::UNSET; self.pairs.len()];
                    let mut stats = vec![PenaltyStats::default(); self.pairs.len()];
                    for _ in 0..self.passes {
                        distance_many_serial(&self.pairs, &self.opts, &mut out, &mut stats)
                            .expect("batch size validated by the scene");
                    }
                });
                start.elapsed().as_secs_f64()
            })
            .fold(f64::INFINITY, f64::min)
            / (threads * self.pairs_per_thread()) as f64
    }
}

/// One run from the initial state, timed, on the current pool (kept busy
/// between parallel sections, as in `tridem run`).
fn one_run(scene: &Scene, steps: u64) -> RunResult {
    let mut sim = Simulation::new(scene);
    let start = Instant::now();
    dem::busy_workers::with_busy_workers(|| {
        for _ in 0..steps {
            sim.step();
        }
    });
    RunResult {
        seconds: start.elapsed().as_secs_f64(),
        sections: sim.timings,
        positions: sim.world.bodies.iter().map(|b| b.x).collect(),
    }
}
