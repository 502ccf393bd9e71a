//! The scene file as TOML has it, before any check: what serde reads.

use super::{OutputSection, Parallel};
use crate::distance::{Fallback, Threading};
use serde::Deserialize;
use std::path::PathBuf;
use toml::Spanned;

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SceneFile {
    pub(super) simulation: Spanned<SimulationSpec>,
    pub(super) effects: Spanned<toml::Table>,
    #[serde(default)]
    pub(super) materials: Vec<Spanned<MaterialSpec>>,
    #[serde(default)]
    pub(super) particles: Vec<Spanned<ParticleSpec>>,
    #[serde(default)]
    pub(super) obstacles: Vec<Spanned<ObstacleSpec>>,
    #[serde(default)]
    pub(super) kernel: Option<Spanned<KernelSpec>>,
    #[serde(default)]
    pub(super) parallel: Option<Spanned<Parallel>>,
    #[serde(default)]
    pub(super) output: Option<Spanned<OutputSection>>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct SimulationSpec {
    pub(super) dt: f64,
    pub(super) end_time: f64,
    #[serde(default = "default_output_every")]
    pub(super) output_every: u64,
    /// Run with a step above the stable one (with a warning) instead of refusing.
    #[serde(default)]
    pub(super) allow_unstable_dt: bool,
    /// Start with bodies overlapping, and go on when contacts stay deeper
    /// than the halos, instead of refusing and stopping.
    #[serde(default)]
    pub(super) allow_deep_contacts: bool,
}

pub(super) fn default_output_every() -> u64 {
    1000
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct KernelSpec {
    #[serde(default = "default_method")]
    pub(super) method: String,
    #[serde(default = "default_batch")]
    pub(super) batch: usize,
    /// Recompute only uncertified pairs by brute force (the default), not
    /// their whole batch (the published kernel, `false`).
    #[serde(default = "default_fallback_failed_pairs")]
    pub(super) fallback_failed_pairs: bool,
    /// How body pairs are shared among threads: static, dynamic or guided.
    #[serde(default = "default_schedule")]
    pub(super) schedule: String,
    /// Body pairs per task of the dynamic schedule, smallest task of the guided one.
    #[serde(default = "default_grain")]
    pub(super) grain: usize,
    /// Newton iterations of the penalty kernel (penalty and hybrid methods).
    pub(super) iterations: Option<usize>,
    /// Rounds of the penalty kernel's exact finish (penalty and hybrid methods).
    pub(super) finish_rounds: Option<usize>,
    /// The penalty kernel certifies a pair when its error bound is at most
    /// tolerance × the pair's size (penalty and hybrid methods).
    pub(super) tolerance: Option<f64>,
}

pub(super) fn default_fallback_failed_pairs() -> bool {
    Fallback::default() == Fallback::FailedPairs
}

pub(super) fn default_grain() -> usize {
    Threading::default().grain
}

pub(super) fn default_schedule() -> String {
    Threading::default().schedule.name().into()
}

pub(super) fn default_method() -> String {
    "hybrid".into()
}
pub(super) fn default_batch() -> usize {
    8
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct MaterialSpec {
    pub(super) name: String,
    pub(super) density: f64,
    pub(super) stiffness: Option<f64>,
    pub(super) restitution: Option<f64>,
    pub(super) halo: Option<f64>,
    pub(super) friction: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub(super) enum ShapeSpec {
    Hull {
        triangles: usize,
        radius: f64,
        #[serde(default)]
        seed: u64,
    },
    Box {
        size: [f64; 3],
        /// Each triangle split into four this many times: the same box with
        /// more triangles (for checking that results do not depend on the mesh).
        #[serde(default)]
        subdivide: usize,
    },
    Tetrahedron {
        radius: f64,
    },
    /// A rotating drum's shell, along y, or a funnel's, its inner radius
    /// `end_inner_radius` at the +y end (see [`crate::mesh::tube`]).
    Tube {
        inner_radius: f64,
        #[serde(default)]
        end_inner_radius: Option<f64>,
        thickness: f64,
        length: f64,
        #[serde(default = "tube_segments")]
        segments: usize,
    },
    Mesh {
        file: PathBuf,
        #[serde(default = "one")]
        scale: f64,
    },
}

pub(super) fn tube_segments() -> usize {
    48
}

pub(super) fn one() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
pub(super) enum PlacementSpec {
    Single {
        position: [f64; 3],
    },
    Lattice {
        count: [usize; 3],
        spacing: f64,
        origin: [f64; 3],
    },
    Random {
        count: usize,
        lo: [f64; 3],
        hi: [f64; 3],
        #[serde(default)]
        seed: u64,
    },
    /// Particles that enter during the run (the `insertion` effect).
    Insert {
        count: usize,
        region: crate::effects::InsertRegion,
        /// Particles per second (absent: all at `start`).
        #[serde(default)]
        rate: Option<f64>,
        #[serde(default)]
        start: f64,
        #[serde(default)]
        seed: u64,
    },
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ParticleSpec {
    pub(super) material: String,
    pub(super) shape: ShapeSpec,
    pub(super) placement: PlacementSpec,
    #[serde(default)]
    pub(super) velocity: [f64; 3],
    #[serde(default)]
    pub(super) angular_velocity: [f64; 3],
    /// "identity" (default) or "random".
    #[serde(default)]
    pub(super) orientation: Option<String>,
    /// Rotation vector (axis times angle, radians) applied to the shape.
    #[serde(default)]
    pub(super) rotation: Option<[f64; 3]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub(super) struct ObstacleSpec {
    pub(super) material: String,
    pub(super) shape: ShapeSpec,
    #[serde(default)]
    pub(super) position: [f64; 3],
    /// Rotation vector (axis times angle, radians).
    #[serde(default)]
    pub(super) rotation: Option<[f64; 3]>,
    /// A prescribed velocity of its frame's origin (m/s) and angular
    /// velocity about it (rad/s, world axes): the obstacle moves (the
    /// `wall_motion` effect).
    #[serde(default)]
    pub(super) velocity: Option<[f64; 3]>,
    #[serde(default)]
    pub(super) angular_velocity: Option<[f64; 3]>,
    /// The same as tables of rows [t, x, y, z], times increasing: linear
    /// between rows, the first row's value before it and the last's after
    /// (instead of the constant keys). Angular rows keep one axis.
    #[serde(default)]
    pub(super) velocity_table: Option<Vec<[f64; 4]>>,
    #[serde(default)]
    pub(super) angular_velocity_table: Option<Vec<[f64; 4]>>,
    /// The time (s) from which the obstacle is gone: it takes part in no
    /// contact after it (a gate pulled out).
    #[serde(default)]
    pub(super) remove_at: Option<f64>,
}
