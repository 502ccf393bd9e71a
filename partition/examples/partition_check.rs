//! Run under mpirun by partition's tests: partitions a workload with one
//! backend, migrates, exchanges ghosts, and reports what the tests check.
//!
//! Usage: partition_check BACKEND WORKLOAD ITEMS HALO [MOVE]
//! MOVE > 0 repartitions once more after moving the items by that time fraction.
use mpi::traits::*;
use mpi_harness::Reporter;
use partition::comm::all_gather_v;
use partition::ghosts::{exchange_ghosts, exchange_ghosts_during};
use partition::migrate::migrate;
use partition::workload::{Spec, Workload};
use partition::{metrics, Aabb, Backend, Partitioner};
use std::time::Instant;

// A test program, long on purpose: its checks run in the order the tests
// read its report, one after the other.
fn main() {
    let universe = mpi::initialize().expect("MPI init");
    let world = universe.world();
    let (me, size) = (world.rank(), world.size());
    let mut out = Reporter::new(me as usize);
    let args: Vec<String> = std::env::args().collect();
    let backend: Backend = args[1].parse().unwrap();
    let workload: Workload = args[2].parse().unwrap();
    let n: u64 = args[3].parse().unwrap();
    let halo: f64 = args[4].parse().unwrap();
    let shift: f64 = args.get(5).map_or(0.0, |s| s.parse().unwrap());
    // "fresh": every partitioning from scratch, not building on the last.
    let reuse = args.get(6).is_none_or(|s| s != "fresh");
    // After the shift, an item costs this many times as much for each of
    // its coordinates below 0.5: whichever axis a cut takes, its low side
    // holds skew / (1 + skew) of the weight of uniform items.
    let skew: f64 = args.get(7).map_or(1.0, |s| s.parse().unwrap());

    let spec = Spec::new(workload, n);
    let mut local = spec.initial(me, size);
    // Weighted items: ids divisible by 3 cost three times as much.
    let weigh = |items: &mut [partition::Item], skew: f64| {
        for it in items {
            let low = it.point.iter().filter(|&&x| x < 0.5).count() as i32;
            it.weight = skew.powi(low) * if it.id % 3 == 0 { 3.0 } else { 1.0 };
        }
    };
    weigh(&mut local.items, 1.0);
    let mut part = backend
        .create(&world, partition::Setup { halo, reuse })
        .unwrap();
    let t = Instant::now();
    let owners = part.partition(&world, &local.items).unwrap();
    let dt = t.elapsed().as_secs_f64();
    let (moved, mstats) = migrate(&world, local, &owners);
    local = moved;
    let ghosts = exchange_ghosts(&world, part.as_ref(), &local, halo).unwrap();
    let m = metrics::collect(&world, 0, part.name(), &local, dt, 0.0, &mstats, &ghosts);

    out.kv("local_items", local.len());
    out.kv("id_sum", local.items.iter().map(|i| i.id).sum::<u64>());
    out.kv(
        "id_sq_sum",
        local
            .items
            .iter()
            .map(|i| (i.id as u128 * i.id as u128) as f64)
            .sum::<f64>(),
    );
    out.kv("payload_ok", local.payloads_match_ids());
    out.kv("weight", local.items.iter().map(|i| i.weight).sum::<f64>());
    out.kv("imbalance", m.imbalance);
    out.kv("ghost_items", m.ghost_items);
    out.kv("migrated_items", m.migrated_items);

    // Point and box queries agree with the partition.
    let mut owner_mismatch = 0;
    let mut box_mismatch = 0;
    let mut buf = Vec::new();
    for it in &local.items {
        // The owner of the point is this rank, or the point lies on a cut
        // and both closed regions hold it.
        let owner = part.owner(it.point).unwrap();
        buf.clear();
        part.ranks_overlapping(&Aabb::new(it.point, it.point), &mut buf)
            .unwrap();
        if owner != me && !(buf.contains(&owner) && buf.contains(&me)) {
            owner_mismatch += 1;
        }
        for scale in [0.0, 1e-3, 0.05, 0.3] {
            let b = Aabb::new(it.point, it.point).inflated(scale);
            buf.clear();
            part.ranks_overlapping(&b, &mut buf).unwrap();
            if !buf.contains(&me) {
                box_mismatch += 1;
            }
        }
    }
    out.kv("owner_mismatch", owner_mismatch);
    out.kv("box_mismatch", box_mismatch);

    // Ghost completeness against brute force over all items of all ranks.
    let everything = all_gather_v(&world, &local.items);
    let counts: Vec<i32> = {
        let mut v = vec![0i32; size as usize];
        world.all_gather_into(&(local.len() as i32), &mut v[..]);
        v
    };
    let mut rank_of_item = Vec::with_capacity(everything.len());
    for (r, &c) in counts.iter().enumerate() {
        rank_of_item.extend(std::iter::repeat_n(r as i32, c as usize));
    }
    let got: std::collections::HashSet<u64> = ghosts.received.iter().map(|g| g.id).collect();
    let mut missing = 0;
    for it in &local.items {
        let b = it.bbox.inflated(halo);
        for (o, &r) in everything.iter().zip(&rank_of_item) {
            if r != me && b.overlaps(&o.bbox.inflated(halo)) && !got.contains(&o.id) {
                missing += 1;
            }
        }
    }
    out.kv("ghosts_missing", missing);

    // The non-blocking exchange delivers the same ghosts, in the same order,
    // while work on the owned items runs.
    let (overlapped, owned_pairs) =
        exchange_ghosts_during(&world, part.as_ref(), &local, halo, || {
            let boxes: Vec<Aabb> = local.items.iter().map(|i| i.bbox.inflated(halo)).collect();
            (0..boxes.len())
                .flat_map(|i| (i + 1..boxes.len()).map(move |j| (i, j)))
                .filter(|&(i, j)| boxes[i].overlaps(&boxes[j]))
                .count()
        })
        .unwrap();
    out.kv(
        "overlapped_ghosts_equal",
        overlapped.received == ghosts.received
            && overlapped.items_sent == ghosts.items_sent
            && overlapped.bytes_sent == ghosts.bytes_sent
            && overlapped.neighbours == ghosts.neighbours,
    );
    out.kv("owned_pairs", owned_pairs);
    out.kv("ghosts_received", ghosts.received.len());

    // Zoltan's RCB boxes, clamped to the domain, hold this rank's points.
    if backend == Backend::ZoltanRcb {
        let mut zp =
            partition::zoltan::ZoltanPartitioner::new(&world, partition::zoltan::Method::Rcb)
                .unwrap();
        let owners = zp.partition(&world, &local.items).unwrap();
        let stay = owners.iter().filter(|&&o| o == me).count();
        let mut domain = Aabb::EMPTY;
        for it in &everything {
            domain.grow(it.point);
        }
        let b = zp.zoltan().rcb_box(me, &domain).unwrap();
        let outside = local
            .items
            .iter()
            .zip(&owners)
            .filter(|(i, &o)| o == me && !b.contains(i.point))
            .count();
        out.kv("rcb_box_outside", outside);
        out.kv(
            "rcb_box_inside_domain",
            b.lo.iter().zip(&domain.lo).all(|(x, d)| x >= d)
                && b.hi.iter().zip(&domain.hi).all(|(x, d)| x <= d),
        );
        out.kv("rcb_stay", stay);
    }

    if shift > 0.0 {
        spec.advance(&mut local, shift);
        weigh(&mut local.items, skew);
        // What keeping every cut would move: the items now outside the
        // region of the rank that holds them.
        let outside = local
            .items
            .iter()
            .filter(|i| part.owner(i.point).unwrap() != me)
            .count() as u64;
        let mut drifted = 0u64;
        world.all_reduce_into(
            &outside,
            &mut drifted,
            mpi::collective::SystemOperation::sum(),
        );
        out.kv("drifted_items", drifted);
        let owners = part.partition(&world, &local.items).unwrap();
        let (moved, ms) = migrate(&world, local, &owners);
        let mut total = 0u64;
        world.all_reduce_into(
            &ms.items_sent,
            &mut total,
            mpi::collective::SystemOperation::sum(),
        );
        out.kv("remigrated_items", total);
        out.kv("local_items_after", moved.len());
        // The weight imbalance (max over mean) the repartitioning left.
        let mine: f64 = moved.items.iter().map(|i| i.weight).sum();
        let (mut most, mut sum) = (0.0f64, 0.0f64);
        world.all_reduce_into(&mine, &mut most, mpi::collective::SystemOperation::max());
        world.all_reduce_into(&mine, &mut sum, mpi::collective::SystemOperation::sum());
        out.kv("imbalance_after", most * f64::from(size) / sum);
    }
}
