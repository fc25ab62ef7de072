//! The error-against-run-time plot of a solve (`convergence.png`).

use crate::solver::SolveReport;
use crate::ReflectError;
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
    let draw = |tmp: &Path| -> Result<(), String> {
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
            .build_cartesian_2d(0.0..xmax, 0.0..ymax)
            .map_err(|e| e.to_string())?;
        if fonts {
            chart
                .configure_mesh()
                .x_desc("cumulative wall time (s)")
                .y_desc("error")
                .draw()
                .map_err(|e| e.to_string())?;
        }
        chart
            .draw_series(LineSeries::new(
                pts_res.iter().copied(),
                BLUE.stroke_width(2),
            ))
            .map_err(|e| e.to_string())?
            .label("photo residual, relative RMS")
            .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], BLUE));
        chart
            .draw_series(pts_res.iter().map(|p| Circle::new(*p, 4, BLUE.filled())))
            .map_err(|e| e.to_string())?;
        if !pts_truth.is_empty() {
            chart
                .draw_series(LineSeries::new(
                    pts_truth.iter().copied(),
                    RED.stroke_width(2),
                ))
                .map_err(|e| e.to_string())?
                .label("rho_d RMS error vs truth")
                .legend(|(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], RED));
            chart
                .draw_series(pts_truth.iter().map(|p| Circle::new(*p, 4, RED.filled())))
                .map_err(|e| e.to_string())?;
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
    };
    igi_imaging::io::write_atomic(path, |tmp| {
        draw(tmp).map_err(|e| igi_imaging::ImagingError::Encode {
            path: path.to_path_buf(),
            msg: format!("cannot draw plot: {e}"),
        })
    })?;
    Ok(())
}
