//! Importer for the Middlebury multi-view stereo sets (Seitz et al. 2006; `dinoSparseRing`,
//! `templeSparseRing`, ...) into a `rig.toml` folder.
//!
//! * `*_par.txt`: a count line, then one line per image `name k11..k33 r11..r33 t1 t2 t3`
//!   with `P = K [R | t]`, the OpenCV convention. The published rotations are off by about
//!   1e-6 from orthonormal, which the camera loader's 1e-6 check refuses; the importer projects
//!   each R to the nearest rotation (SVD, `U V^T`) and refuses an R more than 1e-3 away.
//! * World frame: the sets are not Z up. The importer takes the mean image-up direction of the
//!   cameras (`-y` of each camera in the world), picks the signed world axis nearest to it as
//!   +Z, and rotates the world by that signed axis permutation (so the README's box stays a box).
//! * Bounding box: the two `(x y z)` lines after "bounding box" in `README.txt`.
//! * Masks: the README's recipe on the images listed in `*_good_silhouette_images.txt`:
//!   threshold at 0.19 (largest channel, values in [0, 1]), dilate by 10 pixels, erode by 7.
//!   Only those views are imported.
//!
//! The output folder gets `rig.toml`, `cameras/`, `photos/` (copies) and `masks/`; it is
//! assembled in a temporary sibling folder and renamed into place, so a failure leaves nothing.

use crate::HullError;
use glam::{DMat3, DVec3};
use igi_camera::rig::{Rig, RigObject, RigView};
use igi_camera::{Camera, Intrinsics, WorldToCamera};
use igi_imaging::{read_image, Mask};
use std::path::{Path, PathBuf};

/// The largest distance (max entry of `R - nearest rotation`) the importer corrects.
pub const MAX_ROTATION_ERROR: f64 = 1e-3;

/// One parsed `_par.txt` line.
#[derive(Clone, Debug, PartialEq)]
pub struct ParEntry {
    pub image: String,
    pub k: [[f64; 3]; 3],
    pub r: DMat3,
    pub t: DVec3,
    /// Max entry of `|R_file - R|` removed by the projection.
    pub correction: f64,
}

/// What the import did.
#[derive(Clone, Debug, serde::Serialize)]
pub struct ImportReport {
    pub views: usize,
    pub skipped: Vec<String>,
    /// Largest rotation correction over the views.
    pub max_rotation_correction: f64,
    /// The Middlebury axis that became +Z, e.g. "-y".
    pub up_axis: String,
    pub bbox_min: [f64; 3],
    pub bbox_max: [f64; 3],
    /// Views whose mask touches the frame (the object leaves the picture).
    pub masks_touching_frame: Vec<String>,
}

/// Nearest rotation to `m` (`igi_camera::planar::nearest_rotation`) and the largest entry of
/// their difference.
pub fn nearest_rotation(m: &DMat3) -> (DMat3, f64) {
    let out = igi_camera::planar::nearest_rotation(m);
    let dist = (out - *m)
        .to_cols_array()
        .iter()
        .fold(0.0f64, |a, x| a.max(x.abs()));
    (out, dist)
}

/// Parse a `_par.txt` file, projecting every R to the nearest rotation.
pub fn parse_par(path: &Path) -> Result<Vec<ParEntry>, HullError> {
    let text = std::fs::read_to_string(path).map_err(|e| HullError::io(path, e))?;
    let bad = |line: usize, msg: String| HullError::ParLine {
        path: path.to_path_buf(),
        line,
        msg,
    };
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let (_, first) = lines.next().ok_or_else(|| bad(1, "empty file".into()))?;
    let count: usize = first.trim().parse().map_err(|_| {
        bad(
            1,
            format!("first line must be the image count, found {first:?}"),
        )
    })?;
    let mut out = Vec::new();
    for (i, l) in lines {
        out.push(parse_par_line(path, i + 1, l)?);
    }
    if out.len() != count {
        return Err(bad(
            1,
            format!(
                "the count line says {count} images but {} lines follow",
                out.len()
            ),
        ));
    }
    Ok(out)
}

/// One camera line `name k11 .. k33 r11 .. r33 t1 t2 t3` (line `n`), R projected to the
/// nearest rotation.
fn parse_par_line(path: &Path, n: usize, l: &str) -> Result<ParEntry, HullError> {
    let bad = |line: usize, msg: String| HullError::ParLine {
        path: path.to_path_buf(),
        line,
        msg,
    };
    let toks: Vec<&str> = l.split_whitespace().collect();
    if toks.len() != 22 {
        return Err(bad(
            n,
            format!(
                "expected an image name and 21 numbers (K, R, t), found {} fields",
                toks.len()
            ),
        ));
    }
    let v: Vec<f64> = toks[1..]
        .iter()
        .map(|t| {
            t.parse::<f64>()
                .ok()
                .filter(|x| x.is_finite())
                .ok_or_else(|| bad(n, format!("{t:?} is not a finite number")))
        })
        .collect::<Result<_, _>>()?;
    let k = [[v[0], v[1], v[2]], [v[3], v[4], v[5]], [v[6], v[7], v[8]]];
    if k[0][1] != 0.0
        || k[1][0] != 0.0
        || k[2] != [0.0, 0.0, 1.0]
        || !(k[0][0] > 0.0 && k[1][1] > 0.0)
    {
        return Err(bad(n, format!("K must be [[fx, 0, cx], [0, fy, cy], [0, 0, 1]] with positive focal lengths, found {k:?}")));
    }
    let r_file = DMat3::from_cols_array_2d(&[
        [v[9], v[10], v[11]],
        [v[12], v[13], v[14]],
        [v[15], v[16], v[17]],
    ])
    .transpose();
    let (r, correction) = nearest_rotation(&r_file);
    if correction > MAX_ROTATION_ERROR {
        return Err(HullError::NotRotation {
            path: path.to_path_buf(),
            line: n,
            image: toks[0].into(),
            distance: correction,
            limit: MAX_ROTATION_ERROR,
        });
    }
    Ok(ParEntry {
        image: toks[0].to_string(),
        k,
        r,
        t: DVec3::new(v[18], v[19], v[20]),
        correction,
    })
}

/// The two `(x y z)` corners after "bounding box" in a Middlebury README.
pub fn parse_readme_bbox(path: &Path) -> Result<(DVec3, DVec3), HullError> {
    let text = std::fs::read_to_string(path).map_err(|e| HullError::io(path, e))?;
    let bad = |msg: &str| HullError::HullFolder {
        path: path.to_path_buf(),
        msg: msg.into(),
    };
    let lines: Vec<&str> = text.lines().collect();
    let at = lines
        .iter()
        .position(|l| l.to_ascii_lowercase().contains("bounding box"))
        .ok_or_else(|| bad("no \"bounding box\" line"))?;
    let corners: Vec<DVec3> = lines[at + 1..]
        .iter()
        .filter_map(|l| {
            let l = l.trim();
            let inner = l.strip_prefix('(')?.strip_suffix(')')?;
            let v: Vec<f64> = inner
                .split_whitespace()
                .filter_map(|t| t.parse().ok())
                .collect();
            (v.len() == 3).then(|| DVec3::new(v[0], v[1], v[2]))
        })
        .take(2)
        .collect();
    if corners.len() != 2 {
        return Err(bad("the bounding box needs two lines of the form (x y z)"));
    }
    Ok((corners[0].min(corners[1]), corners[0].max(corners[1])))
}

/// The README's silhouette recipe: threshold 0.19, dilate 10, erode 7.
pub fn recipe_mask(photo: &igi_imaging::HdrImage) -> Mask {
    Mask::threshold(photo, 0.19).dilate(10.0).erode(7.0)
}

/// The signed axis permutation taking the mean camera up direction to +Z, and its name.
pub fn z_up_rotation(entries: &[ParEntry]) -> (DMat3, String) {
    let up: DVec3 = entries.iter().map(|e| -e.r.row(1)).sum();
    let k = (0..3)
        .max_by(|&a, &b| up[a].abs().total_cmp(&up[b].abs()))
        .unwrap_or(2);
    let s = up[k].signum();
    let mut z = DVec3::ZERO;
    z[k] = s;
    let mut x = DVec3::ZERO;
    x[(k + 1) % 3] = 1.0;
    let y = z.cross(x);
    let name = format!("{}{}", if s < 0.0 { "-" } else { "+" }, ["x", "y", "z"][k]);
    (DMat3::from_cols(x, y, z).transpose(), name)
}

/// Import a Middlebury set folder into `out` (which must not exist, or be empty).
pub fn import(dir: &Path, out: &Path) -> Result<ImportReport, HullError> {
    let find = |suffix: &str| -> Result<PathBuf, HullError> {
        let rd = std::fs::read_dir(dir).map_err(|e| HullError::io(dir, e))?;
        let mut hits: Vec<PathBuf> = rd
            .filter_map(|e| e.ok().map(|e| e.path()))
            .filter(|p| p.to_string_lossy().ends_with(suffix))
            .collect();
        hits.sort();
        hits.into_iter().next().ok_or_else(|| {
            HullError::io(
                dir.join(format!("*{suffix}")),
                std::io::Error::new(std::io::ErrorKind::NotFound, "no such file in the set"),
            )
        })
    };
    let par_path = find("_par.txt")?;
    let entries = parse_par(&par_path)?;
    let (bmin, bmax) = parse_readme_bbox(&dir.join("README.txt"))?;
    let good_path = find("_good_silhouette_images.txt")?;
    let good_text =
        std::fs::read_to_string(&good_path).map_err(|e| HullError::io(&good_path, e))?;
    let good: Vec<&str> = good_text.split_whitespace().collect();
    let (m, up_axis) = z_up_rotation(&entries);
    let corners = (0..8).map(|c| {
        m * DVec3::new(
            [bmin.x, bmax.x][c & 1],
            [bmin.y, bmax.y][c >> 1 & 1],
            [bmin.z, bmax.z][c >> 2 & 1],
        )
    });
    let (lo, hi) = corners.fold((DVec3::MAX, DVec3::MIN), |(lo, hi), p| {
        (lo.min(p), hi.max(p))
    });
    let staged = prepare_views(dir, &entries, &good, m)?;
    if staged.is_empty() {
        return Err(HullError::HullFolder {
            path: good_path,
            msg: "lists none of the images of the _par file".into(),
        });
    }
    let report = ImportReport {
        views: staged.len(),
        skipped: entries
            .iter()
            .filter(|e| !good.contains(&e.image.as_str()))
            .map(|e| e.image.clone())
            .collect(),
        max_rotation_correction: entries.iter().map(|e| e.correction).fold(0.0, f64::max),
        up_axis,
        bbox_min: lo.to_array(),
        bbox_max: hi.to_array(),
        masks_touching_frame: staged
            .iter()
            .filter(|s| s.mask.frame_contact().touches())
            .map(|s| s.id.clone())
            .collect(),
    };
    write_rig_folder(
        out,
        &staged,
        RigObject {
            bbox_min: lo.to_array(),
            bbox_max: hi.to_array(),
        },
    )?;
    Ok(report)
}

struct Staged {
    id: String,
    source: PathBuf,
    camera: Camera,
    mask: Mask,
}

fn prepare_views(
    dir: &Path,
    entries: &[ParEntry],
    good: &[&str],
    m: DMat3,
) -> Result<Vec<Staged>, HullError> {
    let mut out = Vec::new();
    for e in entries.iter().filter(|e| good.contains(&e.image.as_str())) {
        let source = dir.join(&e.image);
        let photo = read_image(&source)?;
        let intrinsics = Intrinsics {
            fx: e.k[0][0],
            fy: e.k[1][1],
            cx: e.k[0][2],
            cy: e.k[1][2],
            dist: Default::default(),
        };
        // x_cam = R x_mb + t = (R M^T) x_zup + t
        let pose = WorldToCamera {
            r: e.r * m.transpose(),
            t: e.t,
        };
        let camera = Camera {
            width: photo.width as u32,
            height: photo.height as u32,
            intrinsics,
            pose,
        };
        let id = e.image.trim_end_matches(".png").to_string();
        out.push(Staged {
            id,
            source,
            camera,
            mask: recipe_mask(&photo),
        });
    }
    Ok(out)
}

fn write_rig_folder(out: &Path, staged: &[Staged], object: RigObject) -> Result<(), HullError> {
    crate::build::write_folder(out, |tmp| {
        for sub in ["cameras", "photos", "masks"] {
            std::fs::create_dir_all(tmp.join(sub)).map_err(|e| HullError::io(tmp.join(sub), e))?;
        }
        let mut views = Vec::new();
        for s in staged {
            let cam = tmp.join("cameras").join(format!("{}.json", s.id));
            s.camera.save(&cam)?;
            let photo = tmp.join("photos").join(format!("{}.png", s.id));
            std::fs::copy(&s.source, &photo).map_err(|e| HullError::io(&s.source, e))?;
            let mask = tmp.join("masks").join(format!("{}.png", s.id));
            s.mask.save_png(&mask)?;
            views.push(RigView {
                id: s.id.clone(),
                camera: cam,
                photo,
                mask: Some(mask),
                backdrops: vec![],
                lights: vec![],
            });
        }
        let rig = Rig {
            object,
            views,
            path: tmp.join("rig.toml"),
        };
        rig.save(&tmp.join("rig.toml"))?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn nearest_rotation_fixes_small_errors_and_measures_large_ones() {
        let r = DMat3::from_rotation_z(0.3) * DMat3::from_rotation_x(-1.1);
        let noisy =
            r + DMat3::from_cols_array(&[1e-6, -2e-6, 0.0, 0.0, 1e-6, 0.0, 3e-7, 0.0, -1e-6]);
        let (p, d) = nearest_rotation(&noisy);
        assert!(d < 3e-6 && d > 1e-7, "{d}");
        igi_camera::camera::check_rotation(&p).unwrap();
        assert!((p - r).to_cols_array().iter().all(|x| x.abs() < 3e-6));
        let (_, d) = nearest_rotation(&(r * 1.01));
        assert!(d > 1e-3);
    }
}
