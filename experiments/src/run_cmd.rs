//! `tridem run SCENE`: a DEM run on one node, with HDF5 output and a summary.

use crate::checkpoint_file;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::sections::{label, section_rows};
use dem::scene::Scene;
use dem::simulation::Simulation;
use indicatif::{ProgressBar, ProgressStyle};
use signal_hook::consts::TERM_SIGNALS;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

pub fn run(args: &RunArgs) -> CliResult {
    let universe =
        mpi::initialize().ok_or_else(|| CliError::runtime("MPI was already initialised"))?;
    let comm = universe.world();
    if mpi::traits::Communicator::size(&comm) > 1 {
        return crate::run_mpi::run(args, &comm);
    }
    refuse_resume_without_output(args)?;
    let scene = Scene::load_with(&args.scene, &args.overrides)
        .map_err(|e| CliError::input(e.to_string()))?;
    for w in &scene.warnings {
        eprintln!("tridem: warning: {w}");
    }
    rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build_global()
        .map_err(|e| CliError::runtime(e.to_string()))?;
    let (mut sim, first) = crate::run_mpi::start(args, &scene)?;
    let last = (scene.end_time / scene.dt).round() as u64;
    let steps = match args.steps {
        Some(n) => n,
        None if args.resume.is_none() || first < last => last.saturating_sub(first),
        None => {
            return Err(CliError::input(format!(
                "the checkpoint is at step {first}, the scene's end ({:e} s) at step {last}: \
                 nothing left to run (--steps N runs N more)",
                scene.end_time
            )))
        }
    };
    // Resumed into the directory it was written to, the output goes on in the
    // same file; a fresh run starts its own.
    let (mut out, write_first, _lock) = match &args.output {
        Some(dir) => {
            let (o, first, lock) =
                crate::output::open_run_output(dir, args.resume.as_deref(), args.overwrite, &sim)?;
            (Some(o), first, Some(lock))
        }
        None => (None, false, None),
    };
    let checkpoint_path = args.output.as_ref().map(|d| d.join("checkpoint.h5"));
    eprintln!(
        "{}: {} particles ({} triangles), {} obstacles, effects: {}; dt {:e} s{}, {steps} steps, {} threads",
        args.scene.display(),
        sim.world.dynamic_count(),
        sim.world.particle_triangles(),
        sim.world.bodies.len() - sim.world.dynamic_count(),
        sim.effect_names().join(", "),
        scene.dt,
        scene.stable_dt.map_or(String::new(), |h| format!(" (stable: {h:.3e} s)")),
        rayon::current_num_threads(),
    );
    if let Some(o) = out.as_mut().filter(|_| write_first) {
        o.write_step(&sim)?;
    }
    let bar = ProgressBar::new(steps).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps {elapsed} eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    if args.quiet {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    // SIGTERM (a batch system's time limit or preemption) or Ctrl-C ends the
    // run after the step under way, with a checkpoint; a second one at once.
    let stop = stop_on_signals()?;
    let mut checkpoint_secs = 0.0;
    let start = Instant::now();
    // The whole loop runs on a worker of the pool, so that parallel sections
    // start from inside it, and the other workers poll instead of sleeping
    // between sections (see dem::busy_workers; measured on the hopper: waking
    // threads took 25-40% of a run on a 2-core machine).
    let mut deep_steps = 0;
    let looped: CliResult<Option<u64>> = dem::busy_workers::with_busy_workers(|| {
        for s in 1..=steps {
            sim.step();
            deep_steps = if sim.last_stats().detection.deep_contacts > 0 {
                deep_steps + 1
            } else {
                0
            };
            if let Err(e) = refuse_lasting_crossings(&scene, &sim, deep_steps) {
                bar.abandon();
                return Err(e);
            }
            if sim.world.bodies.iter().any(|b| {
                !(b.x.is_finite() && b.v.is_finite() && b.q.is_finite() && b.l.is_finite())
            }) {
                bar.abandon();
                return Err(CliError::runtime(format!(
                    "the simulation became non-finite at step {s} (t = {:e} s): the time step is too large for this scene",
                    sim.world.time
                )));
            }
            // Output steps count from the start of the run, resumed or not.
            if sim.world.step % scene.output_every == 0 {
                if let (Some(o), Some(c)) = (&mut out, &checkpoint_path) {
                    o.write_step(&sim)?;
                    let start = Instant::now();
                    checkpoint_file::write(c, &sim.checkpoint())?;
                    checkpoint_secs += start.elapsed().as_secs_f64();
                }
            }
            if s % 64 == 0 || s == steps {
                bar.set_position(s);
            }
            if stop.load(Ordering::Relaxed) {
                bar.abandon();
                return Ok(Some(s));
            }
        }
        Ok(None)
    });
    if let Some(s) = looped? {
        let resume = match &checkpoint_path {
            Some(c) => {
                checkpoint_file::write(c, &sim.checkpoint())?;
                format!("its state is in {}: go on with --resume", c.display())
            }
            None => "no checkpoint without --output".into(),
        };
        return Err(CliError::runtime(format!(
            "stopped by a signal after {s} of {steps} steps, at step {} (t = {:.6e} s); {resume}",
            sim.world.step, sim.world.time
        )));
    }
    bar.finish_and_clear();
    // So that a run that ended between output steps can be taken further.
    if let Some(c) = checkpoint_path.as_ref() {
        if steps == 0 || sim.world.step % scene.output_every != 0 {
            let start = Instant::now();
            checkpoint_file::write(c, &sim.checkpoint())?;
            checkpoint_secs += start.elapsed().as_secs_f64();
        }
    }
    let secs = start.elapsed().as_secs_f64();
    warn_fallen(&scene, &sim);
    if sim.totals.detection.deep_contacts > 0 {
        eprintln!(
            "tridem: warning: {} contacts went deeper than the particles' halos (triangles crossed); \
             raise the stiffness or the halo, or lower the impact speed",
            sim.totals.detection.deep_contacts
        );
    }
    let n = sim.world.dynamic_count() as f64;
    let t = &sim.totals;
    let dynamic: Vec<_> = sim.world.bodies.iter().filter(|b| !b.is_static()).collect();
    let com = dynamic.iter().map(|b| b.x * b.mass).sum::<glam::DVec3>()
        / dynamic.iter().map(|b| b.mass).sum::<f64>();
    let lowest = dynamic.iter().map(|b| b.x.z).fold(f64::INFINITY, f64::min);
    let highest = dynamic
        .iter()
        .map(|b| b.x.z)
        .fold(f64::NEG_INFINITY, f64::max);
    let sections = section_rows(&sim.timings);
    let stepping = sim.timings.total();
    let mut section_json = serde_json::Map::new();
    for r in &sections {
        section_json.insert(r.key(), r.seconds.into());
    }
    // Output, the finiteness check and the progress bar.
    section_json.insert("checkpoints".into(), checkpoint_secs.into());
    section_json.insert(
        "other".into(),
        (secs - stepping - checkpoint_secs).max(0.0).into(),
    );
    let summary = serde_json::json!({
        "centre_of_mass": [com.x, com.y, com.z],
        "lowest_z": lowest,
        "highest_z": highest,
        "scene": args.scene.display().to_string(),
        "steps": steps,
        "first_step": first,
        "last_step": sim.world.step,
        "particles": sim.world.dynamic_count(),
        "threads": rayon::current_num_threads(),
        "seconds": secs,
        "steps_per_second": steps as f64 / secs,
        "seconds_per_particle_step": secs / (steps as f64 * n),
        "broad_phases": t.detection.broad_phases,
        "body_pairs_checked": t.detection.body_pairs,
        "triangle_pairs_checked": t.detection.triangle_pairs,
        "fallback_rate": if t.detection.triangle_pairs > 0 { t.detection.fallback_pairs as f64 / t.detection.triangle_pairs as f64 } else { 0.0 },
        "task_fallback_rate": task_fallback_rate(&t.detection),
        "contacts": t.detection.contacts,
        "deep_contacts": t.detection.deep_contacts,
        "tangential_evaluations": t.tangential_evaluations,
        "kinetic_energy": sim.world.kinetic_energy(),
        "stepping_seconds": stepping,
        "narrow_phase_busy_thread_seconds": sim.timings.detection.narrow_phase_busy,
        "section_seconds": section_json,
    });
    if args.json {
        println!("{summary}");
    } else {
        println!(
            "steps                  {steps} in {secs:.2} s ({:.0} steps/s)",
            steps as f64 / secs
        );
        println!("cost per particle-step {:.3e} s", secs / (steps as f64 * n));
        println!("broad phases           {}", t.detection.broad_phases);
        println!("body pairs checked     {}", t.detection.body_pairs);
        println!("triangle pairs checked {}", t.detection.triangle_pairs);
        println!(
            "kernel fallback rate   {:.1}%",
            100.0 * summary["fallback_rate"].as_f64().unwrap_or(0.0)
        );
        println!("contacts (sum)         {}", t.detection.contacts);
        println!("tangential evaluations {}", t.tangential_evaluations);
        println!("deep contacts          {}", t.detection.deep_contacts);
        println!(
            "particles' z           {lowest:.4} .. {highest:.4} (centre of mass {:.4})",
            com.z
        );
        println!("time by section        seconds  share");
        let mut rows: Vec<(String, f64)> = sections.iter().map(|r| (label(r), r.seconds)).collect();
        rows.push(("checkpoints".into(), checkpoint_secs));
        rows.push((
            "output and checks".into(),
            (secs - stepping - checkpoint_secs).max(0.0),
        ));
        for (name, s) in rows {
            println!("  {name:<20} {s:>8.3}  {:>4.1}%", 100.0 * s / secs);
        }
        if let Some(dir) = &args.output {
            println!(
                "output                 {}/run.h5 (open {}/run.xmf in ParaView)",
                dir.display(),
                dir.display()
            );
            println!(
                "checkpoint             {}/checkpoint.h5 (step {}; go on with --resume)",
                dir.display(),
                sim.world.step
            );
        }
    }
    Ok(())
}

/// The fallback rate of the least and the most falling-back detection task,
/// averaged over passes: whole-batch fallback makes it depend on how pairs
/// are cut into tasks, and so on the threads.
fn task_fallback_rate(d: &dem::contact::DetectionStats) -> serde_json::Value {
    let n = d.passes_with_pairs.max(1) as f64;
    serde_json::json!({
        "least": d.task_fallback_min / n,
        "most": d.task_fallback_max / n,
    })
}

/// Resuming continues a run's output: without a directory to write to, a
/// resumed run would compute and keep nothing.
pub(crate) fn refuse_resume_without_output(args: &RunArgs) -> CliResult {
    match (&args.resume, &args.output) {
        (Some(c), None) => Err(CliError::input(format!(
            "--resume {}: give --output DIR too (the run's directory, to go on in its files), \
             or the resumed run writes nothing",
            c.display()
        ))),
        _ => Ok(()),
    }
}

/// Steps in a row with contacts deeper than the halos after which a run
/// stops: a contact that crosses for this long is not holding its bodies
/// apart (too soft, or hit too fast), and what follows is not physics.
pub(crate) const DEEP_STEPS: u64 = 100;

/// Bodies whose surfaces cross at the start are refused, and a run whose
/// contacts stay crossed for [`DEEP_STEPS`] steps stops, naming the pair,
/// unless the scene sets `simulation.allow_deep_contacts`.
pub(crate) fn refuse_crossings(scene: &Scene, sim: &Simulation, when: &str) -> CliResult {
    if scene.allow_deep_contacts {
        return Ok(());
    }
    let crossed = sim.crossed_pairs();
    let Some(&(a, b, depth)) = crossed.iter().max_by(|x, y| x.2.total_cmp(&y.2)) else {
        return Ok(());
    };
    Err(CliError::input(format!(
        "{} and {} cross by {depth:e} m (deeper than their halos) {when}{}: move them apart, \
         raise the stiffness or the halo, or lower dt or the speed; \
         simulation.allow_deep_contacts = true lets the run go on",
        scene.body_name(a),
        scene.body_name(b),
        match crossed.len() {
            1 => String::new(),
            n => format!(", as do {} more pairs", n - 1),
        }
    )))
}

fn refuse_lasting_crossings(scene: &Scene, sim: &Simulation, deep_steps: u64) -> CliResult {
    if deep_steps < DEEP_STEPS {
        return Ok(());
    }
    let when = format!(
        "for {DEEP_STEPS} steps in a row (step {}, t = {:e} s); the run stops",
        sim.world.step, sim.world.time
    );
    refuse_crossings(scene, sim, &when).map_err(|e| CliError::runtime(e.to_string()))
}

/// Warns of particles that ended below every obstacle, along gravity: they
/// fell through a wall (too fast for the step, or too soft a contact) or
/// out of the scene, and what they do no longer means anything.
pub(crate) fn warn_fallen(scene: &Scene, sim: &Simulation) {
    let Some(down) = scene.effects.gravity.and_then(|g| g.try_normalize()) else {
        return;
    };
    let w = &sim.world;
    let lowest_obstacle = w
        .bodies
        .iter()
        .filter(|b| b.is_static())
        .flat_map(|b| {
            w.shapes[b.shape]
                .vertices
                .iter()
                .map(|&v| (b.x + b.q * v).dot(down))
        })
        .fold(f64::NEG_INFINITY, f64::max);
    if lowest_obstacle == f64::NEG_INFINITY {
        return;
    }
    let fallen: Vec<usize> = (0..w.bodies.len())
        .filter(|&i| !w.bodies[i].is_static() && w.bodies[i].x.dot(down) > lowest_obstacle)
        .collect();
    if let Some(&first) = fallen.first() {
        eprintln!(
            "tridem: warning: {} particles ended below every obstacle (fell through a wall or \
             out of the scene), the first {}",
            fallen.len(),
            scene.body_name(first)
        );
    }
}

/// A repeat of the stop signal within this many milliseconds is the same
/// request delivered twice (`scancel --full` signals the batch shell, which
/// forwards it, and tridem itself), not a second one.
const REPEAT_MS: u64 = 2000;

/// A flag that SIGTERM, SIGINT or SIGQUIT set: the run ends after the step
/// under way, with a checkpoint. A second signal, more than [`REPEAT_MS`]
/// after the first, ends the process at once.
pub(crate) fn stop_on_signals() -> CliResult<Arc<AtomicBool>> {
    use std::sync::atomic::AtomicU64;
    use std::sync::OnceLock;
    static ORIGIN: OnceLock<Instant> = OnceLock::new();
    // Milliseconds after ORIGIN of the first signal, plus one (0: none yet).
    static FIRST: AtomicU64 = AtomicU64::new(0);
    let origin = *ORIGIN.get_or_init(Instant::now);
    let stop = Arc::new(AtomicBool::new(false));
    for &signal in TERM_SIGNALS {
        let flag = Arc::clone(&stop);
        // SAFETY: the handler only reads the monotonic clock (clock_gettime
        // is async-signal-safe), touches atomics and calls _exit.
        unsafe {
            signal_hook::low_level::register(signal, move || {
                let now = origin.elapsed().as_millis() as u64 + 1;
                match FIRST.compare_exchange(0, now, Ordering::SeqCst, Ordering::SeqCst) {
                    Ok(_) => flag.store(true, Ordering::SeqCst),
                    Err(first) if now.saturating_sub(first) > REPEAT_MS => {
                        signal_hook::low_level::exit(128 + signal)
                    }
                    Err(_) => {}
                }
            })
        }
        .map_err(|e| CliError::runtime(format!("cannot handle signal {signal}: {e}")))?;
    }
    Ok(stop)
}
