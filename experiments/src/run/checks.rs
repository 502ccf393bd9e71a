//! The checks a run makes of its command line and of its bodies, with the
//! errors that name what is wrong and how to go on. The simulations find
//! what is wrong (crossed pairs, a non-finite state); these say it.

use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use dem::scene::Scene;

/// Steps in a row with contacts deeper than the halos after which a run
/// stops: a contact that crosses for this long is not holding its bodies
/// apart (too soft, or hit too fast), and what follows is not physics.
pub(crate) const DEEP_STEPS: u64 = 100;

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

/// The error that stops a run whose contacts stayed deeper than the halos
/// for [`DEEP_STEPS`] steps, at `step` and `time`, naming the deepest pair
/// of `crossed` (`None`: another rank reports it).
pub(crate) fn lasting_crossings(
    scene: &Scene,
    step: u64,
    time: f64,
    crossed: Option<Vec<(usize, usize, f64)>>,
) -> CliError {
    let when =
        format!("for {DEEP_STEPS} steps in a row (step {step}, t = {time:e} s); the run stops");
    let Some(crossed) = crossed else {
        return CliError::reported_elsewhere(1);
    };
    match refuse_crossings(scene, &crossed, &when) {
        Err(e) => CliError::runtime(e.to_string()),
        // Deep in the step before last, apart since.
        Ok(()) => CliError::runtime(format!(
            "contacts stayed deeper than the halos {when}; \
             simulation.allow_deep_contacts = true lets the run go on"
        )),
    }
}
