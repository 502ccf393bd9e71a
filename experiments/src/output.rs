//! Simulation output: one HDF5 file per run with a group per output step, the
//! meshes and the surface's connectivity once, and an XDMF sidecar so that
//! ParaView opens it directly.
//!
//! Layout of `DIR/run.h5` (SI units; docs/output.md has the whole table):
//! - written once: `/shapes/<s>/vertices` (V×3, body frame) and
//!   `/shapes/<s>/triangles` (T×3); `/surface/{triangles (T×3), body (T),
//!   material (T)}`, every body's mesh with its vertices numbered body after
//!   body as in each step's `surface/points`; `/bodies/{material, mass,
//!   obstacle}` (N; mass 0 for obstacles); `/materials` (an attribute per
//!   material, its index).
//! - `/steps/<k>/{positions, velocities, angular_momenta, angular_velocities}`
//!   (N×3), `orientations` (N×4, xyzw), `speeds`, `kinetic_translation`,
//!   `kinetic_rotation` (N), `contacts` (N, contacts per body), `time`
//!   (attribute).
//! - `/steps/<k>/energy`: attributes `kinetic_translation`, `kinetic_rotation`, and per
//!   effect `<effect>_stored` (gravity's potential, springs) and `<effect>_dissipated`
//!   (work of dashpots, sliding and damping since the start), in J: their sum is constant
//!   up to the integrator's error.
//! - `/steps/<k>/probes`: attributes, what the `probes` effect measured (if declared).
//! - `/steps/<k>/contact_forces/`: per contact (C) its `points`, `forces` (on the first
//!   body; the second takes the opposite), `normal_forces`, `tangential_forces` (C×3),
//!   `normal_force_magnitudes`, `overlaps`, `slides` (C), `bodies` (C×2); and the contact
//!   network's `line_points` (2C×3) and `lines` (C×2); `point_index` (C), 0..C, the
//!   contact points' connectivity.
//! - `/steps/<k>/surface/points` (V×3): every body's mesh vertices where the body stands.
//!
//! The XDMF file `DIR/run.xmf` holds four temporal collections, which ParaView
//! opens directly: `surface` (the meshes, cells by body and material),
//! `particles` (a point per body with its motion, mass, material and
//! coordination number), `contacts` (a line per contact between the bodies'
//! centres, with its forces and overlap: the force network) and
//! `contact_points` (the contact points with their force, for glyphs).
//!
//! The scene's `[output] fields` chooses what a step writes besides the
//! states (positions, velocities, angular momenta, orientations, contacts per
//! body) and the energy books, which are always written: `surface` (the
//! surface's points per step, the connectivity once, the `surface` grid),
//! `particles` (the per-body motion fields and the `particles` grid) and
//! `contacts` (`contact_forces` and the two contact grids). All three by
//! default; the file's root attribute `fields` lists those written.
//!
//! Each step is written and flushed as it is produced, so a run stopped early
//! keeps everything written before; a run resumed from a checkpoint goes on
//! appending to the same file. What is written is a [`Frame`]: one process
//! and a run split across ranks write the same bytes.

use crate::error::{create_output_dir, CliError, CliResult};
use dem::frame::Frame;
use dem::mesh::TriMesh;
use dem::scene::census::Run;
use dem::scene::{Census, Scene};
use ndarray::{Array1, Array2};
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// An exclusive lock on an output directory, held while a run writes it:
/// a second run into the directory is refused before it changes anything.
/// The lock file goes when the lock does.
pub struct DirLock {
    file: std::fs::File,
    path: PathBuf,
}

impl Drop for DirLock {
    fn drop(&mut self) {
        // Unlinked while still locked: a run that opened it meanwhile fails
        // its try_lock and is refused, as it should be.
        let _ = std::fs::remove_file(&self.path);
        let _ = self.file.unlock();
    }
}

/// Locks `dir` (created if missing) for this process.
pub fn lock_dir(dir: &Path) -> CliResult<DirLock> {
    use std::io::{Read, Seek, Write};
    create_output_dir(dir)?;
    let path = dir.join("tridem.lock");
    let io = |e: std::io::Error| CliError::runtime(format!("{}: {e}", path.display()));
    let mut file = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .create(true)
        .truncate(false)
        .open(&path)
        .map_err(io)?;
    match file.try_lock() {
        Ok(()) => {
            file.set_len(0).map_err(io)?;
            file.rewind().map_err(io)?;
            write!(file, "{}", std::process::id()).map_err(io)?;
            Ok(DirLock { file, path })
        }
        Err(std::fs::TryLockError::WouldBlock) => {
            let mut pid = String::new();
            let _ = file.read_to_string(&mut pid);
            Err(CliError::input(format!(
                "{}: in use by another tridem run (pid {}); wait for it to end, or write elsewhere",
                dir.display(),
                pid.trim()
            )))
        }
        Err(std::fs::TryLockError::Error(e)) => Err(io(e)),
    }
}

/// Opens the output of a run in `dir`: appended to when the run resumes
/// into its own directory, created otherwise (refused over an earlier run's
/// output unless `overwrite`, which replaces the whole run: its output and
/// its checkpoint). Returns the output, whether the present state is still
/// to be written as an output step, and the directory's lock. Nothing is
/// changed before every check has passed and the lock is held.
pub fn open_run_output(
    dir: &Path,
    resume: Option<&Path>,
    overwrite: bool,
    layout: &Layout,
    time: f64,
) -> CliResult<(Output, bool, DirLock)> {
    let run_h5 = dir.join("run.h5");
    if resume.is_none() && run_h5.exists() && !overwrite {
        return Err(CliError::input(format!(
            "{}: holds the output of an earlier run; go on with it with --resume {}, \
             write to another directory, or replace it with --overwrite",
            run_h5.display(),
            dir.join("checkpoint.h5").display()
        )));
    }
    let lock = lock_dir(dir)?;
    if let Some(from) = resume.filter(|_| run_h5.exists()) {
        // Its own checkpoint is the truth of the directory: output steps
        // past it were written by a run killed before its checkpoint.
        let own = same_file(from, &dir.join("checkpoint.h5"));
        let (out, current) = Output::append(dir, layout, time, own)?;
        return Ok((out, !current, lock));
    }
    let checkpoint = dir.join("checkpoint.h5");
    if checkpoint.exists() && resume.is_none_or(|r| !same_file(r, &checkpoint)) {
        std::fs::remove_file(&checkpoint).map_err(|e| {
            CliError::runtime(format!("{}: cannot replace: {e}", checkpoint.display()))
        })?;
    }
    Ok((Output::create(dir, layout)?, true, lock))
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

/// What an output step writes besides the bodies' states and the energy
/// books (the scene's `[output] fields`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Field {
    Surface,
    Particles,
    Contacts,
}

dem::named_enum!(
    Field,
    "output field",
    [
        (Surface, "surface"),
        (Particles, "particles"),
        (Contacts, "contacts"),
    ]
);

/// The fields the scene's `[output]` asks for (every one by default), in
/// table order; an unknown name is refused at the section's line of `file`.
pub fn fields_of(scene: &Scene, file: &Path) -> CliResult<Vec<Field>> {
    let Some(names) = &scene.output.fields else {
        return Ok(Field::ALL.iter().map(|(f, _)| *f).collect());
    };
    let mut asked = Vec::new();
    for n in names {
        let f: Field = n.parse().map_err(|e: String| {
            CliError::input(format!(
                "{}:{}: output.fields: {e}",
                file.display(),
                scene.output.line
            ))
        })?;
        asked.push(f);
    }
    Ok(Field::ALL
        .iter()
        .map(|(f, _)| *f)
        .filter(|f| asked.contains(f))
        .collect())
}

/// The fields a run's output holds (its root attribute `fields`; a file
/// without it holds them all).
pub fn fields_in(file: &hdf5::File) -> Vec<Field> {
    match file
        .attr("fields")
        .and_then(|a| a.read_raw::<hdf5::types::VarLenUnicode>())
    {
        Ok(names) => names
            .iter()
            .filter_map(|n| n.as_str().parse().ok())
            .collect(),
        Err(_) => Field::ALL.iter().map(|(f, _)| *f).collect(),
    }
}

/// What a run's output is made of, whatever its state: the shapes and
/// materials, and which body has which (obstacles included, in id order).
#[derive(Debug, Clone)]
pub struct Layout {
    pub shapes: Vec<TriMesh>,
    pub body_shapes: Vec<usize>,
    pub materials: Vec<String>,
    /// Runs of bodies alike: material, mass, inverse inertia (the census).
    pub census: Census,
    /// What each step writes besides the states and the books.
    pub fields: Vec<Field>,
}

impl Layout {
    /// The layout of the whole scene (read from `file`), however many of
    /// its bodies `scene` holds.
    pub fn of(scene: &Scene, file: &Path) -> CliResult<Layout> {
        Ok(Layout {
            shapes: scene.world.shapes.clone(),
            body_shapes: scene.census.shapes().collect(),
            materials: scene
                .world
                .materials
                .iter()
                .map(|m| m.name.clone())
                .collect(),
            census: scene.census.clone(),
            fields: fields_of(scene, file)?,
        })
    }

    pub fn has(&self, f: Field) -> bool {
        self.fields.contains(&f)
    }

    /// Per body, in id order: what its run says of it.
    fn per_body<T: Copy>(&self, f: impl Fn(&Run) -> T) -> Vec<T> {
        let runs = self.census.runs();
        runs.iter()
            .flat_map(|r| std::iter::repeat_n(f(r), r.ids.len()))
            .collect()
    }
}

pub struct Output {
    file: hdf5::File,
    dir: PathBuf,
    steps: Vec<StepIndex>,
    layout: Layout,
    /// The surface's size: points (mesh vertices) and triangles.
    points: usize,
    triangles: usize,
    /// Per body: whether it is an obstacle.
    obstacle: Vec<bool>,
}

/// What the XDMF index needs of an output step.
#[derive(Debug, Clone, Copy)]
struct StepIndex {
    k: usize,
    time: f64,
    bodies: usize,
    contacts: usize,
}

fn h5err(e: hdf5::Error) -> CliError {
    CliError::runtime(format!("HDF5: {e}"))
}

/// Writes `data` as the dataset `name` of `group`.
fn put<'d, A, T, D>(group: &hdf5::Group, name: &str, data: A) -> CliResult
where
    A: Into<ndarray::ArrayView<'d, T, D>>,
    T: hdf5::H5Type + 'd,
    D: ndarray::Dimension + 'd,
{
    group
        .new_dataset_builder()
        .with_data(data)
        .create(name)
        .map_err(h5err)?;
    Ok(())
}

impl Output {
    /// The output of a run of `layout` (the bodies' states come with each
    /// step).
    pub fn create(dir: &Path, layout: &Layout) -> CliResult<Output> {
        create_output_dir(dir)?;
        let path = dir.join("run.h5");
        let file = hdf5::File::create(&path)
            .map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))?;
        let shapes = file.create_group("shapes").map_err(h5err)?;
        for (i, m) in layout.shapes.iter().enumerate() {
            let g = shapes.create_group(&i.to_string()).map_err(h5err)?;
            let v = Array2::from_shape_fn((m.vertices.len(), 3), |(r, c)| m.vertices[r][c]);
            let t = Array2::from_shape_fn((m.triangles.len(), 3), |(r, c)| m.triangles[r][c]);
            put(&g, "vertices", &v)?;
            put(&g, "triangles", &t)?;
        }
        let names: Vec<hdf5::types::VarLenUnicode> = layout
            .fields
            .iter()
            .map(|f| f.name().parse().expect("a field's name is text"))
            .collect();
        file.new_attr::<hdf5::types::VarLenUnicode>()
            .shape(names.len())
            .create("fields")
            .and_then(|a| a.write_raw(&names))
            .map_err(h5err)?;
        let mut out = Output::of(file, dir, layout);
        if layout.has(Field::Surface) {
            out.write_connectivity()?;
        }
        out.write_bodies()?;
        out.file.create_group("steps").map_err(h5err)?;
        Ok(out)
    }

    /// `/bodies/{material, mass, obstacle, index}` per body and `/materials` (an
    /// attribute per material: its name, with its index as value): what
    /// never changes, written once.
    fn write_bodies(&self) -> CliResult {
        let layout = &self.layout;
        let g = self.file.create_group("bodies").map_err(h5err)?;
        let material: Vec<u32> = layout.per_body(|r| r.material as u32);
        let bodies = material.len() as u32;
        let obstacle: Vec<u8> = layout.per_body(|r| u8::from(r.fixed.is_some()));
        let mass: Vec<f64> = layout.per_body(|r| if r.fixed.is_some() { 0.0 } else { r.mass });
        put(&g, "material", &Array1::from(material))?;
        put(&g, "mass", &Array1::from(mass))?;
        put(&g, "obstacle", &Array1::from(obstacle))?;
        // The particles grid's connectivity (a vertex per body): XDMF 3
        // readers draw no cell of a point set without it.
        let index: Vec<u32> = (0..bodies).collect();
        put(&g, "index", &Array1::from(index))?;
        let m = self.file.create_group("materials").map_err(h5err)?;
        for (i, name) in layout.materials.iter().enumerate() {
            m.new_attr::<u32>()
                .create(name.as_str())
                .and_then(|a| a.write_scalar(&(i as u32)))
                .map_err(h5err)?;
        }
        Ok(())
    }

    fn of(file: hdf5::File, dir: &Path, layout: &Layout) -> Output {
        let count = |f: fn(&TriMesh) -> usize| {
            let shapes = &layout.shapes;
            layout.body_shapes.iter().map(|&s| f(&shapes[s])).sum()
        };
        Output {
            file,
            dir: dir.to_path_buf(),
            steps: Vec::new(),
            points: count(|m| m.vertices.len()),
            triangles: count(|m| m.triangles.len()),
            obstacle: layout.per_body(|r| r.fixed.is_some()),
            layout: layout.clone(),
        }
    }

    /// `/surface/triangles`, `/surface/body` and `/surface/material`: each
    /// body's mesh, its vertices numbered after the bodies before it,
    /// written a block of bodies at a time (never built whole: a large
    /// scene's connectivity is its triangle count times 20 bytes).
    fn write_connectivity(&mut self) -> CliResult {
        let g = self.file.create_group("surface").map_err(h5err)?;
        let n = self.triangles;
        let create = |name: &str, shape: &[usize]| {
            g.new_dataset::<u32>()
                .shape(shape)
                .create(name)
                .map_err(h5err)
        };
        let (triangles, body, material) = (
            create("triangles", &[n, 3])?,
            create("body", &[n])?,
            create("material", &[n])?,
        );
        let Layout {
            shapes,
            body_shapes,
            ..
        } = &self.layout;
        let materials: Vec<u32> = self.layout.per_body(|r| r.material as u32);
        let widest = shapes.iter().map(|s| s.triangles.len()).max().unwrap_or(0);
        let mut block = Connectivity::with_capacity(CONNECTIVITY_BLOCK + widest);
        let (mut first_vertex, mut at, mut from) = (0u32, 0usize, 0usize);
        for (i, &s) in body_shapes.iter().enumerate() {
            let m = &shapes[s];
            for t in &m.triangles {
                block.triangles.extend(t.map(|v| first_vertex + v));
                block.body.push(i as u32);
                block.material.push(materials[i]);
            }
            first_vertex += m.vertices.len() as u32;
            at += m.triangles.len();
            if (block.body.len() >= CONNECTIVITY_BLOCK || i + 1 == body_shapes.len()) && at > from {
                let t = ndarray::ArrayView2::from_shape((at - from, 3), &block.triangles)
                    .expect("three vertices per triangle");
                triangles.write_slice(t, (from..at, ..)).map_err(h5err)?;
                body.write_slice(&block.body, from..at).map_err(h5err)?;
                material
                    .write_slice(&block.material, from..at)
                    .map_err(h5err)?;
                block.clear();
                from = at;
            }
        }
        Ok(())
    }

    /// Opens the output of a run of `layout` that resumes at `time`, to
    /// append to it; and whether its last step is the resumed state (a
    /// checkpoint is taken with each output step). Output steps of a later
    /// time are dropped when `drop_later` (the directory's own checkpoint is
    /// resumed: a run killed between an output step and its checkpoint left
    /// them); otherwise refused: they belong to a run that went further
    /// than the checkpoint, and appending would interleave two histories.
    pub fn append(
        dir: &Path,
        layout: &Layout,
        time: f64,
        drop_later: bool,
    ) -> CliResult<(Output, bool)> {
        let path = dir.join("run.h5");
        let fail = |why: String| CliError::input(format!("{}: {why}", path.display()));
        let file = hdf5::File::open_rw(&path).map_err(|e| fail(e.to_string()))?;
        let group = file
            .group("steps")
            .map_err(|e| fail(format!("not the output of tridem run: {e}")))?;
        file.group("bodies")
            .map_err(|e| fail(format!("not the output of this tridem run: {e}")))?;
        let written = fields_in(&file);
        if written != layout.fields {
            let names = |f: &[Field]| f.iter().map(|f| f.name()).collect::<Vec<_>>().join(", ");
            return Err(fail(format!(
                "written with the output fields [{}], the resumed run's are [{}]; \
                 write it to another directory",
                names(&written),
                names(&layout.fields)
            )));
        }
        let triangles = match layout.has(Field::Surface) {
            true => file
                .dataset("surface/body")
                .map_err(|e| fail(format!("not the output of this tridem run: {e}")))?
                .size(),
            false => 0,
        };
        let mut steps = Vec::new();
        for name in group.member_names().map_err(|e| fail(e.to_string()))? {
            let step = |e: hdf5::Error| fail(format!("steps/{name}: {e}"));
            let k: usize = name
                .parse()
                .map_err(|_| fail(format!("steps/{name}: not a step number")))?;
            let g = group.group(&name).map_err(step)?;
            let time: f64 = g.attr("time").and_then(|a| a.read_scalar()).map_err(step)?;
            let n = g.dataset("positions").map_err(step)?.shape()[0];
            let nc = g
                .dataset("contact_forces/bodies")
                .map_or(0, |d| d.shape()[0]);
            steps.push(StepIndex {
                k,
                time,
                bodies: n,
                contacts: nc,
            });
        }
        steps.sort_by_key(|s| s.k);
        if steps.iter().enumerate().any(|(i, s)| s.k != i) {
            return Err(fail("output steps are not numbered 0, 1, 2, ...".into()));
        }
        let n = layout.body_shapes.len();
        if let Some(s) = steps.iter().find(|s| s.bodies != n) {
            return Err(fail(format!(
                "output step {} has {} bodies, the resumed run {n}",
                s.k, s.bodies
            )));
        }
        let mut out = Output::of(file, dir, layout);
        if layout.has(Field::Surface) && triangles != out.triangles {
            return Err(fail(format!(
                "its surface has {triangles} triangles, the resumed run's {}",
                out.triangles
            )));
        }
        if drop_later {
            while steps.last().is_some_and(|s| s.time > time) {
                let last = steps.pop().expect("a step");
                group
                    .unlink(&last.k.to_string())
                    .map_err(|e| fail(format!("steps/{}: {e}", last.k)))?;
            }
        }
        if let Some(s) = steps.iter().find(|s| s.time > time) {
            return Err(fail(format!(
                "holds output step {} at t = {:e} s, after the checkpoint's t = {time:e} s; \
                 write the resumed run to another directory",
                s.k, s.time
            )));
        }
        let current = steps.last().is_some_and(|s| s.time == time);
        out.steps = steps;
        out.file.flush().map_err(h5err)?;
        out.write_xdmf()?;
        Ok((out, current))
    }

    /// Writes `frame` as the next output step, then rewrites the XDMF index;
    /// an error names the file (a full disk, say).
    pub fn write_step(&mut self, frame: &Frame) -> CliResult {
        let path = self.dir.join("run.h5");
        let k = self.steps.len();
        self.write_frame(frame)
            .map_err(|e| e.within(format!("{}: cannot write output step {k}", path.display())))
    }

    fn write_frame(&mut self, frame: &Frame) -> CliResult {
        let k = self.steps.len();
        let b = &frame.bodies;
        let n = b.len();
        let g = self
            .file
            .group("steps")
            .and_then(|s| s.create_group(&k.to_string()))
            .map_err(h5err)?;
        let vec3 =
            |f: &dyn Fn(usize) -> glam::DVec3| Array2::from_shape_fn((n, 3), |(r, c)| f(r)[c]);
        put(&g, "positions", &vec3(&|i| b[i].x))?;
        put(&g, "velocities", &vec3(&|i| b[i].v))?;
        put(&g, "angular_momenta", &vec3(&|i| b[i].l))?;
        let q = Array2::from_shape_fn((n, 4), |(r, c)| b[r].q.to_array()[c]);
        put(&g, "orientations", &q)?;
        put(&g, "contacts", &Array1::from(frame.contact_counts()))?;
        let removed: Vec<u8> = b.iter().map(|s| u8::from(s.removed)).collect();
        put(&g, "removed", &Array1::from(removed))?;
        let pending: Vec<u8> = b.iter().map(|s| u8::from(s.pending)).collect();
        put(&g, "pending", &Array1::from(pending))?;
        g.new_attr::<f64>()
            .create("time")
            .and_then(|a| a.write_scalar(&frame.time))
            .map_err(h5err)?;
        if self.layout.has(Field::Particles) {
            self.write_motion(&g, frame)?;
        }
        if self.layout.has(Field::Surface) {
            self.write_surface(&g, frame)?;
        }
        write_energies(&g, frame)?;
        let nc = match self.layout.has(Field::Contacts) {
            true => write_contacts(&g, frame, &self.obstacle)?,
            false => 0,
        };
        self.file.flush().map_err(h5err)?;
        self.steps.push(StepIndex {
            k,
            time: frame.time,
            bodies: n,
            contacts: nc,
        });
        self.write_xdmf()
    }

    /// What the bodies' states give per body: angular velocity (rad/s),
    /// speed (m/s), and kinetic energy of translation and of rotation (J);
    /// zero for obstacles.
    fn write_motion(&self, g: &hdf5::Group, frame: &Frame) -> CliResult {
        let b = &frame.bodies;
        let n = b.len();
        let runs: Vec<(f64, glam::DMat3, bool)> = self
            .layout
            .per_body(|r| (r.mass, r.inv_inertia, r.fixed.is_some()));
        let mut omega = Array2::<f64>::zeros((n, 3));
        let (mut speed, mut translation, mut rotation) = (vec![0.0; n], vec![0.0; n], vec![0.0; n]);
        for (i, s) in b.iter().enumerate() {
            let (mass, inv_inertia, obstacle) = runs[i];
            if obstacle {
                continue;
            }
            let w = dem::body::omega_of(s.q, inv_inertia, s.l);
            for c in 0..3 {
                omega[[i, c]] = w[c];
            }
            speed[i] = s.v.length();
            translation[i] = 0.5 * mass * s.v.length_squared();
            rotation[i] = 0.5 * s.l.dot(w);
        }
        put(g, "angular_velocities", &omega)?;
        for (name, v) in [
            ("speeds", speed),
            ("kinetic_translation", translation),
            ("kinetic_rotation", rotation),
        ] {
            put(g, name, &Array1::from(v))?;
        }
        Ok(())
    }

    /// The step's surface points: each body's mesh vertices where it
    /// stands, written a block of bodies at a time (a large scene's surface
    /// is never built whole).
    fn write_surface(&self, g: &hdf5::Group, frame: &Frame) -> CliResult {
        let s = g.create_group("surface").map_err(h5err)?;
        let d = s
            .new_dataset::<f64>()
            .shape((self.points, 3))
            .create("points")
            .map_err(h5err)?;
        let Layout {
            shapes,
            body_shapes,
            ..
        } = &self.layout;
        // One block, sized once: it never grows by doubling, so what the
        // surface holds at a time is the block, whatever the scene's size.
        let widest = shapes.iter().map(|s| s.vertices.len()).max().unwrap_or(0);
        let mut block: Vec<f64> = Vec::with_capacity(SURFACE_BLOCK + 3 * widest);
        let (mut at, mut first) = (0usize, 0usize);
        for (i, state) in frame.bodies.iter().enumerate() {
            let vertices = &shapes[body_shapes[i]].vertices;
            for &v in vertices {
                let p = state.x + state.q * v;
                block.extend(p.to_array());
            }
            at += vertices.len();
            if block.len() >= SURFACE_BLOCK || i + 1 == frame.bodies.len() {
                let a = ndarray::ArrayView2::from_shape((block.len() / 3, 3), &block)
                    .expect("three coordinates per point");
                d.write_slice(a, (first..at, ..)).map_err(h5err)?;
                block.clear();
                first = at;
            }
        }
        Ok(())
    }

    /// `DIR/run.xmf`: four temporal collections over the output steps, all
    /// reading `run.h5` (see the module doc).
    fn write_xdmf(&self) -> CliResult {
        let mut x = String::new();
        let _ = writeln!(x, r#"<?xml version="1.0" ?>"#);
        let _ = writeln!(x, r#"<Xdmf Version="3.0"><Domain>"#);
        if self.layout.has(Field::Surface) {
            self.xdmf_collection(&mut x, "surface", |x, s| self.xdmf_surface(x, s));
        }
        if self.layout.has(Field::Particles) {
            self.xdmf_collection(&mut x, "particles", |x, s| self.xdmf_particles(x, s));
        }
        if self.layout.has(Field::Contacts) {
            self.xdmf_collection(&mut x, "contacts", xdmf_contact_lines);
            self.xdmf_collection(&mut x, "contact_points", xdmf_contact_points);
        }
        let _ = writeln!(x, "</Domain></Xdmf>");
        let path = self.dir.join("run.xmf");
        // Write beside and rename, so the index on disk is never half written.
        let tmp = self.dir.join("run.xmf.tmp");
        std::fs::write(&tmp, x)
            .and_then(|_| std::fs::rename(&tmp, &path))
            .map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))
    }

    /// One grid per output step, in a temporal collection named `name`.
    fn xdmf_collection(&self, x: &mut String, name: &str, grid: impl Fn(&mut String, &StepIndex)) {
        let _ = writeln!(
            x,
            r#"<Grid Name="{name}" GridType="Collection" CollectionType="Temporal">"#
        );
        for s in &self.steps {
            let _ = writeln!(
                x,
                r#"<Grid Name="{name}{}" GridType="Uniform"><Time Value="{:e}"/>"#,
                s.k, s.time
            );
            grid(x, s);
            let _ = writeln!(x, "</Grid>");
        }
        let _ = writeln!(x, "</Grid>");
    }

    /// Every body's mesh: points per mesh vertex, cells coloured by body
    /// and material.
    fn xdmf_surface(&self, x: &mut String, s: &StepIndex) {
        let (nt, np, k) = (self.triangles, self.points, s.k);
        let _ = writeln!(
            x,
            r#"<Topology TopologyType="Triangle" NumberOfElements="{nt}">{}</Topology>"#,
            item(&[nt, 3], "UInt", 4, "surface/triangles")
        );
        geometry(x, np, &format!("steps/{k}/surface/points"));
        attribute(x, "body", "Cell", &[nt], "UInt", 4, "surface/body");
        attribute(x, "material", "Cell", &[nt], "UInt", 4, "surface/material");
    }

    /// One point per body at its centre of mass.
    fn xdmf_particles(&self, x: &mut String, s: &StepIndex) {
        let (n, k) = (s.bodies, s.k);
        point_set(x, n, "bodies/index");
        geometry(x, n, &format!("steps/{k}/positions"));
        let step = |what: &str| format!("steps/{k}/{what}");
        attribute(x, "material", "Node", &[n], "UInt", 4, "bodies/material");
        attribute(x, "mass", "Node", &[n], "Float", 8, "bodies/mass");
        attribute(x, "obstacle", "Node", &[n], "UChar", 1, "bodies/obstacle");
        for (name, what) in [
            ("velocity", "velocities"),
            ("angular_velocity", "angular_velocities"),
        ] {
            attribute(x, name, "Node", &[n, 3], "Float", 8, &step(what));
        }
        for (name, what) in [
            ("speed", "speeds"),
            ("kinetic_translation", "kinetic_translation"),
            ("kinetic_rotation", "kinetic_rotation"),
        ] {
            attribute(x, name, "Node", &[n], "Float", 8, &step(what));
        }
        attribute(x, "removed", "Node", &[n], "UChar", 1, &step("removed"));
        attribute(x, "pending", "Node", &[n], "UChar", 1, &step("pending"));
        attribute(
            x,
            "coordination",
            "Node",
            &[n],
            "UInt",
            4,
            &step("contacts"),
        );
    }
}

/// The contact network: a line per contact between the bodies it joins.
fn xdmf_contact_lines(x: &mut String, s: &StepIndex) {
    let (nc, k) = (s.contacts, s.k);
    let c = |what: &str| format!("steps/{k}/contact_forces/{what}");
    let _ = writeln!(
        x,
        r#"<Topology TopologyType="Polyline" NodesPerElement="2" NumberOfElements="{nc}">{}</Topology>"#,
        item(&[nc, 2], "UInt", 4, &c("lines"))
    );
    geometry(x, 2 * nc, &c("line_points"));
    attribute(
        x,
        "normal_force",
        "Cell",
        &[nc],
        "Float",
        8,
        &c("normal_force_magnitudes"),
    );
    attribute(x, "overlap", "Cell", &[nc], "Float", 8, &c("overlaps"));
    attribute(x, "slides", "Cell", &[nc], "UChar", 1, &c("slides"));
    for (name, what) in [
        ("normal_force_vector", "normal_forces"),
        ("tangential_force", "tangential_forces"),
        ("force", "forces"),
    ] {
        attribute(x, name, "Cell", &[nc, 3], "Float", 8, &c(what));
    }
}

/// Each contact's point, with the force on its first body (glyphs show it).
fn xdmf_contact_points(x: &mut String, s: &StepIndex) {
    let (nc, k) = (s.contacts, s.k);
    let c = |what: &str| format!("steps/{k}/contact_forces/{what}");
    point_set(x, nc, &c("point_index"));
    geometry(x, nc, &c("points"));
    attribute(x, "force", "Node", &[nc, 3], "Float", 8, &c("forces"));
}

/// A topology of `n` unconnected points, one vertex each, numbered by the
/// dataset `index` (0..n): both XDMF readers of ParaView (2 and 3) draw it.
fn point_set(x: &mut String, n: usize, index: &str) {
    let _ = writeln!(
        x,
        r#"<Topology TopologyType="Polyvertex" NodesPerElement="1" NumberOfElements="{n}">{}</Topology>"#,
        item(&[n], "UInt", 4, index)
    );
}

/// An HDF5 data item of `run.h5`.
fn item(dims: &[usize], kind: &str, precision: u8, path: &str) -> String {
    let dims: Vec<String> = dims.iter().map(usize::to_string).collect();
    format!(
        r#"<DataItem Dimensions="{}" NumberType="{kind}" Precision="{precision}" Format="HDF">run.h5:/{path}</DataItem>"#,
        dims.join(" ")
    )
}

fn geometry(x: &mut String, points: usize, path: &str) {
    let _ = writeln!(
        x,
        r#"<Geometry GeometryType="XYZ">{}</Geometry>"#,
        item(&[points, 3], "Float", 8, path)
    );
}

fn attribute(
    x: &mut String,
    name: &str,
    center: &str,
    dims: &[usize],
    kind: &str,
    precision: u8,
    path: &str,
) {
    let kind_of = if dims.len() == 2 { "Vector" } else { "Scalar" };
    let _ = writeln!(
        x,
        r#"<Attribute Name="{name}" AttributeType="{kind_of}" Center="{center}">{}</Attribute>"#,
        item(dims, kind, precision, path)
    );
}

/// Triangles per block of the surface's connectivity written at once.
const CONNECTIVITY_BLOCK: usize = 8192;

/// One block of the surface's connectivity: per triangle, its vertices in
/// the surface's numbering, its body and its body's material.
struct Connectivity {
    triangles: Vec<u32>,
    body: Vec<u32>,
    material: Vec<u32>,
}

impl Connectivity {
    fn with_capacity(n: usize) -> Connectivity {
        Connectivity {
            triangles: Vec::with_capacity(3 * n),
            body: Vec::with_capacity(n),
            material: Vec::with_capacity(n),
        }
    }

    fn clear(&mut self) {
        self.triangles.clear();
        self.body.clear();
        self.material.clear();
    }
}

/// Coordinates per block of the surface written at once: 8,192 points,
/// 192 KiB.
const SURFACE_BLOCK: usize = 3 << 13;

/// The energy attributes of one output step, and the probes' (if any).
fn write_energies(g: &hdf5::Group, frame: &Frame) -> CliResult {
    let e = &frame.energies;
    let group = g.create_group("energy").map_err(h5err)?;
    let mut values = vec![
        ("kinetic_translation".to_string(), e.translation),
        ("kinetic_rotation".to_string(), e.rotation),
    ];
    for x in &e.effects {
        values.push((format!("{}_stored", x.effect), x.stored));
        values.push((format!("{}_dissipated", x.effect), x.dissipated));
    }
    scalars(&group, values)?;
    if !e.measures.is_empty() {
        let group = g.create_group("probes").map_err(h5err)?;
        scalars(&group, e.measures.iter().cloned())?;
    }
    Ok(())
}

/// Writes each (name, value) as an f64 attribute of `group`.
fn scalars(group: &hdf5::Group, values: impl IntoIterator<Item = (String, f64)>) -> CliResult {
    for (name, v) in values {
        group
            .new_attr::<f64>()
            .create(name.as_str())
            .and_then(|a| a.write_scalar(&v))
            .map_err(h5err)?;
    }
    Ok(())
}

/// The contacts of one output step; returns how many. Each is also a line
/// of the contact network: from the first body's centre to the second's,
/// an obstacle's end at the contact point instead (an obstacle's centre can
/// lie anywhere).
fn write_contacts(g: &hdf5::Group, frame: &Frame, obstacle: &[bool]) -> CliResult<usize> {
    let c = &frame.contacts;
    let nc = c.len();
    let group = g.create_group("contact_forces").map_err(h5err)?;
    let vectors =
        |f: &dyn Fn(usize) -> glam::DVec3| Array2::from_shape_fn((nc, 3), |(r, k)| f(r)[k]);
    let points = vectors(&|r| c[r].point);
    let f = vectors(&|r| c[r].force());
    let normal = vectors(&|r| c[r].normal_force);
    let tangential = vectors(&|r| c[r].tangential_force);
    let end = |r: usize, id: u32| match obstacle[id as usize] {
        true => c[r].point,
        false => frame.bodies[id as usize].x,
    };
    let ends = Array2::from_shape_fn((2 * nc, 3), |(r, k)| {
        let contact = r / 2;
        let id = if r % 2 == 0 {
            c[contact].a
        } else {
            c[contact].b
        };
        end(contact, id)[k]
    });
    let bodies = Array2::from_shape_fn((nc, 2), |(r, k)| [c[r].a, c[r].b][k]);
    let lines = Array2::from_shape_fn((nc, 2), |(r, k)| (2 * r + k) as u32);
    put(
        &group,
        "normal_force_magnitudes",
        &Array1::from_iter(c.iter().map(|x| x.normal_force.length())),
    )?;
    put(
        &group,
        "overlaps",
        &Array1::from_iter(c.iter().map(|x| x.depth)),
    )?;
    put(
        &group,
        "slides",
        &Array1::from_iter(c.iter().map(|x| u8::from(x.slides))),
    )?;
    put(&group, "lines", &lines)?;
    put(&group, "point_index", &Array1::from_iter(0..nc as u32))?;
    for (name, data) in [
        ("points", &points),
        ("forces", &f),
        ("normal_forces", &normal),
        ("tangential_forces", &tangential),
        ("line_points", &ends),
    ] {
        put(&group, name, data)?;
    }
    put(&group, "bodies", &bodies)?;
    Ok(nc)
}
