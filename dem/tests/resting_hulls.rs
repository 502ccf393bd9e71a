//! Static friction holds a hull at rest on an incline below its friction
//! angle, once the step resolves the rocking on its corners.
//!
//! A hull rests on three corners, and the body rocks on them faster than it
//! bounces on one (its rotational inertia makes a corner's effective mass
//! smaller than the body's): a step of half the one-contact bound h_crit
//! does not resolve that rocking, and the rattle ratchets the hull down an
//! incline it should stand on. The scene's `rocking_dt` bounds the step
//! that does (docs/dem.md, "Stable time step"); the test runs just below it.

use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

/// One hull (`seed`, `orientation`) dropped onto a plate tilted by `tilt`
/// (rad) about y; grain and plate friction 0.5 (tan⁻¹ 0.5 = 26.6°),
/// rotation on, no damping, the hopper's grain and wall materials.
fn hull_on_incline(dt: f64, seed: u64, orientation: &str, tilt: f64) -> Scene {
    let text = format!(
        r#"
        [simulation]
        dt = {dt}
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{}}
        friction = {{}}
        rotation = {{}}
        [[materials]]
        name = "grain"
        density = 2500.0
        stiffness = 50000.0
        restitution = 0.4
        halo = 6e-4
        friction = 0.5
        [[materials]]
        name = "floor"
        density = 7800.0
        stiffness = 500000.0
        restitution = 0.4
        halo = 6e-4
        friction = 0.5
        [[particles]]
        material = "grain"
        shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = {seed} }}
        placement = {{ kind = "single", position = [0.0, 0.0, 0.008] }}
        orientation = "{orientation}"
        [[obstacles]]
        material = "floor"
        shape = {{ kind = "box", size = [0.2, 0.2, 0.01] }}
        position = [0.0, 0.0, -0.005]
        rotation = [0.0, {tilt}, 0.0]
        "#
    );
    Scene::parse(&text, "incline.toml", Path::new(".")).unwrap()
}

/// At nine tenths of the scene's `rocking_dt`, landed and settled for
/// 0.75 s, each hull then moves less than a millionth of its size in
/// 0.25 s: four shapes, each upright on a 15° incline and turned at random
/// on a 10° one (tan = 0.27, 0.18 < μ = 0.5). The bound is a worst case computed from the shapes and
/// materials, not fitted to this.
#[test]
fn a_hull_on_an_incline_below_its_friction_angle_stays_put() {
    let rocking = hull_on_incline(1e-5, 11, "identity", 0.2618).rocking_dt;
    let dt = 0.9 * rocking.expect("with contacts and rotation, a rocking bound");
    for seed in [11, 4, 7, 23] {
        for (tilt, orientation) in [(0.2618, "identity"), (0.1745, "random")] {
            let mut sim = Simulation::new(&hull_on_incline(dt, seed, orientation, tilt));
            for _ in 0..(0.75 / dt) as usize {
                sim.step();
            }
            let x0 = sim.world.bodies[0].x;
            assert!(x0.z > -0.01, "seed {seed}: the hull landed on the plate");
            for _ in 0..(0.25 / dt) as usize {
                sim.step();
            }
            let moved = (sim.world.bodies[0].x - x0).length();
            assert!(
                moved < 1e-8,
                "seed {seed}, {orientation}, tilt {tilt}: moved {moved:e} m at rest"
            );
        }
    }
}
