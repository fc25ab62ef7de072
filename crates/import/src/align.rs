//! A model aligned to the scan by ground control points: each point triangulated from its
//! observations (the midpoint of its rays in least squares, pixels undistorted through the
//! image's contract camera), then the similarity `x_scan = s R x_model + t` fitted by Umeyama's
//! method inside a deterministic RANSAC over triples, and refitted on the inliers.
//!
//! The bound on the residuals ([`AlignOptions::max_residual`], by default
//! [`DEFAULT_RESIDUAL_FRACTION`] of the control points' spread) is both the inlier threshold and
//! the largest RMS residual of the inliers accepted.

use std::collections::HashMap;
use std::path::Path;

use glam::{DMat3, DVec3};
use igi_camera::{Camera, WorldToCamera};
use igi_formats::ControlObservation;
use nalgebra::{Matrix3, SymmetricEigen, Vector3};
use serde::Serialize;

use crate::error::ImportError;

/// The default bound on control residuals: this fraction of the points' spread (the RMS
/// distance of the surveyed points from their centroid).
pub const DEFAULT_RESIDUAL_FRACTION: f64 = 0.05;

/// Points whose second singular value (of the centred surveyed positions) is below this
/// fraction of the first lie too near a line to fix a rotation about it.
pub const COLINEAR_RATIO: f64 = 1e-3;

/// Triples tried by RANSAC at most (all of them when there are fewer).
const RANSAC_TRIALS: usize = 2000;

/// How the alignment is fitted and accepted.
#[derive(Clone, Copy, Debug, Default)]
pub struct AlignOptions {
    /// Metres: inlier threshold and largest accepted RMS residual (default: 5 % of the spread).
    pub max_residual: Option<f64>,
}

/// `x_scan = scale * rotation * x_model + translation`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Similarity {
    pub scale: f64,
    pub rotation: DMat3,
    pub translation: DVec3,
}

impl Similarity {
    pub fn identity() -> Self {
        Similarity {
            scale: 1.0,
            rotation: DMat3::IDENTITY,
            translation: DVec3::ZERO,
        }
    }
    pub fn apply(&self, x: DVec3) -> DVec3 {
        self.scale * (self.rotation * x) + self.translation
    }
    /// A model-frame camera moved into the scan's frame: with `x_cam = R x_model + t` and
    /// `x_model = Rs^T (x_scan - ts) / s`, the camera frame scaled by `s` (the same rays, so the
    /// same intrinsics) gives `R' = R Rs^T`, `t' = s t - R' ts`.
    pub fn camera(&self, cam: &Camera) -> Camera {
        let r = cam.pose.r * self.rotation.transpose();
        let t = self.scale * cam.pose.t - r * self.translation;
        Camera {
            pose: WorldToCamera { r, t },
            ..cam.clone()
        }
    }
}

/// One control point's numbers after the fit.
#[derive(Clone, Debug, Serialize)]
pub struct PointResidual {
    pub name: String,
    /// Images it was triangulated from.
    pub views: usize,
    pub surveyed: [f64; 3],
    /// Triangulated, in the model's frame.
    pub model: [f64; 3],
    /// Triangulated and moved by the similarity (scan frame).
    pub aligned: [f64; 3],
    /// Metres: |aligned - surveyed|.
    pub residual_m: f64,
    /// Pixels: RMS over its observations of the surveyed point projected by the aligned
    /// cameras against the observed pixel (`None` when behind a camera).
    pub reprojection_px: Option<f64>,
    /// Whether it was within the bound and used in the final fit.
    pub inlier: bool,
}

/// The fitted similarity and every control point's residuals.
#[derive(Clone, Debug)]
pub struct Alignment {
    pub similarity: Similarity,
    /// Metres: the RMS distance of the surveyed points from their centroid.
    pub spread_m: f64,
    /// Metres: the inlier threshold and largest accepted RMS residual.
    pub max_residual_m: f64,
    /// Metres: RMS residual of the inliers.
    pub rms_m: f64,
    pub points: Vec<PointResidual>,
}

/// One control point with its observations resolved to cameras.
pub(crate) struct Group<'a> {
    pub(crate) name: String,
    pub(crate) world: DVec3,
    pub(crate) views: Vec<(&'a Camera, [f64; 2])>,
    /// The image of each view.
    pub(crate) images: Vec<String>,
}

/// The observations grouped by point (file order), each image found and each pixel checked.
fn group<'a>(
    path: &Path,
    obs: &[ControlObservation],
    cameras: &'a HashMap<String, Camera>,
) -> Result<Vec<Group<'a>>, ImportError> {
    let mut groups: Vec<Group> = Vec::new();
    for o in obs {
        let cam = cameras.get(&o.image).ok_or_else(|| {
            ImportError::control(
                path,
                format!("row `{o}`: image `{}` is not in the model", o.image),
            )
        })?;
        if !cam.in_frame(glam::DVec2::from_array(o.pixel)) {
            let (w, h) = (cam.width, cam.height);
            return Err(ImportError::control(
                path,
                format!("row `{o}`: pixel {:?} is outside the {w} x {h} image (centre of the top-left pixel at 0, 0)", o.pixel),
            ));
        }
        match groups.iter_mut().find(|g| g.name == o.name) {
            Some(g) => {
                g.views.push((cam, o.pixel));
                g.images.push(o.image.clone());
            }
            None => groups.push(Group {
                name: o.name.clone(),
                world: DVec3::from_array(o.world),
                views: vec![(cam, o.pixel)],
                images: vec![o.image.clone()],
            }),
        }
    }
    Ok(groups)
}

/// The point nearest, in least squares, to the rays of its views; `None` when the rays are
/// (near) parallel.
pub fn triangulate(views: &[(&Camera, [f64; 2])]) -> Option<DVec3> {
    let mut a = Matrix3::<f64>::zeros();
    let mut b = Vector3::<f64>::zeros();
    for (cam, [u, v]) in views {
        let (c, d) = cam.pixel_ray(*u, *v);
        let d = Vector3::new(d.x, d.y, d.z);
        let p = Matrix3::identity() - d * d.transpose();
        a += p;
        b += p * Vector3::new(c.x, c.y, c.z);
    }
    let eig = SymmetricEigen::new(a);
    let (lo, hi) = eig
        .eigenvalues
        .iter()
        .fold((f64::MAX, 0.0f64), |(l, h), &e| (l.min(e), h.max(e)));
    if !(lo > 1e-10 * hi) {
        return None;
    }
    let x = a.try_inverse()? * b;
    Some(DVec3::new(x.x, x.y, x.z))
}

fn to_na(v: DVec3) -> Vector3<f64> {
    Vector3::new(v.x, v.y, v.z)
}

/// Singular values (descending) of the centred points, and their centroid.
fn centred_singular(points: &[DVec3]) -> ([f64; 3], DVec3) {
    let mean = points.iter().copied().sum::<DVec3>() / points.len() as f64;
    let mut cov = Matrix3::<f64>::zeros();
    for p in points {
        let d = to_na(*p - mean);
        cov += d * d.transpose();
    }
    let mut s: Vec<f64> = SymmetricEigen::new(cov)
        .eigenvalues
        .iter()
        .map(|e| e.max(0.0).sqrt())
        .collect();
    s.sort_by(|a, b| b.total_cmp(a));
    ([s[0], s[1], s[2]], mean)
}

/// Umeyama's least-squares similarity taking `src` onto `dst`; `None` for colinear points.
pub fn umeyama(src: &[DVec3], dst: &[DVec3]) -> Option<Similarity> {
    let ([s0, s1, _], mx) = centred_singular(src);
    if !(s1 > COLINEAR_RATIO * s0) {
        return None;
    }
    let my = dst.iter().copied().sum::<DVec3>() / dst.len() as f64;
    let n = src.len() as f64;
    let mut sigma = Matrix3::<f64>::zeros();
    let mut var = 0.0;
    for (x, y) in src.iter().zip(dst) {
        sigma += to_na(*y - my) * to_na(*x - mx).transpose();
        var += (*x - mx).length_squared();
    }
    let (sigma, var) = (sigma / n, var / n);
    let svd = sigma.svd(true, true);
    let (u, vt) = (svd.u?, svd.v_t?);
    let sign = if (u.determinant() * vt.determinant()) < 0.0 {
        -1.0
    } else {
        1.0
    };
    let d = Matrix3::from_diagonal(&Vector3::new(1.0, 1.0, sign));
    let r = u * d * vt;
    let scale =
        (svd.singular_values[0] + svd.singular_values[1] + sign * svd.singular_values[2]) / var;
    let rotation = DMat3::from_cols_array(&[
        r[(0, 0)],
        r[(1, 0)],
        r[(2, 0)],
        r[(0, 1)],
        r[(1, 1)],
        r[(2, 1)],
        r[(0, 2)],
        r[(1, 2)],
        r[(2, 2)],
    ]);
    let translation = my - scale * (rotation * mx);
    (scale > 0.0 && scale.is_finite()).then_some(Similarity {
        scale,
        rotation,
        translation,
    })
}

/// The triples RANSAC tries: all of them when few, else a seeded pseudo-random draw.
fn triples(n: usize) -> Vec<[usize; 3]> {
    let all = n * (n - 1) * (n - 2) / 6;
    if all <= RANSAC_TRIALS {
        let mut out = Vec::with_capacity(all);
        for i in 0..n {
            for j in i + 1..n {
                out.extend((j + 1..n).map(|k| [i, j, k]));
            }
        }
        return out;
    }
    let mut state: u64 = 0x9E37_79B9_7F4A_7C15;
    let mut next = move || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) % n as u64) as usize
    };
    (0..RANSAC_TRIALS)
        .filter_map(|_| {
            let t = [next(), next(), next()];
            (t[0] != t[1] && t[1] != t[2] && t[0] != t[2]).then_some(t)
        })
        .collect()
}

/// The inliers of the best similarity of any triple (most inliers, then least summed
/// residual), or `None` when no triple fits.
fn ransac(model: &[DVec3], world: &[DVec3], bound: f64) -> Option<Vec<bool>> {
    let mut best: Option<(usize, f64, Vec<bool>)> = None;
    for t in triples(model.len()) {
        let Some(sim) = umeyama(&t.map(|i| model[i]), &t.map(|i| world[i])) else {
            continue;
        };
        let r: Vec<f64> = model
            .iter()
            .zip(world)
            .map(|(m, w)| sim.apply(*m).distance(*w))
            .collect();
        let inl: Vec<bool> = r.iter().map(|&e| e <= bound).collect();
        let count = inl.iter().filter(|&&b| b).count();
        let cost: f64 = r.iter().map(|e| e.min(bound)).sum();
        if best
            .as_ref()
            .is_none_or(|b| count > b.0 || (count == b.0 && cost < b.1))
        {
            best = Some((count, cost, inl));
        }
    }
    best.map(|b| b.2)
}

/// Aligns the model to the scan by the control points of `path` (`cameras`: the model's contract
/// cameras by image name, in the model's frame).
pub fn align(
    path: &Path,
    obs: &[ControlObservation],
    cameras: &HashMap<String, Camera>,
    opts: AlignOptions,
) -> Result<Alignment, ImportError> {
    if let Some(m) = opts.max_residual.filter(|m| !(*m > 0.0 && m.is_finite())) {
        return Err(ImportError::control(
            path,
            format!("--max-residual {m} m is not a positive distance"),
        ));
    }
    let groups = group(path, obs, cameras)?;
    let model = triangulate_all(path, &groups)?;
    let world: Vec<DVec3> = groups.iter().map(|g| g.world).collect();
    if groups.len() < 3 {
        return Err(ImportError::control(path, format!("{} usable control points; at least 3 are needed to fix scale, rotation and translation", groups.len())));
    }
    let ([s0, s1, _], mean) = centred_singular(&world);
    if !(s1 > COLINEAR_RATIO * s0) {
        return Err(ImportError::control(path, format!("the control points lie near a line (singular values {s0:.3e}, {s1:.3e} of their centred positions: ratio below {COLINEAR_RATIO}); a rotation about it cannot be fixed")));
    }
    let spread =
        (world.iter().map(|w| w.distance_squared(mean)).sum::<f64>() / world.len() as f64).sqrt();
    let bound = opts
        .max_residual
        .unwrap_or(DEFAULT_RESIDUAL_FRACTION * spread);
    let inliers = ransac(&model, &world, bound)
        .ok_or_else(|| ImportError::control(path, "no three control points fix a similarity"))?;
    let fit = refit(path, &model, &world, &inliers)?;
    let points = residuals(&groups, &model, &fit, &inliers);
    finish(path, fit, spread, bound, points)
}

/// Each group's triangulated point; a point seen once, or whose rays are parallel, is refused.
/// Each group's point triangulated from its views, which must be two or more, not (near)
/// parallel, and meet in front of every camera that sees the point.
pub(crate) fn triangulate_all(path: &Path, groups: &[Group]) -> Result<Vec<DVec3>, ImportError> {
    groups
        .iter()
        .map(|g| {
            if g.views.len() < 2 {
                return Err(ImportError::control(path, format!("point `{}` is seen in only one image; a point needs two views to be triangulated", g.name)));
            }
            let x = triangulate(&g.views).ok_or_else(|| ImportError::control(path, format!("point `{}`: its rays are (near) parallel and do not fix a position", g.name)))?;
            in_front(path, g, x)?;
            Ok(x)
        })
        .collect()
}

/// Refuses a triangulated point `x` that lies behind a camera of its group: its rows do not
/// observe one point (a mislabelled point or image).
fn in_front(path: &Path, g: &Group, x: DVec3) -> Result<(), ImportError> {
    for ((cam, _), image) in g.views.iter().zip(&g.images) {
        if !(cam.pose.apply(x).z > 0.0) {
            return Err(ImportError::control(path, format!("point `{}` triangulates behind the camera of image `{image}`: its rows do not observe one point (a mislabelled point or image?)", g.name)));
        }
    }
    Ok(())
}

fn refit(
    path: &Path,
    model: &[DVec3],
    world: &[DVec3],
    inl: &[bool],
) -> Result<Similarity, ImportError> {
    let pick = |v: &[DVec3]| -> Vec<DVec3> {
        v.iter()
            .zip(inl)
            .filter(|(_, &b)| b)
            .map(|(p, _)| *p)
            .collect()
    };
    let (m, w) = (pick(model), pick(world));
    if m.len() < 3 {
        return Err(ImportError::control(path, format!("only {} control points agree on a similarity; at least 3 are needed (see --max-residual)", m.len())));
    }
    umeyama(&m, &w)
        .ok_or_else(|| ImportError::control(path, "the agreeing control points lie near a line"))
}

fn residuals(
    groups: &[Group],
    model: &[DVec3],
    fit: &Similarity,
    inl: &[bool],
) -> Vec<PointResidual> {
    groups
        .iter()
        .zip(model)
        .zip(inl)
        .map(|((g, m), &inlier)| {
            let aligned = fit.apply(*m);
            let d2: Option<Vec<f64>> = g
                .views
                .iter()
                .map(|(cam, px)| {
                    Some(
                        fit.camera(cam)
                            .project(g.world)?
                            .distance_squared(glam::DVec2::from_array(*px)),
                    )
                })
                .collect();
            PointResidual {
                name: g.name.clone(),
                views: g.views.len(),
                surveyed: g.world.to_array(),
                model: m.to_array(),
                aligned: aligned.to_array(),
                residual_m: aligned.distance(g.world),
                reprojection_px: d2.map(|d| (d.iter().sum::<f64>() / d.len() as f64).sqrt()),
                inlier,
            }
        })
        .collect()
}

fn finish(
    path: &Path,
    fit: Similarity,
    spread: f64,
    bound: f64,
    points: Vec<PointResidual>,
) -> Result<Alignment, ImportError> {
    let inl: Vec<f64> = points
        .iter()
        .filter(|p| p.inlier)
        .map(|p| p.residual_m)
        .collect();
    let rms = (inl.iter().map(|r| r * r).sum::<f64>() / inl.len() as f64).sqrt();
    if !(rms <= bound) {
        return Err(ImportError::control(path, format!("RMS residual {rms:.4} m of the agreeing control points is above the bound {bound:.4} m (--max-residual; default 5 % of the points' spread {spread:.4} m)")));
    }
    Ok(Alignment {
        similarity: fit,
        spread_m: spread,
        max_residual_m: bound,
        rms_m: rms,
        points,
    })
}
