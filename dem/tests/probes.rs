//! Probes (the `probes` effect) against a stream whose answer is known: a
//! column of particles in free fall, each centre at z₀ − g t²/2 at time t.
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

const G: f64 = 9.81;

fn column(probes: &str) -> Scene {
    let text = format!(
        r#"
        [simulation]
        dt = 1e-4
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -{G}] }}
        {probes}
        [[materials]]
        name = "m"
        density = 1000.0
        [[particles]]
        material = "m"
        shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = 4 }}
        placement = {{ kind = "lattice", count = [1, 2, 10], spacing = 0.02, origin = [0.0, 0.0, 0.011] }}
        "#
    );
    Scene::parse(&text, "probes.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn measure(sim: &Simulation, name: &str) -> f64 {
    sim.measure(name)
        .unwrap_or_else(|| panic!("no measure {name}"))
}

/// A plane at z = 0 facing down counts the particles that fell past it, and
/// a box below z = 0.05 those in it with their momentum, −m g t each: at
/// every output time, the counts exactly, the masses and momenta to rounding.
#[test]
fn probes_count_a_falling_column() {
    let probes = r#"probes = { planes = [{ name = "floor", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, -1.0] }], regions = [{ name = "low", lo = [-1.0, -1.0, -1.0], hi = [1.0, 1.0, 0.05] }] }"#;
    let mut sim = Simulation::new(&column(probes));
    let z0: Vec<f64> = sim.world.bodies.iter().map(|b| b.x.z).collect();
    let m = sim.world.bodies[0].mass;
    let mut seen_past = 0.0f64;
    for _ in 0..20 {
        for _ in 0..100 {
            sim.step();
        }
        let t = sim.world.time;
        let z = |z0: f64| z0 - 0.5 * G * t * t;
        let past = z0.iter().filter(|&&z0| z(z0) < 0.0).count() as f64;
        let low = z0.iter().filter(|&&z0| z(z0) <= 0.05).count() as f64;
        assert_eq!(measure(&sim, "floor_count_past"), past, "t = {t}");
        assert!((measure(&sim, "floor_mass_past") - past * m).abs() <= 1e-12 * m * 20.0);
        assert_eq!(measure(&sim, "low_count"), low, "t = {t}");
        assert!((measure(&sim, "low_mass") - low * m).abs() <= 1e-12 * m * 20.0);
        let p = measure(&sim, "low_momentum_z");
        let expected = -low * m * G * t;
        assert!(
            (p - expected).abs() <= 1e-9 * expected.abs().max(m * G * t),
            "t = {t}: momentum {p}, expected {expected}"
        );
        assert_eq!(measure(&sim, "low_momentum_x"), 0.0);
        seen_past = seen_past.max(past);
    }
    assert!(
        seen_past >= 10.0,
        "the column fell past the plane: {seen_past}"
    );
}

/// Bad probes are refused with the file, line and cause; no probe is no
/// measure.
#[test]
fn bad_probes_are_refused_and_absent_probes_measure_nothing() {
    for (probes, says) in [
        ("probes = {}", "at least one region or plane"),
        (
            r#"probes = { planes = [{ name = "a", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 0.0] }] }"#,
            "normal not zero",
        ),
        (
            r#"probes = { regions = [{ name = "a", lo = [0.0, 0.0, 1.0], hi = [1.0, 1.0, 0.0] }] }"#,
            "lo ≤ hi",
        ),
        (
            r#"probes = { regions = [{ name = "a b", lo = [0.0, 0.0, 0.0], hi = [1.0, 1.0, 1.0] }] }"#,
            "probe name",
        ),
        (
            r#"probes = { regions = [{ name = "a", lo = [0.0, 0.0, 0.0], hi = [1.0, 1.0, 1.0] }], planes = [{ name = "a", point = [0.0, 0.0, 0.0], normal = [0.0, 0.0, 1.0] }] }"#,
            "two probes are named `a`",
        ),
    ] {
        let text = format!(
            "[simulation]\ndt = 1e-4\nend_time = 1.0\n[effects]\n{probes}\n[[materials]]\nname = \"m\"\ndensity = 1.0\n[[particles]]\nmaterial = \"m\"\nshape = {{ kind = \"tetrahedron\", radius = 0.01 }}\nplacement = {{ kind = \"single\", position = [0.0, 0.0, 0.0] }}\n"
        );
        let e = Scene::parse(&text, "probes.toml", Path::new("."))
            .map(|_| ())
            .unwrap_err()
            .to_string();
        assert!(e.contains(says), "{probes}: {e}");
        assert!(e.contains("probes.toml:5"), "names the line: {e}");
    }
    let sim = Simulation::new(&column(""));
    assert!(sim.energies().measures.is_empty());
}
