//! `tridem run SCENE`: a DEM run on one node, with HDF5 output and a summary.

use crate::checkpoint_file;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::run_summary::{RunSummary, RunTimes};
use dem::scene::Scene;
use dem::simulation::Simulation;
use indicatif::{ProgressBar, ProgressStyle};
use signal_hook::consts::TERM_SIGNALS;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;

pub fn run(args: &RunArgs) -> CliResult {
    // A singleton MPI start costs seconds (Open MPI starts its runtime
    // daemon) and gives one rank: a run not started by a launcher goes
    // without MPI.
    let universe = if launched_by_mpi() {
        // Funneled: MPI is called from the main thread only, while the
        // thread pool's workers and the signal thread exist.
        let (universe, _) = mpi::initialize_with_threading(mpi::Threading::Funneled)
            .ok_or_else(|| CliError::runtime("MPI was already initialised"))?;
        Some(universe)
    } else {
        None
    };
    if let Some(comm) = universe.as_ref().map(|u| u.world()) {
        if mpi::traits::Communicator::size(&comm) > 1 {
            return crate::run_mpi::run(args, &comm);
        }
    }
    refuse_resume_without_output(args)?;
    let scene = load_scene(args)?;
    // Not used on one process, but a name no partitioner, exchange or
    // weighing knows is an error wherever the scene runs.
    crate::parallel::settings(args, &scene)?;
    crate::output::fields_of(&scene, &args.scene)?;
    rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build_global()
        .map_err(|e| CliError::runtime(e.to_string()))?;
    let (mut sim, first) = start(args, &scene)?;
    let steps = steps_to_run(args, &scene, first)?;
    let mut files = RunFiles::open(args, &scene, &sim)?;
    announce(args, &scene, steps);
    files.write_first(&sim)?;
    let stop = stop_on_signals()?;
    let start = Instant::now();
    if let Some(s) = step_loop(args, &scene, &mut sim, steps, &mut files, &stop)? {
        return Err(files.stopped(&sim, s, steps));
    }
    files.write_last_checkpoint(&sim, steps == 0 || sim.world.step % scene.output_every != 0)?;
    let times = RunTimes {
        seconds: start.elapsed().as_secs_f64(),
        checkpoint_seconds: files.checkpoint_seconds,
    };
    warn_fallen(&scene, &sim);
    warn_deep_contacts(&sim);
    let summary = RunSummary::of(
        &args.scene,
        &sim,
        first,
        steps,
        times,
        args.output.as_deref(),
    );
    if args.json {
        println!(
            "{}",
            serde_json::to_string(&summary).expect("a summary is plain data")
        );
    } else {
        summary.print();
    }
    Ok(())
}

/// The scene with `--set` over it, its warnings printed.
fn load_scene(args: &RunArgs) -> CliResult<Scene> {
    let scene = Scene::load_with(&args.scene, &args.overrides)
        .map_err(|e| CliError::input(e.to_string()))?;
    for w in &scene.warnings {
        eprintln!("tridem: warning: {w}");
    }
    Ok(scene)
}

/// `--steps`, or what is left to the scene's end from step `first`.
pub(crate) fn steps_to_run(args: &RunArgs, scene: &Scene, first: u64) -> CliResult<u64> {
    let last = (scene.end_time / scene.dt).round() as u64;
    match args.steps {
        Some(n) => Ok(n),
        None if args.resume.is_none() || first < last => Ok(last.saturating_sub(first)),
        None => Err(CliError::finished(format!(
            "the checkpoint is at step {first}, the scene's end ({:e} s) at step {last}: \
             nothing left to run (--steps N runs N more)",
            scene.end_time
        ))),
    }
}

/// What the run is, on one line of standard error.
fn announce(args: &RunArgs, scene: &Scene, steps: u64) {
    eprintln!(
        "{}, {} threads",
        describe(args, scene, steps),
        rayon::current_num_threads()
    );
}

/// The scene, its bodies and effects, the step and the steps to run.
pub(crate) fn describe(args: &RunArgs, scene: &Scene, steps: u64) -> String {
    let c = &scene.census;
    format!(
        "{}: {} particles ({} triangles), {} obstacles, effects: {}; dt {:e} s{}, {steps} steps",
        args.scene.display(),
        c.particles(),
        scene.particle_triangles(),
        c.obstacles(),
        scene.effects.names().join(", "),
        scene.dt,
        scene
            .stable_dt
            .map_or(String::new(), |h| format!(" (stable: {h:.3e} s)")),
    )
}

/// A run's files: its output (`DIR/run.h5`, locked while the run writes)
/// and its checkpoint, or nothing without `--output`.
struct RunFiles {
    out: Option<crate::output::Output>,
    write_first: bool,
    checkpoint: Option<std::path::PathBuf>,
    checkpoint_seconds: f64,
    _lock: Option<crate::output::DirLock>,
}

impl RunFiles {
    /// Resumed into the directory it was written to, the output goes on in
    /// the same file; a fresh run starts its own.
    fn open(args: &RunArgs, scene: &Scene, sim: &Simulation) -> CliResult<RunFiles> {
        let Some(dir) = &args.output else {
            return Ok(RunFiles {
                out: None,
                write_first: false,
                checkpoint: None,
                checkpoint_seconds: 0.0,
                _lock: None,
            });
        };
        let (out, write_first, lock) = crate::output::open_run_output(
            dir,
            args.resume.as_deref(),
            args.overwrite,
            &crate::output::Layout::of(scene, &args.scene)?,
            sim.world.time,
        )?;
        Ok(RunFiles {
            out: Some(out),
            write_first,
            checkpoint: Some(dir.join("checkpoint.h5")),
            checkpoint_seconds: 0.0,
            _lock: Some(lock),
        })
    }

    /// The initial state, when the output starts with this run.
    fn write_first(&mut self, sim: &Simulation) -> CliResult {
        match self.out.as_mut().filter(|_| self.write_first) {
            Some(o) => o.write_step(&sim.frame()),
            None => Ok(()),
        }
    }

    /// An output step: the state, then the checkpoint that goes with it.
    fn write_output_step(&mut self, sim: &Simulation) -> CliResult {
        if let Some(o) = &mut self.out {
            o.write_step(&sim.frame())?;
            self.write_checkpoint(sim)?;
        }
        Ok(())
    }

    fn write_checkpoint(&mut self, sim: &Simulation) -> CliResult {
        if let Some(c) = &self.checkpoint {
            let start = Instant::now();
            checkpoint_file::write(c, &sim.checkpoint())?;
            self.checkpoint_seconds += start.elapsed().as_secs_f64();
        }
        Ok(())
    }

    /// So that a run that ended between output steps can be taken further.
    fn write_last_checkpoint(&mut self, sim: &Simulation, between_outputs: bool) -> CliResult {
        match between_outputs {
            true => self.write_checkpoint(sim),
            false => Ok(()),
        }
    }

    /// A run stopped by a signal after `s` of `steps` steps: its checkpoint
    /// written, the error that says how to go on.
    fn stopped(&mut self, sim: &Simulation, s: u64, steps: u64) -> CliError {
        let resume = match self.write_checkpoint(sim) {
            Err(e) => return e,
            Ok(()) => match &self.checkpoint {
                Some(c) => format!("its state is in {}: go on with --resume", c.display()),
                None => "no checkpoint without --output".into(),
            },
        };
        CliError::runtime(format!(
            "stopped by a signal after {s} of {steps} steps, at step {} (t = {:.6e} s); {resume}",
            sim.world.step, sim.world.time
        ))
    }
}

/// The steps, with their checks, output and progress bar: `Some(s)` when a
/// signal stopped the run after step `s`.
///
/// The whole loop runs on a worker of the pool, so that parallel sections
/// start from inside it, and the other workers poll instead of sleeping
/// between sections (see dem::busy_workers; measured on the hopper: waking
/// threads took 25-40% of a run on a 2-core machine).
fn step_loop(
    args: &RunArgs,
    scene: &Scene,
    sim: &mut Simulation,
    steps: u64,
    files: &mut RunFiles,
    stop: &AtomicBool,
) -> CliResult<Option<u64>> {
    let bar = progress_bar(steps, args.quiet);
    let mut deep_steps = 0;
    let looped = dem::busy_workers::with_busy_workers(|| {
        for s in 1..=steps {
            sim.step();
            deep_steps = match sim.last_stats().detection.deep_contacts {
                0 => 0,
                _ => deep_steps + 1,
            };
            refuse_lasting_crossings(scene, sim, deep_steps)?;
            refuse_non_finite_state(sim, s)?;
            // Output steps count from the start of the run, resumed or not.
            if sim.world.step.is_multiple_of(scene.output_every) {
                files.write_output_step(sim)?;
            }
            if s % 64 == 0 || s == steps {
                bar.set_position(s);
            }
            if stop.load(Ordering::Relaxed) {
                return Ok(Some(s));
            }
        }
        Ok(None)
    });
    match looped {
        Ok(None) => bar.finish_and_clear(),
        _ => bar.abandon(),
    }
    looped
}

pub(crate) fn progress_bar(steps: u64, quiet: bool) -> ProgressBar {
    let bar = ProgressBar::new(steps).with_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} steps {elapsed} eta {eta}")
            .expect("template")
            .progress_chars("=> "),
    );
    if quiet {
        bar.set_draw_target(indicatif::ProgressDrawTarget::hidden());
    }
    bar
}

/// Every state variable of every body must stay finite.
fn refuse_non_finite_state(sim: &Simulation, s: u64) -> CliResult {
    let finite = |b: &dem::body::Body| {
        b.x.is_finite() && b.v.is_finite() && b.q.is_finite() && b.l.is_finite()
    };
    if sim.world.bodies.iter().all(finite) {
        return Ok(());
    }
    Err(CliError::runtime(format!(
        "the simulation became non-finite at step {s} (t = {:e} s): \
         the time step is too large for this scene",
        sim.world.time
    )))
}

fn warn_deep_contacts(sim: &Simulation) {
    let deep = sim.totals.detection.deep_contacts;
    if deep > 0 {
        eprintln!(
            "tridem: warning: {deep} contacts went deeper than the particles' halos \
             (triangles crossed); raise the stiffness or the halo, or lower the impact speed"
        );
    }
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

/// The run's simulation, new (refused when bodies cross at the start) or
/// resumed from a checkpoint, and its first step.
fn start(args: &RunArgs, scene: &Scene) -> CliResult<(Simulation, u64)> {
    match &args.resume {
        None => {
            let sim = Simulation::new(scene);
            if !scene.allow_deep_contacts {
                let enclosed = sim.world.enclosed_pairs();
                refuse_overlaps_at_start(scene, &sim.crossed_pairs(), &enclosed)?;
            }
            Ok((sim, 0))
        }
        Some(file) => {
            let c = checkpoint_file::read(file)?;
            let sim = Simulation::resume(scene, &c).map_err(|e| misfit(args, file, e))?;
            Ok((sim, c.step))
        }
    }
}

/// A checkpoint that does not fit the run's scene.
pub(crate) fn misfit(
    args: &RunArgs,
    file: &std::path::Path,
    e: impl std::fmt::Display,
) -> CliError {
    CliError::input(format!(
        "{}: does not fit the scene {}: {e}",
        file.display(),
        args.scene.display()
    ))
}

/// Whether an MPI launcher started this process: mpirun (Open MPI, its
/// PRRTE runtime, MPICH's Hydra) and srun with a PMI or PMIx plugin all set
/// one of these.
fn launched_by_mpi() -> bool {
    ["OMPI_COMM_WORLD_SIZE", "PMIX_RANK", "PMI_RANK", "PMI_SIZE"]
        .iter()
        .any(|v| std::env::var_os(v).is_some())
}

/// Steps in a row with contacts deeper than the halos after which a run
/// stops: a contact that crosses for this long is not holding its bodies
/// apart (too soft, or hit too fast), and what follows is not physics.
pub(crate) const DEEP_STEPS: u64 = 100;

/// Bodies whose surfaces cross at the start are refused, and a run whose
/// contacts stay crossed for [`DEEP_STEPS`] steps stops, naming the pair,
/// unless the scene sets `simulation.allow_deep_contacts`. `crossed`: the
/// pairs (a, b, depth) crossing, by id.
pub(crate) fn refuse_crossings(
    scene: &Scene,
    crossed: &[(usize, usize, f64)],
    when: &str,
) -> CliResult {
    if scene.allow_deep_contacts {
        return Ok(());
    }
    let Some(&(a, b, depth)) = crossed.iter().max_by(|x, y| x.2.total_cmp(&y.2)) else {
        return Ok(());
    };
    Err(CliError::input(format!(
        "{} and {} cross by {depth:e} m (deeper than their halos) {when}{}: move them apart, \
         raise the stiffness or the halo, or lower dt or the speed; \
         simulation.allow_deep_contacts = true lets the run go on",
        scene.body_name(a),
        scene.body_name(b),
        and_more(crossed.len())
    )))
}

/// ", as do N more pairs" after the first of `n` pairs named.
fn and_more(n: usize) -> String {
    match n {
        0 | 1 => String::new(),
        n => format!(", as do {} more pairs", n - 1),
    }
}

/// A new run is refused when bodies start crossing, or when one starts
/// wholly inside another (no contact sees that: their surfaces need not
/// meet), unless the scene sets `simulation.allow_deep_contacts`.
/// `enclosed`: pairs (inner, outer) by id, sorted.
pub(crate) fn refuse_overlaps_at_start(
    scene: &Scene,
    crossed: &[(usize, usize, f64)],
    enclosed: &[(usize, usize)],
) -> CliResult {
    refuse_crossings(scene, crossed, "at the start")?;
    if scene.allow_deep_contacts {
        return Ok(());
    }
    let Some(&(inner, outer)) = enclosed.first() else {
        return Ok(());
    };
    Err(CliError::input(format!(
        "{} lies wholly inside {} at the start{}: move it out; \
         simulation.allow_deep_contacts = true lets the run go on",
        scene.body_name(inner),
        scene.body_name(outer),
        and_more(enclosed.len())
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
    refuse_crossings(scene, &sim.crossed_pairs(), &when)
        .map_err(|e| CliError::runtime(e.to_string()))
}

/// Warns of particles that ended below every obstacle, along gravity: they
/// fell through a wall (too fast for the step, or too soft a contact) or
/// out of the scene, and what they do no longer means anything.
pub(crate) fn warn_fallen(scene: &Scene, sim: &Simulation) {
    let Some(down) = scene
        .effects
        .get::<dem::effects::GravityParams>()
        .and_then(|g| g.g().try_normalize())
    else {
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
