//! A run gives the same motion, to the bit, on any number of threads: the
//! contact detection's per-thread copies of the triangles (one set per pool
//! thread) hold what the one set of a one-thread run holds, also after bodies,
//! moving or static, were placed by hand.
mod common;

use dem::scene::Scene;
use dem::simulation::Simulation;
use glam::DVec3;
use std::path::Path;

fn hopper() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/hopper.toml");
    Scene::load(&path).unwrap()
}

/// Per step, every body's position and angular momentum bits, and at the end
/// the floor's contact count. After 200 steps the floor (the last obstacle,
/// numbered last) is raised to just under the lattice and the last particle
/// put on top of the first, so that both kinds of bodies are found where
/// they were put.
fn run(scene: &Scene, threads: usize, steps: usize) -> (Vec<Vec<u64>>, u32) {
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build()
        .unwrap();
    pool.install(|| {
        let mut sim = Simulation::new(scene);
        let floor = sim.world.bodies.len() - 1;
        let last = sim.world.dynamic_count() - 1;
        assert!(sim.world.bodies[floor].is_static() && !sim.world.bodies[last].is_static());
        let mut states = Vec::new();
        for step in 0..steps {
            if step == 200 {
                // Floor top from z = 0 to 0.108; the lowest particles'
                // centres are at 0.115, their radius 0.005.
                sim.world.bodies[floor].x += DVec3::new(0.0, 0.0, 0.108);
                let x0 = sim.world.bodies[0].x;
                sim.world.bodies[last].x = x0 + DVec3::new(0.0, 0.0, 1e-3);
                sim.forget_motion();
            }
            sim.step();
            states.push(common::motion_bits(&sim.world));
        }
        (states, sim.contact_counts()[floor])
    })
}

#[test]
fn bit_identical_motion_on_one_two_and_three_threads() {
    let scene = hopper();
    let steps = 900;
    let (reference, floor_contacts) = run(&scene, 1, steps);
    assert!(
        floor_contacts > 0,
        "a test whose raised floor carries particles"
    );
    for threads in [2, 3] {
        let (states, floor) = run(&scene, threads, steps);
        assert_eq!(floor, floor_contacts, "{threads} threads: floor contacts");
        for step in 0..steps {
            assert!(
                states[step] == reference[step],
                "{threads} threads, step {step}: states differ from one thread's"
            );
        }
    }
}
