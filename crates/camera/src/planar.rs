//! Pure-Rust planar geometry (no OpenCV): the homography between two point sets by the
//! normalised DLT, and the camera pose of a plane from four or more points (homography
//! decomposition, then Gauss-Newton on the reprojection error with the full distortion model).
//!
//! The plane is the world plane z = 0; points on it are given as (x, y).

use crate::{CameraError, Intrinsics, PlanarError, WorldToCamera};
use glam::{DMat3, DVec2, DVec3};
use nalgebra::{DMatrix, Matrix3, SVD};

/// Apply a homography to a point: `H (x, y, 1)` dehomogenised (`None` at infinity).
pub fn apply_homography(h: &DMat3, p: DVec2) -> Option<DVec2> {
    let q = *h * DVec3::new(p.x, p.y, 1.0);
    (q.z.abs() > 1e-300 && q.is_finite())
        .then(|| DVec2::new(q.x / q.z, q.y / q.z))
        .filter(|r| r.is_finite())
}

/// Hartley normalisation: a similarity taking the points to centroid 0, mean distance sqrt(2).
fn normaliser(p: &[DVec2]) -> Result<DMat3, CameraError> {
    let n = p.len() as f64;
    let c = p.iter().fold(DVec2::ZERO, |a, x| a + *x) / n;
    let d = p.iter().map(|x| (*x - c).length()).sum::<f64>() / n;
    if !(d > 0.0) || !d.is_finite() {
        return Err(PlanarError::Coincident.into());
    }
    let s = std::f64::consts::SQRT_2 / d;
    Ok(DMat3::from_cols(
        DVec3::new(s, 0.0, 0.0),
        DVec3::new(0.0, s, 0.0),
        DVec3::new(-s * c.x, -s * c.y, 1.0),
    ))
}

/// Largest |cross| / (|a| |b|)-style collinearity measure: the smallest triangle "sine" over
/// all triples, for a point set already normalised to unit scale.
fn min_triangle_area(p: &[DVec2]) -> f64 {
    let mut m = f64::INFINITY;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            for k in j + 1..p.len() {
                m = m.min((p[j] - p[i]).perp_dot(p[k] - p[i]).abs() * 0.5);
            }
        }
    }
    m
}

/// Homography `dst ~ H src` from n >= 4 correspondences (normalised DLT, least squares for
/// n > 4). Errors when the points are degenerate: with four points, three of them (nearly)
/// collinear in either set; in general a rank-deficient system.
pub fn homography_dlt(src: &[DVec2], dst: &[DVec2]) -> Result<DMat3, CameraError> {
    if src.len() != dst.len() || src.len() < 4 {
        return Err(PlanarError::HomographyPoints {
            src: src.len(),
            dst: dst.len(),
        }
        .into());
    }
    if src.iter().chain(dst).any(|p| !p.is_finite()) {
        return Err(PlanarError::NonFinitePoint.into());
    }
    let (ts, td) = (normaliser(src)?, normaliser(dst)?);
    let s: Vec<DVec2> = src.iter().map(|p| ts.transform_point2(*p)).collect();
    let d: Vec<DVec2> = dst.iter().map(|p| td.transform_point2(*p)).collect();
    if src.len() == 4 {
        // normalised coordinates have unit scale: a triangle of area < 1e-3 is a degenerate one
        let (a, b) = (min_triangle_area(&s), min_triangle_area(&d));
        if a.min(b) < 1e-3 {
            return Err(PlanarError::Collinear { area: a.min(b) }.into());
        }
    }
    let rows = (2 * src.len()).max(9);
    let mut a = DMatrix::<f64>::zeros(rows, 9);
    for (i, (p, q)) in s.iter().zip(&d).enumerate() {
        let (x, y, u, v) = (p.x, p.y, q.x, q.y);
        let r0 = [x, y, 1.0, 0.0, 0.0, 0.0, -u * x, -u * y, -u];
        let r1 = [0.0, 0.0, 0.0, x, y, 1.0, -v * x, -v * y, -v];
        for c in 0..9 {
            a[(2 * i, c)] = r0[c];
            a[(2 * i + 1, c)] = r1[c];
        }
    }
    let svd = SVD::new(a, false, true);
    let vt = svd.v_t.ok_or_else(|| CameraError::from(PlanarError::Svd))?;
    let sv = &svd.singular_values;
    let (imin, _) =
        sv.iter().enumerate().fold(
            (0, f64::INFINITY),
            |b, (i, x)| if *x < b.1 { (i, *x) } else { b },
        );
    let mut sorted: Vec<f64> = sv.iter().copied().collect();
    sorted.sort_by(|a, b| a.total_cmp(b));
    if !(sorted[1] > 1e-9 * sorted[8]) {
        return Err(PlanarError::RankDeficient.into());
    }
    let h = vt.row(imin);
    let hn =
        DMat3::from_cols_array_2d(&[[h[0], h[3], h[6]], [h[1], h[4], h[7]], [h[2], h[5], h[8]]]);
    let hm = td.inverse() * hn * ts;
    let scale = if hm.z_axis.z.abs() > 1e-12 {
        hm.z_axis.z
    } else {
        hm.to_cols_array()
            .iter()
            .fold(0.0f64, |m, x| m.max(x.abs()))
    };
    let out = hm * (1.0 / scale);
    if !out.is_finite() {
        return Err(PlanarError::NonFiniteHomography.into());
    }
    Ok(out)
}

/// Pose of a planar target from [`pose_from_plane`].
#[derive(Clone, Copy, Debug)]
pub struct PlanarPose {
    /// World (plane z = 0) to camera.
    pub pose: WorldToCamera,
    /// RMS reprojection error over the points, pixels (with distortion).
    pub rms_px: f64,
}

/// The nearest rotation (polar factor, det +1; nearest in the Frobenius norm) to a 3x3 matrix.
pub fn nearest_rotation(m: &DMat3) -> DMat3 {
    let a = m.to_cols_array();
    let mm = Matrix3::from_column_slice(&a);
    let svd = SVD::new(mm, true, true);
    let (u, vt) = (svd.u.unwrap(), svd.v_t.unwrap());
    let mut r = u * vt;
    if r.determinant() < 0.0 {
        let mut u2 = u;
        u2.column_mut(2).neg_mut();
        r = u2 * vt;
    }
    DMat3::from_cols_slice(r.as_slice())
}

fn residuals(
    intr: &Intrinsics,
    pose: &WorldToCamera,
    world: &[DVec3],
    px: &[DVec2],
) -> Option<Vec<f64>> {
    let mut r = Vec::with_capacity(2 * world.len());
    for (w, p) in world.iter().zip(px) {
        let c = pose.apply(*w);
        if !(c.z > 0.0) {
            return None;
        }
        let q = intr.to_pixel(DVec2::new(c.x / c.z, c.y / c.z)) - *p;
        r.push(q.x);
        r.push(q.y);
    }
    Some(r)
}

fn perturb(pose: &WorldToCamera, d: &[f64; 6]) -> WorldToCamera {
    let w = DVec3::new(d[0], d[1], d[2]);
    let th = w.length();
    let dr = if th > 0.0 {
        DMat3::from_axis_angle(w / th, th)
    } else {
        DMat3::IDENTITY
    };
    WorldToCamera {
        r: dr * pose.r,
        t: pose.t + DVec3::new(d[3], d[4], d[5]),
    }
}

/// Camera pose of the plane z = 0 from n >= 4 points `plane_xy` seen at `pixels` (distorted
/// pixel coordinates of a camera with intrinsics `intr`). The pixels are undistorted, the
/// plane-to-normalised-image homography is decomposed into `[r1 r2 t]` (rotation made
/// orthonormal by its polar factor, sign chosen so the points lie in front of the camera),
/// then refined by damped Gauss-Newton on the distorted reprojection error.
pub fn pose_from_plane(
    intr: &Intrinsics,
    plane_xy: &[DVec2],
    pixels: &[DVec2],
) -> Result<PlanarPose, CameraError> {
    if plane_xy.len() != pixels.len() || plane_xy.len() < 4 {
        return Err(PlanarError::PosePoints {
            plane: plane_xy.len(),
            pixels: pixels.len(),
        }
        .into());
    }
    let norm = undistort_all(intr, pixels)?;
    let pose = pose_from_homography(plane_xy, &norm)?;
    let world: Vec<DVec3> = plane_xy.iter().map(|p| DVec3::new(p.x, p.y, 0.0)).collect();
    let res = residuals(intr, &pose, &world, pixels)
        .ok_or_else(|| CameraError::from(PlanarError::Behind))?;
    let (mut pose, res) = refine_pose(intr, pose, res, &world, pixels);
    pose.r = nearest_rotation(&pose.r);
    let rms_px = (sum_of_squares(&res) / world.len() as f64).sqrt();
    if !rms_px.is_finite() || !pose.t.is_finite() {
        return Err(PlanarError::NonFinitePose.into());
    }
    Ok(PlanarPose { pose, rms_px })
}

/// Normalised image coordinates of distorted pixels.
fn undistort_all(intr: &Intrinsics, pixels: &[DVec2]) -> Result<Vec<DVec2>, CameraError> {
    let mut norm = Vec::with_capacity(pixels.len());
    for p in pixels {
        norm.push(
            intr.to_normalized(*p)
                .ok_or_else(|| CameraError::from(PlanarError::Undistort { x: p.x, y: p.y }))?,
        );
    }
    Ok(norm)
}

/// The plane-to-normalised-image homography decomposed into `[r1 r2 t]`, the rotation made
/// orthonormal and the sign chosen so the first point lies in front of the camera.
fn pose_from_homography(plane_xy: &[DVec2], norm: &[DVec2]) -> Result<WorldToCamera, CameraError> {
    let h = homography_dlt(plane_xy, norm)?;
    let (h1, h2, h3) = (h.x_axis, h.y_axis, h.z_axis);
    let mut lambda = 2.0 / (h1.length() + h2.length());
    // depth of the first point: third row of lambda * H applied to (x, y, 1)
    let p0 = plane_xy[0];
    if lambda * (h1.z * p0.x + h2.z * p0.y + h3.z) < 0.0 {
        lambda = -lambda;
    }
    let (r1, r2) = (h1 * lambda, h2 * lambda);
    let r = nearest_rotation(&DMat3::from_cols(r1, r2, r1.cross(r2)));
    Ok(WorldToCamera { r, t: h3 * lambda })
}

fn sum_of_squares(r: &[f64]) -> f64 {
    r.iter().map(|x| x * x).sum::<f64>()
}

/// Central-difference Jacobian of the residuals over the six pose parameters (rotation
/// vector, translation); a column whose perturbation puts a point behind the camera stops
/// the filling and stays zero, as do the columns after it.
fn residual_jacobian(
    intr: &Intrinsics,
    pose: &WorldToCamera,
    world: &[DVec3],
    pixels: &[DVec2],
    m: usize,
) -> DMatrix<f64> {
    let mut j = DMatrix::<f64>::zeros(m, 6);
    let scale = pose.t.length().max(1e-6);
    for k in 0..6 {
        let eps = if k < 3 { 1e-7 } else { 1e-7 * scale };
        let mut d = [0.0; 6];
        d[k] = eps;
        let rp = residuals(intr, &perturb(pose, &d), world, pixels);
        d[k] = -eps;
        let rm = residuals(intr, &perturb(pose, &d), world, pixels);
        let (Some(rp), Some(rm)) = (rp, rm) else {
            break;
        };
        for i in 0..m {
            j[(i, k)] = (rp[i] - rm[i]) / (2.0 * eps);
        }
    }
    j
}

/// Damped Gauss-Newton (Levenberg-Marquardt) on the distorted reprojection error, from `pose`
/// with residuals `res`; returns the refined pose and its residuals.
fn refine_pose(
    intr: &Intrinsics,
    mut pose: WorldToCamera,
    mut res: Vec<f64>,
    world: &[DVec3],
    pixels: &[DVec2],
) -> (WorldToCamera, Vec<f64>) {
    let mut mu = 1e-3;
    for _ in 0..50 {
        let c0 = sum_of_squares(&res);
        let j = residual_jacobian(intr, &pose, world, pixels, res.len());
        let jt = j.transpose();
        let jtj = &jt * &j;
        let g = &jt * nalgebra::DVector::from_vec(res.clone());
        let mut improved = false;
        for _ in 0..10 {
            let mut a = jtj.clone();
            for k in 0..6 {
                a[(k, k)] += mu * (jtj[(k, k)] + 1e-12);
            }
            let Some(step) = a.lu().solve(&(-&g)) else {
                break;
            };
            let d = [step[0], step[1], step[2], step[3], step[4], step[5]];
            let cand = perturb(&pose, &d);
            if let Some(rn) = residuals(intr, &cand, world, pixels) {
                if sum_of_squares(&rn) < c0 {
                    pose = cand;
                    res = rn;
                    mu = (mu * 0.3).max(1e-12);
                    improved = true;
                    break;
                }
            }
            mu *= 10.0;
        }
        if !improved || c0 - sum_of_squares(&res) < 1e-14 * c0.max(1e-30) {
            break;
        }
    }
    (pose, res)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{cv::rotation_angle_between, Camera, Distortion};

    fn cam() -> Camera {
        let mut c = Camera::pinhole(1200, 900, 1100.0, 1095.0, 610.0, 445.0);
        c.intrinsics.dist = Distortion {
            k1: -0.12,
            k2: 0.05,
            p1: 0.001,
            p2: -0.0007,
            k3: 0.0,
        };
        c.pose = WorldToCamera::look_at(
            DVec3::new(0.15, -0.3, 0.4),
            DVec3::new(0.01, 0.02, 0.0),
            DVec3::Z,
        )
        .unwrap();
        c
    }

    #[test]
    fn homography_of_four_points_is_exact() {
        let h =
            DMat3::from_cols_array_2d(&[[1.2, 0.1, 0.001], [-0.2, 0.9, 0.002], [30.0, 40.0, 1.0]]);
        let src = [
            DVec2::new(0.0, 0.0),
            DVec2::new(100.0, 5.0),
            DVec2::new(90.0, 80.0),
            DVec2::new(-10.0, 70.0),
        ];
        let dst: Vec<DVec2> = src
            .iter()
            .map(|p| apply_homography(&h, *p).unwrap())
            .collect();
        let e = homography_dlt(&src, &dst).unwrap();
        for p in [DVec2::new(50.0, 50.0), DVec2::new(-30.0, 120.0)] {
            let d = apply_homography(&e, p).unwrap() - apply_homography(&h, p).unwrap();
            assert!(d.length() < 1e-8, "{d}");
        }
    }

    #[test]
    fn homography_rejects_collinear_points() {
        let src = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(2.0, 2.0),
            DVec2::new(0.0, 1.0),
        ];
        let dst = [
            DVec2::new(0.0, 0.0),
            DVec2::new(1.0, 0.0),
            DVec2::new(1.0, 1.0),
            DVec2::new(0.0, 1.0),
        ];
        let e = homography_dlt(&src, &dst).unwrap_err().to_string();
        assert!(e.contains("collinear"), "{e}");
    }

    #[test]
    fn pose_from_four_plane_points_with_distortion() {
        let c = cam();
        let plane = [
            DVec2::new(-0.12, -0.1),
            DVec2::new(0.13, -0.09),
            DVec2::new(0.12, 0.1),
            DVec2::new(-0.11, 0.11),
        ];
        let px: Vec<DVec2> = plane
            .iter()
            .map(|p| c.project(DVec3::new(p.x, p.y, 0.0)).unwrap())
            .collect();
        let p = pose_from_plane(&c.intrinsics, &plane, &px).unwrap();
        let ang = rotation_angle_between(&p.pose.r, &c.pose.r).to_degrees();
        let dc = (p.pose.inverse().t - c.center_world()).length();
        assert!(
            ang < 1e-6 && dc < 1e-8 && p.rms_px < 1e-6,
            "angle {ang} deg, centre {dc} m, rms {}",
            p.rms_px
        );
        // 0.5 px noise on the four points: still within 0.5 degrees and 3 mm
        let noisy: Vec<DVec2> = px
            .iter()
            .zip([0.5, -0.4, 0.3, -0.5])
            .map(|(q, n)| *q + DVec2::new(n, -n * 0.7))
            .collect();
        let p = pose_from_plane(&c.intrinsics, &plane, &noisy).unwrap();
        let ang = rotation_angle_between(&p.pose.r, &c.pose.r).to_degrees();
        let dc = (p.pose.inverse().t - c.center_world()).length();
        assert!(
            ang < 0.5 && dc < 3e-3,
            "noisy: angle {ang} deg, centre {dc} m"
        );
    }
}
