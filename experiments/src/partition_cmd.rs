//! `tridem partition`: one partitioner on a synthetic workload, step by step,
//! measuring what load balancing costs and buys.

use crate::cli::PartitionArgs;
use crate::error::{create_output_dir, CliError, CliResult};
use indicatif::{ProgressBar, ProgressStyle};
use mpi::collective::SystemOperation;
use mpi::traits::*;
use partition::ghosts::{exchange_ghosts, exchange_ghosts_during};
use partition::metrics::{collect, StepMetrics};
use partition::migrate::migrate;
use partition::workload::Spec;
use std::io::Write;
use std::time::Instant;

pub fn run(args: &PartitionArgs) -> CliResult {
    if args.list {
        partition::Backend::ALL
            .iter()
            .for_each(|b| println!("{}", b.name()));
        return Ok(());
    }
    let partitioner = args.partitioner.expect("clap: required without --list");
    // An item's coordinates, id, weight and part in the partitioner's and
    // the exchange's buffers: about 200 B.
    crate::bounds::fits_in_memory(
        &format!("--items {}", args.items),
        args.items as f64 * 200.0,
    )
    .map_err(CliError::input)?;
    let universe =
        mpi::initialize().ok_or_else(|| CliError::runtime("MPI was already initialised"))?;
    let world = universe.world();
    let (me, size) = (world.rank(), world.size());
    let spec = Spec::new(args.workload, args.items);
    let halo = args.halo.unwrap_or(0.25 * spec.size);
    if !(halo.is_finite() && halo >= 0.0) {
        return Err(CliError::input(format!(
            "--halo must be a finite non-negative number, got {halo}"
        )));
    }
    // The partitioners use rayon's global pool (MPI handles cannot cross into
    // another pool's closures), so size it once here.
    rayon::ThreadPoolBuilder::new()
        .num_threads(args.threads.unwrap_or(0))
        .build_global()
        .map_err(|e| CliError::runtime(e.to_string()))?;
    let mut part = partitioner
        .create(&world, partition::Setup::with_halo(halo))
        .map_err(|e| CliError::runtime(e.to_string()))?;

    let csv_path = match (&args.output, me) {
        (Some(dir), 0) => {
            create_output_dir(dir)?;
            Some(dir.join(format!(
                "partition-{}-{}-{}ranks.csv",
                partitioner.name(),
                workload_name(args),
                size
            )))
        }
        _ => None,
    };
    let bar = (me == 0 && args.steps > 1).then(|| {
        ProgressBar::new(args.steps as u64).with_style(
            ProgressStyle::with_template("{msg} [{bar:30}] {pos}/{len} steps {elapsed}")
                .expect("template")
                .progress_chars("=> "),
        )
    });
    if let Some(b) = &bar {
        b.set_message(partitioner.name());
    }

    let mut local = spec.initial(me, size);
    let mut records: Vec<(StepMetrics, Overlap)> = Vec::new();
    if me == 0 && !args.json {
        print_header(size, args, halo);
    }
    for step in 0..args.steps {
        let t = if args.steps > 1 {
            step as f64 / (args.steps - 1) as f64
        } else {
            0.0
        };
        spec.advance(&mut local, t);
        if step % args.every == 0 {
            let measured = partition_step(&world, part.as_mut(), &mut local, step, halo)?;
            if me == 0 {
                let line = report_line(args, &measured, halo);
                match &bar {
                    Some(b) => b.suspend(|| println!("{line}")),
                    None => println!("{line}"),
                }
            }
            records.push((measured.metrics, measured.overlap));
        }
        if let Some(b) = &bar {
            b.inc(1);
        }
    }
    if let Some(b) = bar {
        b.finish_and_clear();
    }
    if let Some(path) = csv_path {
        write_csv(&path, &records, args)?;
        eprintln!("wrote {}", path.display());
    }
    Ok(())
}

/// What one partitioning step measured.
struct Measured {
    metrics: StepMetrics,
    overlap: Overlap,
    imbalance_before: f64,
    queries_per_s: f64,
}

/// One partitioning step: partition, migrate, exchange ghosts (alone and
/// overlapped), query boxes; each timed.
fn partition_step(
    world: &mpi::topology::SimpleCommunicator,
    part: &mut dyn partition::Partitioner,
    local: &mut partition::LocalItems,
    step: usize,
    halo: f64,
) -> CliResult<Measured> {
    let imbalance_before = imbalance(world, local);
    world.barrier();
    let start = Instant::now();
    let owners = part
        .partition(world, &local.items)
        .map_err(|e| CliError::runtime(e.to_string()))?;
    let partition_s = start.elapsed().as_secs_f64();
    let start = Instant::now();
    let (moved, mstats) = migrate(world, std::mem::take(local), &owners);
    *local = moved;
    let migrate_s = start.elapsed().as_secs_f64();
    let (ghosts, overlap) = ghost_overlap(world, part, local, halo)?;
    let metrics = collect(
        world,
        step,
        part.name(),
        local,
        partition_s,
        migrate_s,
        &mstats,
        &ghosts,
    );
    let queries_per_s = box_query_rate(world, part, local, halo)?;
    Ok(Measured {
        metrics,
        overlap,
        imbalance_before,
        queries_per_s,
    })
}

/// A step's line: a JSON object (the metrics, plus what only this command
/// knows) with `--json`, else a row of the table.
fn report_line(args: &PartitionArgs, m: &Measured, halo: f64) -> String {
    if !args.json {
        return format_row(&m.metrics, m.imbalance_before, &m.overlap);
    }
    let mut record = serde_json::to_value(&m.metrics).expect("metrics serialise");
    let extra = serde_json::json!({
        "workload": workload_name(args), "imbalance_before": m.imbalance_before,
        "halo": halo, "box_queries_per_s": m.queries_per_s,
        "ghost_exchange_s": m.overlap.exchange_s, "owned_pairs_s": m.overlap.work_s,
        "overlapped_s": m.overlap.overlapped_s, "owned_pairs": m.overlap.pairs,
    });
    if let (Some(r), Some(e)) = (record.as_object_mut(), extra.as_object()) {
        r.extend(e.clone());
    }
    record.to_string()
}

/// The ghost exchange timed alone, the owned items' contact candidates
/// found alone, and both at once: the exchange's non-blocking messages in
/// flight while the candidates are found, as a distributed step would do.
/// Times of the slowest rank.
#[derive(Debug, Clone, Copy)]
struct Overlap {
    exchange_s: f64,
    work_s: f64,
    overlapped_s: f64,
    /// Owned item pairs whose boxes, inflated by the halo, overlap (all ranks).
    pairs: u64,
}

fn ghost_overlap(
    world: &mpi::topology::SimpleCommunicator,
    part: &dyn partition::Partitioner,
    local: &partition::LocalItems,
    halo: f64,
) -> CliResult<(partition::ghosts::Ghosts, Overlap)> {
    let slowest = |x: f64| {
        let mut y = 0.0;
        world.all_reduce_into(&x, &mut y, SystemOperation::max());
        y
    };
    let failed = |e: partition::PartitionError| CliError::runtime(e.to_string());
    world.barrier();
    let start = Instant::now();
    let ghosts = exchange_ghosts(world, part, local, halo).map_err(failed)?;
    let exchange_s = slowest(start.elapsed().as_secs_f64());
    world.barrier();
    let start = Instant::now();
    let pairs = owned_candidate_pairs(&local.items, halo);
    let work_s = slowest(start.elapsed().as_secs_f64());
    world.barrier();
    let start = Instant::now();
    let (_, again) = exchange_ghosts_during(world, part, local, halo, || {
        owned_candidate_pairs(&local.items, halo)
    })
    .map_err(failed)?;
    let overlapped_s = slowest(start.elapsed().as_secs_f64());
    debug_assert_eq!(pairs, again);
    let mut total = 0u64;
    world.all_reduce_into(&pairs, &mut total, SystemOperation::sum());
    let overlap = Overlap {
        exchange_s,
        work_s,
        overlapped_s,
        pairs: total,
    };
    Ok((ghosts, overlap))
}

/// Pairs of items whose boxes, inflated by the halo, overlap: sort and sweep
/// along x. The local-local contact candidates, which need no ghosts.
fn owned_candidate_pairs(items: &[partition::Item], halo: f64) -> u64 {
    let mut boxes: Vec<partition::Aabb> = items.iter().map(|i| i.bbox.inflated(halo)).collect();
    boxes.sort_unstable_by(|a, b| a.lo[0].total_cmp(&b.lo[0]));
    let mut n = 0;
    for (i, a) in boxes.iter().enumerate() {
        for b in &boxes[i + 1..] {
            if b.lo[0] > a.hi[0] {
                break;
            }
            n += u64::from(a.overlaps(b));
        }
    }
    n
}

/// Box queries per second on the slowest rank: every local item's box,
/// inflated by the halo, as in ghost search.
fn box_query_rate(
    world: &mpi::topology::SimpleCommunicator,
    part: &dyn partition::Partitioner,
    local: &partition::LocalItems,
    halo: f64,
) -> CliResult<f64> {
    let mut buf = Vec::with_capacity(16);
    let start = Instant::now();
    for it in &local.items {
        buf.clear();
        part.ranks_overlapping(&it.bbox.inflated(halo), &mut buf)
            .map_err(|e| CliError::runtime(e.to_string()))?;
        std::hint::black_box(&buf);
    }
    let dt = start.elapsed().as_secs_f64();
    let rate = if dt > 0.0 {
        local.items.len() as f64 / dt
    } else {
        f64::INFINITY
    };
    let mut slowest = 0.0;
    world.all_reduce_into(&rate, &mut slowest, SystemOperation::min());
    Ok(slowest)
}

fn workload_name(args: &PartitionArgs) -> &'static str {
    args.workload.name()
}

/// Max over mean of the ranks' weights as currently owned.
fn imbalance(world: &mpi::topology::SimpleCommunicator, local: &partition::LocalItems) -> f64 {
    let w: f64 = local.items.iter().map(|i| i.weight).sum();
    let (mut max, mut sum) = (0.0, 0.0);
    world.all_reduce_into(&w, &mut max, SystemOperation::max());
    world.all_reduce_into(&w, &mut sum, SystemOperation::sum());
    if sum > 0.0 {
        max / (sum / world.size() as f64)
    } else {
        1.0
    }
}

fn print_header(size: i32, args: &PartitionArgs, halo: f64) {
    println!(
        "{} on {} ranks: {} items, workload {}, halo {halo:.3e}, {} steps, repartition every {}",
        args.partitioner.map_or("", |p| p.name()),
        size,
        args.items,
        workload_name(args),
        args.steps,
        args.every
    );
    println!(
        "{:>5} {:>10} {:>9} {:>11} {:>9} {:>10} {:>12} {:>9} {:>12} {:>6} {:>8} {:>8} {:>8}",
        "step",
        "imb.before",
        "imbalance",
        "partition s",
        "migrate s",
        "migrated",
        "migrated B",
        "ghosts",
        "ghost B",
        "neigh",
        "ghost s",
        "owned s",
        "both s"
    );
}

fn format_row(m: &StepMetrics, before: f64, o: &Overlap) -> String {
    format!(
        "{:>5} {:>10.4} {:>9.4} {:>11.4} {:>9.4} {:>10} {:>12} {:>9} {:>12} {:>6} {:>8.4} {:>8.4} {:>8.4}",
        m.step,
        before,
        m.imbalance,
        m.partition_s,
        m.migrate_s,
        m.migrated_items,
        m.migrated_bytes,
        m.ghost_items,
        m.ghost_bytes,
        m.neighbours_max,
        o.exchange_s,
        o.work_s,
        o.overlapped_s
    )
}

fn write_csv(
    path: &std::path::Path,
    records: &[(StepMetrics, Overlap)],
    args: &PartitionArgs,
) -> CliResult {
    let mut f = std::fs::File::create(path)
        .map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))?;
    let mut text = String::from("step,partitioner,workload,ranks,items,imbalance,partition_s,migrate_s,migrated_items,migrated_bytes,ghost_items,ghost_bytes,neighbours_max,neighbours_mean,ghost_exchange_s,owned_pairs_s,overlapped_s,owned_pairs\n");
    for (m, o) in records {
        text.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{},{}\n",
            m.step,
            m.partitioner,
            workload_name(args),
            m.ranks,
            m.items,
            m.imbalance,
            m.partition_s,
            m.migrate_s,
            m.migrated_items,
            m.migrated_bytes,
            m.ghost_items,
            m.ghost_bytes,
            m.neighbours_max,
            m.neighbours_mean,
            o.exchange_s,
            o.work_s,
            o.overlapped_s,
            o.pairs
        ));
    }
    f.write_all(text.as_bytes())
        .map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))
}

/// `tridem partition-plot`: the first step of every run in a JSON-lines file.
pub fn plot(args: &crate::cli::PartitionPlotArgs) -> CliResult {
    let name = args.input.display().to_string();
    let text = std::fs::read_to_string(&args.input)
        .map_err(|e| CliError::input(format!("{name}: {e}")))?;
    let mut records = Vec::new();
    for (i, line) in text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty())
    {
        let v: serde_json::Value = serde_json::from_str(line)
            .map_err(|e| CliError::input(format!("{name}:{}: {e}", i + 1)))?;
        let field = |k: &str| {
            v.get(k)
                .ok_or_else(|| CliError::input(format!("{name}:{}: missing field `{k}`", i + 1)))
        };
        let num = |k: &str| {
            field(k)?.as_f64().ok_or_else(|| {
                CliError::input(format!("{name}:{}: field `{k}` is not a number", i + 1))
            })
        };
        let text = |k: &str| {
            field(k)?.as_str().map(String::from).ok_or_else(|| {
                CliError::input(format!("{name}:{}: field `{k}` is not a string", i + 1))
            })
        };
        records.push(crate::plot::PartitionRecord {
            workload: text("workload")?,
            partitioner: text("partitioner")?,
            step: num("step")? as u64,
            partition_s: num("partition_s")?,
            ghost_items: num("ghost_items")?,
        });
    }
    if records.is_empty() {
        return Err(CliError::input(format!("{name}: no records")));
    }
    crate::plot::partition_summary(&args.output, &records)
        .map_err(|e| CliError::runtime(format!("{}: {e}", args.output.display())))?;
    eprintln!("wrote {}", args.output.display());
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::owned_candidate_pairs;
    use partition::{Aabb, Item};

    #[test]
    fn sweep_finds_the_pairs_brute_force_finds() {
        // Boxes of mixed sizes, some touching exactly, on a coarse grid.
        let items: Vec<Item> = (0..400u64)
            .map(|id| {
                let c = [(id % 7) as f64, ((id / 7) % 9) as f64, (id % 5) as f64];
                let r = 0.3 + (id % 4) as f64 * 0.2;
                Item {
                    id,
                    point: c,
                    bbox: Aabb::new(c.map(|x| x - r), c.map(|x| x + r)),
                    ..Item::default()
                }
            })
            .collect();
        for halo in [0.0, 0.05, 0.4] {
            let boxes: Vec<Aabb> = items.iter().map(|i| i.bbox.inflated(halo)).collect();
            let brute = (0..boxes.len())
                .flat_map(|i| (i + 1..boxes.len()).map(move |j| (i, j)))
                .filter(|&(i, j)| boxes[i].overlaps(&boxes[j]))
                .count() as u64;
            assert!(brute > 0);
            assert_eq!(owned_candidate_pairs(&items, halo), brute, "halo {halo}");
        }
    }
}
