//! The survey's photographs as the page overlays them from their capture cameras
//! (`igi view --survey`): each photo's pinhole camera for the page (its K, R and t in the
//! contract's convention; docs/VIEW.md gives the page's conversion) and its picture, an 8-bit
//! sRGB PNG made when the page asks for it.
//!
//! The picture is the photograph as the solve reads it (`igi_workflow`'s
//! [`PhotoSpec::load_image`](igi_workflow::survey::PhotoSpec::load_image): made linear, its
//! camera radiometry applied, divided by its exposure), freed of lens distortion onto the same
//! K (`igi_camera::camera::undistort_image`; the page's camera is a pinhole), at the exposure that puts
//! its median luminance at 0.18 (`igi_imaging::auto_exposure`); invalid pixels (clipped, or
//! outside the photograph once undistorted) are black.

use crate::ViewError;
use igi_workflow::survey::{PhotoSpec, Survey};
use std::path::Path;
use std::sync::Mutex;

/// The photographs of a survey, their cameras checked.
pub struct PagePhotos {
    specs: Vec<PhotoSpec>,
    cameras: Vec<igi_camera::Camera>,
    /// Whether the survey's `[site]` gives a latitude and longitude.
    located: bool,
    /// The last picture made (its index and PNG bytes): a page asks for the photo it shows.
    last: Mutex<Option<(usize, Vec<u8>)>>,
}

impl PagePhotos {
    /// Read the survey (`survey.toml` or its folder) and every photo's camera.
    pub fn open(survey: &Path) -> Result<PagePhotos, ViewError> {
        let s = Survey::load(survey).map_err(|e| ViewError::Survey(Box::new(e)))?;
        let cameras = s
            .photos
            .iter()
            .map(|p| igi_camera::Camera::load(&p.camera))
            .collect::<Result<Vec<_>, _>>()
            .map_err(|e| ViewError::Survey(Box::new(e.into())))?;
        Ok(PagePhotos {
            located: s.site.location().is_some(),
            specs: s.photos,
            cameras,
            last: Mutex::new(None),
        })
    }

    /// Whether the survey's `[site]` gives a latitude and longitude (for the sky of a time).
    pub fn has_location(&self) -> bool {
        self.located
    }

    /// What the page gets in `scene.json`: per photo its [`camera_json`] and the address of
    /// its picture (`url`).
    pub fn json(&self) -> serde_json::Value {
        let list: Vec<_> = self
            .specs
            .iter()
            .zip(&self.cameras)
            .enumerate()
            .map(|(k, (p, c))| {
                let mut v = camera_json(&p.id, c);
                v["url"] = format!("/igi/photo/{k}.png").into();
                v
            })
            .collect();
        serde_json::Value::Array(list)
    }

    /// Photo `k`'s picture (PNG bytes); `None` when there is no photo `k`.
    pub fn png(&self, k: usize) -> Option<Result<Vec<u8>, String>> {
        let spec = self.specs.get(k)?;
        let mut last = self.last.lock().unwrap_or_else(|e| e.into_inner());
        if let Some((j, png)) = last.as_ref() {
            if *j == k {
                return Some(Ok(png.clone()));
            }
        }
        let made = picture(spec);
        if let Ok(png) = &made {
            *last = Some((k, png.clone()));
        }
        Some(made)
    }
}

/// A camera as the page looks through it: its name (`id`), size, pinhole K (`fx, fy, cx, cy`,
/// pixel centres at integers), `R` (rows) and `t` (world to camera, OpenCV's axes).
pub fn camera_json(id: &str, c: &igi_camera::Camera) -> serde_json::Value {
    let i = &c.intrinsics;
    let r = c.pose.r.transpose(); // glam is column-major: rows of R
    serde_json::json!({
        "id": id,
        "width": c.width,
        "height": c.height,
        "K": [i.fx, i.fy, i.cx, i.cy],
        "R": [r.x_axis.to_array(), r.y_axis.to_array(), r.z_axis.to_array()],
        "t": c.pose.t.to_array(),
    })
}

/// The cameras of `igi view --camera` (camera files), named by their file stems, for the page
/// to look through (no picture).
pub fn cameras_json(files: &[std::path::PathBuf]) -> Result<serde_json::Value, ViewError> {
    let mut list = Vec::new();
    for f in files {
        let c = igi_camera::Camera::load(f)?;
        let id = f
            .file_stem()
            .map_or_else(String::new, |s| s.to_string_lossy().into_owned());
        list.push(camera_json(&id, &c));
    }
    Ok(serde_json::Value::Array(list))
}

/// The PNG of one photograph (the module's overview says how it is made).
fn picture(spec: &PhotoSpec) -> Result<Vec<u8>, String> {
    let (image, camera) = spec.load_image().map_err(|e| e.to_string())?;
    let mut image = if camera.intrinsics.dist.is_zero() {
        image
    } else {
        igi_camera::camera::undistort_image(&image, &camera)
            .map_err(|e| format!("{}: {e}", spec.image.display()))?
            .0
    };
    let exposure = igi_imaging::auto_exposure(&image);
    for (p, v) in image.pixels.iter_mut().zip(&image.valid) {
        if !*v {
            *p = [0.0; 3];
        }
    }
    igi_imaging::png_tonemapped(&spec.image, &image, exposure).map_err(|e| e.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn fixture() -> std::path::PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../datasets/fixtures/survey")
    }

    /// The page gets each photo's camera as its file holds it, and its picture is the
    /// photograph at the exposure that puts its median luminance at 0.18.
    #[test]
    fn the_survey_photos_come_with_their_cameras_and_pictures() {
        let photos = PagePhotos::open(&fixture()).unwrap();
        let json = photos.json();
        let list = json.as_array().unwrap();
        assert_eq!(list.len(), photos.specs.len());
        let cam = igi_camera::Camera::load(&fixture().join("cameras/v01-lowsun.json")).unwrap();
        let p = &list[1];
        assert_eq!(p["id"], "v01-lowsun");
        assert_eq!(p["url"], "/igi/photo/1.png");
        for (row, want) in p["R"].as_array().unwrap().iter().zip(0..3) {
            for c in 0..3 {
                let r = cam.pose.r.col(c)[want]; // R[want][c]
                assert_eq!(row[c].as_f64().unwrap(), r);
            }
        }
        assert_eq!(p["K"][2].as_f64().unwrap(), cam.intrinsics.cx);
        assert_eq!(p["t"][1].as_f64().unwrap(), cam.pose.t.y);

        let png = photos.png(1).unwrap().unwrap();
        let got = image::load_from_memory(&png).unwrap().to_rgb8();
        assert_eq!(got.dimensions(), (cam.width, cam.height));
        let img = igi_imaging::read_image(&fixture().join("photos/v01-lowsun.exr")).unwrap();
        let e = igi_imaging::auto_exposure(&img);
        assert!(e.is_finite() && e > 0.0);
        let (x, y) = (80, 60);
        let want = img.pixels[y * img.width + x]
            .map(|c| (igi_imaging::io::linear_to_srgb(c * e) * 255.0 + 0.5) as u8);
        assert_eq!(got.get_pixel(x as u32, y as u32).0, want);
        // asked again, the same bytes (kept); no photo 99
        assert_eq!(photos.png(1).unwrap().unwrap(), png);
        assert!(photos.png(99).is_none());
    }
}
