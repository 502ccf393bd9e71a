//! Culling chooses which triangle pairs reach the kernel; it must never
//! change what is found. The hull test and the sweep ([`Culling::Hulls`],
//! the default) against every pair of triangles near the other body's box
//! ([`Culling::Boxes`]): the same body pairs, the same contacts and the same
//! motion, to the bit, step by step, with far fewer triangle pairs examined.
mod common;

use dem::contact::Culling;
use dem::effects::ContactParams;
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

/// Per step: body pairs (examined, or left out as still apart), contacts
/// and triangle pairs; then the motion bits, and the body pairs the hulls
/// settled, those left out as still apart, and those examined on their kept
/// triangle pairs.
type Run = (Vec<[u64; 3]>, Vec<Vec<u64>>, [u64; 3]);

fn run(scene: &Scene, culling: Culling, steps: usize) -> Run {
    let mut scene = scene.clone();
    let skin = scene.effects.get::<ContactParams>().map_or(0.0, |c| c.skin);
    scene.effects.set(ContactParams { skin, culling });
    let mut sim = Simulation::new(&scene);
    let (mut counts, mut states) = (Vec::new(), Vec::new());
    for _ in 0..steps {
        sim.step();
        let d = sim.last_stats().detection;
        counts.push([d.body_pairs, d.contacts, d.triangle_pairs]);
        states.push(common::motion_bits(&sim.world));
    }
    let t = sim.totals.detection;
    (counts, states, [t.hulls_apart, t.known_apart, t.near_kept])
}

/// Runs both cullings; asserts the same finds and motion; returns the
/// triangle pairs each examined, and the body pairs the hulls settled,
/// those left out as still apart and those examined on kept triangle pairs.
fn compare(scene: &Scene, steps: usize) -> (u64, u64, [u64; 3]) {
    let (boxes, boxes_states, none_apart) = run(scene, Culling::Boxes, steps);
    let (hulls, hulls_states, apart) = run(scene, Culling::Hulls, steps);
    assert_eq!(
        none_apart,
        [0, 0, 0],
        "boxes neither test hulls nor keep pairs"
    );
    let contacts: u64 = boxes.iter().map(|c| c[1]).sum();
    assert!(contacts > 0, "a test with contacts to find");
    for step in 0..steps {
        // A pair left out as still apart is one whose box may overlap:
        // body pairs are counted differently, contacts the same.
        assert_eq!(hulls[step][1], boxes[step][1], "step {step}: contacts");
        assert!(
            hulls_states[step] == boxes_states[step],
            "step {step}: motion differs"
        );
    }
    let pairs = |r: &[[u64; 3]]| r.iter().map(|c| c[2]).sum::<u64>();
    (pairs(&boxes), pairs(&hulls), apart)
}

fn scene(name: &str) -> Scene {
    let path = Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(name);
    Scene::load(&path).unwrap()
}

/// The hopper: small particles (20 triangles) in a hopper of plates.
#[test]
fn hull_culling_finds_what_box_culling_finds_in_the_hopper() {
    let (boxes, hulls, [apart, still, kept]) = compare(&scene("hopper.toml"), 3_000);
    eprintln!(
        "triangle pairs: boxes {boxes}, hulls {hulls}; body pairs {apart} apart, {still} still apart, {kept} on kept pairs"
    );
    assert!(apart > 0 && hulls < boxes / 2, "{hulls} of {boxes}");
    assert!(still > 0, "the clearance left pairs out");
    assert!(kept > 0, "triangle pairs were kept");
}

/// Large meshes (hulls of 600 triangles, tumbling onto a floor and each
/// other): the sweep pairs the triangles there.
#[test]
fn hull_culling_finds_what_box_culling_finds_between_large_meshes() {
    let text = r#"
[simulation]
dt = 1e-4
end_time = 1.0
[effects]
gravity = { g = [0.0, 0.0, -9.81] }
contact = { skin = 2e-3 }
friction = {}
rotation = {}
[[materials]]
name = "rock"
density = 2600.0
stiffness = 1e6
restitution = 0.4
halo = 1e-3
friction = 0.5
[[particles]]
material = "rock"
shape = { kind = "hull", triangles = 600, radius = 0.05, seed = 3 }
placement = { kind = "lattice", count = [2, 2, 2], spacing = 0.104, origin = [-0.05, -0.05, 0.055] }
orientation = "random"
[[obstacles]]
material = "rock"
shape = { kind = "box", size = [0.5, 0.5, 0.02] }
position = [0.0, 0.0, -0.01]
"#;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::parse(text, "large-meshes.toml", dir).unwrap();
    let (boxes, hulls, apart) = compare(&scene, 1_500);
    eprintln!("triangle pairs: boxes {boxes}, hulls {hulls}; body pairs apart {apart:?}");
    assert!(hulls < boxes, "{hulls} of {boxes}");
}

/// Triangle pairs kept for a body pair, where the bound on the bodies'
/// displacement is tight: a finely meshed box, tilted by 0.01 rad, falls
/// without turning (no rotation, no gravity, no friction) straight onto a
/// finely meshed floor and sinks into the halos. Its lower bottom edge comes
/// within reach first; its upper one, 1 mm higher, comes within reach while
/// the pair is examined on the triangle pairs kept at an earlier step (the
/// margin is 2 mm), its triangles closing on the floor by exactly the
/// displacement. Every step finds what culling from scratch finds.
#[test]
fn kept_triangle_pairs_miss_none_that_come_within_reach() {
    let text = r#"
[simulation]
dt = 1e-5
end_time = 1.0
[effects]
contact = { skin = 8e-3 }
[[materials]]
name = "rock"
density = 2600.0
stiffness = 1e4
restitution = 0.4
halo = 1e-3
[[particles]]
material = "rock"
shape = { kind = "box", size = [0.1, 0.1, 0.1], subdivide = 3 }
placement = { kind = "single", position = [0.0, 0.0, 0.054] }
rotation = [0.01, 0.0, 0.0]
velocity = [0.0, 0.0, -1.0]
[[obstacles]]
material = "rock"
shape = { kind = "box", size = [0.3, 0.3, 0.02], subdivide = 3 }
position = [0.0, 0.0, -0.01]
"#;
    let dir = Path::new(env!("CARGO_MANIFEST_DIR"));
    let scene = Scene::parse(text, "sinking-box.toml", dir).unwrap();
    let steps = 1_500;
    let (_, _, [_, _, kept]) = compare(&scene, steps);
    let (counts, _, _) = run(&scene, Culling::Hulls, steps);
    let most = counts.iter().map(|c| c[1]).max().unwrap_or(0);
    let first = counts.iter().map(|c| c[1]).find(|&c| c > 0).unwrap_or(0);
    eprintln!("{kept} steps on kept pairs; contacts: {first} at first touch, {most} at most");
    assert!(kept > 100, "the pair was examined on kept pairs: {kept}");
    assert!(
        most > first,
        "more contacts came within reach: {first} then {most}"
    );
}

/// A grain a millionth of a metre across near a floor a million metres
/// across: the kernel's answers are certified to a fraction of the pair's
/// scale, the floor's, which is here larger than the gap between a corner's
/// distance and the reach. The triangle pairs within reach by that error
/// still reach the feature contacts, which decide from the features' exact
/// data: the hybrid finds the contacts brute force finds, with the same
/// motion, at every tilt and height within the reach.
#[test]
fn a_tiny_grain_on_a_huge_floor_has_brute_forces_contacts() {
    let text = |method: &str, rotation: [f64; 3]| {
        format!(
            r#"
[simulation]
dt = 1e-12
end_time = 1e-11
[effects]
contact = {{}}
rotation = {{}}
[[materials]]
name = "m"
density = 1000.0
stiffness = 1e-3
restitution = 0.5
halo = 2e-7
[[particles]]
material = "m"
shape = {{ kind = "tetrahedron", radius = 2e-6 }}
placement = {{ kind = "single", position = [0.3, 0.2, 0.0] }}
rotation = {rotation:?}
[[obstacles]]
material = "m"
shape = {{ kind = "box", size = [1e6, 1e6, 2.0] }}
position = [0.0, 0.0, -1.0]
[kernel]
method = "{method}"
"#
        )
    };
    let (mut found, mut differ) = (0, Vec::new());
    // An edge level with the floor (no rotation: the tetrahedron's lowest
    // edge is horizontal), turned about the vertical; then turns about
    // axes spread over the sphere (a golden-angle spiral).
    let rotations = (0..8)
        .map(|k| [0.0, 0.0, 0.4 * k as f64])
        .chain((0..400).map(|k| {
            let z = 1.0 - 2.0 * (k as f64 + 0.5) / 400.0;
            let phi = k as f64 * 2.399_963_229_728_653;
            let r = (1.0 - z * z).sqrt();
            let angle = 0.1 + 3.0 * ((k * 7) % 31) as f64 / 31.0;
            [r * phi.cos() * angle, r * phi.sin() * angle, z * angle]
        }));
    for (k, rotation) in rotations.enumerate() {
        for height in [0.3, 0.9, 0.99, 0.999] {
            let run = |method: &str| {
                let mut scene = Scene::parse(&text(method, rotation), "s.toml", Path::new("."))
                    .unwrap_or_else(|e| panic!("{e}"));
                let body = &scene.world.bodies[0];
                let r = glam::DMat3::from_quat(body.q);
                let lowest = scene.world.shapes[body.shape]
                    .vertices
                    .iter()
                    .map(|&v| (body.x + r * v).z)
                    .fold(f64::INFINITY, f64::min);
                // The lowest corner `height` reaches (4e-7) above the floor.
                scene.world.bodies[0].x.z += height * 4e-7 - lowest;
                let mut sim = Simulation::new(&scene);
                sim.step();
                let contacts = sim.last_stats().detection.contacts;
                (contacts, common::motion_bits(&sim.world))
            };
            let (brute, hybrid) = (run("brute"), run("hybrid"));
            found += brute.0;
            if brute != hybrid {
                differ.push((k, height, brute.0, hybrid.0));
            }
        }
    }
    assert!(
        found >= 408 * 4,
        "every tilt and height has a contact: {found}"
    );
    assert!(
        differ.is_empty(),
        "(tilt, height, brute, hybrid contacts): {differ:?}"
    );
}
