//! `tridem run` as users call it: output that ParaView can open, a summary,
//! and clear errors for bad scenes.
mod common;

use common::{scene, tridem};
use std::process::Command;

#[test]
fn run_writes_hdf5_and_xdmf_for_every_output_step() {
    let dir = std::env::temp_dir().join(format!("tridem-run-{}", std::process::id()));
    let (code, out, err) = tridem(&[
        "run",
        &scene("drop.toml"),
        "--steps",
        "400",
        "--output",
        dir.to_str().unwrap(),
        "--json",
        "--quiet",
    ]);
    assert_eq!(code, 0, "{err}");
    let summary: serde_json::Value = serde_json::from_str(out.trim()).unwrap();
    assert_eq!(summary["steps"], 400);
    assert_eq!(summary["particles"], 18);
    assert!(summary["seconds_per_particle_step"].as_f64().unwrap() > 0.0);
    assert_eq!(summary["deep_contacts"], 0);

    let f = hdf5::File::open(dir.join("run.h5")).unwrap();
    let steps = f.group("steps").unwrap();
    // output_every = 200: steps 0, 200, 400.
    assert_eq!(steps.member_names().unwrap().len(), 3);
    let last = steps.group("2").unwrap();
    let pos: ndarray::Array2<f64> = last.dataset("positions").unwrap().read_2d().unwrap();
    assert_eq!(pos.shape(), &[19, 3]);
    let t: f64 = last.attr("time").unwrap().read_scalar().unwrap();
    assert!((t - 400.0 * 5e-5).abs() < 1e-12);
    let q: ndarray::Array2<f64> = last.dataset("orientations").unwrap().read_2d().unwrap();
    for row in q.rows() {
        let n: f64 = row.iter().map(|x| x * x).sum();
        assert!((n - 1.0).abs() < 1e-12);
    }
    let pts: ndarray::Array2<f64> = last
        .group("surface")
        .unwrap()
        .dataset("points")
        .unwrap()
        .read_2d()
        .unwrap();
    // One point per mesh vertex: 18 hulls of 20 triangles (12 vertices)
    // and a box (8 vertices); the connectivity once, for every step.
    assert_eq!(pts.shape(), &[18 * 12 + 8, 3]);
    let triangles: ndarray::Array2<u32> =
        f.dataset("surface/triangles").unwrap().read_2d().unwrap();
    assert_eq!(triangles.shape(), &[18 * 20 + 12, 3]);
    assert!(triangles.iter().all(|&v| (v as usize) < pts.nrows()));
    // The energy books: kinetic energy, gravity's potential, the springs and
    // what the dashpots and friction dissipated.
    let energy = last.group("energy").unwrap();
    let read = |name: &str| -> f64 { energy.attr(name).unwrap().read_scalar().unwrap() };
    assert!(read("kinetic_translation") > 0.0);
    for name in [
        "gravity_stored",
        "contact_stored",
        "contact_dissipated",
        "friction_dissipated",
    ] {
        assert!(read(name).is_finite(), "{name}");
    }
    // Contact forces: one point, force and body pair per contact (none yet:
    // the particles are still falling; an empty step must be readable too).
    let contacts = last.group("contact_forces").unwrap();
    let forces: ndarray::Array2<f64> = contacts.dataset("forces").unwrap().read_2d().unwrap();
    let bodies: ndarray::Array2<u32> = contacts.dataset("bodies").unwrap().read_2d().unwrap();
    assert_eq!(forces.ncols(), 3);
    assert_eq!(bodies.nrows(), forces.nrows());
    let xmf = std::fs::read_to_string(dir.join("run.xmf")).unwrap();
    assert_eq!(xmf.matches("<Grid Name=\"surface").count(), 1 + 3);
    assert!(xmf.contains("run.h5:/steps/2/surface/points"));
    assert!(xmf.contains("run.h5:/steps/2/contact_forces/forces"));
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn a_bad_scene_is_an_error_with_file_and_line() {
    let dir = std::env::temp_dir().join(format!("tridem-bad-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let text = std::fs::read_to_string(scene("drop.toml"))
        .unwrap()
        .replace("rotation = {}", "rotation = {}\nlevitation = {}");
    let line = text
        .lines()
        .position(|l| l.starts_with("levitation"))
        .unwrap()
        + 1;
    let p = dir.join("bad.toml");
    std::fs::write(&p, &text).unwrap();
    let (code, _, err) = tridem(&["run", p.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(
        err.contains(&format!("bad.toml:{line}:")) && err.contains("levitation"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
    let missing = dir.join("missing.toml");
    let (code, _, err) = tridem(&["run", missing.to_str().unwrap()]);
    assert_eq!(code, 2);
    assert!(
        err.contains(&format!("{}: cannot read the scene", missing.display())),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(dir);
}

#[test]
fn set_overrides_scene_values_and_refuses_bad_ones() {
    let drop = scene("drop.toml");
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--steps",
        "1",
        "--quiet",
        "--set",
        "simulation.dt=2.5e-5",
    ]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("dt 2.5e-5 s"), "{err}");
    // The overridden value is checked like the file's own.
    for (bad, says) in [
        ("kernel.schedule=sometimes", "sometimes"),
        ("kernel.tolerance=0.5", "kernel.tolerance must be between"),
        ("simulation", "expected section.key=value"),
        ("particles.x=1", "not a section"),
    ] {
        let (code, _, err) = tridem(&["run", &drop, "--steps", "1", "--set", bad]);
        assert_eq!(code, 2, "{bad}: {err}");
        assert!(err.contains("--set") && err.contains(says), "{bad}: {err}");
    }
}

#[test]
fn shipped_scenes_parse() {
    let dir = std::path::PathBuf::from(scene(""));
    let mut names: Vec<_> = [dir.clone(), dir.join("validation")]
        .iter()
        .flat_map(|d| std::fs::read_dir(d).expect("scenes/ and scenes/validation/ exist"))
        .map(|e| e.expect("readable entry").path())
        .filter(|p| p.extension().is_some_and(|x| x == "toml"))
        .collect();
    names.sort();
    assert!(names.len() >= 9, "{names:?}");
    for p in names {
        dem::scene::Scene::load(&p).unwrap_or_else(|e| panic!("{e}"));
    }
}

#[test]
fn scaling_compares_thread_counts_and_their_results() {
    // `tridem scaling` on the hopper with `extra` arguments: its JSON rows.
    let scaling_rows = |extra: &[&str]| -> Vec<serde_json::Value> {
        let hopper = scene("hopper.toml");
        let mut args = vec!["scaling", &hopper, "--repeat", "2", "--json"];
        args.extend_from_slice(extra);
        let (code, out, err) = tridem(&args);
        assert_eq!(code, 0, "{err}");
        out.lines()
            .map(|l| serde_json::from_str(l).unwrap())
            .collect()
    };
    let rows = scaling_rows(&["--steps", "300", "--threads", "1,2"]);
    assert_eq!(rows.len(), 2, "{rows:?}");
    assert_eq!(rows[0]["threads"], 1);
    assert_eq!(rows[1]["threads"], 2);
    // The reference's speed-up is 1 by definition; each row lists its runs.
    assert_eq!(rows[0]["speedup"], 1.0);
    for r in &rows {
        assert_eq!(r["seconds"].as_array().unwrap().len(), 2);
        let (m, s) = (
            r["median_seconds"].as_f64().unwrap(),
            r["speedup"].as_f64().unwrap(),
        );
        assert!(m > 0.0 && s > 0.0, "{r}");
        // The hopper falls back per failed pair: results do not depend on threads.
        assert_eq!(r["identical_results"], true, "{r}");
        // Tasks run within the phase, one at a time per thread: the
        // threads' time in it splits into busy and idle, neither negative.
        let (busy, idle) = (
            r["narrow_phase_busy_thread_seconds"].as_f64().unwrap(),
            r["narrow_phase_idle_thread_seconds"].as_f64().unwrap(),
        );
        assert!(busy > 0.0 && idle >= 0.0, "{r}");
    }
    // With --statistic min the speed-up is the ratio of the fastest runs.
    let rows = scaling_rows(&["--steps", "100", "--statistic", "min"]);
    let min = |r: &serde_json::Value| r["min_seconds"].as_f64().unwrap();
    for r in &rows {
        assert_eq!(r["statistic"], "min");
        let runs: Vec<f64> = r["seconds"]
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(min(r), runs.iter().copied().fold(f64::INFINITY, f64::min));
        assert!(min(r) <= r["median_seconds"].as_f64().unwrap(), "{r}");
    }
    // serde_json's default float parsing may be off by an ulp: compare to
    // rounding, not bit for bit.
    let (speedup, expected) = (
        rows[1]["speedup"].as_f64().unwrap(),
        min(&rows[0]) / min(&rows[1]),
    );
    assert!(
        (speedup - expected).abs() <= 1e-12 * expected,
        "{speedup} vs {expected}"
    );
    // The reference workload: its speed-up is the ratio of its own times, and
    // the scene's relative speed-up divides the two (default on).
    let f = |r: &serde_json::Value, key: &str| r[key].as_f64().unwrap();
    let close = |a: f64, b: f64| (a - b).abs() <= 1e-12 * b.abs();
    for r in &rows {
        // 200,000 calls asked for, in whole passes over 4,096 pairs.
        assert_eq!(r["reference_pairs_per_thread"], 49 * 4096, "{r}");
        let reference =
            f(&rows[0], "reference_seconds_per_pair") / f(r, "reference_seconds_per_pair");
        assert!(close(f(r, "reference_speedup"), reference), "{r}");
        assert!(
            close(
                f(r, "speedup_relative_to_reference"),
                f(r, "speedup") / reference
            ),
            "{r}"
        );
    }
    assert_eq!(rows[0]["reference_speedup"], 1.0);
    let rows = scaling_rows(&["--steps", "20", "--threads", "1", "--reference-pairs", "0"]);
    assert!(
        rows[0]["reference_seconds_per_pair"].is_null(),
        "{:?}",
        rows[0]
    );
    assert!(rows[0]["speedup_relative_to_reference"].is_null());
    let (code, _, err) = tridem(&["scaling", &scene("hopper.toml"), "--threads", "0"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--threads") && !err.contains("panicked"),
        "{err}"
    );
    let (code, out, err) = tridem(&["scaling", &scene("hopper.toml"), "--steps", "0"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("no steps to time") && out.is_empty(), "{err}");
}

/// Every output step's positions and orientations in `dir/run.h5`, by time.
fn output_steps(dir: &std::path::Path) -> Vec<(f64, Vec<u64>)> {
    let f = hdf5::File::open(dir.join("run.h5")).unwrap();
    let steps = f.group("steps").unwrap();
    let mut v: Vec<(f64, Vec<u64>)> = (0..steps.member_names().unwrap().len())
        .map(|k| {
            let g = steps.group(&k.to_string()).unwrap();
            let t: f64 = g.attr("time").unwrap().read_scalar().unwrap();
            let bits = ["positions", "orientations", "velocities"]
                .iter()
                .flat_map(|d| {
                    let a: ndarray::Array2<f64> = g.dataset(d).unwrap().read_2d().unwrap();
                    a.iter().map(|x| x.to_bits()).collect::<Vec<_>>()
                })
                .collect();
            (t, bits)
        })
        .collect();
    v.sort_by(|a, b| a.0.total_cmp(&b.0));
    v
}

#[test]
fn a_run_resumed_from_its_checkpoint_goes_on_in_the_same_file_bit_for_bit() {
    let base = std::env::temp_dir().join(format!("tridem-resume-{}", std::process::id()));
    let (whole, parts) = (base.join("whole"), base.join("parts"));
    let drop = scene("drop.toml");
    let run = |dir: &std::path::Path, extra: &[&str]| {
        let mut args = vec!["run", &drop, "--quiet", "--output", dir.to_str().unwrap()];
        args.extend_from_slice(extra);
        let (code, out, err) = tridem(&args);
        assert_eq!(code, 0, "{err}");
        out
    };
    // The grains reach the floor at about step 1,200 (output_every = 200).
    run(&whole, &["--steps", "2300"]);
    // Stopped between output steps: the run's end is checkpointed too.
    run(&parts, &["--steps", "1300"]);
    let checkpoint = parts.join("checkpoint.h5");
    let c = checkpoint.to_str().unwrap();
    let springs = hdf5::File::open(&checkpoint)
        .and_then(|f| f.dataset("effects/friction/history"))
        .unwrap()
        .size()
        / 8;
    assert!(springs >= 1, "friction springs cross the stop: {springs}");
    run(&parts, &["--resume", c, "--steps", "600"]);
    run(&parts, &["--resume", c, "--steps", "400"]);
    let (a, b) = (output_steps(&whole), output_steps(&parts));
    // Steps 0, 200, ..., 2200 of both, and the parts' stops at steps 1,300
    // and 1,900, where each resumed run starts.
    assert_eq!(a.len(), 12);
    assert_eq!(b.len(), 14);
    let stops = [1300.0, 1900.0].map(|s| s * 5e-5);
    let (stops_found, b): (Vec<_>, Vec<_>) = b
        .into_iter()
        .partition(|s| stops.iter().any(|t| (s.0 - t).abs() < 1e-9));
    assert_eq!(stops_found.len(), 2);
    for (x, y) in a.iter().zip(&b) {
        assert_eq!(x.0.to_bits(), y.0.to_bits());
        assert!(x.1 == y.1, "t = {}: the resumed run departs", x.0);
    }
    // The last checkpoint is of step 2,300, both ways.
    assert_eq!(checkpoint_of(&whole), checkpoint_of(&parts));
    assert_eq!(checkpoint_of(&whole).0, 2300);
    let _ = std::fs::remove_dir_all(base);
}

#[test]
fn a_checkpoint_that_does_not_fit_is_an_error_and_nothing_is_lost() {
    let base = std::env::temp_dir().join(format!("tridem-resume-bad-{}", std::process::id()));
    let dir = base.join("drop");
    let d = dir.to_str().unwrap();
    let drop = scene("drop.toml");
    let (code, _, err) = tridem(&["run", &drop, "--quiet", "--steps", "400", "--output", d]);
    assert_eq!(code, 0, "{err}");
    let checkpoint = dir.join("checkpoint.h5");
    let c = checkpoint.to_str().unwrap();
    let before = std::fs::read(dir.join("run.h5")).unwrap();

    let hopper = scene("hopper.toml");
    let scratch = base.join("scratch");
    let o = scratch.to_str().unwrap();
    let (code, _, err) = tridem(&["run", &hopper, "--resume", c, "--steps", "1", "--output", o]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains(c) && err.contains("another scene") && !err.contains("panicked"),
        "{err}"
    );
    let missing = base.join("none.h5");
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--resume",
        missing.to_str().unwrap(),
        "--output",
        o,
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("none.h5: no such checkpoint file"), "{err}");
    let not_h5 = base.join("scene-as-checkpoint.h5");
    std::fs::copy(&drop, &not_h5).unwrap();
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--resume",
        not_h5.to_str().unwrap(),
        "--output",
        o,
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("not an HDF5 file"), "{err}");
    // Refused before anything was written.
    assert!(!scratch.exists());

    // An older checkpoint resumed into the output of a run that went past
    // it would interleave two histories: refused, and the file untouched.
    let old = base.join("step-400.h5");
    std::fs::copy(&checkpoint, &old).unwrap();
    let (code, _, err) = tridem(&[
        "run", &drop, "--quiet", "--resume", c, "--steps", "200", "--output", d,
    ]);
    assert_eq!(code, 0, "{err}");
    let after = std::fs::read(dir.join("run.h5")).unwrap();
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--resume",
        old.to_str().unwrap(),
        "--steps",
        "200",
        "--output",
        d,
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("after the checkpoint"), "{err}");
    assert_eq!(std::fs::read(dir.join("run.h5")).unwrap(), after);
    assert_ne!(before, after);
    // Nothing left to run: the checkpoint is at the scene's end.
    let mut end = std::fs::read_to_string(&drop).unwrap();
    end = end.replace("end_time = 0.4", "end_time = 0.03");
    let short = base.join("short.toml");
    std::fs::write(&short, end).unwrap();
    let (code, _, err) = tridem(&["run", short.to_str().unwrap(), "--resume", c, "--output", o]);
    assert_eq!(code, 3, "{err}");
    assert!(err.contains("nothing left to run"), "{err}");
    // A fresh run into the directory would replace it: only when asked to.
    let (code, _, err) = tridem(&["run", &drop, "--quiet", "--steps", "10", "--output", d]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("--overwrite") && err.contains("--resume"),
        "{err}"
    );
    assert_eq!(std::fs::read(dir.join("run.h5")).unwrap(), after);
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--quiet",
        "--steps",
        "10",
        "--output",
        d,
        "--overwrite",
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(output_steps(&dir).len(), 1);
    let _ = std::fs::remove_dir_all(base);
}

/// The step and every body's angular momentum (as bits) of `dir/checkpoint.h5`.
fn checkpoint_of(dir: &std::path::Path) -> (u64, Vec<u64>) {
    let f = hdf5::File::open(dir.join("checkpoint.h5")).unwrap();
    let step: u64 = f.attr("step").unwrap().read_scalar().unwrap();
    let l: ndarray::Array2<f64> = f.dataset("angular_momenta").unwrap().read_2d().unwrap();
    (step, l.iter().map(|x| x.to_bits()).collect())
}

#[test]
fn a_run_stopped_by_sigterm_checkpoints_the_step_it_reached() {
    let base = std::env::temp_dir().join(format!("tridem-sigterm-{}", std::process::id()));
    let (stopped, whole) = (base.join("stopped"), base.join("whole"));
    let drop = scene("drop.toml");
    let mut child = Command::new(env!("CARGO_BIN_EXE_tridem"))
        .args(["run", &drop, "--quiet", "--steps", "100000000", "--output"])
        .arg(&stopped)
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // The first output step's checkpoint shows the run is under way (the
    // bound only keeps a broken build from hanging the suite).
    let first = stopped.join("checkpoint.h5");
    for _ in 0..6000 {
        if first.exists() || child.try_wait().unwrap().is_some() {
            break;
        }
        std::thread::sleep(std::time::Duration::from_millis(10));
    }
    assert!(first.exists(), "no checkpoint written");
    let kill = Command::new("kill")
        .args(["-TERM", &child.id().to_string()])
        .status()
        .unwrap();
    assert!(kill.success());
    let out = child.wait_with_output().unwrap();
    let err = String::from_utf8_lossy(&out.stderr);
    assert_eq!(out.status.code(), Some(1), "{err}");
    assert!(
        err.contains("stopped by a signal")
            && err.contains("--resume")
            && !err.contains("panicked"),
        "{err}"
    );
    let (step, _) = checkpoint_of(&stopped);
    assert!(step > 0 && step < 100_000_000, "{step}");
    // The checkpoint is of the step the run reached, not of the last output
    // step: going on from it gives the uninterrupted run's state.
    let c = first.to_str().unwrap();
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--quiet",
        "--resume",
        c,
        "--steps",
        "150",
        "--output",
        stopped.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    let total = (step + 150).to_string();
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--quiet",
        "--steps",
        &total,
        "--output",
        whole.to_str().unwrap(),
    ]);
    assert_eq!(code, 0, "{err}");
    assert_eq!(checkpoint_of(&stopped), checkpoint_of(&whole));
    let _ = std::fs::remove_dir_all(base);
}

fn positions_of_every_step(run_h5: &std::path::Path) -> Vec<Vec<u64>> {
    let f = hdf5::File::open(run_h5).unwrap();
    let steps = f.group("steps").unwrap();
    (0..steps.member_names().unwrap().len())
        .map(|k| {
            let g = steps.group(&k.to_string()).unwrap();
            let p: ndarray::Array2<f64> = g.dataset("positions").unwrap().read_2d().unwrap();
            p.iter().map(|x| x.to_bits()).collect()
        })
        .collect()
}

#[test]
fn a_second_run_into_a_directory_in_use_is_refused_and_changes_nothing() {
    let dir = std::env::temp_dir().join(format!("tridem-lock-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().unwrap();
    let silo = scene("silo-1000.toml");
    let mut first = Command::new(env!("CARGO_BIN_EXE_tridem"))
        .args(["run", &silo, "--steps", "3000", "--quiet", "--output", d])
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::null())
        .spawn()
        .unwrap();
    let start = std::time::Instant::now();
    while !dir.join("run.xmf").exists() {
        assert!(
            start.elapsed().as_secs() < 60,
            "the first run did not start"
        );
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    let (code, _, err) = tridem(&["run", &silo, "--steps", "10", "--output", d, "--overwrite"]);
    let still_running = first.try_wait().unwrap().is_none();
    assert_eq!(code, 2, "{err}");
    if still_running {
        assert!(err.contains("in use by another tridem run (pid"), "{err}");
    }
    assert!(first.wait().unwrap().success());
    // The first run's output is whole: steps 0 .. 3000 every 1000.
    assert_eq!(positions_of_every_step(&dir.join("run.h5")).len(), 4);
    assert!(!dir.join("tridem.lock").exists());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn overwrite_replaces_the_whole_run_checkpoint_included() {
    let dir = std::env::temp_dir().join(format!("tridem-overwrite-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().unwrap();
    let drop = scene("drop.toml");
    let (code, _, err) = tridem(&["run", &drop, "--steps", "400", "--quiet", "--output", d]);
    assert_eq!(code, 0, "{err}");
    assert!(dir.join("checkpoint.h5").exists());
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--steps",
        "0",
        "--quiet",
        "--output",
        d,
        "--overwrite",
    ]);
    assert_eq!(code, 0, "{err}");
    // No step was run: the checkpoint it announces is this run's start,
    // none of the old run's.
    assert_eq!(checkpoint_of(&dir).0, 0);
    assert_eq!(positions_of_every_step(&dir.join("run.h5")).len(), 1);
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_killed_between_output_and_checkpoint_resumes_to_the_bit() {
    let base = std::env::temp_dir().join(format!("tridem-window-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&base);
    let (straight, killed) = (base.join("straight"), base.join("killed"));
    let drop = scene("drop.toml");
    let run = |dir: &std::path::Path, steps: &str, resume: bool| {
        let d = dir.to_str().unwrap().to_string();
        let c = dir.join("checkpoint.h5").to_str().unwrap().to_string();
        let mut args = vec!["run", &drop, "--steps", steps, "--quiet", "--output", &d];
        if resume {
            args.extend(["--resume", &c]);
        }
        let (code, _, err) = tridem(&args);
        assert_eq!(code, 0, "{err}");
    };
    run(&straight, "400", false);
    // The state a kill leaves after output step 400 and before its
    // checkpoint: the output at step 400, the checkpoint at step 200.
    run(&killed, "200", false);
    let at_200 = std::fs::read(killed.join("checkpoint.h5")).unwrap();
    run(&killed, "200", true);
    std::fs::write(killed.join("checkpoint.h5"), at_200).unwrap();
    run(&killed, "200", true);
    assert_eq!(
        positions_of_every_step(&straight.join("run.h5")),
        positions_of_every_step(&killed.join("run.h5"))
    );
    assert_eq!(
        std::fs::read(straight.join("checkpoint.h5")).unwrap(),
        std::fs::read(killed.join("checkpoint.h5")).unwrap()
    );
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn a_damaged_checkpoint_is_refused() {
    let dir = std::env::temp_dir().join(format!("tridem-damaged-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let d = dir.to_str().unwrap();
    let drop = scene("drop.toml");
    let (code, _, err) = tridem(&["run", &drop, "--steps", "200", "--quiet", "--output", d]);
    assert_eq!(code, 0, "{err}");
    let good = std::fs::read(dir.join("checkpoint.h5")).unwrap();
    // A bit flipped in the positions (the first dataset of doubles holding
    // a body's x = the lattice's first x, found by its bytes).
    let f = hdf5::File::open(dir.join("checkpoint.h5")).unwrap();
    let x: ndarray::Array2<f64> = f.dataset("positions").unwrap().read_2d().unwrap();
    drop_file(f);
    let needle = x[[0, 0]].to_le_bytes();
    let at = good
        .windows(8)
        .position(|w| w == needle)
        .expect("the position's bytes in the file");
    let mut bad = good.clone();
    bad[at] ^= 1;
    let damaged = dir.join("damaged.h5");
    std::fs::write(&damaged, &bad).unwrap();
    let (code, _, err) = tridem(&[
        "run",
        &drop,
        "--resume",
        damaged.to_str().unwrap(),
        "--steps",
        "1",
    ]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("damaged") && err.contains("damaged.h5"),
        "{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

fn drop_file(f: hdf5::File) {
    f.close().unwrap();
}
