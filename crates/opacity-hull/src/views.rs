//! Loading a rig's views: camera, photo, matte and the silhouette used for carving.
//!
//! A view's matte comes from its matting captures when it has them (Eq. 2, maximum over
//! lambda), otherwise from its mask (opacity 0 or 1). The silhouette for carving is
//! `alpha > threshold` (0.05 in the paper); pixels whose matte is invalid are **unknown**, as
//! are all pixels outside the frame: neither carves.

use crate::backdrop::{alpha_from_pair, Matte};
use crate::HullError;
use igi_imaging::rig::{Rig, RigView};
use igi_imaging::{read_image, Camera, HdrImage, Mask};

/// Matting options.
#[derive(Clone, Copy, Debug)]
pub struct MatteOptions {
    /// Silhouette threshold on alpha (the paper: 0.05).
    pub alpha_threshold: f32,
    /// Smallest backdrop-pair difference that carries signal (see [`alpha_from_pair`]).
    pub min_signal: f32,
}

impl Default for MatteOptions {
    fn default() -> Self {
        MatteOptions {
            alpha_threshold: 0.05,
            min_signal: 0.02,
        }
    }
}

/// One loaded view.
#[derive(Clone, Debug)]
pub struct View {
    pub id: String,
    pub camera: Camera,
    pub photo: HdrImage,
    pub matte: Matte,
    /// `alpha > threshold` where the matte is valid.
    pub silhouette: Mask,
    /// Pixels whose matte is valid (inside the frame by construction).
    pub known: Mask,
}

impl View {
    /// True when pixel (x, y) is known background (carves).
    #[inline]
    pub fn is_background(&self, x: usize, y: usize) -> bool {
        let i = y * self.silhouette.width + x;
        self.known.data[i] && !self.silhouette.data[i]
    }
}

/// Load every view of the rig (at least two), checking image sizes against cameras and that
/// no silhouette is empty or fills the whole frame. Errors name the rig file and the view.
pub fn load_views(rig: &Rig, opts: MatteOptions) -> Result<Vec<View>, HullError> {
    rig.require_views(2)?;
    rig.views.iter().map(|v| load_view(rig, v, opts)).collect()
}

/// Load one view (see [`load_views`]).
pub fn load_view(rig: &Rig, v: &RigView, opts: MatteOptions) -> Result<View, HullError> {
    let camera = rig.load_camera(v)?;
    let (w, h) = (camera.width as usize, camera.height as usize);
    let read = |p: &std::path::Path| -> Result<HdrImage, HullError> {
        let img = read_image(p).map_err(|e| rig.view_error(v, e))?;
        if (img.width, img.height) != (w, h) {
            return Err(rig
                .view_message(
                    v,
                    format!(
                        "{} is {}x{} but the view's camera is {w}x{h}",
                        p.display(),
                        img.width,
                        img.height
                    ),
                )
                .into());
        }
        Ok(img)
    };
    let photo = read(v.photo.as_path())?;
    let matte = if !v.backdrops.is_empty() {
        matte_from_backdrops(rig, v, (w, h), opts, &read)?
    } else if let Some(m) = &v.mask {
        let mask = Mask::threshold(&read(m.as_path())?, 0.0);
        Matte {
            width: w,
            height: h,
            alpha: mask.data.iter().map(|&b| b as u8 as f32).collect(),
            valid: vec![true; w * h],
        }
    } else {
        return Err(rig
            .view_message(v, "has neither a mask nor matting captures (backdrops)")
            .into());
    };
    let silhouette = Mask {
        width: w,
        height: h,
        data: matte
            .alpha
            .iter()
            .zip(&matte.valid)
            .map(|(&a, &ok)| ok && a > opts.alpha_threshold)
            .collect(),
    };
    let known = Mask {
        width: w,
        height: h,
        data: matte.valid.clone(),
    };
    let fg = silhouette.count();
    if fg == 0 {
        return Err(HullError::Silhouette {
            rig: rig.path.clone(),
            view: v.id.clone(),
            what: "empty (no pixel is the object)",
        });
    }
    if fg == w * h {
        return Err(HullError::Silhouette {
            rig: rig.path.clone(),
            view: v.id.clone(),
            what: "full (every pixel is the object)",
        });
    }
    Ok(View {
        id: v.id.clone(),
        camera,
        photo,
        matte,
        silhouette,
        known,
    })
}

/// Eq. 2 per lambda on the view's (n = +1, n = -1) pairs, maximum over lambda.
fn matte_from_backdrops(
    rig: &Rig,
    v: &RigView,
    (w, h): (usize, usize),
    opts: MatteOptions,
    read: &dyn Fn(&std::path::Path) -> Result<HdrImage, HullError>,
) -> Result<Matte, HullError> {
    let mut lambdas: Vec<f64> = v.backdrops.iter().map(|b| b.lambda).collect();
    lambdas.sort_by(f64::total_cmp);
    lambdas.dedup();
    let mut out = Matte::invalid(w, h);
    for lambda in lambdas {
        let find = |n: i32| {
            v.backdrops.iter().find(|b| b.lambda == lambda && b.n == n).ok_or_else(|| {
                HullError::from(rig.view_message(v, format!("backdrop lambda = {lambda} has no n = {n} capture (Eq. 2 needs both signs)")))
            })
        };
        let (p, m) = (find(1)?, find(-1)?);
        let matte = alpha_from_pair(
            &read(p.object.as_path())?,
            &read(m.object.as_path())?,
            &read(p.backdrop.as_path())?,
            &read(m.backdrop.as_path())?,
            opts.min_signal,
        );
        out.max_with(&matte);
    }
    Ok(out)
}
