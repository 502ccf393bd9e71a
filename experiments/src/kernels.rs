//! `tridem kernels`: the triangle-distance benchmark and the accuracy-vs-time sweep.
//!
//! Every number is measured in this run, side by side on the same pairs: the
//! rows run in alternating rounds and each time is the median (or, with
//! `--statistic min`, the minimum) over rounds, so ratios between rows are
//! what to read.

use crate::cli::KernelsArgs;
use crate::error::{create_output_dir, CliError, CliResult};
use crate::plot;
use dem::busy_workers::with_busy_workers;
use dem::distance::{
    distance_many, distances, pair_scale, penalty::BATCH_SIZES, penalty_many_on, penalty_scalar,
    random_unit_pairs, Closest, Counts, Fallback, Isa, Method, Options, PenaltyParams,
    PenaltyStats, Threading, Triangle, UnsupportedBatch,
};
use indicatif::{ProgressBar, ProgressStyle};
use serde::Serialize;
use std::time::Instant;

#[derive(Debug, Clone, Serialize)]
pub struct Row {
    pub method: String,
    pub variant: String,
    pub isa: String,
    pub threads: usize,
    pub schedule: String,
    pub batch: usize,
    pub ns_per_pair: f64,
    /// How `ns_per_pair` summarises the repetitions: "median" or "min".
    pub statistic: String,
    pub fallback_rate: Option<f64>,
    pub certified_rate: Option<f64>,
}

pub fn run(args: &KernelsArgs) -> CliResult {
    check_args(args)?;
    if args.accuracy {
        return accuracy_sweep(args);
    }
    let pairs = random_unit_pairs(args.pairs, args.seed);
    let pool = pool(args.threads)?;
    let single = pool_of(1)?;
    let threads = pool.current_num_threads();
    // Every row is one closure over shared output buffers; the closures run in
    // alternating rounds (one repetition of each per round) and each row is the
    // median of its rounds. Run one after the other, a shared machine's speed swings of
    // +-30% between minutes land on whole rows and distort the ratios between
    // them; alternated, every row sees the same swings.
    let mut measures = methods_on_the_pool(args, &pairs, &pool);
    measures.extend(single_thread_kernels(args, &pairs));
    if threads > 1 {
        measures.extend(hybrid_on_one_thread(args, &pairs, &single));
    }
    run_rounds(&mut measures, pairs.len(), args.repeat);
    let rows = rows(measures, args, threads, pairs.len());
    if args.jsonl {
        for r in &rows {
            println!("{}", serde_json::to_string(r).expect("rows serialise"));
        }
    } else if args.json {
        println!(
            "{}",
            serde_json::to_string_pretty(&rows).expect("rows serialise")
        );
    } else {
        print_table(&rows, args.pairs, args.seed, args.statistic.name());
    }
    Ok(())
}

/// The kernel's options for `method` with `fallback`, as the arguments set them.
fn options(args: &KernelsArgs, method: Method, fallback: Fallback) -> Options {
    Options {
        method,
        batch: args.batch,
        fallback,
        threading: Threading {
            schedule: args.schedule,
            grain: args.grain,
        },
        penalty: PenaltyParams::default(),
    }
}

/// Brute force, penalty and the hybrid with both fallbacks, on the pool.
fn methods_on_the_pool<'a>(
    args: &KernelsArgs,
    pairs: &'a [(Triangle, Triangle)],
    pool: &'a rayon::ThreadPool,
) -> Vec<Measure<'a>> {
    [
        (Method::Brute, Fallback::WholeBatch, "exact"),
        (Method::Penalty, Fallback::WholeBatch, "simd"),
        (Method::Hybrid, Fallback::WholeBatch, "whole-batch fallback"),
        (
            Method::Hybrid,
            Fallback::FailedPairs,
            "failed-pairs fallback",
        ),
    ]
    .into_iter()
    .map(|(method, fallback, variant)| on_pool(args, pairs, pool, method, fallback, variant))
    .collect()
}

/// One method of `distance_many` on every thread of `pool`.
fn on_pool<'a>(
    args: &KernelsArgs,
    pairs: &'a [(Triangle, Triangle)],
    pool: &'a rayon::ThreadPool,
    method: Method,
    fallback: Fallback,
    variant: &'static str,
) -> Measure<'a> {
    let o = options(args, method, fallback);
    Measure::new(
        method.name(),
        variant,
        Isa::detect().name(),
        pool.current_num_threads(),
        Box::new(move |out, stats| {
            let (counts, seconds) = timed_on_awake_pool(pool, || {
                distance_many(pairs, &o, out, stats).expect("batch size checked by check_args")
            });
            (Some(counts), seconds)
        }),
    )
}

/// SIMD against scalar, one thread: the penalty kernel and brute force on
/// every instruction set this CPU has (an AVX-512 machine also shows what
/// AVX2 gets), and each one's scalar routine.
fn single_thread_kernels<'a>(
    args: &KernelsArgs,
    pairs: &'a [(Triangle, Triangle)],
) -> Vec<Measure<'a>> {
    let isas: Vec<Isa> = [Isa::Avx512, Isa::Avx2, Isa::Baseline]
        .into_iter()
        .filter(|i| i.available() == *i)
        .collect();
    let batch = args.batch;
    let prm = PenaltyParams::default();
    let mut measures = Vec::new();
    for &chosen in &isas {
        measures.push(Measure::new(
            "penalty",
            "simd, 1 thread",
            chosen.name(),
            1,
            Box::new(move |out, stats| {
                let ((), seconds) = timed(|| {
                    penalty_many_on(pairs, batch, &prm, chosen, out, stats)
                        .expect("batch size checked by check_args")
                });
                (None, seconds)
            }),
        ));
    }
    measures.push(Measure::new(
        "penalty",
        "scalar, 1 thread",
        "baseline",
        1,
        Box::new(move |_, _| {
            let ((), seconds) = timed(|| {
                for (a, b) in pairs {
                    std::hint::black_box(penalty_scalar(a, b, &prm));
                }
            });
            (None, seconds)
        }),
    ));
    for &chosen in &isas {
        measures.push(Measure::new(
            "brute",
            "simd, 1 thread",
            chosen.name(),
            1,
            Box::new(move |out, _| {
                let ((), seconds) =
                    timed(|| dem::distance::distance_triangle_triangle_many_on(pairs, chosen, out));
                (None, seconds)
            }),
        ));
    }
    measures.push(Measure::new(
        "brute",
        "scalar, 1 thread",
        "baseline",
        1,
        Box::new(move |_, _| {
            let ((), seconds) = timed(|| {
                for (a, b) in pairs {
                    std::hint::black_box(dem::distance::distance_triangle_triangle(a, b));
                }
            });
            (None, seconds)
        }),
    ));
    measures
}

/// The hybrid (both fallbacks) on one thread: its thread scaling, measured
/// in the same rounds as the pool's rows.
fn hybrid_on_one_thread<'a>(
    args: &KernelsArgs,
    pairs: &'a [(Triangle, Triangle)],
    single: &'a rayon::ThreadPool,
) -> Vec<Measure<'a>> {
    [
        (Fallback::WholeBatch, "whole-batch fallback"),
        (Fallback::FailedPairs, "failed-pairs fallback"),
    ]
    .into_iter()
    .map(|(fallback, variant)| on_pool(args, pairs, single, Method::Hybrid, fallback, variant))
    .collect()
}

/// A warm-up round, then `rounds` rounds of every measure in turn, into
/// output buffers allocated once (the rows time the kernels, not page faults).
fn run_rounds(measures: &mut [Measure], pairs: usize, rounds: usize) {
    let mut out = vec![Closest::UNSET; pairs];
    let mut stats = vec![PenaltyStats::default(); pairs];
    let bar = ProgressBar::new((measures.len() * (rounds + 1)) as u64);
    bar.set_style(
        ProgressStyle::with_template("{bar:40} {pos}/{len} runs, {elapsed}").expect("template"),
    );
    for round in 0..=rounds {
        for m in measures.iter_mut() {
            let (counts, seconds) = (m.run)(&mut out, &mut stats);
            if round > 0 {
                m.times.push(seconds * 1e9 / pairs.max(1) as f64);
            }
            m.counts = counts.or(m.counts);
            bar.inc(1);
        }
    }
    bar.finish_and_clear();
}

/// Each measure's row: its time by the statistic, and the fallback and
/// certified rates where they mean something.
fn rows(measures: Vec<Measure>, args: &KernelsArgs, threads: usize, pairs: usize) -> Vec<Row> {
    let n = pairs as f64;
    measures
        .into_iter()
        .map(|m| {
            let hybrid = m.method == "hybrid" && m.threads == threads;
            Row {
                schedule: if m.threads > 1 {
                    args.schedule.name().into()
                } else {
                    "serial".into()
                },
                batch: args.batch,
                ns_per_pair: args.statistic.of(m.times),
                statistic: args.statistic.name().into(),
                fallback_rate: m
                    .counts
                    .filter(|_| hybrid)
                    .map(|c| c.fallback_pairs as f64 / n),
                certified_rate: m
                    .counts
                    .filter(|_| m.method != "brute")
                    .map(|c| c.certified as f64 / n),
                method: m.method.into(),
                variant: m.variant.into(),
                isa: m.isa.into(),
                threads: m.threads,
            }
        })
        .collect()
}

fn print_table(rows: &[Row], pairs: usize, seed: u64, statistic: &str) {
    println!("{pairs} random pairs in the unit cube (seed {seed}); {statistic} ns per pair");
    println!(
        "{:<8} {:<22} {:<9} {:>7} {:<8} {:>5} {:>11} {:>9} {:>9}",
        "method",
        "variant",
        "isa",
        "threads",
        "schedule",
        "batch",
        "ns/pair",
        "fallback",
        "certified"
    );
    for r in rows {
        let pct = |x: Option<f64>| {
            x.map(|v| format!("{:.1}%", 100.0 * v))
                .unwrap_or_else(|| "-".into())
        };
        println!(
            "{:<8} {:<22} {:<9} {:>7} {:<8} {:>5} {:>11.1} {:>9} {:>9}",
            r.method,
            r.variant,
            r.isa,
            r.threads,
            r.schedule,
            r.batch,
            r.ns_per_pair,
            pct(r.fallback_rate),
            pct(r.certified_rate)
        );
    }
    let find = |m: &str, v: &str, t: Option<usize>| {
        rows.iter()
            .find(|r| r.method == m && r.variant == v && t.is_none_or(|t| r.threads == t))
            .map(|r| r.ns_per_pair)
    };
    if let (Some(simd), Some(scalar)) = (
        find("penalty", "simd, 1 thread", None),
        find("penalty", "scalar, 1 thread", None),
    ) {
        println!(
            "SIMD speed-up of penalty over its scalar version: {:.2}x",
            scalar / simd
        );
    }
    if let (Some(simd), Some(scalar)) = (
        find("brute", "simd, 1 thread", None),
        find("brute", "scalar, 1 thread", None),
    ) {
        println!(
            "SIMD speed-up of brute force over its scalar version: {:.2}x",
            scalar / simd
        );
    }
    for multi in rows
        .iter()
        .filter(|r| r.method == "hybrid" && r.threads > 1)
    {
        if let Some(one) = find("hybrid", &multi.variant, Some(1)) {
            println!(
                "hybrid ({}), {} threads over 1 thread: {:.2}x",
                multi.variant,
                multi.threads,
                one / multi.ns_per_pair
            );
        }
    }
}

fn accuracy_sweep(args: &KernelsArgs) -> CliResult {
    // Before the sweep, so that a bad path does not cost its minutes.
    create_output_dir(&args.output)?;
    let pairs = random_unit_pairs(args.pairs, args.seed);
    let pool = pool(args.threads.or(Some(1)))?;
    let settings = sweep_settings();
    // Accuracy first, one run per setting (it also warms up); then the times,
    // in rounds that run every setting once, each setting's time the median
    // over rounds: measured one setting after the other, a shared machine's swings of
    // +-30% between minutes gave one setting 73-110 ns/pair within a sweep.
    let bar = ProgressBar::new((settings.len() * (1 + args.repeat)) as u64).with_style(
        ProgressStyle::with_template("{msg:>24} [{bar:30}] {pos}/{len} {elapsed}")
            .expect("template")
            .progress_chars("=> "),
    );
    let mut rows = sweep_accuracy(&pairs, &pool, &settings, &bar);
    bar.set_message("timing");
    time_sweep(&pairs, &pool, &settings, &mut rows, args.repeat, &bar);
    bar.finish_and_clear();
    write_sweep(args, &settings, rows)
}

/// What a setting of the sweep varies (each alone, from the defaults).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Sweep {
    Iterations,
    IterationsNoFinish,
    FinishRounds,
    Penalty,
    Tolerance,
    Batch,
}

impl Sweep {
    /// The name in the CSV and the plot's legend.
    fn name(self) -> &'static str {
        match self {
            Sweep::Iterations => "iterations",
            Sweep::IterationsNoFinish => "iterations (no finish)",
            Sweep::FinishRounds => "finish rounds",
            Sweep::Penalty => "penalty r",
            Sweep::Tolerance => "tolerance",
            Sweep::Batch => "batch",
        }
    }

    /// A point's label: the value this sweep varies.
    fn label(self, p: &PenaltyParams, batch: usize) -> String {
        match self {
            Sweep::Iterations | Sweep::IterationsNoFinish => format!("{}", p.max_iterations),
            Sweep::FinishRounds => format!("rounds={}", p.finish_rounds),
            Sweep::Penalty => format!("r={:e}", p.penalty),
            Sweep::Tolerance => format!("tol={:e}", p.tol),
            Sweep::Batch => format!("N={batch}"),
        }
    }
}

/// One setting of the sweep: what it varies, the penalty kernel's
/// parameters, and the batch size.
type Setting = (Sweep, PenaltyParams, usize);

/// Iterations (with and without the exact finish), finish rounds, penalty
/// r, tolerance and batch size, each varied alone from the defaults.
fn sweep_settings() -> Vec<Setting> {
    let d = PenaltyParams::default();
    let mut settings: Vec<Setting> = Vec::new();
    for (sweep, rounds) in [
        (Sweep::Iterations, d.finish_rounds),
        (Sweep::IterationsNoFinish, 0),
    ] {
        for max_iterations in 1..=8 {
            let p = PenaltyParams {
                max_iterations,
                finish_rounds: rounds,
                ..d
            };
            settings.push((sweep, p, 8));
        }
    }
    for finish_rounds in 0..=4 {
        settings.push((Sweep::FinishRounds, PenaltyParams { finish_rounds, ..d }, 8));
    }
    for penalty in [1e2, 1e4, 1e6, 1e8, 1e10] {
        settings.push((Sweep::Penalty, PenaltyParams { penalty, ..d }, 8));
    }
    for tol in [1e-6, 1e-8, 1e-10, 1e-12, 1e-13] {
        settings.push((Sweep::Tolerance, PenaltyParams { tol, ..d }, 8));
    }
    for b in [1, 2, 4, 8, 16, 32, 64] {
        settings.push((Sweep::Batch, d, b));
    }
    settings
}

fn sweep_options(method: Method, penalty: PenaltyParams, batch: usize) -> Options {
    Options {
        method,
        batch,
        penalty,
        fallback: Fallback::WholeBatch,
        threading: Threading::default(),
    }
}

/// Each setting's errors against brute force, and its certified and
/// fallback rates.
fn sweep_accuracy(
    pairs: &[(Triangle, Triangle)],
    pool: &rayon::ThreadPool,
    settings: &[Setting],
    bar: &ProgressBar,
) -> Vec<SweepRow> {
    let brute = sweep_options(Method::Brute, PenaltyParams::default(), 8);
    let exact: Vec<Closest> = pool.install(|| distances(pairs, &brute).expect("batch").0);
    let n = pairs.len() as f64;
    let mut rows = Vec::new();
    for &(sweep, prm, batch) in settings {
        bar.set_message(sweep.name());
        let run = |method| {
            pool.install(|| distances(pairs, &sweep_options(method, prm, batch)).expect("batch"))
        };
        let (pen, _, pen_counts) = run(Method::Penalty);
        let (hyb, _, hyb_counts) = run(Method::Hybrid);
        let mut errs = rel_errors(pairs, &pen, &exact);
        errs.sort_by(f64::total_cmp);
        let hyb_max = rel_errors(pairs, &hyb, &exact)
            .into_iter()
            .fold(0.0, f64::max);
        rows.push(SweepRow {
            max: *errs.last().unwrap_or(&0.0),
            median: errs.get(errs.len() / 2).copied().unwrap_or(0.0),
            certified: pen_counts.certified as f64 / n,
            fallback: hyb_counts.fallback_pairs as f64 / n,
            hyb_max,
            pen_ns: Vec::new(),
            hyb_ns: Vec::new(),
        });
        bar.inc(1);
    }
    rows
}

/// `rounds` rounds, each timing every setting once, penalty and hybrid.
fn time_sweep(
    pairs: &[(Triangle, Triangle)],
    pool: &rayon::ThreadPool,
    settings: &[Setting],
    rows: &mut [SweepRow],
    rounds: usize,
    bar: &ProgressBar,
) {
    let n = pairs.len() as f64;
    for _ in 0..rounds {
        for (&(_, prm, batch), row) in settings.iter().zip(rows.iter_mut()) {
            for (method, times) in [
                (Method::Penalty, &mut row.pen_ns),
                (Method::Hybrid, &mut row.hyb_ns),
            ] {
                let o = sweep_options(method, prm, batch);
                let (_, seconds) = timed_on_awake_pool(pool, || {
                    std::hint::black_box(distances(pairs, &o).expect("batch"))
                });
                times.push(seconds * 1e9 / n);
            }
            bar.inc(1);
        }
    }
}

/// The sweep's CSV (also printed) and its error-against-time plot.
fn write_sweep(args: &KernelsArgs, settings: &[Setting], rows: Vec<SweepRow>) -> CliResult {
    let mut points = Vec::new();
    let mut csv = String::from("sweep,iterations,penalty,tol,batch,finish_rounds,penalty_ns,hybrid_ns,max_err_over_L,median_err_over_L,certified_rate,fallback_rate,hybrid_max_err_over_L,time_statistic\n");
    let stat = args.statistic;
    for (&(sweep, prm, batch), row) in settings.iter().zip(rows) {
        let (pen_ns, hyb_ns) = (stat.of(row.pen_ns), stat.of(row.hyb_ns));
        csv.push_str(&format!(
            "{},{},{},{},{batch},{},{pen_ns:.2},{hyb_ns:.2},{:e},{:e},{:.4},{:.4},{:e},{}\n",
            sweep.name(),
            prm.max_iterations,
            prm.penalty,
            prm.tol,
            prm.finish_rounds,
            row.max,
            row.median,
            row.certified,
            row.fallback,
            row.hyb_max,
            stat.name()
        ));
        points.push(plot::Point {
            series: sweep.name().to_string(),
            x: pen_ns,
            y: row.median,
            max: row.max,
            certified: row.certified,
            label: sweep.label(&prm, batch),
        });
    }
    let dir = &args.output;
    let csv_path = dir.join("kernels-accuracy.csv");
    std::fs::write(&csv_path, &csv)
        .map_err(|e| CliError::runtime(format!("{}: {e}", csv_path.display())))?;
    let svg_path = dir.join("kernels-accuracy.svg");
    plot::error_vs_time(&svg_path, &points, args.pairs)
        .map_err(|e| CliError::runtime(format!("{}: {e}", svg_path.display())))?;
    print!("{csv}");
    eprintln!(
        "wrote {}, {} and {}",
        csv_path.display(),
        svg_path.display(),
        svg_path.with_extension("png").display()
    );
    Ok(())
}

/// One setting of the accuracy sweep: its errors, measured once, and its
/// times per round.
struct SweepRow {
    max: f64,
    median: f64,
    certified: f64,
    fallback: f64,
    hyb_max: f64,
    pen_ns: Vec<f64>,
    hyb_ns: Vec<f64>,
}

fn rel_errors(pairs: &[(Triangle, Triangle)], got: &[Closest], exact: &[Closest]) -> Vec<f64> {
    pairs
        .iter()
        .zip(got.iter().zip(exact))
        .map(|((a, b), (g, e))| {
            (g.distance - e.distance).abs() / pair_scale(a, b).max(f64::MIN_POSITIVE)
        })
        .collect()
}

/// Runs once over all pairs, writing into the shared buffers; returns the
/// hybrid's counts where there are any.
/// Runs a row once: the kernel's counts (when it reports them) and the seconds it took.
type RunOnce<'a> =
    Box<dyn FnMut(&mut [Closest], &mut [PenaltyStats]) -> (Option<Counts>, f64) + 'a>;

/// `f`'s result and the seconds it took, on the calling thread.
fn timed<R>(f: impl FnOnce() -> R) -> (R, f64) {
    let start = Instant::now();
    let r = f();
    (r, start.elapsed().as_secs_f64())
}

/// `f`'s result and the seconds it took on `pool`, timed from the moment every
/// worker of the pool is awake, and kept awake (polling for work, as in a DEM
/// run: `with_busy_workers`) until `f` returns.
///
/// Rows run one after the other, so a pool's workers sleep while the other
/// rows run. Waking a sleeping worker takes a fraction of a millisecond, and
/// the woken thread may be run on the busy core until the first has
/// finished: a large part of a short run at two threads, charged to the
/// kernel. The clock starts once a broadcast has reached every
/// worker and, on top of that, the other workers have polled for
/// `WARM_UP` (an idle core's first milliseconds ran about 10% slower).
fn timed_on_awake_pool<R: Send>(
    pool: &rayon::ThreadPool,
    f: impl FnOnce() -> R + Send,
) -> (R, f64) {
    pool.install(|| {
        with_busy_workers(|| {
            rayon::broadcast(|_| ());
            let warm = Instant::now();
            while warm.elapsed() < WARM_UP {
                std::hint::spin_loop();
            }
            timed(f)
        })
    })
}

/// How long the workers of a pool poll before a timed run starts.
const WARM_UP: std::time::Duration = std::time::Duration::from_millis(2);

/// One row of the benchmark: what to run and what it measured.
struct Measure<'a> {
    method: &'static str,
    variant: &'static str,
    isa: &'static str,
    threads: usize,
    run: RunOnce<'a>,
    times: Vec<f64>,
    counts: Option<Counts>,
}

impl<'a> Measure<'a> {
    fn new(
        method: &'static str,
        variant: &'static str,
        isa: &'static str,
        threads: usize,
        run: RunOnce<'a>,
    ) -> Self {
        Measure {
            method,
            variant,
            isa,
            threads,
            run,
            times: Vec::new(),
            counts: None,
        }
    }
}

/// Option values that would make the benchmark fail part-way or print
/// meaningless numbers, refused before anything runs.
fn check_args(args: &KernelsArgs) -> CliResult {
    // A pair (two triangles, 144 B), its answers under each method and
    // their statistics: about 400 B.
    crate::bounds::fits_in_memory(
        &format!("--pairs {}", args.pairs),
        args.pairs as f64 * 400.0,
    )
    .map_err(CliError::input)?;
    if !BATCH_SIZES.contains(&args.batch) {
        return Err(CliError::input(format!(
            "--batch {}: {}",
            args.batch,
            UnsupportedBatch(args.batch)
        )));
    }
    Ok(())
}

fn pool(threads: Option<usize>) -> CliResult<rayon::ThreadPool> {
    pool_of(threads.unwrap_or(0))
}

fn pool_of(threads: usize) -> CliResult<rayon::ThreadPool> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .map_err(|e| CliError::runtime(format!("thread pool: {e}")))
}
