//! Run under mpirun by experiments' tests: contact detection between
//! triangles split across real MPI ranks, as a distributed step would do it.
//!
//! Every rank steps the hopper scene to a state with contacts (the same bits
//! on every rank), then deals the particles' triangles out, lets a
//! partitioner place them by centroid, and migrates them with their vertices
//! as payload; the obstacles' triangles are held by every rank. Each rank
//! finds the contacts among its owned triangles while the ghost triangles
//! (vertices included) are in flight, then those between owned and ghost
//! triangles. The union over ranks is compared, on every rank, with what one
//! node finds.
//!
//! Usage: contacts_mpi BACKEND STEPS
use dem::contact::{Bounds, Detector, Phase, TriangleContact, TriangleKey, TriangleSet};
use dem::distance::{Method, Options, Triangle};
use dem::scene::Scene;
use dem::simulation::Simulation;
use glam::DVec3;
use mpi::traits::*;
use mpi_harness::Reporter;
use partition::comm::all_gather_v;
use partition::ghosts::exchange_ghost_records_during;
use partition::migrate::migrate;
use partition::{Aabb, Backend, Item, LocalItems};
use std::collections::BTreeMap;

/// A ghost triangle as it travels: its key and world-space vertices.
#[derive(Debug, Clone, Copy, Default, Equivalence)]
struct GhostTriangle {
    body: u32,
    index: u32,
    vertices: [f64; 9],
}

/// A triangle contact as gathered for the comparison.
#[derive(Debug, Clone, Copy, Default, Equivalence)]
struct Found {
    keys: [u32; 4],
    distance: f64,
}

fn flatten(t: &Triangle) -> [f64; 9] {
    let mut v = [0.0; 9];
    for (k, p) in t.iter().enumerate() {
        v[3 * k..3 * k + 3].copy_from_slice(&p.to_array());
    }
    v
}

fn unflatten(v: &[f64]) -> Triangle {
    let p = |k: usize| DVec3::new(v[3 * k], v[3 * k + 1], v[3 * k + 2]);
    [p(0), p(1), p(2)]
}

fn found(contacts: &[TriangleContact]) -> Vec<Found> {
    contacts
        .iter()
        .map(|c| Found {
            keys: [c.a.body, c.a.index, c.b.body, c.b.index],
            distance: c.closest.distance,
        })
        .collect()
}

fn main() {
    let universe = mpi::initialize().expect("MPI init");
    let comm = universe.world();
    let (me, size) = (comm.rank(), comm.size());
    let mut out = Reporter::new(me as usize);
    let args: Vec<String> = std::env::args().collect();
    let backend: Backend = args[1].parse().expect("backend");
    let steps: u64 = args[2].parse().expect("steps");

    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/hopper.toml");
    let scene = Scene::load(&path).unwrap_or_else(|e| panic!("{e}"));
    let mut sim = Simulation::new(&scene);
    for _ in 0..steps {
        sim.step();
    }
    let world = &sim.world;
    let halos = world.per_body(|m| m.halo);
    let mut all = TriangleSet::default();
    all.update_from_world(world, &halos);
    // Brute force answers pair by pair: the same bits whichever rank asks.
    let opts = Options {
        method: Method::Brute,
        ..Options::default()
    };

    // The obstacles (floor, hopper walls) do not move: every rank holds all
    // of their triangles as owned, and only the particles' are partitioned.
    // Obstacle pairs are never examined, and a particle-obstacle pair is
    // found on the rank owning the particle's triangle, so once. As items, a
    // wall spanning the scene would give every particle triangle the wall's
    // reach, and every rank would get every other rank's triangles as ghosts.
    let is_static = |i: usize| world.bodies[all.key(i).body as usize].is_static();
    let obstacles: Vec<(TriangleKey, Triangle)> = (0..all.len())
        .filter(|&i| is_static(i))
        .map(|i| (all.key(i), all.triangle(i).vertices))
        .collect();
    // Particle triangles are dealt out by position, then placed by the
    // partitioner; each triangle's box is inflated by its body's halo, so
    // that boxes overlap exactly when the triangles may touch.
    let mut items = Vec::new();
    let mut payload = Vec::new();
    let particles = (0..all.len()).filter(|&i| !is_static(i));
    for i in particles.filter(|i| i % size as usize == me as usize) {
        let (key, t) = (all.key(i), all.triangle(i).vertices);
        assert!(key.body < 1 << 16 && key.index < 1 << 16, "{key:?}");
        let b = Bounds::of(&t, halos[key.body as usize]);
        items.push(Item {
            // Zoltan's ids are 32 bits wide.
            id: (u64::from(key.body) << 16) | u64::from(key.index),
            point: ((t[0] + t[1] + t[2]) / 3.0).to_array(),
            weight: 1.0,
            bbox: Aabb::new(b.lo.to_array(), b.hi.to_array()),
            payload_bytes: 72,
        });
        payload.extend(flatten(&t).iter().flat_map(|x| x.to_le_bytes()));
    }
    let local = LocalItems::new(items, payload);
    let mut part = backend.create(&comm, 0.0).expect("partitioner");
    let owners = part.partition(&comm, &local.items).expect("partition");
    let (local, _) = migrate(&comm, local, &owners);

    // What arrived, with its vertices from the payload.
    let vertices: Vec<Triangle> = local
        .payload
        .chunks_exact(72)
        .map(|b| {
            let x: Vec<f64> = b
                .chunks_exact(8)
                .map(|c| f64::from_le_bytes(c.try_into().expect("8 bytes")))
                .collect();
            unflatten(&x)
        })
        .collect();
    let key = |it: &Item| TriangleKey {
        body: (it.id >> 16) as u32,
        index: (it.id & 0xffff) as u32,
    };
    let owned: Vec<(TriangleKey, Triangle)> = local
        .items
        .iter()
        .zip(&vertices)
        .map(|(it, t)| (key(it), *t))
        .chain(obstacles)
        .collect();
    let mut set = TriangleSet::with_owned(owned, &halos);
    let mut detector = Detector::default();
    let record = |i: usize| {
        let k = key(&local.items[i]);
        GhostTriangle {
            body: k.body,
            index: k.index,
            vertices: flatten(&vertices[i]),
        }
    };
    let (sent, ghosts, mut contacts) =
        exchange_ghost_records_during(&comm, part.as_ref(), &local, 0.0, record, || {
            let mut f = Vec::new();
            detector.triangle_contacts(world, &set, &halos, &opts, Phase::LocalLocal, &mut f);
            f
        })
        .expect("ghost exchange");
    let local_local = contacts.len();
    let ghosts: Vec<(TriangleKey, Triangle)> = ghosts
        .iter()
        .map(|g| {
            let k = TriangleKey {
                body: g.body,
                index: g.index,
            };
            (k, unflatten(&g.vertices))
        })
        .collect();
    out.kv("ghosts_received", ghosts.len());
    out.kv("ghosts_sent", sent.items_sent);
    set.set_ghosts(ghosts, &halos);
    detector.triangle_contacts(world, &set, &halos, &opts, Phase::LocalGhost, &mut contacts);
    out.kv("owned_particle_triangles", local.len());
    out.kv("local_local_contacts", local_local);
    out.kv("local_ghost_contacts", contacts.len() - local_local);

    // The union over ranks against one node, pair by pair, to the bit.
    let union = all_gather_v(&comm, &found(&contacts));
    let mut one_node = Vec::new();
    Detector::default().triangle_contacts(
        world,
        &all,
        &halos,
        &opts,
        Phase::LocalLocal,
        &mut one_node,
    );
    let reference: BTreeMap<[u32; 4], u64> = found(&one_node)
        .iter()
        .map(|f| (f.keys, f.distance.to_bits()))
        .collect();
    let mut seen = BTreeMap::new();
    let (mut duplicates, mut extra, mut differ) = (0, 0, 0);
    for f in &union {
        if seen.insert(f.keys, ()).is_some() {
            duplicates += 1;
        }
        match reference.get(&f.keys) {
            None => extra += 1,
            Some(&bits) if bits != f.distance.to_bits() => differ += 1,
            Some(_) => {}
        }
    }
    let missing = reference.keys().filter(|k| !seen.contains_key(*k)).count();
    out.kv("one_node_contacts", reference.len());
    out.kv("union_contacts", union.len());
    out.kv("missing", missing);
    out.kv("extra", extra);
    out.kv("duplicates", duplicates);
    out.kv("distances_differ", differ);
}
