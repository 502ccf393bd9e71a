//! `tridem render DIR`: a PNG of an output step of a run, from its
//! `run.h5` (docs/output.md): the particles coloured by a field, the
//! obstacles translucent, and optionally the contact network.

use crate::cli::{ColourBy, RenderArgs, View};
use crate::error::{CliError, CliResult};
use crate::output::Field;
use crate::raster::{category, scale, Camera, Picture};
use glam::DVec3;
use ndarray::{Array1, Array2};
use plotters::prelude::*;
use std::path::{Path, PathBuf};

/// What one output step draws from.
struct Step {
    time: f64,
    points: Vec<DVec3>,
    /// Per body: the value it is coloured by.
    value: Vec<f64>,
    lines: Vec<(DVec3, DVec3, f64)>,
}

/// What every step shares: the surface's triangles and bodies.
struct Surface {
    triangles: Array2<u32>,
    body: Array1<u32>,
    obstacle: Array1<u8>,
    material: Array1<u32>,
}

pub fn run(args: &RenderArgs) -> CliResult {
    let path = args.dir.join("run.h5");
    let fail = |why: String| CliError::input(format!("{}: {why}", path.display()));
    let file = hdf5::File::open(&path).map_err(|e| fail(e.to_string()))?;
    let fields = crate::output::fields_in(&file);
    let needs = [
        (Field::Surface, true, "a picture"),
        (
            Field::Particles,
            args.color_by == ColourBy::Speed,
            "--color-by speed",
        ),
        (Field::Contacts, args.contacts, "--contacts"),
    ];
    if let Some((f, _, what)) = needs
        .iter()
        .find(|(f, asked, _)| *asked && !fields.contains(f))
    {
        return Err(fail(format!(
            "written without the {} field (its scene's [output] fields), which {what} needs",
            f.name()
        )));
    }
    let surface =
        read_surface(&file).map_err(|e| fail(format!("not the output of tridem run: {e}")))?;
    let count = file.group("steps").map_err(|e| fail(e.to_string()))?.len() as usize;
    if count == 0 {
        return Err(fail("no output steps".into()));
    }
    let steps: Vec<usize> = match (args.all, args.step) {
        (true, _) => (0..count).collect(),
        (false, Some(k)) if k >= count => {
            return Err(CliError::input(format!(
                "--step {k}: {} has output steps 0 to {}",
                path.display(),
                count - 1
            )))
        }
        (false, k) => vec![k.unwrap_or(count - 1)],
    };
    let out = outputs(args, &steps)?;
    for (&k, png) in steps.iter().zip(&out) {
        let step =
            read_step(&file, k, args, &surface).map_err(|e| fail(format!("steps/{k}: {e}")))?;
        draw(args, &surface, &step, k, png)?;
        eprintln!("wrote {}", png.display());
    }
    Ok(())
}

/// The PNG of each step: `--output` (a file for one step, a directory for
/// several), or beside the run.
fn outputs(args: &RenderArgs, steps: &[usize]) -> CliResult<Vec<PathBuf>> {
    let name = |k: usize| format!("render-step-{k:05}.png");
    let dir = match (&args.output, steps.len()) {
        (Some(p), 1) if p.extension().is_some_and(|e| e == "png") => return Ok(vec![p.clone()]),
        (Some(p), _) => p.clone(),
        (None, _) => args.dir.clone(),
    };
    std::fs::create_dir_all(&dir)
        .map_err(|e| CliError::runtime(format!("{}: {e}", dir.display())))?;
    Ok(steps.iter().map(|&k| dir.join(name(k))).collect())
}

fn read_surface(file: &hdf5::File) -> hdf5::Result<Surface> {
    Ok(Surface {
        triangles: file.dataset("surface/triangles")?.read_2d()?,
        body: file.dataset("surface/body")?.read_1d()?,
        obstacle: file.dataset("bodies/obstacle")?.read_1d()?,
        material: file.dataset("bodies/material")?.read_1d()?,
    })
}

fn read_step(file: &hdf5::File, k: usize, args: &RenderArgs, s: &Surface) -> hdf5::Result<Step> {
    let g = file.group(&format!("steps/{k}"))?;
    let rows = |a: Array2<f64>| -> Vec<DVec3> {
        a.rows()
            .into_iter()
            .map(|r| DVec3::new(r[0], r[1], r[2]))
            .collect()
    };
    let points = rows(g.dataset("surface/points")?.read_2d()?);
    let n = s.obstacle.len();
    let c = g.group("contact_forces")?;
    let ends = rows(c.dataset("line_points")?.read_2d()?);
    let magnitude: Array1<f64> = c.dataset("normal_force_magnitudes")?.read_1d()?;
    let pairs: Array2<u32> = c.dataset("bodies")?.read_2d()?;
    let value = match args.color_by {
        ColourBy::Speed => g.dataset("speeds")?.read_1d::<f64>()?.to_vec(),
        ColourBy::Body => (0..n).map(|i| i as f64).collect(),
        ColourBy::Material => s.material.iter().map(|&m| f64::from(m)).collect(),
        ColourBy::Force => {
            let mut f = vec![0.0; n];
            for (p, &m) in pairs.rows().into_iter().zip(magnitude.iter()) {
                f[p[0] as usize] += m;
                f[p[1] as usize] += m;
            }
            f
        }
    };
    let lines = (0..magnitude.len())
        .map(|i| (ends[2 * i], ends[2 * i + 1], magnitude[i]))
        .collect();
    Ok(Step {
        time: g.attr("time")?.read_scalar()?,
        points,
        value,
        lines,
    })
}

/// The particles' colours: a category, or the value on the scale from the
/// particles' least to their most.
fn colours(args: &RenderArgs, s: &Surface, step: &Step) -> (Vec<[f64; 3]>, (f64, f64)) {
    let moving = (0..s.obstacle.len()).filter(|&i| s.obstacle[i] == 0);
    let (lo, hi) = moving.fold((f64::INFINITY, f64::NEG_INFINITY), |(lo, hi), i| {
        (lo.min(step.value[i]), hi.max(step.value[i]))
    });
    let span = if hi > lo { hi - lo } else { 1.0 };
    let colour = |v: f64| match args.color_by {
        ColourBy::Body | ColourBy::Material => category(v as usize),
        ColourBy::Speed | ColourBy::Force => scale((v - lo) / span),
    };
    (step.value.iter().map(|&v| colour(v)).collect(), (lo, hi))
}

fn draw(args: &RenderArgs, s: &Surface, step: &Step, k: usize, png: &Path) -> CliResult {
    let size = (args.width, args.height);
    let forward = match args.view {
        View::Iso => DVec3::new(-1.0, 1.3, -0.8),
        View::Front => DVec3::Y,
        View::Side => -DVec3::X,
        View::Top => -DVec3::Z,
    };
    let framed: Vec<DVec3> = match args.whole_scene {
        true => step.points.clone(),
        false => s
            .triangles
            .rows()
            .into_iter()
            .zip(s.body.iter())
            .filter(|(_, &b)| s.obstacle[b as usize] == 0)
            .flat_map(|(t, _)| t.to_vec())
            .map(|v| step.points[v as usize])
            .collect(),
    };
    let cam = Camera::fitting(forward, &framed, size);
    let mut picture = Picture::new(size, [1.0; 3]);
    let (colour, range) = colours(args, s, step);
    let corners = |t: ndarray::ArrayView1<u32>| [0, 1, 2].map(|i| step.points[t[i] as usize]);
    // Particles first (opaque, with depth), then the obstacles over them.
    for pass_obstacles in [false, true] {
        for (t, &b) in s.triangles.rows().into_iter().zip(s.body.iter()) {
            let b = b as usize;
            if (s.obstacle[b] == 1) != pass_obstacles {
                continue;
            }
            let (c, alpha) = match pass_obstacles {
                true => ([0.55, 0.6, 0.65], 0.18),
                false => (colour[b], 1.0),
            };
            picture.triangle(&cam, corners(t), c, alpha);
        }
    }
    if args.contacts {
        let most = step.lines.iter().map(|l| l.2).fold(0.0, f64::max);
        for &(a, b, f) in &step.lines {
            let w = if most > 0.0 {
                1.0 + 3.0 * f / most
            } else {
                1.0
            };
            picture.line(&cam, a, b, [0.7, 0.05, 0.05], w);
        }
    }
    let caption = caption(args, step, k, range);
    write_png(png, &picture, &caption)
        .map_err(|e| CliError::runtime(format!("{}: {e}", png.display())))
}

fn caption(args: &RenderArgs, step: &Step, k: usize, (lo, hi): (f64, f64)) -> String {
    let what = match args.color_by {
        ColourBy::Speed => format!("colour: speed {lo:.3} to {hi:.3} m/s"),
        ColourBy::Force => format!("colour: contact force on the particle {lo:.3e} to {hi:.3e} N"),
        ColourBy::Body => "colour: body".into(),
        ColourBy::Material => "colour: material".into(),
    };
    let lines = if args.contacts {
        "; lines: contacts"
    } else {
        ""
    };
    format!(
        "{}  step {k}, t = {:.4} s; {what}{lines}",
        args.dir.display(),
        step.time
    )
}

fn write_png(path: &Path, p: &Picture, caption: &str) -> Result<(), Box<dyn std::error::Error>> {
    crate::plot::register_font();
    let root = BitMapBackend::new(path, p.size).into_drawing_area();
    for y in 0..p.size.1 {
        for x in 0..p.size.0 {
            let c = p
                .at(x, y)
                .map(|v| (v.clamp(0.0, 1.0) * 255.0).round() as u8);
            root.draw_pixel((x as i32, y as i32), &RGBColor(c[0], c[1], c[2]))?;
        }
    }
    root.draw(&Text::new(caption.to_string(), (8, 6), ("sans-serif", 15)))?;
    root.present()?;
    Ok(())
}
