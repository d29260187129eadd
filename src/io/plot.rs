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

/// One chart in a stack (or a grid, [`write_grid`]).
pub struct Panel {
    /// Title above the chart.
    pub title: String,
    /// X axis label.
    pub x_label: String,
    /// Y axis label.
    pub y_label: String,
    /// Lines, drawn in order (later on top).
    pub series: Vec<Series>,
    /// Axis ranges and line styles; the default fits the data and cycles a palette.
    pub style: PanelStyle,
}

/// How a panel is drawn when the default does not do: fixed axis ranges (so that panels side
/// by side compare at a glance) and a colour and width per series.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct PanelStyle {
    /// X range; None: the data's.
    pub x_range: Option<(f64, f64)>,
    /// Y range; None: the data's, with a margin.
    pub y_range: Option<(f64, f64)>,
    /// Style of series k (the palette's colour and width 1 beyond the list).
    pub lines: Vec<LineStyle>,
    /// The legend in the upper right corner (leave room for it there with `y_range`) instead
    /// of the middle right.
    pub legend_on_top: bool,
}

/// Colour (RGB) and stroke width of one series.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct LineStyle {
    /// Red, green, blue.
    pub colour: (u8, u8, u8),
    /// Stroke width in pixels.
    pub width: u32,
}

const COLOURS: [RGBColor; 6] = [
    RGBColor(160, 160, 160),
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(148, 103, 189),
    RGBColor(255, 127, 14),
];

/// The data's bounds: x from first to last, y with a 5% margin.
pub fn bounds<'a>(series: impl IntoIterator<Item = &'a Series>) -> ((f64, f64), (f64, f64)) {
    let pts = series.into_iter().flat_map(|s| s.points.iter());
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

/// A tick label with the decimals its spacing `step` needs, and no `-0`.
fn tick(v: f64, step: f64) -> String {
    let decimals = if step > 0.0 && step.is_finite() {
        (-step.log10().floor()).clamp(0.0, 12.0) as usize
    } else {
        1
    };
    let text = format!("{v:.decimals$}");
    match text.strip_prefix('-') {
        Some(rest) if rest.chars().all(|c| c == '0' || c == '.') => rest.to_string(),
        _ => text,
    }
}

/// Draw `panels` stacked vertically into an SVG file at `path` (temporary file, then rename).
pub fn write_panels(path: &Path, panels: &[Panel]) -> Result<(), String> {
    write_grid(path, panels, 1)
}

/// Draw `panels` in rows of `columns` (row by row) into an SVG file at `path` (temporary file,
/// then rename).
pub fn write_grid(path: &Path, panels: &[Panel], columns: usize) -> Result<(), String> {
    let columns = columns.max(1);
    let rows = panels.len().div_ceil(columns).max(1);
    let mut svg = String::new();
    {
        let width = if columns == 1 {
            1000
        } else {
            700 * columns as u32
        };
        let height = 300 * rows as u32;
        let root = SVGBackend::with_string(&mut svg, (width, height)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let areas = root.split_evenly((rows, columns));
        for (panel, area) in panels.iter().zip(areas.iter()) {
            let ((dx0, dx1), (dy0, dy1)) = bounds(&panel.series);
            let (x0, x1) = panel.style.x_range.unwrap_or((dx0, dx1));
            let (y0, y1) = panel.style.y_range.unwrap_or((dy0, dy1));
            let mut chart = ChartBuilder::on(area)
                .caption(&panel.title, ("sans-serif", 18))
                .margin(10)
                .x_label_area_size(35)
                .y_label_area_size(70)
                .build_cartesian_2d(x0..x1, y0..y1)
                .map_err(|e| e.to_string())?;
            let (x_step, y_step) = ((x1 - x0) / 10.0, (y1 - y0) / 10.0);
            chart
                .configure_mesh()
                .x_desc(&panel.x_label)
                .y_desc(&panel.y_label)
                .x_label_formatter(&|v| tick(*v, x_step))
                .y_label_formatter(&|v| tick(*v, y_step))
                .draw()
                .map_err(|e| e.to_string())?;
            for (k, s) in panel.series.iter().enumerate() {
                let (colour, width) = match panel.style.lines.get(k) {
                    Some(l) => (RGBColor(l.colour.0, l.colour.1, l.colour.2), l.width),
                    None => (COLOURS[k % COLOURS.len()], 1),
                };
                chart
                    .draw_series(LineSeries::new(
                        s.points.iter().copied(),
                        colour.stroke_width(width),
                    ))
                    .map_err(|e| e.to_string())?
                    .label(&s.name)
                    .legend(move |(x, y)| {
                        PathElement::new(vec![(x, y), (x + 20, y)], colour.stroke_width(width))
                    });
            }
            chart
                .configure_series_labels()
                .position(if panel.style.legend_on_top {
                    SeriesLabelPosition::UpperRight
                } else {
                    SeriesLabelPosition::MiddleRight
                })
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

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_carry_the_decimals_of_their_spacing_and_no_negative_zero() {
        assert_eq!(tick(2.5, 0.5), "2.5");
        assert_eq!(tick(2.0, 0.5), "2.0");
        assert_eq!(tick(-0.0001, 0.2), "0.0");
        assert_eq!(tick(-0.2, 0.2), "-0.2");
        assert_eq!(tick(150.0, 50.0), "150");
        assert_eq!(tick(0.015, 0.005), "0.015");
    }
}
