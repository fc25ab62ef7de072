//! Assembling data lumispheres (Sec. 4.1): for every grid point (a covered atlas texel of the
//! mesh) the (colour, direction) pairs of the views that see it. Visibility is a ray cast from
//! the point (offset along its normal) to the camera centre through igi-render's Embree scene
//! of the mesh; colours are bilinear lookups that fail when any tap is an invalid pixel (so
//! masked or clipped pixels never contribute). Pixels off the mesh, and those whose footprint
//! may straddle its silhouette against the background, are invalid too: a ray cast of every
//! pixel centre must hit the mesh, and so must those of its 8 neighbours. Then the
//! reparameterisation of Eqs. 9-10, with the view-angle gain taken out.

use crate::fit::{DataLumisphere, Sample};
use crate::lumisphere::{median_rgb, reflect_about_normal, AngleGain, Octahedron};
use glam::Vec3;
use igi_camera::Camera;
use igi_imaging::HdrImage;
use igi_raycast::offset_origin;
use igi_raycast::RtScene;
use rayon::prelude::*;

/// One photograph and its camera (image size equal to the camera's; checked by the caller).
#[derive(Clone, Copy)]
pub struct View<'a> {
    pub camera: &'a Camera,
    pub image: &'a HdrImage,
}

/// A surface grid point.
#[derive(Clone, Copy, Debug)]
pub struct GridPoint {
    pub position: Vec3,
    pub normal: Vec3,
}

/// The raw observations of one grid point: (colour, unit direction toward the camera).
pub type Observations = Vec<(Vec3, Vec3)>;

/// What the gathering saw.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct GatherReport {
    pub points: usize,
    /// Grid points no view sees (their lumisphere stays zero: median only, and the median is 0).
    pub unseen_points: usize,
    pub samples: usize,
    /// Pixels of the views (over all views) that see the mesh but are invalid as lying on its
    /// silhouette (a neighbour's centre ray misses the mesh).
    pub edge_pixels: usize,
    /// Median over observations of the pixel footprint on the surface (metres per pixel at the
    /// point's distance), to compare with the atlas texel size.
    pub median_pixel_footprint: f64,
}

/// Marks pixels of an 8-bit photo whose channel reached the clip level as invalid.
pub fn mask_clipped(img: &mut HdrImage, clip: f32) {
    for (p, v) in img.pixels.iter().zip(img.valid.iter_mut()) {
        if p.iter().any(|c| *c >= clip) {
            *v = false;
        }
    }
}

/// The observations of every grid point in every view (parallel over points; the order of the
/// samples is the order of the views, so the result does not depend on the thread count).
pub fn gather(
    scene: &RtScene,
    points: &[GridPoint],
    views: &[View],
) -> (Vec<Observations>, GatherReport) {
    let hits: Vec<Vec<bool>> = views.par_iter().map(|v| pixel_hits(scene, v)).collect();
    gather_with_hits(scene, points, views, &hits)
}

/// [`gather`] with each view's [`pixel_hits`] already cast (one per view, in order).
pub fn gather_with_hits(
    scene: &RtScene,
    points: &[GridPoint],
    views: &[View],
    hits: &[Vec<bool>],
) -> (Vec<Observations>, GatherReport) {
    let cleaned: Vec<(HdrImage, usize)> = views
        .par_iter()
        .zip(hits)
        .map(|(v, hit)| without_edges(v, hit))
        .collect();
    let views: Vec<View> = views
        .iter()
        .zip(&cleaned)
        .map(|(v, (image, _))| View {
            camera: v.camera,
            image,
        })
        .collect();
    let per_point: Vec<(Observations, Vec<f64>)> = points
        .par_iter()
        .map(|p| observe(scene, p, &views))
        .collect();
    let mut footprints: Vec<f64> = per_point
        .iter()
        .flat_map(|(_, f)| f.iter().copied())
        .collect();
    footprints.sort_by(|a, b| a.total_cmp(b));
    let obs: Vec<Observations> = per_point.into_iter().map(|(o, _)| o).collect();
    let report = GatherReport {
        points: points.len(),
        unseen_points: obs.iter().filter(|o| o.is_empty()).count(),
        samples: obs.iter().map(|o| o.len()).sum(),
        edge_pixels: cleaned.iter().map(|(_, n)| n).sum(),
        median_pixel_footprint: footprints.get(footprints.len() / 2).copied().unwrap_or(0.0),
    };
    (obs, report)
}

/// Whether each pixel centre's ray through the view's camera hits the scene (row-major, the
/// photograph's size).
pub fn pixel_hits(scene: &RtScene, v: &View) -> Vec<bool> {
    let w = v.image.width;
    (0..w * v.image.height)
        .into_par_iter()
        .map(|i| {
            let (o, d) = v.camera.pixel_ray((i % w) as f64, (i / w) as f64);
            scene
                .intersect(o.as_vec3(), d.as_vec3(), 0.0, f32::INFINITY)
                .is_some()
        })
        .collect()
}

/// A copy of the view's photograph whose pixels off the mesh or on its silhouette are invalid (a
/// pixel is kept when its centre ray and those of its 8 neighbours hit the mesh: `hit`, from
/// [`pixel_hits`]), and the number of valid pixels on the mesh dropped as silhouette pixels.
fn without_edges(v: &View, hit: &[bool]) -> (HdrImage, usize) {
    let (w, h) = (v.image.width, v.image.height);
    let mut img = v.image.clone();
    let mut dropped = 0;
    for (i, valid) in img.valid.iter_mut().enumerate() {
        let (x, y) = ((i % w) as i64, (i / w) as i64);
        let inside = (-1..=1i64).all(|dy| {
            (-1..=1i64).all(|dx| {
                let (a, b) = (x + dx, y + dy);
                a >= 0
                    && b >= 0
                    && (a as usize) < w
                    && (b as usize) < h
                    && hit[b as usize * w + a as usize]
            })
        });
        if !inside {
            dropped += usize::from(*valid && hit[i]);
            *valid = false;
        }
    }
    (img, dropped)
}

fn observe(scene: &RtScene, p: &GridPoint, views: &[View]) -> (Observations, Vec<f64>) {
    let mut out = Vec::new();
    let mut footprint = Vec::new();
    let origin = offset_origin(p.position, p.normal);
    for v in views {
        let centre = v.camera.center_world().as_vec3();
        let to_cam = centre - p.position;
        let dist = to_cam.length();
        let w = to_cam / dist;
        if !(dist > 0.0) || w.dot(p.normal) <= 0.0 {
            continue;
        }
        let Some(px) = v.camera.project(p.position.as_dvec3()) else {
            continue;
        };
        let Some(c) = v.image.bilinear(px.x as f32, px.y as f32) else {
            continue;
        };
        if scene.occluded(origin, w, 0.0, dist * 0.999) {
            continue;
        }
        out.push((Vec3::from_array(c), w));
        footprint.push(dist as f64 / v.camera.intrinsics.fx);
    }
    (out, footprint)
}

/// Eq. 9's median: the per-channel median of a point's observed colours.
pub fn observation_median(obs: &Observations) -> Vec3 {
    let colours: Vec<Vec3> = obs.iter().map(|(c, _)| *c).collect();
    median_rgb(&colours)
}

/// The view-angle gain of a capture ([`AngleGain::estimate`]) from every point's observations,
/// normal and median.
pub fn angle_gain(obs: &[Observations], points: &[GridPoint], medians: &[Vec3]) -> AngleGain {
    AngleGain::estimate(obs.iter().zip(points).zip(medians).flat_map(|((o, p), m)| {
        o.iter()
            .map(move |(c, w)| (w.dot(p.normal), (*c - *m).length_squared()))
    }))
}

/// Eqs. 9-10: the samples with the point's median removed, divided by the view-angle gain at
/// their n . w, and their directions reflected about the normal, located on the lumisphere.
pub fn reparameterise(
    oct: &Octahedron,
    obs: &Observations,
    normal: Vec3,
    median: Vec3,
    gain: &AngleGain,
) -> DataLumisphere {
    let samples = obs
        .iter()
        .map(|(c, w)| Sample {
            bary: oct.locate(reflect_about_normal(*w, normal)),
            colour: (*c - median) / gain.at(w.dot(normal)),
        })
        .collect();
    DataLumisphere { samples }
}
