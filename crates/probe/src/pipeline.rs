//! From one board photograph (linear HDR) to the lighting: sky map, sun, diagnostics.

use crate::board::{Board, SphereKind};
use crate::envmap::{self, Integrator};
use crate::resample::{self, Reflector};
use crate::ProbeError;
use glam::{DVec2, DVec3, Vec3};
use igi_camera::Camera;
use igi_capture::highlight::{locate_spot, LocatedSpot, SpotPixels};
use igi_capture::sphere::{SpherePixel, SphereView};
use igi_imaging::HdrImage;
use rayon::prelude::*;

/// Tunable parameters of [`process`].
#[derive(Clone, Debug, serde::Serialize)]
pub struct ProbeOptions {
    /// Width of the lat-long sky map (height is half).
    pub map_width: usize,
    /// Side of the upper-hemisphere pictures.
    pub hemi_size: usize,
    /// Each map texel averages at least `n` x `n` sub-directions, more where its footprint in
    /// the photograph is larger (two per pixel, up to [`resample::MAX_SUBSAMPLES`]; see [`resample`]).
    pub map_supersample: usize,
    /// Width of the lat-long map integrated for the diffuse convolution (divides `map_width`).
    pub conv_width: usize,
    /// Mirror and black sphere pixels beyond this incidence angle are not used (grazing
    /// samples are stretched and mix with the background).
    pub max_incidence_deg: f64,
    /// Cone around the direction toward the camera masked out (the camera's own reflection).
    pub camera_mask_deg: f64,
    /// Diffuse sphere pixels beyond this incidence angle are not used.
    pub diffuse_max_incidence_deg: f64,
    /// The sun is declared visible when the black sphere's brightest spot exceeds this
    /// multiple of its median (or when the mirror or black sphere has saturated pixels).
    pub sun_peak_ratio: f64,
    /// Radius in pixels masked around the sun's reflection in the mirror sphere.
    pub sun_mask_px: f64,
    /// Angular diameter of the sun disk.
    pub sun_diameter_deg: f64,
    /// Pixels with any channel at or above this value are treated as saturated (for clipped
    /// single images); `None` trusts the image's own mask.
    pub saturation: Option<f32>,
    /// Spheres smaller than this (pixels) get a warning.
    pub min_radius_px: f64,
    /// Move the mirror and black spheres' centres across the line of sight to fit their
    /// silhouettes in the image ([`crate::outline`]) before anything else: for centres from an
    /// imprecise pose (fiducials); it leaves about 0.1 px of its own error.
    pub refine_centers: bool,
}

impl Default for ProbeOptions {
    fn default() -> Self {
        ProbeOptions {
            map_width: 256,
            hemi_size: 512,
            map_supersample: 2,
            conv_width: 128,
            max_incidence_deg: 72.0,
            camera_mask_deg: 4.0,
            diffuse_max_incidence_deg: 75.0,
            sun_peak_ratio: 50.0,
            sun_mask_px: 4.0,
            sun_diameter_deg: igi_imaging::color::SUN_ANGULAR_DIAMETER_DEG,
            saturation: None,
            min_radius_px: 20.0,
            refine_centers: false,
        }
    }
}

/// The recovered sun.
#[derive(Clone, Debug, serde::Serialize)]
pub struct SunEstimate {
    /// Unit vector toward the sun, world frame.
    pub direction: [f64; 3],
    pub elevation_deg: f64,
    pub azimuth_deg: f64,
    /// Radiance of the disk per channel (same units as the map); `None` without a diffuse sphere.
    pub radiance: Option<[f32; 3]>,
    pub angular_diameter_deg: f64,
    /// Sub-pixel centre of the spot on the sphere it was found on.
    pub spot_pixel: [f64; 2],
    /// Blur (pixels) of the Gaussian fitted to the spot ([`igi_capture::spot::fit_spot`]); `None` where the
    /// spot was clipped or the fit failed and the intensity-weighted centroid was used.
    pub spot_fit_sigma_px: Option<f64>,
    /// "black" or "mirror".
    pub found_on: String,
    /// Where the sun reflects in the mirror sphere (masked there).
    pub mirror_pixel: Option<[f64; 2]>,
    /// RMS of D' + a D* - D over the diffuse sphere, percent of mean D.
    pub residual_rms_percent: Option<f64>,
}

/// What happened, for people and scripts (written as JSON by the CLI).
#[derive(Clone, Debug, serde::Serialize)]
pub struct Diagnostics {
    pub sun_found: bool,
    pub sun_decision: String,
    pub sun: Option<SunEstimate>,
    /// RMS of (diffuse convolution of the final lighting - diffuse sphere image), percent of
    /// the mean diffuse sphere value (the paper: 2 %).
    pub check_rms_percent: Option<f64>,
    pub mirror_saturated_pixels: usize,
    pub black_saturated_pixels: usize,
    pub diffuse_pixels_used: usize,
    pub diffuse_pixels_masked: usize,
    pub black_peak_ratio: Option<f64>,
    pub sky_valid_fraction: f64,
    pub sphere_radius_px: Vec<(String, f64)>,
    pub warnings: Vec<String>,
    pub options: ProbeOptions,
    /// The board's pose from its fiducials when they placed the spheres (set by the caller of
    /// [`process`], see [`crate::fiducial::place_board`]).
    pub board_pose: Option<crate::fiducial::BoardPose>,
    /// The spheres' centres refined from their outlines (with `refine_centers`).
    pub outline_fits: Vec<crate::outline::OutlineFit>,
}

/// Everything [`process`] produces.
#[derive(Clone, Debug)]
pub struct ProbeResult {
    /// Lat-long sky (unit-albedo mirror map, sun removed when it is solved separately), holes filled, all valid.
    pub sky: HdrImage,
    /// The same before filling, with the validity mask (saturated pixels, camera reflection,
    /// directions the sphere cannot see, the sun's neighbourhood).
    pub sky_measured: HdrImage,
    /// Upper-hemisphere maps ([`envmap::hemisphere_direction`] layout).
    pub mirror_hemi: HdrImage,
    pub black_hemi: Option<HdrImage>,
    pub diffuse_hemi: Option<HdrImage>,
    /// Diffuse sphere crop: D (measured, divided by the paint reflectance) and the model D' + a D*.
    pub diffuse_compare: Option<(HdrImage, HdrImage)>,
    pub diagnostics: Diagnostics,
}

/// Rec. 709 luminance in double precision (`igi_imaging::color::luminance_f64`).
pub fn luminance(p: [f32; 3]) -> f64 {
    igi_imaging::color::luminance_f64(p.map(f64::from))
}

fn to_v3(d: DVec3) -> Vec3 {
    d.as_vec3()
}

use igi_imaging::color::median_in_place as median;

fn hemisphere_map(size: usize, f: &(dyn Fn(DVec3) -> Option<[f32; 3]> + Sync)) -> HdrImage {
    let rows: Vec<Vec<Option<[f32; 3]>>> = (0..size)
        .into_par_iter()
        .map(|y| {
            (0..size)
                .map(|x| {
                    envmap::hemisphere_direction(x, y, size)
                        .and_then(|d| f(d.as_dvec3().normalize()))
                })
                .collect()
        })
        .collect();
    let mut out = HdrImage::new(size, size);
    for (y, row) in rows.into_iter().enumerate() {
        for (x, v) in row.into_iter().enumerate() {
            let k = y * size + x;
            match v {
                Some(p) => out.pixels[k] = p,
                None => out.valid[k] = false,
            }
        }
    }
    out
}

fn sphere_saturated(img: &HdrImage, px: &[SpherePixel]) -> Vec<usize> {
    (0..px.len())
        .filter(|&i| !img.valid[px[i].y * img.width + px[i].x])
        .collect()
}

fn log_outline_fits(fits: &[crate::outline::OutlineFit]) {
    for f in fits {
        tracing::info!(
            "{} sphere centre refined from its outline: moved {:.3} px ({} edge points, RMS {:.3} px)",
            f.kind,
            f.shift_px,
            f.edge_points_used,
            f.rms_px
        );
    }
}

/// The board's spheres as seen by the camera.
struct BoardViews<'a> {
    mirror: SphereView<'a>,
    black: Option<SphereView<'a>>,
    diffuse: Option<SphereView<'a>>,
}

impl<'a> BoardViews<'a> {
    fn new(camera: &'a Camera, board: &Board) -> Self {
        let view = |kind, s: &Option<_>| s.as_ref().map(|s| SphereView::new(camera, kind, s));
        BoardViews {
            mirror: SphereView::new(camera, SphereKind::Mirror, &board.mirror),
            black: view(SphereKind::Black, &board.black),
            diffuse: view(SphereKind::Diffuse, &board.diffuse),
        }
    }

    /// Every sphere must lie inside the image; one under `min_radius_px` gets a warning.
    /// Returns each sphere's apparent radius, pixels.
    fn check_sizes(
        &self,
        min_radius_px: f64,
        warnings: &mut Vec<String>,
    ) -> Result<Vec<(String, f64)>, ProbeError> {
        let mut radii = Vec::new();
        for v in std::iter::once(&self.mirror)
            .chain(self.black.iter())
            .chain(self.diffuse.iter())
        {
            let r = v.check_in_image()?;
            if r < min_radius_px {
                let m = format!(
                    "the {} sphere is only {r:.1} px in radius (under {min_radius_px} px): expect a coarse map and a poor sun direction",
                    v.kind.name(),
                );
                tracing::warn!("{m}");
                warnings.push(m);
            }
            radii.push((v.kind.name().to_string(), r));
        }
        Ok(radii)
    }
}

/// What every step of [`process`] reads.
struct Ctx<'a> {
    /// The working copy of the photograph (non-finite and clipped pixels invalid).
    img: &'a HdrImage,
    board: &'a Board,
    opt: &'a ProbeOptions,
    /// Cosines of `max_incidence_deg` and `camera_mask_deg`.
    min_cos: f64,
    cam_cos: f64,
}

impl Ctx<'_> {
    fn mirror_refl(&self) -> impl Fn(f64) -> [f64; 3] + Sync + '_ {
        |c| self.board.mirror_reflectance(c)
    }

    fn black_refl(&self) -> impl Fn(f64) -> [f64; 3] + Sync + '_ {
        |c| self.board.black_reflectance(c)
    }
}

fn check_inputs(image: &HdrImage, camera: &Camera, opt: &ProbeOptions) -> Result<(), ProbeError> {
    if image.width != camera.width as usize || image.height != camera.height as usize {
        return Err(ProbeError::ImageSize {
            image_w: image.width,
            image_h: image.height,
            camera_w: camera.width,
            camera_h: camera.height,
        });
    }
    if opt.map_width < 8
        || !opt.map_width.is_multiple_of(2)
        || opt.conv_width == 0
        || !opt.map_width.is_multiple_of(opt.conv_width)
    {
        return Err(ProbeError::MapWidth {
            map: opt.map_width,
            conv: opt.conv_width,
        });
    }
    Ok(())
}

/// The working copy of the photograph: non-finite and (with `saturation`) clipped pixels
/// become invalid.
fn working_copy(image: &HdrImage, saturation: Option<f32>) -> HdrImage {
    let mut img = image.clone();
    for (p, v) in img.pixels.iter_mut().zip(img.valid.iter_mut()) {
        if p.iter().any(|c| !c.is_finite()) {
            *v = false;
            *p = [0.0; 3];
        } else if let Some(s) = saturation {
            if p.iter().any(|c| *c >= s) {
                *v = false;
            }
        }
    }
    img
}

/// The sun search: whether it is visible and where.
struct SunSearch {
    found: bool,
    decision: String,
    /// `Some` when found.
    located: Option<LocatedSpot>,
    mirror_saturated: usize,
    black_saturated: usize,
    peak_ratio: Option<f64>,
    /// "black" or "mirror": the sphere the spot is sought on.
    found_on: &'static str,
}

/// Decide from saturation and the black (else mirror) sphere's brightest spot whether the sun
/// is visible; if so, locate its spot ([`locate_spot`]).
fn find_sun(
    ctx: &Ctx,
    views: &BoardViews,
    warnings: &mut Vec<String>,
) -> Result<SunSearch, ProbeError> {
    let (img, opt) = (ctx.img, ctx.opt);
    let mirror_px = views.mirror.pixels(ctx.min_cos);
    let mirror_sat = sphere_saturated(img, &mirror_px);
    let spot_view = views.black.as_ref().unwrap_or(&views.mirror);
    let (black_refl, mirror_refl) = (ctx.black_refl(), ctx.mirror_refl());
    let spot_refl: &dyn Fn(f64) -> [f64; 3] = if views.black.is_some() {
        &black_refl
    } else {
        &mirror_refl
    };
    let spot_px = if views.black.is_some() {
        spot_view.pixels(ctx.min_cos)
    } else {
        mirror_px
    };
    let spot_sat = sphere_saturated(img, &spot_px);
    let spot_val: Vec<f64> = spot_px
        .iter()
        .map(|p| luminance(img.pixels[p.y * img.width + p.x]) / spot_refl(p.cos_i)[1])
        .collect();
    let (peak, peak_ratio) = peak_over_median(img, &spot_px, &spot_val);
    let found = !mirror_sat.is_empty()
        || !spot_sat.is_empty()
        || peak_ratio.is_some_and(|r| r > opt.sun_peak_ratio);
    let decision = format!(
        "{} saturated mirror pixels, {} saturated {} pixels, brightest spot {} x median (threshold {}) -> sun {}",
        mirror_sat.len(),
        spot_sat.len(),
        spot_view.kind.name(),
        peak_ratio.map(|r| format!("{r:.1}")).unwrap_or_else(|| "n/a".into()),
        opt.sun_peak_ratio,
        if found { "visible" } else { "not visible: sun solve skipped" }
    );
    tracing::info!("{decision}");
    let located = if found {
        let spots = SpotPixels {
            img,
            view: spot_view,
            px: &spot_px,
            val: &spot_val,
            saturated: &spot_sat,
            peak,
        };
        let l = locate_spot(&spots, opt.sun_diameter_deg).ok_or(ProbeError::NoSunPixels)?;
        if l.direction.is_none() {
            warnings.push("the sun spot's centre does not lie on the sphere; sun ignored".into());
        }
        Some(l)
    } else {
        None
    };
    Ok(SunSearch {
        found,
        decision,
        located,
        mirror_saturated: mirror_sat.len(),
        black_saturated: if views.black.is_some() {
            spot_sat.len()
        } else {
            0
        },
        peak_ratio,
        found_on: spot_view.kind.name(),
    })
}

/// The brightest pixel's index and its ratio to the median of the valid pixels (`None` where
/// that median is not positive).
fn peak_over_median(
    img: &HdrImage,
    px: &[SpherePixel],
    val: &[f64],
) -> (Option<usize>, Option<f64>) {
    let mut valid_vals: Vec<f64> = px
        .iter()
        .zip(val)
        .filter(|(p, _)| img.valid[p.y * img.width + p.x])
        .map(|(_, v)| *v)
        .collect();
    let med = median(&mut valid_vals);
    let (mut peak_i, mut peak_v) = (None, f64::MIN);
    for (i, v) in val.iter().enumerate() {
        if *v > peak_v {
            peak_v = *v;
            peak_i = Some(i);
        }
    }
    (peak_i, if med > 0.0 { Some(peak_v / med) } else { None })
}

/// The mirror (and black) sphere unwarped.
struct MirrorMaps {
    sky: HdrImage,
    sky_measured: HdrImage,
    mirror_hemi: HdrImage,
    black_hemi: Option<HdrImage>,
    /// Where the sun reflects in the mirror sphere (masked there).
    mirror_pixel: Option<[f64; 2]>,
}

/// Mask the sun's neighbourhood in the mirror (its light goes into the disk; `solved_sun` is
/// the direction of a sun whose radiance is solved separately) and unwarp the mirror into the
/// lat-long sky (holes filled) and the hemisphere pictures.
impl MirrorMaps {
    /// Refuses a non-finite value in the sky or the mirror's hemisphere.
    fn check_finite(&self) -> Result<(), ProbeError> {
        for p in self.sky.pixels.iter().chain(self.mirror_hemi.pixels.iter()) {
            if p.iter().any(|c| !c.is_finite()) {
                return Err(ProbeError::NonFiniteMap);
            }
        }
        Ok(())
    }
}

fn unwarp_mirror(ctx: &Ctx, views: &BoardViews, solved_sun: Option<DVec3>) -> MirrorMaps {
    let (img, opt) = (ctx.img, ctx.opt);
    let mut mirror_img = img.clone();
    let mirror_pixel = solved_sun
        .and_then(|s| views.mirror.reflection_point(s))
        .map(|rp| {
            mask_disc(&mut mirror_img, rp.pixel, opt.sun_mask_px);
            [rp.pixel.x, rp.pixel.y]
        });
    let (mw, ms) = (opt.map_width, opt.map_supersample);
    let (mirror_refl, black_refl) = (ctx.mirror_refl(), ctx.black_refl());
    let mirror_reader = Reflector {
        img: &mirror_img,
        view: &views.mirror,
        refl: &mirror_refl,
        min_cos: ctx.min_cos,
        cam_cos: ctx.cam_cos,
    };
    let sky_measured = resample::resample(
        &mirror_reader,
        &resample::latlong_layout(mw, mw / 2),
        mw,
        mw / 2,
        ms,
    );
    let mut sky = sky_measured.clone();
    envmap::fill_invalid_latlong(&mut sky);
    sky.valid.iter_mut().for_each(|v| *v = true);
    let hemi = resample::hemisphere_layout(opt.hemi_size);
    let mirror_hemi = resample::resample(&mirror_reader, &hemi, opt.hemi_size, opt.hemi_size, ms);
    let black_hemi = views.black.as_ref().map(|b| {
        let reader = Reflector {
            img,
            view: b,
            refl: &black_refl,
            min_cos: ctx.min_cos,
            cam_cos: ctx.cam_cos,
        };
        resample::resample(&reader, &hemi, opt.hemi_size, opt.hemi_size, ms)
    });
    MirrorMaps {
        sky,
        sky_measured,
        mirror_hemi,
        black_hemi,
        mirror_pixel,
    }
}

/// Mark the pixels within `r` of `c` invalid.
fn mask_disc(img: &mut HdrImage, c: DVec2, r: f64) {
    let (x0, x1) = (
        (c.x - r).floor().max(0.0) as usize,
        (c.x + r).ceil() as usize,
    );
    let (y0, y1) = (
        (c.y - r).floor().max(0.0) as usize,
        (c.y + r).ceil() as usize,
    );
    for y in y0..=y1.min(img.height - 1) {
        for x in x0..=x1.min(img.width - 1) {
            if DVec2::new(x as f64, y as f64).distance(c) <= r {
                img.valid[y * img.width + x] = false;
            }
        }
    }
}

/// What the diffuse sphere gives: the sun's radiance, the checks and the pictures.
#[derive(Default)]
struct DiffuseSolve {
    sun_radiance: Option<[f32; 3]>,
    residual: Option<f64>,
    check: Option<f64>,
    used: usize,
    masked: usize,
    hemi: Option<HdrImage>,
    compare: Option<(HdrImage, HdrImage)>,
}

/// The diffuse sphere's usable pixels and their values D (divided by the paint reflectance).
struct DiffuseSamples<'a> {
    good: Vec<&'a SpherePixel>,
    d_meas: Vec<[f64; 3]>,
}

/// The diffuse sphere: D, D' (the sky's diffuse convolution), D* (the sun's, per unit
/// radiance), the sun's radiance `a` from the per-channel least squares `D' + a D* = D`, and
/// the check of the final lighting against D.
fn solve_diffuse(
    ctx: &Ctx,
    dv: &SphereView,
    sky: &HdrImage,
    solved_sun: Option<DVec3>,
    warnings: &mut Vec<String>,
) -> Result<DiffuseSolve, ProbeError> {
    let (img, opt) = (ctx.img, ctx.opt);
    let dmin = opt.diffuse_max_incidence_deg.to_radians().cos();
    let px = dv.pixels(dmin);
    let s = diffuse_samples(ctx, &px)?;
    let used = s.good.len();
    let normals: Vec<Vec3> = s.good.iter().map(|p| to_v3(p.normal)).collect();
    let conv = envmap::downsample_latlong(sky, opt.map_width / opt.conv_width);
    let d_prime: Vec<[f64; 3]> = Integrator::new(&conv)
        .irradiance_many(&normals)
        .into_iter()
        .map(|e| e.map(|v| v as f64 / std::f64::consts::PI))
        .collect();
    let d_star: Vec<f64> = match solved_sun {
        Some(sd) => {
            let k = envmap::disk_cosine_solid_angle(opt.sun_diameter_deg) / std::f64::consts::PI;
            s.good
                .iter()
                .map(|p| k * p.normal.dot(sd).max(0.0))
                .collect()
        }
        None => vec![0.0; used],
    };
    let sun_radiance =
        solved_sun.and_then(|_| solve_sun_radiance(&d_star, &s.d_meas, &d_prime, warnings));
    let a = sun_radiance.unwrap_or([0.0; 3]);
    let model: Vec<[f64; 3]> = d_prime
        .iter()
        .zip(&d_star)
        .map(|(dp, s)| [dp[0] + a[0] * s, dp[1] + a[1] * s, dp[2] + a[2] * s])
        .collect();
    // check: the diffuse convolution of the final lighting (the sky map as written plus the
    // sun disk as written) against the diffuse sphere image
    let check = rms_percent(&model, &s.d_meas);
    Ok(DiffuseSolve {
        sun_radiance: sun_radiance.map(|a| a.map(|v| v as f32)),
        residual: sun_radiance.map(|_| check),
        check: Some(check),
        used,
        masked: px.len() - used,
        hemi: Some(diffuse_hemisphere(img, dv, dmin, opt.hemi_size, ctx.board)),
        compare: Some(diffuse_compare(dv, &s, &model)),
    })
}

fn diffuse_samples<'a>(ctx: &Ctx, px: &'a [SpherePixel]) -> Result<DiffuseSamples<'a>, ProbeError> {
    let img = ctx.img;
    let rho = ctx.board.diffuse_reflectance;
    let good: Vec<&SpherePixel> = px
        .iter()
        .filter(|p| img.valid[p.y * img.width + p.x])
        .collect();
    let (used, masked) = (good.len(), px.len() - good.len());
    if masked > 0 {
        tracing::info!("{masked} saturated/invalid diffuse sphere pixels left out of the solve");
    }
    if used < 10 {
        return Err(ProbeError::TooFewDiffusePixels { used, masked });
    }
    let d_meas = good
        .iter()
        .map(|p| {
            let v = img.pixels[p.y * img.width + p.x];
            [
                v[0] as f64 / rho[0],
                v[1] as f64 / rho[1],
                v[2] as f64 / rho[2],
            ]
        })
        .collect();
    Ok(DiffuseSamples { good, d_meas })
}

/// The sun's radiance per channel, `a = sum D* (D - D') / sum D*^2`, negative values clamped
/// to 0 with a warning; `None` (with a warning) when the sun lights no visible part of the
/// sphere.
fn solve_sun_radiance(
    d_star: &[f64],
    d_meas: &[[f64; 3]],
    d_prime: &[[f64; 3]],
    warnings: &mut Vec<String>,
) -> Option<[f64; 3]> {
    let ss: f64 = d_star.iter().map(|v| v * v).sum();
    if ss <= 0.0 {
        warnings.push(
            "the sun lights no visible part of the diffuse sphere: radiance not solvable".into(),
        );
        return None;
    }
    let mut a = [0.0f64; 3];
    for c in 0..3 {
        let num: f64 = d_star
            .iter()
            .zip(d_meas)
            .zip(d_prime)
            .map(|((s, d), dp)| s * (d[c] - dp[c]))
            .sum();
        a[c] = num / ss;
        if a[c] < 0.0 {
            warnings.push(format!(
                "negative sun radiance in channel {c} ({:.3e}) clamped to 0",
                a[c]
            ));
            a[c] = 0.0;
        }
    }
    Some(a)
}

/// RMS of `model - d` over all channels, percent of the mean of `d`.
fn rms_percent(model: &[[f64; 3]], d: &[[f64; 3]]) -> f64 {
    let n = d.len() as f64;
    let mean_d: f64 = d.iter().map(|d| (d[0] + d[1] + d[2]) / 3.0).sum::<f64>() / n;
    let se: f64 = model
        .iter()
        .zip(d)
        .map(|(m, d)| (0..3).map(|c| (m[c] - d[c]).powi(2)).sum::<f64>())
        .sum();
    100.0 * (se / (3.0 * n)).sqrt() / mean_d.max(1e-30)
}

/// The diffuse sphere mapped by its normals (divided by the paint reflectance).
fn diffuse_hemisphere(
    img: &HdrImage,
    dv: &SphereView,
    dmin: f64,
    size: usize,
    board: &Board,
) -> HdrImage {
    let rho = board.diffuse_reflectance;
    hemisphere_map(size, &|n| {
        let p = dv.center + dv.radius * n;
        let v = (dv.eye - p).normalize();
        if n.dot(v) < dmin {
            return None;
        }
        let px = dv.camera.project(p)?;
        let q = img.bilinear(px.x as f32, px.y as f32)?;
        Some([
            (q[0] as f64 / rho[0]) as f32,
            (q[1] as f64 / rho[1]) as f32,
            (q[2] as f64 / rho[2]) as f32,
        ])
    })
}

/// The diffuse sphere's crop: D beside the model D' + a D*.
fn diffuse_compare(
    dv: &SphereView,
    s: &DiffuseSamples,
    model: &[[f64; 3]],
) -> (HdrImage, HdrImage) {
    let (x0, y0, x1, y1) = dv.pixel_bbox();
    let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
    let mut dimg = HdrImage::new(cw, ch);
    let mut mimg = HdrImage::new(cw, ch);
    dimg.valid.iter_mut().for_each(|v| *v = false);
    mimg.valid.iter_mut().for_each(|v| *v = false);
    for ((p, d), m) in s.good.iter().zip(&s.d_meas).zip(model) {
        let k = (p.y - y0) * cw + (p.x - x0);
        dimg.pixels[k] = d.map(|v| v as f32);
        mimg.pixels[k] = m.map(|v| v as f32);
        dimg.valid[k] = true;
        mimg.valid[k] = true;
    }
    (dimg, mimg)
}

/// The recovered sun toward `s` with what the search, the mirror and the diffuse sphere found.
fn sun_estimate(
    s: DVec3,
    search: &SunSearch,
    maps: &MirrorMaps,
    diffuse: &DiffuseSolve,
    opt: &ProbeOptions,
) -> SunEstimate {
    SunEstimate {
        direction: s.to_array(),
        elevation_deg: s.z.clamp(-1.0, 1.0).asin().to_degrees(),
        azimuth_deg: s.y.atan2(s.x).to_degrees().rem_euclid(360.0),
        radiance: diffuse.sun_radiance,
        angular_diameter_deg: opt.sun_diameter_deg,
        spot_pixel: search.located.as_ref().map_or([0.0; 2], |l| l.pixel),
        spot_fit_sigma_px: search.located.as_ref().and_then(|l| l.fit_sigma),
        found_on: search.found_on.to_string(),
        mirror_pixel: maps.mirror_pixel,
        residual_rms_percent: diffuse.residual,
    }
}

/// Process one board photograph.
pub fn process(
    image: &HdrImage,
    camera: &Camera,
    board: &Board,
    opt: &ProbeOptions,
) -> Result<ProbeResult, ProbeError> {
    check_inputs(image, camera, opt)?;
    let mut warnings = Vec::new();
    let img = working_copy(image, opt.saturation);
    let (refined, outline_fits) = match opt.refine_centers {
        true => {
            let (b, fits, w) = crate::outline::refine_board(&img, camera, board, 0.5);
            log_outline_fits(&fits);
            warnings.extend(w);
            (Some(b), fits)
        }
        false => (None, Vec::new()),
    };
    let board = refined.as_ref().unwrap_or(board);
    let views = BoardViews::new(camera, board);
    let radii = views.check_sizes(opt.min_radius_px, &mut warnings)?;
    let ctx = Ctx {
        img: &img,
        board,
        opt,
        min_cos: opt.max_incidence_deg.to_radians().cos(),
        cam_cos: opt.camera_mask_deg.to_radians().cos(),
    };
    let search = find_sun(&ctx, &views, &mut warnings)?;
    let sun_dir = search.located.as_ref().and_then(|l| l.direction);
    if sun_dir.is_some() && views.diffuse.is_none() {
        warnings.push(
            "sun visible but the board has no diffuse sphere: its radiance cannot be solved, it stays in the map"
                .into(),
        );
    }
    let solved_sun = sun_dir.filter(|_| views.diffuse.is_some());
    let maps = unwarp_mirror(&ctx, &views, solved_sun);
    let diffuse = match &views.diffuse {
        Some(dv) => solve_diffuse(&ctx, dv, &maps.sky, solved_sun, &mut warnings)?,
        None => DiffuseSolve::default(),
    };
    maps.check_finite()?;
    let sun = sun_dir.map(|s| sun_estimate(s, &search, &maps, &diffuse, opt));
    let sky_valid_fraction = maps.sky_measured.valid_fraction();
    Ok(ProbeResult {
        sky_measured: maps.sky_measured,
        diagnostics: Diagnostics {
            sun_found: search.found,
            sun_decision: search.decision,
            sun,
            check_rms_percent: diffuse.check,
            mirror_saturated_pixels: search.mirror_saturated,
            black_saturated_pixels: search.black_saturated,
            diffuse_pixels_used: diffuse.used,
            diffuse_pixels_masked: diffuse.masked,
            black_peak_ratio: search.peak_ratio,
            sky_valid_fraction,
            sphere_radius_px: radii,
            warnings,
            options: opt.clone(),
            board_pose: None,
            outline_fits,
        },
        sky: maps.sky,
        mirror_hemi: maps.mirror_hemi,
        black_hemi: maps.black_hemi,
        diffuse_hemi: diffuse.hemi,
        diffuse_compare: diffuse.compare,
    })
}
