//! Probes: what is in a region, and what has passed a plane, measured at
//! every output step and written to `run.h5` as time series
//! (`/steps/<k>/probes`, docs/output.md).
//!
//! - A region (an axis-aligned box, lo ≤ x ≤ hi for the particle's centre
//!   of mass): the particles in it, their mass and momentum; their mean
//!   velocity is momentum / mass.
//! - A plane (a point p and a normal n): the particles whose centre lies
//!   past it, (x − p)·n > 0, and their mass. The mass flow through the
//!   plane is the rate of change of that mass: exact for grains that cross
//!   once (a silo's outlet, a floor's edge), and the difference of two
//!   output steps divided by their time apart is the mean rate between them.
//!
//! Each quantity is an exact sum over the particles ([`ExactSum`]), so a
//! run split across ranks measures the same bits as one process. A probe
//! adds no force: it reads the state, at output steps only.

use super::places::{Cuboid, HalfSpace};
use super::{Declare, Effect, Forces, Setting, StepContext};
use crate::ledger::ExactSum;
use crate::world::World;
use serde::Deserialize;

/// `probes = { regions = [{ name, lo, hi }], planes = [{ name, point, normal }] }`.
#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ProbesParams {
    #[serde(default)]
    pub regions: Vec<Region>,
    #[serde(default)]
    pub planes: Vec<Plane>,
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Region {
    pub name: String,
    pub lo: [f64; 3],
    pub hi: [f64; 3],
}

#[derive(Debug, Clone, PartialEq, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Plane {
    pub name: String,
    pub point: [f64; 3],
    pub normal: [f64; 3],
}

impl Declare for ProbesParams {
    const NAME: &'static str = "probes";
    fn check(&self) -> Result<(), String> {
        let names: Vec<&str> = self
            .regions
            .iter()
            .map(|r| r.name.as_str())
            .chain(self.planes.iter().map(|p| p.name.as_str()))
            .collect();
        if names.is_empty() {
            return Err("declare at least one region or plane".into());
        }
        for (k, name) in names.iter().enumerate() {
            let word = |c: char| c.is_ascii_alphanumeric() || c == '_' || c == '-';
            if name.is_empty() || !name.chars().all(word) {
                return Err(format!(
                    "probe name `{name}`: use letters, digits, `_` and `-`"
                ));
            }
            if names[..k].contains(name) {
                return Err(format!("two probes are named `{name}`"));
            }
        }
        for r in &self.regions {
            Cuboid::of(r.lo, r.hi).map_err(|why| format!("region `{}`: {why}", r.name))?;
        }
        for p in &self.planes {
            HalfSpace::of(p.point, p.normal).map_err(|why| format!("plane `{}`: {why}", p.name))?;
        }
        Ok(())
    }
    fn build(&self, _: &Setting) -> Option<Box<dyn Effect>> {
        Some(Box::new(ProbesEffect {
            regions: (self.regions.iter())
                .map(|r| Some((r.name.clone(), Cuboid::of(r.lo, r.hi).ok()?)))
                .collect::<Option<_>>()?,
            planes: (self.planes.iter())
                .map(|p| Some((p.name.clone(), HalfSpace::of(p.point, p.normal).ok()?)))
                .collect::<Option<_>>()?,
        }))
    }
}

pub struct ProbesEffect {
    regions: Vec<(String, Cuboid)>,
    planes: Vec<(String, HalfSpace)>,
}

impl Effect for ProbesEffect {
    fn name(&self) -> &'static str {
        ProbesParams::NAME
    }

    fn apply(&mut self, _world: &World, _ctx: &mut StepContext, _forces: &mut Forces) {}

    /// Per region: `<name>_count`, `_mass`, `_momentum_{x,y,z}`; per plane:
    /// `<name>_count_past`, `_mass_past`; over the particles `ctx.bodies`.
    fn measures(&self, world: &World, ctx: &StepContext) -> Vec<(String, ExactSum)> {
        let mut out = Vec::new();
        for (name, region) in &self.regions {
            let mut sums: [ExactSum; 5] = Default::default();
            for &i in &ctx.bodies {
                let b = &world.bodies[i];
                if region.holds(b.x) {
                    let p = b.v * b.mass;
                    for (s, x) in sums.iter_mut().zip([1.0, b.mass, p.x, p.y, p.z]) {
                        s.add(x);
                    }
                }
            }
            let names = ["count", "mass", "momentum_x", "momentum_y", "momentum_z"];
            out.extend(
                names
                    .iter()
                    .zip(sums)
                    .map(|(n, s)| (format!("{name}_{n}"), s)),
            );
        }
        for (name, plane) in &self.planes {
            let (mut count, mut mass) = (ExactSum::default(), ExactSum::default());
            for &i in &ctx.bodies {
                let b = &world.bodies[i];
                if plane.holds(b.x) {
                    count.add(1.0);
                    mass.add(b.mass);
                }
            }
            out.push((format!("{name}_count_past"), count));
            out.push((format!("{name}_mass_past"), mass));
        }
        out
    }
}
