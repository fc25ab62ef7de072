//! Loading a rig's views: camera, photo, matte and the silhouette used for carving.
//!
//! A view's matte comes from its matting captures when it has them (Eq. 2, maximum over
//! lambda), otherwise from its mask (opacity 0 or 1). The silhouette for carving is
//! `alpha > threshold` (0.05 in the paper); pixels whose matte is invalid are **unknown**, as
//! are all pixels outside the frame: neither carves. Where the silhouette runs into the frame's
//! edge, the object goes on outside the frame, and its parts near the edge that lie in shadow
//! read like the backdrop (the Middlebury README warns of dark shadows on the object): there a
//! band along the edge ([`MatteOptions::frame_band`]) is weak evidence: a cell that only band
//! pixels call background is carved when two views' bands agree, or when no more views see it
//! as object than see it as band background ([`crate::carve::carve_band_votes`]). The band is left out of the carving only; every known
//! pixel counts in the reprojection IoU.

use crate::backdrop::{alpha_from_pair, Matte};
use crate::HullError;
use igi_camera::rig::{Rig, RigView};
use igi_camera::Camera;
use igi_imaging::{read_image, HdrImage, Mask};

/// Matting options.
#[derive(Clone, Copy, Debug)]
pub struct MatteOptions {
    /// Silhouette threshold on alpha (the paper: 0.05).
    pub alpha_threshold: f32,
    /// Smallest backdrop-pair difference that carries signal (see [`alpha_from_pair`]).
    pub min_signal: f32,
    /// Depth in pixels of the band along the frame's edge that does not carve, wherever the
    /// silhouette meets the edge (within this many pixels along it); 0: none.
    pub frame_band: usize,
}

impl Default for MatteOptions {
    fn default() -> Self {
        MatteOptions {
            alpha_threshold: 0.05,
            min_signal: 0.02,
            frame_band: 30,
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
    /// Known pixels that may carve: `known` less the frame band
    /// ([`MatteOptions::frame_band`]).
    pub carves: Mask,
}

impl View {
    /// True when pixel (x, y) is known background that carves.
    #[inline]
    pub fn is_background(&self, x: usize, y: usize) -> bool {
        let i = y * self.silhouette.width + x;
        self.carves.data[i] && !self.silhouette.data[i]
    }

    /// True when pixel (x, y) is known background inside the frame band: weak evidence, weighed
    /// against the other views ([`crate::carve::carve_band_votes`]).
    #[inline]
    pub fn is_band_background(&self, x: usize, y: usize) -> bool {
        let i = y * self.silhouette.width + x;
        self.known.data[i] && !self.carves.data[i] && !self.silhouette.data[i]
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
    let carves = without_frame_band(&silhouette, &known, opts.frame_band);
    Ok(View {
        id: v.id.clone(),
        camera,
        photo,
        matte,
        silhouette,
        known,
        carves,
    })
}

/// `known` less a band `band` pixels deep along each edge of the frame, over the stretch of the
/// edge within `band` pixels of a silhouette pixel on it.
pub fn without_frame_band(silhouette: &Mask, known: &Mask, band: usize) -> Mask {
    let (w, h) = (silhouette.width, silhouette.height);
    let mut out = known.clone();
    if band == 0 || w == 0 || h == 0 {
        return out;
    }
    let on = |x: usize, y: usize| silhouette.data[y * w + x];
    // the four edges: length, the silhouette on it at position t, pixel at (t, depth d)
    type Px = fn(usize, usize, usize, usize) -> (usize, usize);
    let edges: [(usize, Px); 4] = [
        (w, |t, d, _, _| (t, d)),
        (w, |t, d, _, h| (t, h - 1 - d)),
        (h, |t, d, _, _| (d, t)),
        (h, |t, d, w, _| (w - 1 - d, t)),
    ];
    for (len, at) in edges {
        let touching: Vec<bool> = (0..len)
            .map(|t| {
                let (x, y) = at(t, 0, w, h);
                on(x, y)
            })
            .collect();
        for t in 0..len {
            let lo = t.saturating_sub(band);
            let hi = (t + band).min(len - 1);
            if !touching[lo..=hi].iter().any(|b| *b) {
                continue;
            }
            for d in 0..band.min(if len == w { h } else { w }) {
                let (x, y) = at(t, d, w, h);
                out.data[y * w + x] = false;
            }
        }
    }
    out
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

#[cfg(test)]
mod tests {
    use super::*;

    /// A silhouette that meets the top edge over columns 40-49 of a 100 x 80 frame: a band 10
    /// deep over columns 30-59 stops carving; the rest of the frame, and a frame whose
    /// silhouette stays inside, are unchanged.
    #[test]
    fn the_band_follows_where_the_silhouette_meets_the_edge() {
        let (w, h) = (100, 80);
        let mut sil = Mask::new(w, h);
        for y in 0..30 {
            for x in 40..50 {
                sil.data[y * w + x] = true;
            }
        }
        let known = Mask {
            width: w,
            height: h,
            data: vec![true; w * h],
        };
        let carves = without_frame_band(&sil, &known, 10);
        for y in 0..h {
            for x in 0..w {
                let banded = y < 10 && (30..60).contains(&x);
                assert_eq!(carves.data[y * w + x], !banded, "({x}, {y})");
            }
        }
        let mut inside = Mask::new(w, h);
        inside.data[40 * w + 50] = true;
        assert_eq!(without_frame_band(&inside, &known, 10), known);
        assert_eq!(without_frame_band(&sil, &known, 0), known);
    }
}
