//! Beverloo's law, reduced to what a test can afford: grains pour out of a
//! flat-bottomed silo faster through a wider slot. The full validation (five
//! widths, 2,025 grains, the fitted law) is `scripts/validate-beverloo.sh`
//! (docs/validation.md); this is its scene at a quarter of the grains, on
//! two widths far enough apart that the law predicts about twice the rate.
mod common;

use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;

/// The validation's silo (120 mm across, slot along y), half as deep and with
/// a lower column, its floor split by a slot `width` wide; the gate under the
/// slot slides away at 2 m/s from `open` s on.
fn silo(width: f64, open: f64) -> Scene {
    let half = 0.5 * (0.120 - width);
    let floor_x = 0.5 * width + 0.5 * half;
    // The gate's trailing edge reaches the slot's far side at `open`.
    let gate_x = 0.5 * width + 0.825 - 2.0 * open;
    let materials = common::grains_and_walls(6e-4, 0.3, 0.3);
    let text = format!(
        r#"
        [simulation]
        dt = 5e-5
        end_time = 1.0
        [effects]
        gravity = {{ g = [0.0, 0.0, -9.81] }}
        contact = {{ skin = 1e-3 }}
        friction = {{}}
        rotation = {{}}
        wall_motion = {{}}
        probes = {{ planes = [{{ name = "outlet", point = [0.0, 0.0, -0.05], normal = [0.0, 0.0, -1.0] }}] }}
        {materials}
        [[particles]]
        material = "grain"
        shape = {{ kind = "hull", triangles = 20, radius = 0.005, seed = 11 }}
        placement = {{ kind = "lattice", count = [9, 2, 16], spacing = 0.0118, origin = [-0.0472, -0.0059, 0.0065] }}
        orientation = "random"
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [0.004, 0.034, 0.4] }}
        position = [-0.062, 0.0, 0.2]
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [0.004, 0.034, 0.4] }}
        position = [0.062, 0.0, 0.2]
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [0.128, 0.004, 0.4102] }}
        position = [0.0, -0.015, 0.1949]
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [0.128, 0.004, 0.4102] }}
        position = [0.0, 0.015, 0.1949]
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [{half}, 0.034, 0.01] }}
        position = [-{floor_x}, 0.0, -0.005]
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [{half}, 0.034, 0.01] }}
        position = [{floor_x}, 0.0, -0.005]
        [[obstacles]]
        material = "wall"
        shape = {{ kind = "box", size = [1.65, 0.034, 0.01] }}
        position = [{gate_x}, 0.0, -0.0152]
        velocity = [2.0, 0.0, 0.0]
        "#
    );
    Scene::parse(&text, "silo.toml", Path::new(".")).unwrap_or_else(|e| panic!("{e}"))
}

fn measure(sim: &Simulation, name: &str) -> f64 {
    sim.measure(name)
        .unwrap_or_else(|| panic!("no measure {name}"))
}

/// The discharge rate (kg/s) through a slot `width` wide: the mass that
/// left through the outlet plane over the `WINDOW` s that start 0.01 s after
/// the first grain crossed it (the flow has started, and the bed is still
/// deeper than the slots are wide).
fn discharge_rate(width: f64) -> f64 {
    let mut sim = Simulation::new(&silo(width, 0.25));
    let mut start = None;
    // 0.01 s apart.
    let mut mass = Vec::new();
    while sim.world.time < 0.6 {
        for _ in 0..200 {
            sim.step();
        }
        let m = measure(&sim, "outlet_mass_past");
        mass.push(m);
        if m > 0.0 && start.is_none() {
            start = Some(mass.len() - 1);
        }
        if let Some(s) = start {
            if mass.len() > s + 1 + SAMPLES {
                let (a, b) = (mass[s + 1], mass[s + 1 + SAMPLES]);
                return (b - a) / WINDOW;
            }
        }
    }
    panic!("no steady flow through a slot {width} m wide: {mass:?}");
}

/// The window over which a rate is measured, and its samples.
const WINDOW: f64 = 0.05;
const SAMPLES: usize = 5;

/// Beverloo's slot law, W ∝ (D − k d)^(3/2) with k ≈ 1.2-3 for grains of
/// diameter d = 7.1 mm, predicts 2.3-8 times the rate through 51 mm as
/// through 30 mm (the fit of docs/validation.md on the full scenes: about 3).
#[test]
fn a_wider_slot_discharges_faster() {
    let narrow = discharge_rate(0.030);
    let wide = discharge_rate(0.051);
    assert!(narrow > 0.0, "no flow through 30 mm");
    let ratio = wide / narrow;
    eprintln!("rates {narrow:.4} and {wide:.4} kg/s through 30 and 51 mm: {ratio:.2} times");
    assert!(
        (1.5..=10.0).contains(&ratio),
        "rates {narrow:.4} and {wide:.4} kg/s through 30 and 51 mm: {ratio:.2} times"
    );
}
