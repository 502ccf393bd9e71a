//! Scenes in TOML: materials, particles, obstacles, time stepping, and the
//! list of effects. Every error names the file, the line and the cause.
//!
//! ```toml
//! [simulation]
//! dt = 1e-5              # s
//! end_time = 0.2         # s
//! output_every = 1000    # steps between outputs
//! # allow_unstable_dt = true    # run a step above the stable one, with a warning
//! # allow_deep_contacts = true  # start with bodies crossing, and go on when
//! #                             # contacts stay deeper than the halos
//!
//! [effects]              # only these are computed
//! gravity = { g = [0.0, 0.0, -9.81] }
//! contact = {}           # needs stiffness, restitution, halo in every material;
//!                        # { skin = 1e-3 } keeps a neighbour list (m, see docs/dem.md)
//! friction = {}          # needs friction in every material
//! damping = { linear = 0.5, angular = 0.5 }
//! rotation = {}          # without it bodies only translate
//!
//! [[materials]]
//! name = "glass"
//! density = 2500.0
//! stiffness = 1e4
//! restitution = 0.5
//! halo = 1e-4
//! friction = 0.4
//!
//! [[particles]]
//! material = "glass"
//! shape = { kind = "hull", triangles = 20, radius = 0.005, seed = 1 }
//! placement = { kind = "lattice", count = [3, 3, 3], spacing = 0.012, origin = [0.0, 0.0, 0.02] }
//!
//! [[obstacles]]
//! material = "glass"
//! shape = { kind = "box", size = [0.2, 0.2, 0.01] }
//! position = [0.0, 0.0, -0.005]
//!
//! [kernel]               # contact detection (docs/dem.md, docs/distance.md)
//! method = "hybrid"      # brute, penalty or hybrid
//! fallback_failed_pairs = true
//! schedule = "guided"    # static, dynamic or guided
//! # batch = 8, grain, iterations = 4, finish_rounds = 1, tolerance = 1e-13
//!
//! [parallel]             # under mpirun (the command line wins)
//! partitioner = "zoltan-rcb"   # zoltan-rib, zoltan-hsfc, metis, rcb
//! repartition_every = 100      # steps (0: only at the start)
//! exchange = "nonblocking"     # or "blocking"
//! ```

use crate::body::Body;
use crate::distance::{Fallback, Method, Options, PenaltyParams, Schedule, Threading};
use crate::material::{damping_ratio, Material};
use crate::mesh::{
    box_mesh, load_mesh, sphere_hull, subdivided, tetrahedron, MassProperties, TriMesh,
};
use crate::world::World;
use glam::{DMat3, DQuat, DVec3};
use rand::{Rng, SeedableRng};
use rand_xoshiro::Xoshiro256PlusPlus;
use serde::Deserialize;
use std::path::{Path, PathBuf};
use toml::Spanned;

/// A scene error: where and why.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct SceneError {
    pub file: String,
    /// 1-based; 0 when the error is about the file as a whole (unreadable).
    pub line: usize,
    pub cause: String,
}

impl std::fmt::Display for SceneError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self.line {
            0 => write!(f, "{}: {}", self.file, self.cause),
            line => write!(f, "{}:{line}: {}", self.file, self.cause),
        }
    }
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SceneFile {
    simulation: Spanned<SimulationSpec>,
    effects: Spanned<EffectsSpec>,
    #[serde(default)]
    materials: Vec<Spanned<MaterialSpec>>,
    #[serde(default)]
    particles: Vec<Spanned<ParticleSpec>>,
    #[serde(default)]
    obstacles: Vec<Spanned<ObstacleSpec>>,
    #[serde(default)]
    kernel: Option<Spanned<KernelSpec>>,
    #[serde(default)]
    parallel: Option<Spanned<Parallel>>,
}

/// How a run under mpirun is split (`[parallel]`), names as the command line takes them.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Parallel {
    pub partitioner: Option<String>,
    pub repartition_every: Option<u64>,
    pub exchange: Option<String>,
}

/// The partitioners and exchanges `[parallel]` may name.
const PARTITIONERS: [&str; 5] = ["zoltan-rcb", "zoltan-rib", "zoltan-hsfc", "metis", "rcb"];
const EXCHANGES: [&str; 2] = ["nonblocking", "blocking"];

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct SimulationSpec {
    dt: f64,
    end_time: f64,
    #[serde(default = "default_output_every")]
    output_every: u64,
    /// Run with a step above the stable one (with a warning) instead of refusing.
    #[serde(default)]
    allow_unstable_dt: bool,
    /// Start with bodies overlapping, and go on when contacts stay deeper
    /// than the halos, instead of refusing and stopping.
    #[serde(default)]
    allow_deep_contacts: bool,
}

fn default_output_every() -> u64 {
    1000
}

#[derive(Debug, Deserialize, Default)]
#[serde(deny_unknown_fields)]
struct EffectsSpec {
    gravity: Option<GravitySpec>,
    contact: Option<ContactSpec>,
    friction: Option<EmptySpec>,
    damping: Option<DampingSpec>,
    rotation: Option<EmptySpec>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct EmptySpec {}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ContactSpec {
    /// Neighbour-list skin (m); 0: the broad phase runs every step.
    #[serde(default)]
    skin: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct GravitySpec {
    g: [f64; 3],
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct DampingSpec {
    #[serde(default)]
    linear: f64,
    #[serde(default)]
    angular: f64,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct KernelSpec {
    #[serde(default = "default_method")]
    method: String,
    #[serde(default = "default_batch")]
    batch: usize,
    #[serde(default)]
    fallback_failed_pairs: bool,
    /// How body pairs are shared among threads: static, dynamic or guided.
    #[serde(default = "default_schedule")]
    schedule: String,
    /// Body pairs per task of the dynamic schedule, smallest task of the guided one.
    #[serde(default = "default_grain")]
    grain: usize,
    /// Newton iterations of the penalty kernel (penalty and hybrid methods).
    iterations: Option<usize>,
    /// Rounds of the penalty kernel's exact finish (penalty and hybrid methods).
    finish_rounds: Option<usize>,
    /// The penalty kernel certifies a pair when its error bound is at most
    /// tolerance × the pair's size (penalty and hybrid methods).
    tolerance: Option<f64>,
}

/// Bounds of the penalty kernel's settings in a scene: iteration counts are
/// reported per pair in a byte. The accuracy sweep (`tridem kernels
/// --accuracy`, rounds 0-4) found rounds after the second certifying almost
/// no more pairs; 8 leaves room above what was measured and keeps a typo
/// from turning every uncertified batch into a long loop.
const MAX_ITERATIONS: usize = 255;
/// A box subdivided 6 times has 49,152 triangles: enough for any test of
/// mesh independence, and a typo cannot ask for billions.
const MAX_SUBDIVIDE: usize = 6;
pub const MAX_FINISH_ROUNDS: usize = 8;
/// A convex hull of a million triangles is finer than any particle model
/// needs; its hull computation alone would take minutes.
const MAX_HULL_TRIANGLES: usize = 1_000_000;

fn default_grain() -> usize {
    Threading::default().grain
}

fn default_schedule() -> String {
    Threading::default().schedule.name().into()
}

fn default_method() -> String {
    "hybrid".into()
}
fn default_batch() -> usize {
    8
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialSpec {
    name: String,
    density: f64,
    stiffness: Option<f64>,
    restitution: Option<f64>,
    halo: Option<f64>,
    friction: Option<f64>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
enum ShapeSpec {
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
    Mesh {
        file: PathBuf,
        #[serde(default = "one")]
        scale: f64,
    },
}

fn one() -> f64 {
    1.0
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields, tag = "kind", rename_all = "snake_case")]
enum PlacementSpec {
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
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ParticleSpec {
    material: String,
    shape: ShapeSpec,
    placement: PlacementSpec,
    #[serde(default)]
    velocity: [f64; 3],
    #[serde(default)]
    angular_velocity: [f64; 3],
    /// "identity" (default) or "random".
    #[serde(default)]
    orientation: Option<String>,
    /// Rotation vector (axis times angle, radians) applied to the shape.
    #[serde(default)]
    rotation: Option<[f64; 3]>,
}

#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
struct ObstacleSpec {
    material: String,
    shape: ShapeSpec,
    #[serde(default)]
    position: [f64; 3],
    /// Rotation vector (axis times angle, radians).
    #[serde(default)]
    rotation: Option<[f64; 3]>,
}

/// Which effects a scene declared, with their parameters.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct Effects {
    pub gravity: Option<DVec3>,
    pub contact: bool,
    /// The contact effect's neighbour-list skin (m; 0: no list).
    pub contact_skin: f64,
    pub friction: bool,
    pub damping: Option<(f64, f64)>,
    pub rotation: bool,
}

impl Effects {
    pub fn names(&self) -> Vec<&'static str> {
        let mut v = Vec::new();
        if self.gravity.is_some() {
            v.push("gravity");
        }
        if self.contact {
            v.push("contact");
        }
        if self.friction {
            v.push("friction");
        }
        if self.damping.is_some() {
            v.push("damping");
        }
        if self.rotation {
            v.push("rotation");
        }
        v
    }
}

/// A parsed scene: the initial world and how to run it.
#[derive(Debug, Clone)]
pub struct Scene {
    pub world: World,
    pub effects: Effects,
    pub dt: f64,
    pub end_time: f64,
    pub output_every: u64,
    /// The largest stable step for this scene's stiffest contact and lightest particle.
    pub stable_dt: Option<f64>,
    pub kernel: Options,
    /// Set when the step exceeds the stable one and the scene allowed it.
    pub warnings: Vec<String>,
    pub parallel: Parallel,
    /// Per body, the line of the scene file that placed it (for messages).
    pub body_lines: Vec<usize>,
    /// The scene allows bodies to overlap at the start and contacts to stay
    /// deeper than the halos (`simulation.allow_deep_contacts`).
    pub allow_deep_contacts: bool,
}

/// Steps at most, however long `end_time / dt` is: a typo in either cannot
/// ask for a run of centuries.
pub const MAX_STEPS: u64 = 1 << 40;

/// Particles a scene may place at most: each costs its triangles and their
/// per-thread copies; beyond this a scene asks for more than any machine of
/// ours holds.
pub const MAX_PARTICLES: usize = 10_000_000;

impl Scene {
    /// Where body `i` comes from, for messages: "body 3 (line 31)".
    pub fn body_name(&self, i: usize) -> String {
        match self.body_lines.get(i) {
            Some(&line) if line > 0 => format!("body {i} (line {line})"),
            _ => format!("body {i}"),
        }
    }
}

struct Ctx<'a> {
    file: String,
    text: &'a str,
    dir: PathBuf,
}

impl Ctx<'_> {
    fn line_of(&self, offset: usize) -> usize {
        self.text[..offset.min(self.text.len())]
            .matches('\n')
            .count()
            + 1
    }
    fn err<T>(
        &self,
        span: std::ops::Range<usize>,
        cause: impl Into<String>,
    ) -> Result<T, SceneError> {
        Err(SceneError {
            file: self.file.clone(),
            line: self.line_of(span.start),
            cause: cause.into(),
        })
    }
}

impl Scene {
    /// Reads and builds a scene file.
    pub fn load(path: &Path) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: path.display().to_string(),
            line: 0,
            cause: format!("cannot read the scene: {e}"),
        })?;
        Scene::parse(
            &text,
            &path.display().to_string(),
            path.parent().unwrap_or(Path::new(".")),
        )
    }

    /// Reads a scene file with `overrides` set over it, each
    /// `section.key=value` with a TOML value (a bare word is a string), as
    /// `tridem run --set kernel.schedule=dynamic` does. The file is checked
    /// as written first, so its own errors name its lines.
    pub fn load_with(path: &Path, overrides: &[String]) -> Result<Scene, SceneError> {
        let scene = Scene::load(path)?;
        if overrides.is_empty() {
            return Ok(scene);
        }
        let file = format!("{} with --set {}", path.display(), overrides.join(" "));
        let err = |cause: String| SceneError {
            file: file.clone(),
            line: 0,
            cause,
        };
        let text = std::fs::read_to_string(path).map_err(|e| err(e.to_string()))?;
        let mut table: toml::Table = text
            .parse()
            .map_err(|e: toml::de::Error| err(e.to_string()))?;
        for o in overrides {
            set_override(&mut table, o).map_err(err)?;
        }
        let text = toml::to_string(&table).map_err(|e| err(e.to_string()))?;
        Scene::parse(&text, &file, path.parent().unwrap_or(Path::new(".")))
            .map_err(|e| err(e.cause))
    }

    /// Builds a scene from TOML text; `file` names it in errors and `dir`
    /// resolves relative mesh paths.
    pub fn parse(text: &str, file: &str, dir: &Path) -> Result<Scene, SceneError> {
        let ctx = Ctx {
            file: file.to_string(),
            text,
            dir: dir.to_path_buf(),
        };
        let spec: SceneFile = toml::from_str(text).map_err(|e| SceneError {
            file: file.to_string(),
            line: e.span().map_or(0, |s| ctx.line_of(s.start)),
            cause: e.message().to_string(),
        })?;
        refuse_non_finite(&ctx)?;
        build(&ctx, spec)
    }
}

/// No number of a scene may be NaN or infinite (TOML writes them `nan`,
/// `inf`): refused where written, naming the key, before anything is built
/// from it. The text has parsed as TOML, so outside strings and comments
/// these words can only be values.
fn refuse_non_finite(ctx: &Ctx) -> Result<(), SceneError> {
    let mut offset = 0;
    let mut key = String::new();
    for line in ctx.text.split_inclusive('\n') {
        let code = strip_strings_and_comment(line);
        if code.trim_start().starts_with('[') && !code.contains('=') {
            offset += line.len();
            continue;
        }
        // Keys of the inline tables the value sits in ("contact.skin").
        let mut tables: Vec<String> = Vec::new();
        let parts = code.split('=').count();
        for (i, part) in code.split('=').enumerate() {
            // The last part is all value; the others end with the next key.
            let next_key = if i + 1 == parts {
                String::new()
            } else {
                part.trim_end()
                    .rsplit(|c: char| c.is_whitespace() || ",{[".contains(c))
                    .next()
                    .unwrap_or("")
                    .to_string()
            };
            let value = if i == 0 {
                ""
            } else {
                &part[..part.trim_end().len() - next_key.len()]
            };
            let bad = value
                .split(|c: char| c.is_whitespace() || ",[]{}".contains(c))
                .find(|w| matches!(w.trim_start_matches(['+', '-']), "nan" | "inf"));
            if let Some(word) = bad {
                let path: Vec<&str> = tables
                    .iter()
                    .map(String::as_str)
                    .chain([key.as_str()])
                    .collect();
                return ctx.err(
                    offset..offset + line.len(),
                    format!(
                        "{} = {word}: every number of a scene must be finite",
                        path.join(".")
                    ),
                );
            }
            if i > 0 && value.trim_start().starts_with('{') {
                tables.push(key.clone());
            }
            for _ in 0..value.matches('}').count() {
                tables.pop();
            }
            if !next_key.is_empty() {
                key = next_key;
            }
        }
        offset += line.len();
    }
    Ok(())
}

/// A line of TOML with its strings blanked and its comment cut.
fn strip_strings_and_comment(line: &str) -> String {
    let mut out = String::with_capacity(line.len());
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for c in line.chars() {
        match quote {
            Some(q) => {
                if c == q && !escaped {
                    quote = None;
                }
                escaped = c == '\\' && !escaped && q == '"';
                out.push(' ');
            }
            None if c == '"' || c == '\'' => {
                quote = Some(c);
                out.push(' ');
            }
            None if c == '#' => break,
            None => out.push(c),
        }
    }
    out
}

/// Sets one `section.key=value` of `--set` in a scene's table.
fn set_override(table: &mut toml::Table, o: &str) -> Result<(), String> {
    let (path, value) = o
        .split_once('=')
        .ok_or_else(|| format!("--set {o}: expected section.key=value"))?;
    let keys: Vec<&str> = path.trim().split('.').map(str::trim).collect();
    if keys.len() < 2 || keys.iter().any(|k| k.is_empty()) {
        return Err(format!("--set {o}: expected section.key=value"));
    }
    let value = value.trim();
    let value = format!("v = {value}")
        .parse::<toml::Table>()
        .ok()
        .and_then(|mut t| t.remove("v"))
        .unwrap_or_else(|| toml::Value::String(value.to_string()));
    let (last, sections) = keys.split_last().expect("two keys or more");
    let mut at = table;
    for k in sections {
        let entry = at
            .entry(k.to_string())
            .or_insert_with(|| toml::Value::Table(toml::Table::new()));
        at = entry.as_table_mut().ok_or_else(|| {
            format!("--set {o}: {k} is not a section (lists of bodies cannot be set)")
        })?;
    }
    at.insert(last.to_string(), value);
    Ok(())
}

fn positive(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    what: &str,
    x: f64,
) -> Result<f64, SceneError> {
    if x.is_finite() && x > 0.0 {
        Ok(x)
    } else {
        ctx.err(
            span,
            format!("{what} must be a positive finite number, got {x}"),
        )
    }
}

fn build(ctx: &Ctx, spec: SceneFile) -> Result<Scene, SceneError> {
    let sim_span = spec.simulation.span();
    let sim = spec.simulation.into_inner();
    let dt = positive(ctx, sim_span.clone(), "simulation.dt", sim.dt)?;
    let end_time = positive(ctx, sim_span.clone(), "simulation.end_time", sim.end_time)?;
    if sim.output_every == 0 {
        return ctx.err(sim_span, "simulation.output_every must be at least 1");
    }
    if end_time < dt {
        return ctx.err(
            sim_span,
            format!(
                "simulation.end_time ({end_time:e} s) is shorter than one step (dt = {dt:e} s)"
            ),
        );
    }
    if end_time / dt > MAX_STEPS as f64 {
        return ctx.err(
            sim_span,
            format!(
                "simulation.end_time / dt = {:.3e} steps, more than the {MAX_STEPS} a run may take",
                end_time / dt
            ),
        );
    }
    let eff_span = spec.effects.span();
    let e = spec.effects.into_inner();
    if e.friction.is_some() && e.contact.is_none() {
        return ctx.err(eff_span, "the friction effect needs the contact effect");
    }
    let effects = Effects {
        gravity: match e.gravity {
            Some(g) => {
                let g = DVec3::from_array(g.g);
                if !g.is_finite() {
                    return ctx.err(eff_span, "gravity.g must be finite");
                }
                Some(g)
            }
            None => None,
        },
        contact: e.contact.is_some(),
        contact_skin: match &e.contact {
            Some(c) if c.skin >= 0.0 && c.skin.is_finite() => c.skin,
            Some(c) => {
                return ctx.err(
                    eff_span,
                    format!(
                        "contact.skin must be a finite length >= 0 (m), got {}",
                        c.skin
                    ),
                )
            }
            None => 0.0,
        },
        friction: e.friction.is_some(),
        damping: match e.damping {
            Some(d)
                if d.linear >= 0.0
                    && d.angular >= 0.0
                    && d.linear.is_finite()
                    && d.angular.is_finite() =>
            {
                Some((d.linear, d.angular))
            }
            Some(_) => return ctx.err(eff_span, "damping rates must be finite and non-negative"),
            None => None,
        },
        rotation: e.rotation.is_some(),
    };

    // Materials: parameters only for declared effects, and all those effects need.
    let mut materials = Vec::new();
    for m in &spec.materials {
        let span = m.span();
        let m = m.get_ref();
        let name = &m.name;
        if materials.iter().any(|x: &Material| &x.name == name) {
            return ctx.err(span, format!("material `{name}` is defined twice"));
        }
        positive(
            ctx,
            span.clone(),
            &format!("material `{name}`: density"),
            m.density,
        )?;
        let contact_params = [
            ("stiffness", m.stiffness),
            ("restitution", m.restitution),
            ("halo", m.halo),
        ];
        for (p, v) in contact_params {
            match (effects.contact, v) {
                (false, Some(_)) => {
                    return ctx.err(span, format!("material `{name}` sets `{p}`, but the scene does not declare the contact effect"))
                }
                (true, None) => return ctx.err(span, format!("material `{name}` needs `{p}` for the contact effect")),
                (true, Some(x)) => {
                    positive(ctx, span.clone(), &format!("material `{name}`: {p}"), x)?;
                }
                (false, None) => {}
            }
        }
        if let Some(e) = m.restitution {
            if e > 1.0 {
                return ctx.err(
                    span,
                    format!("material `{name}`: restitution must be in (0, 1], got {e}"),
                );
            }
        }
        match (effects.friction, m.friction) {
            (false, Some(_)) => {
                return ctx.err(span, format!("material `{name}` sets `friction`, but the scene does not declare the friction effect"))
            }
            (true, None) => return ctx.err(span, format!("material `{name}` needs `friction` for the friction effect")),
            (true, Some(mu)) if !(mu.is_finite() && mu >= 0.0) => {
                return ctx.err(span, format!("material `{name}`: friction must be finite and non-negative"))
            }
            _ => {}
        }
        materials.push(Material {
            name: name.clone(),
            density: m.density,
            stiffness: m.stiffness,
            restitution: m.restitution,
            halo: m.halo,
            friction: m.friction,
        });
    }
    let material_index = |span: std::ops::Range<usize>, name: &str| -> Result<usize, SceneError> {
        materials
            .iter()
            .position(|m| m.name == name)
            .map_or_else(|| ctx.err(span, format!("unknown material `{name}`")), Ok)
    };

    let mut world = World {
        materials: materials.clone(),
        ..World::default()
    };
    let mut body_lines = Vec::new();
    let mut warnings = Vec::new();
    for p in &spec.particles {
        let span = p.span();
        let p = p.get_ref();
        let mat = material_index(span.clone(), &p.material)?;
        let mesh = make_shape(ctx, span.clone(), &p.shape)?;
        let props = MassProperties::of(&mesh, materials[mat].density);
        let local = mesh.translated(-props.centroid);
        let shape = world.shapes.len();
        world.shapes.push(local.clone());
        let inv_inertia = props.inertia.inverse();
        if !inv_inertia.is_finite() {
            return ctx.err(span, "particle shape has a singular inertia tensor");
        }
        let radius = local
            .vertices
            .iter()
            .map(|v| v.length())
            .fold(0.0, f64::max);
        let thickness = smallest_extent(&local);
        let halo = materials[mat].halo.unwrap_or(0.0);
        if halo > thickness / 2.0 {
            return ctx.err(
                span,
                format!(
                    "material `{}`: the halo ({halo:e} m) is more than half the particle's \
                     smallest extent ({thickness:e} m): contacts would act from further away \
                     than the particle is thick",
                    p.material
                ),
            );
        }
        let positions = placements(
            ctx,
            span.clone(),
            &p.placement,
            radius,
            local.triangles.len(),
        )?;
        if world.bodies.len() + positions.len() > MAX_PARTICLES {
            return ctx.err(
                span,
                format!("the scene places more than the {MAX_PARTICLES} particles a scene may"),
            );
        }
        let mut rng = Xoshiro256PlusPlus::seed_from_u64(0x5eed);
        for pos in positions {
            let mut q = match p.orientation.as_deref() {
                None | Some("identity") => DQuat::IDENTITY,
                Some("random") => random_rotation(&mut rng),
                Some(o) => {
                    return ctx.err(
                        span,
                        format!("orientation must be `identity` or `random`, got `{o}`"),
                    )
                }
            };
            if let Some(r) = p.rotation {
                q = crate::integrate::exp_map(DVec3::from_array(r)) * q;
            }
            let omega = DVec3::from_array(p.angular_velocity);
            let inertia_world =
                DMat3::from_quat(q) * props.inertia * DMat3::from_quat(q).transpose();
            let body = Body {
                shape,
                material: mat,
                x: DVec3::from_array(pos),
                q,
                v: DVec3::from_array(p.velocity),
                l: inertia_world * omega,
                inv_mass: 1.0 / props.mass,
                mass: props.mass,
                inv_inertia_body: inv_inertia,
                inertia_body: props.inertia,
            };
            check_motion(
                ctx,
                span.clone(),
                &body,
                omega,
                dt,
                thickness,
                &mut warnings,
            )?;
            world.bodies.push(body);
            body_lines.push(ctx.line_of(span.start));
        }
    }
    for o in &spec.obstacles {
        let span = o.span();
        let o = o.get_ref();
        let mat = material_index(span.clone(), &o.material)?;
        let mesh = make_shape(ctx, span.clone(), &o.shape)?;
        let q = o.rotation.map_or(DQuat::IDENTITY, |r| {
            crate::integrate::exp_map(DVec3::from_array(r))
        });
        world.shapes.push(mesh);
        world.bodies.push(Body {
            shape: world.shapes.len() - 1,
            material: mat,
            x: DVec3::from_array(o.position),
            q,
            v: DVec3::ZERO,
            l: DVec3::ZERO,
            inv_mass: 0.0,
            mass: f64::INFINITY,
            inv_inertia_body: DMat3::ZERO,
            inertia_body: DMat3::ZERO,
        });
        body_lines.push(ctx.line_of(span.start));
    }
    if world.dynamic_count() == 0 {
        return ctx.err(0..0, "the scene has no particles");
    }

    let kernel = match spec.kernel {
        None => Options::default(),
        Some(k) => {
            let span = k.span();
            let k = k.into_inner();
            let method: Method = k
                .method
                .parse()
                .map_or_else(|e| ctx.err(span.clone(), e), Ok)?;
            let schedule: Schedule = k
                .schedule
                .parse()
                .map_or_else(|e| ctx.err(span.clone(), e), Ok)?;
            if !crate::distance::penalty::BATCH_SIZES.contains(&k.batch) {
                return ctx.err(
                    span,
                    format!(
                        "kernel.batch must be one of 1, 2, 4, 8, 16, 32, 64, got {}",
                        k.batch
                    ),
                );
            }
            if k.grain == 0 {
                return ctx.err(span, "kernel.grain must be at least 1");
            }
            let mut penalty = PenaltyParams::default();
            if method == Method::Brute
                && (k.iterations.is_some() || k.finish_rounds.is_some() || k.tolerance.is_some())
            {
                return ctx.err(
                    span,
                    "kernel.iterations, kernel.finish_rounds and kernel.tolerance set the \
                     penalty kernel, which method = \"brute\" does not run",
                );
            }
            if let Some(tol) = k.tolerance {
                // Below a few ulps nothing is ever certified; at 1e-2 an
                // answer may be 1% of the pair's size off.
                if !(1e-15..=1e-2).contains(&tol) {
                    return ctx.err(
                        span,
                        format!("kernel.tolerance must be between 1e-15 and 1e-2, got {tol}"),
                    );
                }
                penalty.tol = tol;
            }
            if let Some(n) = k.iterations {
                // Per-pair iteration counts are reported in a byte.
                if !(1..=MAX_ITERATIONS).contains(&n) {
                    return ctx.err(
                        span,
                        format!(
                            "kernel.iterations must be between 1 and {MAX_ITERATIONS}, got {n}"
                        ),
                    );
                }
                penalty.max_iterations = n;
            }
            if let Some(n) = k.finish_rounds {
                if n > MAX_FINISH_ROUNDS {
                    return ctx.err(
                        span,
                        format!("kernel.finish_rounds must be between 0 and {MAX_FINISH_ROUNDS}, got {n}"),
                    );
                }
                penalty.finish_rounds = n;
            }
            Options {
                method,
                batch: k.batch,
                penalty,
                fallback: if k.fallback_failed_pairs {
                    Fallback::FailedPairs
                } else {
                    Fallback::WholeBatch
                },
                threading: Threading {
                    schedule,
                    grain: k.grain,
                },
            }
        }
    };

    // Stable step: ω = √(k/m*) for the stiffest pair of materials that can meet
    // (springs in series) and the lightest reduced mass (half the lightest
    // particle), h = (2/ω)(√(1 + ζ²) − ζ) with the largest damping ratio.
    let stable_dt = if effects.contact {
        let mut used_by_particles = vec![false; materials.len()];
        let mut used = vec![false; materials.len()];
        for b in &world.bodies {
            used[b.material] = true;
            used_by_particles[b.material] |= !b.is_static();
        }
        let mut k_max = 0.0f64;
        for (_, mi) in materials
            .iter()
            .enumerate()
            .filter(|(i, _)| used_by_particles[*i])
        {
            for (_, mj) in materials.iter().enumerate().filter(|(j, _)| used[*j]) {
                let (ki, kj) = (mi.stiffness.unwrap_or(0.0), mj.stiffness.unwrap_or(0.0));
                k_max = k_max.max(ki * kj / (ki + kj));
            }
        }
        let zeta = materials
            .iter()
            .filter_map(|m| m.restitution)
            .map(damping_ratio)
            .fold(0.0, f64::max);
        let m_min = world
            .bodies
            .iter()
            .filter(|b| !b.is_static())
            .map(|b| b.mass)
            .fold(f64::INFINITY, f64::min);
        let omega = (k_max / (0.5 * m_min)).sqrt();
        Some(2.0 / omega * ((1.0 + zeta * zeta).sqrt() - zeta))
    } else {
        None
    };
    if let Some(h) = stable_dt {
        if dt > h {
            let msg = format!("simulation.dt = {dt:e} s is above the stable step {h:e} s (stiffest contact pair, lightest particle)");
            if sim.allow_unstable_dt {
                warnings.push(msg);
            } else {
                return ctx.err(
                    sim_span,
                    format!("{msg}; lower dt or set allow_unstable_dt = true"),
                );
            }
        }
    }
    let parallel = match spec.parallel {
        None => Parallel::default(),
        Some(p) => {
            let span = p.span();
            let p = p.into_inner();
            let known = |name: &Option<String>, list: &[&str]| {
                name.as_ref().is_none_or(|n| list.contains(&n.as_str()))
            };
            if !known(&p.partitioner, &PARTITIONERS) {
                return ctx.err(
                    span,
                    format!(
                        "parallel.partitioner `{}` is none of {}",
                        p.partitioner.unwrap_or_default(),
                        PARTITIONERS.join(", ")
                    ),
                );
            }
            if !known(&p.exchange, &EXCHANGES) {
                return ctx.err(
                    span,
                    format!(
                        "parallel.exchange `{}` is none of {}",
                        p.exchange.unwrap_or_default(),
                        EXCHANGES.join(", ")
                    ),
                );
            }
            p
        }
    };
    Ok(Scene {
        world,
        effects,
        dt,
        end_time,
        output_every: sim.output_every,
        stable_dt,
        kernel,
        warnings,
        parallel,
        body_lines,
        allow_deep_contacts: sim.allow_deep_contacts,
    })
}

/// The smallest side of a shape's box in its own frame: how thick it is.
fn smallest_extent(mesh: &TriMesh) -> f64 {
    let (lo, hi) = mesh.vertices.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), &v| (lo.min(v), hi.max(v)),
    );
    (hi - lo).min_element()
}

/// A particle's initial motion must be a number the integrator can carry:
/// its kinetic energy finite (a velocity of 1e200 m/s squares to infinity).
/// One that crosses half its own thickness in a step can pass through a
/// wall between two detections: warned.
fn check_motion(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    b: &Body,
    omega: DVec3,
    dt: f64,
    thickness: f64,
    warnings: &mut Vec<String>,
) -> Result<(), SceneError> {
    let energy = 0.5 * b.mass * b.v.length_squared() + 0.5 * omega.dot(b.l);
    if !(energy.is_finite() && b.l.is_finite() && b.q.is_finite() && b.x.is_finite()) {
        return ctx.err(
            span,
            format!(
                "particle: velocity [{:e}, {:e}, {:e}] m/s and angular velocity \
                 [{:e}, {:e}, {:e}] rad/s give a kinetic energy of {energy:e} J, \
                 which is not a finite number",
                b.v.x, b.v.y, b.v.z, omega.x, omega.y, omega.z
            ),
        );
    }
    let travel = b.v.length() * dt;
    if travel > thickness / 2.0 {
        warnings.push(format!(
            "{}:{}: a particle moves {travel:e} m in one step, more than half its thickness \
             ({thickness:e} m): it can pass through walls and other particles between two \
             detections; lower dt or the speed",
            ctx.file,
            ctx.line_of(span.start)
        ));
    }
    Ok(())
}

fn make_shape(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    s: &ShapeSpec,
) -> Result<TriMesh, SceneError> {
    match s {
        ShapeSpec::Hull {
            triangles,
            radius,
            seed,
        } => {
            let r = positive(ctx, span.clone(), "shape.radius", *radius)?;
            if *triangles < 4 || triangles % 2 != 0 {
                return ctx.err(
                    span,
                    format!("a hull needs an even number of triangles >= 4, got {triangles}"),
                );
            }
            if *triangles > MAX_HULL_TRIANGLES {
                return ctx.err(
                    span,
                    format!(
                        "a hull of {triangles} triangles is more than the {MAX_HULL_TRIANGLES} \
                         a scene may ask for (about {:.0} GB per particle)",
                        *triangles as f64 * BYTES_PER_TRIANGLE / 1e9
                    ),
                );
            }
            Ok(sphere_hull(*triangles, r, *seed))
        }
        ShapeSpec::Box { size, subdivide } => {
            for (k, &x) in size.iter().enumerate() {
                positive(ctx, span.clone(), &format!("shape.size[{k}]"), x)?;
            }
            if *subdivide > MAX_SUBDIVIDE {
                return ctx.err(
                    span,
                    format!(
                        "shape.subdivide must be between 0 and {MAX_SUBDIVIDE}, got {subdivide}"
                    ),
                );
            }
            Ok(subdivided(&box_mesh(DVec3::from_array(*size)), *subdivide))
        }
        ShapeSpec::Tetrahedron { radius } => {
            Ok(tetrahedron(positive(ctx, span, "shape.radius", *radius)?))
        }
        ShapeSpec::Mesh { file, scale } => {
            let path = if file.is_absolute() {
                file.clone()
            } else {
                ctx.dir.join(file)
            };
            let s = positive(ctx, span.clone(), "shape.scale", *scale)?;
            load_mesh(&path)
                .map(|m| m.scaled(s))
                .or_else(|e| ctx.err(span, e.to_string()))
        }
    }
}

/// Bytes a particle's triangle takes in a run, about: the world-space copy
/// and its box, per-thread copies, the broad phase's entries, the output.
const BYTES_PER_TRIANGLE: f64 = 400.0;

fn placements(
    ctx: &Ctx,
    span: std::ops::Range<usize>,
    p: &PlacementSpec,
    radius: f64,
    triangles: usize,
) -> Result<Vec<[f64; 3]>, SceneError> {
    let count = match p {
        PlacementSpec::Single { .. } => 1.0,
        PlacementSpec::Lattice { count, .. } => count.iter().map(|&c| c as f64).product(),
        PlacementSpec::Random { count, .. } => *count as f64,
    };
    if count > MAX_PARTICLES as f64 {
        return ctx.err(
            span,
            format!(
                "{count:e} particles is more than the {MAX_PARTICLES} a scene may place \
                 (at {triangles} triangles each they would need about {:.0} GB)",
                count * triangles as f64 * BYTES_PER_TRIANGLE / 1e9
            ),
        );
    }
    match p {
        PlacementSpec::Single { position } => Ok(vec![*position]),
        PlacementSpec::Lattice {
            count,
            spacing,
            origin,
        } => {
            let s = positive(ctx, span.clone(), "placement.spacing", *spacing)?;
            if s < 2.0 * radius {
                return ctx.err(
                    span,
                    format!(
                        "placement.spacing {s} is below the particle diameter {}",
                        2.0 * radius
                    ),
                );
            }
            let mut v = Vec::new();
            for k in 0..count[2] {
                for j in 0..count[1] {
                    for i in 0..count[0] {
                        v.push([
                            origin[0] + i as f64 * s,
                            origin[1] + j as f64 * s,
                            origin[2] + k as f64 * s,
                        ]);
                    }
                }
            }
            Ok(v)
        }
        PlacementSpec::Random {
            count,
            lo,
            hi,
            seed,
        } => {
            // Random sequential packing: reject positions closer than a diameter.
            let mut rng = Xoshiro256PlusPlus::seed_from_u64(*seed);
            let mut v: Vec<[f64; 3]> = Vec::with_capacity(*count);
            let mut tries = 0usize;
            while v.len() < *count {
                tries += 1;
                if tries > 1000 * count.max(&1) {
                    return ctx.err(
                        span,
                        format!(
                            "could place only {} of {count} particles without overlap in the box",
                            v.len()
                        ),
                    );
                }
                let p = [0, 1, 2].map(|k| {
                    lo[k] + radius + (hi[k] - lo[k] - 2.0 * radius).max(0.0) * rng.random::<f64>()
                });
                let ok = v.iter().all(|o| {
                    (0..3).map(|k| (o[k] - p[k]).powi(2)).sum::<f64>() >= (2.0 * radius).powi(2)
                });
                if ok {
                    v.push(p);
                }
            }
            Ok(v)
        }
    }
}

fn random_rotation(rng: &mut Xoshiro256PlusPlus) -> DQuat {
    // Shoemake's uniform random unit quaternion.
    let (u1, u2, u3): (f64, f64, f64) = (rng.random(), rng.random(), rng.random());
    let tau = 2.0 * std::f64::consts::PI;
    DQuat::from_xyzw(
        (1.0 - u1).sqrt() * (tau * u2).sin(),
        (1.0 - u1).sqrt() * (tau * u2).cos(),
        u1.sqrt() * (tau * u3).sin(),
        u1.sqrt() * (tau * u3).cos(),
    )
    .normalize()
}
