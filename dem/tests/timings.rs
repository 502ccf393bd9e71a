//! The time-by-section accounting: every section of the pipeline that runs is
//! counted once, the parts of contact detection within the contact effect,
//! and an effect a scene does not declare has no time. (No assertion is made
//! on how long anything takes.)
use dem::effects::{ContactParams, FrictionParams};
use dem::scene::Scene;
use dem::simulation::Simulation;
use std::path::Path;
use std::time::Instant;

fn drop_scene() -> Scene {
    Scene::load(&Path::new(env!("CARGO_MANIFEST_DIR")).join("../scenes/drop.toml")).unwrap()
}

#[test]
fn sections_cover_the_pipeline_and_add_up_within_the_wall_time() {
    let mut sim = Simulation::new(&drop_scene());
    // Nothing counted before the first step (the initial force evaluation).
    assert_eq!(sim.timings.total(), 0.0);
    let start = Instant::now();
    for _ in 0..300 {
        sim.step();
    }
    let wall = start.elapsed().as_secs_f64();
    let t = &sim.timings;
    let names: Vec<_> = t.effects.iter().map(|e| e.0).collect();
    let declared: Vec<_> = sim
        .effect_names()
        .into_iter()
        .filter(|&n| n != "rotation")
        .collect();
    assert_eq!(names, declared);
    assert!(t.integration > 0.0);
    assert!(
        t.effects.iter().all(|e| e.1 > 0.0 && e.1.is_finite()),
        "{t:?}"
    );
    let contact = t.effects.iter().find(|e| e.0 == "contact").unwrap().1;
    let d = &t.detection;
    assert!(
        d.triangle_update > 0.0 && d.broad_phase > 0.0 && d.narrow_phase > 0.0,
        "{d:?}"
    );
    assert!(
        d.total() <= contact,
        "detection {d:?} outside contact {contact}"
    );
    assert!(t.total() <= wall, "sections {} > wall {wall}", t.total());
    // The tasks run within the phase, one at a time per thread; there are
    // tasks when there are body pairs to examine.
    let threads = rayon::current_num_threads() as f64;
    let pairs = sim.totals.detection.body_pairs;
    assert_eq!(d.narrow_phase_busy > 0.0, pairs > 0, "{pairs} body pairs");
    assert!(
        d.narrow_phase_busy >= 0.0 && d.narrow_phase_busy <= d.narrow_phase * threads,
        "narrow phase busy {} thread-s, {} s wall on {threads} threads",
        d.narrow_phase_busy,
        d.narrow_phase
    );
}

#[test]
fn a_scene_without_contact_spends_nothing_on_detection() {
    let mut scene = drop_scene();
    scene.effects.remove::<ContactParams>();
    scene.effects.remove::<FrictionParams>();
    let mut sim = Simulation::new(&scene);
    for _ in 0..100 {
        sim.step();
    }
    assert!(sim.timings.effects.iter().all(|e| e.0 != "contact"));
    assert_eq!(sim.timings.detection, Default::default());
}
