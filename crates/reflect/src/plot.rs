//! The error-against-run-time plot of a solve (`convergence.png`), and of several solves of
//! one survey side by side ([`plot_runs`]).

use crate::record::SolveReport;
use crate::ReflectError;
use igi_plot::{write_chart, Axis, Chart, Series, BLUE_RGB, PALETTE, RED_RGB};
use std::path::Path;

/// Plots, against cumulative wall time, the relative photo residual RMS and (with ground
/// truth) the RMS error of `rho_d`, one point per iteration. Written atomically.
pub fn plot_convergence(report: &SolveReport, path: &Path) -> Result<(), ReflectError> {
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
    let mut series = vec![curve(pts_res, BLUE_RGB, "photo residual, relative RMS")];
    if !pts_truth.is_empty() {
        series.push(curve(pts_truth, RED_RGB, "rho_d RMS error vs truth"));
    }
    let chart = Chart {
        title: "igi solve: error against run time".into(),
        x: Axis::linear("cumulative wall time (s)", 0.0..xmax),
        y: Axis::linear("error", 0.0..ymax),
        series,
    };
    write_chart(path, (800, 500), &chart)?;
    Ok(())
}

/// Plots several solves of one survey with ground truth (`runs`: a label and the report of
/// each): the albedo MAE over the surface (the mean of the channels; per texel where a report
/// has no surface error) against cumulative wall time, one curve per run, each point an
/// iteration. Runs without truth errors are left out. Written atomically.
pub fn plot_runs(runs: &[(String, &SolveReport)], path: &Path) -> Result<(), ReflectError> {
    let mean = |m: [f32; 3]| (m[0] + m[1] + m[2]) as f64 / 3.0;
    let curves: Vec<(String, Vec<(f64, f64)>)> = runs
        .iter()
        .map(|(label, report)| {
            let points = report
                .iterations
                .iter()
                .filter_map(|r| {
                    let e = r.truth_surface_mae.or(r.truth_mae)?;
                    Some((r.cumulative_s, mean(e)))
                })
                .collect();
            (label.clone(), points)
        })
        .filter(|(_, p): &(String, Vec<(f64, f64)>)| !p.is_empty())
        .collect();
    let all = || curves.iter().flat_map(|(_, p)| p.iter());
    let xmax = all().map(|p| p.0).fold(0.0, f64::max).max(1e-3) * 1.05;
    let ymax = all().map(|p| p.1).fold(0.0, f64::max).max(1e-4) * 1.15;
    let series = curves
        .into_iter()
        .enumerate()
        .map(|(k, (label, points))| curve(points, PALETTE[k % PALETTE.len()], &label))
        .collect();
    let chart = Chart {
        title: "igi solve: albedo error against run time".into(),
        x: Axis::linear("cumulative wall time of the iterations (s)", 0.0..xmax),
        y: Axis::linear("rho_d MAE over the surface (mean of R, G, B)", 0.0..ymax),
        series,
    };
    write_chart(path, (800, 500), &chart)?;
    Ok(())
}

/// One curve: the points joined by a line (with a legend entry `label`) and marked by dots.
fn curve(points: Vec<(f64, f64)>, colour: [u8; 3], label: &str) -> Series {
    Series {
        dot_radius: 4,
        legend: Some(label.into()),
        ..Series::line(points, colour, 2)
    }
}
