//! What `tridem run` reports at the end of a run on one node: one struct,
//! written as JSON (`--json`) or as a table.

use crate::sections::{label, section_rows};
use dem::contact::DetectionStats;
use dem::simulation::Simulation;
use serde::Serialize;
use std::path::{Path, PathBuf};

/// The summary of a run on one node.
#[derive(Debug, Serialize)]
pub struct RunSummary {
    pub centre_of_mass: [f64; 3],
    pub lowest_z: f64,
    pub highest_z: f64,
    pub scene: String,
    pub steps: u64,
    pub first_step: u64,
    pub last_step: u64,
    pub particles: usize,
    pub threads: usize,
    pub seconds: f64,
    pub steps_per_second: f64,
    pub seconds_per_particle_step: f64,
    pub broad_phases: u64,
    pub body_pairs_checked: u64,
    /// Body pairs checked whose hulls were farther apart than their reach:
    /// no triangle pair of theirs went to the kernel.
    pub body_pairs_apart_by_hulls: u64,
    /// Listed body pairs not checked: their hulls were shown apart earlier
    /// with a clearance, or no triangle pair of theirs was within reach
    /// plus the kept pairs' margin, and the bodies have not travelled that
    /// far since.
    pub body_pairs_known_apart: u64,
    /// Body pairs checked on the triangle pairs kept from an earlier
    /// culling, with no culling of their own.
    pub body_pairs_near_kept: u64,
    pub triangle_pairs_checked: u64,
    /// Triangle pairs checked per contact found (0 without contacts).
    pub triangle_pairs_per_contact: f64,
    /// Narrow-phase thread time (culling, kernel and contact building) per
    /// triangle pair checked, in ns.
    pub narrow_phase_ns_per_triangle_pair: f64,
    pub fallback_rate: f64,
    pub task_fallback_rate: TaskFallbackRate,
    pub contacts: u64,
    pub deep_contacts: u64,
    pub tangential_evaluations: u64,
    pub kinetic_energy: f64,
    pub stepping_seconds: f64,
    pub narrow_phase_busy_thread_seconds: f64,
    /// Seconds per section of the step pipeline, then checkpoints and the
    /// rest (output, the finiteness check, the progress bar), in table order.
    pub section_seconds: serde_json::Map<String, serde_json::Value>,
    /// The effects' measures at the end (probes, outflow, insertion), by name.
    pub measures: serde_json::Map<String, serde_json::Value>,
    /// The sections as the table shows them: label and seconds.
    #[serde(skip)]
    rows: Vec<(String, f64)>,
    #[serde(skip)]
    output: Option<PathBuf>,
}

/// a / b, 0 when b is 0.
fn ratio(a: f64, b: f64) -> f64 {
    if b > 0.0 {
        a / b
    } else {
        0.0
    }
}

/// The effects' measures as JSON, by name.
pub fn measure_map(measures: Vec<(String, f64)>) -> serde_json::Map<String, serde_json::Value> {
    measures.into_iter().map(|(n, v)| (n, v.into())).collect()
}

/// The effects' measures at the end of the run, one per line (none
/// printed when the scene declares no effect that measures).
pub fn print_measures(measures: &serde_json::Map<String, serde_json::Value>) {
    if measures.is_empty() {
        return;
    }
    println!("measures at the end");
    for (name, v) in measures {
        println!("  {name:<28} {}", v.as_f64().unwrap_or(f64::NAN));
    }
}

/// The fallback rate of the least and the most falling-back detection task,
/// averaged over passes: whole-batch fallback makes it depend on how pairs
/// are cut into tasks, and so on the threads.
#[derive(Debug, Serialize)]
pub struct TaskFallbackRate {
    pub least: f64,
    pub most: f64,
}

impl TaskFallbackRate {
    fn of(d: &DetectionStats) -> TaskFallbackRate {
        let n = d.passes_with_pairs.max(1) as f64;
        TaskFallbackRate {
            least: d.task_fallback_min / n,
            most: d.task_fallback_max / n,
        }
    }
}

/// Where a run's time went that the step pipeline does not count.
pub struct RunTimes {
    /// From the first step to the last.
    pub seconds: f64,
    /// Writing checkpoints, within `seconds`.
    pub checkpoint_seconds: f64,
}

impl RunSummary {
    pub fn of(
        scene: &Path,
        sim: &Simulation,
        first_step: u64,
        steps: u64,
        times: RunTimes,
        output: Option<&Path>,
    ) -> RunSummary {
        let secs = times.seconds;
        let t = &sim.totals;
        // The particles in the run (all of them, if none is yet).
        let particles = sim.world.bodies.iter().filter(|b| !b.is_static());
        let present: Vec<_> = particles.clone().filter(|b| !b.is_out()).collect();
        let dynamic = match present.is_empty() {
            true => particles.collect(),
            false => present,
        };
        let com = dynamic.iter().map(|b| b.x * b.mass).sum::<glam::DVec3>()
            / dynamic.iter().map(|b| b.mass).sum::<f64>();
        let z = dynamic.iter().map(|b| b.x.z);
        let stepping = sim.timings.total();
        let mut rows: Vec<(String, f64)> = Vec::new();
        let mut section_seconds = serde_json::Map::new();
        for r in section_rows(&sim.timings) {
            section_seconds.insert(r.key(), r.seconds.into());
            rows.push((label(&r), r.seconds));
        }
        let other = (secs - stepping - times.checkpoint_seconds).max(0.0);
        section_seconds.insert("checkpoints".into(), times.checkpoint_seconds.into());
        section_seconds.insert("other".into(), other.into());
        rows.push(("checkpoints".into(), times.checkpoint_seconds));
        rows.push(("output and checks".into(), other));
        let d = &t.detection;
        RunSummary {
            centre_of_mass: com.to_array(),
            lowest_z: z.clone().fold(f64::INFINITY, f64::min),
            highest_z: z.fold(f64::NEG_INFINITY, f64::max),
            scene: scene.display().to_string(),
            steps,
            first_step,
            last_step: sim.world.step,
            particles: dynamic.len(),
            threads: rayon::current_num_threads(),
            seconds: secs,
            steps_per_second: steps as f64 / secs,
            seconds_per_particle_step: secs / (steps as f64 * dynamic.len() as f64),
            broad_phases: d.broad_phases,
            body_pairs_checked: d.body_pairs,
            body_pairs_apart_by_hulls: d.hulls_apart,
            body_pairs_known_apart: d.known_apart,
            body_pairs_near_kept: d.near_kept,
            triangle_pairs_checked: d.triangle_pairs,
            triangle_pairs_per_contact: ratio(d.triangle_pairs as f64, d.contacts as f64),
            narrow_phase_ns_per_triangle_pair: ratio(
                1e9 * sim.timings.detection.narrow_phase_busy,
                d.triangle_pairs as f64,
            ),
            fallback_rate: match d.triangle_pairs {
                0 => 0.0,
                n => d.fallback_pairs as f64 / n as f64,
            },
            task_fallback_rate: TaskFallbackRate::of(d),
            contacts: d.contacts,
            deep_contacts: d.deep_contacts,
            tangential_evaluations: t.tangential_evaluations,
            kinetic_energy: sim.world.kinetic_energy(),
            stepping_seconds: stepping,
            narrow_phase_busy_thread_seconds: sim.timings.detection.narrow_phase_busy,
            section_seconds,
            measures: measure_map(sim.energies().measures),
            rows,
            output: output.map(Path::to_path_buf),
        }
    }

    /// The summary as a table, for people.
    pub fn print(&self) {
        let secs = self.seconds;
        println!(
            "steps                  {} in {secs:.2} s ({:.0} steps/s)",
            self.steps, self.steps_per_second
        );
        println!(
            "cost per particle-step {:.3e} s",
            self.seconds_per_particle_step
        );
        println!("broad phases           {}", self.broad_phases);
        println!(
            "body pairs checked     {} ({} apart by their hulls; {} on kept triangle pairs; {} more still apart, not checked)",
            self.body_pairs_checked,
            self.body_pairs_apart_by_hulls,
            self.body_pairs_near_kept,
            self.body_pairs_known_apart
        );
        println!(
            "triangle pairs checked {} ({:.1} per contact; narrow phase {:.0} ns each)",
            self.triangle_pairs_checked,
            self.triangle_pairs_per_contact,
            self.narrow_phase_ns_per_triangle_pair
        );
        println!("kernel fallback rate   {:.1}%", 100.0 * self.fallback_rate);
        println!("contacts (sum)         {}", self.contacts);
        println!("tangential evaluations {}", self.tangential_evaluations);
        println!("deep contacts          {}", self.deep_contacts);
        println!(
            "particles' z           {:.4} .. {:.4} (centre of mass {:.4})",
            self.lowest_z, self.highest_z, self.centre_of_mass[2]
        );
        println!("time by section        seconds  share");
        for (name, s) in &self.rows {
            println!("  {name:<20} {s:>8.3}  {:>4.1}%", 100.0 * s / secs);
        }
        print_measures(&self.measures);
        if let Some(dir) = &self.output {
            print_output_lines(dir, self.last_step);
        }
    }
}

/// Where a run's output and checkpoint are, and how to go on.
pub fn print_output_lines(dir: &Path, step: u64) {
    println!(
        "output                 {}/run.h5 (open {}/run.xmf in ParaView)",
        dir.display(),
        dir.display()
    );
    println!(
        "checkpoint             {}/checkpoint.h5 (step {step}; go on with --resume)",
        dir.display(),
    );
}
