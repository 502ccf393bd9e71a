//! The contact effect's neighbour list (a skin): the broad phase runs only
//! when some body may have left its padded box, yet every step finds the
//! same contacts and gives the same motion, to the bit, as a broad phase in
//! every step. The body pairs it examines are the broad phase's, less some
//! that a listed pair's earlier hull test showed still apart. (How many
//! triangle pairs reach the kernel may differ: the hull test starts from the
//! direction that last separated a listed pair, and a list rebuilt keeps it
//! only for the pairs that were apart.) Without a skin, the detection keeps
//! nothing from one step to the next: the reference.
mod common;

use dem::contact::Culling;
use dem::effects::ContactParams;
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

fn hopper() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/hopper.toml");
    Scene::load(&path).unwrap()
}

/// Runs the hopper with the given skin; per step, the detection counts
/// (body pairs examined, contacts, body pairs left out as still apart) and
/// every body's position and angular momentum bits.
fn run(scene: &Scene, skin: f64, steps: usize) -> (Vec<[u64; 3]>, Vec<Vec<u64>>, u64) {
    let mut scene = scene.clone();
    scene.effects.set(ContactParams {
        skin,
        culling: Culling::default(),
    });
    let mut sim = Simulation::new(&scene);
    let (mut counts, mut states) = (Vec::new(), Vec::new());
    for _ in 0..steps {
        sim.step();
        let d = sim.last_stats().detection;
        counts.push([d.body_pairs, d.contacts, d.known_apart]);
        states.push(common::motion_bits(&sim.world));
    }
    (counts, states, sim.totals.detection.broad_phases)
}

#[test]
fn a_skin_changes_how_often_the_broad_phase_runs_and_nothing_else() {
    let scene = hopper();
    // The particles start at rest; within 3,000 steps (0.15 s) they fall
    // into the hopper, onto its walls and each other, at up to 1.5 m/s.
    let steps = 3_000;
    let (counts, states, broad) = run(&scene, 0.0, steps);
    assert_eq!(
        broad, steps as u64,
        "without a skin: one broad phase per step"
    );
    assert!(
        counts.iter().any(|c| c[1] > 0),
        "a test with contacts to find"
    );
    assert!(
        counts.iter().all(|c| c[2] == 0),
        "no list, nothing left out"
    );
    // A skin small enough to rebuild often, and one that rebuilds rarely.
    let mut last = steps as u64;
    for skin in [1e-4, 2e-3] {
        let (c, s, b) = run(&scene, skin, steps);
        eprintln!("skin {skin}: {b} broad phases in {steps} steps");
        assert!(
            b > 1 && b < last,
            "skin {skin}: {b} broad phases in {steps} steps, fewer expected"
        );
        last = b;
        let left_out: u64 = c.iter().map(|c| c[2]).sum();
        assert!(left_out > 0, "skin {skin}: no pair left out as still apart");
        for step in 0..steps {
            let [examined, contacts, still_apart] = c[step];
            assert_eq!(
                contacts, counts[step][1],
                "skin {skin}, step {step}: contacts"
            );
            // The pairs left out may or may not have overlapping boxes.
            assert!(
                examined <= counts[step][0] && counts[step][0] <= examined + still_apart,
                "skin {skin}, step {step}: body pairs {:?} against {:?}",
                c[step],
                counts[step]
            );
            assert!(
                s[step] == states[step],
                "skin {skin}, step {step}: states differ"
            );
        }
    }
}

/// A body moved by hand between steps is found where it went, once the
/// simulation is told: the list is rebuilt rather than trusted.
#[test]
fn bodies_moved_by_hand_are_followed_after_forget_motion() {
    let mut scene = hopper();
    scene.effects.set(ContactParams {
        skin: 2e-3,
        culling: Culling::default(),
    });
    let mut sim = Simulation::new(&scene);
    for _ in 0..10 {
        sim.step();
    }
    let before = sim.totals.detection.broad_phases;
    // The first and last particles start at opposite corners of the lattice,
    // far beyond the 2 mm skin: put the last one onto the first.
    let last = scene.world.dynamic_count() - 1;
    let x0 = sim.world.bodies[0].x;
    sim.world.bodies[last].x = x0 + glam::DVec3::new(0.0, 0.0, 1e-3);
    sim.forget_motion();
    sim.step();
    assert_eq!(sim.totals.detection.broad_phases, before + 1);
    let counts = sim.contact_counts();
    assert!(
        counts[0] > 0 && counts[last] > 0,
        "the moved particle touches the other"
    );
}
