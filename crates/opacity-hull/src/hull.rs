//! The visual hull of a set of views: carving, the surface mesh, reprojection checks, and the
//! volume against the number of views.

use crate::carve::{
    carve, carve_band_votes, carve_sets, CellGrid, ViewIndex, KEPT, MAX_VIEWS, UNSEEN,
};
use crate::raster::{iou_over, rasterize_depth, uncovered_fraction};
use crate::views::View;
use crate::HullError;
use glam::DVec3;
use igi_geometry::{marching_cubes, Grid, TriMesh};
use rand::seq::SliceRandom;
use rand::SeedableRng;
use std::path::Path;

/// A carved hull: the grid, the first carving view per cell, the surface.
#[derive(Clone, Debug)]
pub struct VisualHull {
    pub grid: CellGrid,
    /// Per cell, the index (into the views given) of the first view that carves it, [`KEPT`],
    /// or [`UNSEEN`] (carved because no view sees it as object).
    pub carver: Vec<ViewIndex>,
    pub mesh: TriMesh,
}

impl VisualHull {
    /// Cells kept by every view.
    pub fn occupied(&self) -> usize {
        self.carver.iter().filter(|&&c| c == KEPT).count()
    }

    /// Volume of the kept cells (cubic metres).
    pub fn volume(&self) -> f64 {
        let c = self.grid.cell_size();
        self.occupied() as f64 * c.x * c.y * c.z
    }
}

/// Bytes a carving cell holds at the build's peak: its first carving view and that view's
/// per-block copy (2 + 2), then its marching-cubes value (4) beside the first (measured: the
/// dino's `igi hull build` peaks at 281 MB at 256 cells a side and 1.21 GB at 512, 7.9 bytes
/// a cell more).
pub const BYTES_PER_CELL: u128 = 8;

/// Refuses, before any work, a carving of `resolution` cells a side whose grid would need more
/// memory than the limit (`IGI_MAX_MEMORY`, 8 GiB by default; [`BYTES_PER_CELL`] a cell).
pub fn check_carving_memory(resolution: usize) -> Result<(), HullError> {
    let cells = (resolution as u128).pow(3);
    let what = format!(
        "the carving grid of {resolution}^3 cells (--resolution {resolution}, {BYTES_PER_CELL} bytes a cell)"
    );
    igi_files::check_alloc_default(&what, cells * BYTES_PER_CELL)?;
    Ok(())
}

/// Carve the hull of `views` in the box with `resolution` cells per axis and extract its
/// surface (marching cubes on the occupancy, iso 0.5, closed at the box faces; each vertex
/// placed between its two centres by the mattes' contours). `rig` names the
/// capture in errors: when carving leaves nothing the error names the view that removed the
/// last cells.
pub fn carve_hull(
    rig: &Path,
    views: &[&View],
    min: DVec3,
    max: DVec3,
    resolution: usize,
) -> Result<VisualHull, HullError> {
    if !(2..=2048).contains(&resolution) {
        return Err(HullError::CarvingResolution(resolution));
    }
    if views.len() > MAX_VIEWS {
        return Err(HullError::TooManyViews {
            rig: rig.to_path_buf(),
            views: views.len(),
            max: MAX_VIEWS,
        });
    }
    check_carving_memory(resolution)?;
    let grid = CellGrid::new(min, max, resolution);
    let mut carver = carve(&grid, views);
    carve_band_votes(&grid, views, &mut carver);
    if !carver.contains(&KEPT) {
        let last = carver.iter().copied().filter(|&v| v != UNSEEN).max();
        return Err(HullError::CarvedEmpty {
            rig: rig.to_path_buf(),
            view: last.map_or_else(
                || "none (no view sees any cell of the box as object)".to_string(),
                |v| views[v as usize].id.clone(),
            ),
        });
    }
    let mesh = occupancy_mesh(&grid, &carver, views)?;
    Ok(VisualHull { grid, carver, mesh })
}

/// Marching cubes on the kept cells padded with one empty layer, its vertices placed between
/// the centres by the mattes' contours ([`crate::contour::occupancy_values`]).
fn occupancy_mesh(
    grid: &CellGrid,
    carver: &[ViewIndex],
    views: &[&View],
) -> Result<TriMesh, HullError> {
    let (values, dims) = crate::contour::occupancy_values(grid, carver, views);
    let cs = grid.cell_size();
    let origin = grid.min - cs * 0.5;
    let g = Grid {
        values: &values,
        dims,
        origin: origin.as_vec3().to_array(),
        spacing: cs.as_vec3().to_array(),
    };
    Ok(marching_cubes(&g, 0.5)?)
}

/// How well the hull reproduces one view's silhouette.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Reprojection {
    pub view: String,
    /// IoU of the hull's projection and the silhouette over the view's known pixels.
    pub iou: f64,
    /// Fraction of the silhouette the hull's projection misses.
    pub uncovered: f64,
    pub silhouette_pixels: usize,
}

/// Project `mesh` into `view` and compare with its silhouette.
pub fn reproject(mesh: &TriMesh, view: &View) -> Reprojection {
    let cover = rasterize_depth(mesh, &view.camera).coverage();
    Reprojection {
        view: view.id.clone(),
        iou: iou_over(&cover, &view.silhouette, &view.known),
        uncovered: uncovered_fraction(&view.silhouette, &cover, &view.known),
        silhouette_pixels: view.silhouette.count(),
    }
}

/// Leave-one-out: for each view, the hull of all the others projected into it.
pub fn leave_one_out(
    rig: &Path,
    views: &[View],
    min: DVec3,
    max: DVec3,
    resolution: usize,
) -> Result<Vec<Reprojection>, HullError> {
    (0..views.len())
        .map(|held| {
            let others: Vec<&View> = views
                .iter()
                .enumerate()
                .filter(|(i, _)| *i != held)
                .map(|(_, v)| v)
                .collect();
            let hull = carve_hull(rig, &others, min, max, resolution)?;
            Ok(reproject(&hull.mesh, &views[held]))
        })
        .collect()
}

/// Volume (kept cells / cells kept by all views) after the first 1..=n views, for `orders`
/// random orders of the views (seeded): the curves of Matusik et al.'s Fig. 12.
pub fn volume_curves(
    views: &[&View],
    min: DVec3,
    max: DVec3,
    resolution: usize,
    orders: usize,
    seed: u64,
) -> Vec<Vec<f64>> {
    let grid = CellGrid::new(min, max, resolution);
    let sets = carve_sets(&grid, views);
    let final_volume = (0..sets.len()).filter(|&c| sets.kept(c)).count().max(1) as f64;
    let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
    (0..orders)
        .map(|_| {
            let mut order: Vec<usize> = (0..views.len()).collect();
            order.shuffle(&mut rng);
            volume_in_order(&sets, &order, final_volume)
        })
        .collect()
}

/// Relative volume after the first 1..=n views of `order`: each cell is counted until the
/// first view of the order that carves it (one pass over the cells, whatever the view count).
fn volume_in_order(sets: &crate::carve::ViewSets, order: &[usize], final_volume: f64) -> Vec<f64> {
    let n = order.len();
    let first = |c: usize| order.iter().position(|&v| sets.carves(c, v)).unwrap_or(n);
    let mut carved_at = vec![0usize; n + 1];
    for c in 0..sets.len() {
        carved_at[first(c)] += 1;
    }
    let mut left = sets.len();
    (0..n)
        .map(|k| {
            left -= carved_at[k];
            left as f64 / final_volume
        })
        .collect()
}

/// Plot volume curves (relative volume against the number of views) to a PNG, atomically.
pub fn plot_volume_curves(path: &Path, curves: &[Vec<f64>]) -> Result<(), HullError> {
    use igi_plot::{write_chart, Axis, Chart, Series, BLUE_RGB};
    let n = curves.first().map_or(1, Vec::len);
    let ymax = curves
        .iter()
        .flatten()
        .fold(1.0f64, |a, &b| a.max(b))
        .min(50.0)
        * 1.05;
    let series = curves
        .iter()
        .map(|c| {
            let pts = c.iter().enumerate();
            let pts = pts.map(|(i, &v)| ((i + 1) as f64, v.min(ymax))).collect();
            Series {
                opacity: 0.4,
                ..Series::line(pts, BLUE_RGB, 1)
            }
        })
        .collect();
    let chart = Chart {
        title: "visual hull volume against views (random orders)".into(),
        x: Axis::linear("number of views", 1f64..n as f64),
        y: Axis::linear("volume / final volume", 0.9f64..ymax),
        series,
    };
    write_chart(path, (800, 500), &chart)?;
    Ok(())
}
