//! # igi-plot
//!
//! The plots people look at (plotters with its `ab_glyph` text backend): one home for the
//! chart boilerplate of every crate (bitmap backend, chart builder, mesh, series, legend, atomic
//! write of the PNG).
//!
//! A [`Chart`] is a title, two [`Axis`] (linear or logarithmic) and [`Series`] of points drawn
//! as lines, dots or both, optionally with a legend entry and a text label at each point.
//! [`write_chart`] draws one chart into a PNG, [`write_chart_grid`] a grid of smaller panels;
//! both write atomically (a temporary file, then a rename).
//!
//! plotters draws text only with fonts registered at run time. `register_fonts` registers
//! DejaVu Sans (Debian's `fonts-dejavu-core`, installed by `scripts/deps.sh`) as "sans-serif",
//! once per process. Without the font, plots are still drawn, only without text.

use plotters::coord::ranged1d::{AsRangedCoord, ValueFormatter};
use plotters::coord::Shift;
use plotters::prelude::*;
use std::ops::Range;
use std::path::Path;
use std::path::PathBuf;
use std::sync::OnceLock;

/// Where DejaVu Sans is looked for, in order.
const CANDIDATES: [&str; 3] = [
    "/usr/share/fonts/truetype/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/dejavu/DejaVuSans.ttf",
    "/usr/share/fonts/TTF/DejaVuSans.ttf",
];

/// Registers the "sans-serif" font for plotters; returns whether a font is available.
pub fn register_fonts() -> bool {
    static DONE: OnceLock<bool> = OnceLock::new();
    *DONE.get_or_init(|| {
        for path in CANDIDATES {
            if let Ok(bytes) = std::fs::read(path) {
                let bytes: &'static [u8] = Box::leak(bytes.into_boxed_slice());
                if plotters::style::register_font(
                    "sans-serif",
                    plotters::style::FontStyle::Normal,
                    bytes,
                )
                .is_ok()
                {
                    return true;
                }
            }
        }
        false
    })
}

/// One axis: its description and range; `log` for a logarithmic scale (the range must then be
/// positive).
#[derive(Clone, Debug)]
pub struct Axis {
    pub label: String,
    pub range: Range<f64>,
    pub log: bool,
}

impl Axis {
    /// A linear axis.
    pub fn linear(label: impl Into<String>, range: Range<f64>) -> Axis {
        Axis {
            label: label.into(),
            range,
            log: false,
        }
    }

    /// A logarithmic axis.
    pub fn log(label: impl Into<String>, range: Range<f64>) -> Axis {
        Axis {
            label: label.into(),
            range,
            log: true,
        }
    }
}

/// A series of (x, y) points, drawn as a line of `line_width` pixels (0: none) and dots of
/// `dot_radius` pixels (0: none) in `colour` (sRGB) at `opacity`; `legend` names it in the
/// chart's legend; `point_labels` (empty or one per point) are written beside the dots.
#[derive(Clone, Debug)]
pub struct Series {
    pub points: Vec<(f64, f64)>,
    pub colour: [u8; 3],
    pub opacity: f64,
    pub line_width: u32,
    pub dot_radius: u32,
    pub legend: Option<String>,
    pub point_labels: Vec<String>,
}

impl Series {
    /// An opaque line of width `width` without dots or legend.
    pub fn line(points: Vec<(f64, f64)>, colour: [u8; 3], width: u32) -> Series {
        Series {
            points,
            colour,
            opacity: 1.0,
            line_width: width,
            dot_radius: 0,
            legend: None,
            point_labels: Vec::new(),
        }
    }

    /// Opaque dots of radius `radius` without a line or legend.
    pub fn dots(points: Vec<(f64, f64)>, colour: [u8; 3], radius: u32) -> Series {
        Series {
            line_width: 0,
            dot_radius: radius,
            ..Series::line(points, colour, 0)
        }
    }
}

/// One chart: a title, the axes and the series, drawn in order. A legend is drawn when a
/// series has a `legend`.
#[derive(Clone, Debug)]
pub struct Chart {
    pub title: String,
    pub x: Axis,
    pub y: Axis,
    pub series: Vec<Series>,
}

/// Blue, red and a six-colour cycle (matplotlib's first six) for series.
pub const BLUE_RGB: [u8; 3] = [0, 0, 255];
pub const RED_RGB: [u8; 3] = [255, 0, 0];
pub const PALETTE: [[u8; 3]; 6] = [
    [31, 119, 180],
    [255, 127, 14],
    [44, 160, 44],
    [214, 39, 40],
    [148, 103, 189],
    [140, 86, 75],
];

/// Margins and text sizes: a full-size chart or a panel of a grid.
#[derive(Clone, Copy)]
struct Layout {
    margin: u32,
    caption: u32,
    x_label_area: u32,
    y_label_area: u32,
}

const FULL: Layout = Layout {
    margin: 10,
    caption: 20,
    x_label_area: 40,
    y_label_area: 60,
};

const PANEL: Layout = Layout {
    margin: 8,
    caption: 18,
    x_label_area: 30,
    y_label_area: 50,
};

type DrawResult = Result<(), Box<dyn std::error::Error>>;

/// A plot that could not be drawn or written; it names the file.
#[derive(Debug, thiserror::Error)]
pub enum PlotError {
    /// plotters failed to draw or encode the chart.
    #[error("{}: cannot encode image: cannot draw the plot: {msg}", path.display())]
    Draw { path: PathBuf, msg: String },
    /// The PNG could not be written.
    #[error(transparent)]
    Files(#[from] igi_files::FilesError),
}

/// Draws `chart` into a `width` x `height` PNG at `path`, atomically.
pub fn write_chart(path: &Path, size: (u32, u32), chart: &Chart) -> Result<(), PlotError> {
    write_png(path, size, |root| draw_chart(root, chart, FULL))
}

/// Draws `charts` as a grid of `rows` x `cols` panels (row by row) into a `width` x `height`
/// PNG at `path`, atomically.
pub fn write_chart_grid(
    path: &Path,
    size: (u32, u32),
    (rows, cols): (usize, usize),
    charts: &[Chart],
) -> Result<(), PlotError> {
    write_png(path, size, |root| {
        let panels = root.split_evenly((rows, cols));
        for (panel, chart) in panels.iter().zip(charts) {
            draw_chart(panel, chart, PANEL)?;
        }
        Ok(())
    })
}

/// A white `size` canvas drawn by `draw`, presented into a temporary PNG renamed to `path`.
fn write_png(
    path: &Path,
    size: (u32, u32),
    draw: impl FnOnce(&DrawingArea<BitMapBackend<'_>, Shift>) -> DrawResult,
) -> Result<(), PlotError> {
    register_fonts();
    igi_files::write_atomic(path, |tmp| {
        let run = || -> DrawResult {
            let root = BitMapBackend::new(tmp, size).into_drawing_area();
            root.fill(&WHITE)?;
            draw(&root)?;
            root.present()?;
            Ok(())
        };
        run().map_err(|e| PlotError::Draw {
            path: path.to_path_buf(),
            msg: e.to_string(),
        })
    })
}

fn draw_chart(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    chart: &Chart,
    l: Layout,
) -> DrawResult {
    let (x, y) = (chart.x.range.clone(), chart.y.range.clone());
    match (chart.x.log, chart.y.log) {
        (false, false) => draw_on(area, chart, l, x, y),
        (true, false) => draw_on(area, chart, l, x.log_scale(), y),
        (false, true) => draw_on(area, chart, l, x, y.log_scale()),
        (true, true) => draw_on(area, chart, l, x.log_scale(), y.log_scale()),
    }
}

/// The chart on `area` with the x and y coordinates `xc`, `yc` (linear or logarithmic). Text
/// (caption, axis descriptions, legend, point labels) only when a font is registered.
fn draw_on<X, Y>(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    chart: &Chart,
    l: Layout,
    xc: X,
    yc: Y,
) -> DrawResult
where
    X: AsRangedCoord<Value = f64>,
    Y: AsRangedCoord<Value = f64>,
    X::CoordDescType: ValueFormatter<f64>,
    Y::CoordDescType: ValueFormatter<f64>,
{
    let fonts = register_fonts();
    let mut b = ChartBuilder::on(area);
    b.margin(l.margin);
    if fonts {
        b.caption(&chart.title, ("sans-serif", l.caption))
            .x_label_area_size(l.x_label_area)
            .y_label_area_size(l.y_label_area);
    }
    let mut ctx = b.build_cartesian_2d(xc, yc)?;
    if fonts {
        ctx.configure_mesh()
            .x_desc(chart.x.label.as_str())
            .y_desc(chart.y.label.as_str())
            .draw()?;
    }
    for s in &chart.series {
        draw_series(&mut ctx, s, fonts)?;
    }
    if fonts && chart.series.iter().any(|s| s.legend.is_some()) {
        ctx.configure_series_labels()
            .background_style(WHITE.mix(0.8))
            .border_style(BLACK)
            .draw()?;
    }
    Ok(())
}

/// One series: its line (carrying the legend entry), then its dots (carrying it when there is
/// no line), then its point labels.
fn draw_series<X, Y>(
    ctx: &mut ChartContext<'_, BitMapBackend<'_>, Cartesian2d<X, Y>>,
    s: &Series,
    fonts: bool,
) -> DrawResult
where
    X: Ranged<ValueType = f64>,
    Y: Ranged<ValueType = f64>,
{
    let colour = RGBColor(s.colour[0], s.colour[1], s.colour[2]).mix(s.opacity);
    let legend = s.legend.as_deref().filter(|_| fonts);
    let entry = move |(x, y): (i32, i32)| PathElement::new(vec![(x, y), (x + 20, y)], colour);
    if s.line_width > 0 {
        let line = LineSeries::new(s.points.iter().copied(), colour.stroke_width(s.line_width));
        let anno = ctx.draw_series(line)?;
        if let Some(name) = legend {
            anno.label(name).legend(entry);
        }
    }
    if s.dot_radius > 0 {
        let dots = s
            .points
            .iter()
            .map(|&p| Circle::new(p, s.dot_radius, colour.filled()));
        let anno = ctx.draw_series(dots)?;
        if let (Some(name), 0) = (legend, s.line_width) {
            anno.label(name).legend(entry);
        }
    }
    if fonts && !s.point_labels.is_empty() {
        let labels = s.points.iter().zip(&s.point_labels).map(|(&p, text)| {
            EmptyElement::at(p) + Text::new(text.clone(), (9, -7), ("sans-serif", 14))
        });
        ctx.draw_series(labels)?;
    }
    Ok(())
}
