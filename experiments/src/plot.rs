//! Plots written as SVG with plotters.

use plotters::prelude::*;
use std::path::Path;

/// One measured setting: time per pair (x) and max error / L (y).
pub struct Point {
    pub series: String,
    pub x: f64,
    pub y: f64,
    pub label: String,
}

/// Max error over L against ns per pair, one colour per sweep, log-scale error.
pub fn error_vs_time(
    path: &Path,
    points: &[Point],
    pairs: usize,
) -> Result<(), Box<dyn std::error::Error>> {
    // Errors of exactly 0 cannot be shown on a log axis: floor them at 1e-17.
    const FLOOR: f64 = 1e-17;
    let y = |p: &Point| p.y.max(FLOOR);
    let xmax = points.iter().map(|p| p.x).fold(0.0, f64::max) * 1.1;
    let ymax = points.iter().map(y).fold(FLOOR, f64::max) * 10.0;
    let root = SVGBackend::new(path, (900, 600)).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(
            format!("Penalty kernel: max error vs time ({pairs} random pairs)"),
            ("sans-serif", 20),
        )
        .margin(15)
        .x_label_area_size(45)
        .y_label_area_size(70)
        .build_cartesian_2d(0.0..xmax.max(1.0), (FLOOR..ymax).log_scale())?;
    chart
        .configure_mesh()
        .x_desc("ns per pair (penalty, median)")
        .y_desc("max |d - d_exact| / L")
        .draw()?;
    let mut series: Vec<&str> = points.iter().map(|p| p.series.as_str()).collect();
    series.dedup();
    for (i, s) in series.iter().enumerate() {
        let color = Palette99::pick(i).to_rgba();
        let pts: Vec<&Point> = points.iter().filter(|p| p.series == *s).collect();
        chart
            .draw_series(LineSeries::new(
                pts.iter().map(|p| (p.x, y(p))),
                color.stroke_width(1),
            ))?
            .label(*s)
            .legend(move |(x, yy)| Circle::new((x + 10, yy), 4, color.filled()));
        chart.draw_series(pts.iter().map(|p| {
            EmptyElement::at((p.x, y(p)))
                + Circle::new((0, 0), 4, color.filled())
                + Text::new(p.label.clone(), (6, -6), ("sans-serif", 11))
        }))?;
    }
    chart
        .configure_series_labels()
        .border_style(BLACK)
        .background_style(WHITE)
        .draw()?;
    root.present()?;
    Ok(())
}
