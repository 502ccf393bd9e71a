//! Simulation output: one HDF5 file per run with a group per output step, the
//! meshes and the surface's connectivity once, and an XDMF sidecar so that
//! ParaView opens it directly.
//!
//! Layout of `DIR/run.h5`:
//! - `/shapes/<s>/vertices` (V×3, body frame) and `/shapes/<s>/triangles` (T×3)
//! - `/surface/triangles` (T×3) and `/surface/body` (T): every body's mesh, its
//!   vertices numbered body after body as in each step's `surface/points`;
//!   written once (the connectivity never changes).
//! - `/steps/<k>/{positions, velocities, angular_momenta} (N×3), orientations (N×4, xyzw),
//!   contacts (N), time (attribute)`
//! - `/steps/<k>/energy`: attributes `kinetic_translation`, `kinetic_rotation`, and per
//!   effect `<effect>_stored` (gravity's potential, springs) and `<effect>_dissipated`
//!   (work of dashpots, sliding and damping since the start), in J: their sum is constant
//!   up to the integrator's error.
//! - `/steps/<k>/contact_forces/{points (C×3), forces (C×3), bodies (C×2)}`: each contact's
//!   point, the force on its first body (the second takes the opposite), and the bodies.
//! - `/steps/<k>/surface/points` (V×3): every body's mesh vertices where the body stands.
//!
//! The XDMF file `DIR/run.xmf` shows the surfaces and the contact forces (points with a
//! `force` vector: glyphs in ParaView show the force chains) as time series.
//!
//! Each step is written and flushed as it is produced, so a run stopped early
//! keeps everything written before; a run resumed from a checkpoint goes on
//! appending to the same file. What is written is a [`Frame`]: one process
//! and a run split across ranks write the same bytes.

use crate::error::{create_output_dir, CliError, CliResult};
use dem::frame::Frame;
use dem::mesh::TriMesh;
use dem::world::World;
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

/// What a run's output is made of, whatever its state: the shapes, and
/// which body has which (obstacles included, in id order).
#[derive(Debug, Clone)]
pub struct Layout {
    pub shapes: Vec<TriMesh>,
    pub body_shapes: Vec<usize>,
}

impl Layout {
    pub fn of(world: &World) -> Layout {
        Layout {
            shapes: world.shapes.clone(),
            body_shapes: world.bodies.iter().map(|b| b.shape).collect(),
        }
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
            g.new_dataset_builder()
                .with_data(&v)
                .create("vertices")
                .map_err(h5err)?;
            g.new_dataset_builder()
                .with_data(&t)
                .create("triangles")
                .map_err(h5err)?;
        }
        let mut out = Output::of(file, dir, layout);
        out.write_connectivity()?;
        out.file.create_group("steps").map_err(h5err)?;
        Ok(out)
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
            layout: layout.clone(),
        }
    }

    /// `/surface/triangles` and `/surface/body`: each body's mesh, its
    /// vertices numbered after the bodies before it.
    fn write_connectivity(&mut self) -> CliResult {
        let mut triangles = Vec::with_capacity(self.triangles);
        let mut body = Vec::with_capacity(self.triangles);
        let mut first = 0u32;
        for (i, &s) in self.layout.body_shapes.iter().enumerate() {
            let m = &self.layout.shapes[s];
            for t in &m.triangles {
                triangles.push(t.map(|v| first + v));
                body.push(i as u32);
            }
            first += m.vertices.len() as u32;
        }
        let g = self.file.create_group("surface").map_err(h5err)?;
        let t = Array2::from_shape_fn((triangles.len(), 3), |(r, c)| triangles[r][c]);
        g.new_dataset_builder()
            .with_data(&t)
            .create("triangles")
            .map_err(h5err)?;
        g.new_dataset_builder()
            .with_data(&Array1::from(body))
            .create("body")
            .map_err(h5err)?;
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
        let triangles = file
            .dataset("surface/body")
            .map_err(|e| fail(format!("not the output of this tridem run: {e}")))?
            .size();
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
        if triangles != out.triangles {
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
        g.new_dataset_builder()
            .with_data(&vec3(&|i| b[i].x))
            .create("positions")
            .map_err(h5err)?;
        g.new_dataset_builder()
            .with_data(&vec3(&|i| b[i].v))
            .create("velocities")
            .map_err(h5err)?;
        g.new_dataset_builder()
            .with_data(&vec3(&|i| b[i].l))
            .create("angular_momenta")
            .map_err(h5err)?;
        let q = Array2::from_shape_fn((n, 4), |(r, c)| b[r].q.to_array()[c]);
        g.new_dataset_builder()
            .with_data(&q)
            .create("orientations")
            .map_err(h5err)?;
        g.new_dataset_builder()
            .with_data(&Array1::from(frame.contact_counts()))
            .create("contacts")
            .map_err(h5err)?;
        g.new_attr::<f64>()
            .create("time")
            .and_then(|a| a.write_scalar(&frame.time))
            .map_err(h5err)?;
        self.write_surface(&g, frame)?;
        write_energies(&g, frame)?;
        let nc = write_contacts(&g, frame)?;
        self.file.flush().map_err(h5err)?;
        self.steps.push(StepIndex {
            k,
            time: frame.time,
            bodies: n,
            contacts: nc,
        });
        self.write_xdmf()
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
        let mut block: Vec<f64> = Vec::new();
        let (mut at, mut first) = (0usize, 0usize);
        let Layout {
            shapes,
            body_shapes,
        } = &self.layout;
        for (i, state) in frame.bodies.iter().enumerate() {
            let vertices = &shapes[body_shapes[i]].vertices;
            for &v in vertices {
                let p = state.x + state.q * v;
                block.extend(p.to_array());
            }
            at += vertices.len();
            if block.len() >= SURFACE_BLOCK || i + 1 == frame.bodies.len() {
                let rows = block.len() / 3;
                let a = Array2::from_shape_vec((rows, 3), std::mem::take(&mut block))
                    .expect("three coordinates per point");
                d.write_slice(&a, (first..at, ..)).map_err(h5err)?;
                first = at;
            }
        }
        Ok(())
    }

    fn write_xdmf(&self) -> CliResult {
        let mut x = String::new();
        let _ = writeln!(x, r#"<?xml version="1.0" ?>"#);
        let _ = writeln!(x, r#"<Xdmf Version="3.0"><Domain>"#);
        let _ = writeln!(
            x,
            r#"<Grid Name="surface" GridType="Collection" CollectionType="Temporal">"#
        );
        let (nt, np) = (self.triangles, self.points);
        for &StepIndex { k, time: t, .. } in &self.steps {
            let _ = writeln!(
                x,
                r#"<Grid Name="step{k}" GridType="Uniform"><Time Value="{t:e}"/>"#
            );
            let _ = writeln!(
                x,
                r#"<Topology TopologyType="Triangle" NumberOfElements="{nt}"><DataItem Dimensions="{nt} 3" NumberType="UInt" Precision="4" Format="HDF">run.h5:/surface/triangles</DataItem></Topology>"#
            );
            let _ = writeln!(
                x,
                r#"<Geometry GeometryType="XYZ"><DataItem Dimensions="{np} 3" NumberType="Float" Precision="8" Format="HDF">run.h5:/steps/{k}/surface/points</DataItem></Geometry>"#
            );
            let _ = writeln!(
                x,
                r#"<Attribute Name="body" AttributeType="Scalar" Center="Cell"><DataItem Dimensions="{nt}" NumberType="UInt" Precision="4" Format="HDF">run.h5:/surface/body</DataItem></Attribute>"#
            );
            let _ = writeln!(x, "</Grid>");
        }
        let _ = writeln!(x, "</Grid>");
        let _ = writeln!(
            x,
            r#"<Grid Name="contacts" GridType="Collection" CollectionType="Temporal">"#
        );
        for s in &self.steps {
            let (k, nc) = (s.k, s.contacts);
            let _ = writeln!(
                x,
                r#"<Grid Name="contacts{k}" GridType="Uniform"><Time Value="{:e}"/>"#,
                s.time
            );
            let _ = writeln!(
                x,
                r#"<Topology TopologyType="Polyvertex" NumberOfElements="{nc}"/>"#
            );
            let item = |what: &str| {
                format!(
                    r#"<DataItem Dimensions="{nc} 3" NumberType="Float" Precision="8" Format="HDF">run.h5:/steps/{k}/contact_forces/{what}</DataItem>"#
                )
            };
            let _ = writeln!(
                x,
                r#"<Geometry GeometryType="XYZ">{}</Geometry>"#,
                item("points")
            );
            let _ = writeln!(
                x,
                r#"<Attribute Name="force" AttributeType="Vector" Center="Node">{}</Attribute>"#,
                item("forces")
            );
            let _ = writeln!(x, "</Grid>");
        }
        let _ = writeln!(x, "</Grid></Domain></Xdmf>");
        let path = self.dir.join("run.xmf");
        // Write beside and rename, so the index on disk is never half written.
        let tmp = self.dir.join("run.xmf.tmp");
        std::fs::write(&tmp, x)
            .and_then(|_| std::fs::rename(&tmp, &path))
            .map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))
    }
}

/// Points per block of the surface written at once (as coordinates).
const SURFACE_BLOCK: usize = 3 << 16;

/// The energy attributes of one output step.
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
    for (name, v) in values {
        group
            .new_attr::<f64>()
            .create(name.as_str())
            .and_then(|a| a.write_scalar(&v))
            .map_err(h5err)?;
    }
    Ok(())
}

/// The contacts of one output step; returns how many.
fn write_contacts(g: &hdf5::Group, frame: &Frame) -> CliResult<usize> {
    let c = &frame.contacts;
    let nc = c.len();
    let group = g.create_group("contact_forces").map_err(h5err)?;
    let points = Array2::from_shape_fn((nc, 3), |(r, k)| c[r].point[k]);
    let f = Array2::from_shape_fn((nc, 3), |(r, k)| c[r].force()[k]);
    let bodies = Array2::from_shape_fn((nc, 2), |(r, k)| [c[r].a, c[r].b][k]);
    for (name, data) in [("points", &points), ("forces", &f)] {
        group
            .new_dataset_builder()
            .with_data(data)
            .create(name)
            .map_err(h5err)?;
    }
    group
        .new_dataset_builder()
        .with_data(&bodies)
        .create("bodies")
        .map_err(h5err)?;
    Ok(nc)
}
