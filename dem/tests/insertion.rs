//! Insertion (the `insertion` effect) against its schedule, its promise of
//! no overlap, the energy books, its seed and a resume.
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

/// Hulls of radius 5 mm (halo 0.5 mm) poured from `region` at `rate`,
/// `count` of them, falling under gravity onto each other in a box with no
/// floor; rotation, contacts and friction on.
fn pour(region: &str, rate: &str, count: usize, seed: u64) -> String {
    format!(
        r#"
        [simulation]
        dt = 2e-5
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{}}
        friction = {{}}
        rotation = {{}}
        insertion = {{}}
        [[materials]]
        name = "m"
        density = 2500.0
        stiffness = 5e4
        restitution = 0.4
        halo = 5e-4
        friction = 0.5
        [[particles]]
        material = "m"
        shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = 4 }}
        placement = {{ kind = "insert", count = {count}, region = {region}, {rate} seed = {seed} }}
        orientation = "random"
        velocity = [0.0, 0.0, -0.5]
        angular_velocity = [2.0, 0.0, -1.0]
        "#
    )
}

const WIDE: &str = r#"{ kind = "box", lo = [-0.2, -0.2, 0.0], hi = [0.2, 0.2, 0.1] }"#;
const NARROW: &str =
    r#"{ kind = "cylinder", base = [0.0, 0.0, 0.0], top = [0.0, 0.0, 0.03], radius = 0.012 }"#;

fn scene(text: &str) -> Scene {
    Scene::parse(text, "pour.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

/// The bounding radius plus halo of every body (all of one shape here).
fn reach(sim: &Simulation) -> f64 {
    let mesh = &sim.world.shapes[0];
    let r = mesh.vertices.iter().map(|v| v.length()).fold(0.0, f64::max);
    r + 5e-4
}

/// Steps `sim` `n` times; after each, every particle that entered in it
/// stands clear (bounding spheres with halos apart) of every particle in
/// the run. Returns how many entered.
fn step_checking_room(sim: &mut Simulation, n: usize) -> usize {
    let reach = reach(sim);
    let mut entered = 0;
    for _ in 0..n {
        let waiting: Vec<bool> = sim.world.bodies.iter().map(|b| b.pending).collect();
        sim.step();
        let bodies = &sim.world.bodies;
        for (i, b) in bodies.iter().enumerate() {
            if !waiting[i] || b.pending {
                continue;
            }
            entered += 1;
            for (j, o) in bodies.iter().enumerate() {
                if j != i && !o.is_out() {
                    let gap = (b.x - o.x).length();
                    assert!(gap >= 2.0 * reach, "{i} entered {gap:e} m from {j}");
                }
            }
        }
    }
    entered
}

/// In a wide region, where there is room for every particle when it is due,
/// particle k enters at the end of the first step reaching t_k = k / rate:
/// after n steps of dt, exactly ⌊n dt · rate⌋ + 1 have entered (each clear
/// of all others), the measure `inserted_count` says so, and the energy
/// books (kinetic + gravity's potential + springs + what friction and
/// dashpots took − what insertion brought in) keep their start's total.
#[test]
fn particles_enter_on_schedule_with_room_and_their_energy_is_booked() {
    let rate = 2000.0;
    let mut sim = Simulation::new(&scene(&pour(WIDE, "rate = 2000.0,", 60, 1)));
    let (dt, total0) = (sim.dt, sim.energies().total());
    assert_eq!(sim.energies().total(), 0.0, "nothing in the run yet");
    let mut entered = 0;
    for block in 1..=15 {
        entered += step_checking_room(&mut sim, 100);
        let n = 100 * block;
        // Due: t_k ≤ the run's time, in floating point, as the effect tests
        // it; within one of ⌊n dt · rate⌋ + 1 (the time is a sum of steps).
        let t = sim.world.time;
        let due = (0..60).filter(|&k| k as f64 / rate <= t).count();
        let ideal = ((n as f64 * dt * rate).floor() as usize + 1).min(60);
        assert!(due.abs_diff(ideal) <= 1);
        assert_eq!(entered, due, "after {n} steps");
        assert_eq!(sim.measure("inserted_count"), Some(due as f64));
    }
    assert_eq!(entered, 60);
    let total = sim.energies().total();
    let scale = sim.energies().translation.max(1e-12);
    assert!(
        (total - total0).abs() <= 1e-12 * scale,
        "books drift {:e} J against a kinetic energy of {scale:e} J",
        total - total0
    );
}

/// In a region with room for about one particle at a time, due particles
/// queue: none ever enters touching another, none enters early, all enter
/// once those before them have fallen out of the way, and no contact is
/// ever deeper than the halos.
#[test]
fn a_crowded_region_makes_particles_wait_and_never_overlap() {
    let mut sim = Simulation::new(&scene(&pour(NARROW, "", 25, 3)));
    // Waiting at one point, they are no bodies inside others.
    assert!(sim.world.enclosed_pairs().is_empty());
    let mut total = 0;
    let mut waited = false;
    for _ in 0..100 {
        let entered = step_checking_room(&mut sim, 100);
        total += entered;
        waited |= total < 25;
        assert!(
            sim.crossed_pairs().is_empty(),
            "a contact deeper than the halos"
        );
    }
    assert!(waited, "all 25 due at once cannot all fit at once");

    assert_eq!(total, 25, "each enters once the region clears");
}

/// The same seed gives the same run to the bit; another seed other
/// positions. Stopped with particles still waiting, a checkpoint resumes to
/// the bits of the run that did not stop.
#[test]
fn the_seed_decides_and_a_resume_keeps_the_draws() {
    let text = pour(NARROW, "rate = 400.0,", 30, 9);
    let run = |text: &str, steps: usize| {
        let mut sim = Simulation::new(&scene(text));
        (0..steps).for_each(|_| sim.step());
        sim
    };
    let whole = run(&text, 3000);
    assert_eq!(whole.checkpoint(), run(&text, 3000).checkpoint());
    let other = run(&pour(NARROW, "rate = 400.0,", 30, 10), 3000);
    assert_ne!(whole.world.bodies[1].x, other.world.bodies[1].x);
    let half = run(&text, 1500);
    let c = half.checkpoint();
    assert!(c.bodies.iter().any(|b| b.pending) && c.bodies.iter().any(|b| !b.pending));
    let mut resumed = Simulation::resume(&scene(&text), &c).unwrap();
    (0..1500).for_each(|_| resumed.step());
    assert_eq!(resumed.checkpoint(), whole.checkpoint());
    assert_eq!(resumed.energies(), whole.energies());
}

/// Refused, naming the file and line: a group to insert without the
/// effect, the effect with nothing to insert, a bad region, rate or start,
/// and a region that reaches an obstacle.
#[test]
fn bad_insertions_are_refused_with_file_and_line() {
    let refused = |text: String, cause: &str| {
        let e = Scene::parse(&text, "pour.toml", Path::new("."))
            .err()
            .unwrap_or_else(|| panic!("accepted: {cause}"))
            .to_string();
        assert!(e.contains("pour.toml:") && e.contains(cause), "{e}");
    };
    let good = pour(NARROW, "rate = 10.0,", 5, 0);
    refused(
        good.replace("insertion = {}", ""),
        "declare `insertion = {}`",
    );
    refused(
        good.replace(
            r#"kind = "insert", count = 5,"#,
            r#"kind = "random", count = 5, lo = [0.0, 0.0, 0.0], hi = [1.0, 1.0, 1.0],"#,
        )
        .replace(&format!("region = {NARROW}, rate = 10.0, "), ""),
        "no group is",
    );
    refused(good.replace("radius = 0.012", "radius = -1.0"), "radius");
    refused(
        good.replace("top = [0.0, 0.0, 0.03]", "top = [0.0, 0.0, 0.0]"),
        "must differ",
    );
    refused(
        good.replace("rate = 10.0", "rate = 0.0"),
        "rate must be positive",
    );
    refused(
        good.replace("rate = 10.0,", "rate = 10.0, start = -1.0,"),
        "start",
    );
    refused(
        good.replace(r#"count = 5,"#, r#"count = 0,"#),
        "count = 0 inserts no particle",
    );
    let wall = r#"
        [[obstacles]]
        material = "m"
        shape = { kind = "box", size = [0.1, 0.1, 0.01] }
        position = [0.0, 0.0, -0.009]
    "#;
    refused(good.clone() + wall, "reaches the obstacle");
    // Clear of it, the same floor is accepted.
    let clear = wall.replace("-0.009", "-0.02");
    Scene::parse(&(good + &clear), "pour.toml", Path::new(".")).unwrap();
}
