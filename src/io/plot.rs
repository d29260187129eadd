//! SVG charts (plotters): stacked panels of line series, and log-log charts with error bars,
//! written atomically.

use plotters::prelude::*;
use std::path::Path;

/// One line on a panel.
pub struct Series {
    /// Legend text.
    pub name: String,
    /// (x, y) points, in drawing order.
    pub points: Vec<(f64, f64)>,
}

/// One chart in a vertical stack.
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// Lines, drawn in order (later on top).
    pub series: Vec<Series>,
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(160, 160, 160),
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
];

fn bounds(panel: &Panel) -> ((f64, f64), (f64, f64)) {
    let pts = panel.series.iter().flat_map(|s| s.points.iter());
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for &(x, y) in pts {
        x0 = x0.min(x);
        x1 = x1.max(x);
        y0 = y0.min(y);
        y1 = y1.max(y);
    }
    if x0 > x1 {
        return ((0.0, 1.0), (0.0, 1.0));
    }
    let pad = ((y1 - y0) * 0.05).max(1e-12);
    ((x0, x1.max(x0 + 1e-12)), (y0 - pad, y1 + pad))
}

/// Draw `panels` stacked vertically into an SVG file at `path` (temporary file, then rename).
pub fn write_panels(path: &Path, panels: &[Panel]) -> Result<(), String> {
    let mut svg = String::new();
    {
        let height = 300 * panels.len().max(1) as u32;
        let root = SVGBackend::with_string(&mut svg, (1000, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((panels.len().max(1), 1));
        for (panel, area) in panels.iter().zip(areas.iter()) {
            let ((x0, x1), (y0, y1)) = bounds(panel);
            let mut chart = ChartBuilder::on(area)
                .caption(&panel.title, ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(70)
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|e| e.to_string())?;
            chart
                .configure_mesh()
                .x_desc(&panel.x_label)
                .y_desc(&panel.y_label)
                .draw()
                .map_err(|e| e.to_string())?;
            for (k, s) in panel.series.iter().enumerate() {
                let colour = COLOURS[k % COLOURS.len()];
                chart
                    .draw_series(LineSeries::new(s.points.iter().copied(), colour))
                    .map_err(|e| e.to_string())?
                    .label(&s.name)
                    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            }
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    super::atomic::write_atomically(path, svg.as_bytes())
        .map_err(|e| format!("{}: {e}", path.display()))
}

/// A point with a vertical error bar.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ErrorPoint {
    /// Abscissa.
    pub x: f64,
    /// Ordinate.
    pub y: f64,
    /// Lower end of the bar.
    pub lo: f64,
    /// Upper end of the bar.
    pub hi: f64,
}

/// A log-log chart: measured curves with error bars, model lines, and notes in a corner (like the
/// Allan plot of a gyro data sheet).
pub struct LogLogChart {
    /// Title above the chart.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// Measured curves: legend text and points.
    pub curves: Vec<(String, Vec<ErrorPoint>)>,
    /// Lines (e.g. fitted terms), drawn dashed-light under the curves.
    pub lines: Vec<Series>,
    /// Text lines printed in the upper right (the legend goes lower left).
    pub notes: Vec<String>,
}

fn log_bounds(chart: &LogLogChart) -> ((f64, f64), (f64, f64)) {
    let (mut x0, mut x1, mut y0, mut y1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    for p in chart.curves.iter().flat_map(|c| c.1.iter()) {
        if p.x > 0.0 {
            x0 = x0.min(p.x);
            x1 = x1.max(p.x);
        }
        for v in [p.y, p.lo, p.hi] {
            if v > 0.0 && v.is_finite() {
                y0 = y0.min(v);
                y1 = y1.max(v);
            }
        }
    }
    if x0 > x1 || y0 > y1 {
        return ((1.0, 10.0), (1.0, 10.0));
    }
    ((x0 / 1.5, x1 * 1.5), (y0 / 2.0, y1 * 2.0))
}

/// Draw a log-log chart into an SVG file at `path` (temporary file, then rename). Line points
/// outside the measured range are clipped to it.
pub fn write_loglog(path: &Path, chart: &LogLogChart) -> Result<(), String> {
    let mut svg = String::new();
    {
        let root = SVGBackend::with_string(&mut svg, (1000, 700)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let ((x0, x1), (y0, y1)) = log_bounds(chart);
        let mut c = ChartBuilder::on(&root)
            .caption(&chart.title, ("sans-serif", 20))
            .margin(15)
            .x_label_area_size(45)
            .y_label_area_size(80)
            .build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())
            .map_err(|e| e.to_string())?;
        c.configure_mesh()
            .x_desc(&chart.x_label)
            .y_desc(&chart.y_label)
            .y_label_formatter(&|v| format!("{v:.1e}"))
            .draw()
            .map_err(|e| e.to_string())?;
        let inside = |&(x, y): &(f64, f64)| x >= x0 && x <= x1 && y >= y0 && y <= y1;
        for (k, s) in chart.lines.iter().enumerate() {
            let colour = COLOURS[(k + 2) % COLOURS.len()];
            let pts: Vec<(f64, f64)> = s.points.iter().copied().filter(inside).collect();
            c.draw_series(LineSeries::new(pts, colour.stroke_width(1)))
                .map_err(|e| e.to_string())?
                .label(&s.name)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
        }
        for (k, (name, pts)) in chart.curves.iter().enumerate() {
            let colour = COLOURS[(k + 1) % COLOURS.len()];
            let bars: Vec<PathElement<(f64, f64)>> = pts
                .iter()
                .filter(|p| p.lo > 0.0 && p.hi.is_finite())
                .map(|p| PathElement::new(vec![(p.x, p.lo.max(y0)), (p.x, p.hi.min(y1))], colour))
                .collect();
            c.draw_series(bars).map_err(|e| e.to_string())?;
            c.draw_series(LineSeries::new(
                pts.iter().map(|p| (p.x, p.y)),
                colour.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?
            .label(name)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
            c.draw_series(
                pts.iter()
                    .map(|p| Circle::new((p.x, p.y), 3, colour.filled())),
            )
            .map_err(|e| e.to_string())?;
        }
        c.configure_series_labels()
            .position(SeriesLabelPosition::LowerLeft)
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()
            .map_err(|e| e.to_string())?;
        for (i, note) in chart.notes.iter().enumerate() {
            root.draw(&Text::new(
                note.clone(),
                (560, 60 + 18 * i as i32),
                ("monospace", 14),
            ))
            .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
    }
    super::atomic::write_atomically(path, svg.as_bytes())
        .map_err(|e| format!("{}: {e}", path.display()))
}
