//! From one board photograph (linear HDR) to the lighting: sky map, sun, diagnostics.

use crate::board::{Board, SphereKind};
use crate::envmap::{self, Integrator};
use crate::resample::{self, Reflector};
use crate::ProbeError;
use glam::{DVec2, DVec3, Vec3};
use igi_capture::highlight::{locate_spot, SpotPixels};
use igi_capture::sphere::{SpherePixel, SphereView};
use igi_imaging::{Camera, HdrImage};
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

/// Process one board photograph.
pub fn process(
    image: &HdrImage,
    camera: &Camera,
    board: &Board,
    opt: &ProbeOptions,
) -> Result<ProbeResult, ProbeError> {
    if image.width != camera.width as usize || image.height != camera.height as usize {
        return Err(ProbeError::InvalidInput(format!(
            "the image is {}x{} but the camera is {}x{}",
            image.width, image.height, camera.width, camera.height
        )));
    }
    if opt.map_width < 8
        || opt.map_width % 2 != 0
        || opt.conv_width == 0
        || opt.map_width % opt.conv_width != 0
    {
        return Err(ProbeError::InvalidInput(format!(
            "map width {} must be even and a multiple of the convolution width {}",
            opt.map_width, opt.conv_width
        )));
    }
    let mut warnings = Vec::new();
    // working copy: non-finite and (optionally) clipped pixels become invalid
    let mut img = image.clone();
    for (p, v) in img.pixels.iter_mut().zip(img.valid.iter_mut()) {
        if p.iter().any(|c| !c.is_finite()) {
            *v = false;
            *p = [0.0; 3];
        } else if let Some(s) = opt.saturation {
            if p.iter().any(|c| *c >= s) {
                *v = false;
            }
        }
    }

    let refined;
    let mut outline_fits = Vec::new();
    let board = if opt.refine_centers {
        let (b, fits, w) = crate::outline::refine_board(&img, camera, board, 0.5);
        log_outline_fits(&fits);
        warnings.extend(w);
        outline_fits = fits;
        refined = b;
        &refined
    } else {
        board
    };
    let mirror = SphereView::new(camera, SphereKind::Mirror, &board.mirror);
    let black = board
        .black
        .as_ref()
        .map(|s| SphereView::new(camera, SphereKind::Black, s));
    let diffuse = board
        .diffuse
        .as_ref()
        .map(|s| SphereView::new(camera, SphereKind::Diffuse, s));
    let mut radii = Vec::new();
    for v in std::iter::once(&mirror)
        .chain(black.iter())
        .chain(diffuse.iter())
    {
        let r = v.check_in_image()?;
        if r < opt.min_radius_px {
            let m = format!(
                "the {} sphere is only {r:.1} px in radius (under {} px): expect a coarse map and a poor sun direction",
                v.kind.name(),
                opt.min_radius_px
            );
            tracing::warn!("{m}");
            warnings.push(m);
        }
        radii.push((v.kind.name().to_string(), r));
    }
    let min_cos = opt.max_incidence_deg.to_radians().cos();
    let cam_cos = opt.camera_mask_deg.to_radians().cos();
    let mirror_refl = |c: f64| board.mirror_reflectance(c);
    let black_refl = |c: f64| board.black_reflectance(c);

    // ---- sun: decide from saturation and the black sphere's brightest spot
    let mirror_px = mirror.pixels(min_cos);
    let mirror_sat = sphere_saturated(&img, &mirror_px);
    let spot_view = black.as_ref().unwrap_or(&mirror);
    let spot_refl: &dyn Fn(f64) -> [f64; 3] = if black.is_some() {
        &black_refl
    } else {
        &mirror_refl
    };
    let spot_px = if black.is_some() {
        spot_view.pixels(min_cos)
    } else {
        mirror_px.clone()
    };
    let spot_sat = sphere_saturated(&img, &spot_px);
    let spot_val: Vec<f64> = spot_px
        .iter()
        .map(|p| luminance(img.pixels[p.y * img.width + p.x]) / spot_refl(p.cos_i)[1])
        .collect();
    let mut valid_vals: Vec<f64> = spot_px
        .iter()
        .zip(&spot_val)
        .filter(|(p, _)| img.valid[p.y * img.width + p.x])
        .map(|(_, v)| *v)
        .collect();
    let med = median(&mut valid_vals);
    let (mut peak_i, mut peak_v) = (None, f64::MIN);
    for (i, v) in spot_val.iter().enumerate() {
        if *v > peak_v {
            peak_v = *v;
            peak_i = Some(i);
        }
    }
    let peak_ratio = if med > 0.0 { Some(peak_v / med) } else { None };
    let black_sat_count = if black.is_some() { spot_sat.len() } else { 0 };
    let sun_found = !mirror_sat.is_empty()
        || !spot_sat.is_empty()
        || peak_ratio.is_some_and(|r| r > opt.sun_peak_ratio);
    let decision = format!(
        "{} saturated mirror pixels, {} saturated {} pixels, brightest spot {} x median (threshold {}) -> sun {}",
        mirror_sat.len(),
        spot_sat.len(),
        spot_view.kind.name(),
        peak_ratio.map(|r| format!("{r:.1}")).unwrap_or_else(|| "n/a".into()),
        opt.sun_peak_ratio,
        if sun_found { "visible" } else { "not visible: sun solve skipped" }
    );
    tracing::info!("{decision}");

    let located = if sun_found {
        let spots = SpotPixels {
            img: &img,
            view: spot_view,
            px: &spot_px,
            val: &spot_val,
            saturated: &spot_sat,
            peak: peak_i,
        };
        let l = locate_spot(&spots, opt.sun_diameter_deg).ok_or_else(|| {
            ProbeError::InvalidInput("the sun sphere has no usable pixels".into())
        })?;
        if l.direction.is_none() {
            warnings.push("the sun spot's centre does not lie on the sphere; sun ignored".into());
        }
        Some(l)
    } else {
        None
    };
    let sun_dir = located.as_ref().and_then(|l| l.direction);
    let spot_pixel = located.as_ref().map_or([0.0; 2], |l| l.pixel);
    let spot_sigma = located.as_ref().and_then(|l| l.fit_sigma);

    // ---- mirror: mask the sun's neighbourhood (its light goes into the disk) and unwarp
    let solve_sun = sun_dir.is_some() && diffuse.is_some();
    if sun_dir.is_some() && diffuse.is_none() {
        warnings.push(
            "sun visible but the board has no diffuse sphere: its radiance cannot be solved, it stays in the map"
                .into(),
        );
    }
    let mut mirror_img = img.clone();
    let mut mirror_pixel = None;
    if let (true, Some(s)) = (solve_sun, sun_dir) {
        if let Some(rp) = mirror.reflection_point(s) {
            mirror_pixel = Some([rp.pixel.x, rp.pixel.y]);
            let r = opt.sun_mask_px;
            let (x0, x1) = (
                (rp.pixel.x - r).floor().max(0.0) as usize,
                (rp.pixel.x + r).ceil() as usize,
            );
            let (y0, y1) = (
                (rp.pixel.y - r).floor().max(0.0) as usize,
                (rp.pixel.y + r).ceil() as usize,
            );
            for y in y0..=y1.min(img.height - 1) {
                for x in x0..=x1.min(img.width - 1) {
                    if DVec2::new(x as f64, y as f64).distance(rp.pixel) <= r {
                        mirror_img.valid[y * img.width + x] = false;
                    }
                }
            }
        }
    }
    let (mw, ms) = (opt.map_width, opt.map_supersample);
    let mirror_reader = Reflector {
        img: &mirror_img,
        view: &mirror,
        refl: &mirror_refl,
        min_cos,
        cam_cos,
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
    let black_hemi = black.as_ref().map(|b| {
        let reader = Reflector {
            img: &img,
            view: b,
            refl: &black_refl,
            min_cos,
            cam_cos,
        };
        resample::resample(&reader, &hemi, opt.hemi_size, opt.hemi_size, ms)
    });

    // ---- diffuse sphere: D, D', D*, the sun's radiance, the check
    let mut sun_radiance = None;
    let mut residual = None;
    let mut check = None;
    let (mut used, mut masked) = (0, 0);
    let mut diffuse_hemi = None;
    let mut diffuse_compare = None;
    if let Some(dv) = &diffuse {
        let rho = board.diffuse_reflectance;
        let dmin = opt.diffuse_max_incidence_deg.to_radians().cos();
        let px = dv.pixels(dmin);
        let good: Vec<&SpherePixel> = px
            .iter()
            .filter(|p| img.valid[p.y * img.width + p.x])
            .collect();
        used = good.len();
        masked = px.len() - used;
        if masked > 0 {
            tracing::info!(
                "{masked} saturated/invalid diffuse sphere pixels left out of the solve"
            );
        }
        if used < 10 {
            return Err(ProbeError::InvalidInput(format!(
                "only {used} usable diffuse sphere pixels ({masked} saturated or invalid)"
            )));
        }
        let d_meas: Vec<[f64; 3]> = good
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
        let normals: Vec<Vec3> = good.iter().map(|p| to_v3(p.normal)).collect();
        let conv = envmap::downsample_latlong(&sky, opt.map_width / opt.conv_width);
        let integ = Integrator::new(&conv);
        let d_prime: Vec<[f64; 3]> = integ
            .irradiance_many(&normals)
            .into_iter()
            .map(|e| e.map(|v| v as f64 / std::f64::consts::PI))
            .collect();
        let mut a = [0.0f64; 3];
        let d_star: Vec<f64> = match (solve_sun, sun_dir) {
            (true, Some(s)) => {
                let k =
                    envmap::disk_cosine_solid_angle(opt.sun_diameter_deg) / std::f64::consts::PI;
                good.iter().map(|p| k * p.normal.dot(s).max(0.0)).collect()
            }
            _ => vec![0.0; good.len()],
        };
        if solve_sun {
            let ss: f64 = d_star.iter().map(|v| v * v).sum();
            if ss <= 0.0 {
                warnings.push(
                    "the sun lights no visible part of the diffuse sphere: radiance not solvable"
                        .into(),
                );
            } else {
                for c in 0..3 {
                    let num: f64 = d_star
                        .iter()
                        .zip(&d_meas)
                        .zip(&d_prime)
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
                sun_radiance = Some(a.map(|v| v as f32));
            }
        }
        let mean_d: f64 = d_meas
            .iter()
            .map(|d| (d[0] + d[1] + d[2]) / 3.0)
            .sum::<f64>()
            / used as f64;
        let model: Vec<[f64; 3]> = d_prime
            .iter()
            .zip(&d_star)
            .map(|(dp, s)| [dp[0] + a[0] * s, dp[1] + a[1] * s, dp[2] + a[2] * s])
            .collect();
        let rms = |m: &[[f64; 3]]| {
            let se: f64 = m
                .iter()
                .zip(&d_meas)
                .map(|(m, d)| (0..3).map(|c| (m[c] - d[c]).powi(2)).sum::<f64>())
                .sum();
            100.0 * (se / (3.0 * used as f64)).sqrt() / mean_d.max(1e-30)
        };
        if sun_radiance.is_some() {
            residual = Some(rms(&model));
        }
        // check: the diffuse convolution of the final lighting (the sky map as written plus the
        // sun disk as written) against the diffuse sphere image
        check = Some(rms(&model));

        // pictures: the diffuse sphere mapped by its normals, and D beside D' + a D*
        let dview = dv.clone();
        diffuse_hemi = Some(hemisphere_map(opt.hemi_size, &|n| {
            let p = dview.center + dview.radius * n;
            let v = (dview.eye - p).normalize();
            if n.dot(v) < dmin {
                return None;
            }
            let px = dview.camera.project(p)?;
            let q = img.bilinear(px.x as f32, px.y as f32)?;
            Some([
                (q[0] as f64 / rho[0]) as f32,
                (q[1] as f64 / rho[1]) as f32,
                (q[2] as f64 / rho[2]) as f32,
            ])
        }));
        let (x0, y0, x1, y1) = dv.pixel_bbox();
        let (cw, ch) = (x1 - x0 + 1, y1 - y0 + 1);
        let mut dimg = HdrImage::new(cw, ch);
        let mut mimg = HdrImage::new(cw, ch);
        dimg.valid.iter_mut().for_each(|v| *v = false);
        mimg.valid.iter_mut().for_each(|v| *v = false);
        for ((p, d), m) in good.iter().zip(&d_meas).zip(&model) {
            let k = (p.y - y0) * cw + (p.x - x0);
            dimg.pixels[k] = d.map(|v| v as f32);
            mimg.pixels[k] = m.map(|v| v as f32);
            dimg.valid[k] = true;
            mimg.valid[k] = true;
        }
        diffuse_compare = Some((dimg, mimg));
    }

    let sun = sun_dir.map(|s| SunEstimate {
        direction: s.to_array(),
        elevation_deg: s.z.clamp(-1.0, 1.0).asin().to_degrees(),
        azimuth_deg: s.y.atan2(s.x).to_degrees().rem_euclid(360.0),
        radiance: sun_radiance,
        angular_diameter_deg: opt.sun_diameter_deg,
        spot_pixel,
        spot_fit_sigma_px: spot_sigma,
        found_on: spot_view.kind.name().to_string(),
        mirror_pixel,
        residual_rms_percent: residual,
    });
    let sky_valid_fraction = sky_measured.valid_fraction();
    for p in sky.pixels.iter().chain(mirror_hemi.pixels.iter()) {
        if p.iter().any(|c| !c.is_finite()) {
            return Err(ProbeError::InvalidInput(
                "non-finite value in the unwarped map".into(),
            ));
        }
    }
    Ok(ProbeResult {
        sky,
        sky_measured,
        mirror_hemi,
        black_hemi,
        diffuse_hemi,
        diffuse_compare,
        diagnostics: Diagnostics {
            sun_found,
            sun_decision: decision,
            sun,
            check_rms_percent: check,
            mirror_saturated_pixels: mirror_sat.len(),
            black_saturated_pixels: black_sat_count,
            diffuse_pixels_used: used,
            diffuse_pixels_masked: masked,
            black_peak_ratio: peak_ratio,
            sky_valid_fraction,
            sphere_radius_px: radii,
            warnings,
            options: opt.clone(),
            board_pose: None,
            outline_fits,
        },
    })
}
