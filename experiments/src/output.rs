//! Simulation output: one HDF5 file per run with a group per output step, the
//! meshes once, and an XDMF sidecar so that ParaView opens it directly.
//!
//! Layout of `DIR/run.h5`:
//! - `/shapes/<s>/vertices` (V×3, body frame) and `/shapes/<s>/triangles` (T×3)
//! - `/steps/<k>/{positions, velocities, angular_momenta} (N×3), orientations (N×4, xyzw),
//!   contacts (N), time (attribute)`
//! - `/steps/<k>/energy`: attributes `kinetic_translation`, `kinetic_rotation`, and per
//!   effect `<effect>_stored` (gravity's potential, springs) and `<effect>_dissipated`
//!   (work of dashpots, sliding and damping since the start), in J: their sum is constant
//!   up to the integrator's error.
//! - `/steps/<k>/contact_forces/{points (C×3), forces (C×3), bodies (C×2)}`: each contact's
//!   point, the force on its first body (the second takes the opposite), and the bodies.
//! - `/steps/<k>/surface/{points (3T×3), triangles (T×3), body (T)}`: the world-space
//!   surface of all bodies.
//!
//! The XDMF file `DIR/run.xmf` shows the surfaces and the contact forces (points with a
//! `force` vector: glyphs in ParaView show the force chains) as time series.
//!
//! Each step is written and flushed as it is produced, so a run stopped early
//! keeps everything written before; a run resumed from a checkpoint goes on
//! appending to the same file.

use crate::error::{create_output_dir, CliError, CliResult};
use dem::simulation::Simulation;
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
    sim: &Simulation,
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
        let (out, current) = Output::append(dir, sim, own)?;
        return Ok((out, !current, lock));
    }
    let checkpoint = dir.join("checkpoint.h5");
    if checkpoint.exists() && resume.is_none_or(|r| !same_file(r, &checkpoint)) {
        std::fs::remove_file(&checkpoint).map_err(|e| {
            CliError::runtime(format!("{}: cannot replace: {e}", checkpoint.display()))
        })?;
    }
    Ok((Output::create(dir, sim)?, true, lock))
}

fn same_file(a: &Path, b: &Path) -> bool {
    match (a.canonicalize(), b.canonicalize()) {
        (Ok(a), Ok(b)) => a == b,
        _ => false,
    }
}

pub struct Output {
    file: hdf5::File,
    dir: PathBuf,
    steps: Vec<StepIndex>,
}

/// What the XDMF index needs of an output step.
#[derive(Debug, Clone, Copy)]
struct StepIndex {
    k: usize,
    time: f64,
    triangles: usize,
    bodies: usize,
    contacts: usize,
}

fn h5err(e: hdf5::Error) -> CliError {
    CliError::runtime(format!("HDF5: {e}"))
}

impl Output {
    pub fn create(dir: &Path, sim: &Simulation) -> CliResult<Output> {
        create_output_dir(dir)?;
        let path = dir.join("run.h5");
        let file = hdf5::File::create(&path)
            .map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))?;
        let shapes = file.create_group("shapes").map_err(h5err)?;
        for (i, m) in sim.world.shapes.iter().enumerate() {
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
        file.create_group("steps").map_err(h5err)?;
        Ok(Output {
            file,
            dir: dir.to_path_buf(),
            steps: Vec::new(),
        })
    }

    /// Opens the output of a run that `sim` resumes, to append to it; and
    /// whether its last step is `sim`'s present state (a checkpoint is taken
    /// with each output step). Output steps of a later time than `sim`'s
    /// are dropped when `drop_later` (the directory's own checkpoint is
    /// resumed: a run killed between an output step and its checkpoint
    /// left them); otherwise refused: they belong to a run that went further
    /// than the checkpoint, and appending would interleave two histories.
    pub fn append(dir: &Path, sim: &Simulation, drop_later: bool) -> CliResult<(Output, bool)> {
        let path = dir.join("run.h5");
        let fail = |why: String| CliError::input(format!("{}: {why}", path.display()));
        let file = hdf5::File::open_rw(&path).map_err(|e| fail(e.to_string()))?;
        let group = file
            .group("steps")
            .map_err(|e| fail(format!("not the output of tridem run: {e}")))?;
        let mut steps = Vec::new();
        for name in group.member_names().map_err(|e| fail(e.to_string()))? {
            let step = |e: hdf5::Error| fail(format!("steps/{name}: {e}"));
            let k: usize = name
                .parse()
                .map_err(|_| fail(format!("steps/{name}: not a step number")))?;
            let g = group.group(&name).map_err(step)?;
            let time: f64 = g.attr("time").and_then(|a| a.read_scalar()).map_err(step)?;
            let n = g.dataset("positions").map_err(step)?.shape()[0];
            let nt = g.dataset("surface/body").map_err(step)?.size();
            let nc = g
                .dataset("contact_forces/bodies")
                .map_or(0, |d| d.shape()[0]);
            steps.push(StepIndex {
                k,
                time,
                triangles: nt,
                bodies: n,
                contacts: nc,
            });
        }
        steps.sort_by_key(|s| s.k);
        if steps.iter().enumerate().any(|(i, s)| s.k != i) {
            return Err(fail("output steps are not numbered 0, 1, 2, ...".into()));
        }
        let (time, n) = (sim.world.time, sim.world.bodies.len());
        if let Some(s) = steps.iter().find(|s| s.bodies != n) {
            return Err(fail(format!(
                "output step {} has {} bodies, the resumed run {n}",
                s.k, s.bodies
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
        let out = Output {
            file,
            dir: dir.to_path_buf(),
            steps,
        };
        out.file.flush().map_err(h5err)?;
        out.write_xdmf()?;
        Ok((out, current))
    }

    /// Writes the current state as the next output step, then rewrites the XDMF index.
    pub fn write_step(&mut self, sim: &Simulation) -> CliResult {
        let k = self.steps.len();
        let w = &sim.world;
        let n = w.bodies.len();
        let g = self
            .file
            .group("steps")
            .and_then(|s| s.create_group(&k.to_string()))
            .map_err(h5err)?;
        let vec3 =
            |f: &dyn Fn(usize) -> glam::DVec3| Array2::from_shape_fn((n, 3), |(r, c)| f(r)[c]);
        g.new_dataset_builder()
            .with_data(&vec3(&|i| w.bodies[i].x))
            .create("positions")
            .map_err(h5err)?;
        g.new_dataset_builder()
            .with_data(&vec3(&|i| w.bodies[i].v))
            .create("velocities")
            .map_err(h5err)?;
        g.new_dataset_builder()
            .with_data(&vec3(&|i| w.bodies[i].l))
            .create("angular_momenta")
            .map_err(h5err)?;
        let q = Array2::from_shape_fn((n, 4), |(r, c)| w.bodies[r].q.to_array()[c]);
        g.new_dataset_builder()
            .with_data(&q)
            .create("orientations")
            .map_err(h5err)?;
        let contacts = Array1::from(sim.contact_counts());
        g.new_dataset_builder()
            .with_data(&contacts)
            .create("contacts")
            .map_err(h5err)?;
        g.new_attr::<f64>()
            .create("time")
            .and_then(|a| a.write_scalar(&w.time))
            .map_err(h5err)?;

        // World-space surface for visualisation.
        let mut pts = Vec::new();
        let mut body = Vec::new();
        for (bi, b) in w.bodies.iter().enumerate() {
            let m = &w.shapes[b.shape];
            for t in &m.triangles {
                for &v in t {
                    pts.push(b.to_world(m.vertices[v as usize]));
                }
                body.push(bi as u32);
            }
        }
        let nt = body.len();
        let s = g.create_group("surface").map_err(h5err)?;
        let p = Array2::from_shape_fn((3 * nt, 3), |(r, c)| pts[r][c]);
        let t = Array2::from_shape_fn((nt, 3), |(r, c)| (3 * r + c) as u32);
        s.new_dataset_builder()
            .with_data(&p)
            .create("points")
            .map_err(h5err)?;
        s.new_dataset_builder()
            .with_data(&t)
            .create("triangles")
            .map_err(h5err)?;
        s.new_dataset_builder()
            .with_data(&Array1::from(body))
            .create("body")
            .map_err(h5err)?;
        write_energies(&g, sim)?;
        let nc = write_contacts(&g, sim)?;
        self.file.flush().map_err(h5err)?;
        self.steps.push(StepIndex {
            k,
            time: w.time,
            triangles: nt,
            bodies: n,
            contacts: nc,
        });
        self.write_xdmf()
    }

    fn write_xdmf(&self) -> CliResult {
        let mut x = String::new();
        let _ = writeln!(x, r#"<?xml version="1.0" ?>"#);
        let _ = writeln!(x, r#"<Xdmf Version="3.0"><Domain>"#);
        let _ = writeln!(
            x,
            r#"<Grid Name="surface" GridType="Collection" CollectionType="Temporal">"#
        );
        for &StepIndex {
            k,
            time: t,
            triangles: nt,
            ..
        } in &self.steps
        {
            let _ = writeln!(
                x,
                r#"<Grid Name="step{k}" GridType="Uniform"><Time Value="{t:e}"/>"#
            );
            let _ = writeln!(
                x,
                r#"<Topology TopologyType="Triangle" NumberOfElements="{nt}"><DataItem Dimensions="{nt} 3" NumberType="UInt" Precision="4" Format="HDF">run.h5:/steps/{k}/surface/triangles</DataItem></Topology>"#
            );
            let _ = writeln!(
                x,
                r#"<Geometry GeometryType="XYZ"><DataItem Dimensions="{} 3" NumberType="Float" Precision="8" Format="HDF">run.h5:/steps/{k}/surface/points</DataItem></Geometry>"#,
                3 * nt
            );
            let _ = writeln!(
                x,
                r#"<Attribute Name="body" AttributeType="Scalar" Center="Cell"><DataItem Dimensions="{nt}" NumberType="UInt" Precision="4" Format="HDF">run.h5:/steps/{k}/surface/body</DataItem></Attribute>"#
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

/// The energy attributes of one output step.
fn write_energies(g: &hdf5::Group, sim: &Simulation) -> CliResult {
    let e = sim.energies();
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
fn write_contacts(g: &hdf5::Group, sim: &Simulation) -> CliResult<usize> {
    let forces: Vec<_> = sim.contact_forces().collect();
    let nc = forces.len();
    let group = g.create_group("contact_forces").map_err(h5err)?;
    let points = Array2::from_shape_fn((nc, 3), |(r, c)| forces[r].0.point[c]);
    let f = Array2::from_shape_fn((nc, 3), |(r, c)| forces[r].1[c]);
    let bodies = Array2::from_shape_fn((nc, 2), |(r, c)| {
        let contact = forces[r].0;
        [contact.a, contact.b][c] as u32
    });
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
