//! Outflow (the `outflow` effect) against streams whose answer is known,
//! and its bookkeeping: the energy the particles carry out, the checkpoint,
//! and a scene without it.
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

const G: f64 = 9.81;

/// A column of 20 particles, 2 by 10, 20 mm apart, in free fall from rest,
/// plus the scene's `extra` effects; particle k starts at z₀ = 0.011 + 0.02 k
/// (two per height).
fn column(extra: &str) -> Scene {
    let text = format!(
        r#"
        [simulation]
        dt = 1e-4
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -{G}] }}
        rotation = {{}}
        {extra}
        [[materials]]
        name = "m"
        density = 1000.0
        [[particles]]
        material = "m"
        shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = 4 }}
        placement = {{ kind = "lattice", count = [1, 2, 10], spacing = 0.02, origin = [0.0, 0.0, 0.011] }}
        angular_velocity = [3.0, -1.0, 2.0]
        "#
    );
    Scene::parse(&text, "outflow.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn measure(sim: &Simulation, name: &str) -> f64 {
    sim.measure(name)
        .unwrap_or_else(|| panic!("no measure {name}"))
}

const SINK: &str =
    r#"outflow = { planes = [{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, -1.0] }] }"#;

/// A plane at z = 0: a particle leaves at the end of the first step at
/// which its centre is below it, t_k = the first multiple of dt past
/// √(2 z₀ / g). At every output time the count is exactly the particles
/// whose crossing time has passed, the mass their mass; a particle that
/// left stays where it left (within one step's fall of the plane); and the
/// energy books (kinetic + gravity's potential + what was carried out)
/// keep the start's total to the integrator's rounding.
#[test]
fn an_outflow_plane_takes_out_what_falls_past_it_and_books_its_energy() {
    let mut sim = Simulation::new(&column(SINK));
    let z0: Vec<f64> = sim.world.bodies.iter().map(|b| b.x.z).collect();
    let m = sim.world.bodies[0].mass;
    let total0 = sim.energies().total();
    let dt = sim.dt;
    for _ in 0..20 {
        for _ in 0..100 {
            sim.step();
        }
        let t = sim.world.time;
        // Velocity Verlet in uniform gravity is exact: z(t) = z₀ − g t²/2
        // at every step, so the crossing step is known. Crossings within a
        // step of an output time are left out of the count's test.
        let crossing = |z0: f64| (2.0 * z0 / G).sqrt();
        let near = z0.iter().any(|&z| (crossing(z) - t).abs() < 2.0 * dt);
        let gone = z0.iter().filter(|&&z| crossing(z) < t).count() as f64;
        if !near {
            assert_eq!(measure(&sim, "outflow_count"), gone, "t = {t}");
            assert!((measure(&sim, "outflow_mass") - gone * m).abs() <= 1e-12 * m * 20.0);
        }
        for (b, &z) in sim.world.bodies.iter().zip(&z0) {
            assert_eq!(b.removed, b.x.z < 0.0, "t = {t}: removed exactly when past");
            if b.removed {
                let v = G * crossing(z);
                assert!(b.x.z > -v * dt * 1.01, "t = {t}: parked where it left");
            }
        }
        let total = sim.energies().total();
        assert!(
            (total - total0).abs() <= 1e-7 * total0.abs().max(m * G * 0.2),
            "t = {t}: energy {total} against {total0} at the start"
        );
    }
    assert_eq!(measure(&sim, "outflow_count"), 20.0, "the column has left");
    let left: f64 = sim
        .energies()
        .effects
        .iter()
        .find(|e| e.effect == "outflow")
        .map(|e| e.stored)
        .unwrap();
    assert!(
        left != 0.0,
        "the outflow holds what the particles carried out"
    );
}

/// A box: particles leave once their centre is outside it, whichever face
/// they cross; a particle shot sideways leaves by the side.
#[test]
fn an_outflow_box_takes_out_what_leaves_it() {
    let text = r#"
        [simulation]
        dt = 1e-4
        end_time = 1.0
        [effects]
        outflow = { inside = { lo = [-0.1, -0.1, -0.1], hi = [0.1, 0.1, 0.1] } }
        [[materials]]
        name = "m"
        density = 1000.0
        [[particles]]
        material = "m"
        shape = { kind = "tetrahedron", radius = 0.005 }
        placement = { kind = "single", position = [0.0, 0.0, 0.0] }
        velocity = [1.0, 0.0, 0.0]
        [[particles]]
        material = "m"
        shape = { kind = "tetrahedron", radius = 0.005 }
        placement = { kind = "single", position = [0.0, 0.05, 0.0] }
        velocity = [0.0, 0.0, -0.25]
    "#;
    let scene = Scene::parse(text, "box.toml", Path::new(".")).unwrap();
    let mut sim = Simulation::new(&scene);
    // x = t: the first leaves after 0.1 s; z = −t/4: the second after 0.4 s.
    for (steps, count) in [(990, 0.0), (20, 1.0), (2970, 1.0), (40, 2.0)] {
        for _ in 0..steps {
            sim.step();
        }
        assert_eq!(
            measure(&sim, "outflow_count"),
            count,
            "t = {}",
            sim.world.time
        );
    }
    let parked = sim.world.bodies[0].x;
    for _ in 0..100 {
        sim.step();
    }
    assert_eq!(
        sim.world.bodies[0].x, parked,
        "a removed particle does not move"
    );
}

/// A checkpoint taken after some particles left resumes to the bits of
/// the uninterrupted run, the removed ones still out.
#[test]
fn a_run_with_an_outflow_resumes_to_the_bit() {
    let scene = column(SINK);
    let mut through = Simulation::new(&scene);
    for _ in 0..1000 {
        through.step();
    }
    let checkpoint = through.checkpoint();
    assert!(checkpoint.bodies.iter().any(|b| b.removed));
    assert!(checkpoint.bodies.iter().any(|b| !b.removed));
    let mut resumed = Simulation::resume(&scene, &checkpoint).unwrap();
    for _ in 0..1000 {
        through.step();
        resumed.step();
    }
    assert_eq!(resumed.checkpoint(), through.checkpoint());
    assert_eq!(
        measure(&resumed, "outflow_count"),
        measure(&through, "outflow_count")
    );
}

/// An outflow nothing reaches changes no bit of the run, and a scene
/// without it measures nothing of it.
#[test]
fn an_outflow_nothing_reaches_changes_nothing() {
    let far =
        r#"outflow = { planes = [{ point = [0.0, 0.0, -100.0], normal = [0.0, 0.0, -1.0] }] }"#;
    let (mut with, mut without) = (Simulation::new(&column(far)), Simulation::new(&column("")));
    for _ in 0..500 {
        with.step();
        without.step();
    }
    assert_eq!(with.checkpoint().bodies, without.checkpoint().bodies);
    assert_eq!(measure(&with, "outflow_count"), 0.0);
    assert!(without.measure("outflow_count").is_none());
}

/// Bad outflows are refused with the file, line and cause.
#[test]
fn bad_outflows_are_refused() {
    for (outflow, says) in [
        ("outflow = {}", "declare a plane"),
        (
            r#"outflow = { planes = [{ point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 0.0] }] }"#,
            "normal not zero",
        ),
        (
            r#"outflow = { inside = { lo = [0.0, 0.0, 0.0], hi = [1.0, -1.0, 1.0] } }"#,
            "lo ≤ hi",
        ),
        (r#"outflow = { below = 0.0 }"#, "unknown field"),
    ] {
        let text = format!(
            "[simulation]\ndt = 1e-4\nend_time = 1.0\n[effects]\n{outflow}\n[[materials]]\nname = \"m\"\ndensity = 1.0\n[[particles]]\nmaterial = \"m\"\nshape = {{ kind = \"tetrahedron\", radius = 0.01 }}\nplacement = {{ kind = \"single\", position = [0.0, 0.0, 0.0] }}\n"
        );
        let e = Scene::parse(&text, "bad.toml", Path::new("."))
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("bad.toml:5") && e.contains(says),
            "{outflow}: {e}"
        );
    }
}
