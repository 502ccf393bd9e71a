//! Validation of the DEM against analytic references. Tolerances are on the
//! physics; nothing here is timed.
use dem::scene::Scene;
use dem::simulation::Simulation;
use glam::DVec3;
use std::path::Path;

fn scene(text: &str) -> Scene {
    Scene::parse(text, "test.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn run(sim: &mut Simulation, steps: u64) {
    for _ in 0..steps {
        sim.step();
    }
}

/// Tetrahedra under gravity alone, placed (and set moving) by `placement`.
fn falling(placement: &str) -> Scene {
    scene(&format!(
        r#"
        [simulation]
        dt = 1e-3
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        [[materials]]
        name = "m"
        density = 1000.0
        [[particles]]
        material = "m"
        shape = {{ kind = "tetrahedron", radius = 0.01 }}
        {placement}
        "#
    ))
}

/// x(t) = x0 + v0 t + g t²/2: velocity Verlet is exact for constant force.
#[test]
fn free_fall_matches_the_parabola() {
    let s = falling(
        r#"placement = { kind = "single", position = [0.1, -0.2, 3.0] }
        velocity = [1.0, 0.5, 2.0]"#,
    );
    let mut sim = Simulation::new(&s);
    let (x0, v0, g) = (
        DVec3::new(0.1, -0.2, 3.0),
        DVec3::new(1.0, 0.5, 2.0),
        DVec3::new(0.0, 0.0, -9.81),
    );
    for _ in 0..10 {
        run(&mut sim, 100);
        let t = sim.world.time;
        let exact = x0 + v0 * t + g * (0.5 * t * t);
        let x = sim.world.bodies[0].x;
        assert!(
            (x - exact).length() <= 1e-12 * exact.length(),
            "t={t}: {x} vs {exact}"
        );
        assert!((sim.world.bodies[0].v - (v0 + g * t)).length() <= 1e-12 * 10.0);
    }
}

fn two_boxes(e: f64, extra: &str) -> Scene {
    scene(&format!(
        r#"
        [simulation]
        dt = 2e-6
        end_time = 1.0
        [effects]
        contact = {{}}
        {extra}
        [[materials]]
        name = "m"
        density = 1000.0
        stiffness = 200000.0
        restitution = {e}
        halo = 1e-4
        [[particles]]
        material = "m"
        shape = {{ kind = "box", size = [0.02, 0.02, 0.02] }}
        placement = {{ kind = "single", position = [-0.0102, 0.0, 0.0] }}
        velocity = [0.3, 0.0, 0.0]
        [[particles]]
        material = "m"
        shape = {{ kind = "box", size = [0.02, 0.02, 0.02] }}
        placement = {{ kind = "single", position = [0.0102, 0.0, 0.0] }}
        velocity = [-0.3, 0.0, 0.0]
        "#
    ))
}

/// Head-on impact: the measured coefficient of restitution is the set one (2%).
#[test]
fn two_body_impact_restitution() {
    for e in [0.3, 0.5, 0.9] {
        let mut sim = Simulation::new(&two_boxes(e, ""));
        let before = sim.world.bodies[0].v.x - sim.world.bodies[1].v.x;
        // Until the contact has come and gone.
        let mut touched = false;
        for _ in 0..1_000_000 {
            sim.step();
            let c = sim.last_stats().detection.contacts;
            touched |= c > 0;
            if touched && c == 0 {
                break;
            }
        }
        assert!(touched);
        let after = sim.world.bodies[0].v.x - sim.world.bodies[1].v.x;
        let measured = -after / before;
        assert!(
            (measured - e).abs() <= 0.02 * e,
            "set {e}, measured {measured}"
        );
    }
}

/// With damping and friction off and e = 1, total energy (kinetic + springs)
/// is conserved over 10,000 steps of repeated collisions between two walls.
#[test]
fn energy_is_conserved_without_dissipation() {
    let s = scene(
        r#"
        [simulation]
        dt = 1e-5
        end_time = 1.0
        [effects]
        contact = {}
        [[materials]]
        name = "m"
        density = 1000.0
        stiffness = 10000.0
        restitution = 1.0
        halo = 1e-3
        [[particles]]
        material = "m"
        shape = { kind = "box", size = [0.02, 0.02, 0.02] }
        placement = { kind = "single", position = [0.0, 0.0, 0.0] }
        velocity = [0.5, 0.0, 0.0]
        [[obstacles]]
        material = "m"
        shape = { kind = "box", size = [0.01, 0.1, 0.1] }
        position = [-0.0175, 0.0, 0.0]
        [[obstacles]]
        material = "m"
        shape = { kind = "box", size = [0.01, 0.1, 0.1] }
        position = [0.0175, 0.0, 0.0]
        "#,
    );
    let mut sim = Simulation::new(&s);
    let e0 = sim.total_energy();
    let mut collisions = 0;
    let mut was = false;
    let mut worst = 0.0f64;
    for _ in 0..10_000 {
        sim.step();
        let now = sim.last_stats().detection.contacts > 0;
        if now && !was {
            collisions += 1;
        }
        was = now;
        worst = worst.max((sim.total_energy() - e0).abs() / e0);
    }
    assert!(collisions >= 5, "only {collisions} collisions");
    assert!(worst <= 0.005, "energy drift {worst}");
}

/// A torque-free asymmetric body: angular momentum conserved to 1e-10
/// (relative), rotational energy bounded, and the tumbling that of Euler's
/// equations.
#[test]
fn torque_free_rotation_conserves_angular_momentum() {
    let s = scene(
        r#"
        [simulation]
        dt = 1e-3
        end_time = 1.0
        [effects]
        rotation = {}
        [[materials]]
        name = "m"
        density = 1000.0
        [[particles]]
        material = "m"
        shape = { kind = "box", size = [0.01, 0.02, 0.03] }
        placement = { kind = "single", position = [0.0, 0.0, 0.0] }
        angular_velocity = [1.0, 20.0, 0.5]
        orientation = "random"
        "#,
    );
    let mut sim = Simulation::new(&s);
    let l0 = sim.world.bodies[0].l;
    let e0 = sim.world.kinetic_energy();
    let mut worst_e = 0.0f64;
    for _ in 0..20_000 {
        sim.step();
        worst_e = worst_e.max((sim.world.kinetic_energy() - e0).abs() / e0);
    }
    let l = sim.world.bodies[0].l;
    assert!((l - l0).length() <= 1e-10 * l0.length(), "{l} vs {l0}");
    assert!(worst_e <= 1e-3, "rotational energy drift {worst_e}");
    // The body tumbles as Euler's equations say: its angular momentum in
    // body axes, L_b' = L_b × I⁻¹ L_b, integrated here by RK4 at a step a
    // hundred times finer, ends where the simulation's does, and has moved
    // far from where it started (the check is not of a body at rest).
    let b = &sim.world.bodies[0];
    let start = &s.world.bodies[0];
    let inv = start.inv_inertia_body;
    let rate = |lb: glam::DVec3| lb.cross(inv * lb);
    let mut lb = start.q.inverse() * start.l;
    let h = 1e-5;
    for _ in 0..(20.0 / h) as usize {
        let k1 = rate(lb);
        let k2 = rate(lb + 0.5 * h * k1);
        let k3 = rate(lb + 0.5 * h * k2);
        let k4 = rate(lb + h * k3);
        lb += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
    }
    let got = b.q.inverse() * b.l;
    let lb0 = start.q.inverse() * start.l;
    assert!(
        (lb - lb0).length() > 0.1 * lb0.length(),
        "no tumbling: {lb0} -> {lb}"
    );
    assert!(
        (got - lb).length() <= 2e-2 * lb0.length(),
        "body-axes angular momentum {got} vs Euler's equations {lb}"
    );
    let q = sim.world.bodies[0].q;
    assert!((q.length() - 1.0).abs() < 1e-12);
}

fn incline(theta_deg: f64, mu: f64) -> Scene {
    let th = theta_deg.to_radians();
    let n = DVec3::new(th.sin(), 0.0, th.cos());
    let c = n * (0.005 + 0.005 + 2e-4 - 1e-6);
    scene(&format!(
        r#"
        [simulation]
        dt = 2e-5
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{}}
        friction = {{}}
        [[materials]]
        name = "m"
        density = 1000.0
        stiffness = 20000.0
        restitution = 0.3
        halo = 1e-4
        friction = {mu}
        [[particles]]
        material = "m"
        shape = {{ kind = "box", size = [0.02, 0.02, 0.01] }}
        placement = {{ kind = "single", position = [{}, {}, {}] }}
        rotation = [0.0, {th}, 0.0]
        [[obstacles]]
        material = "m"
        shape = {{ kind = "box", size = [0.4, 0.1, 0.01] }}
        position = [0.0, 0.0, 0.0]
        rotation = [0.0, {th}, 0.0]
        "#,
        c.x, c.y, c.z
    ))
}

/// A block sliding down an incline accelerates at g (sin θ − μ cos θ).
#[test]
fn block_slides_down_incline_at_the_coulomb_rate() {
    let (theta, mu) = (30f64, 0.2);
    let mut sim = Simulation::new(&incline(theta, mu));
    let th = theta.to_radians();
    let down = DVec3::new(th.cos(), 0.0, -th.sin());
    run(&mut sim, 2500); // settle onto the slope: 0.05 s
    let (t1, v1) = (sim.world.time, sim.world.bodies[0].v.dot(down));
    run(&mut sim, 5000);
    let (t2, v2) = (sim.world.time, sim.world.bodies[0].v.dot(down));
    let a = (v2 - v1) / (t2 - t1);
    let expect = 9.81 * (th.sin() - mu * th.cos());
    assert!(
        (a - expect).abs() <= 0.02 * expect,
        "a = {a}, expected {expect}"
    );
}

/// When tan θ < μ the block stays at rest.
#[test]
fn block_stays_on_a_gentle_incline() {
    let (theta, mu) = (10f64, 0.3);
    let mut sim = Simulation::new(&incline(theta, mu));
    run(&mut sim, 2500);
    let x1 = sim.world.bodies[0].x;
    run(&mut sim, 10_000);
    let x2 = sim.world.bodies[0].x;
    // Over 0.2 s, sliding at even 1% of g sin θ would cover 0.3 mm.
    assert!((x2 - x1).length() < 1e-6, "moved {}", (x2 - x1).length());
    assert!(sim.world.bodies[0].v.length() < 1e-4);
}

fn stack_text(effects: &str) -> String {
    let mut t = format!(
        r#"
        [simulation]
        dt = 2e-5
        end_time = 10.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{}}
        {effects}
        [[materials]]
        name = "m"
        density = 1000.0
        stiffness = 20000.0
        restitution = 0.3
        halo = 1e-4
        "#
    );
    if effects.contains("friction") {
        t.push_str("friction = 0.5\n");
    }
    for k in 0..10 {
        t.push_str(&format!(
            r#"
            [[particles]]
            material = "m"
            shape = {{ kind = "box", size = [0.01, 0.01, 0.01] }}
            placement = {{ kind = "single", position = [0.0, 0.0, {}] }}
            "#,
            0.005 + 2e-4 + k as f64 * (0.01 + 2e-4)
        ));
    }
    t.push_str(
        r#"
        [[obstacles]]
        material = "m"
        shape = { kind = "box", size = [0.1, 0.1, 0.01] }
        position = [0.0, 0.0, -0.005]
        "#,
    );
    t
}

/// Ten particles stacked on a floor settle and stay at rest over 100,000 steps.
#[test]
fn resting_stack_stays_at_rest() {
    let s = scene(&stack_text(
        "friction = {}\nrotation = {}\ndamping = { linear = 20.0, angular = 20.0 }",
    ));
    let mut sim = Simulation::new(&s);
    run(&mut sim, 40_000);
    let settled: Vec<DVec3> = sim.world.bodies.iter().map(|b| b.x).collect();
    let mut max_v = 0.0f64;
    for _ in 0..100 {
        run(&mut sim, 1000);
        for b in sim.world.bodies.iter().filter(|b| !b.is_static()) {
            assert!(b.x.is_finite(), "explosion");
            max_v = max_v.max(b.v.length());
        }
    }
    let drift = sim
        .world
        .bodies
        .iter()
        .zip(&settled)
        .map(|(b, x)| (b.x - *x).length())
        .fold(0.0, f64::max);
    assert!(drift < 1e-5, "drift {drift}");
    assert!(max_v < 1e-3, "jitter {max_v}");
    // Each particle still rests on the one below, in order.
    for k in 1..10 {
        assert!(sim.world.bodies[k].x.z > sim.world.bodies[k - 1].x.z + 0.009);
    }
}

/// No friction effect: no tangential force is ever evaluated. A declared
/// effect with zero parameters changes nothing when removed.
#[test]
fn only_declared_effects_act() {
    let mut no_friction = Simulation::new(&scene(&stack_text("rotation = {}")));
    run(&mut no_friction, 2000);
    assert!(no_friction.totals.detection.contacts > 0);
    assert_eq!(no_friction.totals.tangential_evaluations, 0);
    assert_eq!(
        no_friction.effect_names(),
        vec!["gravity", "contact", "rotation"]
    );

    let mut with = Simulation::new(&scene(&stack_text("friction = {}\nrotation = {}")));
    run(&mut with, 2000);
    assert!(with.totals.tangential_evaluations > 0);

    let mut a = Simulation::new(&scene(&stack_text(
        "friction = {}\nrotation = {}\ndamping = { linear = 0.0, angular = 0.0 }",
    )));
    let mut b = Simulation::new(&scene(&stack_text("friction = {}\nrotation = {}")));
    run(&mut a, 3000);
    run(&mut b, 3000);
    for (x, y) in a.world.bodies.iter().zip(&b.world.bodies) {
        assert_eq!(x.x, y.x);
        assert_eq!(x.v, y.v);
        assert_eq!(x.q, y.q);
    }
}

/// Without the rotation effect orientations never change.
#[test]
fn without_rotation_bodies_only_translate() {
    let mut sim = Simulation::new(&scene(&stack_text("friction = {}")));
    let q0: Vec<_> = sim.world.bodies.iter().map(|b| b.q).collect();
    run(&mut sim, 3000);
    for (b, q) in sim.world.bodies.iter().zip(q0) {
        assert_eq!(b.q, q);
    }
}

/// The step that makes a state non-finite says so, with its step and time;
/// the steps before it find nothing wrong.
#[test]
fn the_step_that_makes_the_state_non_finite_is_named() {
    let s = falling(
        r#"placement = { kind = "lattice", count = [3, 1, 1], spacing = 0.1, origin = [0.0, 0.0, 1.0] }"#,
    );
    let mut sim = Simulation::new(&s);
    for _ in 0..10 {
        sim.step();
        assert_eq!(sim.check(), Ok(()), "step {}", sim.world.step);
    }
    // A velocity that overflows: the next drift carries it into the position.
    sim.world.bodies[2].v.y = f64::MAX;
    sim.world.bodies[2].v.y *= 2.0;
    sim.forget_motion();
    sim.step();
    let e = sim.check().expect_err("an infinite position");
    assert_eq!((e.step, e.time), (11, sim.world.time));
    assert!(e.to_string().contains("non-finite at step 11"), "{e}");
}
