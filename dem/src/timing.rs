//! Where a run's time goes, section by section of the step pipeline, as
//! LAMMPS breaks down its run time at the end of a run: a section that does
//! not speed up with more threads shows here. Wall-clock seconds, summed over
//! steps; for finding bottlenecks, never asserted on by tests.

use std::ops::AddAssign;
use std::time::Instant;

/// Seconds spent in contact detection, by phase.
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct DetectionTimes {
    /// Moving the triangles with their bodies (world vertices and boxes).
    pub triangle_update: f64,
    /// Body pairs whose boxes overlap (serial).
    pub broad_phase: f64,
    /// Triangle culling, the distance kernel and merging per body pair, in
    /// parallel tasks.
    pub narrow_phase: f64,
    /// Thread-seconds the narrow phase's tasks ran, summed over the tasks
    /// (not part of [`Self::total`]): against `narrow_phase` times the
    /// threads, what the threads spent waiting (a late start, the last task).
    pub narrow_phase_busy: f64,
}

impl DetectionTimes {
    pub fn total(&self) -> f64 {
        self.triangle_update + self.broad_phase + self.narrow_phase
    }
}

impl AddAssign for DetectionTimes {
    fn add_assign(&mut self, o: DetectionTimes) {
        self.triangle_update += o.triangle_update;
        self.broad_phase += o.broad_phase;
        self.narrow_phase += o.narrow_phase;
        self.narrow_phase_busy += o.narrow_phase_busy;
    }
}

/// Seconds per section of the step pipeline, summed over steps.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SectionTimes {
    /// The kicks and the drift.
    pub integration: f64,
    /// Each effect of the pipeline, in its order; contact detection counts in
    /// the contact effect's time and is broken down in `detection`.
    pub effects: Vec<(&'static str, f64)>,
    pub detection: DetectionTimes,
    /// The effect whose time includes `detection`, if any.
    pub detecting_effect: Option<&'static str>,
}

impl SectionTimes {
    /// Integration and effects: all the time spent in steps.
    pub fn total(&self) -> f64 {
        self.integration + self.effects.iter().map(|e| e.1).sum::<f64>()
    }
}

/// Seconds elapsed since `start`.
pub(crate) fn seconds_since(start: Instant) -> f64 {
    start.elapsed().as_secs_f64()
}
