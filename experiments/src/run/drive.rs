//! The step loop every run goes through, on one process or split across
//! ranks: the steps, the checks of their state, the output steps and
//! checkpoints, the progress bar and the stop on a signal are written once,
//! here, over [`Driven`], so that the two ways to run cannot drift apart.

use super::checks::{lasting_crossings, DEEP_STEPS};
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use dem::scene::Scene;
use indicatif::{ProgressBar, ProgressStyle};
use std::path::Path;
use std::sync::atomic::{AtomicBool, Ordering};

/// A simulation the step loop drives: one process's, or this rank's part
/// of a split one (whose every method is then collective, and returns the
/// same outcome on every rank).
pub(crate) trait Driven {
    /// One step; `Ok(true)` when a stop was asked (`stop` here, or on any
    /// rank). A state the step left non-finite is the error.
    fn step(&mut self, stop: bool) -> CliResult<bool>;
    /// The step the state is at.
    fn step_number(&self) -> u64;
    fn time(&self) -> f64;
    /// Steps in a row, up to the last, that found a contact deeper than the
    /// halos.
    fn deep_steps_in_a_row(&self) -> u64;
    /// The body pairs crossing now, (a, b, depth) by id; `None` on a rank
    /// that does not report them.
    fn crossed_pairs(&self) -> Option<Vec<(usize, usize, f64)>>;
    /// Writes the present state as an output step (`output`) and as the
    /// checkpoint (`checkpoint`), where the run writes files.
    fn write(&mut self, output: bool, checkpoint: bool) -> CliResult;
    /// Where the checkpoint is written, if the run writes one (on the rank
    /// that writes).
    fn checkpoint_path(&self) -> Option<&Path>;
    /// What follows step `s` of the run (`last`: the run's last, or the
    /// step it stops or fails after): metrics.
    fn after_step(&mut self, _s: u64, _last: bool) -> CliResult {
        Ok(())
    }
    /// An error reached together (on every rank, when split), reported once.
    fn together(&self, e: CliError) -> CliError {
        e
    }
    /// Whether this process shows the progress bar.
    fn shows_progress(&self) -> bool {
        true
    }
}

/// Runs `steps` steps with their checks, output steps (at the scene's
/// `output_every`, counted from the run's start, resumed or not) and
/// progress bar; then, so that a run that ended between output steps can be
/// taken further, its checkpoint. A signal ends the run after the step under
/// way, with its checkpoint written, as an error that says how to go on.
pub(crate) fn run_steps(
    run: &mut impl Driven,
    args: &RunArgs,
    scene: &Scene,
    steps: u64,
    stop: &AtomicBool,
) -> CliResult {
    let bar = progress_bar(steps, args.quiet || !run.shows_progress());
    let looped = step_loop(run, scene, steps, stop, &bar);
    match looped {
        Ok(None) => bar.finish_and_clear(),
        _ => bar.abandon(),
    }
    if let Some(s) = looped? {
        return Err(stopped(run, s, steps));
    }
    if steps == 0 || !run.step_number().is_multiple_of(scene.output_every) {
        run.write(false, true)?;
    }
    Ok(())
}

/// The steps: `Some(s)` when a signal stopped the run after step `s`.
fn step_loop(
    run: &mut impl Driven,
    scene: &Scene,
    steps: u64,
    stop: &AtomicBool,
    bar: &ProgressBar,
) -> CliResult<Option<u64>> {
    for s in 1..=steps {
        let stopping = run.step(stop.load(Ordering::Relaxed))?;
        let crossing = run.deep_steps_in_a_row() >= DEEP_STEPS && !scene.allow_deep_contacts;
        run.after_step(s, s == steps || stopping || crossing)?;
        if crossing {
            let crossed = run.crossed_pairs();
            let e = lasting_crossings(scene, run.step_number(), run.time(), crossed);
            return Err(run.together(e));
        }
        if run.step_number().is_multiple_of(scene.output_every) {
            run.write(true, true)?;
        }
        if s % 16 == 0 || s == steps {
            bar.set_position(s);
        }
        if stopping {
            return Ok(Some(s));
        }
    }
    Ok(None)
}

/// A run stopped by a signal after `s` of `steps` steps: its checkpoint
/// written, the error that says how to go on.
fn stopped(run: &mut impl Driven, s: u64, steps: u64) -> CliError {
    if let Err(e) = run.write(false, true) {
        return e;
    }
    let resume = match run.checkpoint_path() {
        Some(c) => format!("its state is in {}: go on with --resume", c.display()),
        None => "no checkpoint without --output".into(),
    };
    let e = CliError::runtime(format!(
        "stopped by a signal after {s} of {steps} steps, at step {} (t = {:.6e} s); {resume}",
        run.step_number(),
        run.time()
    ));
    run.together(e)
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
        stable_note(scene),
    )
}

/// The stable steps the header quotes: of one contact, and, with rotation,
/// of a particle rocking on its corners (below which a state at rest stays
/// at rest; docs/dem.md, "Stable time step").
fn stable_note(scene: &Scene) -> String {
    match (scene.stable_dt, scene.rocking_dt) {
        (Some(h), Some(r)) => format!(" (stable: {h:.3e} s; at rest: {r:.3e} s)"),
        (Some(h), None) => format!(" (stable: {h:.3e} s)"),
        _ => String::new(),
    }
}
