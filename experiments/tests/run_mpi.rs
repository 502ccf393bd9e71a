//! `mpirun -np P tridem run`: the DEM split across ranks gives what one
//! process gives, to the bit, on any rank count, with any partitioner and
//! any repartitioning; resumes on another rank count; survives empty ranks,
//! bad input and signals with one clear message.
use mpi_harness::{launch_args, launcher, open_mpi_local_env};
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

struct Ran {
    code: i32,
    stdout: String,
    stderr: String,
}

fn tridem() -> &'static str {
    env!("CARGO_BIN_EXE_tridem")
}

fn scene(name: &str) -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR"))
        .join("../scenes")
        .join(name)
}

fn temp(name: &str) -> PathBuf {
    let d = std::env::temp_dir().join(format!("tridem-mpi-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `tridem ARGS` on `ranks` ranks (1: without mpirun), within a time limit.
fn run(ranks: usize, args: &[&str]) -> Ran {
    let mut cmd = if ranks == 1 {
        Command::new(tridem())
    } else {
        let mut c = Command::new(launcher());
        c.args(launch_args(ranks)).arg(tridem());
        c
    };
    cmd.args(args).envs(open_mpi_local_env());
    let out = cmd
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    finish(out, Duration::from_secs(600))
}

/// Runs `scene_file` quietly on `ranks` with `args`, a metrics line every
/// 10 steps into `dir`; the run, once it succeeded, and its metrics lines.
fn run_with_metrics(
    ranks: usize,
    dir: &Path,
    scene_file: &Path,
    args: &[&str],
) -> (Ran, Vec<serde_json::Value>) {
    let metrics = dir.join("m.jsonl");
    let base = [
        "run",
        scene_file.to_str().unwrap(),
        "--quiet",
        "--metrics",
        metrics.to_str().unwrap(),
        "--metrics-every",
        "10",
    ];
    let r = run(ranks, &[&base[..], args].concat());
    assert_eq!(r.code, 0, "{}", r.stderr);
    let lines = std::fs::read_to_string(&metrics)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    (r, lines)
}

/// The ranks stopped with one message between them.
fn assert_one_error(r: &Ran) {
    let messages = r.stderr.matches("tridem: error:").count();
    assert_eq!(messages, 1, "{}", r.stderr);
}

fn finish(mut child: std::process::Child, limit: Duration) -> Ran {
    let start = Instant::now();
    loop {
        if child.try_wait().unwrap().is_some() {
            break;
        }
        if start.elapsed() > limit {
            child.kill().unwrap();
            panic!("no end within {limit:?}: a hang");
        }
        std::thread::sleep(Duration::from_millis(20));
    }
    let out = child.wait_with_output().unwrap();
    Ran {
        code: out.status.code().unwrap_or(-1),
        stdout: String::from_utf8_lossy(&out.stdout).into_owned(),
        stderr: String::from_utf8_lossy(&out.stderr).into_owned(),
    }
}

fn bytes(p: &Path) -> Vec<u8> {
    std::fs::read(p).unwrap_or_else(|e| panic!("{}: {e}", p.display()))
}

/// Runs `scene_file` for `steps` on one process and on each of `splits`
/// (ranks, extra options), each writing output and a checkpoint; every
/// split's run.h5 and checkpoint.h5 must be byte for byte the one-process ones.
fn same_as_one_process(
    name: &str,
    scene_file: &Path,
    steps: &str,
    least_contacts: u64,
    splits: &[(usize, Vec<&str>)],
) -> String {
    let dir = temp(name);
    let one = dir.join("one");
    let base = [
        "run",
        scene_file.to_str().unwrap(),
        "--steps",
        steps,
        "--quiet",
    ];
    let r = run(
        1,
        &[&base[..], &["--output", one.to_str().unwrap()]].concat(),
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let one_out = r.stdout.clone();
    let contacts = r
        .stdout
        .lines()
        .find(|l| l.starts_with("contacts (sum)"))
        .and_then(|l| l.split_whitespace().last())
        .and_then(|n| n.parse::<u64>().ok())
        .unwrap();
    assert!(
        contacts >= least_contacts,
        "{name}: {contacts} contacts, too few to test"
    );
    for (k, (ranks, opts)) in splits.iter().enumerate() {
        let out = dir.join(format!("split{k}"));
        let args = [&base[..], &["--output", out.to_str().unwrap()], &opts[..]].concat();
        let r = run(*ranks, &args);
        let ctx = format!("{name}: {ranks} ranks {opts:?}");
        assert_eq!(r.code, 0, "{ctx}: {}", r.stderr);
        assert!(
            r.stdout
                .contains(&format!("contacts (sum)         {contacts}")),
            "{ctx}: contacts differ\n{}",
            r.stdout
        );
        for file in ["checkpoint.h5", "run.h5", "run.xmf"] {
            assert!(
                bytes(&one.join(file)) == bytes(&out.join(file)),
                "{ctx}: {file} differs from one process's"
            );
        }
        assert_eq!(
            measures(&r.stdout),
            measures(&one_out),
            "{ctx}: the summary's measures differ from one process's"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
    one_out
}

/// The summary's "measures at the end": (name, value) lines.
fn measures(stdout: &str) -> Vec<(String, f64)> {
    stdout
        .lines()
        .skip_while(|l| *l != "measures at the end")
        .skip(1)
        .take_while(|l| l.starts_with("  "))
        .map(|l| {
            let mut w = l.split_whitespace();
            let name = w.next().unwrap().to_string();
            (name, w.next().unwrap().parse().unwrap())
        })
        .collect()
}

/// The measure `name` in a summary, which must show it.
fn measure(stdout: &str, name: &str) -> f64 {
    let m = measures(stdout);
    m.iter()
        .find(|(n, _)| n == name)
        .unwrap_or_else(|| panic!("no measure {name} in {m:?}"))
        .1
}

#[test]
fn the_hopper_on_any_split_is_one_process_to_the_bit() {
    // Each partitioner with each repartitioning (never, every step, every
    // 10), on 2, 3 and 4 ranks in turn; the hybrid kernel recomputing
    // only the uncertified pairs, as the scene says.
    let mut splits = Vec::new();
    let partitioners = partition::Backend::ALL.map(|b| b.name());
    for (i, p) in partitioners.into_iter().enumerate() {
        for (j, every) in ["0", "1", "10"].into_iter().enumerate() {
            let ranks = 2 + (i + j) % 3;
            splits.push((
                ranks,
                vec!["--partitioner", p, "--repartition-every", every],
            ));
        }
    }
    splits.push((2, vec!["--exchange", "blocking"]));
    // Weighed by triangles, by pairs (the default) and by measured time,
    // which differs from run to run: the partition may, the bits may not.
    for (ranks, weights) in [(2, "triangles"), (3, "time"), (4, "pairs")] {
        let opts = vec!["--weights", weights, "--repartition-every", "50"];
        splits.push((ranks, opts));
    }
    // Repartitioned when the measured busy time is imbalanced: when, differs
    // from run to run; the bits may not.
    splits.push((
        3,
        vec!["--repartition-every", "0", "--repartition-when", "1.02"],
    ));
    // Every repartitioning from scratch: other owners, the same bits.
    splits.push((
        4,
        vec![
            "--partitioner",
            "metis",
            "--repartition-every",
            "10",
            "--fresh-partitions",
        ],
    ));
    same_as_one_process("hopper", &scene("hopper.toml"), "3000", 1000, &splits);
}

#[test]
fn the_brute_force_kernel_splits_to_the_bit_too() {
    let dir = temp("brute-scene");
    let text = std::fs::read_to_string(scene("hopper.toml")).unwrap();
    let head = &text[..text.find("[kernel]").unwrap()];
    let file = dir.join("hopper-brute.toml");
    std::fs::write(&file, format!("{head}[kernel]\nmethod = \"brute\"\n")).unwrap();
    let splits = [
        (2, vec!["--repartition-every", "10"]),
        (3, vec!["--partitioner", "rcb"]),
    ];
    same_as_one_process("brute", &file, "3000", 1000, &splits);
}

#[test]
fn a_thousand_particles_split_to_the_bit() {
    let splits = [
        (
            2,
            vec!["--partitioner", "zoltan-rcb", "--repartition-every", "10"],
        ),
        (
            3,
            vec!["--partitioner", "metis", "--repartition-every", "1"],
        ),
        (4, vec!["--partitioner", "zoltan-hsfc"]),
        (4, vec!["--partitioner", "rcb", "--repartition-every", "10"]),
    ];
    same_as_one_process("silo-1000", &scene("silo-1000.toml"), "500", 1000, &splits);
}

/// Moving walls (a paddle spun up by a table, a sliding floor, a shelf removed) on every rank, each
/// placed by the time alone: split, repartitioned and resumed across rank
/// counts, the run is one process's to the bit, its books and probes
/// included.
#[test]
fn moving_walls_split_and_resume_to_the_bit() {
    let mixer = scene("mixer.toml");
    let splits = [
        (2, vec!["--repartition-every", "10"]),
        (3, vec!["--partitioner", "rcb", "--repartition-every", "1"]),
    ];
    same_as_one_process("mixer", &mixer, "2000", 1000, &splits);
    resumed_across_rank_counts("resume-mixer", &mixer, &[(2, 700), (3, 600), (1, 700)]);
}

/// An outflow plane across the hopper's lower part takes out grains that
/// are still touching others, on whichever rank owns them: split,
/// repartitioned and resumed across rank counts, the run is one process's
/// to the bit, the removals, books and counts included.
#[test]
fn an_outflow_splits_and_resumes_to_the_bit() {
    let dir = temp("outflow-scene");
    let text = std::fs::read_to_string(scene("hopper.toml")).unwrap();
    let sink = "outflow = { planes = [{ point = [0.0, 0.0, 0.07], normal = [0.0, 0.0, -1.0] }] }";
    let text = text.replacen("rotation = {}\n", &format!("rotation = {{}}\n{sink}\n"), 1);
    assert!(text.contains(sink));
    let file = dir.join("hopper-outflow.toml");
    std::fs::write(&file, text).unwrap();
    let splits = [(3, vec!["--partitioner", "rcb", "--repartition-every", "1"])];
    // The plane takes out grains the runs below compare, most of them
    // while others touch them.
    let out = dir.join("check");
    let r = run(
        1,
        &[
            "run",
            file.to_str().unwrap(),
            "--steps",
            "2500",
            "--quiet",
            "--output",
            out.to_str().unwrap(),
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let removed = removed_at_last_step(&out.join("run.h5"));
    assert!(
        (20..100).contains(&removed),
        "{removed} grains out by step 2,500"
    );
    let one = same_as_one_process("outflow", &file, "4000", 700, &splits);
    let out = measure(&one, "outflow_count");
    assert!(
        out > removed as f64,
        "{out} out by step 4,000, {removed} by 2,500"
    );
    resumed_across_rank_counts("resume-outflow", &file, &[(2, 2500), (1, 1500)]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Grains poured into the hopper from a box above its fill, 40 at 400 per
/// second, onto grains that are still moving: on 2 and 3 ranks,
/// repartitioned as they go, the candidates, blocked tests and choices
/// are one process's, and so is the run, to the bit; resumed with grains
/// still waiting, across rank counts, too.
#[test]
fn an_insertion_splits_and_resumes_to_the_bit() {
    let dir = temp("insertion-scene");
    let text = std::fs::read_to_string(scene("hopper.toml")).unwrap();
    let text = text.replacen("rotation = {}\n", "rotation = {}\ninsertion = {}\n", 1);
    let pour = r#"
[[particles]]
material = "grain"
shape = { kind = "hull", triangles = 20, radius = 0.005, seed = 11 }
placement = { kind = "insert", count = 40, region = { kind = "box", lo = [-0.02, -0.02, 0.17], hi = [0.02, 0.02, 0.19] }, rate = 400.0, seed = 5 }
orientation = "random"
velocity = [0.0, 0.0, -0.5]

[[obstacles]]"#;
    let text = text.replacen("\n[[obstacles]]", pour, 1);
    assert!(text.contains("insertion = {}") && text.contains("kind = \"insert\""));
    let file = dir.join("hopper-pour.toml");
    std::fs::write(&file, text).unwrap();
    let splits = [
        (2, vec!["--partitioner", "rcb", "--repartition-every", "7"]),
        (3, vec!["--partitioner", "rcb", "--repartition-every", "1"]),
    ];
    let one = same_as_one_process("insertion", &file, "3000", 700, &splits);
    // All 40 are due by step 2,000 and find room in the box.
    assert_eq!(measure(&one, "inserted_count"), 40.0);
    // At step 1,000 (t = 0.05 s) about half the grains still wait.
    resumed_across_rank_counts("resume-insertion", &file, &[(2, 1000), (1, 800), (3, 700)]);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Grains that wait to be inserted touch nothing: before the first enters,
/// none goes to another rank as a ghost, though two streams wait 8 mm apart,
/// one on each rank, closer than a grain's size.
#[test]
fn particles_out_of_the_run_are_never_ghosts() {
    let dir = temp("waiting");
    let text = std::fs::read_to_string(scene("hopper.toml")).unwrap();
    let text = text.replacen("rotation = {}\n", "rotation = {}\ninsertion = {}\n", 1);
    // The hopper's own grains replaced by 2 x 20 that enter from t = 1 s on
    // and wait at their regions' centres, x = -4 mm and 4 mm.
    let start = text.find("[[particles]]").unwrap();
    let end = start + text[start..].find("[[obstacles]]").unwrap();
    let stream = |lo: f64| {
        format!(
            "[[particles]]\nmaterial = \"grain\"\n\
             shape = {{ kind = \"hull\", triangles = 20, radius = 0.005, seed = 11 }}\n\
             placement = {{ kind = \"insert\", count = 20, region = {{ kind = \"box\", \
             lo = [{lo}, -0.01, 0.17], hi = [{}, 0.01, 0.19] }}, rate = 400.0, start = 1.0, \
             seed = 5 }}\n\n",
            lo + 0.02
        )
    };
    let wait = stream(-0.014) + &stream(-0.006);
    let text = format!("{}{wait}{}", &text[..start], &text[end..]);
    let file = dir.join("waiting.toml");
    std::fs::write(&file, text).unwrap();
    let args = [
        "--steps",
        "40",
        "--partitioner",
        "rcb",
        "--repartition-every",
        "10",
    ];
    let (_, lines) = run_with_metrics(2, &dir, &file, &args);
    assert_eq!(lines.len(), 4);
    for l in &lines {
        assert_eq!(l["sum"]["owned_bodies"], 40.0, "{l}");
        let per_rank = l["per_rank"]["owned_bodies"].as_array().unwrap();
        assert!(
            per_rank.iter().all(|n| n.as_f64() > Some(0.0)),
            "both ranks hold some: {l}"
        );
        assert_eq!(l["sum"]["ghosts_sent"], 0.0, "{l}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Five planes of four grains each, falling free: the weighted median lies
/// in the middle plane, so an even split must cut through it. Every
/// geometric partitioner splits the 20 grains 10 / 10, at the start and at
/// every repartitioning, rather than moving a whole plane of exactly equal
/// coordinates to one side (12 / 8): the lattice every placed scene starts
/// from keeps its planes exact while it falls. (METIS is left out: its
/// regions are grid cells, each given whole to one rank.)
#[test]
fn a_lattice_whose_median_plane_holds_several_grains_is_split_evenly() {
    let dir = temp("lattice");
    let file = dir.join("lattice.toml");
    let text = "[simulation]\ndt = 5e-5\nend_time = 0.01\n\n\
        [effects]\ngravity = { g = [0.0, 0.0, -9.81] }\ncontact = {}\nrotation = {}\n\n\
        [[materials]]\nname = \"grain\"\ndensity = 2500.0\nstiffness = 50000.0\n\
        restitution = 0.4\nhalo = 2.5e-4\n\n\
        [[particles]]\nmaterial = \"grain\"\n\
        shape = { kind = \"hull\", triangles = 20, radius = 0.005, seed = 11 }\n\
        placement = { kind = \"lattice\", count = [5, 2, 2], spacing = 0.0125, \
        origin = [0.0, 0.0, 0.0] }\n";
    std::fs::write(&file, text).unwrap();
    for p in partition::Backend::ALL.map(|b| b.name()) {
        if p == "metis" {
            continue;
        }
        let args = [
            "--steps",
            "40",
            "--partitioner",
            p,
            "--repartition-every",
            "10",
            "--overwrite",
        ];
        let (_, lines) = run_with_metrics(2, &dir, &file, &args);
        for l in &lines {
            for n in l["per_rank"]["owned_bodies"].as_array().unwrap() {
                let n = n.as_f64().unwrap();
                assert_eq!(n, 10.0, "{p}: {l}");
            }
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn more_ranks_than_particles_leaves_ranks_empty_and_the_result_unchanged() {
    let splits = [
        (4, vec!["--repartition-every", "5"]),
        (3, vec!["--partitioner", "metis"]),
    ];
    same_as_one_process("two", &scene("two-particles.toml"), "2500", 20, &splits);
}

/// The particles an outflow had taken out at the last output step.
fn removed_at_last_step(run_h5: &Path) -> u64 {
    let f = hdf5::File::open(run_h5).unwrap();
    let steps = f.group("steps").unwrap();
    let last = steps.member_names().unwrap().len() - 1;
    let removed: ndarray::Array1<u8> = steps
        .dataset(&format!("{last}/removed"))
        .unwrap()
        .read_1d()
        .unwrap();
    removed.iter().map(|&r| u64::from(r)).sum()
}

/// Positions, velocities and energies of every output step, as bits.
/// Each output step as bits, the time first.
fn output_steps(run_h5: &Path) -> Vec<Vec<u64>> {
    let f = hdf5::File::open(run_h5).unwrap();
    let steps = f.group("steps").unwrap();
    (0..steps.member_names().unwrap().len())
        .map(|k| {
            let g = steps.group(&k.to_string()).unwrap();
            let time: f64 = g.attr("time").unwrap().read_scalar().unwrap();
            let mut bits = vec![time.to_bits()];
            for d in ["positions", "velocities", "angular_momenta", "orientations"] {
                let a: ndarray::Array2<f64> = g.dataset(d).unwrap().read_2d().unwrap();
                bits.extend(a.iter().map(|x| x.to_bits()));
            }
            for flag in ["removed", "pending"] {
                let a: ndarray::Array1<u8> = g.dataset(flag).unwrap().read_1d().unwrap();
                bits.extend(a.iter().map(|&r| u64::from(r)));
            }
            let e = g.group("energy").unwrap();
            let mut names = e.attr_names().unwrap();
            names.sort();
            for n in names {
                let v: f64 = e.attr(&n).unwrap().read_scalar().unwrap();
                bits.push(v.to_bits());
            }
            bits
        })
        .collect()
}

/// `scene_file` run `parts` in turn into one directory, each part (ranks,
/// steps) resuming the last one's checkpoint, gives the checkpoint and the
/// output steps of one uninterrupted process.
fn resumed_across_rank_counts(name: &str, scene_file: &Path, parts: &[(usize, u64)]) {
    let dir = temp(name);
    let scene_file = scene_file.to_str().unwrap();
    let (one, split) = (dir.join("one"), dir.join("split"));
    let total: u64 = parts.iter().map(|p| p.1).sum();
    let total = total.to_string();
    let one_out = one.to_str().unwrap();
    let r = run(
        1,
        &[
            "run", scene_file, "--steps", &total, "--quiet", "--output", one_out,
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let out = split.to_str().unwrap();
    let checkpoint = split.join("checkpoint.h5");
    let c = checkpoint.to_str().unwrap();
    for (k, &(ranks, steps)) in parts.iter().enumerate() {
        let steps = steps.to_string();
        let mut args = vec![
            "run", scene_file, "--steps", &steps, "--quiet", "--output", out,
        ];
        if k > 0 {
            args.extend(["--resume", c]);
        }
        let r = run(ranks, &args);
        assert_eq!(r.code, 0, "{name}, part {k} on {ranks} ranks: {}", r.stderr);
    }
    assert!(
        bytes(&one.join("checkpoint.h5")) == bytes(&checkpoint),
        "{name}: the checkpoint after {total} steps differs"
    );
    // A resumed run begins with an output step of its start; the others
    // are those of one process.
    let whole = output_steps(&one.join("run.h5"));
    let mut parts_steps = output_steps(&split.join("run.h5"));
    parts_steps.retain(|s| whole.iter().any(|w| w[0] == s[0]));
    assert_eq!(whole, parts_steps, "{name}: the output steps differ");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_run_resumed_on_other_rank_counts_goes_on_to_the_bit() {
    // 1 rank, then 3, then 2: the checkpoints are plain data, not a rank's.
    let hopper = scene("hopper.toml");
    resumed_across_rank_counts("resume-hopper", &hopper, &[(1, 1000), (3, 1000), (2, 1500)]);
    // The silo's grains reach the floor and each other by step 1,000, and
    // its friction history moves with them between ranks.
    let silo = scene("silo-1000.toml");
    resumed_across_rank_counts(
        "resume-silo",
        &silo,
        &[(2, 700), (3, 600), (1, 200), (4, 500)],
    );
}

/// A rank killed outright ends the whole run (no rank left waiting for
/// it), and the last checkpoint goes on, on one process, to the bits of a
/// run never interrupted.
#[test]
fn a_rank_killed_mid_run_ends_the_run_and_its_checkpoint_resumes() {
    let dir = temp("kill");
    let out = dir.join("out");
    let silo = scene("silo-1000.toml");
    let silo = silo.to_str().unwrap();
    let every = "simulation.output_every=50";
    let mut cmd = Command::new(launcher());
    cmd.args(launch_args(2))
        .args([tridem(), "run", silo, "--quiet", "--set", every])
        .args(["--output", out.to_str().unwrap()])
        .envs(open_mpi_local_env())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let child = cmd.spawn().unwrap();
    let checkpoint = out.join("checkpoint.h5");
    let start = Instant::now();
    while !checkpoint.exists() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(20));
    }
    std::thread::sleep(Duration::from_millis(300));
    let pattern = format!("^{} run .*{}", tridem(), out.display());
    let pids = Command::new("pgrep")
        .args(["-f", &pattern])
        .output()
        .unwrap();
    let pid = String::from_utf8_lossy(&pids.stdout)
        .lines()
        .last()
        .expect("the ranks run")
        .to_string();
    assert!(Command::new("kill")
        .args(["-KILL", &pid])
        .status()
        .unwrap()
        .success());
    let r = finish(child, Duration::from_secs(120));
    assert_ne!(r.code, 0, "a run that lost a rank ended well");
    let step = |c: &Path| -> u64 {
        hdf5::File::open(c)
            .and_then(|f| f.attr("step"))
            .and_then(|a| a.read_scalar())
            .unwrap()
    };
    let at = step(&checkpoint);
    assert!(at > 0 && at % 50 == 0, "checkpoint at step {at}");
    // Resumed to step `at` + 100, against one process run there at once.
    let whole = dir.join("whole");
    let to = (at + 100).to_string();
    let set = ["--set", every];
    let w = whole.to_str().unwrap();
    let r = run(
        1,
        &[
            &["run", silo, "--steps", &to, "--quiet", "--output", w][..],
            &set,
        ]
        .concat(),
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let c = checkpoint.to_str().unwrap();
    let o = out.to_str().unwrap();
    let resume = [
        "run", silo, "--steps", "100", "--quiet", "--output", o, "--resume", c,
    ];
    let r = run(1, &[&resume[..], &set].concat());
    assert_eq!(r.code, 0, "{}", r.stderr);
    assert!(bytes(&whole.join("checkpoint.h5")) == bytes(&checkpoint));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A command line that does not parse is reported once, not once per rank.
#[test]
fn a_bad_command_line_is_reported_once() {
    let r = run(3, &["run", "--no-such-option"]);
    assert_eq!(r.code, 2, "{}", r.stderr);
    let messages = r.stderr.matches("error:").count();
    assert_eq!(messages, 1, "{}", r.stderr);
}

/// An output step that cannot be written (here: the file is /dev/full, a
/// full disk) ends every rank with one message naming the file.
#[test]
fn a_full_disk_names_the_file() {
    let dir = temp("full");
    let out = dir.join("out");
    std::fs::create_dir_all(&out).unwrap();
    std::os::unix::fs::symlink("/dev/full", out.join("run.h5")).unwrap();
    let silo = scene("silo-1000.toml");
    let o = out.to_str().unwrap();
    let args = [
        "run",
        silo.to_str().unwrap(),
        "--steps",
        "20",
        "--quiet",
        "--output",
        o,
    ];
    let r = run(2, &[&args[..], &["--overwrite"]].concat());
    assert_ne!(r.code, 0, "{}", r.stderr);
    assert_one_error(&r);
    assert!(r.stderr.contains("run.h5"), "{}", r.stderr);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Metrics lines written in batches come out one per step, in step order,
/// each of one step's ranks: past a batch's end and in the part-filled last.
#[test]
fn metrics_lines_come_one_per_step_in_order_across_batches() {
    let dir = temp("metrics-batches");
    let metrics = dir.join("m.jsonl");
    let hopper = scene("hopper.toml");
    let args = [
        "run",
        hopper.to_str().unwrap(),
        "--quiet",
        "--steps",
        "150",
        "--metrics",
        metrics.to_str().unwrap(),
        "--metrics-every",
        "1",
    ];
    let r = run(2, &args);
    assert_eq!(r.code, 0, "{}", r.stderr);
    let text = std::fs::read_to_string(&metrics).unwrap();
    let lines: Vec<serde_json::Value> = text
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 150);
    for (k, l) in lines.iter().enumerate() {
        assert_eq!(l["step"], k as u64 + 1, "{l}");
        assert_eq!(l["per_rank"]["owned_bodies"].as_array().unwrap().len(), 2);
        // One step's ranks: every body owned once, what is sent received.
        assert_eq!(l["sum"]["owned_bodies"], 100.0, "{l}");
        assert_eq!(l["sum"]["ghosts_sent"], l["sum"]["ghosts_received"], "{l}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn metrics_count_every_rank_and_every_body_once() {
    let dir = temp("metrics");
    let args = ["--steps", "200", "--repartition-every", "50"];
    let (r, lines) = run_with_metrics(3, &dir, &scene("silo-1000.toml"), &args);
    assert_eq!(lines.len(), 20);
    let mut migrated = 0.0;
    let mut drifted = Vec::new();
    for l in &lines {
        assert_eq!(l["ranks"], 3);
        assert_eq!(l["sum"]["owned_bodies"], 1000.0, "{l}");
        assert_eq!(l["sum"]["owned_triangles"], 20000.0, "{l}");
        assert_eq!(l["per_rank"]["owned_bodies"].as_array().unwrap().len(), 3);
        // What is sent is received.
        assert_eq!(l["sum"]["ghosts_sent"], l["sum"]["ghosts_received"], "{l}");
        assert!(l["triangle_imbalance"].as_f64().unwrap() >= 1.0);
        migrated += l["sum"]["migrated_bodies"].as_f64().unwrap();
        drifted.push(l["sum"]["drifted_bodies"].as_f64().unwrap());
        // The slowest rank's busy time, carried by the all-reduce, is the
        // same on every rank and at least each rank's own, step by step.
        let column = |f: &str| -> Vec<f64> {
            let v = l["per_rank"][f].as_array().unwrap();
            v.iter().map(|x| x.as_f64().unwrap()).collect()
        };
        let slowest = column("slowest_busy_seconds");
        assert!(slowest.iter().all(|&s| s == slowest[0]), "{l}");
        assert!(
            column("counted_busy_seconds")
                .iter()
                .all(|&c| c <= slowest[0]),
            "{l}"
        );
        assert!(l["busy_imbalance_per_step"].as_f64().unwrap() >= 1.0, "{l}");
        // So is the largest modelled work, a count.
        let most = column("most_work_ns");
        assert!(most.iter().all(|&m| m == most[0]), "{l}");
        assert!(
            column("counted_work_ns").iter().all(|&c| c <= most[0]),
            "{l}"
        );
        assert!(l["work_imbalance_per_step"].as_f64().unwrap() >= 1.0, "{l}");
    }
    // The busy time and the work carried are each step's, one step late:
    // all of it but the last step's.
    let total = |f: &str, r: usize| -> f64 {
        let at = |l: &serde_json::Value| l["per_rank"][f][r].as_f64().unwrap();
        lines.iter().map(at).sum()
    };
    let last = lines.last().unwrap();
    for r in 0..3 {
        let missing = total("busy_seconds", r) - total("counted_busy_seconds", r);
        let last_ten = last["per_rank"]["busy_seconds"][r].as_f64().unwrap();
        assert!(missing > 0.0 && missing < last_ten, "{missing} {last_ten}");
        let missing = total("modelled_work_ns", r) - total("counted_work_ns", r);
        let last_ten = last["per_rank"]["modelled_work_ns"][r].as_f64().unwrap();
        assert!(missing > 0.0 && missing < last_ten, "{missing} {last_ten}");
    }
    // The first step places the bodies dealt out in turn.
    assert!(migrated > 0.0);
    // The first partition has no regions before it for a body to leave;
    // the repartitionings that follow find falling grains that crossed a
    // cut, never more than the bodies there are.
    assert_eq!(drifted[0], 0.0, "{drifted:?}");
    assert!(drifted[1..].iter().any(|&d| d > 0.0), "{drifted:?}");
    assert!(drifted.iter().all(|&d| d < 1000.0), "{drifted:?}");
    assert!(r.stdout.contains("wait_seconds"), "{}", r.stdout);
    let _ = std::fs::remove_dir_all(&dir);
}

/// The ghost lists, drawn with a wider pad, outlast the neighbour list,
/// which is redrawn alone in between; never the other way round.
#[test]
fn the_neighbour_list_is_redrawn_alone_between_ghost_lists() {
    let dir = temp("two-pads");
    let args = ["--steps", "800", "--repartition-every", "1000"];
    let (_, lines) = run_with_metrics(2, &dir, &scene("silo-1000.toml"), &args);
    for r in 0..2 {
        let drawn = |f: &str, l: &serde_json::Value| l["per_rank"][f][r].as_f64().unwrap();
        for l in &lines {
            assert!(
                drawn("neighbour_lists_drawn", l) >= drawn("lists_drawn", l),
                "{l}"
            );
        }
        let total = |f: &str| -> f64 { lines.iter().map(|l| drawn(f, l)).sum() };
        let (ghost, neighbour) = (total("lists_drawn"), total("neighbour_lists_drawn"));
        assert!(
            ghost >= 1.0 && neighbour > ghost,
            "rank {r}: {ghost} {neighbour}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Grains spinning in place: their triangles sweep past the neighbour
/// list's skin every few steps while their centres hardly move. The ghost
/// lists (spheres about the centres) are drawn for the centres' travel
/// alone: were turning counted, a pad of `GHOST_SKINS` half skins would
/// redraw them at least once per `GHOST_SKINS` neighbour lists; here they
/// outlast twice that many, and the split is one process's run to the bit.
#[test]
fn turning_alone_does_not_redraw_the_ghost_lists() {
    let file = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/spinning-grains.toml");
    let splits = [
        (2, vec!["--threads", "1"]),
        (3, vec!["--partitioner", "rcb"]),
    ];
    same_as_one_process("spinning", &file, "600", 5000, &splits);
    let dir = temp("spinning-lists");
    let (_, lines) = run_with_metrics(2, &dir, &file, &["--steps", "600"]);
    for r in 0..2 {
        let drawn = |f: &str| -> f64 {
            (lines.iter())
                .map(|l| l["per_rank"][f][r].as_f64().unwrap())
                .sum()
        };
        let (ghost, neighbour) = (drawn("lists_drawn"), drawn("neighbour_lists_drawn"));
        assert!(
            ghost >= 1.0 && neighbour > 2.0 * distributed::GHOST_SKINS * ghost,
            "rank {r}: ghost lists {ghost}, neighbour lists {neighbour}"
        );
    }
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_bad_scene_ends_every_rank_with_one_message() {
    let dir = temp("bad");
    let bad = dir.join("bad.toml");
    std::fs::write(
        &bad,
        "[simulation]\ndt = 1e-5\nend_time = 1.0\n[effects]\nbogus = {}\n",
    )
    .unwrap();
    let r = run(3, &["run", bad.to_str().unwrap(), "--quiet"]);
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert_one_error(&r);
    assert!(r.stderr.contains("bad.toml:5"), "{}", r.stderr);
    assert!(!r.stderr.contains("MPI_ABORT"), "{}", r.stderr);
    // A resume from a file that is not a checkpoint: refused, nothing written.
    let out = dir.join("out");
    let r = run(
        2,
        &[
            "run",
            scene("hopper.toml").to_str().unwrap(),
            "--resume",
            bad.to_str().unwrap(),
            "--output",
            out.to_str().unwrap(),
        ],
    );
    assert_eq!(r.code, 2, "{}", r.stderr);
    assert_one_error(&r);
    assert!(!out.exists(), "a refused run created {}", out.display());
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn lasting_crossed_contacts_stop_every_rank_with_one_message() {
    let scene = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/crossing-grains.toml");
    let scene = scene.to_str().unwrap();
    let r = run(2, &["run", scene, "--quiet"]);
    assert_eq!(r.code, 1, "{}", r.stderr);
    assert_one_error(&r);
    assert!(r.stderr.contains("100 steps in a row"), "{}", r.stderr);
    let allow = "simulation.allow_deep_contacts=true";
    let r = run(2, &["run", scene, "--quiet", "--set", allow]);
    assert_eq!(r.code, 0, "{}", r.stderr);
}

#[test]
fn sigterm_checkpoints_and_ends_every_rank() {
    let dir = temp("term");
    let out = dir.join("out");
    let silo = scene("silo-1000.toml");
    let mut cmd = Command::new(launcher());
    cmd.args(launch_args(2))
        .args([tridem(), "run", silo.to_str().unwrap(), "--quiet"])
        .args(["--output", out.to_str().unwrap()])
        .envs(open_mpi_local_env())
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let child = cmd.spawn().unwrap();
    // Once the first output step is written, the run is under way.
    let start = Instant::now();
    while !out.join("run.xmf").exists() && start.elapsed() < Duration::from_secs(120) {
        std::thread::sleep(Duration::from_millis(50));
    }
    std::thread::sleep(Duration::from_millis(500));
    // As a batch system's time limit does: every rank gets the signal
    // (mpirun itself, signalled, would end the ranks at once).
    let pattern = format!("^{} run .*{}", tridem(), out.display());
    assert!(Command::new("pkill")
        .args(["-TERM", "-f", &pattern])
        .status()
        .unwrap()
        .success());
    let r = finish(child, Duration::from_secs(120));
    assert_ne!(r.code, 0);
    assert!(r.stderr.contains("stopped by a signal"), "{}", r.stderr);
    assert_one_error(&r);
    // Its checkpoint goes on, on one process, to the same bits as a run
    // that was never stopped.
    let c = out.join("checkpoint.h5");
    let r = run(
        1,
        &[
            "run",
            silo.to_str().unwrap(),
            "--resume",
            c.to_str().unwrap(),
            "--output",
            out.to_str().unwrap(),
            "--steps",
            "10",
            "--quiet",
        ],
    );
    assert_eq!(r.code, 0, "{}", r.stderr);
    let _ = std::fs::remove_dir_all(&dir);
}
