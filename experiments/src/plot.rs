//! Plots written as SVG with plotters.

use plotters::prelude::*;
use std::path::Path;

/// One measured setting of the penalty kernel.
pub struct Point {
    pub series: String,
    /// ns per pair.
    pub x: f64,
    /// Median |d - d_exact| / L over all pairs.
    pub y: f64,
    /// Fraction of pairs certified to the tolerance.
    pub certified: f64,
    pub label: String,
}

/// Two panels against ns per pair: the median error over L (log scale; the max
/// is in the CSV, it is set by the uncertified pairs) and the fraction of pairs
/// certified, which decides how often the hybrid falls back.
pub fn error_vs_time(
    path: &Path,
    points: &[Point],
    pairs: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    // Errors of exactly 0 cannot be shown on a log axis: floor them at 1e-17.
    const FLOOR: f64 = 1e-17;
    let xmax = points.iter().map(|p| p.x).fold(0.0, f64::max) * 1.1;
    let ymax = points.iter().map(|p| p.y.max(FLOOR)).fold(FLOOR, f64::max) * 100.0;
    let root = SVGBackend::new(path, (1100, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let (left, right) = root.split_horizontally(550);
    let mut series: Vec<&str> = points.iter().map(|p| p.series.as_str()).collect();
    series.dedup();
    let draw = |area: &DrawingArea<SVGBackend, plotters::coord::Shift>,
                log: bool,
                ydesc: &str,
                y: &dyn Fn(&Point) -> f64|
     -> Result<(), Box<dyn std::error::Error>> {
        let caption = format!("penalty kernel, {pairs} random pairs: {ydesc}");
        if log {
            let mut chart = ChartBuilder::on(area)
                .caption(caption, ("sans-serif", 15))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..xmax.max(1.0), (FLOOR..ymax).log_scale())?;
            chart
                .configure_mesh()
                .x_desc("ns per pair (median of repetitions)")
                .y_label_formatter(&|v| format!("{v:.0e}"))
                .draw()?;
            plot_series(&mut chart, points, &series, &|p| y(p).max(FLOOR))?;
        } else {
            let mut chart = ChartBuilder::on(area)
                .caption(caption, ("sans-serif", 15))
                .margin(12)
                .x_label_area_size(40)
                .y_label_area_size(60)
                .build_cartesian_2d(0.0..xmax.max(1.0), 0.0..1.05)?;
            chart
                .configure_mesh()
                .x_desc("ns per pair (median of repetitions)")
                .draw()?;
            plot_series(&mut chart, points, &series, y)?;
        }
        Ok(())
    };
    draw(&left, true, "median error / L", &|p| p.y)?;
    draw(&right, false, "fraction certified", &|p| p.certified)?;
    root.present()?;
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
pub fn partition_summary(
    path: &Path,
    records: &[PartitionRecord],
) -> Result<(), Box<dyn std::error::Error>> {
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
    let root = SVGBackend::new(path, (1000, 450)).into_drawing_area();
    root.fill(&WHITE)?;
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
    root.present()?;
    Ok(())
}

/// One line of a [`lines`] plot.
pub struct Series {
    pub name: String,
    pub points: Vec<(f64, f64)>,
}

/// Lines with markers, one per series, on linear axes (x log-scaled when
/// `log_x`), with a legend; an empty plot says so rather than failing.
pub fn lines(
    path: &Path,
    caption: &str,
    (xdesc, ydesc): (&str, &str),
    series: &[Series],
    log_x: bool,
) -> Result<(), Box<dyn std::error::Error>> {
    let all = series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y1) = (f64::INFINITY, f64::NEG_INFINITY, 0.0f64);
    for &(x, y) in all {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y1 = y1.max(y);
    }
    if !x0.is_finite() {
        (x0, x1, y1) = (1.0, 2.0, 1.0);
    }
    if x1 <= x0 {
        x1 = x0 + 1.0;
    }
    let y1 = if y1 > 0.0 { y1 * 1.1 } else { 1.0 };
    let root = SVGBackend::new(path, (800, 500)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut builder = ChartBuilder::on(&root);
    builder
        .caption(caption, ("sans-serif", 18))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70);
    let colour = |k: usize| Palette99::pick(k).to_rgba();
    macro_rules! draw {
        ($chart:expr) => {{
            let mut chart = $chart;
            chart.configure_mesh().x_desc(xdesc).y_desc(ydesc).draw()?;
            for (k, s) in series.iter().enumerate() {
                let c = colour(k);
                chart
                    .draw_series(LineSeries::new(s.points.iter().copied(), c.stroke_width(2)))?
                    .label(s.name.clone())
                    .legend(move |(x, y)| {
                        PathElement::new([(x, y), (x + 18, y)], c.stroke_width(2))
                    });
                chart.draw_series(s.points.iter().map(|&p| Circle::new(p, 3, c.filled())))?;
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()?;
        }};
    }
    if log_x {
        draw!(builder.build_cartesian_2d((x0..x1).log_scale(), 0.0..y1)?);
    } else {
        draw!(builder.build_cartesian_2d(x0..x1, 0.0..y1)?);
    }
    root.present()?;
    Ok(())
}
