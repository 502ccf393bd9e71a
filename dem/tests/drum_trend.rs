//! The rotating drum, reduced to what a test can afford: a bed of more
//! frictional grains rolls at a steeper slope. The full validation (five
//! speeds across the rolling regime, 324 grains) is
//! `scripts/validate-drum.sh` (docs/validation.md); this is its drum at
//! half the length with 98 grains, turning at Fr = 5e-2, with the grains'
//! friction at 0.1 and at 0.6.
mod common;

use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

/// The drum's inner radius (m), and its rate (rad/s): Fr = ω²R/g = 5e-2.
const R: f64 = 0.08;
const OMEGA: f64 = 2.4761;
/// The drum turns at full rate from here on (s).
const SPIN: f64 = 0.4;

/// The validation's drum, 26 mm long, with grains of friction `mu`.
fn drum(mu: f64) -> Scene {
    let turn =
        format!("angular_velocity_table = [[0.3, 0.0, 0.0, 0.0], [{SPIN}, 0.0, {OMEGA}, 0.0]]");
    let materials = common::grains_and_walls(3e-4, mu, 0.6);
    let text = format!(
        r#"
        [simulation]
        dt = 5e-5
        end_time = 3.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{ skin = 1e-3 }}
        friction = {{}}
        rotation = {{}}
        wall_motion = {{}}
        {materials}
        [[particles]]
        material = "grain"
        shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = 11 }}
        placement = {{ kind = "lattice", count = [7, 2, 7], spacing = 0.0118, origin = [-0.0354, -0.0059, -0.0354] }}
        orientation = "random"
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "tube", inner_radius = {R}, thickness = 0.005, length = 0.026 }}
        position = [0.0, 0.0, 0.0]
        {turn}
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [0.18, 0.004, 0.18] }}
        position = [0.0, -0.015, 0.0]
        {turn}
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [0.18, 0.004, 0.18] }}
        position = [0.0, 0.015, 0.0]
        {turn}
        "#
    );
    Scene::parse(&text, "drum.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

/// The bed's slope (degrees, positive when lifted where the wall rises, at
/// -x): the direction of its centre of mass from the axis, which for a flat
/// surface is the surface's normal.
fn slope(sim: &Simulation) -> f64 {
    let grains: Vec<_> = sim.world.bodies.iter().filter(|b| !b.is_static()).collect();
    let n = grains.len() as f64;
    let x = grains.iter().map(|b| b.x.x).sum::<f64>() / n;
    let z = grains.iter().map(|b| b.x.z).sum::<f64>() / n;
    (-x).atan2(-z).to_degrees()
}

/// The mean slope while the drum turns from 0.8 to 1.3 rad (once the bed
/// has been lifted), sampled every 5 ms.
fn dynamic_angle(mu: f64) -> f64 {
    let mut sim = Simulation::new(&drum(mu));
    let window = (SPIN + 0.8 / OMEGA, SPIN + 1.3 / OMEGA);
    let mut angles = Vec::new();
    while sim.world.time < window.1 {
        for _ in 0..100 {
            sim.step();
        }
        if sim.world.time >= window.0 {
            angles.push(slope(&sim));
        }
    }
    angles.iter().sum::<f64>() / angles.len() as f64
}

/// Friction is what holds a slope up: grains of μ = 0.6 roll at a steeper
/// angle than grains of μ = 0.1, and both beds are lifted the way the wall
/// turns (by at least 5°), to a slope well below the vertical. Without
/// friction neither bed is lifted at all.
#[test]
fn more_friction_rolls_at_a_steeper_angle() {
    let (smooth, rough) = std::thread::scope(|s| {
        let smooth = s.spawn(|| dynamic_angle(0.1));
        let rough = s.spawn(|| dynamic_angle(0.6));
        (smooth.join().unwrap(), rough.join().unwrap())
    });
    eprintln!("dynamic angles {smooth:.1} (μ = 0.1) and {rough:.1} (μ = 0.6) degrees");
    for a in [smooth, rough] {
        assert!((5.0..75.0).contains(&a), "angle {a:.1} degrees");
    }
    assert!(
        rough > smooth + 3.0,
        "μ = 0.6 rolls at {rough:.1} degrees, μ = 0.1 at {smooth:.1}"
    );
}
