//! `tridem run SCENE` on one process: the simulation on this node's
//! threads, its HDF5 output and checkpoints, and a summary.

use super::checks::{misfit, refuse_overlaps_at_start, refuse_resume_without_output};
use super::drive::{describe, run_steps, steps_to_run, Driven};
use super::signals::stop_on_signals;
use crate::checkpoint_file;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::run_summary::{RunSummary, RunTimes};
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;
use std::time::Instant;

pub(crate) fn run(args: &RunArgs) -> CliResult {
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
    let (sim, first) = start(args, &scene)?;
    let steps = steps_to_run(args, &scene, first)?;
    let files = RunFiles::open(args, &scene, &sim)?;
    announce(args, &scene, steps);
    let mut node = Node { sim, files };
    node.files.write_first(&node.sim)?;
    let stop = stop_on_signals()?;
    let start = Instant::now();
    // The whole loop runs on a worker of the pool, so that parallel sections
    // start from inside it, and the other workers poll instead of sleeping
    // between sections (see dem::busy_workers; measured on the hopper: waking
    // threads took 25-40% of a run on a 2-core machine).
    dem::busy_workers::with_busy_workers(|| run_steps(&mut node, args, &scene, steps, &stop))?;
    let Node { sim, files } = node;
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

/// The simulation and the files it writes, driven by the step loop.
struct Node {
    sim: Simulation,
    files: RunFiles,
}

impl Driven for Node {
    fn step(&mut self, stop: bool) -> CliResult<bool> {
        self.sim.step();
        self.sim
            .check()
            .map_err(|e| CliError::runtime(e.to_string()))?;
        Ok(stop)
    }

    fn step_number(&self) -> u64 {
        self.sim.world.step
    }

    fn time(&self) -> f64 {
        self.sim.world.time
    }

    fn deep_steps_in_a_row(&self) -> u64 {
        self.sim.deep_steps_in_a_row()
    }

    fn crossed_pairs(&self) -> Option<Vec<(usize, usize, f64)>> {
        Some(self.sim.crossed_pairs())
    }

    fn write(&mut self, output: bool, checkpoint: bool) -> CliResult {
        if output {
            self.files.write_output_step(&self.sim)?;
        }
        if checkpoint {
            self.files.write_checkpoint(&self.sim)?;
        }
        Ok(())
    }

    fn checkpoint_path(&self) -> Option<&Path> {
        self.files.checkpoint.as_deref()
    }
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

/// What the run is, on one line of standard error.
fn announce(args: &RunArgs, scene: &Scene, steps: u64) {
    eprintln!(
        "{}, {} threads",
        describe(args, scene, steps),
        rayon::current_num_threads()
    );
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

    /// An output step: the state as the output shows it.
    fn write_output_step(&mut self, sim: &Simulation) -> CliResult {
        match &mut self.out {
            Some(o) => o.write_step(&sim.frame()),
            None => Ok(()),
        }
    }

    fn write_checkpoint(&mut self, sim: &Simulation) -> CliResult {
        if let Some(c) = &self.checkpoint {
            let start = Instant::now();
            checkpoint_file::write(c, &sim.checkpoint())?;
            self.checkpoint_seconds += start.elapsed().as_secs_f64();
        }
        Ok(())
    }
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

/// Warns of particles that ended below every obstacle, along gravity: they
/// fell through a wall (too fast for the step, or too soft a contact) or
/// out of the scene, and what they do no longer means anything. Not when an
/// effect takes particles out: the scene then says where particles leave,
/// and those below every obstacle are falling towards it (a silo's outflow
/// plane under its floor).
fn warn_fallen(scene: &Scene, sim: &Simulation) {
    if sim.removes_particles() {
        return;
    }
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
        .filter(|&i| {
            let b = &w.bodies[i];
            !b.is_static() && !b.is_out() && b.x.dot(down) > lowest_obstacle
        })
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
