//! Moving walls (the `wall_motion` effect): a driven obstacle goes where its
//! velocity puts it, carries what rests on it by friction as mechanics says,
//! and the work it does is booked, so that the energy books still balance.
//! Rotation on, no global damping.
use dem::body::{Drive, Profile};
use dem::exp_map::exp_map;
use dem::scene::Scene;
use dem::simulation::Simulation;
use glam::{DQuat, DVec3};
use std::path::Path;

fn parse(text: &str) -> Result<Scene, String> {
    Scene::parse(text, "walls.toml", Path::new(".")).map_err(|e| e.to_string())
}

/// A 2 × 2 × 1 cm block two halos above a 30 cm floor whose motion is
/// `motion` (TOML keys of the obstacle), with gravity and friction μ = 0.5.
fn block_on_floor(block_at: DVec3, motion: &str, effects: &str) -> String {
    format!(
        r#"
        [simulation]
        dt = 5e-6
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{}}
        friction = {{}}
        rotation = {{}}
        {effects}
        [[materials]]
        name = "m"
        density = 1000.0
        stiffness = 1e5
        restitution = 0.5
        halo = 1e-4
        friction = 0.5
        [[particles]]
        material = "m"
        shape = {{ kind = "box", size = [0.02, 0.02, 0.01] }}
        placement = {{ kind = "single", position = [{:e}, {:e}, 0.0052] }}
        [[obstacles]]
        material = "m"
        shape = {{ kind = "box", size = [0.3, 0.3, 0.02] }}
        position = [0.0, 0.0, -0.01]
        {motion}
        "#,
        block_at.x, block_at.y
    )
}

const WALLS: &str = "wall_motion = {}";

fn run(sim: &mut Simulation, steps: u64) {
    for _ in 0..steps {
        sim.step();
    }
}

/// Every body's position, velocity and angular momentum, as bits.
fn state_bits(s: &Simulation) -> Vec<u64> {
    s.world
        .bodies
        .iter()
        .flat_map(|b| [b.x.to_array(), b.v.to_array(), b.l.to_array()])
        .flatten()
        .map(f64::to_bits)
        .collect()
}

/// `scene` run 6,000 steps straight and stopped at 3,000 and resumed: the
/// same bits and books. Returns the resumed run.
fn stopped_and_resumed(scene: &Scene) -> Simulation {
    let mut straight = Simulation::new(scene);
    run(&mut straight, 3_000);
    let checkpoint = straight.checkpoint();
    run(&mut straight, 3_000);
    let mut resumed = Simulation::resume(scene, &checkpoint).unwrap();
    run(&mut resumed, 3_000);
    assert_eq!(state_bits(&straight), state_bits(&resumed));
    assert_eq!(straight.energies(), resumed.energies());
    resumed
}

fn booked(sim: &Simulation, effect: &str) -> f64 {
    let e = sim.energies();
    e.effects
        .iter()
        .find(|x| x.effect == effect)
        .map(|x| x.dissipated)
        .unwrap_or_else(|| panic!("no books of {effect}: {e:?}"))
}

/// A floor sliding at constant v under a block at rest: friction, the only
/// horizontal force, brings the block to v, and the floor's work is then
/// v · (the horizontal impulse it gave) = m v² exactly, half of it kinetic
/// energy, half dissipated by sliding. Measured: the block's speed (0.5%),
/// the booked work (1%), the books' balance (1% of the work), and the
/// floor's pose, x₀ + v t to rounding.
#[test]
fn a_sliding_floor_carries_a_block_and_its_work_is_booked() {
    let v = DVec3::new(0.05, 0.02, 0.0);
    let text = block_on_floor(DVec3::ZERO, "velocity = [0.05, 0.02, 0.0]", WALLS);
    let scene = parse(&text).unwrap();
    let mut sim = Simulation::new(&scene);
    let start = sim.energies().total();
    run(&mut sim, 40_000);
    let (block, floor) = (&sim.world.bodies[0], &sim.world.bodies[1]);
    let m = block.mass;
    let horizontal = DVec3::new(block.v.x, block.v.y, 0.0);
    assert!(
        (horizontal - v).length() <= 5e-3 * v.length(),
        "block at {horizontal}, floor at {v}"
    );
    let work = -booked(&sim, "wall_motion");
    let expected = m * v.dot(horizontal);
    assert!(
        (work - expected).abs() <= 1e-2 * expected,
        "floor's work {work} J, m v·v_block = {expected} J"
    );
    let friction = booked(&sim, "friction");
    assert!(
        (friction - 0.5 * expected).abs() <= 0.05 * expected,
        "sliding dissipated {friction} J of {expected} J"
    );
    let e = sim.energies();
    assert!(
        (e.total() - start).abs() <= 1e-2 * work,
        "books off by {} J, the floor did {work} J: {e:?}",
        e.total() - start
    );
    let t = sim.world.time;
    let x = DVec3::new(0.0, 0.0, -0.01) + v * t;
    assert!((floor.x - x).length() <= 4.0 * f64::EPSILON * x.length());
    assert_eq!(floor.v, v, "a driven wall keeps its velocity");
}

/// A turntable at Ω carries a block at radius r round with it: the block
/// moves at Ω r and turns at Ω (1%), and the books balance (1% of the
/// table's work), with the table's orientation exp(Ω t) to rounding.
#[test]
fn a_turntable_carries_a_block_round() {
    let omega = DVec3::new(0.0, 0.0, 2.0);
    let r = DVec3::new(0.05, 0.0, 0.0);
    let text = block_on_floor(r, "angular_velocity = [0.0, 0.0, 2.0]", WALLS);
    let mut sim = Simulation::new(&parse(&text).unwrap());
    let start = sim.energies().total();
    run(&mut sim, 100_000);
    let (block, table) = (&sim.world.bodies[0], &sim.world.bodies[1]);
    let arm = DVec3::new(block.x.x, block.x.y, 0.0);
    let carried = omega.cross(arm);
    assert!(
        (block.v - carried).length() <= 1e-2 * carried.length(),
        "block at {}, table surface at {carried}",
        block.v
    );
    assert!(
        (block.omega() - omega).length() <= 1e-2 * omega.length(),
        "block turns at {}",
        block.omega()
    );
    assert!((arm.length() - r.length()).abs() <= 1e-3 * r.length());
    let work = -booked(&sim, "wall_motion");
    let e = sim.energies();
    assert!(work > 0.0);
    assert!(
        (e.total() - start).abs() <= 1e-2 * work,
        "books off by {} J, the table did {work} J: {e:?}",
        e.total() - start
    );
    let q = exp_map(omega * sim.world.time);
    assert!(
        (table.q.dot(q).abs() - 1.0).abs() <= 1e-14,
        "table at {:?}, exp(Ω t) = {q:?}",
        table.q
    );
    assert_eq!(table.omega(), omega);
}

/// Stopped and resumed, a run with a moving wall goes on to the same bits.
#[test]
fn a_resumed_run_with_a_moving_wall_gives_the_same_bits() {
    let text = block_on_floor(
        DVec3::new(0.02, 0.0, 0.0),
        "velocity = [0.03, 0.0, 0.001]\nangular_velocity = [0.0, 0.0, 1.0]",
        WALLS,
    );
    stopped_and_resumed(&parse(&text).unwrap());
}

/// A floor whose velocity ramps up over 0.1 s, then holds (a table), under
/// a block that sticks to it (the ramp's acceleration is a tenth of μ g):
/// the block ends at the floor's velocity (0.5%), the floor's work is the
/// block's kinetic energy and what sliding took (1%), the books balance (1%
/// of the work), and the floor stands where the area under its table puts
/// it: x₀ + v_end (t − 0.05 s) once the ramp is done, to rounding.
#[test]
fn a_floor_ramped_up_by_a_table_carries_a_block() {
    let v = DVec3::new(0.04, -0.03, 0.0);
    let motion = "velocity_table = [[0.0, 0.0, 0.0, 0.0], [0.1, 0.04, -0.03, 0.0]]";
    let mut sim = Simulation::new(&parse(&block_on_floor(DVec3::ZERO, motion, WALLS)).unwrap());
    let start = sim.energies().total();
    run(&mut sim, 40_000);
    let (block, floor) = (&sim.world.bodies[0], &sim.world.bodies[1]);
    let horizontal = DVec3::new(block.v.x, block.v.y, 0.0);
    assert!(
        (horizontal - v).length() <= 5e-3 * v.length(),
        "block at {horizontal}, floor at {v}"
    );
    let work = -booked(&sim, "wall_motion");
    let kinetic = 0.5 * block.mass * horizontal.length_squared();
    let slid = booked(&sim, "friction");
    assert!(
        (work - kinetic - slid).abs() <= 1e-2 * work,
        "floor's work {work} J, block's kinetic energy {kinetic} J, sliding {slid} J"
    );
    let e = sim.energies();
    assert!(
        (e.total() - start).abs() <= 1e-2 * work,
        "books off by {} J, the floor did {work} J: {e:?}",
        e.total() - start
    );
    let t = sim.world.time;
    let x = DVec3::new(0.0, 0.0, -0.01) + v * (t - 0.05);
    assert!(
        (floor.x - x).length() <= 1e-12 * x.length(),
        "{} against {x}",
        floor.x
    );
    assert_eq!(floor.v, v, "held at the last row's velocity");
}

/// Stopped in the middle of its tables and resumed, a run whose wall is
/// spun up and pushed by tables goes on to the same bits.
#[test]
fn a_resumed_run_with_a_wall_on_tables_gives_the_same_bits() {
    let text = block_on_floor(
        DVec3::new(0.02, 0.0, 0.0),
        "velocity_table = [[0.0, 0.0, 0.0, 0.0], [0.02, 0.03, 0.0, 0.001], [0.04, 0.0, 0.01, 0.0]]\n\
         angular_velocity_table = [[0.01, 0.0, 0.0, 0.0], [0.03, 0.0, 0.0, -1.5]]",
        WALLS,
    );
    let resumed = stopped_and_resumed(&parse(&text).unwrap());
    let table = &resumed.world.bodies[1];
    assert_eq!(
        table.omega(),
        DVec3::new(0.0, 0.0, -1.5),
        "held after the last row"
    );
}

/// A floor removed at 0.05 s under a block resting on it: before, the block
/// rests (its height within a halo of where it settled); after, nothing
/// holds it, and over the next N steps its velocity changes by exactly
/// −g N h (velocity Verlet is exact under a constant force) while its
/// horizontal velocity stays put. Stopped after the removal and resumed, the
/// run goes on to the same bits.
/// With and without a neighbour list.
#[test]
fn a_removed_floor_lets_its_load_fall_freely() {
    let text = block_on_floor(DVec3::ZERO, "remove_at = 0.05", "");
    removed_floor(&text);
    removed_floor(&text.replace("contact = {}", "contact = { skin = 1e-3 }"));
}

fn removed_floor(text: &str) {
    let scene = parse(text).unwrap();
    let mut sim = Simulation::new(&scene);
    let h = 5e-6;
    // To the first step wholly after the removal.
    let before = (0.05 / h) as u64 - 1;
    run(&mut sim, before);
    let resting = sim.world.bodies[0].x.z;
    assert!(
        sim.world.bodies[0].v.length() < 1e-3,
        "settled on the floor"
    );
    run(&mut sim, 2);
    let v0 = sim.world.bodies[0].v;
    let checkpoint = sim.checkpoint();
    let n = 4000;
    run(&mut sim, n);
    let v = sim.world.bodies[0].v;
    let g = 9.81 * n as f64 * h;
    assert!(
        (v.z - (v0.z - g)).abs() <= 1e-9 * g,
        "fell at {} after {} s, free fall gives {}",
        v.z,
        n as f64 * h,
        v0.z - g
    );
    assert_eq!((v.x, v.y), (v0.x, v0.y));
    assert!(sim.world.bodies[0].x.z < resting - 0.5 * 9.81 * (n as f64 * h).powi(2) * 0.99);
    let mut resumed = Simulation::resume(&scene, &checkpoint).unwrap();
    run(&mut resumed, n);
    assert_eq!(state_bits(&sim), state_bits(&resumed));
}

/// What a removal does to the books, as docs/dem.md says: across the step
/// that removes the floor under a resting block, the books' total drops by
/// the energy the floor's contacts (spring and friction) stored just before,
/// within a hundredth of it; in the steps before and after, it stays put to
/// a thousandth of that.
#[test]
fn a_removal_takes_its_contacts_stored_energy_out_of_the_books() {
    let text = block_on_floor(DVec3::ZERO, "remove_at = 0.05", "");
    let mut sim = Simulation::new(&parse(&text).unwrap());
    let stored = |sim: &Simulation| -> f64 {
        let e = sim.energies();
        e.effects
            .iter()
            .filter(|x| x.effect == "contact" || x.effect == "friction")
            .map(|x| x.stored)
            .sum()
    };
    run(&mut sim, (0.05 / 5e-6) as u64 - 10);
    // (total, stored) each step, to two steps past the one that removes it.
    let mut books = vec![(sim.energies().total(), stored(&sim))];
    while books.len() < 3 || books[books.len() - 3].1 > 0.0 {
        assert!(books.len() < 100, "the floor was never removed");
        run(&mut sim, 1);
        books.push((sim.energies().total(), stored(&sim)));
    }
    let k = books.len() - 3;
    let ((e0, _), (e1, held), (e2, gone), (e3, _)) =
        (books[k - 2], books[k - 1], books[k], books[k + 1]);
    assert!(
        held > 0.0 && gone == 0.0,
        "the block rested on the floor, then nothing held it"
    );
    assert!(
        (e2 - e1 + held).abs() <= 1e-2 * held,
        "dropped by {}, the contacts held {held} J",
        e1 - e2
    );
    assert!((e1 - e0).abs() <= 1e-3 * held, "before: {}", e1 - e0);
    assert!((e3 - e2).abs() <= 1e-3 * held, "after: {}", e3 - e2);
}

/// A moving wall needs the effect that books its work, and the effect needs
/// a moving wall; a non-finite velocity is refused. Each refusal names the
/// line.
#[test]
fn moving_walls_are_declared_together_with_their_effect() {
    let cases = [
        (
            "velocity = [0.1, 0.0, 0.0]",
            "",
            "declare `wall_motion = {}`",
        ),
        ("", WALLS, "no obstacle sets a velocity"),
        (
            "angular_velocity = [0.0, nan, 0.0]",
            WALLS,
            "must be finite",
        ),
        (
            "velocity = [0.1, 0.0, 0.0]\nvelocity_table = [[0.0, 0.1, 0.0, 0.0]]",
            WALLS,
            "not both",
        ),
        (
            "velocity_table = [[0.0, 0.0, 0.0, 0.0], [0.2, 1.0, 0.0, 0.0], [0.1, 0.0, 0.0, 0.0]]",
            WALLS,
            "times must increase, but row 3",
        ),
        (
            "velocity_table = [[0.0, 0.0, 0.0, 0.0], [0.1, inf, 0.0, 0.0]]",
            WALLS,
            "must be finite",
        ),
        ("velocity_table = []", WALLS, "has no rows"),
        (
            "angular_velocity_table = [[0.0, 0.0, 0.0, 1.0], [1.0, 0.0, 1.0, 1.0]]",
            WALLS,
            "one axis",
        ),
        (
            "remove_at = -1.0",
            "",
            "remove_at must be a time after the start",
        ),
        ("remove_at = 0.5", WALLS, "no obstacle sets a velocity"),
    ];
    for (motion, effects, says) in cases {
        let e = parse(&block_on_floor(DVec3::ZERO, motion, effects)).unwrap_err();
        assert!(e.contains(says), "{motion} / {effects}: {e}");
        assert!(e.contains("walls.toml:"), "names the file and line: {e}");
    }
}

/// A drive's pose is the closed form at every time: x₀ + v t, exp(ω t) q₀.
#[test]
fn a_drive_places_its_wall_by_the_time_alone() {
    let q0 = exp_map(DVec3::new(0.1, -0.2, 0.3));
    let d = Drive::new(
        DVec3::new(1e6, -2e6, 3.0),
        q0,
        Profile::Constant(DVec3::new(0.5, 0.0, -0.25)),
        Profile::Constant(DVec3::new(0.0, 0.0, std::f64::consts::PI)),
    );
    let (x, q) = d.pose(2.0);
    assert_eq!(x, DVec3::new(1e6 + 1.0, -2e6, 2.5));
    // Half a turn a second: two seconds is a whole turn, back to q0.
    assert!((q.dot(q0).abs() - 1.0).abs() <= 1e-15);
    let (_, half) = d.pose(1.0);
    let expected = DQuat::from_rotation_z(std::f64::consts::PI) * q0;
    assert!((half.dot(expected).abs() - 1.0).abs() <= 1e-15);
}

/// A piston wall and a hull coming at each other, under a neighbour list
/// (skin) and without: the same bits, from five starting gaps (they close by
/// the whole skin between rebuilds of the list, so one of them meets the
/// wall within it). The list must allow for the wall's motion as for the
/// hull's, or the impact would come late.
#[test]
fn a_neighbour_list_sees_a_moving_wall() {
    let piston = |contact: &str, gap: f64| {
        format!(
            r#"
            [simulation]
            dt = 1e-5
            end_time = 1.0
            [effects]
            contact = {contact}
            friction = {{}}
            rotation = {{}}
            wall_motion = {{}}
            [[materials]]
            name = "m"
            density = 1000.0
            stiffness = 1e4
            restitution = 0.5
            halo = 1e-4
            friction = 0.3
            [[particles]]
            material = "m"
            shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = 3 }}
            placement = {{ kind = "single", position = [0.0, 0.0, 0.0] }}
            velocity = [-0.5, 0.0, 0.0]
            [[obstacles]]
            material = "m"
            shape = {{ kind = "box", size = [0.01, 0.1, 0.1] }}
            position = [{x:e}, 0.001, -0.002]
            velocity = [0.5, 0.0, 0.0]
            "#,
            x = -0.03 - gap
        )
    };
    let run_of = |contact: &str, gap: f64| {
        let mut sim = Simulation::new(&parse(&piston(contact, gap)).unwrap());
        run(&mut sim, 8_000);
        let b = &sim.world.bodies[0];
        assert!(b.v.x > 0.3, "the hull bounced off the piston: {}", b.v);
        [b.x, b.v, b.l].map(|v| v.to_array().map(f64::to_bits))
    };
    for k in 0..5 {
        let gap = 4e-4 * f64::from(k);
        assert_eq!(
            run_of("{}", gap),
            run_of("{ skin = 2e-3 }", gap),
            "gap +{gap}"
        );
    }
}

/// A wall that would leave finite numbers within the run is refused; one
/// that would jump past half a particle in a step is warned of, naming the
/// line; an ordinary one is neither.
#[test]
fn walls_too_fast_for_the_run_are_refused_or_warned_of() {
    let text = block_on_floor(DVec3::ZERO, "velocity = [1e308, 0.0, 0.0]", WALLS)
        .replace("end_time = 1.0", "end_time = 10.0");
    let e = parse(&text).unwrap_err();
    assert!(e.contains("beyond finite numbers"), "{e}");
    assert!(e.contains("walls.toml:"), "{e}");
    let fast = parse(&block_on_floor(
        DVec3::ZERO,
        "angular_velocity = [0.0, 0.0, 1e4]",
        WALLS,
    ))
    .unwrap();
    assert!(
        fast.warnings
            .iter()
            .any(|w| w.contains("moving obstacle's surface moves") && w.contains("walls.toml:")),
        "{:?}",
        fast.warnings
    );
    let slow = parse(&block_on_floor(
        DVec3::ZERO,
        "velocity = [1.0, 0.0, 0.0]",
        WALLS,
    ))
    .unwrap();
    assert!(slow.warnings.is_empty(), "{:?}", slow.warnings);
}
