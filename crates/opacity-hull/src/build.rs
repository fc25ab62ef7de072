//! `igi hull build`: a rig in, a hull folder out.
//!
//! The folder holds `hull.json` (the manifest: the rig file, the views in order, the grid),
//! `hull.ply` (the visual hull's surface), `surfels.ply` (surfels with per-view visibility and
//! opacity), `mattes/ID.exr` (each view's alpha, the matte validity as the `valid` channel),
//! `volume.png` (volume against views over random orders, Fig. 12) and `report.json` (per-view
//! reprojection IoU, timings). A rig whose views have light images adds `reflectance/` (the
//! surface reflectance field, [`crate::reflectance`]) and its numbers to the report. It is assembled in a temporary sibling folder and renamed into
//! place, so a failure leaves nothing.

use crate::hull::{
    carve_hull, plot_volume_curves, reproject, volume_curves, Reprojection, VisualHull,
};
use crate::lightweights::light_weights;
use crate::reflectance::{build_fields, read_fields, FieldOptions, ReflectanceReport, ViewField};
use crate::render::HullModel;
use crate::surfel::{make_surfels, Surfels};
use crate::views::{load_views, MatteOptions, View};
use crate::HullError;
use glam::DVec3;
use igi_camera::rig::Rig;
use igi_camera::Camera;
use igi_formats::lighting::LightingRadiance;
use igi_geometry::{PointCloud, TriMesh};
use igi_imaging::{read_image, HdrImage};
use rayon::prelude::*;
use std::path::{Path, PathBuf};
use std::time::Instant;

/// The surfels' splat radius, in the largest edge of a carving cell. The paper's one cell
/// widened every thin part and every rim by about a pixel; 0.7 is the smallest that keeps the
/// dino's surfaces closed (0.6 opens holes; docs/OPACITY_HULL.md, "Splat radius").
pub const SPLAT_RADIUS: f64 = 0.7;

/// Build options.
#[derive(Clone, Copy, Debug)]
pub struct BuildOptions {
    /// Carving cells per axis of the bounding box (at least 256: cells no coarser than bbox/256).
    pub resolution: usize,
    pub matte: MatteOptions,
    /// Random view orders for the volume plot, and its grid resolution.
    pub volume_orders: usize,
    pub volume_resolution: usize,
    pub seed: u64,
    /// The reflectance field's PCA (used when the rig has light images).
    pub field: FieldOptions,
}

impl Default for BuildOptions {
    fn default() -> Self {
        BuildOptions {
            resolution: 256,
            matte: MatteOptions::default(),
            volume_orders: 30,
            volume_resolution: 64,
            seed: 1,
            field: FieldOptions::default(),
        }
    }
}

/// The manifest `hull.json`.
#[derive(Clone, Debug, serde::Serialize, serde::Deserialize)]
pub struct Manifest {
    /// The rig file: relative to the hull folder, or absolute where the two share only the
    /// root (older folders name it absolutely; both are read).
    pub rig: PathBuf,
    pub views: Vec<String>,
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    pub resolution: usize,
    pub surfels: usize,
}

/// Seconds spent per stage.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct Timings {
    pub load_s: f64,
    pub carve_s: f64,
    pub surfels_s: f64,
    pub reproject_s: f64,
    pub volume_s: f64,
    pub write_s: f64,
}

/// `report.json`.
#[derive(Clone, Debug, serde::Serialize)]
pub struct BuildReport {
    pub views: Vec<Reprojection>,
    pub iou_min: f64,
    pub iou_mean: f64,
    pub resolution: usize,
    pub cell_size: [f64; 3],
    pub volume_m3: f64,
    pub triangles: usize,
    pub surfels: usize,
    pub timings: Timings,
    /// The surface reflectance field (only when the rig has light images).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub reflectance: Option<ReflectanceReport>,
}

/// Stages reported to a progress callback.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Stage {
    Load,
    Carve,
    Surfels,
    Reproject,
    /// Only when the rig has light images.
    Reflectance,
    Volume,
    Write,
}

/// Build a hull folder from a rig (see the module docs). `progress` hears each stage start.
pub fn build(
    rig: &Rig,
    out: &Path,
    opts: BuildOptions,
    progress: &mut dyn FnMut(Stage),
) -> Result<BuildReport, HullError> {
    if opts.resolution < 256 {
        return Err(HullError::CoarseResolution(opts.resolution));
    }
    if rig.views.len() > crate::carve::MAX_VIEWS {
        return Err(HullError::TooManyViews {
            rig: rig.path.clone(),
            views: rig.views.len(),
            max: crate::carve::MAX_VIEWS,
        });
    }
    crate::hull::check_carving_memory(opts.resolution)?;
    // the output claimed and checked before any work (staging of this process, the lock)
    let staging = igi_files::Staging::begin(out)?;
    check_output(out)?;
    let mut t = Timings::default();
    let mut clock = Instant::now();
    let mut lap = |slot: &mut f64| {
        *slot = clock.elapsed().as_secs_f64();
        clock = Instant::now();
    };
    progress(Stage::Load);
    crate::reflectance::check_light_files(rig)?;
    let views = load_views(rig, opts.matte)?;
    lap(&mut t.load_s);
    progress(Stage::Carve);
    let (min, max) = (
        DVec3::from_array(rig.object.bbox_min),
        DVec3::from_array(rig.object.bbox_max),
    );
    let refs: Vec<&View> = views.iter().collect();
    let hull = carve_hull(&rig.path, &refs, min, max, opts.resolution)?;
    lap(&mut t.carve_s);
    progress(Stage::Surfels);
    let cell = hull.grid.cell_size().max_element();
    let surfels = make_surfels(&hull.mesh, (SPLAT_RADIUS * cell) as f32, 1.5 * cell, &views);
    lap(&mut t.surfels_s);
    progress(Stage::Reproject);
    let reps: Vec<Reprojection> = views.par_iter().map(|v| reproject(&hull.mesh, v)).collect();
    lap(&mut t.reproject_s);
    if rig.views.iter().any(|v| !v.lights.is_empty()) {
        progress(Stage::Reflectance);
    }
    let field = build_fields(rig, &views, &surfels, opts.field)?;
    lap(&mut 0.0); // timed in its own report
    progress(Stage::Volume);
    let curves = volume_curves(
        &refs,
        min,
        max,
        opts.volume_resolution,
        opts.volume_orders,
        opts.seed,
    );
    lap(&mut t.volume_s);
    progress(Stage::Write);
    let manifest = hull_manifest(rig, out, &views, &opts, surfels.len())?;
    let mut report = build_report(reps, &opts, &hull, surfels.len(), t);
    report.reflectance = field.as_ref().map(|f| f.1.clone());
    let write_start = Instant::now();
    write_staged(staging, |dir| {
        write_products(dir, &manifest, &hull.mesh, &surfels, &views, &curves)?;
        if let Some((fields, r)) = &field {
            crate::reflectance::write_fields(dir, fields, r)?;
        }
        report.timings.write_s = write_start.elapsed().as_secs_f64();
        igi_files::write_text_atomic(
            &dir.join("report.json"),
            &serde_json::to_string_pretty(&stored_report(&report)).expect("report"),
        )?;
        Ok(())
    })?;
    Ok(report)
}

/// The report as the folder stores it: without wall-clock times (`timings`, the reflectance
/// fit's `seconds`), so identical builds give identical bytes; the command prints them.
fn stored_report(report: &BuildReport) -> serde_json::Value {
    let mut v = serde_json::to_value(report).expect("report");
    if let Some(o) = v.as_object_mut() {
        o.remove("timings");
        if let Some(r) = o.get_mut("reflectance").and_then(|r| r.as_object_mut()) {
            r.remove("seconds");
        }
    }
    v
}

/// The `hull.json` of the folder `out`. It names the rig relative to `out` when the two share
/// more than the root, so a capture folder holding both can move as one.
fn hull_manifest(
    rig: &Rig,
    out: &Path,
    views: &[View],
    opts: &BuildOptions,
    surfels: usize,
) -> Result<Manifest, HullError> {
    Ok(Manifest {
        rig: igi_files::named_from(&rig.path, out).map_err(|e| HullError::io(&rig.path, e))?,
        views: views.iter().map(|v| v.id.clone()).collect(),
        bbox_min: rig.object.bbox_min,
        bbox_max: rig.object.bbox_max,
        resolution: opts.resolution,
        surfels,
    })
}

/// The report (its write time is filled in while writing).
fn build_report(
    reps: Vec<Reprojection>,
    opts: &BuildOptions,
    hull: &VisualHull,
    surfels: usize,
    timings: Timings,
) -> BuildReport {
    BuildReport {
        iou_min: reps.iter().map(|r| r.iou).fold(1.0, f64::min),
        iou_mean: reps.iter().map(|r| r.iou).sum::<f64>() / reps.len() as f64,
        views: reps,
        resolution: opts.resolution,
        cell_size: hull.grid.cell_size().to_array(),
        volume_m3: hull.volume(),
        triangles: hull.mesh.triangle_count(),
        surfels,
        timings,
        reflectance: None,
    }
}

/// Everything in the folder but the report: manifest, hull mesh, surfels, mattes, volume plot.
fn write_products(
    dir: &Path,
    manifest: &Manifest,
    mesh: &TriMesh,
    surfels: &Surfels,
    views: &[View],
    curves: &[Vec<f64>],
) -> Result<(), HullError> {
    igi_files::write_text_atomic(
        &dir.join("hull.json"),
        &serde_json::to_string_pretty(manifest).expect("manifest"),
    )?;
    igi_geometry::write_ply(&dir.join("hull.ply"), mesh)?;
    igi_geometry::write_points_ply(&dir.join("surfels.ply"), &surfels.to_cloud())?;
    std::fs::create_dir_all(dir.join("mattes"))
        .map_err(|e| HullError::io(dir.join("mattes"), e))?;
    for v in views {
        igi_imaging::write_exr(
            &dir.join("mattes").join(format!("{}.exr", v.id)),
            &v.matte.to_image(),
        )?;
    }
    plot_volume_curves(&dir.join("volume.png"), curves)?;
    Ok(())
}

fn check_output(out: &Path) -> Result<(), HullError> {
    if out.exists()
        && std::fs::read_dir(out)
            .map_err(|e| HullError::io(out, e))?
            .next()
            .is_some()
    {
        return Err(HullError::io(
            out,
            std::io::Error::new(
                std::io::ErrorKind::AlreadyExists,
                "output folder exists and is not empty",
            ),
        ));
    }
    Ok(())
}

/// Fill a staging folder beside `out` with `fill`, then rename it to `out` (which must be
/// absent or empty); on error the staging folder is removed (`igi_files::Staging`: per-process
/// names, dead ones removed, the lock).
pub(crate) fn write_folder(
    out: &Path,
    fill: impl FnOnce(&Path) -> Result<(), HullError>,
) -> Result<(), HullError> {
    let staging = igi_files::Staging::begin(out)?;
    check_output(out)?;
    write_staged(staging, fill)
}

/// [`write_folder`] into a staging folder begun before the work.
fn write_staged(
    staging: igi_files::Staging,
    fill: impl FnOnce(&Path) -> Result<(), HullError>,
) -> Result<(), HullError> {
    fill(staging.path())?;
    staging.commit(false)?;
    Ok(())
}

/// A hull folder opened for rendering: its manifest, surfels and rig.
struct OpenHull {
    manifest_path: PathBuf,
    manifest: Manifest,
    surfels: Surfels,
    rig: Rig,
}

fn open_hull(dir: &Path) -> Result<OpenHull, HullError> {
    let mpath = dir.join("hull.json");
    let text = std::fs::read_to_string(&mpath).map_err(|e| HullError::io(&mpath, e))?;
    let manifest: Manifest = serde_json::from_str(&text).map_err(|e| HullError::HullFolder {
        path: mpath.clone(),
        msg: e.to_string(),
    })?;
    let cloud = igi_geometry::read_points_ply(&dir.join("surfels.ply"))?;
    check_folder(&manifest, &cloud, dir)?;
    let nv = manifest.views.len();
    let surfels = Surfels::from_cloud(&cloud, nv).ok_or_else(|| HullError::HullFolder {
        path: dir.join("surfels.ply"),
        msg: format!("lacks the normals, radius, visibility or opacity properties of {nv} views"),
    })?;
    // a relative rig is relative to the hull folder (FORMATS.md); older folders name it
    // absolutely
    let rig = Rig::load(&dir.join(&manifest.rig))?;
    Ok(OpenHull {
        manifest_path: mpath,
        manifest,
        surfels,
        rig,
    })
}

/// What `hull.json` and `surfels.ply` must hold for a render to mean the capture: at least one
/// view, each once, and exactly that many opacity columns; opacities in [0, 1], positive splat
/// radii and areas of at least 0 (the finite values `read_points_ply` already checked).
fn check_folder(manifest: &Manifest, cloud: &PointCloud, dir: &Path) -> Result<(), HullError> {
    let bad = |file: &str, msg: String| HullError::HullFolder {
        path: dir.join(file),
        msg,
    };
    let nv = manifest.views.len();
    if nv == 0 {
        return Err(bad("hull.json", "lists no views".into()));
    }
    let mut seen = std::collections::HashSet::new();
    if let Some(v) = manifest.views.iter().find(|v| !seen.insert(v.as_str())) {
        return Err(bad("hull.json", format!("lists view {v:?} twice")));
    }
    if cloud.property(&format!("alpha_v{nv}")).is_some() {
        let msg = format!("holds the opacities of more views than the {nv} of hull.json");
        return Err(bad("surfels.ply", msg));
    }
    for v in 0..nv {
        let Some(a) = cloud.property(&format!("alpha_v{v}")) else {
            continue; // Surfels::from_cloud names the missing column
        };
        if let Some(s) = a.iter().position(|a| !(0.0..=1.0).contains(a)) {
            let msg = format!(
                "alpha_v{v} of point {s} is {}, not an opacity in [0, 1]",
                a[s]
            );
            return Err(bad("surfels.ply", msg));
        }
    }
    if let Some(s) = cloud.radii.iter().flatten().position(|r| !(*r > 0.0)) {
        let r = cloud.radii.as_ref().map_or(0.0, |r| r[s]);
        return Err(bad(
            "surfels.ply",
            format!("radius of point {s} is {r}, not positive"),
        ));
    }
    let area = cloud.property("area").unwrap_or_default();
    if let Some(s) = area.iter().position(|a| !(*a >= 0.0)) {
        let msg = format!("area of point {s} is {}, not an area (at least 0)", area[s]);
        return Err(bad("surfels.ply", msg));
    }
    Ok(())
}

impl OpenHull {
    /// The rig's view `id` and its camera.
    fn view(&self, id: &str) -> Result<(&igi_camera::rig::RigView, Camera), HullError> {
        let rv = self.rig.view(id).ok_or_else(|| HullError::HullFolder {
            path: self.manifest_path.clone(),
            msg: format!("view {id:?} is not in {}", self.rig.path.display()),
        })?;
        Ok((rv, self.rig.load_camera(rv)?))
    }

    /// The model with `colors[s * views + v]` sampled from `image(v)` (views whose image is
    /// `None` are taken out of every surfel's visibility).
    fn model(
        mut self,
        mut image: impl FnMut(&Self, usize) -> Result<(Camera, Option<HdrImage>), HullError>,
    ) -> Result<HullModel, HullError> {
        let nv = self.manifest.views.len();
        let mut centres = Vec::with_capacity(nv);
        let mut colors = vec![[0.0f32; 3]; self.surfels.len() * nv];
        for v in 0..nv {
            let (cam, img) = image(&self, v)?;
            centres.push(cam.center_world());
            match img {
                Some(img) => sample_view(&self.surfels, v, &cam, &img, &mut colors),
                None => {
                    for s in 0..self.surfels.len() {
                        self.surfels.visible[s * nv + v] = false;
                    }
                }
            }
        }
        Ok(HullModel {
            surfels: self.surfels,
            centres,
            colors,
        })
    }
}

/// `colors[s * views + v]` for the surfels visible in view `v`: `image` (bilinear; the nearest
/// pixel at the border) at their projection.
fn sample_view(
    surfels: &Surfels,
    v: usize,
    cam: &Camera,
    image: &HdrImage,
    colors: &mut [[f32; 3]],
) {
    let nv = surfels.views;
    for s in 0..surfels.len() {
        if !surfels.visible[s * nv + v] {
            continue;
        }
        let p = DVec3::from_array(surfels.positions[s].map(f64::from));
        if let Some(px) = cam.project(p) {
            colors[s * nv + v] = image.bilinear(px.x as f32, px.y as f32).unwrap_or_else(|| {
                let (x, y) = (
                    px.x.round().clamp(0.0, image.width as f64 - 1.0),
                    px.y.round().clamp(0.0, image.height as f64 - 1.0),
                );
                image.get(x as usize, y as usize)
            });
        }
    }
}

/// Load a hull folder for rendering: the surfels, and each view's camera centre and photo
/// samples at the surfels it sees (read again from the rig the manifest names).
pub fn load_model(dir: &Path) -> Result<HullModel, HullError> {
    open_hull(dir)?.model(|h, v| {
        let (rv, cam) = h.view(&h.manifest.views[v])?;
        let photo = read_image(&rv.photo).map_err(|e| h.rig.view_error(rv, e))?;
        Ok((cam, Some(photo)))
    })
}

/// Load a hull folder for rendering under new light (Eq. 3): each view's image is its
/// reflectance field relit with the light weights of `light` over its light directions
/// ([`light_weights`]); views without a field are not blended. A hull without a reflectance
/// field is refused ([`HullError::NoReflectance`], naming the folder).
pub fn load_relit_model(dir: &Path, light: &LightingRadiance) -> Result<HullModel, HullError> {
    let Some(fields) = read_fields(dir)? else {
        open_hull(dir)?; // a folder that is no hull folder at all says so first
        return Err(HullError::NoReflectance {
            dir: dir.to_path_buf(),
        });
    };
    let hull = open_hull(dir)?;
    let field_of = |id: &str| -> Option<&ViewField> { fields.iter().find(|f| f.id == id) };
    hull.model(|h, v| {
        let id = &h.manifest.views[v];
        let (_, cam) = h.view(id)?;
        let Some(f) = field_of(id) else {
            return Ok((cam, None));
        };
        if (f.width, f.height) != (cam.width as usize, cam.height as usize) {
            return Err(HullError::HullFolder {
                path: crate::reflectance::folder(dir),
                msg: format!(
                    "view {id:?} is {}x{} but its camera is {}x{}",
                    f.width, f.height, cam.width, cam.height
                ),
            });
        }
        let weights = light_weights(light, &f.directions)?;
        Ok((cam, Some(f.relight(&weights))))
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn manifest(views: &[&str]) -> Manifest {
        Manifest {
            rig: PathBuf::from("rig.toml"),
            views: views.iter().map(|v| v.to_string()).collect(),
            bbox_min: [0.0; 3],
            bbox_max: [1.0; 3],
            resolution: 256,
            surfels: 2,
        }
    }

    /// Two surfels with the opacities of two views.
    fn cloud() -> PointCloud {
        let column = |name: &str, v: [f32; 2]| (name.to_string(), v.to_vec());
        PointCloud {
            positions: vec![[0.0; 3], [1.0, 0.0, 0.0]],
            normals: Some(vec![[0.0, 0.0, 1.0]; 2]),
            radii: Some(vec![0.01, 0.02]),
            properties: vec![
                column("vis0", [3.0, 1.0]),
                column("alpha_v0", [1.0, 0.0]),
                column("alpha_v1", [0.5, 1.0]),
            ],
            ..Default::default()
        }
    }

    /// A hull folder whose manifest and surfels disagree, or whose opacities and radii cannot
    /// be a hull's, is refused naming the file (each rendered before, some as an empty image).
    #[test]
    fn a_hull_folder_that_cannot_mean_the_capture_is_refused_naming_the_file() {
        let dir = Path::new("h");
        assert!(check_folder(&manifest(&["a", "b"]), &cloud(), dir).is_ok());
        let mut wide_alpha = cloud();
        wide_alpha.properties[2].1[0] = 1.5;
        let mut no_radius = cloud();
        no_radius.radii = Some(vec![0.01, 0.0]);
        let mut negative_area = cloud();
        negative_area
            .properties
            .push(("area".into(), vec![1e-4, -1e-4]));
        for (m, c, file, says) in [
            (manifest(&[]), cloud(), "hull.json", "lists no views"),
            (
                manifest(&["a", "a"]),
                cloud(),
                "hull.json",
                "lists view \"a\" twice",
            ),
            (
                manifest(&["a"]),
                cloud(),
                "surfels.ply",
                "more views than the 1",
            ),
            (
                manifest(&["a", "b"]),
                wide_alpha,
                "surfels.ply",
                "alpha_v1 of point 0 is 1.5",
            ),
            (
                manifest(&["a", "b"]),
                no_radius,
                "surfels.ply",
                "radius of point 1 is 0",
            ),
            (
                manifest(&["a", "b"]),
                negative_area,
                "surfels.ply",
                "area of point 1 is -0.0001",
            ),
        ] {
            let err = check_folder(&m, &c, dir).unwrap_err().to_string();
            assert!(err.contains(file) && err.contains(says), "{err}");
        }
    }
}
