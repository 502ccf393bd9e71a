//! Bad input at every door gets a clear refusal naming the file, line and
//! cause, with exit status 2 and nothing written; impossible set-ups are
//! refused or warned of; a run killed at any instant resumes to the bit.
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};

mod common;

use common::tridem;

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tridem-bad-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// A scene of one steel floor, glass particles as `particles` says, and the
/// simulation section `simulation`.
fn scene(dir: &Path, name: &str, simulation: &str, particles: &str) -> String {
    let text = format!(
        "[simulation]\n{simulation}\n\n[effects]\ngravity = {{ g = [0.0, 0.0, -9.81] }}\n\
         contact = {{}}\nrotation = {{}}\n\n\
         [[materials]]\nname = \"glass\"\ndensity = 2500.0\nstiffness = 50000.0\n\
         restitution = 0.5\nhalo = 2.5e-4\n\n\
         [[materials]]\nname = \"steel\"\ndensity = 7800.0\nstiffness = 500000.0\n\
         restitution = 0.5\nhalo = 2.5e-4\n\n\
         [[obstacles]]\nmaterial = \"steel\"\nshape = {{ kind = \"box\", size = [0.2, 0.2, 0.01] }}\n\
         position = [0.0, 0.0, -0.005]\n\n{particles}\n"
    );
    let path = dir.join(format!("{name}.toml"));
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

const SIM: &str = "dt = 5e-5\nend_time = 0.05\noutput_every = 200";

fn particle(extra: &str) -> String {
    format!(
        "[[particles]]\nmaterial = \"glass\"\n\
         shape = {{ kind = \"hull\", triangles = 20, radius = 0.005, seed = 7 }}\n\
         placement = {{ kind = \"single\", position = [0.0, 0.0, 0.02] }}\n{extra}"
    )
}

/// The line of `text` in the file at `path` (1-based).
fn line_of(path: &str, text: &str) -> usize {
    let body = std::fs::read_to_string(path).unwrap();
    body.lines().position(|l| l.contains(text)).unwrap() + 1
}

#[test]
fn impossible_or_non_finite_scenes_are_refused_naming_the_line_and_writing_nothing() {
    let dir = temp("scenes");
    // (name, simulation, particles, text on the line named, cause)
    let cases: Vec<(&str, &str, String, &str, &str)> = vec![
        ("nan-velocity", SIM, particle("velocity = [0.0, nan, 0.0]"), "velocity", "finite"),
        ("inf-rotation", SIM, particle("rotation = [inf, 0.0, 0.0]"), "rotation = [inf", "finite"),
        ("nan-material", SIM, particle(""), "density = nan", "finite"),
        (
            "huge-spin",
            SIM,
            particle("angular_velocity = [1e308, 0.0, 0.0]"),
            "[[particles]]",
            "kinetic energy",
        ),
        (
            "huge-speed",
            SIM,
            particle("velocity = [0.0, 0.0, -1e300]"),
            "[[particles]]",
            "kinetic energy",
        ),
        ("short", "dt = 5e-5\nend_time = 1e-6", particle(""), "[simulation]", "shorter than one step"),
        ("endless", "dt = 5e-5\nend_time = 1e300", particle(""), "[simulation]", "a run may take"),
        (
            "too-many",
            SIM,
            "[[particles]]\nmaterial = \"glass\"\n\
             shape = { kind = \"hull\", triangles = 20, radius = 0.005 }\n\
             placement = { kind = \"lattice\", count = [1000, 1000, 1000], spacing = 0.02, origin = [0.0, 0.0, 0.02] }\n"
                .into(),
            "[[particles]]",
            "GB",
        ),
        (
            "huge-hull",
            SIM,
            "[[particles]]\nmaterial = \"glass\"\n\
             shape = { kind = \"hull\", triangles = 1000000000, radius = 0.005 }\n\
             placement = { kind = \"single\", position = [0.0, 0.0, 0.02] }\n"
                .into(),
            "[[particles]]",
            "GB",
        ),
        (
            "unknown-partitioner",
            SIM,
            particle("") + "\n[parallel]\npartitioner = \"zoltan-hfsc\"\n",
            "[parallel]",
            "zoltan-hsfc",
        ),
        (
            "unknown-weights",
            SIM,
            particle("") + "\n[parallel]\nweights = \"pair\"\n",
            "[parallel]",
            "triangles, pairs, time",
        ),
    ];
    for (name, sim, particles, on, cause) in cases {
        let mut text = particles.clone();
        if name == "nan-material" {
            text.push_str("\n[[materials]]\nname = \"odd\"\ndensity = nan\n");
        }
        let path = scene(&dir, name, sim, &text);
        let out = dir.join(format!("{name}-out"));
        let (code, _, err) = tridem(&["run", &path, "--output", out.to_str().unwrap()]);
        assert_eq!(code, 2, "{name}: {err}");
        let line = line_of(&path, on);
        assert!(
            err.contains(&format!("{path}:{line}:")) && err.contains(cause),
            "{name}: expected {path}:{line}: and `{cause}` in: {err}"
        );
        assert!(!err.contains("panicked"), "{name}: {err}");
        assert!(!out.exists(), "{name}: a refused run created its output");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn overlapping_bodies_are_refused_unless_the_scene_allows_them() {
    let dir = temp("overlap");
    let two = format!(
        "{}\n[[particles]]\nmaterial = \"glass\"\n\
         shape = {{ kind = \"hull\", triangles = 20, radius = 0.005, seed = 7 }}\n\
         placement = {{ kind = \"single\", position = [0.004, 0.0, 0.02] }}\n",
        particle("")
    );
    let path = scene(&dir, "two", SIM, &two);
    let (code, _, err) = tridem(&["run", &path, "--steps", "10"]);
    assert_eq!(code, 2, "{err}");
    let first = line_of(&path, "[[particles]]");
    assert!(
        err.contains(&format!("body 0 (line {first})"))
            && err.contains("body 1")
            && err.contains("at the start"),
        "{err}"
    );
    let allowed = scene(
        &dir,
        "allowed",
        &format!("{SIM}\nallow_deep_contacts = true"),
        &two,
    );
    let (code, _, err) = tridem(&["run", &allowed, "--steps", "10", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_halo_thicker_than_the_particle_is_refused_and_a_tunnelling_speed_warned_of() {
    let dir = temp("halo");
    let path = scene(&dir, "halo", SIM, &particle(""));
    let text = std::fs::read_to_string(&path)
        .unwrap()
        .replace("halo = 2.5e-4", "halo = 5e-3");
    std::fs::write(&path, text).unwrap();
    let (code, _, err) = tridem(&["run", &path, "--steps", "1"]);
    assert_eq!(code, 2, "{err}");
    assert!(
        err.contains("halo") && err.contains("smallest extent"),
        "{err}"
    );

    // 500 m/s crosses the 1 cm floor in one step: warned at load, and the
    // particle that went through is named at the end.
    let fast = scene(
        &dir,
        "fast",
        SIM,
        &particle("velocity = [0.0, 0.0, -500.0]"),
    );
    let (code, _, err) = tridem(&["run", &fast, "--steps", "100", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    assert!(err.contains("pass through walls"), "{err}");
    assert!(err.contains("below every obstacle"), "{err}");
    // With an outflow plane far under the floor, a particle below every
    // obstacle is on its way out, as the scene says: no warning.
    let text = std::fs::read_to_string(&fast).unwrap().replace(
        "rotation = {}",
        "rotation = {}\noutflow = { planes = [{ point = [0.0, 0.0, -10.0], normal = [0.0, 0.0, -1.0] }] }",
    );
    let sink = dir.join("sink.toml");
    std::fs::write(&sink, text).unwrap();
    let (code, out, err) = tridem(&["run", sink.to_str().unwrap(), "--steps", "100"]);
    assert_eq!(code, 0, "{err}");
    assert!(
        out.contains("outflow_count") && !err.contains("below every obstacle"),
        "{out}\n{err}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn command_line_counts_follow_one_rule_with_their_bounds() {
    let drop = format!("{}/../scenes/drop.toml", env!("CARGO_MANIFEST_DIR"));
    for args in [
        vec!["run", &drop, "--threads", "0"],
        vec!["run", &drop, "--threads", "100000"],
        vec!["scaling", &drop, "--repeat", "0"],
        vec!["kernels", "--repeat", "0"],
        vec!["kernels", "--grain", "0"],
        vec!["distance", "--finish-rounds", "100"],
        vec!["run", &drop, "--steps", "1e300"],
    ] {
        let (code, _, err) = tridem(&args);
        assert_eq!(code, 2, "{args:?}: {err}");
        assert!(
            err.contains("outside") || err.contains("whole number"),
            "{args:?}: {err}"
        );
    }
    // Sizes the machine cannot hold are refused with the estimate.
    let (code, _, err) = tridem(&["kernels", "--pairs", "1e12"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("GB of memory"), "{err}");
    // Resuming with nowhere to write is refused before anything runs.
    let (code, _, err) = tridem(&["run", &drop, "--resume", "x.h5"]);
    assert_eq!(code, 2, "{err}");
    assert!(err.contains("--output"), "{err}");
}

#[test]
fn distance_holds_over_the_whole_range_of_f64() {
    // Two parallel unit triangles one apart, scaled by s: distance s, the
    // closest points scaled too (powers of ten are not exact in binary:
    // compared to a few ulps).
    for s in [1e-300, 1e-200, 1e-6, 1.0, 1e6, 1e200, 1e300] {
        let a = [0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0, 0.0];
        let b = [0.0, 0.0, 1.0, 1.0, 0.0, 1.0, 0.0, 1.0, 1.0];
        let row: Vec<String> = a.iter().chain(&b).map(|x| format!("{:e}", x * s)).collect();
        let mut child = Command::new(env!("CARGO_BIN_EXE_tridem"))
            .arg("distance")
            .stdin(Stdio::piped())
            .stdout(Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        writeln!(child.stdin.take().unwrap(), "{}", row.join(",")).unwrap();
        let out = child.wait_with_output().unwrap();
        assert!(out.status.success());
        let text = String::from_utf8_lossy(&out.stdout);
        let d: f64 = text.split(',').next().unwrap().parse().unwrap();
        assert!((d / s - 1.0).abs() < 1e-14, "scale {s}: distance {d}");
    }
}

/// The positions of every output step of a run, as bits.
fn positions(run: &Path) -> Vec<Vec<u64>> {
    let f = hdf5::File::open(run).unwrap();
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
fn a_run_killed_at_any_instant_resumes_to_the_bit() {
    let base = temp("kill9");
    let hopper = format!("{}/../scenes/hopper.toml", env!("CARGO_MANIFEST_DIR"));
    // 2,000 steps, an output step and checkpoint every 100.
    let set = [
        "--set",
        "simulation.end_time=0.1",
        "--set",
        "simulation.output_every=100",
    ];
    let run = |dir: &Path, resume: bool| -> std::process::Child {
        let mut c = Command::new(env!("CARGO_BIN_EXE_tridem"));
        c.args(["run", &hopper, "--quiet", "--threads", "1", "--output"])
            .arg(dir)
            .args(set);
        if resume {
            c.arg("--resume").arg(dir.join("checkpoint.h5"));
        } else {
            c.arg("--overwrite");
        }
        c.stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap()
    };
    let straight = base.join("straight");
    let out = run(&straight, false).wait_with_output().unwrap();
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let expected = positions(&straight.join("run.h5"));
    let final_checkpoint = std::fs::read(straight.join("checkpoint.h5")).unwrap();
    // SIGKILL at spread instants: during start-up, between steps, during
    // output and checkpoints, twice in one run.
    for (k, delays) in [[30u64, 0], [100, 0], [200, 0], [350, 0], [150, 200]]
        .iter()
        .enumerate()
    {
        let dir = base.join(format!("killed-{k}"));
        let (mut resume, mut finished) = (false, false);
        for &ms in delays.iter().filter(|&&ms| ms > 0) {
            let mut child = run(&dir, resume);
            std::thread::sleep(std::time::Duration::from_millis(ms));
            let _ = child.kill();
            // A run that ended before its kill (its status a success, not
            // the signal) has nothing left to resume.
            // Killed after its last checkpoint, it has reached the end too.
            finished = child.wait().unwrap().success()
                || std::fs::read(dir.join("checkpoint.h5")).ok().as_ref()
                    == Some(&final_checkpoint);
            resume = dir.join("checkpoint.h5").exists();
        }
        if !finished {
            let out = run(&dir, resume).wait_with_output().unwrap();
            assert!(
                out.status.success(),
                "kill {k}: {}",
                String::from_utf8_lossy(&out.stderr)
            );
        }
        assert_eq!(positions(&dir.join("run.h5")), expected, "kill {k}");
        assert_eq!(
            std::fs::read(dir.join("checkpoint.h5")).unwrap(),
            final_checkpoint,
            "kill {k}"
        );
    }
    let _ = std::fs::remove_dir_all(&base);
}

#[test]
fn the_pairs_csv_reader_never_panics() {
    // Mutations of a valid file: bytes changed, cut, repeated.
    let valid = "ax,ay,az,bx,by,bz,cx,cy,cz,dx,dy,dz,ex,ey,ez,fx,fy,fz\n\
                 0,0,0,1,0,0,0,1,0,0,0,1,1,0,1,0,1,1\n\
                 0.5,0.5,0,1,0,0,0,1,0,0,0,1e-3,1,0,1,0,1,1\n";
    let mut state = 0x9e3779b97f4a7c15u64;
    let mut next = move |n: usize| {
        state ^= state << 13;
        state ^= state >> 7;
        state ^= state << 17;
        (state % n as u64) as usize
    };
    for _ in 0..150 {
        let mut v = valid.as_bytes().to_vec();
        for _ in 0..1 + next(3) {
            let at = next(v.len());
            match next(3) {
                0 => v[at] = b"0123456789,.-eE\n naNinf\"x"[next(25)],
                1 => {
                    let end = (at + 1 + next(10)).min(v.len());
                    v.drain(at..end);
                }
                _ => {
                    let end = (at + 1 + next(10)).min(v.len());
                    let piece = v[at..end].to_vec();
                    v.splice(at..at, piece);
                }
            }
        }
        let mut child = Command::new(env!("CARGO_BIN_EXE_tridem"))
            .arg("distance")
            .stdin(Stdio::piped())
            .stdout(Stdio::null())
            .stderr(Stdio::piped())
            .spawn()
            .unwrap();
        use std::io::Write;
        let _ = child.stdin.take().unwrap().write_all(&v);
        let out = child.wait_with_output().unwrap();
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            matches!(out.status.code(), Some(0) | Some(2)) && !err.contains("panicked"),
            "{:?} on:\n{}\n{err}",
            out.status,
            String::from_utf8_lossy(&v)
        );
    }
}

fn data(name: &str) -> String {
    format!("{}/tests/data/{name}", env!("CARGO_MANIFEST_DIR"))
}

#[test]
fn a_run_whose_contacts_stay_crossed_stops_unless_the_scene_allows_it() {
    let path = data("crossing-grains.toml");
    let (code, _, err) = tridem(&["run", &path, "--quiet"]);
    assert_eq!(code, 1, "{err}");
    assert!(
        err.contains("body 0") && err.contains("body 1") && err.contains("100 steps in a row"),
        "{err}"
    );
    let allow = "simulation.allow_deep_contacts=true";
    let (code, _, err) = tridem(&["run", &path, "--quiet", "--set", allow]);
    assert_eq!(code, 0, "{err}");
}

#[test]
fn a_body_wholly_inside_another_is_refused_unless_the_scene_allows_it() {
    let dir = temp("enclosed");
    let grain = |radius: f64, z: f64| {
        format!(
            "[[particles]]\nmaterial = \"glass\"\n\
             shape = {{ kind = \"hull\", triangles = 20, radius = {radius}, seed = 7 }}\n\
             placement = {{ kind = \"single\", position = [0.03, -0.02, {z}] }}\n\n"
        )
    };
    // In the floor (0.01 thick, the grain 0.006 across), and a small grain
    // in a large one: no surfaces cross, no contact sees either.
    for (name, particles, inner, outer) in [
        ("in-floor", grain(0.003, -0.005), "body 0", "body 1"),
        (
            "in-grain",
            format!("{}{}", grain(0.012, 0.02), grain(0.003, 0.0205)),
            "body 1",
            "body 0",
        ),
    ] {
        let path = scene(&dir, name, SIM, &particles);
        let (code, _, err) = tridem(&["run", &path, "--steps", "10"]);
        assert_eq!(code, 2, "{name}: {err}");
        assert!(
            err.contains(&format!("{inner} (line"))
                && err.contains(&format!("wholly inside {outer}")),
            "{name}: {err}"
        );
        let allow = "simulation.allow_deep_contacts=true";
        let (code, _, err) = tridem(&["run", &path, "--steps", "10", "--quiet", "--set", allow]);
        assert_eq!(code, 0, "{name}: {err}");
    }
    // Side by side, the same grains are accepted.
    let apart = format!("{}{}", grain(0.012, 0.02), grain(0.003, 0.04));
    let path = scene(&dir, "apart", SIM, &apart);
    let (code, _, err) = tridem(&["run", &path, "--steps", "10", "--quiet"]);
    assert_eq!(code, 0, "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}
