//! Figures drawn with plotters, each written twice: SVG for documents and
//! PNG (same name, `.png`) for viewers that do not show SVG. The PNG's text
//! uses the DejaVu Sans font carried in `assets/`, so that figures look the
//! same on machines without fonts.

use plotters::coord::Shift;
use plotters::prelude::*;
use std::error::Error;
use std::path::Path;

type Res = Result<(), Box<dyn Error>>;

pub(crate) fn register_font() {
    static ONCE: std::sync::Once = std::sync::Once::new();
    ONCE.call_once(|| {
        let font: &'static [u8] = include_bytes!("../assets/DejaVuSans.ttf");
        // The font is valid: a failure here is a build defect, not input.
        plotters::style::register_font("sans-serif", FontStyle::Normal, font)
            .map_err(|_| "font")
            .expect("the embedded DejaVu Sans parses");
    });
}

/// Draws one figure with `$draw(root)` into `$path` (SVG) and beside it as PNG.
macro_rules! svg_and_png {
    ($path:expr, $size:expr, $draw:expr) => {{
        register_font();
        let path: &Path = $path;
        {
            let root = SVGBackend::new(path, $size).into_drawing_area();
            root.fill(&WHITE)?;
            $draw(&root)?;
            root.present()?;
        }
        let png = path.with_extension("png");
        let root = BitMapBackend::new(&png, $size).into_drawing_area();
        root.fill(&WHITE)?;
        $draw(&root)?;
        root.present()?;
        Ok(())
    }};
}

/// One measured setting of the penalty kernel.
pub struct Point {
    pub series: String,
    /// ns per pair.
    pub x: f64,
    /// Median |d - d_exact| / L over all pairs.
    pub y: f64,
    /// The largest |d - d_exact| / L.
    pub max: f64,
    /// Fraction of pairs certified to the tolerance.
    pub certified: f64,
    pub label: String,
}

/// Two panels against ns per pair: the median (filled) and largest (open)
/// error over L (log scale; the largest is set by the uncertified pairs) and
/// the fraction of pairs certified, which decides how often the hybrid falls
/// back.
pub fn error_vs_time(path: &Path, points: &[Point], pairs: usize) -> Res {
    svg_and_png!(path, (1100, 500), |root: &DrawingArea<_, Shift>| {
        let (left, right) = root.split_horizontally(550);
        accuracy_panel(&left, points, pairs, true)?;
        accuracy_panel(&right, points, pairs, false)
    })
}

/// Errors of exactly 0 cannot be shown on a log axis: floored here.
const ERROR_FLOOR: f64 = 1e-17;

/// The median error (log) or the fraction certified against ns per pair.
fn accuracy_panel<DB: DrawingBackend>(
    area: &DrawingArea<DB, Shift>,
    points: &[Point],
    pairs: usize,
    error: bool,
) -> Res
where
    DB::ErrorType: 'static,
{
    let xmax = (points.iter().map(|p| p.x).fold(0.0, f64::max) * 1.1).max(1.0);
    let ymax = points
        .iter()
        .map(|p| p.max.max(p.y).max(ERROR_FLOOR))
        .fold(ERROR_FLOOR, f64::max)
        * 100.0;
    let mut series: Vec<&str> = points.iter().map(|p| p.series.as_str()).collect();
    series.dedup();
    let ydesc = if error {
        "median (filled) and largest (open) error / L"
    } else {
        "fraction certified"
    };
    let caption = format!("penalty kernel, {pairs} random pairs: {ydesc}");
    let mut builder = ChartBuilder::on(area);
    builder
        .caption(caption, ("sans-serif", 15))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(60);
    let xdesc = "ns per pair (median of repetitions)";
    if error {
        let mut chart = builder.build_cartesian_2d(0.0..xmax, (ERROR_FLOOR..ymax).log_scale())?;
        chart
            .configure_mesh()
            .x_desc(xdesc)
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()?;
        plot_series(&mut chart, points, &series, &|p| p.y.max(ERROR_FLOOR))?;
        let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
        for (i, s) in series.iter().enumerate() {
            let color = Palette99::pick(i).to_rgba();
            chart
                .draw_series(
                    points.iter().filter(|p| p.series == *s).map(|p| {
                        Circle::new((p.x, p.max.max(ERROR_FLOOR)), 4, color.stroke_width(1))
                    }),
                )
                .map_err(e)?;
        }
    } else {
        let mut chart = builder.build_cartesian_2d(0.0..xmax, 0.0..1.05)?;
        chart.configure_mesh().x_desc(xdesc).draw()?;
        plot_series(&mut chart, points, &series, &|p| p.certified)?;
    }
    Ok(())
}

fn plot_series<'a, DB: DrawingBackend + 'a, Y>(
    chart: &mut ChartContext<'a, DB, Cartesian2d<plotters::coord::types::RangedCoordf64, Y>>,
    points: &[Point],
    series: &[&str],
    y: &dyn Fn(&Point) -> f64,
) -> Result<(), String>
where
    Y: Ranged<ValueType = f64>,
{
    let e = |e: DrawingAreaErrorKind<DB::ErrorType>| e.to_string();
    for (i, s) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let pts: Vec<&Point> = points.iter().filter(|p| p.series == *s).collect();
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.x, y(p))),
                color.stroke_width(1),
            ))
            .map_err(e)?
            .label(*s)
            .legend(move |(x, yy)| Circle::new((x + 10, yy), 4, color.filled()));
        chart
            .draw_series(pts.iter().map(|p| {
                EmptyElement::at((p.x, y(p)))
                    + Circle::new((0, 0), 4, color.filled())
                    + Text::new(p.label.clone(), (6, -6), ("sans-serif", 10))
            }))
            .map_err(e)?;
    }
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::LowerRight)
        .border_style(BLACK)
        .background_style(WHITE)
        .draw()
        .map_err(e)?;
    Ok(())
}

/// Reads one quantity of a record.
type Metric = fn(&PartitionRecord) -> f64;

/// One partitioning record, as `tridem partition --json` prints it.
pub struct PartitionRecord {
    pub workload: String,
    pub partitioner: String,
    pub step: u64,
    pub partition_s: f64,
    pub ghost_items: f64,
}

/// Two panels, partition time and ghost items (both log scale), one group of bars per
/// workload and one bar per partitioner; the first step of each run (from the initial
/// distribution by id).
pub fn partition_summary(path: &Path, records: &[PartitionRecord]) -> Res {
    let mut workloads: Vec<&str> = Vec::new();
    let mut partitioners: Vec<&str> = Vec::new();
    for r in records {
        if !workloads.contains(&r.workload.as_str()) {
            workloads.push(&r.workload);
        }
        if !partitioners.contains(&r.partitioner.as_str()) {
            partitioners.push(&r.partitioner);
        }
    }
    let first: Vec<&PartitionRecord> = records.iter().filter(|r| r.step == 0).collect();
    svg_and_png!(path, (1000, 450), |root: &DrawingArea<_, Shift>| -> Res {
        let panels = root.split_evenly((1, 2));
        let metrics: [(&str, Metric); 2] = [
            ("partition time (s)", |r| r.partition_s),
            ("ghost items", |r| r.ghost_items),
        ];
        for (area, (label, value)) in panels.iter().zip(metrics) {
            let vals: Vec<f64> = first.iter().map(|r| value(r).max(1e-9)).collect();
            let lo = vals.iter().copied().fold(f64::INFINITY, f64::min) / 2.0;
            // Headroom above the bars for the legend.
            let hi = vals.iter().copied().fold(0.0, f64::max) * 30.0;
            let n = workloads.len() * (partitioners.len() + 1);
            let mut chart = ChartBuilder::on(area)
                .caption(label, ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(30)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..n as f64, (lo..hi).log_scale())?;
            chart
                .configure_mesh()
                .disable_x_mesh()
                .x_labels(n + 1)
                .x_label_formatter(&|x| {
                    // Name each group under its middle bar.
                    let slot = x.round() as usize;
                    let group = partitioners.len() + 1;
                    if slot % group == partitioners.len() / 2 + 1 {
                        workloads
                            .get(slot / group)
                            .map_or(String::new(), |s| s.to_string())
                    } else {
                        String::new()
                    }
                })
                .draw()?;
            for (pi, p) in partitioners.iter().enumerate() {
                let color = Palette99::pick(pi).to_rgba();
                let bars: Vec<Rectangle<(f64, f64)>> = first
                    .iter()
                    .filter(|r| r.partitioner == *p)
                    .filter_map(|r| {
                        let w = workloads.iter().position(|w| *w == r.workload)?;
                        let x = (w * (partitioners.len() + 1) + pi) as f64 + 0.5;
                        Some(Rectangle::new(
                            [(x, lo), (x + 0.9, value(r).max(1e-9))],
                            color.filled(),
                        ))
                    })
                    .collect();
                chart.draw_series(bars)?.label(*p).legend(move |(x, y)| {
                    Rectangle::new([(x, y - 5), (x + 10, y + 5)], color.filled())
                });
            }
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperLeft)
                .border_style(BLACK)
                .background_style(WHITE)
                .draw()?;
        }
        Ok(())
    })
}

/// One line of a [`lines`] plot.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
    /// Per point, the half-width of its error bar (empty, or NaN at a
    /// point: none drawn).
    pub errors: Vec<f64>,
}

impl Series {
    /// The points that have error bars, with the bars' ends: (x, y - e, y, y + e).
    fn bars(&self) -> impl Iterator<Item = (f64, f64, f64, f64)> + '_ {
        self.points
            .iter()
            .zip(&self.errors)
            .filter(|(_, e)| e.is_finite())
            .map(|(&(x, y), &e)| (x, y - e, y, y + e))
    }
}

/// How a figure's axes and marks look.
#[derive(Debug, Clone, Copy, Default)]
pub struct Look {
    pub log_x: bool,
    /// Where the y axis starts (`None`: at 0); imbalances start at 1.
    pub y_from: Option<f64>,
    /// A marker at every point (off for long series, where markers bury
    /// the lines).
    pub markers: bool,
}

/// Bounds of the points, padded: (x0, x1, y0, y1).
fn extent<'a>(points: impl Iterator<Item = &'a (f64, f64)>, look: &Look) -> (f64, f64, f64, f64) {
    let (mut x0, mut x1, mut y0, mut y1) = (
        f64::INFINITY,
        f64::NEG_INFINITY,
        f64::INFINITY,
        f64::NEG_INFINITY,
    );
    for &(x, y) in points {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if !x0.is_finite() {
        (x0, x1, y0, y1) = (1.0, 2.0, 0.0, 1.0);
    }
    if x1 <= x0 {
        (x0, x1) = (x0 - 0.5, x1 + 0.5);
    }
    let y_from = look.y_from.unwrap_or(0.0).min(y0);
    let span = (y1 - y_from).max(f64::EPSILON * y1.abs().max(1.0));
    let pad = 0.05 * (x1 - x0);
    let (x0, x1) = if look.log_x {
        (x0 / 1.2, x1 * 1.2)
    } else {
        (x0 - pad, x1 + pad)
    };
    (x0, x1, y_from, y1 + 0.1 * span)
}

/// Whether every x is a whole number (then the ticks are too).
fn whole(xs: impl Iterator<Item = f64>) -> bool {
    xs.into_iter().all(|x| x.fract() == 0.0)
}

/// The legend, in its own column right of the plot (never over the data).
fn legend<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, names: &[String]) -> Res
where
    DB::ErrorType: 'static,
{
    for (k, name) in names.iter().enumerate() {
        let y = 60 + 22 * k as i32;
        let c = Palette99::pick(k).to_rgba();
        area.draw(&PathElement::new([(4, y), (24, y)], c.stroke_width(2)))?;
        area.draw(&Circle::new((14, y), 3, c.filled()))?;
        area.draw(&Text::new(name.clone(), (30, y - 7), ("sans-serif", 14)))?;
    }
    Ok(())
}

/// The most points of a series that [`lines`] marks one by one.
const MARKED_POINTS: usize = 16;

/// Lines of `series` (x, y), legend outside the data.
pub fn lines(
    path: &Path,
    caption: &str,
    (xdesc, ydesc): (&str, &str),
    series: &[Series],
    look: Look,
) -> Res {
    let ends: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.bars().flat_map(|(x, lo, _, hi)| [(x, lo), (x, hi)]))
        .collect();
    let (x0, x1, y0, y1) = extent(
        series.iter().flat_map(|s| s.points.iter()).chain(&ends),
        &look,
    );
    let whole_x = whole(series.iter().flat_map(|s| s.points.iter().map(|p| p.0)));
    let names: Vec<String> = series.iter().map(|s| s.name.clone()).collect();
    svg_and_png!(path, (960, 500), |root: &DrawingArea<_, Shift>| -> Res {
        let (plot, side) = root.split_horizontally(760);
        legend(&side, &names)?;
        let mut builder = ChartBuilder::on(&plot);
        builder
            .caption(caption, ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        macro_rules! draw {
            ($chart:expr) => {{
                let mut chart = $chart;
                let mut mesh = chart.configure_mesh();
                mesh.x_desc(xdesc).y_desc(ydesc);
                let integer = |v: &f64| format!("{v:.0}");
                if whole_x {
                    mesh.x_label_formatter(&integer);
                }
                mesh.draw()?;
                for (k, s) in series.iter().enumerate() {
                    let c = Palette99::pick(k).to_rgba();
                    chart.draw_series(LineSeries::new(
                        s.points.iter().copied(),
                        c.stroke_width(2),
                    ))?;
                    // A long series is a curve: markers would bury it.
                    if look.markers && s.points.len() <= MARKED_POINTS {
                        chart
                            .draw_series(s.points.iter().map(|&p| Circle::new(p, 3, c.filled())))?;
                    }
                    chart.draw_series(s.bars().map(|(x, lo, y, hi)| {
                        ErrorBar::new_vertical(x, lo, y, hi, c.stroke_width(1), 8)
                    }))?;
                }
            }};
        }
        if look.log_x && whole_x {
            // Ticks at the measured x (rank counts, say): a log axis's own
            // keys are powers of ten, which a range such as 2-64 lacks.
            let mut keys: Vec<f64> = series
                .iter()
                .flat_map(|s| s.points.iter().map(|p| p.0))
                .collect();
            keys.sort_by(f64::total_cmp);
            keys.dedup();
            let axis = (x0..x1).log_scale().with_key_points(keys);
            draw!(builder.build_cartesian_2d(axis, y0..y1)?);
        } else if look.log_x {
            draw!(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1)?);
        } else {
            draw!(builder.build_cartesian_2d(x0..x1, y0..y1)?);
        }
        Ok(())
    })
}

/// A measured setting: its median over repeats and the least and most.
#[derive(Debug, Clone, Copy)]
pub struct Bar {
    pub x: f64,
    pub median: f64,
    pub lo: f64,
    pub hi: f64,
}

/// A named series of [`Bar`]s.
pub struct BarSeries {
    pub name: String,
    pub bars: Vec<Bar>,
}

/// Medians with their min-max as error bars; the medians of a series of
/// three or more settings joined by a line, fewer left as points (two
/// points are no trend). Legend outside the data.
pub fn bars(
    path: &Path,
    caption: &str,
    (xdesc, ydesc): (&str, &str),
    series: &[BarSeries],
    look: Look,
) -> Res {
    let corners: Vec<(f64, f64)> = series
        .iter()
        .flat_map(|s| s.bars.iter().flat_map(|b| [(b.x, b.lo), (b.x, b.hi)]))
        .collect();
    let (x0, x1, y0, y1) = extent(corners.iter(), &look);
    let whole_x = whole(corners.iter().map(|p| p.0));
    let names: Vec<String> = series.iter().map(|s| s.name.clone()).collect();
    svg_and_png!(path, (960, 500), |root: &DrawingArea<_, Shift>| -> Res {
        let (plot, side) = root.split_horizontally(760);
        legend(&side, &names)?;
        let mut builder = ChartBuilder::on(&plot);
        builder
            .caption(caption, ("sans-serif", 17))
            .margin(12)
            .x_label_area_size(40)
            .y_label_area_size(70);
        macro_rules! draw {
            ($chart:expr) => {{
                let mut chart = $chart;
                let mut mesh = chart.configure_mesh();
                mesh.x_desc(xdesc).y_desc(ydesc);
                let integer = |v: &f64| format!("{v:.0}");
                if whole_x {
                    mesh.x_label_formatter(&integer);
                }
                mesh.draw()?;
                for (k, s) in series.iter().enumerate() {
                    let c = Palette99::pick(k).to_rgba();
                    if s.bars.len() >= 3 {
                        let medians = s.bars.iter().map(|b| (b.x, b.median));
                        chart.draw_series(LineSeries::new(medians, c.stroke_width(1)))?;
                    }
                    chart.draw_series(s.bars.iter().map(|b| {
                        ErrorBar::new_vertical(b.x, b.lo, b.median, b.hi, c.filled(), 8)
                    }))?;
                    chart.draw_series(
                        s.bars
                            .iter()
                            .map(|b| Circle::new((b.x, b.median), 4, c.filled())),
                    )?;
                }
            }};
        }
        if look.log_x {
            draw!(builder.build_cartesian_2d((x0..x1).log_scale(), y0..y1)?);
        } else {
            draw!(builder.build_cartesian_2d(x0..x1, y0..y1)?);
        }
        Ok(())
    })
}

/// One setting of a [`labelled_points`] plot.
pub struct Labelled {
    pub label: String,
    pub x: f64,
    pub y: f64,
}

/// One point per setting, y on a log axis, each named by a label placed
/// where it overlaps no other label, point or the frame (a thin line joins
/// a label pushed away from its point). Values of y at or below 0 are
/// drawn on the axis's floor, below the least positive one, and
/// `zero_note` says what that means.
pub fn labelled_points(
    path: &Path,
    caption: &str,
    (xdesc, ydesc): (&str, &str),
    points: &[Labelled],
    zero_note: &str,
) -> Res {
    let positive = points.iter().map(|p| p.y).filter(|&y| y > 0.0);
    let least = positive.clone().fold(f64::INFINITY, f64::min);
    let most = positive.fold(0.0, f64::max);
    let (floor, ymax) = if least.is_finite() {
        (least / 30.0, most * 3.0)
    } else {
        (1e-3, 1.0)
    };
    let y_of = |p: &Labelled| p.y.max(floor);
    let xmax = points.iter().map(|p| p.x).fold(0.0, f64::max).max(1e-12) * 1.1;
    let xmin = points.iter().map(|p| p.x).fold(xmax, f64::min) * 0.9;
    let ymin = floor / 1.5;
    svg_and_png!(path, (900, 560), |root: &DrawingArea<_, Shift>| -> Res {
        let mut chart = ChartBuilder::on(root)
            .caption(caption, ("sans-serif", 16))
            .margin(14)
            .x_label_area_size(44)
            .y_label_area_size(70)
            .build_cartesian_2d(xmin..xmax, (ymin..ymax).log_scale())?;
        chart
            .configure_mesh()
            .x_desc(xdesc)
            .y_desc(ydesc)
            .y_label_formatter(&|v| format!("{v:.0e}"))
            .draw()?;
        let blue = Palette99::pick(0).to_rgba();
        chart.draw_series(
            points
                .iter()
                .map(|p| Circle::new((p.x, y_of(p)), 4, blue.filled())),
        )?;
        let pixels: Vec<(i32, i32)> = points
            .iter()
            .map(|p| chart.backend_coord(&(p.x, y_of(p))))
            .collect();
        let (xr, yr) = chart.plotting_area().get_pixel_range();
        let frame = (xr.start, yr.start, xr.end, yr.end);
        let font = ("sans-serif", 12).into_font();
        for (p, place) in points.iter().zip(place_labels(points, &pixels, frame)) {
            let (at, anchor) = place;
            root.draw(&Text::new(p.label.clone(), at, font.clone()))?;
            if let Some(from) = anchor {
                root.draw(&PathElement::new(vec![from, at], BLACK.mix(0.4)))?;
            }
        }
        if points.iter().any(|p| p.y <= floor) {
            root.draw(&Text::new(
                zero_note.to_string(),
                (xr.start + 8, yr.end - 18),
                font.clone(),
            ))?;
        }
        Ok(())
    })
}

/// Approximate text box of a label of 12-point DejaVu Sans, in pixels.
fn label_box(text: &str, at: (i32, i32)) -> (i32, i32, i32, i32) {
    let w = (7 * text.chars().count()) as i32;
    (at.0, at.1, at.0 + w, at.1 + 14)
}

fn overlaps(a: (i32, i32, i32, i32), b: (i32, i32, i32, i32)) -> bool {
    a.0 < b.2 && b.0 < a.2 && a.1 < b.3 && b.1 < a.3
}

/// A label's top-left corner, and the point to join it to when it sits away
/// from its point.
type Placed = ((i32, i32), Option<(i32, i32)>);

/// Greedy placement: for each point the first spot around it, at growing
/// distances, whose box stays inside the frame and clear of every point and
/// every label already placed. Returns each label's top-left corner, and the
/// point to join it to when it sits away from its point.
fn place_labels(
    points: &[Labelled],
    pixels: &[(i32, i32)],
    frame: (i32, i32, i32, i32),
) -> Vec<Placed> {
    let dots: Vec<_> = pixels
        .iter()
        .map(|&(x, y)| (x - 5, y - 5, x + 5, y + 5))
        .collect();
    let mut taken: Vec<(i32, i32, i32, i32)> = Vec::new();
    let mut out = Vec::new();
    for (p, &(x, y)) in points.iter().zip(pixels) {
        let w = label_box(&p.label, (0, 0)).2;
        let mut chosen = None;
        'search: for ring in 1..12 {
            let d = 8 * ring;
            let spots = [
                (x + d, y - 7),
                (x - d - w, y - 7),
                (x - w / 2, y - d - 14),
                (x - w / 2, y + d),
                (x + d, y - d - 14),
                (x + d, y + d),
                (x - d - w, y - d - 14),
                (x - d - w, y + d),
            ];
            for at in spots {
                let b = label_box(&p.label, at);
                let inside = b.0 >= frame.0 && b.1 >= frame.1 && b.2 <= frame.2 && b.3 <= frame.3;
                if inside && !dots.iter().chain(&taken).any(|&o| overlaps(b, o)) {
                    chosen = Some((at, (ring > 1).then_some((x, y))));
                    break 'search;
                }
            }
        }
        // Nowhere free: beside the point, overlapping (still readable in the CSV).
        let (at, anchor) = chosen.unwrap_or(((x + 8, y - 7), None));
        taken.push(label_box(&p.label, at));
        out.push((at, anchor));
    }
    out
}
