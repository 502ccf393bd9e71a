//! `tridem study NAME`: questions a DEM user asks before spending an
//! allocation, answered on real distributed runs of a scene. Each study
//! starts its runs under mpirun (`$MPIRUN`, default `mpirun`, with
//! `$MPIRUN_ARGS`, default `--oversubscribe`; `MPIRUN=srun` inside a SLURM
//! allocation, with `--mpi=pmix` unless `$TRIDEM_SRUN_MPI` says), keeps every run's metrics
//! (`DIR/runs/LABEL-rN.jsonl`), writes one summary CSV and its figures (SVG
//! and PNG), and prints a short table.
//!
//! Every setting runs `--repeat` times, the settings taken in turn (ABCABC:
//! a drift of the machine spreads over all of them); the tables give the
//! median and the least and most, the figures error bars. Each timing study
//! runs its first setting twice under two labels: the difference between the
//! two is its *noise floor*, and a difference between settings inside it is
//! reported as none.

mod common;
mod model;
mod node;
mod ranks;

use crate::cli::{StudyArgs, StudyName};
use crate::error::{create_output_dir, CliError, CliResult};
use common::{again, Group, Ran, Spec};
use serde_json::Value;
use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::Instant;

pub fn run(args: &StudyArgs) -> CliResult {
    let dir = args
        .output
        .clone()
        .unwrap_or_else(|| PathBuf::from(format!("out/study-{}", args.name.name())));
    if let Some(r) = args
        .ranks
        .iter()
        .find(|&&r| r < 2)
        .filter(|_| args.name.distributed())
    {
        return Err(CliError::input(format!(
            "--ranks {r}: a study compares distributed runs, of 2 ranks or more"
        )));
    }
    if dir.join("summary.csv").exists() && !args.overwrite {
        return Err(CliError::input(format!(
            "{}: holds an earlier study; write to another directory or replace it with --overwrite",
            dir.display()
        )));
    }
    let scene = args.scene();
    if !scene.exists() {
        return Err(CliError::input(format!(
            "{}: no such scene",
            scene.display()
        )));
    }
    let mut specs = if args.name.distributed() {
        ranks::specs(args)
    } else {
        node::specs(args)?
    };
    if args.name != StudyName::Accuracy {
        // The first setting again, under another label: the noise floor.
        let mut twin = specs[0].clone();
        twin.label = again(&twin.label);
        twin.series = "noise floor".into();
        specs.push(twin);
    }
    create_output_dir(&dir.join("runs"))?;
    let resume_from = settle(args, &dir)?;
    let mut groups: Vec<Group> = specs
        .iter()
        .map(|s| Group {
            spec: s.clone(),
            runs: Vec::new(),
        })
        .collect();
    let total = args.repeat as usize * specs.len();
    for rep in 0..args.repeat as usize {
        for (k, spec) in specs.iter().enumerate() {
            let start = Instant::now();
            let r = run_one(args, &dir, spec.clone(), rep, resume_from.as_deref())?;
            eprintln!(
                "[{}/{total}] {:<24} {:>7.2} s",
                rep * specs.len() + k + 1,
                r.spec.label,
                start.elapsed().as_secs_f64()
            );
            groups[k].runs.push(r);
        }
    }
    match args.name.distributed() {
        true => ranks::report(args, &dir, &groups),
        false => node::report(args, &dir, &groups),
    }
}

/// With --settle: runs the scene that many steps once, with brute force on
/// every core, into DIR/settled, and returns the checkpoint every run of
/// the study resumes from.
fn settle(args: &StudyArgs, dir: &Path) -> CliResult<Option<PathBuf>> {
    let steps = args.settle();
    if steps == 0 {
        return Ok(None);
    }
    let out = dir.join("settled");
    let exe = std::env::current_exe().map_err(|e| CliError::runtime(e.to_string()))?;
    let started = Instant::now();
    let done = Command::new(exe)
        .arg("run")
        .arg(args.scene())
        .args(["--steps", &steps.to_string(), "--quiet", "--overwrite"])
        .args(["--set", "kernel.method=brute", "--output"])
        .arg(&out)
        .output()
        .map_err(|e| CliError::runtime(format!("cannot start the settling run: {e}")))?;
    if !done.status.success() {
        return Err(CliError::runtime(format!(
            "the settling run ({steps} steps) failed ({}): {}",
            done.status,
            String::from_utf8_lossy(&done.stderr).trim()
        )));
    }
    eprintln!(
        "settled: {steps} steps in {:.1} s; every run resumes from {}",
        started.elapsed().as_secs_f64(),
        out.join("checkpoint.h5").display()
    );
    Ok(Some(out.join("checkpoint.h5")))
}

/// Runs one run of a study (under the launcher when distributed, with
/// metrics; on one node directly, keeping its output for its final state)
/// and reads its summary and metrics. With `start`, the run resumes from
/// that checkpoint into a directory of its own, made afresh.
fn run_one(
    args: &StudyArgs,
    dir: &Path,
    spec: Spec,
    rep: usize,
    start: Option<&Path>,
) -> CliResult<Ran> {
    let metrics = dir
        .join("runs")
        .join(format!("{}-r{rep}.jsonl", spec.label));
    let scene = args.scene();
    let exe = std::env::current_exe().map_err(|e| CliError::runtime(e.to_string()))?;
    let launcher = std::env::var("MPIRUN").unwrap_or_else(|_| "mpirun".into());
    let own = dir.join("runs").join(&spec.label);
    let mut command = if spec.ranks == 1 {
        let mut c = Command::new(&exe);
        c.arg("run").arg(&scene).arg("--output").arg(&own);
        c
    } else {
        // SLURM's srun takes the task count as -n, needs no oversubscription,
        // and starts Debian's Open MPI through PMIx ($TRIDEM_SRUN_MPI names
        // another plugin).
        let srun = launcher.ends_with("srun");
        let extra = std::env::var("MPIRUN_ARGS").unwrap_or_else(|_| {
            if srun {
                let plugin = std::env::var("TRIDEM_SRUN_MPI").unwrap_or_else(|_| "pmix".into());
                format!("--mpi={plugin}")
            } else {
                "--oversubscribe".into()
            }
        });
        let mut c = Command::new(&launcher);
        c.args(extra.split_whitespace())
            .args([if srun { "-n" } else { "-np" }, &spec.ranks.to_string()])
            .arg(&exe)
            .arg("run")
            .arg(&scene)
            .args(["--metrics-every", &args.metrics_every.to_string()])
            .arg("--metrics")
            .arg(&metrics);
        c
    };
    if let Some(from) = start {
        // A resumed run appends to the output in its directory: each
        // repeat starts from an empty one.
        if own.exists() {
            std::fs::remove_dir_all(&own)
                .map_err(|e| CliError::runtime(format!("{}: {e}", own.display())))?;
        }
        if spec.ranks > 1 {
            command.arg("--output").arg(&own);
        }
        command.arg("--resume").arg(from);
    }
    let out = command
        .args(["--steps", &args.steps().to_string()])
        .args(["--threads", &spec.threads.to_string()])
        .args(["--quiet", "--json", "--overwrite"])
        .args(&spec.args)
        .output()
        .map_err(|e| CliError::runtime(format!("cannot start {launcher}: {e}")))?;
    let stderr = String::from_utf8_lossy(&out.stderr);
    if !out.status.success() {
        return Err(CliError::runtime(format!(
            "run {} failed ({}): {}",
            spec.label,
            out.status,
            stderr.trim()
        )));
    }
    let stdout = String::from_utf8_lossy(&out.stdout);
    let summary: Value = stdout
        .lines()
        .rev()
        .find_map(|l| serde_json::from_str(l).ok())
        .ok_or_else(|| CliError::runtime(format!("run {}: no summary", spec.label)))?;
    if spec.ranks == 1 {
        return Ok(Ran {
            spec,
            summary,
            lines: Vec::new(),
        });
    }
    let text = std::fs::read_to_string(&metrics)
        .map_err(|e| CliError::runtime(format!("{}: {e}", metrics.display())))?;
    let lines = text
        .lines()
        .map(serde_json::from_str)
        .collect::<Result<Vec<Value>, _>>()
        .map_err(|e| CliError::runtime(format!("{}: {e}", metrics.display())))?;
    Ok(Ran {
        spec,
        summary,
        lines,
    })
}
