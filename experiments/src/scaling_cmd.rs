//! `tridem scaling SCENE`: the thread scaling of a DEM run, measured side by
//! side. Rounds alternate between the thread counts, so that a slow minute of
//! a noisy machine hits every count alike; the speed-up is the ratio of the
//! medians (or, with `--statistic min`, of the fastest runs). Each run starts from the scene's initial state, and the final
//! states are compared: a run's result must not depend on its thread count.

use crate::cli::ScalingArgs;
use crate::error::{CliError, CliResult};
use crate::sections::{label, section_rows};
use crate::stats::{median, Statistic};
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
    if args.repeat == 0 {
        return Err(CliError::input("--repeat must be at least 1"));
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
    let bar = ProgressBar::new((args.repeat * pools.len()) as u64).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs {elapsed} eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    let mut results: Vec<Vec<RunResult>> = pools.iter().map(|_| Vec::new()).collect();
    for _ in 0..args.repeat {
        for (pool, runs) in pools.iter().zip(&mut results) {
            runs.push(pool.install(|| one_run(&scene, steps)));
            bar.inc(1);
        }
    }
    bar.finish_and_clear();

    let particles = scene.world.dynamic_count() as f64;
    let reference = &results[0][0].positions;
    let identical = results
        .iter()
        .all(|runs| runs.iter().all(|r| &r.positions == reference));
    let stat = args.statistic;
    let seconds = |runs: &[RunResult]| runs.iter().map(|r| r.seconds).collect::<Vec<_>>();
    let medians: Vec<f64> = results.iter().map(|runs| median(seconds(runs))).collect();
    let minima: Vec<f64> = results
        .iter()
        .map(|runs| Statistic::Min.of(seconds(runs)))
        .collect();
    let times: Vec<f64> = results.iter().map(|runs| stat.of(seconds(runs))).collect();
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
    let rows: Vec<serde_json::Value> = args
        .threads
        .iter()
        .zip(&results)
        .zip(medians.iter().zip(&minima).zip(&times))
        .zip(&section_times)
        .map(|(((&t, runs), ((&m, &min), &time)), sections)| {
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
                "speedup": times[0] / time,
                "identical_results": identical,
                "section_seconds": by_section,
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
        "final states {} across thread counts and runs",
        if identical { "bit-identical" } else { "DIFFER" }
    );
    Ok(())
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
