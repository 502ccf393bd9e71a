//! `tridem scaling SCENE`: the thread scaling of a DEM run, measured side by
//! side. Rounds alternate between the thread counts, so that a slow minute of
//! a noisy machine hits every count alike; the speed-up is the ratio of the
//! medians (or, with `--statistic min`, of the fastest runs). Each run starts from the scene's initial state, and the final
//! states are compared: a run's result must not depend on its thread count.
//!
//! On a shared machine the speed-up two cores deliver swings from minute to
//! minute (on the development VM, the distance kernel alone on 2 threads
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
    let mut workload = Reference::new(args.reference_pairs, &scene);
    let bar = ProgressBar::new((args.repeat * pools.len()) as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs {elapsed} eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    let mut results: Vec<Vec<RunResult>> = pools.iter().map(|_| Vec::new()).collect();
    let mut reference_runs: Vec<Vec<f64>> = pools.iter().map(|_| Vec::new()).collect();
    for _ in 0..args.repeat {
        for ((pool, runs), refs) in pools.iter().zip(&mut results).zip(&mut reference_runs) {
            runs.push(pool.install(|| one_run(&scene, steps)));
            if let Some(r) = workload.as_mut() {
                refs.push(pool.install(|| r.seconds_per_pair()));
            }
            bar.inc(1);
        }
    }
    bar.finish_and_clear();

    let particles = scene.world.dynamic_count() as f64;
    let first_positions = &results[0][0].positions;
    let identical = results
        .iter()
        .all(|runs| runs.iter().all(|r| &r.positions == first_positions));
    let stat = args.statistic;
    let seconds = |runs: &[RunResult]| runs.iter().map(|r| r.seconds).collect::<Vec<_>>();
    let medians: Vec<f64> = results.iter().map(|runs| median(seconds(runs))).collect();
    let minima: Vec<f64> = results
        .iter()
        .map(|runs| Statistic::Min.of(seconds(runs)))
        .collect();
    let times: Vec<f64> = results.iter().map(|runs| stat.of(seconds(runs))).collect();
    // The reference workload's time per kernel call, per thread count, by
    // the same statistic.
    let reference_times: Option<Vec<f64>> = workload
        .is_some()
        .then(|| reference_runs.iter().map(|r| stat.of(r.clone())).collect());
    // Per thread count, per section: the statistic over the runs.
    let section_times: Vec<Vec<f64>> = results
        .iter()
        .map(|runs| {
            let per_run: Vec<Vec<f64>> = runs
                .iter()
                .map(|r| {
                    section_rows(&r.sections)
                        .iter()
                        .map(|s| s.seconds)
                        .collect()
                })
                .collect();
            (0..per_run[0].len())
                .map(|k| stat.of(per_run.iter().map(|v| v[k]).collect()))
                .collect()
        })
        .collect();
    let section_names = section_rows(&results[0][0].sections);
    // Per thread count: the narrow phase's tasks' thread-seconds, and the
    // threads' time in the phase outside tasks (a late start, the wait for
    // the last task), each by the statistic over the runs.
    let narrow_busy_idle: Vec<(f64, f64)> = args
        .threads
        .iter()
        .zip(&results)
        .map(|(&t, runs)| {
            let d = |r: &RunResult| r.sections.detection;
            let busy = stat.of(runs.iter().map(|r| d(r).narrow_phase_busy).collect());
            let idle = stat.of(runs
                .iter()
                .map(|r| t as f64 * d(r).narrow_phase - d(r).narrow_phase_busy)
                .collect());
            (busy, idle)
        })
        .collect();
    let rows: Vec<serde_json::Value> = args
        .threads
        .iter()
        .zip(&results)
        .zip(medians.iter().zip(&minima).zip(&times))
        .zip(section_times.iter().zip(&narrow_busy_idle))
        .enumerate()
        .map(|(k, (((&t, runs), ((&m, &min), &time)), (sections, &(busy, idle))))| {
            let speedup = times[0] / time;
            let (reference_seconds, reference_speedup, relative) = match &reference_times {
                Some(r) => {
                    let rs = r[0] / r[k];
                    (
                        serde_json::json!(r[k]),
                        serde_json::json!(rs),
                        serde_json::json!(speedup / rs),
                    )
                }
                None => (
                    serde_json::Value::Null,
                    serde_json::Value::Null,
                    serde_json::Value::Null,
                ),
            };
            let by_section: serde_json::Map<String, serde_json::Value> = section_names
                .iter()
                .zip(sections)
                .map(|(r, &s)| (r.key(), s.into()))
                .collect();
            serde_json::json!({
                "scene": args.scene.display().to_string(),
                "steps": steps,
                "threads": t,
                "seconds": runs.iter().map(|r| r.seconds).collect::<Vec<_>>(),
                "statistic": stat.name(),
                "median_seconds": m,
                "min_seconds": min,
                "seconds_per_particle_step": time / (steps as f64 * particles),
                "speedup": speedup,
                "identical_results": identical,
                "section_seconds": by_section,
                "narrow_phase_busy_thread_seconds": busy,
                "narrow_phase_idle_thread_seconds": idle,
                "reference_pairs_per_thread": workload.as_ref().map(Reference::pairs_per_thread),
                "reference_seconds_per_pair": reference_seconds,
                "reference_speedup": reference_speedup,
                "speedup_relative_to_reference": relative,
            })
        })
        .collect();
    if args.json {
        for r in &rows {
            println!("{r}");
        }
        return Ok(());
    }
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
    for ((&t, runs), &m) in args.threads.iter().zip(&results).zip(&times) {
        let all: Vec<String> = runs.iter().map(|r| format!("{:.2}", r.seconds)).collect();
        println!(
            "{t:>7}  {m:>10.3}  {:>14.3e}  {:>7.2}x  {}",
            m / (steps as f64 * particles),
            times[0] / m,
            all.join(" ")
        );
    }
    println!(
        "{} seconds by section, and speed-up over {} thread(s)",
        stat.name(),
        args.threads[0]
    );
    print!("  {:<20}", "section");
    for t in &args.threads {
        print!("  {:>8}", format!("{t} thr"));
    }
    for t in &args.threads[1..] {
        print!("  {:>8}", format!("x{t}"));
    }
    println!();
    for (k, r) in section_names.iter().enumerate() {
        print!("  {:<20}", label(r));
        for m in &section_times {
            print!("  {:>8.3}", m[k]);
        }
        for m in &section_times[1..] {
            let ratio = section_times[0][k] / m[k];
            if ratio.is_finite() {
                print!("  {:>7.2}x", ratio);
            } else {
                print!("  {:>8}", "-");
            }
        }
        println!();
    }
    println!(
        "narrow phase: thread-seconds in tasks and outside them (late start, wait for the last task)"
    );
    println!(
        "{:>7}  {:>10}  {:>10}  {:>10}",
        "threads", "busy", "idle", "idle %"
    );
    for (&t, &(busy, idle)) in args.threads.iter().zip(&narrow_busy_idle) {
        println!(
            "{t:>7}  {busy:>10.3}  {idle:>10.3}  {:>9.1}%",
            100.0 * idle / (busy + idle)
        );
    }
    if let Some(r) = &reference_times {
        println!(
            "reference: each thread runs the scene's distance kernel {} times on {} cached pairs, after each run",
            workload.as_ref().map_or(0, Reference::pairs_per_thread),
            REFERENCE_SET
        );
        println!(
            "{:>7}  {:>10}  {:>8}  {:>22}",
            "threads", "ns/pair", "speed-up", "scene / reference"
        );
        for (k, &t) in args.threads.iter().enumerate() {
            let rs = r[0] / r[k];
            println!(
                "{t:>7}  {:>10.2}  {:>7.2}x  {:>22.2}",
                r[k] * 1e9,
                rs,
                (times[0] / times[k]) / rs
            );
        }
    }
    println!(
        "final states {} across thread counts and runs",
        if identical { "bit-identical" } else { "DIFFER" }
    );
    Ok(())
}

/// The reference workload: every thread of the pool computes the scene's
/// distance kernel on the same small set of random pairs, over and over,
/// into buffers of its own. Small, so that it stays in each core's cache at
/// any thread count; read-only and not shared out, so nothing but the cores
/// themselves limits it. (A set shared out between the threads measured
/// superlinear speed-ups on a 2-core machine, 2.07-2.15x with 50,000 to 1,000,000
/// pairs; the likely cause, half a set fitting one core's caches better
/// than the whole, was not confirmed: the guest has no cache counters.)
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
