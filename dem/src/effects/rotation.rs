//! Rotation: bodies turn under the torques of the other effects. Without
//! it they only translate (the integrator leaves orientations alone, and
//! the contact dashpot counts no inertia). It adds no force of its own.

use super::{Declare, Effect, Setting};
use serde::Deserialize;

/// `rotation = {}`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RotationParams {}

impl Declare for RotationParams {
    const NAME: &'static str = "rotation";
    fn build(&self, _: &Setting) -> Option<Box<dyn Effect>> {
        None
    }
}

impl super::Effects {
    /// Whether bodies turn: what the integrator and the contact law ask of
    /// the scene, rather than whether an effect of some type is declared.
    pub fn rotate(&self) -> bool {
        self.has::<RotationParams>()
    }
}
