//! A [`Checkpoint`] on disk, as HDF5, so that h5dump and h5py read it too.
//!
//! Layout of `checkpoint.h5`:
//! - attributes `format` (= 3), `time`, `step`, `dt`, `fingerprint` (the scene's),
//!   `checksum` (of every number and name below: a damaged file is refused)
//! - `positions`, `velocities`, `angular_momenta`, `forces`, `torques` (N×3),
//!   `orientations` (N×4, xyzw)
//! - `removed` (N, 0 or 1): the particles an outflow took out, and
//!   `pending` (N, 0 or 1): those waiting to be inserted; each written only
//!   when there are any (absent: none)
//! - `effects/<name>/`: each stateful effect, with its place in the pipeline
//!   as the attribute `position` and the length of its history's rows as
//!   `row`; datasets `stored` and `taken`, the parts of its books' exact sums
//!   (canonical: the same sums give the same numbers), and `history`, its
//!   per-contact state (rows of `row` numbers, each starting with the
//!   contact's two body ids).
//!
//! A checkpoint is written beside and renamed over the last one: a run killed
//! while writing leaves the previous checkpoint whole.
//!
//! A distributed run resumes with [`read_share`]: each rank reads only the
//! rows of its own particles (a strided selection) and the history rows it
//! restores, in chunks; rank 0 checks the whole file's checksum as it
//! streams by. No rank holds the whole checkpoint.

use crate::error::{CliError, CliResult};
use dem::checkpoint::{BodyState, Checkpoint, CheckpointShare, Digest, EffectState};
use dem::scene::Deal;
use glam::{DQuat, DVec3};
use ndarray::{s, Array1, Array2};
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
    for (name, flag) in FLAGS {
        if b.iter().any(flag) {
            let rows: Array1<u8> = b.iter().map(|s| u8::from(flag(s))).collect();
            file.new_dataset_builder().with_data(&rows).create(name)?;
        }
    }
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

/// The flag columns, each written only when some body has the flag.
type Flag = fn(&BodyState) -> bool;
const FLAGS: [(&str, Flag); 2] = [("removed", |s| s.removed), ("pending", |s| s.pending)];

/// The whole checkpoint at `path`, as one process resumes it.
pub fn read(path: &Path) -> CliResult<Checkpoint> {
    let whole = read_share(path, Deal::WHOLE, usize::MAX)?;
    Ok(Checkpoint {
        time: whole.time,
        step: whole.step,
        dt: whole.dt,
        fingerprint: whole.fingerprint,
        bodies: whole.bodies,
        force: whole.force,
        torque: whole.torque,
        effects: whole.effects,
    })
}

/// Rows read at once when a checkpoint is streamed.
const CHUNK: usize = 1 << 14;

/// The share of the checkpoint at `path` that `deal` gives one rank of a
/// run of a scene of `particles` particles (see the module doc). Rank 0
/// also checks the whole file's checksum, so that a damaged file is refused
/// by the rank that reports.
pub fn read_share(path: &Path, deal: Deal, particles: usize) -> CliResult<CheckpointShare> {
    let file = Opened::open(path)?;
    if deal.rank == 0 {
        file.verify()?;
    }
    let n = file.rows_of("positions", 3)?;
    file.same_rows(n)?;
    let counts = [n, file.rows_of("forces", 3)?, file.rows_of("torques", 3)?];
    let strided = |name: &str, width: usize, rows: usize| -> CliResult<Array2<f64>> {
        let ids = rows.min(particles);
        let start = (deal.rank as usize).min(ids);
        let step = deal.ranks.max(1) as usize;
        file.dataset(name)?
            .read_slice_2d(s![start..ids;step, 0..width])
            .map_err(|e| file.fail(format!("dataset {name}: {e}")))
    };
    let vec3 = |name: &str, rows: usize| -> CliResult<Vec<DVec3>> {
        let a = strided(name, 3, rows)?;
        Ok(a.rows()
            .into_iter()
            .map(|r| DVec3::new(r[0], r[1], r[2]))
            .collect())
    };
    let (x, v, l) = (
        vec3("positions", n)?,
        vec3("velocities", n)?,
        vec3("angular_momenta", n)?,
    );
    let q = strided("orientations", 4, n)?;
    let column = |name: &str| -> CliResult<Vec<bool>> {
        match file.flag_rows(name, n)? {
            false => Ok(vec![false; x.len()]),
            true => {
                let (ids, step) = (n.min(particles), deal.ranks.max(1) as usize);
                let start = (deal.rank as usize).min(ids);
                let r = file
                    .dataset(name)?
                    .read_slice_1d(s![start..ids;step])
                    .map_err(|e| file.fail(format!("dataset {name}: {e}")))?;
                file.flags(name, r)
            }
        }
    };
    let (removed, pending) = (column("removed")?, column("pending")?);
    let bodies = (0..x.len())
        .map(|k| BodyState {
            x: x[k],
            q: DQuat::from_xyzw(q[[k, 0]], q[[k, 1]], q[[k, 2]], q[[k, 3]]),
            v: v[k],
            l: l[k],
            removed: removed[k],
            pending: pending[k],
        })
        .collect();
    let (force, torque) = (vec3("forces", counts[1])?, vec3("torques", counts[2])?);
    let mut effects = Vec::new();
    for (name, row) in file.effects()? {
        let numbers = |what: &str| file.numbers(&name, what, 0..usize::MAX);
        let (stored, taken) = (numbers("stored")?, numbers("taken")?);
        let len = file.length(&name, "history")?;
        if row == 0 && len > 0 {
            return Err(file.fail(format!("effects/{name}: history rows of {row} numbers")));
        }
        let history = if row < 2 || !len.is_multiple_of(row) {
            deal.rows_kept(&numbers("history")?, row, particles)
        } else {
            let mut kept = Vec::new();
            for at in (0..len).step_by(CHUNK * row) {
                let chunk = file.numbers(&name, "history", at..(at + CHUNK * row).min(len))?;
                kept.extend(deal.rows_kept(&chunk, row, particles));
            }
            kept
        };
        effects.push(EffectState {
            effect: name,
            stored,
            taken,
            row,
            history,
        });
    }
    Ok(CheckpointShare {
        time: file.attr_f64("time")?,
        step: file.attr_u64("step")?,
        dt: file.attr_f64("dt")?,
        fingerprint: file.attr_u64("fingerprint")?,
        counts,
        deal,
        bodies,
        force,
        torque,
        effects,
    })
}

/// An open checkpoint file of the format this tridem reads, and the
/// messages that name it.
struct Opened<'p> {
    path: &'p Path,
    file: hdf5::File,
}

impl<'p> Opened<'p> {
    fn open(path: &'p Path) -> CliResult<Opened<'p>> {
        let fail = |why: String| CliError::input(format!("{}: {why}", path.display()));
        if !path.is_file() {
            return Err(fail("no such checkpoint file".into()));
        }
        let file = hdf5::File::open(path)
            .map_err(|e| fail(format!("not an HDF5 file (a tridem checkpoint): {e}")))?;
        let opened = Opened { path, file };
        let format = opened.attr_u64("format")?;
        if format != FORMAT {
            return Err(opened.fail(format!(
                "checkpoint format {format}; this tridem reads format {FORMAT}"
            )));
        }
        Ok(opened)
    }

    fn fail(&self, why: String) -> CliError {
        CliError::input(format!("{}: {why}", self.path.display()))
    }

    fn attr_u64(&self, name: &str) -> CliResult<u64> {
        self.file
            .attr(name)
            .and_then(|a| a.read_scalar())
            .map_err(|e| self.fail(format!("not a tridem checkpoint: attribute {name}: {e}")))
    }

    fn attr_f64(&self, name: &str) -> CliResult<f64> {
        self.file
            .attr(name)
            .and_then(|a| a.read_scalar())
            .map_err(|e| self.fail(format!("not a tridem checkpoint: attribute {name}: {e}")))
    }

    fn dataset(&self, name: &str) -> CliResult<hdf5::Dataset> {
        self.file
            .dataset(name)
            .map_err(|e| self.fail(format!("dataset {name}: {e}")))
    }

    /// Rows of the 2-D dataset `name`, which must have `width` columns.
    fn rows_of(&self, name: &str, width: usize) -> CliResult<usize> {
        let shape = self.dataset(name)?.shape();
        match shape[..] {
            [rows, w] if w == width => Ok(rows),
            [_, w] => Err(self.fail(format!("dataset {name} has {w} columns, {width} expected"))),
            _ => Err(self.fail(format!("dataset {name} is not a table of {width} columns"))),
        }
    }

    /// Whether the file holds the flag column `name` (of `n` rows, each 0 or 1).
    fn flag_rows(&self, name: &str, n: usize) -> CliResult<bool> {
        if !self.file.link_exists(name) {
            return Ok(false);
        }
        let d = self.dataset(name)?;
        if d.shape()[..] != [n] {
            return Err(self.fail(format!("dataset {name} does not hold {n} rows")));
        }
        Ok(true)
    }

    /// Rows of the flag column `name` (refused unless each is 0 or 1).
    fn flags(&self, name: &str, rows: Array1<u8>) -> CliResult<Vec<bool>> {
        match rows.iter().all(|&v| v <= 1) {
            true => Ok(rows.iter().map(|&v| v == 1).collect()),
            false => Err(self.fail(format!("dataset {name} holds a value other than 0 and 1"))),
        }
    }

    /// The bodies' states hold `n` rows each.
    fn same_rows(&self, n: usize) -> CliResult {
        let (v, l, q) = (
            self.rows_of("velocities", 3)?,
            self.rows_of("angular_momenta", 3)?,
            self.rows_of("orientations", 4)?,
        );
        if [v, l, q] != [n; 3] {
            return Err(self.fail(format!(
                "positions, velocities, angular momenta and orientations of {n}, {v}, {l} and {q} bodies"
            )));
        }
        Ok(())
    }

    /// The stateful effects, in pipeline order, with their rows' lengths.
    fn effects(&self) -> CliResult<Vec<(String, usize)>> {
        let group = self
            .file
            .group("effects")
            .map_err(|e| self.fail(format!("group effects: {e}")))?;
        let mut found = Vec::new();
        for name in group.member_names().map_err(|e| self.fail(e.to_string()))? {
            let g = group
                .group(&name)
                .map_err(|e| self.fail(format!("effects/{name}: {e}")))?;
            let attr = |what: &str| -> CliResult<u64> {
                g.attr(what)
                    .and_then(|a| a.read_scalar())
                    .map_err(|e| self.fail(format!("effects/{name}: attribute {what}: {e}")))
            };
            let (position, row) = (attr("position")?, attr("row")?);
            if row as usize > MAX_ROW {
                return Err(self.fail(format!("effects/{name}: history rows of {row} numbers")));
            }
            found.push((position, name, row as usize));
        }
        found.sort_by_key(|(p, _, _)| *p);
        Ok(found.into_iter().map(|(_, n, r)| (n, r)).collect())
    }

    fn length(&self, effect: &str, what: &str) -> CliResult<usize> {
        let d = self
            .file
            .dataset(&format!("effects/{effect}/{what}"))
            .map_err(|e| self.fail(format!("effects/{effect}/{what}: {e}")))?;
        match d.shape()[..] {
            [n] => Ok(n),
            _ => Err(self.fail(format!("effects/{effect}/{what} is not a list of numbers"))),
        }
    }

    /// Numbers `range` (clipped to its length) of an effect's dataset.
    fn numbers(
        &self,
        effect: &str,
        what: &str,
        range: std::ops::Range<usize>,
    ) -> CliResult<Vec<f64>> {
        let len = self.length(effect, what)?;
        let (a, b) = (range.start.min(len), range.end.min(len));
        let d = self
            .file
            .dataset(&format!("effects/{effect}/{what}"))
            .map_err(|e| self.fail(format!("effects/{effect}/{what}: {e}")))?;
        let v: Array1<f64> = d
            .read_slice_1d(s![a..b])
            .map_err(|e| self.fail(format!("effects/{effect}/{what}: {e}")))?;
        Ok(v.to_vec())
    }

    /// Checks the whole file's checksum, streaming it in chunks.
    fn verify(&self) -> CliResult {
        let mut d = Digest::new(
            self.attr_f64("time")?,
            self.attr_u64("step")?,
            self.attr_f64("dt")?,
            self.attr_u64("fingerprint")?,
        );
        let n = self.rows_of("positions", 3)?;
        self.same_rows(n)?;
        d.count(n);
        let chunk = |name: &str, at: usize, end: usize, width: usize| -> CliResult<Array2<f64>> {
            self.dataset(name)?
                .read_slice_2d(s![at..end, 0..width])
                .map_err(|e| self.fail(format!("dataset {name}: {e}")))
        };
        let with = [self.flag_rows("removed", n)?, self.flag_rows("pending", n)?];
        for at in (0..n).step_by(CHUNK) {
            let end = (at + CHUNK).min(n);
            let column = |name: &str, present: bool| match present {
                true => self.flags(
                    name,
                    self.dataset(name)?
                        .read_slice_1d(s![at..end])
                        .map_err(|e| self.fail(format!("dataset {name}: {e}")))?,
                ),
                false => Ok(vec![false; end - at]),
            };
            let (removed, pending) = (column("removed", with[0])?, column("pending", with[1])?);
            let (x, v, l, q) = (
                chunk("positions", at, end, 3)?,
                chunk("velocities", at, end, 3)?,
                chunk("angular_momenta", at, end, 3)?,
                chunk("orientations", at, end, 4)?,
            );
            for k in 0..end - at {
                let row3 = |a: &Array2<f64>| DVec3::new(a[[k, 0]], a[[k, 1]], a[[k, 2]]);
                d.body(&BodyState {
                    x: row3(&x),
                    q: DQuat::from_xyzw(q[[k, 0]], q[[k, 1]], q[[k, 2]], q[[k, 3]]),
                    v: row3(&v),
                    l: row3(&l),
                    removed: removed[k],
                    pending: pending[k],
                });
            }
        }
        for name in ["forces", "torques"] {
            let rows = self.rows_of(name, 3)?;
            for at in (0..rows).step_by(CHUNK) {
                let a = chunk(name, at, (at + CHUNK).min(rows), 3)?;
                a.rows()
                    .into_iter()
                    .for_each(|r| d.vector(DVec3::new(r[0], r[1], r[2])));
            }
        }
        for (name, row) in self.effects()? {
            d.effect(&name, row);
            for what in ["stored", "taken", "history"] {
                let len = self.length(&name, what)?;
                d.count(len);
                for at in (0..len).step_by(CHUNK * 8) {
                    let numbers = self.numbers(&name, what, at..at + CHUNK * 8)?;
                    numbers.into_iter().for_each(|v| d.number(v));
                }
            }
        }
        let stored = self.attr_u64("checksum")?;
        let computed = d.finish();
        if stored != computed {
            return Err(self.fail(format!(
                "damaged: its checksum {stored:#018x} does not match its contents ({computed:#018x}); \
                 resume from an earlier copy"
            )));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A checkpoint of `n` bodies (the last `obstacles` of them obstacles)
    /// with distinct numbers everywhere, and a friction-like history of
    /// `rows` contacts (8 numbers a row, a < b), some touching an obstacle.
    fn checkpoint(n: usize, obstacles: usize, rows: usize) -> Checkpoint {
        let f = |i: usize, k: usize| (i * 17 + k) as f64 * 0.25 + 1.0 / (i + 1) as f64;
        let v = |i: usize, k: usize| DVec3::new(f(i, k), f(i, k + 1), f(i, k + 2));
        let mut history = Vec::new();
        for r in 0..rows {
            let a = (r * 7) % (n - obstacles);
            let b = if r % 5 == 0 { n - 1 } else { a + 1 + r % 3 };
            let (a, b) = (a.min(b), a.max(b));
            history.extend([
                a as f64,
                b as f64,
                1.0,
                r as f64,
                0.0,
                f(r, 1),
                f(r, 2),
                f(r, 3),
            ]);
        }
        Checkpoint {
            time: 0.125,
            step: 42,
            dt: 1e-5,
            fingerprint: 0xfeed,
            bodies: (0..n)
                .map(|i| BodyState {
                    x: v(i, 0),
                    q: DQuat::from_xyzw(f(i, 3), f(i, 4), f(i, 5), f(i, 6)),
                    v: v(i, 7),
                    l: v(i, 10),
                    // Some particles taken out by an outflow.
                    removed: i % 11 == 3 && i < n - obstacles,
                    pending: i % 13 == 5 && i < n - obstacles,
                })
                .collect(),
            force: (0..n).map(|i| v(i, 13)).collect(),
            torque: (0..n).map(|i| v(i, 16)).collect(),
            effects: vec![EffectState {
                effect: "friction".into(),
                stored: vec![1.5, -2.0],
                taken: vec![0.5],
                row: 8,
                history,
            }],
        }
    }

    fn temp(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("tridem-ckpt-{name}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        dir.join("checkpoint.h5")
    }

    #[test]
    fn each_rank_reads_exactly_its_share_and_the_shares_make_the_whole() {
        // More bodies and history rows than one chunk, so that the strided
        // and chunked reads cross chunk bounds.
        let (n, obstacles) = (CHUNK * 2 + 37, 3);
        let c = checkpoint(n, obstacles, CHUNK + 999);
        let path = temp("shares");
        write(&path, &c).unwrap();
        assert_eq!(read(&path).unwrap(), c, "the whole checkpoint read back");
        let particles = n - obstacles;
        for ranks in 1..=4u32 {
            let mut seen = vec![0; particles];
            let mut rows = 0;
            for rank in 0..ranks {
                let deal = Deal { rank, ranks };
                let share = read_share(&path, deal, particles).unwrap();
                // A second method: the share taken in memory.
                assert_eq!(share, CheckpointShare::of(&c, deal, particles));
                for (id, s, f, t) in share.held() {
                    assert_eq!((*s, *f, *t), (c.bodies[id], c.force[id], c.torque[id]));
                    seen[id] += 1;
                }
                rows += share.effects[0].history.len() / 8;
            }
            assert!(
                seen.iter().all(|&k| k == 1),
                "{ranks} ranks: each particle once"
            );
            assert_eq!(
                rows,
                c.effects[0].history.len() / 8,
                "{ranks} ranks: each row once"
            );
        }
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }

    #[test]
    fn rank_zero_refuses_a_damaged_file_without_holding_it() {
        let c = checkpoint(500, 2, 300);
        let path = temp("damaged");
        write(&path, &c).unwrap();
        let mut damaged = c.clone();
        damaged.effects[0].history[8 * 250 + 6] += 1e-12;
        let file = hdf5::File::open_rw(&path).unwrap();
        let g = file.group("effects/friction").unwrap();
        g.unlink("history").unwrap();
        g.new_dataset_builder()
            .with_data(&Array1::from(damaged.effects[0].history.clone()))
            .create("history")
            .unwrap();
        file.close().unwrap();
        let e = read_share(&path, Deal { rank: 0, ranks: 2 }, 498).unwrap_err();
        assert!(format!("{e}").contains("damaged"), "{e}");
        assert!(read(&path).is_err());
        let _ = std::fs::remove_dir_all(path.parent().unwrap());
    }
}
