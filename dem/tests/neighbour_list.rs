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

/// Grains that fall together, turning, onto a floor: the list holds while
/// they fall, however far (their displacements spread little, and the floor
/// is far), and is drawn anew as they near the floor and land, with one
/// process's contacts and motion to the bit. A rule on each body's own
/// travel would draw it every half skin of the fall, a hundred times.
#[test]
fn grains_falling_together_keep_the_list_until_they_near_the_floor() {
    let text = format!(
        r#"
        [simulation]
        dt = 5e-5
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{ skin = 1e-3 }}
        friction = {{}}
        rotation = {{}}
        {}
        [[particles]]
        material = "grain"
        shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = 5 }}
        placement = {{ kind = "lattice", count = [3, 3, 2], spacing = 0.0125, origin = [-0.0125, -0.0125, 0.06] }}
        orientation = "random"
        angular_velocity = [0.6, -0.4, 1.0]
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [0.1, 0.1, 0.01] }}
        position = [0.0, 0.0, -0.005]
        "#,
        common::grains_and_walls(2.5e-4, 0.3, 0.3)
    );
    let scene =
        Scene::parse(&text, "falling.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let steps = 2_600;
    let (counts, states, _) = run(&scene, 0.0, steps);
    let landed = counts
        .iter()
        .position(|c| c[1] > 0)
        .expect("the grains land");
    // The lowest grains start 5.5 cm above the floor: 0.1 s of fall.
    assert!(landed > 1_500, "landed at step {landed}");
    let mut sim = {
        let mut s = scene.clone();
        s.effects.set(ContactParams {
            skin: 1e-3,
            culling: Culling::default(),
        });
        Simulation::new(&s)
    };
    let mut broad = Vec::new();
    for step in 0..steps {
        sim.step();
        broad.push(sim.totals.detection.broad_phases);
        assert_eq!(
            sim.last_stats().detection.contacts,
            counts[step][1],
            "step {step}: contacts"
        );
        assert!(
            common::motion_bits(&sim.world) == states[step],
            "step {step}: states differ"
        );
    }
    // The start's list holds the first half of the fall; by the landing,
    // a few more are drawn.
    assert_eq!(
        broad[landed / 2],
        0,
        "lists drawn in the first half of the fall"
    );
    assert!(
        broad[landed] < 20,
        "{} lists drawn by the landing",
        broad[landed]
    );
    assert!(
        broad[steps - 1] > broad[landed],
        "no list drawn after landing"
    );
}

/// A rod spinning in place sweeps its ends into its neighbour: no centre
/// moves, so the list is drawn anew for the turn alone, and the contact is
/// found when the reference finds it.
#[test]
fn a_turn_alone_redraws_the_list() {
    let text = format!(
        r#"
        [simulation]
        dt = 5e-5
        end_time = 1.0
        [effects]
        contact = {{ skin = 1e-3 }}
        friction = {{}}
        rotation = {{}}
        {}
        [[particles]]
        material = "grain"
        shape = {{ kind = "box", size = [0.04, 0.004, 0.004] }}
        placement = {{ kind = "single", position = [0.0, 0.0, 0.0] }}
        angular_velocity = [0.0, 0.0, 50.0]
        [[particles]]
        material = "grain"
        shape = {{ kind = "box", size = [0.04, 0.004, 0.004] }}
        placement = {{ kind = "single", position = [0.0, 0.012, 0.0] }}
        "#,
        common::grains_and_walls(2.5e-4, 0.3, 0.3)
    );
    let scene = Scene::parse(&text, "rods.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"));
    let steps = 400;
    let (reference, states, _) = run(&scene, 0.0, steps);
    let touch = reference
        .iter()
        .position(|c| c[1] > 0)
        .expect("the rods touch");
    // A quarter turn at most before they touch (0.03 s at 50 rad/s).
    assert!(touch > 50 && touch < 300, "touch at step {touch}");
    let (listed, listed_states, broad) = run(&scene, 1e-3, steps);
    assert!(broad > 2, "{broad} lists drawn");
    for step in 0..steps {
        assert_eq!(listed[step][1], reference[step][1], "step {step}: contacts");
        assert!(listed_states[step] == states[step], "step {step}: states");
    }
}
