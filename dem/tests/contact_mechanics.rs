//! Contact mechanics where flat faces, edges and corners touch, validated the
//! way users run scenes: the rotation effect on, no global damping, on shapes
//! and angles no other test uses, against analytic references and
//! conservation laws. Each test states the property; the tolerances are those
//! docs/dem.md lists for the contact model.
use dem::effects::GravityParams;
use dem::exp_map::exp_map;
use dem::scene::Scene;
use dem::simulation::Simulation;
use glam::{DQuat, DVec3};
use std::path::Path;

fn scene(text: &str) -> Scene {
    Scene::parse(text, "test.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}\n{text}"))
}

/// A scene of `bodies` (TOML of particles and obstacles) with one material.
fn text(dt: f64, effects: &str, material: &str, bodies: &str) -> String {
    format!(
        r#"
        [simulation]
        dt = {dt:e}
        end_time = 100.0
        [effects]
        contact = {{}}
        rotation = {{}}
        {effects}
        [[materials]]
        name = "m"
        density = 1000.0
        {material}
        {bodies}
        "#
    )
}

fn material(stiffness: f64, restitution: f64, halo: f64, friction: Option<f64>) -> String {
    let mut m =
        format!("stiffness = {stiffness:e}\nrestitution = {restitution}\nhalo = {halo:e}\n");
    if let Some(mu) = friction {
        m.push_str(&format!("friction = {mu}\n"));
    }
    m
}

fn v3(v: DVec3) -> String {
    format!("[{:e}, {:e}, {:e}]", v.x, v.y, v.z)
}

fn particle(shape: &str, at: DVec3, rotation: DVec3, velocity: DVec3) -> String {
    format!(
        r#"
        [[particles]]
        material = "m"
        shape = {shape}
        placement = {{ kind = "single", position = {} }}
        rotation = {}
        velocity = {}
        "#,
        v3(at),
        v3(rotation),
        v3(velocity)
    )
}

fn obstacle(shape: &str, at: DVec3, rotation: DVec3) -> String {
    format!(
        r#"
        [[obstacles]]
        material = "m"
        shape = {shape}
        position = {}
        rotation = {}
        "#,
        v3(at),
        v3(rotation)
    )
}

fn boxed(size: DVec3, subdivide: usize) -> String {
    format!(
        "{{ kind = \"box\", size = {}, subdivide = {subdivide} }}",
        v3(size)
    )
}

/// One row of the validation table (docs/tables.md, "Validation", printed
/// with `--nocapture` and gathered by scripts/validation-table.sh): a
/// markdown row, with the `|` of the case's formula escaped.
fn report(case: &str, limit: &str, measured: f64) {
    let case = case.replace('|', "\\|");
    println!("validation | {case} | {limit} | {measured:.3e} |");
}

fn run(sim: &mut Simulation, steps: u64) {
    for _ in 0..steps {
        sim.step();
    }
}

/// Steps until contacts have come and gone; returns the steps in contact.
fn through_contact(sim: &mut Simulation) -> u64 {
    let (mut touched, mut steps) = (false, 0);
    for _ in 0..10_000_000 {
        sim.step();
        let c = sim.last_stats().detection.contacts;
        touched |= c > 0;
        steps += u64::from(c > 0);
        if touched && c == 0 {
            return steps;
        }
    }
    panic!("no contact came and went (touched: {touched})");
}

/// The angle of the rotation taking orientation `from` to `to`.
fn turned(from: DQuat, to: DQuat) -> f64 {
    let r = to * from.conjugate();
    2.0 * r.xyz().length().atan2(r.w.abs())
}

/// Two 20-triangle hulls, turned, one coming at 0.5 m/s with an impact
/// parameter `offset` (m) off the other's centre: elastic, frictionless.
fn hulls(offset: DVec3, dt: f64, ra: DVec3, rb: DVec3) -> Scene {
    let hull =
        |seed: u64| format!("{{ kind = \"hull\", triangles = 20, radius = 0.005, seed = {seed} }}");
    let bodies = particle(&hull(21), DVec3::ZERO, ra, DVec3::new(0.5, 0.0, 0.0))
        + &particle(
            &hull(22),
            DVec3::new(0.0125, 0.0, 0.0) + offset,
            rb,
            DVec3::ZERO,
        );
    scene(&text(dt, "", &material(1e4, 1.0, 1e-4, None), &bodies))
}

/// Elastic, frictionless, oblique: the kinetic energy after the impact is
/// the energy before (0.5%), converging as the step shrinks; with at least
/// 50 steps in contact.
#[test]
fn elastic_oblique_impacts_of_hulls_keep_their_energy() {
    let (ra, rb) = (DVec3::new(0.3, -1.1, 0.7), DVec3::new(-0.9, 0.4, 2.1));
    for y in [0.0015, 0.0035, 0.0055, 0.0075] {
        let offset = DVec3::new(0.0, y, 0.0013);
        let error = |dt: f64| {
            let mut sim = Simulation::new(&hulls(offset, dt, ra, rb));
            let before = sim.world.kinetic_energy();
            let steps = through_contact(&mut sim);
            assert!(steps >= 50, "offset {y}: {steps} steps in contact");
            (sim.world.kinetic_energy() / before - 1.0).abs()
        };
        let (coarse, fine) = (error(4e-6), error(1e-6));
        report(
            &format!("elastic hull impact, offset {y} m, dt 4e-6 s: |ΔE|/E"),
            "5e-3",
            coarse,
        );
        report(
            &format!("elastic hull impact, offset {y} m, dt 1e-6 s: |ΔE|/E"),
            "that at dt 4e-6 s, or 2e-6",
            fine,
        );
        assert!(
            coarse <= 5e-3,
            "offset {y}, dt 4e-6: energy off by {coarse}"
        );
        assert!(
            fine <= coarse.max(2e-6),
            "offset {y}: error {fine} at dt 1e-6, {coarse} at 4e-6"
        );
    }
}

/// The same for many impacts at random angles and orientations: the springs
/// are a potential, so no configuration creates or destroys energy (the
/// residue is the integrator's, about 1e-5 at this step).
#[test]
fn elastic_impacts_at_random_angles_keep_their_energy() {
    let mut x: u64 = 0x9e37_79b9_7f4a_7c15;
    let mut uniform = move || {
        x ^= x << 13;
        x ^= x >> 7;
        x ^= x << 17;
        (x >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut worst = 0.0f64;
    let mut impacts = 0;
    for _ in 0..40 {
        let mut turn = || DVec3::new(uniform(), uniform(), uniform()) * 6.0 - 3.0;
        let (ra, rb) = (turn(), turn());
        let offset = DVec3::new(0.0, 0.009 * uniform(), 0.004 * uniform());
        let mut sim = Simulation::new(&hulls(offset, 2e-6, ra, rb));
        let before = sim.world.kinetic_energy();
        let mut touched = false;
        for _ in 0..20_000 {
            sim.step();
            let c = sim.last_stats().detection.contacts;
            touched |= c > 0;
            if touched && c == 0 {
                break;
            }
        }
        if touched {
            impacts += 1;
            worst = worst.max((sim.world.kinetic_energy() / before - 1.0).abs());
        }
    }
    report(
        &format!("{impacts} elastic hull impacts at random angles: worst |ΔE|/E"),
        "1e-4",
        worst,
    );
    assert!(impacts >= 30, "only {impacts} of 40 hulls met");
    assert!(worst <= 1e-4, "kinetic energy off by {worst}");
}

/// A cube with its body diagonal `down` turned to point straight down.
fn diagonal_down(corner: DVec3) -> DVec3 {
    let a = corner.normalize();
    let b = DVec3::NEG_Z;
    a.cross(b).normalize() * a.dot(b).acos()
}

/// A 2 cm cube (scaled by `s`) meeting a floor at `speed` (scaled), turned
/// by `rotation`, its lowest point one halo above the floor's reach, centred
/// at `origin`; no gravity: the impact alone.
fn cube_on_floor(
    e: f64,
    rotation: DVec3,
    s: f64,
    origin: DVec3,
    friction: Option<f64>,
    subdivide: usize,
) -> Scene {
    let size = DVec3::splat(0.02 * s);
    let halo = 1e-4 * s;
    let q = exp_map(rotation);
    let lowest = (0..8)
        .map(|i| {
            let c = DVec3::new(
                if i & 1 == 0 { -0.5 } else { 0.5 },
                if i & 2 == 0 { -0.5 } else { 0.5 },
                if i & 4 == 0 { -0.5 } else { 0.5 },
            );
            (q * (c * size)).z
        })
        .fold(f64::INFINITY, f64::min);
    let at = origin + DVec3::new(0.003 * s, -0.002 * s, 3.0 * halo - lowest);
    let bodies = particle(
        &boxed(size, subdivide),
        at,
        rotation,
        DVec3::new(0.0, 0.0, -0.3 * s),
    ) + &obstacle(
        &boxed(DVec3::new(0.3, 0.3, 0.02) * s, subdivide),
        origin + DVec3::new(0.0, 0.0, -0.01 * s),
        DVec3::new(0.0, 0.0, 0.0),
    );
    let effects = if friction.is_some() {
        "friction = {}"
    } else {
        ""
    };
    // Stiffness ∝ s³ with the mass: the same contact time at every size.
    scene(&text(
        2e-6,
        effects,
        &material(1e5 * s.powi(3), e, halo, friction),
        &bodies,
    ))
}

/// Restitution and spin after the bounce of a cube landing centrally on a
/// face, an edge or a corner: (−v_z after / v_z before, |ω| R / |v| before).
fn bounce(e: f64, rotation: DVec3, s: f64, origin: DVec3) -> (f64, f64) {
    let mut sim = Simulation::new(&cube_on_floor(e, rotation, s, origin, None, 0));
    let v_in = sim.world.bodies[0].v.z;
    through_contact(&mut sim);
    let b = &sim.world.bodies[0];
    let radius = 0.02 * s * 3f64.sqrt() / 2.0;
    (-b.v.z / v_in, b.omega().length() * radius / v_in.abs())
}

const FACE: DVec3 = DVec3::ZERO;
/// An edge straight below the centre: turned 45 degrees about x.
const EDGE: DVec3 = DVec3::new(std::f64::consts::FRAC_PI_4, 0.0, 0.0);

/// Face, edge and corner impacts rebound with the set restitution (2%):
/// the pair's dashpot is set for all its contacts together.
#[test]
fn face_edge_and_corner_impacts_rebound_with_the_set_restitution() {
    let corner = diagonal_down(DVec3::new(-1.0, -1.0, -1.0));
    for e in [0.35, 0.8] {
        for (what, rotation) in [("face", FACE), ("edge", EDGE), ("corner", corner)] {
            let (measured, _) = bounce(e, rotation, 1.0, DVec3::ZERO);
            report(
                &format!("{what} impact, e = {e}: |e_measured/e − 1|"),
                "2e-2",
                (measured / e - 1.0).abs(),
            );
            assert!(
                (measured - e).abs() <= 0.02 * e,
                "{what}, e = {e}: measured {measured}"
            );
        }
    }
}

/// The same impacts for a cube a thousand times smaller and larger (every
/// length, the halo and the speed scaled; stiffness with the mass), and
/// 10 km from the origin: the same restitution to 1e-6.
#[test]
fn impacts_do_not_depend_on_size_or_place() {
    let corner = diagonal_down(DVec3::new(1.0, -1.0, -1.0));
    for (what, rotation) in [("face", FACE), ("edge", EDGE), ("corner", corner)] {
        let (reference, _) = bounce(0.6, rotation, 1.0, DVec3::ZERO);
        for (s, origin) in [
            (1e-3, DVec3::ZERO),
            (1e3, DVec3::ZERO),
            (1.0, DVec3::new(1e4, -1e4, 1e4)),
        ] {
            let (e, _) = bounce(0.6, rotation, s, origin);
            report(
                &format!(
                    "{what} impact at scale {s:e}, {:e} m from the origin: |e − e_unit|",
                    origin.length()
                ),
                "1e-6",
                (e - reference).abs(),
            );
            assert!(
                (e - reference).abs() <= 1e-6,
                "scale {s}, origin {origin}: e = {e}, {reference} at scale 1"
            );
        }
    }
}

/// A cube dropped flat, without friction, off the floor's centre and turned
/// so that the floor's diagonal runs under it: no spin after the bounce.
#[test]
fn a_flat_landing_does_not_spin() {
    let yaw = DVec3::new(0.0, 0.0, 0.37);
    for e in [0.6, 0.95] {
        let (measured, spin) = bounce(e, yaw, 1.0, DVec3::new(0.021, 0.013, 0.0));
        report(
            &format!("flat landing off-centre, turned, no friction, e = {e}: ω R / v"),
            "1e-4",
            spin,
        );
        assert!(spin <= 1e-4, "e = {e}: ω R / v = {spin}");
        assert!(
            (measured - e).abs() <= 0.02 * e,
            "e = {e}: measured {measured}"
        );
    }
}

/// Elastic, frictionless landings on an edge and on a corner, off-centre, so
/// that the cube leaves spinning: kinetic energy kept (0.5%).
#[test]
fn elastic_landings_on_edges_and_corners_keep_their_energy() {
    for rotation in [DVec3::new(0.41, 0.0, 0.0), DVec3::new(0.3, 0.5, 0.1)] {
        let mut sim = Simulation::new(&cube_on_floor(1.0, rotation, 1.0, DVec3::ZERO, None, 0));
        let before = sim.world.kinetic_energy();
        through_contact(&mut sim);
        let ratio = sim.world.kinetic_energy() / before;
        report(
            &format!("elastic landing, turned by {rotation}: |ΔE|/E"),
            "5e-3",
            (ratio - 1.0).abs(),
        );
        assert!((ratio - 1.0).abs() <= 5e-3, "{rotation}: {ratio}");
        assert!(
            sim.world.bodies[0].omega().length() > 1.0,
            "an off-centre landing turns the cube"
        );
    }
}

/// A 2 x 2 x 1 cm block resting on a slab tilted by `theta` (radians) about
/// y, `uphill` m up the slope from the slab's centre, both meshes
/// subdivided `subdivide` times.
fn incline(theta: f64, mu: f64, uphill: f64, subdivide: usize) -> (Scene, DVec3) {
    let normal = DVec3::new(theta.sin(), 0.0, theta.cos());
    let down = DVec3::new(theta.cos(), 0.0, -theta.sin());
    let halo = 1e-4;
    let at = normal * (0.01 + 0.005 + 2.0 * halo) - down * uphill;
    let tilt = DVec3::new(0.0, theta, 0.0);
    let bodies = particle(
        &boxed(DVec3::new(0.02, 0.02, 0.01), subdivide),
        at,
        tilt,
        DVec3::ZERO,
    ) + &obstacle(
        &boxed(DVec3::new(0.4, 0.1, 0.02), subdivide),
        DVec3::ZERO,
        tilt,
    );
    let effects = "gravity = { g = [0.0, 0.0, -9.81] }\nfriction = {}";
    let text = text(5e-6, effects, &material(1e5, 0.5, halo, Some(mu)), &bodies);
    (scene(&text), down)
}

/// Steps to settle on a slope or a floor: 0.1 s, a hundred contact periods.
const SETTLE: u64 = 20_000;

/// μ > tan θ: the block sticks. Over 2 s after settling it creeps less
/// than 1 µm and turns less than 1e-4 rad, at two angles.
#[test]
fn a_block_sticks_on_an_incline_steeper_than_friction_allows_to_slide() {
    for (deg, mu) in [(23.0f64, 0.65), (37.0, 0.95)] {
        let (s, _) = incline(deg.to_radians(), mu, 0.0, 0);
        let mut sim = Simulation::new(&s);
        run(&mut sim, SETTLE);
        let (x, q) = (sim.world.bodies[0].x, sim.world.bodies[0].q);
        run(&mut sim, 400_000);
        let b = &sim.world.bodies[0];
        let drift = (b.x - x).length();
        report(
            &format!("block on a {deg}° incline, μ = {mu}, 2 s: creep (m)"),
            "1e-6",
            drift,
        );
        report(
            &format!("block on a {deg}° incline, μ = {mu}, 2 s: turn (rad)"),
            "1e-4",
            turned(q, b.q),
        );
        assert!(drift <= 1e-6, "{deg} degrees: crept {drift} m");
        let turn = turned(q, b.q);
        assert!(turn <= 1e-4, "{deg} degrees: turned {turn} rad");
    }
}

/// μ < tan θ: the block slides at g (sin θ − μ cos θ) (1%), without turning.
#[test]
fn a_block_slides_at_the_coulomb_rate_without_turning() {
    for (deg, mu) in [(23.0f64, 0.2), (37.0, 0.45)] {
        let theta = deg.to_radians();
        let (s, down) = incline(theta, mu, 0.15, 0);
        let mut sim = Simulation::new(&s);
        run(&mut sim, SETTLE);
        let (t1, v1, q1) = (
            sim.world.time,
            sim.world.bodies[0].v.dot(down),
            sim.world.bodies[0].q,
        );
        run(&mut sim, 30_000);
        let b = &sim.world.bodies[0];
        let a = (b.v.dot(down) - v1) / (sim.world.time - t1);
        let expect = 9.81 * (theta.sin() - mu * theta.cos());
        assert!(
            (a - expect).abs() <= 0.01 * expect,
            "{deg} degrees: a = {a}, expected {expect}"
        );
        let turn = turned(q1, b.q);
        report(
            &format!("block sliding on a {deg}° incline, μ = {mu}: |a/a_Coulomb − 1|"),
            "1e-2",
            (a / expect - 1.0).abs(),
        );
        report(
            &format!("block sliding on a {deg}° incline, μ = {mu}: turn (rad)"),
            "1e-4",
            turn,
        );
        assert!(
            turn <= 1e-4,
            "{deg} degrees: turned {turn} rad while sliding"
        );
    }
}

/// Three unequal boxes stacked on a floor, aligned or each turned about the
/// vertical, with friction and no global damping, at a step of 1e-5 s (30
/// steps in the fastest rocking period): after settling, over 3 s,
/// nothing drifts (1 µm), turns (1e-4 rad) or gains motion.
#[test]
fn stacks_of_boxes_stay_at_rest() {
    for twist in [0.0, 0.4] {
        let halo = 1e-4;
        let mut bodies = obstacle(
            &boxed(DVec3::new(0.2, 0.2, 0.02), 0),
            DVec3::new(0.0, 0.0, -0.01),
            DVec3::ZERO,
        );
        let mut z = 0.0;
        for (k, (w, h)) in [(0.04, 0.012), (0.03, 0.01), (0.018, 0.008)]
            .into_iter()
            .enumerate()
        {
            let at = DVec3::new(
                0.001 * k as f64,
                -0.0007 * k as f64,
                z + 2.0 * halo + h / 2.0,
            );
            let yaw = DVec3::new(0.0, 0.0, twist * k as f64);
            bodies += &particle(&boxed(DVec3::new(w, w * 0.9, h), 0), at, yaw, DVec3::ZERO);
            z = at.z + h / 2.0;
        }
        let effects = "gravity = { g = [0.0, 0.0, -9.81] }\nfriction = {}";
        let mut sim = Simulation::new(&scene(&text(
            1e-5,
            effects,
            &material(1e5, 0.5, halo, Some(0.5)),
            &bodies,
        )));
        run(&mut sim, SETTLE / 2);
        let start: Vec<(DVec3, DQuat)> = sim.world.bodies.iter().map(|b| (b.x, b.q)).collect();
        let mut fastest = [0.0f64; 3];
        for fastest in &mut fastest {
            for _ in 0..100 {
                run(&mut sim, 1000);
                let v = sim
                    .world
                    .bodies
                    .iter()
                    .map(|b| b.v.length() + b.omega().length() * 0.02);
                *fastest = fastest.max(v.fold(0.0, f64::max));
            }
        }
        let worst = |f: &dyn Fn(&dem::body::Body, &(DVec3, DQuat)) -> f64| {
            sim.world
                .bodies
                .iter()
                .zip(&start)
                .map(|(b, s)| f(b, s))
                .fold(0.0, f64::max)
        };
        report(
            &format!("stack of 3 boxes, twist {twist} rad, 3 s: drift (m)"),
            "1e-6",
            worst(&|b, s| (b.x - s.0).length()),
        );
        report(
            &format!("stack of 3 boxes, twist {twist} rad, 3 s: turn (rad)"),
            "1e-4",
            worst(&|b, s| turned(s.1, b.q)),
        );
        for (i, (b, (x, q))) in sim.world.bodies.iter().zip(&start).enumerate() {
            let (drift, turn) = ((b.x - *x).length(), turned(*q, b.q));
            assert!(drift <= 1e-6, "twist {twist}, body {i}: drifted {drift} m");
            assert!(turn <= 1e-4, "twist {twist}, body {i}: turned {turn} rad");
        }
        assert!(
            fastest[2] <= fastest[0].max(1e-7),
            "twist {twist}: motion grows, fastest point per second {fastest:?} m/s"
        );
    }
}

/// A box meshed with 12 triangles and the same box with each face split into
/// 32 (192 triangles), on a floor or slab also refined: they bounce, slide
/// and stick the same (1%).
#[test]
fn refining_the_mesh_does_not_change_the_physics() {
    let compare = |what: &str, a: f64, b: f64| {
        report(
            &format!("12 vs 192 triangles, {what}: relative difference"),
            "1e-2",
            (a - b).abs() / a.abs().max(b.abs()),
        );
        assert!(
            (a - b).abs() <= 0.01 * a.abs().max(b.abs()),
            "{what}: {a} vs {b}"
        );
    };
    let compare_vectors = |what: &str, a: DVec3, b: DVec3| {
        let scale = a.length().max(b.length());
        report(
            &format!("12 vs 192 triangles, {what}: relative difference"),
            "1e-2",
            (a - b).length() / scale,
        );
        assert!((a - b).length() <= 0.01 * scale, "{what}: {a} vs {b}");
    };
    // Bounce: an off-centre corner landing, with friction.
    let landing = |subdivide: usize| {
        let rotation = DVec3::new(0.3, 0.5, 0.1);
        let s = cube_on_floor(0.7, rotation, 1.0, DVec3::ZERO, Some(0.4), subdivide);
        assert_eq!(s.world.shapes[0].triangles.len(), 12 << (2 * subdivide));
        let mut sim = Simulation::new(&s);
        through_contact(&mut sim);
        let b = &sim.world.bodies[0];
        (b.v, b.omega())
    };
    let ((v0, w0), (v2, w2)) = (landing(0), landing(2));
    compare_vectors("bounce velocity", v0, v2);
    compare_vectors("bounce spin", w0, w2);
    assert!(w0.length() > 1.0, "an off-centre landing turns the cube");
    // Slide and stick on a slope.
    let slope = |mu: f64, subdivide: usize| {
        let (s, down) = incline(0.5, mu, 0.1, subdivide);
        let mut sim = Simulation::new(&s);
        let x0 = sim.world.bodies[0].x;
        run(&mut sim, SETTLE + 20_000);
        (sim.world.bodies[0].x - x0).dot(down)
    };
    compare("slide", slope(0.3, 0), slope(0.3, 2));
    compare("stick", slope(0.8, 0), slope(0.8, 2));
}

/// The energy books balance: kinetic + stored + dissipated stays what the
/// scene started with (1%, the bookkeeping of dissipation being first order
/// in the step) through bounces, sliding and rolling, and the dashpots and
/// friction both dissipate.
#[test]
fn energy_books_balance_with_dissipation() {
    let rotation = DVec3::new(0.3, 0.5, 0.1);
    let mut s = cube_on_floor(0.6, rotation, 1.0, DVec3::ZERO, Some(0.4), 0);
    s.effects.set(GravityParams {
        g: [0.0, 0.0, -9.81],
    });
    s.world.bodies[0].v = DVec3::new(0.4, 0.1, -0.3);
    let mut sim = Simulation::new(&s);
    let start = sim.energies().total();
    let moving = sim.world.kinetic_energy();
    run(&mut sim, 100_000);
    let e = sim.energies();
    assert!(
        (e.total() - start).abs() <= 0.01 * moving,
        "books off by {} of {moving} J kinetic: {e:?}",
        e.total() - start
    );
    for effect in ["contact", "friction"] {
        let d = e.effects.iter().find(|x| x.effect == effect).unwrap();
        assert!(
            d.dissipated > 0.05 * moving,
            "{effect} dissipated {}",
            d.dissipated
        );
    }
}
