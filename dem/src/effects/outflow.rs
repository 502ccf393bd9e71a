//! Outflow: particles that pass a plane, or leave a box, are taken out of
//! the run (a sink under a silo's outlet, the edge of a plate).
//!
//! At the end of each step, once the closing half kick has given every
//! particle its full-step velocity, each particle still in the run whose
//! centre of mass lies past one of the planes, (x − p)·n > 0, or outside
//! the box, is removed ([`Body::removed`]): from the next step on it does
//! not move, takes part in no contact and no effect acts on it. It is
//! parked, not deleted: its state stays as it was when it left, so that a
//! run split across ranks decides and books the same removals as one
//! process (the owner decides, from the state alone), a checkpoint carries
//! them as one flag per body, and the output still lists every body by id
//! (with the flag `removed`).
//!
//! What left is counted and booked, as exact sums over the removed
//! particles (the same bits on any rank count):
//! - the measures `outflow_count` and `outflow_mass` (kg), written with the
//!   probes at each output step; the mass-flow rate out is the rate of
//!   change of `outflow_mass`;
//! - the energy the particles carried out, their kinetic energy and
//!   gravity's potential −m g·x at removal, as energy the effect stores: the
//!   books still balance when particles leave with their energy.

use super::places::{Cuboid, HalfSpace};
use super::{Books, Declare, Effect, Forces, Setting, StepContext};
use crate::body::Body;
use crate::effects::GravityParams;
use crate::ledger::ExactSum;
use crate::world::World;
use glam::DVec3;
use serde::Deserialize;

/// `outflow = { planes = [{ point, normal }], inside = { lo, hi } }`: a
/// particle leaves once its centre is past any plane (on the normal's side)
/// or outside the box.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutflowParams {
    #[serde(default)]
    pub planes: Vec<SinkPlane>,
    /// The box particles must stay in (lo ≤ x ≤ hi, by the centre of mass).
    #[serde(default)]
    pub inside: Option<SinkBox>,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SinkPlane {
    pub point: [f64; 3],
    pub normal: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct SinkBox {
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

impl Declare for OutflowParams {
    const NAME: &'static str = "outflow";
    fn check(&self) -> Result<(), String> {
        if self.planes.is_empty() && self.inside.is_none() {
            return Err("declare a plane (`planes`) or a box (`inside`) to leave".into());
        }
        for (k, p) in self.planes.iter().enumerate() {
            HalfSpace::of(p.point, p.normal).map_err(|why| format!("plane {}: {why}", k + 1))?;
        }
        if let Some(b) = &self.inside {
            Cuboid::of(b.lo, b.hi).map_err(|why| format!("inside: {why}"))?;
        }
        Ok(())
    }
    fn build(&self, setting: &Setting) -> Option<Box<dyn Effect>> {
        let g = setting.effects.get::<GravityParams>().map(|p| p.g());
        Some(Box::new(OutflowEffect {
            planes: (self.planes.iter())
                .map(|p| HalfSpace::of(p.point, p.normal))
                .collect::<Result<_, _>>()
                .ok()?,
            inside: match &self.inside {
                Some(b) => Some(Cuboid::of(b.lo, b.hi).ok()?),
                None => None,
            },
            g: g.unwrap_or(DVec3::ZERO),
        }))
    }
}

pub struct OutflowEffect {
    planes: Vec<HalfSpace>,
    inside: Option<Cuboid>,
    /// Gravity's acceleration (zero without gravity): the potential energy
    /// a particle carries out.
    g: DVec3,
}

impl Effect for OutflowEffect {
    fn name(&self) -> &'static str {
        OutflowParams::NAME
    }

    fn apply(&mut self, _world: &World, _ctx: &mut StepContext, _forces: &mut Forces) {}

    fn removes_particles(&self) -> bool {
        true
    }

    fn removes(&self, b: &Body) -> bool {
        self.planes.iter().any(|p| p.holds(b.x)) || self.inside.is_some_and(|c| !c.holds(b.x))
    }

    /// The energy the removed particles `ctx.removed` carried out, stored.
    fn books(&self, world: &World, ctx: &StepContext) -> Books {
        let mut books = Books::default();
        for &i in &ctx.removed {
            let b = &world.bodies[i];
            books.stored.add(0.5 * b.mass * b.v.length_squared());
            books.stored.add(0.5 * b.l.dot(b.omega()));
            books.stored.add(-b.mass * self.g.dot(b.x));
        }
        books
    }

    /// `outflow_count` and `outflow_mass`: the particles removed so far.
    fn measures(&self, world: &World, ctx: &StepContext) -> Vec<(String, ExactSum)> {
        let (mut count, mut mass) = (ExactSum::default(), ExactSum::default());
        for &i in &ctx.removed {
            count.add(1.0);
            mass.add(world.bodies[i].mass);
        }
        vec![("outflow_count".into(), count), ("outflow_mass".into(), mass)]
    }
}
