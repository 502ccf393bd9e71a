//! A [`Checkpoint`] on disk, as HDF5, so that h5dump and h5py read it too.
//!
//! Layout of `checkpoint.h5`:
//! - attributes `format` (= 3), `time`, `step`, `dt`, `fingerprint` (the scene's),
//!   `checksum` (of every number and name below: a damaged file is refused)
//! - `positions`, `velocities`, `angular_momenta`, `forces`, `torques` (N×3),
//!   `orientations` (N×4, xyzw)
//! - `effects/<name>/`: each stateful effect, with its place in the pipeline
//!   as the attribute `position` and the length of its history's rows as
//!   `row`; datasets `stored` and `taken`, the parts of its books' exact sums
//!   (canonical: the same sums give the same numbers), and `history`, its
//!   per-contact state (rows of `row` numbers, each starting with the
//!   contact's two body ids).
//!
//! A checkpoint is written beside and renamed over the last one: a run killed
//! while writing leaves the previous checkpoint whole.

use crate::error::{CliError, CliResult};
use dem::checkpoint::{BodyState, Checkpoint, EffectState};
use glam::{DQuat, DVec3};
use ndarray::{Array1, Array2};
use std::path::Path;

const FORMAT: u64 = 3;

/// Numbers per history row at most: a row names a contact and its state, a
/// few dozen numbers; more is a damaged or foreign file.
const MAX_ROW: usize = 1024;

pub fn write(path: &Path, c: &Checkpoint) -> CliResult {
    let name = path.file_name().map_or_else(
        || "checkpoint.h5".into(),
        |n| n.to_string_lossy().into_owned(),
    );
    let tmp = path.with_file_name(format!("{name}.tmp"));
    let fail = |e: &dyn std::fmt::Display| {
        CliError::runtime(format!(
            "{}: cannot write the checkpoint: {e}",
            path.display()
        ))
    };
    write_to(&tmp, c).map_err(|e| fail(&e))?;
    std::fs::rename(&tmp, path).map_err(|e| fail(&e))
}

fn write_to(path: &Path, c: &Checkpoint) -> hdf5::Result<()> {
    let file = hdf5::File::create(path)?;
    file.new_attr::<u64>()
        .create("format")?
        .write_scalar(&FORMAT)?;
    file.new_attr::<f64>()
        .create("time")?
        .write_scalar(&c.time)?;
    file.new_attr::<u64>()
        .create("step")?
        .write_scalar(&c.step)?;
    file.new_attr::<f64>().create("dt")?.write_scalar(&c.dt)?;
    file.new_attr::<u64>()
        .create("fingerprint")?
        .write_scalar(&c.fingerprint)?;
    file.new_attr::<u64>()
        .create("checksum")?
        .write_scalar(&c.checksum())?;
    let rows = |v: Vec<[f64; 3]>| Array2::from_shape_fn((v.len(), 3), |(r, k)| v[r][k]);
    let b = &c.bodies;
    let columns: [(&str, Vec<[f64; 3]>); 5] = [
        ("positions", b.iter().map(|s| s.x.to_array()).collect()),
        ("velocities", b.iter().map(|s| s.v.to_array()).collect()),
        (
            "angular_momenta",
            b.iter().map(|s| s.l.to_array()).collect(),
        ),
        ("forces", c.force.iter().map(|f| f.to_array()).collect()),
        ("torques", c.torque.iter().map(|t| t.to_array()).collect()),
    ];
    for (name, v) in columns {
        file.new_dataset_builder()
            .with_data(&rows(v))
            .create(name)?;
    }
    let q = Array2::from_shape_fn((b.len(), 4), |(r, k)| b[r].q.to_array()[k]);
    file.new_dataset_builder()
        .with_data(&q)
        .create("orientations")?;
    let effects = file.create_group("effects")?;
    for (i, e) in c.effects.iter().enumerate() {
        let g = effects.create_group(e.effect.as_str())?;
        g.new_attr::<u64>()
            .create("position")?
            .write_scalar(&(i as u64))?;
        g.new_attr::<u64>()
            .create("row")?
            .write_scalar(&(e.row as u64))?;
        for (name, values) in [
            ("stored", &e.stored),
            ("taken", &e.taken),
            ("history", &e.history),
        ] {
            g.new_dataset_builder()
                .with_data(&Array1::from(values.clone()))
                .create(name)?;
        }
    }
    file.close()
}

pub fn read(path: &Path) -> CliResult<Checkpoint> {
    let fail = |why: String| CliError::input(format!("{}: {why}", path.display()));
    if !path.is_file() {
        return Err(fail("no such checkpoint file".into()));
    }
    let file = hdf5::File::open(path)
        .map_err(|e| fail(format!("not an HDF5 file (a tridem checkpoint): {e}")))?;
    let attr_u64 = |name: &str| -> CliResult<u64> {
        file.attr(name)
            .and_then(|a| a.read_scalar())
            .map_err(|e| fail(format!("not a tridem checkpoint: attribute {name}: {e}")))
    };
    let attr_f64 = |name: &str| -> CliResult<f64> {
        file.attr(name)
            .and_then(|a| a.read_scalar())
            .map_err(|e| fail(format!("not a tridem checkpoint: attribute {name}: {e}")))
    };
    let format = attr_u64("format")?;
    if format != FORMAT {
        return Err(fail(format!(
            "checkpoint format {format}; this tridem reads format {FORMAT}"
        )));
    }
    let columns = |name: &str, width: usize| -> CliResult<Vec<Vec<f64>>> {
        let a: Array2<f64> = file
            .dataset(name)
            .and_then(|d| d.read_2d())
            .map_err(|e| fail(format!("dataset {name}: {e}")))?;
        if a.ncols() != width {
            return Err(fail(format!(
                "dataset {name} has {} columns, {width} expected",
                a.ncols()
            )));
        }
        Ok(a.rows().into_iter().map(|r| r.to_vec()).collect())
    };
    let vec3 = |name: &str| -> CliResult<Vec<DVec3>> {
        Ok(columns(name, 3)?
            .into_iter()
            .map(|r| DVec3::new(r[0], r[1], r[2]))
            .collect())
    };
    let (x, v, l) = (
        vec3("positions")?,
        vec3("velocities")?,
        vec3("angular_momenta")?,
    );
    let q: Vec<DQuat> = columns("orientations", 4)?
        .into_iter()
        .map(|r| DQuat::from_xyzw(r[0], r[1], r[2], r[3]))
        .collect();
    let n = x.len();
    if [v.len(), l.len(), q.len()] != [n; 3] {
        return Err(fail(format!(
            "positions, velocities, angular momenta and orientations of {n}, {}, {} and {} bodies",
            v.len(),
            l.len(),
            q.len()
        )));
    }
    let bodies = (0..n)
        .map(|i| BodyState {
            x: x[i],
            q: q[i],
            v: v[i],
            l: l[i],
        })
        .collect();
    let mut effects = Vec::new();
    let group = file
        .group("effects")
        .map_err(|e| fail(format!("group effects: {e}")))?;
    for name in group.member_names().map_err(|e| fail(e.to_string()))? {
        let within = |e: hdf5::Error| fail(format!("effects/{name}: {e}"));
        let g = group.group(&name).map_err(within)?;
        let attr = |what: &str| -> CliResult<u64> {
            g.attr(what)
                .and_then(|a| a.read_scalar())
                .map_err(|e| fail(format!("effects/{name}: attribute {what}: {e}")))
        };
        let (position, row) = (attr("position")?, attr("row")?);
        let numbers = |what: &str| -> CliResult<Vec<f64>> {
            let v: Array1<f64> = g
                .dataset(what)
                .and_then(|d| d.read_1d())
                .map_err(|e| fail(format!("effects/{name}/{what}: {e}")))?;
            Ok(v.to_vec())
        };
        let (stored, taken, history) = (numbers("stored")?, numbers("taken")?, numbers("history")?);
        if row as usize > MAX_ROW || (row == 0 && !history.is_empty()) {
            return Err(fail(format!(
                "effects/{name}: history rows of {row} numbers"
            )));
        }
        effects.push((
            position,
            EffectState {
                effect: name.clone(),
                stored,
                taken,
                row: row as usize,
                history,
            },
        ));
    }
    effects.sort_by_key(|(p, _)| *p);
    let c = Checkpoint {
        time: attr_f64("time")?,
        step: attr_u64("step")?,
        dt: attr_f64("dt")?,
        fingerprint: attr_u64("fingerprint")?,
        bodies,
        force: vec3("forces")?,
        torque: vec3("torques")?,
        effects: effects.into_iter().map(|(_, e)| e).collect(),
    };
    let stored = attr_u64("checksum")?;
    if stored != c.checksum() {
        return Err(fail(format!(
            "damaged: its checksum {stored:#018x} does not match its contents ({:#018x}); \
             resume from an earlier copy",
            c.checksum()
        )));
    }
    Ok(c)
}
