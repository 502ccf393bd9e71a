//! `tridem plot DIR`: a run's per-step scalars over time, from its output.
//!
//! The scalars of an output step are the attributes of `/steps/<k>/energy`
//! (kinetic energy and each effect's stored and dissipated energy, J), their
//! sum `total`, and `contacts` (the contacts at that step).

use crate::cli::PlotArgs;
use crate::error::{CliError, CliResult};
use crate::plot::{lines, Look, Series};
use std::path::Path;

/// The scalars of every output step, in step order.
struct Steps {
    time: Vec<f64>,
    /// Name, and its value at each step.
    scalars: Vec<(String, Vec<f64>)>,
}

impl Steps {
    fn get(&self, name: &str) -> Option<&[f64]> {
        self.scalars
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }

    fn names(&self) -> Vec<&str> {
        self.scalars.iter().map(|(n, _)| n.as_str()).collect()
    }
}

pub fn run(args: &PlotArgs) -> CliResult {
    let steps = read(&args.dir)?;
    if args.list {
        steps.names().iter().for_each(|n| println!("{n}"));
        return Ok(());
    }
    if !args.energy && args.series.is_empty() {
        return Err(CliError::input(
            "nothing to plot: give --energy or --series NAME (--list names the series)",
        ));
    }
    for name in &args.series {
        if steps.get(name).is_none() {
            return Err(CliError::input(format!(
                "{}: no series `{name}` (it has: {})",
                args.dir.join("run.h5").display(),
                steps.names().join(", ")
            )));
        }
    }
    if args.energy {
        let names: Vec<&str> = steps
            .names()
            .into_iter()
            .filter(|n| *n != "contacts")
            .collect();
        let caption = "Energy books: their sum is constant up to the integrator's error";
        plot(&args.dir, "energy", caption, "energy (J)", &steps, &names)?;
    }
    for name in &args.series {
        let file = format!("series-{name}");
        let unit = if name == "contacts" { "count" } else { "J" };
        plot(
            &args.dir,
            &file,
            name,
            &format!("{name} ({unit})"),
            &steps,
            &[name],
        )?;
    }
    Ok(())
}

/// DIR/FILE.{svg,png,csv}: the series `names` against time.
fn plot(
    dir: &Path,
    file: &str,
    caption: &str,
    ydesc: &str,
    steps: &Steps,
    names: &[&str],
) -> CliResult {
    let series: Vec<Series> = names
        .iter()
        .map(|&n| Series {
            name: n.to_string(),
            points: steps
                .time
                .iter()
                .copied()
                .zip(steps.get(n).unwrap_or(&[]).iter().copied())
                .collect(),
            errors: Vec::new(),
        })
        .collect();
    let svg = dir.join(format!("{file}.svg"));
    let look = Look {
        y_from: None,
        markers: steps.time.len() <= 30,
        ..Look::default()
    };
    lines(&svg, caption, ("time (s)", ydesc), &series, look)
        .map_err(|e| CliError::runtime(format!("{}: {e}", svg.display())))?;
    let mut csv = format!("time,{}\n", names.join(","));
    for (k, t) in steps.time.iter().enumerate() {
        let row: Vec<String> = names
            .iter()
            .map(|n| format!("{:e}", steps.get(n).map_or(f64::NAN, |v| v[k])))
            .collect();
        csv.push_str(&format!("{t:e},{}\n", row.join(",")));
    }
    let path = dir.join(format!("{file}.csv"));
    std::fs::write(&path, csv)
        .map_err(|e| CliError::runtime(format!("{}: {e}", path.display())))?;
    eprintln!(
        "wrote {}, {} and {}",
        svg.display(),
        svg.with_extension("png").display(),
        path.display()
    );
    Ok(())
}

/// How far the energy books of the run in `dir` stray: the largest departure
/// of their sum (kinetic, stored and dissipated) from its value at the
/// first output step, over the largest kinetic energy of the output steps.
pub(crate) fn books_drift(dir: &Path) -> CliResult<f64> {
    let steps = read(dir)?;
    let column = |n: &str| steps.get(n).unwrap_or(&[]).to_vec();
    let (total, t, r) = (
        column("total"),
        column("kinetic_translation"),
        column("kinetic_rotation"),
    );
    let start = total.first().copied().unwrap_or(0.0);
    let drift = total.iter().map(|v| (v - start).abs()).fold(0.0, f64::max);
    let kinetic = t.iter().zip(&r).map(|(a, b)| a + b).fold(0.0, f64::max);
    Ok(if kinetic > 0.0 {
        drift / kinetic
    } else {
        drift
    })
}

/// Every output step's scalars from DIR/run.h5.
fn read(dir: &Path) -> CliResult<Steps> {
    let path = dir.join("run.h5");
    let fail = |why: String| CliError::input(format!("{}: {why}", path.display()));
    let file = hdf5::File::open(&path).map_err(|e| fail(e.to_string()))?;
    let group = file
        .group("steps")
        .map_err(|e| fail(format!("not the output of tridem run: {e}")))?;
    let mut ks: Vec<usize> = group
        .member_names()
        .map_err(|e| fail(e.to_string()))?
        .iter()
        .filter_map(|n| n.parse().ok())
        .collect();
    ks.sort_unstable();
    if ks.is_empty() {
        return Err(fail("no output steps".into()));
    }
    let mut steps = Steps {
        time: Vec::new(),
        scalars: Vec::new(),
    };
    for (i, k) in ks.iter().enumerate() {
        let step = |e: hdf5::Error| fail(format!("steps/{k}: {e}"));
        let g = group.group(&k.to_string()).map_err(step)?;
        steps
            .time
            .push(g.attr("time").and_then(|a| a.read_scalar()).map_err(step)?);
        let energy = g.group("energy").map_err(step)?;
        let mut names = energy.attr_names().map_err(step)?;
        names.sort_by_key(|n| order(n));
        let mut values: Vec<(String, f64)> = Vec::new();
        for n in names {
            let v: f64 = energy
                .attr(&n)
                .and_then(|a| a.read_scalar())
                .map_err(step)?;
            values.push((n, v));
        }
        let total = values.iter().map(|(_, v)| v).sum();
        values.push(("total".into(), total));
        let contacts = g
            .dataset("contact_forces/bodies")
            .map_or(0, |d| d.shape()[0]);
        values.push(("contacts".into(), contacts as f64));
        if i == 0 {
            steps.scalars = values
                .iter()
                .map(|(n, _)| (n.clone(), Vec::new()))
                .collect();
        }
        for (n, v) in values {
            match steps.scalars.iter_mut().find(|(m, _)| *m == n) {
                Some((_, column)) if column.len() == i => column.push(v),
                _ => {
                    return Err(fail(format!(
                        "steps/{k}: its energy books differ from step {}'s",
                        ks[0]
                    )))
                }
            }
        }
    }
    Ok(steps)
}

/// Kinetic energy first, then the effects' books in the order written.
fn order(name: &str) -> (u8, String) {
    let rank = match name {
        "kinetic_translation" => 0,
        "kinetic_rotation" => 1,
        _ => 2,
    };
    (rank, name.to_string())
}

/// `tridem chart`: columns of a CSV file against one another.
pub fn chart(args: &crate::cli::ChartArgs) -> CliResult {
    let path = &args.csv;
    let fail = |why: String| CliError::input(format!("{}: {why}", path.display()));
    let text = std::fs::read_to_string(path).map_err(|e| fail(e.to_string()))?;
    let mut rows = text.lines();
    let header: Vec<&str> = rows
        .next()
        .ok_or_else(|| fail("empty; a header line was expected".into()))?
        .split(',')
        .map(str::trim)
        .collect();
    let column = |name: &str| {
        header.iter().position(|h| *h == name).ok_or_else(|| {
            fail(format!(
                "no column {name}; the columns are {}",
                header.join(", ")
            ))
        })
    };
    let (x, y) = (column(&args.x)?, column(&args.y)?);
    let by = args.by.as_deref().map(column).transpose()?;
    let error = args.error.as_deref().map(column).transpose()?;
    let mut series: Vec<Series> = Vec::new();
    for (k, line) in rows.enumerate().filter(|(_, l)| !l.trim().is_empty()) {
        let cells: Vec<&str> = line.split(',').map(str::trim).collect();
        let at = |i: usize, what: &str| -> CliResult<f64> {
            cells
                .get(i)
                .and_then(|c| c.parse().ok())
                .ok_or_else(|| fail(format!("line {}: column {what} holds no number", k + 2)))
        };
        let point = (at(x, &args.x)?, at(y, &args.y)?);
        // An empty error cell: that point has no bar (a fitted curve's).
        let e = match error {
            Some(i) if cells.get(i).is_some_and(|c| !c.is_empty()) => at(i, "error")?,
            _ => f64::NAN,
        };
        let name = by.map_or(args.y.clone(), |b| cells.get(b).unwrap_or(&"").to_string());
        let s = match series.iter().position(|s| s.name == name) {
            Some(k) => &mut series[k],
            None => {
                series.push(Series {
                    name,
                    points: Vec::new(),
                    errors: Vec::new(),
                });
                series.last_mut().expect("just pushed")
            }
        };
        s.points.push(point);
        s.errors.push(e);
    }
    for s in &mut series {
        let mut order: Vec<usize> = (0..s.points.len()).collect();
        order.sort_by(|&a, &b| s.points[a].0.total_cmp(&s.points[b].0));
        s.points = order.iter().map(|&k| s.points[k]).collect();
        s.errors = order.iter().map(|&k| s.errors[k]).collect();
        if error.is_none() {
            s.errors.clear();
        }
    }
    let caption = args
        .title
        .clone()
        .unwrap_or_else(|| format!("{} against {}", args.y, args.x));
    let look = Look {
        log_x: args.log_x,
        y_from: args.y_from,
        markers: true,
    };
    lines(&args.output, &caption, (&args.x, &args.y), &series, look)
        .map_err(|e| CliError::runtime(format!("{}: {e}", args.output.display())))?;
    eprintln!(
        "wrote {} and {}",
        args.output.display(),
        args.output.with_extension("png").display()
    );
    Ok(())
}
