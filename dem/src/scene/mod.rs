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
//! # or a drum's shell along y: { kind = "tube", inner_radius = 0.07,
//! #   thickness = 0.005, length = 0.045, segments = 48 }
//! position = [0.0, 0.0, -0.005]
//! # velocity = [0.02, 0.0, 0.0]         # a moving wall (m/s, of `position`), and
//! # angular_velocity = [0.0, 0.0, 1.0]  # its turn about `position` (rad/s): both
//! #                                     # need `wall_motion = {}` in [effects]
//! # velocity_table = [[0.0, 0.0, 0.0, 0.0], [0.5, 0.02, 0.0, 0.0]]
//! #                  # or tables of [t, x, y, z]: linear between rows, held
//! #                  # beyond them (angular_velocity_table: rows parallel)
//! # remove_at = 0.5  # gone from t = 0.5 s on: no contact with it after
//!
//! [kernel]               # contact detection (docs/dem.md, docs/distance.md)
//! method = "hybrid"      # brute, penalty or hybrid
//! fallback_failed_pairs = true
//! schedule = "guided"    # static, dynamic or guided
//! # batch = 8, grain, iterations = 4, finish_rounds = 1, tolerance = 1e-13
//!
//! [parallel]             # under mpirun (the command line wins)
//! partitioner = "zoltan-rcb"   # `tridem partition --list` lists them
//! repartition_every = 100      # steps (0: only at the start)
//! # repartition_when = 1.2     # or when the busy time's max/mean exceeds this
//! exchange = "nonblocking"     # or "blocking"
//! weights = "pairs"            # triangles, pairs or time (docs/distributed.md)
//!
//! [output]               # what an output step writes besides the states
//! fields = ["surface", "particles", "contacts"]   # the default (docs/output.md)
//! ```

mod build;
pub mod census;
mod shapes;
mod spec;
mod text;

pub use build::MAX_FINISH_ROUNDS;

use crate::distance::Options;
pub use crate::effects::Effects;
use crate::world::World;
pub use census::Census;
use serde::Deserialize;
use std::path::{Path, PathBuf};

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

/// How a run under mpirun is split (`[parallel]`), names as the command
/// line takes them. The names are read here and checked by the crates that
/// own them (partitioners, exchanges, weights), each against its own list,
/// with `line` to say where.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Parallel {
    pub partitioner: Option<String>,
    pub repartition_every: Option<u64>,
    pub repartition_when: Option<f64>,
    pub exchange: Option<String>,
    pub weights: Option<String>,
    /// The line of `[parallel]` in the scene file (0: none).
    #[serde(skip)]
    pub line: usize,
}

/// What each output step writes besides the bodies' states and the energy
/// books (`[output]`), by name as the scene gives them: the output's writer
/// owns the names and checks them, naming `line`.
#[derive(Debug, Clone, Default, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OutputSection {
    /// `None`: every field.
    pub fields: Option<Vec<String>>,
    /// The line of `[output]` in the scene file (0: none).
    #[serde(skip)]
    pub line: usize,
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
    /// The largest step that resolves a particle's rocking on its corners
    /// (with rotation): above it a body at rest keeps rattling and creeps.
    pub rocking_dt: Option<f64>,
    pub kernel: Options,
    /// Set when the step exceeds the stable one and the scene allowed it.
    pub warnings: Vec<String>,
    pub parallel: Parallel,
    pub output: OutputSection,
    /// The whole scene's bodies in brief, however few of them `world` holds.
    pub census: Census,
    /// Which of the scene's particles `world` holds.
    pub deal: Deal,
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

/// Which of a scene's particles a rank keeps when it loads the scene: the
/// k-th particle (id k) goes to rank k mod `ranks`; every rank keeps every
/// obstacle. [`Deal::WHOLE`] keeps everything.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Deal {
    pub rank: u32,
    pub ranks: u32,
}

impl Deal {
    /// The whole scene, as one process runs it.
    pub const WHOLE: Deal = Deal { rank: 0, ranks: 1 };

    /// The rank particle `id` is dealt to.
    pub fn rank_of(&self, id: u32) -> u32 {
        id % self.ranks
    }

    pub fn keeps(&self, id: u32) -> bool {
        self.rank_of(id) == self.rank
    }
}

impl Scene {
    /// Where body `i` comes from, for messages: "body 3 (line 31)".
    pub fn body_name(&self, i: usize) -> String {
        match self.census.run_of(i) {
            Some(r) if r.line > 0 => format!("body {i} (line {})", r.line),
            _ => format!("body {i}"),
        }
    }

    /// A digest of what a run cannot change: `World::fingerprint` of the
    /// whole scene, however much of it `world` holds. A world holding the
    /// whole scene is digested as it stands (a program may have edited it
    /// since it was loaded); a rank's share, from the census.
    pub fn fingerprint(&self) -> u64 {
        if self.deal == Deal::WHOLE {
            return self.world.fingerprint();
        }
        let mut h = self.world.fingerprint_head();
        self.census.hash_bodies(&mut h);
        h.0
    }

    /// Triangles of all the scene's particles.
    pub fn particle_triangles(&self) -> usize {
        let shapes = &self.world.shapes;
        self.census
            .particle_triangles(|s| shapes[s].triangles.len())
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
        Scene::load_dealt(path, Deal::WHOLE)
    }

    /// Reads a scene file, keeping only `deal`'s particles.
    pub fn load_dealt(path: &Path, deal: Deal) -> Result<Scene, SceneError> {
        let text = std::fs::read_to_string(path).map_err(|e| SceneError {
            file: path.display().to_string(),
            line: 0,
            cause: format!("cannot read the scene: {e}"),
        })?;
        Scene::parse_dealt(
            &text,
            &path.display().to_string(),
            path.parent().unwrap_or(Path::new(".")),
            deal,
        )
    }

    /// Reads a scene file with `overrides` set over it, each
    /// `section.key=value` with a TOML value (a bare word is a string), as
    /// `tridem run --set kernel.schedule=dynamic` does. The file is checked
    /// as written first, so its own errors name its lines.
    pub fn load_with(path: &Path, overrides: &[String]) -> Result<Scene, SceneError> {
        Scene::load_dealt_with(path, overrides, Deal::WHOLE)
    }

    /// [`Scene::load_with`], keeping only `deal`'s particles.
    pub fn load_dealt_with(
        path: &Path,
        overrides: &[String],
        deal: Deal,
    ) -> Result<Scene, SceneError> {
        let scene = Scene::load_dealt(path, deal)?;
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
            text::set_override(&mut table, o).map_err(err)?;
        }
        let text = toml::to_string(&table).map_err(|e| err(e.to_string()))?;
        Scene::parse_dealt(&text, &file, path.parent().unwrap_or(Path::new(".")), deal)
            .map_err(|e| err(e.cause))
    }

    /// Builds a scene from TOML text; `file` names it in errors and `dir`
    /// resolves relative mesh paths.
    pub fn parse(text: &str, file: &str, dir: &Path) -> Result<Scene, SceneError> {
        Scene::parse_dealt(text, file, dir, Deal::WHOLE)
    }

    /// [`Scene::parse`], keeping only `deal`'s particles.
    pub fn parse_dealt(
        text: &str,
        file: &str,
        dir: &Path,
        deal: Deal,
    ) -> Result<Scene, SceneError> {
        let ctx = Ctx {
            file: file.to_string(),
            text,
            dir: dir.to_path_buf(),
        };
        let spec: spec::SceneFile = toml::from_str(text).map_err(|e| SceneError {
            file: file.to_string(),
            line: e.span().map_or(0, |s| ctx.line_of(s.start)),
            cause: e.message().to_string(),
        })?;
        text::refuse_non_finite(&ctx)?;
        build::build(&ctx, spec, deal)
    }
}

/// `x`, if it is a positive finite number; else the error naming `what`.
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
