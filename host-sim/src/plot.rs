//! Figures for the host tools: line and scatter panels written as SVG and PNG.
//!
//! A [`Figure`] is a grid of [`Panel`]s, each with its own axes and a set of
//! [`Series`] (a line or points). [`write_figure`] writes `STEM.svg` and
//! `STEM.png` atomically (a temporary file renamed into place).
//!
//! Text is drawn with the DejaVu Sans font bundled in `host-sim/assets/`
//! (license in `assets/DejaVuSans-LICENSE.txt`), registered with plotters'
//! `ab_glyph` backend, so PNGs render the same on a machine without
//! fontconfig or system fonts.
//!
//! Long series are thinned before drawing: a line keeps the minimum and the
//! maximum of each bucket (so peaks survive), points keep every k-th sample.
//!
//! ```no_run
//! use host_sim::plot::{Figure, Panel, Series};
//! let x: Vec<f64> = (0..100).map(|k| k as f64 * 0.01).collect();
//! let y: Vec<f64> = x.iter().map(|t| t.sin()).collect();
//! let fig = Figure::single(Panel::new("sine", "t [s]", "y").with(Series::line("sin", x, y)));
//! host_sim::plot::write_figure(&fig, std::path::Path::new("/tmp/sine")).unwrap();
//! ```

use std::path::{Path, PathBuf};
use std::sync::Once;

use anyhow::{anyhow, Result};
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::output::Outputs;

/// The bundled font (DejaVu Sans, Bitstream Vera license).
static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Register the bundled font as plotters' `sans-serif` family (once).
pub fn register_bundled_font() {
    static ONCE: Once = Once::new();
    ONCE.call_once(|| {
        // The bytes are a valid TrueType file (checked by the tests); a
        // failure would only leave text undrawn.
        let _ = plotters::style::register_font("sans-serif", FontStyle::Normal, FONT);
    });
}

/// How a series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// A polyline through the points, in order.
    Line,
    /// Small filled circles.
    Points,
}

/// One data series.
#[derive(Clone, Debug, PartialEq)]
pub struct Series {
    /// Legend text (empty: no legend entry).
    pub label: String,
    /// Abscissae.
    pub x: Vec<f64>,
    /// Ordinates (same length as `x`; non-finite pairs are skipped).
    pub y: Vec<f64>,
    /// Line or points.
    pub mark: Mark,
}

impl Series {
    /// A line series.
    pub fn line(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            mark: Mark::Line,
        }
    }

    /// A scatter series.
    pub fn points(label: impl Into<String>, x: Vec<f64>, y: Vec<f64>) -> Self {
        Self {
            label: label.into(),
            x,
            y,
            mark: Mark::Points,
        }
    }
}

/// One set of axes.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct Panel {
    /// Caption above the axes.
    pub title: String,
    /// Abscissa label (with unit).
    pub x_label: String,
    /// Ordinate label (with unit).
    pub y_label: String,
    /// The data.
    pub series: Vec<Series>,
}

impl Panel {
    /// An empty panel.
    pub fn new(
        title: impl Into<String>,
        x_label: impl Into<String>,
        y_label: impl Into<String>,
    ) -> Self {
        Self {
            title: title.into(),
            x_label: x_label.into(),
            y_label: y_label.into(),
            series: Vec::new(),
        }
    }

    /// Add a series (builder style).
    pub fn with(mut self, s: Series) -> Self {
        self.series.push(s);
        self
    }
}

/// A grid of panels.
#[derive(Clone, Debug, PartialEq)]
pub struct Figure {
    /// Panels, row by row.
    pub panels: Vec<Panel>,
    /// Panels per row (at least 1).
    pub columns: usize,
    /// Size of one panel, pixels.
    pub panel_px: (u32, u32),
}

impl Figure {
    /// A figure of one panel, 900 x 500 px.
    pub fn single(panel: Panel) -> Self {
        Self {
            panels: vec![panel],
            columns: 1,
            panel_px: (900, 500),
        }
    }

    /// A grid with `columns` panels per row.
    pub fn grid(panels: Vec<Panel>, columns: usize) -> Self {
        Self {
            panels,
            columns: columns.max(1),
            panel_px: (700, 420),
        }
    }

    /// Total size in pixels.
    pub fn size_px(&self) -> (u32, u32) {
        let cols = self.columns.max(1).min(self.panels.len().max(1));
        let rows = self.panels.len().max(1).div_ceil(cols);
        (self.panel_px.0 * cols as u32, self.panel_px.1 * rows as u32)
    }
}

/// Colours of successive series.
const COLORS: [RGBColor; 8] = [
    RGBColor(31, 119, 180),
    RGBColor(214, 39, 40),
    RGBColor(44, 160, 44),
    RGBColor(255, 127, 14),
    RGBColor(148, 103, 189),
    RGBColor(140, 86, 75),
    RGBColor(227, 119, 194),
    RGBColor(127, 127, 127),
];

/// Most points drawn per series.
const MAX_POINTS: usize = 4000;

/// Thin a series for drawing (see the module documentation).
fn thin(s: &Series) -> Vec<(f64, f64)> {
    let pts: Vec<(f64, f64)> =
        s.x.iter()
            .zip(&s.y)
            .filter(|(x, y)| x.is_finite() && y.is_finite())
            .map(|(x, y)| (*x, *y))
            .collect();
    if pts.len() <= MAX_POINTS {
        return pts;
    }
    match s.mark {
        Mark::Points => {
            let step = pts.len().div_ceil(MAX_POINTS);
            pts.into_iter().step_by(step).collect()
        }
        Mark::Line => {
            let buckets = MAX_POINTS / 2;
            let size = pts.len().div_ceil(buckets);
            let mut out = Vec::with_capacity(2 * buckets);
            for chunk in pts.chunks(size) {
                let (mut lo, mut hi) = (0, 0);
                for (k, p) in chunk.iter().enumerate() {
                    if p.1 < chunk[lo].1 {
                        lo = k;
                    }
                    if p.1 > chunk[hi].1 {
                        hi = k;
                    }
                }
                let (a, b) = if lo <= hi { (lo, hi) } else { (hi, lo) };
                out.push(chunk[a]);
                if b != a {
                    out.push(chunk[b]);
                }
            }
            out
        }
    }
}

/// Axis range covering `v` with 4 % margins; a degenerate range is widened.
fn range(v: impl Iterator<Item = f64>) -> (f64, f64) {
    let Some((lo, hi)) = crate::stats::finite_range(v) else {
        return (0.0, 1.0);
    };
    let span = hi - lo;
    if span <= 1e-12 * lo.abs().max(1e-300) {
        let d = if lo == 0.0 { 1.0 } else { 0.05 * lo.abs() };
        return (lo - d, hi + d);
    }
    (lo - 0.04 * span, hi + 0.04 * span)
}

fn draw_panel<DB: DrawingBackend>(area: &DrawingArea<DB, Shift>, p: &Panel) -> Result<()> {
    let data: Vec<Vec<(f64, f64)>> = p.series.iter().map(thin).collect();
    let (x0, x1) = range(data.iter().flatten().map(|q| q.0));
    let (y0, y1) = range(data.iter().flatten().map(|q| q.1));
    let err = |e: &dyn std::fmt::Display| anyhow!("plot `{}`: {e}", p.title);
    let mut chart = ChartBuilder::on(area)
        .caption(&p.title, ("sans-serif", 20))
        .margin(12)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x0..x1, y0..y1)
        .map_err(|e| err(&e))?;
    chart
        .configure_mesh()
        .x_desc(p.x_label.as_str())
        .y_desc(p.y_label.as_str())
        .label_style(("sans-serif", 14))
        .axis_desc_style(("sans-serif", 15))
        .light_line_style(RGBColor(235, 235, 235))
        .draw()
        .map_err(|e| err(&e))?;
    let mut labelled = false;
    for (k, (s, pts)) in p.series.iter().zip(data).enumerate() {
        let color = COLORS[k % COLORS.len()];
        let anno = match s.mark {
            Mark::Line => chart
                .draw_series(LineSeries::new(pts, color.stroke_width(1)))
                .map_err(|e| err(&e))?,
            Mark::Points => chart
                .draw_series(
                    pts.into_iter()
                        .map(|q| Circle::new(q, 2, color.mix(0.6).filled())),
                )
                .map_err(|e| err(&e))?,
        };
        if !s.label.is_empty() {
            labelled = true;
            anno.label(s.label.as_str()).legend(move |(x, y)| {
                PathElement::new(vec![(x, y), (x + 18, y)], color.stroke_width(3))
            });
        }
    }
    if labelled {
        chart
            .configure_series_labels()
            .label_font(("sans-serif", 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK.mix(0.4))
            .position(SeriesLabelPosition::UpperRight)
            .draw()
            .map_err(|e| err(&e))?;
    }
    Ok(())
}

fn draw<DB: DrawingBackend>(root: DrawingArea<DB, Shift>, fig: &Figure) -> Result<()> {
    root.fill(&WHITE).map_err(|e| anyhow!("plot: {e}"))?;
    let cols = fig.columns.max(1).min(fig.panels.len().max(1));
    let rows = fig.panels.len().max(1).div_ceil(cols);
    let areas = root.split_evenly((rows, cols));
    for (p, a) in fig.panels.iter().zip(&areas) {
        draw_panel(a, p)?;
    }
    root.present().map_err(|e| anyhow!("plot: {e}"))?;
    Ok(())
}

/// The figure as an SVG document.
pub fn render_svg(fig: &Figure) -> Result<String> {
    register_bundled_font();
    let mut s = String::new();
    draw(
        SVGBackend::with_string(&mut s, fig.size_px()).into_drawing_area(),
        fig,
    )?;
    Ok(s)
}

/// Write the figure as SVG to `path` (atomically).
pub fn write_svg(fig: &Figure, path: &Path) -> Result<()> {
    let mut out = Outputs::new();
    stage_svg(&mut out, fig, path)?;
    out.commit()?;
    Ok(())
}

/// Write the figure as PNG to `path` (atomically).
pub fn write_png(fig: &Figure, path: &Path) -> Result<()> {
    let mut out = Outputs::new();
    stage_png(&mut out, fig, path)?;
    out.commit()?;
    Ok(())
}

/// Stage the figure as SVG among a command's outputs ([`crate::output`]).
pub fn stage_svg(out: &mut Outputs, fig: &Figure, path: &Path) -> Result<()> {
    let svg = render_svg(fig)?;
    out.bytes(path, svg.as_bytes())?;
    Ok(())
}

/// Stage the figure as PNG among a command's outputs ([`crate::output`]).
pub fn stage_png(out: &mut Outputs, fig: &Figure, path: &Path) -> Result<()> {
    register_bundled_font();
    // The bitmap backend opens its file itself: draw into the temporary one.
    out.with_temp_path(path, |tmp| {
        draw(
            BitMapBackend::new(tmp, fig.size_px()).into_drawing_area(),
            fig,
        )
        .map_err(|e| std::io::Error::other(format!("{e:#}")))
    })?;
    Ok(())
}

/// Write `STEM.svg` and `STEM.png` (both or neither); returns both paths.
pub fn write_figure(fig: &Figure, stem: &Path) -> Result<[PathBuf; 2]> {
    let mut out = Outputs::new();
    let paths = stage_figure(&mut out, fig, stem)?;
    out.commit()?;
    Ok(paths)
}

/// Stage `STEM.svg` and `STEM.png` among a command's outputs; returns both
/// paths.
pub fn stage_figure(out: &mut Outputs, fig: &Figure, stem: &Path) -> Result<[PathBuf; 2]> {
    let svg = stem.with_extension("svg");
    let png = stem.with_extension("png");
    stage_svg(out, fig, &svg)?;
    stage_png(out, fig, &png)?;
    Ok([svg, png])
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn thinning_keeps_extremes_and_order() {
        let n = 100_000;
        let x: Vec<f64> = (0..n).map(|k| k as f64).collect();
        let mut y: Vec<f64> = x.iter().map(|t| (t * 1e-3).sin()).collect();
        y[54_321] = 7.0;
        y[77_777] = -9.0;
        let t = thin(&Series::line("", x, y));
        assert!(t.len() <= MAX_POINTS, "{} points", t.len());
        assert!(t.iter().any(|p| p.1 == 7.0), "spike kept");
        assert!(t.iter().any(|p| p.1 == -9.0), "dip kept");
        assert!(t.windows(2).all(|w| w[0].0 < w[1].0), "x order kept");
    }

    #[test]
    fn range_handles_flat_and_empty_data() {
        assert_eq!(range([].into_iter()), (0.0, 1.0));
        let (a, b) = range([2.0, 2.0].into_iter());
        assert!(a < 2.0 && b > 2.0);
        let (a, b) = range([0.0, f64::NAN, 10.0].into_iter());
        assert!((a + 0.4).abs() < 1e-12 && (b - 10.4).abs() < 1e-12);
    }
}
