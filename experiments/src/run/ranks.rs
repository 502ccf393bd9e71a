//! `mpirun -np P tridem run SCENE`: the DEM split across P ranks
//! (`distributed`), with the output, checkpoints and summary of a one-node
//! run, written by rank 0 from what it gathers, and per-rank metrics.
//!
//! Every check of the input runs before anything is written: the output
//! directory is made only once the run has started on every rank. A bad
//! input ends every rank with one message between them.

use super::checks::{misfit, refuse_overlaps_at_start, refuse_resume_without_output};
use super::drive::{describe, run_steps, steps_to_run, Driven};
use super::signals::stop_on_signals;
use crate::checkpoint_file;
use crate::cli::RunArgs;
use crate::error::{CliError, CliResult};
use crate::output::{Layout, Output};
use dem::checkpoint::CheckpointShare;
use dem::scene::{Deal, Scene};
use distributed::metrics::{imbalance, json_line, per_step_imbalance, per_step_work_imbalance};
use distributed::{DistributedSimulation, Settings, Start, StepMetrics};
use mpi::collective::SystemOperation;
use mpi::topology::SimpleCommunicator;
use mpi::traits::*;
use partition::comm::gather_v;
use std::io::Write;
use std::path::Path;
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

/// An error every rank reached together (the same on all): rank 0 reports it.
fn on_every_rank(comm: &SimpleCommunicator, e: CliError) -> CliError {
    let code = e.exit_code();
    reported_by(comm, 0, Some(e), code)
}

/// What rank 0 writes: output steps, checkpoints and metrics.
struct Writer {
    /// Held while the run writes its directory.
    _lock: Option<crate::output::DirLock>,
    out: Option<Output>,
    checkpoint: Option<std::path::PathBuf>,
    metrics: Option<(std::path::PathBuf, std::io::BufWriter<std::fs::File>)>,
    /// Whether the present state is still to be written as an output step.
    first: bool,
}

pub(crate) fn run(args: &RunArgs, comm: &SimpleCommunicator) -> CliResult {
    let me = comm.rank();
    // A batch system's time limit signals every rank; each stops after the
    // step under way, and all agree on it within that step. Handled from
    // the start, so that no signal finds a rank without its handler.
    let stop = stop_on_signals()?;
    agree(comm, refuse_resume_without_output(args))?;
    agree(comm, refuse_metrics_over(args))?;
    let mut scene = agree(
        comm,
        Scene::load_dealt_with(&args.scene, &args.overrides, share(comm))
            .map_err(|e| CliError::input(e.to_string())),
    )?;
    if me == 0 {
        for w in &scene.warnings {
            eprintln!("tridem: warning: {w}");
        }
    }
    let settings = agree(comm, crate::parallel::settings(args, &scene))?;
    let layout = match me {
        0 => Layout::of(&scene, &args.scene).map(Some),
        _ => crate::output::fields_of(&scene, &args.scene).map(|_| None),
    };
    let layout = agree(comm, layout)?;
    // Cores are shared by the ranks of a node: one thread each unless told.
    // The main thread is one of the pool's: a parallel section starts in
    // place instead of being handed to another thread and waited for (which
    // cost more than a small rank's detection), and MPI is still called from
    // the main thread only (MPI_THREAD_FUNNELED).
    let threads = args.threads.unwrap_or(1);
    agree(
        comm,
        rayon::ThreadPoolBuilder::new()
            .num_threads(threads)
            .use_current_thread()
            .build_global()
            .map_err(|e| CliError::runtime(e.to_string())),
    )?;
    let particles = scene.census.particles();
    let resumed = agree(comm, read_checkpoint(args, share(comm), particles))?;
    let first = resumed.as_ref().map_or(0, |c| c.step);
    let steps = agree(comm, steps_to_run(args, &scene, first))?;
    let start_with = match &resumed {
        Some(c) => Start::Resume(c),
        None => Start::Fresh,
    };
    let told = describe(args, &scene, steps);
    let dist = DistributedSimulation::new(comm, &mut scene, start_with, settings);
    let dist = agree(
        comm,
        dist.map_err(|e| match &args.resume {
            Some(file) => misfit(args, file, e),
            None => CliError::runtime(e),
        }),
    )?;
    drop(resumed);
    if args.resume.is_none() && !scene.allow_deep_contacts {
        let refused = refuse_start(&scene, &dist);
        agree(comm, refused)?;
    }
    // Only rank 0 touches the disk, once every check has passed; the
    // others learn whether it could.
    let writer = match me {
        0 => open_writer(args, layout.as_ref(), dist.time()).map(Some),
        _ => Ok(None),
    };
    let mut writer = agree(comm, writer)?;
    let first_frame = writer.as_ref().is_some_and(|w| w.first);
    let wants_first = agree_flag(comm, first_frame);
    if wants_first {
        let written = write_gathered(&dist, writer.as_mut(), true, false);
        agree(comm, written)?;
    }
    if me == 0 {
        announce(&told, &settings, comm.size(), threads);
    }
    let start = Instant::now();
    let mut run = Ranks {
        comm,
        args,
        dist,
        writer,
        totals: StepMetrics::default(),
        interval: StepMetrics::default(),
        pending: Vec::new(),
    };
    run_steps(&mut run, args, &scene, steps, &stop)?;
    let secs = start.elapsed().as_secs_f64();
    summary(comm, args, &run.dist, &run.totals, steps, secs);
    Ok(())
}

/// The scene's particles this rank keeps from the start.
fn share(comm: &SimpleCommunicator) -> Deal {
    Deal {
        rank: comm.rank() as u32,
        ranks: comm.size() as u32,
    }
}

/// A metrics file that exists is replaced only with --overwrite.
fn refuse_metrics_over(args: &RunArgs) -> CliResult {
    match args
        .metrics
        .as_ref()
        .filter(|m| m.exists() && !args.overwrite)
    {
        Some(m) => Err(CliError::input(format!(
            "{}: exists; choose another metrics file or replace it with --overwrite",
            m.display()
        ))),
        None => Ok(()),
    }
}

/// This rank's share of the checkpoint to resume from (each rank reads its
/// own rows; rank 0 checks the whole file).
fn read_checkpoint(
    args: &RunArgs,
    deal: Deal,
    particles: usize,
) -> CliResult<Option<CheckpointShare>> {
    match &args.resume {
        Some(file) => checkpoint_file::read_share(file, deal, particles).map(Some),
        None => Ok(None),
    }
}

/// Whether `mine` (rank 0's) holds: told to every rank (collective).
fn agree_flag(comm: &SimpleCommunicator, mine: bool) -> bool {
    let mut flag = u8::from(mine);
    comm.process_at_rank(0).broadcast_into(&mut flag);
    flag == 1
}

/// A new run whose bodies cross or lie inside one another at the start is
/// refused (collective; the error on rank 0).
fn refuse_start(scene: &Scene, dist: &DistributedSimulation) -> CliResult {
    let crossed = dist.crossed_pairs();
    let enclosed = dist.enclosed_pairs();
    let (Some(crossed), Some(enclosed)) = (crossed, enclosed) else {
        return Ok(());
    };
    let crossed: Vec<(usize, usize, f64)> = crossed
        .into_iter()
        .map(|(a, b, d)| (a as usize, b as usize, d))
        .collect();
    let enclosed: Vec<(usize, usize)> = enclosed
        .into_iter()
        .map(|(a, b)| (a as usize, b as usize))
        .collect();
    refuse_overlaps_at_start(scene, &crossed, &enclosed)
}

/// What the run is (`told`: the scene), on one line of rank 0's standard error.
fn announce(told: &str, settings: &Settings, ranks: i32, threads: usize) {
    let every = settings
        .repartition_every
        .map(|k| format!("every {k} steps"));
    let when = settings
        .repartition_when
        .map(|t| format!("when the busy imbalance exceeds {t}"));
    let repartition = match (every, when) {
        (Some(e), Some(w)) => format!("{e} and {w}"),
        (Some(x), None) | (None, Some(x)) => x,
        (None, None) => "at the start only".into(),
    };
    let fresh = if settings.reuse {
        ""
    } else {
        " (from scratch)"
    };
    eprintln!(
        "{told}, {ranks} ranks x {threads} threads, {}, {} exchange, repartition {repartition}{fresh}, \
         weights {}",
        settings.partitioner.name(),
        settings.exchange.name(),
        settings.weights.name(),
    );
}

/// This rank's part of the run, driven by the step loop: each method is
/// collective, and ends every rank with the same outcome.
struct Ranks<'a> {
    comm: &'a SimpleCommunicator,
    args: &'a RunArgs,
    dist: DistributedSimulation<'a>,
    writer: Option<Writer>,
    /// The run's metrics so far, those of the interval not yet ended, and
    /// the ended intervals not yet written.
    totals: StepMetrics,
    interval: StepMetrics,
    pending: Vec<StepMetrics>,
}

/// Metrics lines gathered and written together. A line gathered and
/// written alone makes every rank meet once more each interval, and the
/// time rank 0 spends writing it the others spend waiting: with a line per
/// step, a cost comparable with a short step's own. The lines, and what
/// they say, are the same either way.
const LINES_AT_ONCE: usize = 64;

impl Ranks<'_> {
    /// Writes the ended intervals' lines (collective).
    fn flush_metrics(&mut self) -> CliResult {
        if self.pending.is_empty() {
            return Ok(());
        }
        let written = write_metrics(self.comm, &self.pending, self.writer.as_mut());
        self.pending.clear();
        agree(self.comm, written)
    }
}

impl Driven for Ranks<'_> {
    /// The step's failures are all-reduced within it: every rank has the
    /// same outcome.
    fn step(&mut self, stop: bool) -> CliResult<bool> {
        let stepped = self.dist.step(stop).map_err(CliError::runtime);
        if stepped.is_err() {
            // Every rank fails this step together: the lines of the steps
            // before it are still written, and the step's failure is the
            // error reported.
            let _ = self.flush_metrics();
        }
        stepped.map_err(|e| on_every_rank(self.comm, e))
    }

    fn step_number(&self) -> u64 {
        self.dist.step_number()
    }

    fn time(&self) -> f64 {
        self.dist.time()
    }

    fn deep_steps_in_a_row(&self) -> u64 {
        self.dist.deep_steps_in_a_row()
    }

    fn crossed_pairs(&self) -> Option<Vec<(usize, usize, f64)>> {
        let by_id = |(a, b, d): (u32, u32, f64)| (a as usize, b as usize, d);
        (self.dist.crossed_pairs()).map(|c| c.into_iter().map(by_id).collect())
    }

    fn write(&mut self, output: bool, checkpoint: bool) -> CliResult {
        if self.args.output.is_none() {
            return Ok(());
        }
        let written = write_gathered(&self.dist, self.writer.as_mut(), output, checkpoint);
        agree(self.comm, written)
    }

    fn checkpoint_path(&self) -> Option<&Path> {
        self.writer.as_ref().and_then(|w| w.checkpoint.as_deref())
    }

    /// The metrics: summed for the summary, and written every
    /// `--metrics-every` steps.
    fn after_step(&mut self, s: u64, last: bool) -> CliResult {
        self.totals.accumulate(self.dist.metrics());
        self.interval.extend_interval(self.dist.metrics());
        if self.args.metrics.is_some() && (s.is_multiple_of(self.args.metrics_every) || last) {
            self.pending.push(std::mem::take(&mut self.interval));
            if self.pending.len() >= LINES_AT_ONCE || last {
                self.flush_metrics()?;
            }
        }
        Ok(())
    }

    fn together(&self, e: CliError) -> CliError {
        match agree(self.comm, Err::<(), _>(e)) {
            Err(e) => e,
            Ok(()) => unreachable!("an error on every rank"),
        }
    }

    fn shows_progress(&self) -> bool {
        self.comm.rank() == 0
    }
}

/// Rank 0's output, checkpoint and metrics files (`layout`: the scene's).
fn open_writer(args: &RunArgs, layout: Option<&Layout>, time: f64) -> CliResult<Writer> {
    let (out, first, lock) = match (&args.output, layout) {
        (Some(dir), Some(layout)) => {
            let (o, first, lock) = crate::output::open_run_output(
                dir,
                args.resume.as_deref(),
                args.overwrite,
                layout,
                time,
            )?;
            (Some(o), first, Some(lock))
        }
        _ => (None, false, None),
    };
    let metrics =
        match &args.metrics {
            Some(m) => Some((
                m.clone(),
                std::io::BufWriter::new(std::fs::File::create(m).map_err(|e| {
                    CliError::runtime(format!("{}: cannot write: {e}", m.display()))
                })?),
            )),
            None => None,
        };
    Ok(Writer {
        _lock: lock,
        out,
        checkpoint: args.output.as_ref().map(|d| d.join("checkpoint.h5")),
        metrics,
        first,
    })
}

/// Gathers the state on rank 0 and writes, with `output`, an output step,
/// and with `checkpoint`, the checkpoint. Collective.
fn write_gathered(
    dist: &DistributedSimulation,
    writer: Option<&mut Writer>,
    output: bool,
    checkpoint: bool,
) -> CliResult {
    let Some(mut gathered) = dist.gather(output) else {
        return Ok(());
    };
    let Some(w) = writer else {
        return Ok(());
    };
    if let Some(o) = w.out.as_mut() {
        gathered.show(|f| o.write_step(f)).transpose()?;
    }
    match (&w.checkpoint, checkpoint) {
        (Some(path), true) => checkpoint_file::write(path, &gathered.checkpoint),
        _ => Ok(()),
    }
}

/// Gathers the metrics of `intervals` on rank 0, which writes a JSON line
/// for each. Collective (on every rank, when the run writes metrics; every
/// rank holds the same number of intervals).
fn write_metrics(
    comm: &SimpleCommunicator,
    intervals: &[StepMetrics],
    writer: Option<&mut Writer>,
) -> CliResult {
    let all = gather_v(comm, 0, intervals);
    let (Some(all), Some((path, file))) = (all, writer.and_then(|w| w.metrics.as_mut())) else {
        return Ok(());
    };
    let n = intervals.len();
    let mut lines = (0..n).map(|k| {
        all.iter()
            .skip(k)
            .step_by(n.max(1))
            .copied()
            .collect::<Vec<_>>()
    });
    lines
        .try_for_each(|ranks| writeln!(file, "{}", json_line(&ranks)))
        .and_then(|_| file.flush())
        .map_err(|e| CliError::runtime(format!("{}: cannot write: {e}", path.display())))
}

/// This process's peak resident memory (bytes), from /proc (0 where there
/// is none).
pub fn peak_rss() -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").unwrap_or_default();
    status
        .lines()
        .find_map(|l| l.strip_prefix("VmHWM:"))
        .and_then(|v| v.split_whitespace().next())
        .and_then(|kb| kb.parse::<u64>().ok())
        .map_or(0, |kb| kb * 1024)
}

/// Rank 0 prints the run's summary: time per step and, per metric, its
/// minimum, mean and maximum over the ranks (collective).
fn summary(
    comm: &SimpleCommunicator,
    args: &RunArgs,
    dist: &DistributedSimulation,
    totals: &StepMetrics,
    steps: u64,
    secs: f64,
) {
    let ranks = gather_v(comm, 0, std::slice::from_ref(totals));
    let rss = gather_v(comm, 0, &[peak_rss()]);
    let mine = [
        dist.totals.detection.deep_contacts,
        dist.totals.detection.triangle_pairs,
    ];
    let mut stats = [0u64; 2];
    comm.all_reduce_into(&mine[..], &mut stats[..], SystemOperation::sum());
    let measures = dist.measures();
    let (Some(ranks), Some(rss), Some(measures)) = (ranks, rss, measures) else {
        return;
    };
    let per_step = |v: f64| v / steps.max(1) as f64;
    let mut table = serde_json::Map::new();
    for (name, _) in StepMetrics::default().fields() {
        let column: Vec<f64> = ranks
            .iter()
            .map(|m| per_step(m.fields().iter().find(|f| f.0 == name).map_or(0.0, |f| f.1)))
            .collect();
        table.insert(name.into(), min_mean_max(&column));
    }
    let sections: Vec<f64> = ranks.iter().map(|m| per_step(m.sections())).collect();
    table.insert("sections_seconds".into(), min_mean_max(&sections));
    let contacts = ranks.iter().map(|m| m.contacts).sum::<u64>();
    let particles = dist.particles();
    let rss_f: Vec<f64> = rss.iter().map(|&b| b as f64).collect();
    let summary = serde_json::json!({
        "scene": args.scene.display().to_string(),
        "ranks": ranks.len(),
        "threads": rayon::current_num_threads(),
        "steps": steps,
        "last_step": dist.step_number(),
        "particles": particles,
        "seconds": secs,
        "seconds_per_step": secs / steps.max(1) as f64,
        "seconds_per_particle_step": secs / (steps.max(1) as f64 * particles as f64),
        "contacts": contacts,
        "deep_contacts": stats[0],
        "triangle_pairs_checked": stats[1],
        "triangle_imbalance": imbalance(ranks.iter().map(|m| m.owned_triangles as f64)),
        "busy_imbalance": imbalance(ranks.iter().map(|m| m.busy_seconds)),
        "busy_imbalance_per_step": per_step_imbalance(&ranks),
        "work_imbalance_per_step": per_step_work_imbalance(&ranks),
        "peak_rss_bytes": min_mean_max(&rss_f),
        "per_step_over_ranks": table,
        "measures": crate::run_summary::measure_map(measures),
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
        "imbalance              triangles {:.3}, busy time {:.3} over the run, {:.3} step by step, modelled work {:.3} step by step (max/mean)",
        summary["triangle_imbalance"].as_f64().unwrap_or(1.0),
        summary["busy_imbalance"].as_f64().unwrap_or(1.0),
        summary["busy_imbalance_per_step"].as_f64().unwrap_or(1.0),
        summary["work_imbalance_per_step"].as_f64().unwrap_or(1.0)
    );
    let mib = |b: f64| b / (1u64 << 20) as f64;
    let max_rss = rss_f.iter().copied().fold(0.0, f64::max);
    let mean_rss = rss_f.iter().sum::<f64>() / rss_f.len() as f64;
    println!(
        "peak memory per rank   {:.1} MiB mean, {:.1} MiB max",
        mib(mean_rss),
        mib(max_rss)
    );
    println!(
        "per step, over ranks   {:>12} {:>12} {:>12}",
        "min", "mean", "max"
    );
    for (name, v) in &table {
        let f = |k: &str| v[k].as_f64().unwrap_or(0.0);
        println!(
            "  {name:<24} {:>12.4e} {:>12.4e} {:>12.4e}",
            f("min"),
            f("mean"),
            f("max")
        );
    }
    if let Some(m) = summary["measures"].as_object() {
        crate::run_summary::print_measures(m);
    }
    if let Some(dir) = &args.output {
        crate::run_summary::print_output_lines(dir, dist.step_number());
    }
}

fn min_mean_max(column: &[f64]) -> serde_json::Value {
    let min = column.iter().copied().fold(f64::INFINITY, f64::min);
    let max = column.iter().copied().fold(f64::NEG_INFINITY, f64::max);
    let mean = column.iter().sum::<f64>() / column.len().max(1) as f64;
    serde_json::json!({"min": min, "mean": mean, "max": max})
}
