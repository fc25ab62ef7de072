//! The error-against-run-time plot of a solve (`convergence.png`).

use crate::solver::SolveReport;
use crate::ReflectError;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use std::path::Path;

/// Plots, against cumulative wall time, the relative photo residual RMS and (with ground
/// truth) the RMS error of `rho_d`, one point per iteration. Written atomically.
pub fn plot_convergence(report: &SolveReport, path: &Path) -> Result<(), ReflectError> {
    let fonts = igi_imaging::plot::register_fonts();
    let pts_res: Vec<(f64, f64)> = report
        .iterations
        .iter()
        .map(|r| (r.cumulative_s, r.residual_rel_rms as f64))
        .collect();
    let pts_truth: Vec<(f64, f64)> = report
        .iterations
        .iter()
        .filter_map(|r| r.truth_rms.map(|t| (r.cumulative_s, t as f64)))
        .collect();
    if pts_res.is_empty() {
        return Ok(());
    }
    let xmax = pts_res.iter().map(|p| p.0).fold(0.0, f64::max).max(1e-3) * 1.05;
    let ymax = pts_res
        .iter()
        .chain(pts_truth.iter())
        .map(|p| p.1)
        .fold(0.0, f64::max)
        .max(1e-4)
        * 1.15;
    let figure = Figure {
        fonts,
        residual: &pts_res,
        truth: &pts_truth,
        xmax,
        ymax,
    };
    igi_imaging::io::write_atomic(path, |tmp| {
        figure
            .draw(tmp)
            .map_err(|e| igi_imaging::ImagingError::Encode {
                path: path.to_path_buf(),
                msg: format!("cannot draw plot: {e}"),
            })
    })?;
    Ok(())
}

type Chart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, RangedCoordf64>>;

/// The convergence figure's data: (seconds, error) points and the axes' ranges; text (caption,
/// axis descriptions, legend) only when `fonts` are available.
struct Figure<'a> {
    fonts: bool,
    residual: &'a [(f64, f64)],
    truth: &'a [(f64, f64)],
    xmax: f64,
    ymax: f64,
}

impl Figure<'_> {
    /// Draws the figure into the PNG file `tmp`.
    fn draw(&self, tmp: &Path) -> Result<(), String> {
        let fonts = self.fonts;
        let root = BitMapBackend::new(tmp, (800, 500)).into_drawing_area();
        root.fill(&WHITE).map_err(|e| e.to_string())?;
        let mut b = ChartBuilder::on(&root);
        b.margin(15);
        if fonts {
            b.caption("igi solve: error against run time", ("sans-serif", 22))
                .x_label_area_size(40)
                .y_label_area_size(60);
        }
        let mut chart = b
            .build_cartesian_2d(0.0..self.xmax, 0.0..self.ymax)
            .map_err(|e| e.to_string())?;
        if fonts {
            chart
                .configure_mesh()
                .x_desc("cumulative wall time (s)")
                .y_desc("error")
                .draw()
                .map_err(|e| e.to_string())?;
        }
        draw_curve(
            &mut chart,
            self.residual,
            BLUE,
            "photo residual, relative RMS",
        )?;
        if !self.truth.is_empty() {
            draw_curve(&mut chart, self.truth, RED, "rho_d RMS error vs truth")?;
        }
        if fonts {
            chart
                .configure_series_labels()
                .background_style(WHITE.mix(0.8))
                .border_style(BLACK)
                .draw()
                .map_err(|e| e.to_string())?;
        }
        root.present().map_err(|e| e.to_string())?;
        Ok(())
    }
}

/// One curve: the points joined by a line (with a legend entry `label`) and marked by dots.
fn draw_curve(
    chart: &mut Chart<'_, '_>,
    pts: &[(f64, f64)],
    colour: RGBColor,
    label: &str,
) -> Result<(), String> {
    chart
        .draw_series(LineSeries::new(pts.iter().copied(), colour.stroke_width(2)))
        .map_err(|e| e.to_string())?
        .label(label)
        .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], colour));
    chart
        .draw_series(pts.iter().map(|p| Circle::new(*p, 4, colour.filled())))
        .map_err(|e| e.to_string())?;
    Ok(())
}
