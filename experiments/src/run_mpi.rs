//! `mpirun -np P tridem run SCENE`: the DEM split across P ranks
//! (`distributed`), with the output, checkpoints and summary of a one-node
//! run, written by rank 0, and per-rank metrics.

use crate::checkpoint_file;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::output::Output;
use dem::scene::Scene;
use dem::simulation::Simulation;
use distributed::metrics::{imbalance, json_line};
use distributed::{DistributedSimulation, Exchange, Settings, StepMetrics};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use partition::comm::all_gather_v;
use std::io::Write;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::Instant;

/// Every rank's outcome agreed on (collective): `Ok` on every rank, or an
/// error on every rank, reported once, by the lowest rank that failed.
fn agree<T>(comm: &SimpleCommunicator, r: CliResult<T>) -> CliResult<T> {
    let size = comm.size();
    let mine = if r.is_err() { comm.rank() } else { size };
    let mut first = size;
    comm.all_reduce_into(&mine, &mut first, SystemOperation::min());
    if first == size {
        return r;
    }
    let mut code = match &r {
        Err(e) => e.exit_code(),
        Ok(_) => 0,
    };
    comm.process_at_rank(first).broadcast_into(&mut code);
    Err(reported_by(comm, first, r.err(), code))
}

/// Has rank `by` print `e`, and every rank end silently with `code` only
/// once it has: mpirun ends the other ranks as soon as one exits with an
/// error, which must not cut the message short.
fn reported_by(comm: &SimpleCommunicator, by: i32, e: Option<CliError>, code: u8) -> CliError {
    if let Some(e) = e.filter(|_| comm.rank() == by) {
        eprintln!("tridem: error: {e:#}");
    }
    comm.barrier();
    CliError::reported_elsewhere(code)
}

/// The scene's `[parallel]` settings under the command line's.
fn settings(args: &RunArgs, scene: &Scene) -> CliResult<Settings> {
    let p = &scene.parallel;
    let partitioner = match (args.partitioner, &p.partitioner) {
        (Some(b), _) => b,
        (None, Some(name)) => name.parse().map_err(CliError::input)?,
        (None, None) => partition::Backend::ZoltanRcb,
    };
    let exchange = match (args.exchange, &p.exchange) {
        (Some(x), _) => x,
        (None, Some(name)) => name.parse().map_err(CliError::input)?,
        (None, None) => Exchange::Nonblocking,
    };
    let every = args.repartition_every.or(p.repartition_every).unwrap_or(0);
    Ok(Settings {
        partitioner,
        repartition_every: (every > 0).then_some(every),
        exchange,
        skin: scene
            .effects
            .get::<dem::effects::ContactParams>()
            .map_or(0.0, |c| c.skin),
    })
}

/// What rank 0 writes: output steps, checkpoints and metrics.
struct Writer {
    /// Held while the run writes its directory.
    _lock: Option<crate::output::DirLock>,
    out: Option<Output>,
    checkpoint: Option<std::path::PathBuf>,
    metrics: Option<std::io::BufWriter<std::fs::File>>,
}

pub fn run(args: &RunArgs, comm: &SimpleCommunicator) -> CliResult {
    let me = comm.rank();
    // A batch system's time limit signals every rank; each stops after the
    // step under way, and all agree on it within that step. Handled from
    // the start, so that no signal finds a rank without its handler.
    let stop = crate::run_cmd::stop_on_signals()?;
    agree(comm, crate::run_cmd::refuse_resume_without_output(args))?;
    let scene = agree(
        comm,
        Scene::load_with(&args.scene, &args.overrides).map_err(|e| CliError::input(e.to_string())),
    )?;
    if me == 0 {
        for w in &scene.warnings {
            eprintln!("tridem: warning: {w}");
        }
    }
    let settings = agree(comm, settings(args, &scene))?;
    // Cores are shared by the ranks of a node: one thread each unless told.
    let threads = args.threads.unwrap_or(1);
    agree(
        comm,
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .build_global()
            .map_err(|e| CliError::runtime(e.to_string())),
    )?;
    let (sim, first) = agree(comm, start(args, &scene))?;
    let steps = agree(comm, crate::run_cmd::steps_to_run(args, &scene, first))?;
    // Only rank 0 touches the disk; the others learn whether it could.
    let writer = if me == 0 {
        open_writer(args, &sim)
    } else {
        Ok(None)
    };
    let mut writer = agree(comm, writer)?;
    if me == 0 {
        announce(args, &scene, &sim, &settings, steps, comm.size(), threads);
    }
    let n_particles = sim.world.dynamic_count();
    let mut dist = agree(
        comm,
        DistributedSimulation::new(comm, &scene, sim, settings).map_err(CliError::runtime),
    )?;
    let mut totals = StepMetrics::default();
    let start = Instant::now();
    let ended = step_loop(
        comm,
        args,
        &scene,
        &mut dist,
        steps,
        &mut writer,
        &mut totals,
        &stop,
    )?;
    if let Some(s) = ended {
        let resume = match writer.as_ref().and_then(|w| w.checkpoint.as_ref()) {
            Some(c) => format!("its state is in {}: go on with --resume", c.display()),
            None => "no checkpoint without --output".into(),
        };
        let e = CliError::runtime(format!(
            "stopped by a signal after {s} of {steps} steps, at step {} (t = {:.6e} s); {resume}",
            dist.world.step, dist.world.time
        ));
        return Err(if me == 0 {
            e
        } else {
            CliError::reported_elsewhere(1)
        });
    }
    if steps > 0 && !dist.world.step.is_multiple_of(scene.output_every) {
        agree(comm, write_state(&scene, &dist, writer.as_mut(), false))?;
    }
    let secs = start.elapsed().as_secs_f64();
    summary(comm, args, &dist, &totals, steps, secs, n_particles);
    Ok(())
}

/// What the run is, on one line of rank 0's standard error.
fn announce(
    args: &RunArgs,
    scene: &Scene,
    sim: &Simulation,
    settings: &Settings,
    steps: u64,
    ranks: i32,
    threads: usize,
) {
    eprintln!(
        "{}, {ranks} ranks x {threads} threads, {}, {} exchange, repartition {}",
        crate::run_cmd::describe(args, scene, sim, steps),
        settings.partitioner.name(),
        settings.exchange.name(),
        settings
            .repartition_every
            .map_or("at the start only".into(), |k| format!("every {k} steps")),
    );
}

/// The steps on every rank, with their metrics, output and progress bar
/// (rank 0's): `Some(s)` when a signal stopped the run after step `s`.
#[allow(clippy::too_many_arguments)]
fn step_loop(
    comm: &SimpleCommunicator,
    args: &RunArgs,
    scene: &Scene,
    dist: &mut DistributedSimulation,
    steps: u64,
    writer: &mut Option<Writer>,
    totals: &mut StepMetrics,
    stop: &AtomicBool,
) -> CliResult<Option<u64>> {
    let bar = crate::run_cmd::progress_bar(steps, args.quiet || comm.rank() != 0);
    let mut interval = StepMetrics::default();
    for s in 1..=steps {
        let stopping = dist
            .step(stop.load(Ordering::Relaxed))
            .map_err(CliError::runtime);
        let stopping = agree(comm, stopping)?;
        if let Err(e) = refuse_lasting_crossings(scene, dist) {
            bar.abandon();
            return agree(comm, Err(e));
        }
        totals.accumulate(dist.metrics());
        interval.extend_interval(dist.metrics());
        if s % args.metrics_every == 0 || s == steps {
            write_metrics(comm, &std::mem::take(&mut interval), writer.as_mut())?;
        }
        if dist.world.step.is_multiple_of(scene.output_every) || stopping {
            agree(comm, write_state(scene, dist, writer.as_mut(), true))?;
        }
        if s % 16 == 0 || s == steps {
            bar.set_position(s);
        }
        if stopping {
            bar.abandon();
            return Ok(Some(s));
        }
    }
    bar.finish_and_clear();
    Ok(None)
}

/// Contacts deeper than the halos for DEEP_STEPS steps in a row on any
/// rank stop the run, unless the scene allows them.
fn refuse_lasting_crossings(scene: &Scene, dist: &DistributedSimulation) -> CliResult {
    if dist.deep_steps_in_a_row() < crate::run_cmd::DEEP_STEPS || scene.allow_deep_contacts {
        return Ok(());
    }
    Err(CliError::runtime(format!(
        "contacts stayed deeper than the halos for {} steps in a row (step {}, t = {:e} s); \
         the run stops: raise the stiffness or the halo, or lower dt or the speed; \
         simulation.allow_deep_contacts = true lets the run go on",
        crate::run_cmd::DEEP_STEPS,
        dist.world.step,
        dist.world.time
    )))
}

/// The run's simulation, new (refused when bodies cross at the start) or
/// resumed from a checkpoint, and its first step.
pub(crate) fn start(args: &RunArgs, scene: &Scene) -> CliResult<(Simulation, u64)> {
    match &args.resume {
        None => {
            let sim = Simulation::new(scene);
            crate::run_cmd::refuse_overlaps_at_start(scene, &sim)?;
            Ok((sim, 0))
        }
        Some(file) => {
            let c = checkpoint_file::read(file)?;
            let sim = Simulation::resume(scene, &c).map_err(|e| {
                CliError::input(format!(
                    "{}: does not fit the scene {}: {e}",
                    file.display(),
                    args.scene.display()
                ))
            })?;
            Ok((sim, c.step))
        }
    }
}

/// Rank 0's output, checkpoint and metrics files, the first output step written.
fn open_writer(args: &RunArgs, sim: &Simulation) -> CliResult<Option<Writer>> {
    if let Some(m) = args
        .metrics
        .as_ref()
        .filter(|m| m.exists() && !args.overwrite)
    {
        return Err(CliError::input(format!(
            "{}: exists; choose another metrics file or replace it with --overwrite",
            m.display()
        )));
    }
    let (out, write_first, lock) = match &args.output {
        Some(dir) => {
            let (o, first, lock) =
                crate::output::open_run_output(dir, args.resume.as_deref(), args.overwrite, sim)?;
            (Some(o), first, Some(lock))
        }
        None => (None, false, None),
    };
    let mut out = out;
    if let Some(o) = out.as_mut().filter(|_| write_first) {
        o.write_step(sim)?;
    }
    let metrics = match &args.metrics {
        Some(m) => Some(std::io::BufWriter::new(std::fs::File::create(m).map_err(
            |e| CliError::runtime(format!("{}: cannot write: {e}", m.display())),
        )?)),
        None => None,
    };
    Ok(Some(Writer {
        _lock: lock,
        out,
        checkpoint: args.output.as_ref().map(|d| d.join("checkpoint.h5")),
        metrics,
    }))
}

/// Gathers the state on rank 0 and writes a checkpoint (and, with `output`,
/// an output step). Collective.
fn write_state(
    scene: &Scene,
    dist: &DistributedSimulation,
    writer: Option<&mut Writer>,
    output: bool,
) -> CliResult {
    let gathered = dist.gather();
    let (Some(g), Some(w)) = (gathered, writer) else {
        return Ok(());
    };
    if let Some(o) = w.out.as_mut().filter(|_| output) {
        let mut view = Simulation::resume(scene, &g.checkpoint)
            .map_err(|e| CliError::runtime(format!("gathered state: {e}")))?;
        view.show_contacts(g.contacts, g.contact_forces);
        o.write_step(&view)?;
    }
    if let Some(c) = &w.checkpoint {
        checkpoint_file::write(c, &g.checkpoint)?;
    }
    Ok(())
}

/// Gathers an interval's metrics on every rank; rank 0 writes a JSON line.
fn write_metrics(
    comm: &SimpleCommunicator,
    interval: &StepMetrics,
    writer: Option<&mut Writer>,
) -> CliResult {
    let Some(file) = writer.and_then(|w| w.metrics.as_mut()) else {
        // Collective only when rank 0 writes: it tells the others by having a file.
        let mut writes = 0u8;
        comm.process_at_rank(0).broadcast_into(&mut writes);
        if writes == 1 {
            all_gather_v(comm, std::slice::from_ref(interval));
        }
        return Ok(());
    };
    let mut writes = 1u8;
    comm.process_at_rank(0).broadcast_into(&mut writes);
    let ranks = all_gather_v(comm, std::slice::from_ref(interval));
    writeln!(file, "{}", json_line(&ranks))
        .and_then(|_| file.flush())
        .map_err(|e| CliError::runtime(format!("metrics: {e}")))
}

/// Rank 0 prints the run's summary: time per step and, per metric, its
/// minimum, mean and maximum over the ranks.
fn summary(
    comm: &SimpleCommunicator,
    args: &RunArgs,
    dist: &DistributedSimulation,
    totals: &StepMetrics,
    steps: u64,
    secs: f64,
    particles: usize,
) {
    let ranks = all_gather_v(comm, std::slice::from_ref(totals));
    let contacts = ranks.iter().map(|m| m.contacts).sum::<u64>();
    let mut stats = [0u64; 2];
    let mine = [
        dist.totals.detection.deep_contacts,
        dist.totals.detection.triangle_pairs,
    ];
    comm.all_reduce_into(&mine[..], &mut stats[..], SystemOperation::sum());
    if comm.rank() != 0 {
        return;
    }
    let per_step = |v: f64| v / steps.max(1) as f64;
    let mut table = serde_json::Map::new();
    for (name, _) in StepMetrics::default().fields() {
        if name == "step" {
            continue;
        }
        let column: Vec<f64> = ranks
            .iter()
            .map(|m| per_step(m.fields().iter().find(|f| f.0 == name).map_or(0.0, |f| f.1)))
            .collect();
        let min = column.iter().copied().fold(f64::INFINITY, f64::min);
        let max = column.iter().copied().fold(0.0, f64::max);
        let mean = column.iter().sum::<f64>() / column.len() as f64;
        table.insert(
            name.into(),
            serde_json::json!({"min": min, "mean": mean, "max": max}),
        );
    }
    let summary = serde_json::json!({
        "scene": args.scene.display().to_string(),
        "ranks": ranks.len(),
        "threads": rayon::current_num_threads(),
        "steps": steps,
        "last_step": dist.world.step,
        "particles": particles,
        "seconds": secs,
        "seconds_per_step": secs / steps.max(1) as f64,
        "seconds_per_particle_step": secs / (steps.max(1) as f64 * particles as f64),
        "contacts": contacts,
        "deep_contacts": stats[0],
        "triangle_pairs_checked": stats[1],
        "triangle_imbalance": imbalance(ranks.iter().map(|m| m.owned_triangles as f64)),
        "busy_imbalance": imbalance(ranks.iter().map(|m| m.busy_seconds)),
        "per_step_over_ranks": table,
    });
    if args.json {
        println!("{summary}");
        return;
    }
    println!(
        "steps                  {steps} in {secs:.2} s ({:.0} steps/s) on {} ranks",
        steps as f64 / secs,
        ranks.len()
    );
    println!(
        "cost per particle-step {:.3e} s",
        summary["seconds_per_particle_step"].as_f64().unwrap_or(0.0)
    );
    println!("contacts (sum)         {contacts}");
    println!("deep contacts          {}", stats[0]);
    println!(
        "imbalance              triangles {:.3}, busy time {:.3} (max/mean)",
        summary["triangle_imbalance"].as_f64().unwrap_or(1.0),
        summary["busy_imbalance"].as_f64().unwrap_or(1.0)
    );
    println!(
        "per step, over ranks   {:>12} {:>12} {:>12}",
        "min", "mean", "max"
    );
    for (name, v) in &table {
        let f = |k: &str| v[k].as_f64().unwrap_or(0.0);
        println!(
            "  {name:<20} {:>12.4e} {:>12.4e} {:>12.4e}",
            f("min"),
            f("mean"),
            f("max")
        );
    }
    if let Some(dir) = &args.output {
        crate::run_summary::print_output_lines(dir, dist.world.step);
    }
}
