//! Contact detection split between simulated ranks: each "rank" owns part of
//! the triangles and receives the others within reach as ghosts; its
//! local-local and local-ghost phases together must find exactly the triangle
//! contacts one node finds, each once.
use dem::contact::{
    body_contacts, Bounds, Contact, Detector, Phase, TriangleContact, TriangleKey, TriangleSet,
};
use dem::distance::{Method, Options, Triangle};
use dem::mesh::Features;
use dem::scene::Scene;
use dem::world::World;
use std::collections::BTreeMap;
use std::path::Path;

/// A dense pile: 120 randomly turned hulls on a lattice tighter than their
/// diameter, the bottom layer cutting into a floor, so that contacts of every
/// kind (particle-particle, particle-floor, crossing triangles) abound.
fn dense_world() -> (World, Vec<f64>) {
    let text = r#"
[simulation]
dt = 1e-5
end_time = 1e-3
[effects]
contact = {}
[[materials]]
name = "grain"
density = 2500.0
stiffness = 50000.0
restitution = 0.5
halo = 2.5e-4
[[materials]]
name = "floor"
density = 2500.0
stiffness = 50000.0
restitution = 0.5
halo = 1e-4
[[particles]]
material = "grain"
shape = { kind = "hull", triangles = 20, radius = 0.005, seed = 3 }
placement = { kind = "lattice", count = [6, 5, 4], spacing = 0.0111, origin = [-0.02775, -0.0222, 0.0056] }
orientation = "random"
[[obstacles]]
material = "floor"
shape = { kind = "box", size = [0.1, 0.1, 0.01] }
position = [0.0, 0.0, -0.005]
"#;
    let mut scene =
        Scene::parse(text, "dense.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    // Scenes refuse overlapping lattices; squeeze this one towards the floor's centre.
    for b in scene.world.bodies.iter_mut().filter(|b| !b.is_static()) {
        b.x *= 0.84;
    }
    let halos = scene.world.per_body(|m| m.halo);
    (scene.world, halos)
}

/// The features of every shape of the world.
fn features(world: &World) -> Vec<Features> {
    world.shapes.iter().map(Features::of).collect()
}

/// All triangles of the world by key.
fn all_triangles(world: &World) -> Vec<(TriangleKey, Triangle)> {
    let mut set = TriangleSet::default();
    set.update_from_world(world, &vec![0.0; world.bodies.len()]);
    (0..set.len())
        .map(|i| (set.key(i), set.triangle(i).vertices))
        .collect()
}

/// One node: every triangle owned.
fn one_node(world: &World, halos: &[f64], opts: &Options) -> Vec<TriangleContact> {
    let mut set = TriangleSet::default();
    set.update_from_world(world, halos);
    let mut found = Vec::new();
    Detector::default().triangle_contacts(world, &set, halos, opts, Phase::LocalLocal, &mut found);
    found
}

/// Ranks split by the x of the triangles' centroids (so bodies straddle the
/// cut); each receives as ghosts the other ranks' triangles whose inflated
/// boxes meet an owned one's. Returns every rank's triangle contacts and how
/// many came from the local-ghost phase.
fn split_ranks(
    world: &World,
    halos: &[f64],
    opts: &Options,
    cuts: &[f64],
) -> (Vec<TriangleContact>, usize) {
    let tris = all_triangles(world);
    let rank_of = |t: &Triangle| {
        let cx = (t[0].x + t[1].x + t[2].x) / 3.0;
        cuts.iter().filter(|&&c| cx > c).count()
    };
    let inflated = |(k, t): &(TriangleKey, Triangle)| Bounds::of(t, halos[k.body as usize]);
    let mut all = Vec::new();
    let mut from_ghosts = 0;
    for rank in 0..=cuts.len() {
        let (owned, others): (Vec<_>, Vec<_>) = tris.iter().partition(|(_, t)| rank_of(t) == rank);
        let owned_boxes: Vec<Bounds> = owned.iter().map(&inflated).collect();
        let ghosts: Vec<_> = others
            .into_iter()
            .filter(|e| owned_boxes.iter().any(|b| b.overlaps(&inflated(e))))
            .collect();
        assert!(
            !owned.is_empty() && !ghosts.is_empty(),
            "rank {rank}: the cut must split the pile"
        );
        let mut set = TriangleSet::with_owned(owned, halos);
        let mut detector = Detector::default();
        let mut found = Vec::new();
        detector.triangle_contacts(world, &set, halos, opts, Phase::LocalLocal, &mut found);
        // Ghosts arrive while local-local pairs are computed.
        set.set_ghosts(ghosts, halos);
        let local = found.len();
        detector.triangle_contacts(world, &set, halos, opts, Phase::LocalGhost, &mut found);
        from_ghosts += found.len() - local;
        all.extend(found);
    }
    (all, from_ghosts)
}

fn by_pair(found: &[TriangleContact]) -> BTreeMap<(TriangleKey, TriangleKey), TriangleContact> {
    let mut map = BTreeMap::new();
    for t in found {
        assert!(
            map.insert((t.a, t.b), *t).is_none(),
            "triangle pair {:?}-{:?} found twice",
            t.a,
            t.b
        );
    }
    map
}

fn brute() -> Options {
    Options {
        method: Method::Brute,
        ..Options::default()
    }
}

#[test]
fn split_detection_finds_the_one_node_contacts_exactly_once() {
    let (world, halos) = dense_world();
    for cuts in [vec![0.0], vec![-0.01, 0.004, 0.012]] {
        let single = by_pair(&one_node(&world, &halos, &brute()));
        let (split, from_ghosts) = split_ranks(&world, &halos, &brute(), &cuts);
        let split = by_pair(&split);
        assert!(
            single.len() > 200,
            "the pile has {} triangle contacts",
            single.len()
        );
        assert!(
            from_ghosts > 20,
            "only {from_ghosts} contacts across the cuts {cuts:?}"
        );
        assert_eq!(
            single.keys().collect::<Vec<_>>(),
            split.keys().collect::<Vec<_>>(),
            "cuts {cuts:?}"
        );
        // Brute force is computed pair by pair: the same bits on every rank.
        for (k, t) in &single {
            assert_eq!(t, &split[k]);
        }
        // And the body contacts built from them are the same.
        let mut a: Vec<TriangleContact> = single.values().copied().collect();
        let mut b: Vec<TriangleContact> = split.values().rev().copied().collect();
        let (mut ca, mut cb): (Vec<Contact>, Vec<Contact>) = (Vec::new(), Vec::new());
        assert_eq!(
            body_contacts(&mut a, &world, &features(&world), &halos, &mut ca),
            body_contacts(&mut b, &world, &features(&world), &halos, &mut cb)
        );
        assert_eq!(ca, cb);
    }
}

#[test]
fn split_detection_with_the_hybrid_kernel_agrees_to_its_tolerance() {
    let (world, halos) = dense_world();
    let opts = Options::default();
    let single = by_pair(&one_node(&world, &halos, &opts));
    let (split, _) = split_ranks(&world, &halos, &opts, &[0.0]);
    let split = by_pair(&split);
    assert_eq!(
        single.keys().collect::<Vec<_>>(),
        split.keys().collect::<Vec<_>>()
    );
    // Batches are composed differently on each rank, so a pair may be answered
    // by penalty here and brute force there: equal to the certificate's tolerance.
    for (k, t) in &single {
        let u = &split[k];
        let scale = 0.01;
        assert!(
            (t.closest.distance - u.closest.distance).abs() <= 1e-12 * scale,
            "{k:?}"
        );
    }
}

#[test]
fn the_simulation_detector_matches_the_phase_api() {
    let (world, halos) = dense_world();
    let mut contacts = Vec::new();
    let stats =
        Detector::default().detect(&world, &features(&world), &halos, &brute(), &mut contacts);
    let mut found = one_node(&world, &halos, &brute());
    let mut expected = Vec::new();
    let (n, deep) = body_contacts(&mut found, &world, &features(&world), &halos, &mut expected);
    assert_eq!(contacts, expected);
    assert_eq!((stats.contacts, stats.deep_contacts), (n, deep));
    assert!(deep > 0, "the bottom layer cuts into the floor");
}

/// The detector fills a moving body's triangles only when a detection task
/// needs them, and keeps its set from step to step. Over steps in which the
/// bodies move (and some stay untouched by any task for a while), it must
/// find what a set recomputed from scratch each step gives.
///
/// On one, two and three threads, each with a copy of the set of its own
/// and (a budget of 0 bytes for copies) sharing one.
#[test]
fn the_detector_keeps_up_with_moving_bodies() {
    for threads in [1, 2, 3] {
        for budget in [None, Some(0)] {
            let pool = rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap();
            let mut detector = Detector::default();
            if let Some(bytes) = budget {
                detector = detector.with_replica_budget(bytes);
            }
            pool.install(|| keeps_up(detector, &format!("{threads} threads, budget {budget:?}")));
        }
    }
}

fn keeps_up(mut detector: Detector, context: &str) {
    let (mut world, halos) = dense_world();
    for step in 0..6 {
        let mut contacts = Vec::new();
        detector.detect(&world, &features(&world), &halos, &brute(), &mut contacts);
        let mut found = one_node(&world, &halos, &brute());
        let mut expected = Vec::new();
        body_contacts(&mut found, &world, &features(&world), &halos, &mut expected);
        assert_eq!(contacts, expected, "{context}, step {step}");
        // Spread the pile out and turn every other particle: after a few
        // steps most pairs separate, so their bodies go unfilled; then the
        // pile is pushed back together.
        let factor = if step < 3 { 1.05 } else { 1.0 / 1.05 };
        for (i, b) in world.bodies.iter_mut().enumerate() {
            if !b.is_static() {
                b.x.x *= factor;
                b.x.y *= factor;
                if i % 2 == 0 {
                    b.q = (glam::DQuat::from_rotation_z(0.1) * b.q).normalize();
                }
            }
        }
    }
}
