//! Checkpoint and resume: a run stopped and resumed gives, bit for bit, what
//! it would have given had it not stopped; a checkpoint that does not fit the
//! scene is refused with the reason.

use dem::checkpoint::Checkpoint;
use dem::effects::FrictionParams;
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

fn hopper() -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/hopper.toml");
    Scene::load(&path).unwrap()
}

/// Every body's position, orientation, velocity and angular momentum, as bits.
fn state_bits(sim: &Simulation) -> Vec<u64> {
    sim.world
        .bodies
        .iter()
        .flat_map(|b| {
            let x = b.x.to_array().into_iter().chain(b.q.to_array());
            x.chain(b.v.to_array()).chain(b.l.to_array())
        })
        .map(f64::to_bits)
        .collect()
}

fn friction_springs(c: &Checkpoint) -> usize {
    c.effects
        .iter()
        .find(|e| e.effect == "friction")
        .map_or(0, |e| e.history.len() / e.row.max(1))
}

/// Steps the hopper until grains touch the walls and each other, so that the
/// friction springs carry history across the checkpoint.
fn run_to_contact(scene: &Scene) -> Simulation {
    let mut sim = Simulation::new(scene);
    while friction_springs(&sim.checkpoint()) < 10 {
        assert!(sim.world.step < 5_000, "the grains should touch by now");
        sim.step();
    }
    sim
}

#[test]
fn a_resumed_run_continues_bit_for_bit() {
    let scene = hopper();
    let mut through = run_to_contact(&scene);
    let checkpoint = through.checkpoint();
    assert!(friction_springs(&checkpoint) >= 10);
    let mut resumed = Simulation::resume(&scene, &checkpoint).unwrap();
    assert_eq!(state_bits(&resumed), state_bits(&through));
    assert_eq!(resumed.world.step, through.world.step);
    // The neighbour list of the uninterrupted run dates from some earlier
    // step, the resumed run's from now: the answers must not care.
    let broad_phases = through.totals.detection.broad_phases;
    for step in 0..1_500 {
        through.step();
        resumed.step();
        assert!(
            state_bits(&resumed) == state_bits(&through),
            "step {step} after the checkpoint: the resumed run departs"
        );
    }
    assert!(
        through.totals.detection.broad_phases > broad_phases + 1,
        "neighbour lists rebuilt on their own schedule in both runs"
    );
    assert_eq!(resumed.world.time.to_bits(), through.world.time.to_bits());
    assert_eq!(resumed.checkpoint(), through.checkpoint());
    assert!(
        resumed.last_stats().detection.contacts > 0,
        "a test with contacts to the end"
    );
}

/// Without the forces of the last evaluation, or without the friction
/// springs, the run would go on differently: the checkpoint must hold both.
#[test]
fn forces_and_friction_springs_are_part_of_the_state() {
    let scene = hopper();
    let mut through = run_to_contact(&scene);
    let checkpoint = through.checkpoint();
    let mut no_forces = checkpoint.clone();
    no_forces
        .force
        .iter_mut()
        .for_each(|f| *f = glam::DVec3::ZERO);
    let mut no_springs = checkpoint.clone();
    for e in &mut no_springs.effects {
        if e.effect == "friction" {
            // The books stay; the springs go.
            e.history.clear();
        }
    }
    let mut runs: Vec<Simulation> = [no_forces, no_springs]
        .iter()
        .map(|c| Simulation::resume(&scene, c).unwrap())
        .collect();
    for _ in 0..200 {
        through.step();
        runs.iter_mut().for_each(Simulation::step);
    }
    for (what, run) in ["forces", "friction springs"].iter().zip(&runs) {
        assert!(
            state_bits(run) != state_bits(&through),
            "dropping the {what} changed nothing: the test proves nothing"
        );
    }
}

fn refusal(scene: &Scene, checkpoint: &Checkpoint) -> String {
    match Simulation::resume(scene, checkpoint) {
        Ok(_) => panic!("resumed from a checkpoint that does not fit"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn a_checkpoint_that_does_not_fit_the_scene_is_refused() {
    let scene = hopper();
    let mut sim = Simulation::new(&scene);
    for _ in 0..10 {
        sim.step();
    }
    let checkpoint = sim.checkpoint();

    let mut other_dt = scene.clone();
    other_dt.dt *= 0.5;
    assert!(refusal(&other_dt, &checkpoint).contains("dt"));

    let mut heavier = scene.clone();
    heavier.world.materials[0].density *= 1.01;
    heavier.world.bodies[0].mass *= 1.01;
    assert!(refusal(&heavier, &checkpoint).contains("another scene"));

    let mut moved_floor = scene.clone();
    let last = moved_floor.world.bodies.len() - 1;
    assert!(moved_floor.world.bodies[last].is_static());
    moved_floor.world.bodies[last].x.z -= 1e-3;
    assert!(refusal(&moved_floor, &checkpoint).contains("another scene"));

    let mut frictionless = scene.clone();
    frictionless.effects.remove::<FrictionParams>();
    let why = refusal(&frictionless, &checkpoint);
    assert!(why.contains("friction"), "{why}");

    let mut lost_springs = checkpoint.clone();
    lost_springs.effects.retain(|e| e.effect != "friction");
    let why = refusal(&scene, &lost_springs);
    assert!(why.contains("lacks"), "{why}");

    let mut nan = checkpoint.clone();
    nan.bodies[3].v.y = f64::NAN;
    let why = refusal(&scene, &nan);
    assert!(why.contains("body 3"), "{why}");

    let mut short = checkpoint.clone();
    short.bodies.pop();
    assert!(refusal(&scene, &short).contains("bodies"));

    let mut bad_pair = checkpoint.clone();
    let friction = bad_pair
        .effects
        .iter_mut()
        .find(|e| e.effect == "friction")
        .unwrap();
    friction.history = vec![0.0, 0.0, 4.0, 2.0, 0.0, 0.0, 0.0, 0.0];
    let why = refusal(&scene, &bad_pair);
    assert!(why.contains("a < b"), "{why}");
}
