//! Highlights on photographed spheres: where a small bright source (the sun, a lamp) reflects
//! in a glossy sphere, to sub-pixel precision, and the direction it reflects.
//!
//! - [`find_highlight`] (the sample frame's lamp on its black spheres): the background-subtracted,
//!   intensity-weighted centroid of the bright blob around the brightest pixel of the sphere's
//!   core; a clipped highlight is centred from its saturated pixels and unclipped tails.
//! - [`locate_spot`] (the lighting board's sun on its black or mirror sphere): the centroid of a
//!   9x9 window around the seed, then the fit of the disk's blurred, pixel-integrated reflection
//!   ([`crate::spot::fit_spot`], shape from [`disk_spot_shape`]).

use std::collections::{BTreeSet, HashMap, HashSet};

use glam::{DVec2, DVec3};
use igi_imaging::color::median_in_place as median;
use igi_imaging::HdrImage;
use serde::Serialize;

use crate::sphere::{ray_sphere, SpherePixel, SphereView};
use crate::spot;

/// A located highlight on one sphere.
#[derive(Clone, Debug, Serialize)]
pub struct Highlight {
    /// Sub-pixel centre in the photograph.
    pub pixel: [f64; 2],
    /// True when the highlight was saturated (its centre is the centroid of the saturated pixels).
    pub saturated: bool,
    /// Brightest pixel over its surroundings on the sphere (0 when saturated).
    pub peak_over_background: f64,
    /// Point on the sphere and the unit reflected direction (world coordinates).
    pub point: [f64; 3],
    pub reflected: [f64; 3],
}

/// Thresholds of [`find_highlight`].
#[derive(Clone, Copy, Debug)]
pub struct HighlightLimits {
    /// The brightest pixel must be at least this many times the median of the sphere's pixels
    /// 6 to 10 px away from it.
    pub min_ratio: f64,
    /// Largest fraction of the sphere's pixels that may be saturated.
    pub max_saturated_fraction: f64,
}

/// Why a highlight could not be located.
#[derive(Debug, thiserror::Error)]
pub enum HighlightError {
    #[error("the sphere is (partly) behind the camera")]
    BehindCamera,
    #[error("it covers only {0} usable pixels of the photo (outside the image, or a wrong pose?)")]
    TooFewPixels(usize),
    #[error(
        "{saturated} of its {pixels} pixels ({:.0}%) are saturated or unusable (at most {:.0}%): the highlight cannot be located; use a shorter exposure",
        *saturated as f64 / *pixels as f64 * 100.0,
        max_fraction * 100.0
    )]
    TooSaturated {
        saturated: usize,
        pixels: usize,
        max_fraction: f64,
    },
    #[error(
        "no highlight found: its brightest pixel is {ratio:.2} times its surroundings (at least {min_ratio} needed)"
    )]
    NoHighlight { ratio: f64, min_ratio: f64 },
    #[error("the highlight's centre ({x:.2}, {y:.2}) does not lie on the sphere")]
    OffSphere { x: f64, y: f64 },
}

type Px = (usize, usize);

/// Mean of the three channels of pixel (x, y).
fn mean_rgb(img: &HdrImage, (x, y): Px) -> f64 {
    let p = img.get(x, y);
    (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0
}

/// Locate the highlight on the sphere of `view` (camera pose set): the pixels whose rays hit
/// the sphere within 0.9 of its radius from the centre line (away from the limb) are examined;
/// the highlight centre is the background-subtracted, intensity-weighted centroid of the bright
/// blob around the brightest pixel; when some pixels are saturated, the saturated pixels count
/// with the brightest unclipped level and the unclipped pixels within 3 px with their own.
pub fn find_highlight(
    view: &SphereView,
    img: &HdrImage,
    limits: &HighlightLimits,
) -> Result<Highlight, HighlightError> {
    let mask = core_pixels(view, img)?;
    let sat: Vec<Px> = mask
        .iter()
        .copied()
        .filter(|&(x, y)| !img.is_valid(x, y))
        .collect();
    let (centre, saturated, ratio) = if !sat.is_empty() {
        let frac = sat.len() as f64 / mask.len() as f64;
        if frac > limits.max_saturated_fraction {
            return Err(HighlightError::TooSaturated {
                saturated: sat.len(),
                pixels: mask.len(),
                max_fraction: limits.max_saturated_fraction,
            });
        }
        (clipped_centre(img, &mask, &sat), true, 0.0)
    } else {
        let (c, ratio) = unclipped_centre(img, &mask, limits.min_ratio)?;
        (c, false, ratio)
    };
    let (c, r) = (view.center, view.radius);
    let (o, d) = view.camera.pixel_ray(centre.x, centre.y);
    let s = ray_sphere(o, d, c, r)
        .map(|(near, _)| near)
        .filter(|s| *s > 0.0)
        .ok_or(HighlightError::OffSphere {
            x: centre.x,
            y: centre.y,
        })?;
    let p = o + d * s;
    let n = (p - c) / r;
    Ok(Highlight {
        pixel: centre.to_array(),
        saturated,
        peak_over_background: ratio,
        point: p.to_array(),
        reflected: d.reflect(n).normalize().to_array(),
    })
}

/// The pixels (row by row) whose rays pass the sphere's centre within 0.9 of its radius, inside
/// the bounding box of the projected circumscribing cube (1.2 radii).
fn core_pixels(view: &SphereView, img: &HdrImage) -> Result<Vec<Px>, HighlightError> {
    let (cam, c, r) = (view.camera, view.center, view.radius);
    let (mut lo, mut hi) = (DVec2::splat(f64::INFINITY), DVec2::splat(f64::NEG_INFINITY));
    for k in 0..8 {
        let o = DVec3::new(
            if k & 1 == 0 { -1.0 } else { 1.0 },
            if k & 2 == 0 { -1.0 } else { 1.0 },
            if k & 4 == 0 { -1.0 } else { 1.0 },
        );
        let p = cam
            .project(c + o * 1.2 * r)
            .ok_or(HighlightError::BehindCamera)?;
        lo = lo.min(p);
        hi = hi.max(p);
    }
    let x0 = lo.x.floor().max(0.0) as usize;
    let y0 = lo.y.floor().max(0.0) as usize;
    let x1 = (hi.x.ceil().max(-1.0) as i64).min(img.width as i64 - 1);
    let y1 = (hi.y.ceil().max(-1.0) as i64).min(img.height as i64 - 1);
    let mut mask = Vec::new();
    if x1 >= x0 as i64 && y1 >= y0 as i64 {
        for y in y0..=y1 as usize {
            for x in x0..=x1 as usize {
                let (o, d) = cam.pixel_ray(x as f64, y as f64);
                let tca = (c - o).dot(d);
                if tca > 0.0 && (c - o).length_squared() - tca * tca < (0.9 * r) * (0.9 * r) {
                    mask.push((x, y));
                }
            }
        }
    }
    if mask.len() < 20 {
        return Err(HighlightError::TooFewPixels(mask.len()));
    }
    Ok(mask)
}

/// A clipped highlight: its profile is still symmetric about the centre, so the saturated
/// pixels are weighted with the brightest unclipped level and the unclipped tails within 3 px
/// added, background (the median of the sphere's valid pixels) subtracted.
fn clipped_centre(img: &HdrImage, mask: &[Px], sat: &[Px]) -> DVec2 {
    let inside: HashSet<Px> = mask.iter().copied().collect();
    let mut support: BTreeSet<Px> = BTreeSet::new();
    for &(x, y) in sat {
        for dy in -3i64..=3 {
            for dx in -3i64..=3 {
                let q = (
                    (x as i64 + dx).max(0) as usize,
                    (y as i64 + dy).max(0) as usize,
                );
                if inside.contains(&q) {
                    support.insert(q);
                }
            }
        }
    }
    let mut vals: Vec<f64> = mask
        .iter()
        .filter(|&&(x, y)| img.is_valid(x, y))
        .map(|&q| mean_rgb(img, q))
        .collect();
    let bg = median(&mut vals);
    let plateau = support
        .iter()
        .filter(|&&(x, y)| img.is_valid(x, y))
        .map(|&q| mean_rgb(img, q))
        .fold(bg, f64::max);
    let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for &(x, y) in &support {
        let w = if img.is_valid(x, y) {
            (mean_rgb(img, (x, y)) - bg).max(0.0)
        } else {
            plateau - bg
        };
        sw += w;
        sx += w * x as f64;
        sy += w * y as f64;
    }
    if !(sw > 0.0) {
        sx = sat.iter().map(|p| p.0 as f64).sum::<f64>();
        sy = sat.iter().map(|p| p.1 as f64).sum::<f64>();
        sw = sat.len() as f64;
    }
    DVec2::new(sx / sw, sy / sw)
}

/// An unclipped highlight: the brightest pixel must stand out of its surroundings (the median
/// 6 to 10 px away) by `min_ratio` (the shading of the sphere's base does not); the centre is
/// the background-subtracted centroid of the blob grown from the peak plus one pixel of margin.
/// Returns the centre and the peak's ratio to the background.
fn unclipped_centre(
    img: &HdrImage,
    mask: &[Px],
    min_ratio: f64,
) -> Result<(DVec2, f64), HighlightError> {
    let mut vals: Vec<f64> = mask.iter().map(|&q| mean_rgb(img, q)).collect();
    let (ip, peak) =
        vals.iter().enumerate().fold(
            (0, f64::MIN),
            |b, (i, v)| if *v > b.1 { (i, *v) } else { b },
        );
    let med = median(&mut vals);
    let (px, py) = mask[ip];
    let mut ring: Vec<f64> = mask
        .iter()
        .copied()
        .filter(|&(x, y)| {
            let d = ((x as f64 - px as f64).powi(2) + (y as f64 - py as f64).powi(2)).sqrt();
            d > 6.0 && d <= 10.0
        })
        .map(|q| mean_rgb(img, q))
        .collect();
    let bg = if ring.len() >= 8 {
        median(&mut ring)
    } else {
        med
    };
    let ratio = if bg > 0.0 {
        peak / bg
    } else if peak > 0.0 {
        f64::INFINITY
    } else {
        0.0
    };
    if !(ratio >= min_ratio) {
        return Err(HighlightError::NoHighlight { ratio, min_ratio });
    }
    let inside: HashSet<Px> = mask.iter().copied().collect();
    let support = grow_blob(img, &inside, (px, py), bg + 0.02 * (peak - bg));
    let (mut sw, mut sx, mut sy) = (0.0, 0.0, 0.0);
    for &(x, y) in &support {
        let w = (mean_rgb(img, (x, y)) - bg).max(0.0);
        sw += w;
        sx += w * x as f64;
        sy += w * y as f64;
    }
    Ok((DVec2::new(sx / sw, sy / sw), ratio))
}

/// The 8-connected pixels of `inside` brighter than `thr`, grown from `seed` (at most about
/// 10000), plus one pixel of margin around them (the highlight's tails).
fn grow_blob(img: &HdrImage, inside: &HashSet<Px>, seed: Px, thr: f64) -> HashSet<Px> {
    let neighbours = |(x, y): Px| {
        (-1i64..=1)
            .flat_map(move |dy| (-1i64..=1).map(move |dx| (x as i64 + dx, y as i64 + dy)))
            .filter(|&(nx, ny)| nx >= 0 && ny >= 0)
            .map(|(nx, ny)| (nx as usize, ny as usize))
    };
    let mut blob = vec![seed];
    let mut seen: HashSet<Px> = blob.iter().copied().collect();
    let mut k = 0;
    while k < blob.len() && blob.len() < 10000 {
        let p = blob[k];
        k += 1;
        for q in neighbours(p) {
            if inside.contains(&q) && !seen.contains(&q) && mean_rgb(img, q) > thr {
                seen.insert(q);
                blob.push(q);
            }
        }
    }
    let mut support = seen;
    for &p in &blob {
        support.extend(neighbours(p).filter(|q| inside.contains(q)));
    }
    support
}

/// The pixels of a sphere a spot is sought on ([`locate_spot`]).
pub struct SpotPixels<'a> {
    pub img: &'a HdrImage,
    pub view: &'a SphereView<'a>,
    pub px: &'a [SpherePixel],
    /// Each pixel's value (luminance divided by the sphere's reflectance).
    pub val: &'a [f64],
    /// Indices of the saturated pixels.
    pub saturated: &'a [usize],
    /// Index of the brightest pixel.
    pub peak: Option<usize>,
}

/// Where a spot is and the direction it reflects.
#[derive(Clone, Copy, Debug)]
pub struct LocatedSpot {
    /// `None` when the spot's centre misses the sphere.
    pub direction: Option<DVec3>,
    pub pixel: [f64; 2],
    /// Blur of the fitted spot; `None` where the centroid was kept.
    pub fit_sigma: Option<f64>,
}

/// The reflection of a distant disk of `diameter_deg` (the sun): seed (the saturated pixels'
/// centroid, else the brightest pixel), background (median of a ring 5-8 px out), the centroid
/// of a 9x9 window, then unless a pixel of it is clipped the fit of the disk's blurred,
/// pixel-integrated reflection ([`spot::fit_spot`]); the centre is traced and reflected.
/// `None` when there is neither a saturated nor a brightest pixel.
pub fn locate_spot(s: &SpotPixels, diameter_deg: f64) -> Option<LocatedSpot> {
    let (img, px) = (s.img, s.px);
    let seed = if !s.saturated.is_empty() {
        let n = s.saturated.len() as f64;
        DVec2::new(
            s.saturated.iter().map(|&i| px[i].x as f64).sum::<f64>() / n,
            s.saturated.iter().map(|&i| px[i].y as f64).sum::<f64>() / n,
        )
    } else {
        let i = s.peak?;
        DVec2::new(px[i].x as f64, px[i].y as f64)
    };
    let mut ring: Vec<f64> = px
        .iter()
        .zip(s.val)
        .filter(|(p, _)| {
            let r = DVec2::new(p.x as f64, p.y as f64).distance(seed);
            r > 5.0 && r <= 8.0 && img.valid[p.y * img.width + p.x]
        })
        .map(|(_, v)| *v)
        .collect();
    let bg = median(&mut ring);
    let (samples, window_saturated) = spot_window(s, seed, bg);
    let cen = spot::centroid(&samples).unwrap_or(seed);
    let fit = if window_saturated {
        None
    } else {
        spot::fit_spot(&samples, cen, &disk_spot_shape(s.view, cen, diameter_deg))
    };
    let c = fit.map_or(cen, |f| f.center);
    Some(LocatedSpot {
        direction: s
            .view
            .hit_pixel(c.x, c.y)
            .map(|(_, n, d)| d.reflect(n).normalize()),
        pixel: [c.x, c.y],
        fit_sigma: fit.map(|f| f.sigma),
    })
}

/// The sphere's pixels in the 9x9 window around `seed`, background `bg` subtracted, and whether
/// any of them is saturated.
fn spot_window(s: &SpotPixels, seed: DVec2, bg: f64) -> (Vec<spot::SpotSample>, bool) {
    let img = s.img;
    let lookup: HashMap<Px, usize> =
        s.px.iter()
            .enumerate()
            .map(|(i, p)| ((p.x, p.y), i))
            .collect();
    let (cx, cy) = (seed.x.round() as i64, seed.y.round() as i64);
    let mut samples = Vec::with_capacity(81);
    let mut window_saturated = false;
    for y in (cy - 4).max(0)..=cy + 4 {
        for x in (cx - 4).max(0)..=cx + 4 {
            if let Some(&i) = lookup.get(&(x as usize, y as usize)) {
                window_saturated |= !img.valid[y as usize * img.width + x as usize];
                samples.push(spot::SpotSample {
                    x: x as f64,
                    y: y as f64,
                    v: s.val[i] - bg,
                });
            }
        }
    }
    (samples, window_saturated)
}

/// A distant disk's reflection in `view` around pixel `at`, as points sampling it evenly
/// (offsets in pixels from the reflection of the disk's centre): a 9 x 9 grid over the disk in
/// the plane across the direction reflected at `at`, each point mapped back to its pixel.
/// `[0, 0]` alone where `at` misses the sphere.
pub fn disk_spot_shape(view: &SphereView, at: DVec2, diameter_deg: f64) -> Vec<DVec2> {
    let Some((_, n, d)) = view.hit_pixel(at.x, at.y) else {
        return vec![DVec2::ZERO];
    };
    let s0 = d.reflect(n).normalize();
    let Some(c0) = view.reflection_point(s0) else {
        return vec![DVec2::ZERO];
    };
    let (e1, e2) = s0.any_orthonormal_pair();
    let t = (0.5 * diameter_deg).to_radians().tan();
    let mut pts = Vec::new();
    for i in 0..9 {
        for j in 0..9 {
            let (u, v) = ((i as f64 - 4.0) / 4.5, (j as f64 - 4.0) / 4.5);
            if u * u + v * v > 1.0 {
                continue;
            }
            let w = (s0 + t * (u * e1 + v * e2)).normalize();
            if let Some(q) = view.reflection_point(w) {
                pts.push(q.pixel - c0.pixel);
            }
        }
    }
    if pts.is_empty() {
        pts.push(DVec2::ZERO);
    }
    pts
}
