//! Lighting without probes (issue 34, docs/SKY.md "Lighting estimated with the albedo"): a
//! photo with a `time` and no lighting file is lit by the sun of its time and place (NREL SPA
//! through `igi_sky::sun`) and a physical sky whose parameters are fitted to the photographs,
//! alternating with the albedo solve.
//!
//! The sky of a photo is
//!
//! ```text
//! L = sun_scale * sun_colour * HW_sun(T) + sky_scale * HW_sky(T) + overcast_scale * CIE_overcast(1)
//! ```
//!
//! with `HW_sun(T)` and `HW_sky(T)` the Hosek-Wilkie sun disk and clear sky of turbidity `T`
//! (ground albedo [`GROUND_ALBEDO`]) toward the SPA sun, and `CIE_overcast(1)` the CIE overcast
//! sky of unit zenith radiance, and `sun_colour` a per-channel factor of mean 1 (haze and the
//! sun's spectrum through the atmosphere redden it beyond what the model's turbidity says),
//! white unless [`FitOptions::tie_sun_colour`] is off (free, it trades against the turbidity
//! and the sky and costs blue albedo accuracy). With the albedo fixed, a photograph is
//! linear in the unknowns (the sun's scale, per channel when untied, the sky's, the overcast
//! sky's): each photo's radiance under each basis light (the sun as a white disk of unit
//! radiance, then coloured per turbidity; the clear sky per turbidity; the overcast sky) comes
//! from the light transport traced once per solve ([`crate::lightbasis`]: per texel, where its
//! hemisphere rays go; per photo, its sun's visibility and what its pixels see), so a round
//! traces no ray, and the scales are the non-negative weighted least-squares
//! fit of the photograph's pixels that see the site, with relative weights (each pixel's
//! residual divided by its value), either of a sunny sky (sun and clear sky) or of an overcast
//! one (clear and overcast sky, no sun), whichever fits better (with all five free the two
//! smooth domes trade against each other). The turbidity is the grid value with the smallest residual
//! ([`FitOptions::turbidities`]). Uncertainties are the least-squares standard errors (the
//! residual variance times the inverse normal matrix), which treat pixels as independent.
//! The parameters are the photo time's: photos taken at the same instant share one sky,
//! fitted to all their pixels at once. Each camera body but the first (`[[photo]] body`) has
//! one exposure factor, fitted in turn with the skies (`PhotoFit::body_exposure`).
//!
//! The global scale: the product of albedo and light is fixed by the photographs, one factor
//! is not. With `[[reference]]` targets (discs of known diffuse albedo) the albedo over the
//! seen texels of each disc fixes it ([`apply_gauge`]); without one, the scales are normalised
//! so that the mean sun scale of the photos with sun is 1 (the model's clear-sky sun), and the
//! result says that its albedo is known only up to one scale.

use crate::lightbasis::{sky_bins, PhotoTexels, SunDisk, Transport};
use crate::WorkflowError;
use glam::{DVec3, Vec3};
use igi_formats::lighting::{EnvironmentSection, LightingFile};
use igi_formats::survey::ReferenceTarget;
use igi_formats::{PhotoTime, TomlFile};
use igi_imaging::HdrImage;
use igi_reflect::SolveResult;
use igi_render::lighting::{Environment, Sun};
use igi_render::{Lighting, Scene, Texture};
use igi_sky::{sun_direction, sun_position, CieOvercast, Refraction, Sky, SunPosition};
use serde::{Deserialize, Serialize};
use std::path::Path;

/// The turbidity a photo's sky starts from (and keeps when not fitted).
pub const DEFAULT_TURBIDITY: f64 = 3.0;
/// The Hosek-Wilkie sky's ground albedo (every channel).
pub const GROUND_ALBEDO: f64 = 0.2;
/// Width of the lat-long sky maps (height half).
pub const MAP_WIDTH: usize = 256;

/// A site's location and north, checked (`[site]`).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct SiteLocation {
    pub latitude_deg: f64,
    pub longitude_deg: f64,
    /// The world direction of true north (horizontal).
    pub north: [f64; 3],
}

/// A photo whose light is estimated: its time at the site.
#[derive(Clone, Debug, PartialEq)]
pub struct SkyPhoto {
    pub time: PhotoTime,
    pub site: SiteLocation,
    /// The sun's topocentric position (SPA, standard refraction).
    pub position: SunPosition,
    /// The unit world direction toward the sun.
    pub sun: [f64; 3],
}

impl SkyPhoto {
    /// The sun of `time` at `site`; `None` (with the elevation) when it stands below the
    /// horizon, where the Hosek-Wilkie sky does not hold.
    pub fn new(
        time: PhotoTime,
        site: SiteLocation,
    ) -> Result<Result<SkyPhoto, f64>, WorkflowError> {
        let position = sun_position(
            &time,
            site.latitude_deg,
            site.longitude_deg,
            0.0,
            Refraction::STANDARD,
        )?;
        if position.elevation_deg() < 0.0 {
            return Ok(Err(position.elevation_deg()));
        }
        let sun = sun_direction(position, site.north)?.to_array();
        Ok(Ok(SkyPhoto {
            time,
            site,
            position,
            sun,
        }))
    }

    fn clear_sky(&self, turbidity: f64) -> Result<Sky, WorkflowError> {
        Ok(Sky::new(
            turbidity,
            [GROUND_ALBEDO; 3],
            DVec3::from_array(self.sun),
        )?)
    }

    /// The lighting of `params`.
    pub fn lighting(&self, params: &SkyParams) -> Result<Lighting, WorkflowError> {
        let (map, sun) = self.map_and_sun(params)?;
        let environment = Some(Environment::from_image(&map, 1.0)?);
        let sun = match sun {
            Some(s) => Some(Sun::new(
                Vec3::from_array(s.direction.map(|x| x as f32)),
                Vec3::from_array(s.radiance.map(|x| x as f32)),
                s.angular_diameter_deg as f32,
            )?),
            None => None,
        };
        Ok(Lighting { environment, sun })
    }

    /// The sky map and the sun's section of `params`.
    fn map_and_sun(
        &self,
        params: &SkyParams,
    ) -> Result<(HdrImage, Option<igi_formats::lighting::SunSection>), WorkflowError> {
        let sky = self.clear_sky(params.turbidity)?;
        let (w, h) = (MAP_WIDTH, MAP_WIDTH / 2);
        let mut map = sky.latlong(w, h)?;
        let overcast = CieOvercast::new([1.0; 3])?.latlong(w, h)?;
        for (p, o) in map.pixels.iter_mut().zip(&overcast.pixels) {
            for c in 0..3 {
                p[c] =
                    (params.sky_scale * p[c] as f64 + params.overcast_scale * o[c] as f64) as f32;
            }
        }
        let sun = (params.sun_scale > 0.0).then(|| {
            let mut s = sky.sun_disk().to_section();
            for c in 0..3 {
                s.radiance[c] *= params.sun_scale * params.sun_colour[c];
            }
            s
        });
        Ok((map, sun))
    }

    /// Writes the lighting of `params` as a contract lighting file `dir/ID.toml` with its map
    /// `dir/ID.exr` (each atomically).
    pub fn write_lighting(
        &self,
        dir: &Path,
        id: &str,
        params: &SkyParams,
    ) -> Result<(), WorkflowError> {
        let (map, sun) = self.map_and_sun(params)?;
        let map_name = format!("{id}.exr");
        igi_imaging::io::write_exr(&dir.join(&map_name), &map)?;
        let file = LightingFile {
            environment: Some(EnvironmentSection {
                map: map_name.into(),
                scale: 1.0,
            }),
            sun,
        };
        let header = format!(
            "estimated by igi solve for photo {id} at {}: Hosek-Wilkie turbidity {:.3}, sun scale {:.6} colour {:.4?}, sky scale {:.6}, CIE overcast zenith {:.6}; sun azimuth {:.4} deg, elevation {:.4} deg",
            self.time.to_rfc3339(),
            params.turbidity,
            params.sun_scale,
            params.sun_colour,
            params.sky_scale,
            params.overcast_scale,
            self.position.azimuth_deg,
            self.position.elevation_deg()
        );
        file.write(&dir.join(format!("{id}.toml")), &[&header])?;
        Ok(())
    }
}

/// The sky parameters of one photo.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct SkyParams {
    /// Hosek-Wilkie turbidity (1-10).
    pub turbidity: f64,
    /// The sun disk's radiance over the model's (transmission through cloud and haze).
    pub sun_scale: f64,
    /// Per channel factor of the sun's radiance, mean 1.
    #[serde(default = "white")]
    pub sun_colour: [f64; 3],
    /// The clear sky's radiance over the model's.
    pub sky_scale: f64,
    /// The zenith radiance of an added CIE overcast sky.
    pub overcast_scale: f64,
}

impl Default for SkyParams {
    fn default() -> Self {
        SkyParams {
            turbidity: DEFAULT_TURBIDITY,
            sun_scale: 1.0,
            sun_colour: [1.0; 3],
            sky_scale: 1.0,
            overcast_scale: 0.0,
        }
    }
}

fn white() -> [f64; 3] {
    [1.0; 3]
}

/// Unknowns of the fit: the sun per channel, the clear sky, the overcast sky.
const N: usize = 5;
type Mat = [[f64; N]; N];

/// How the scales are fitted.
#[derive(Clone, Debug)]
pub struct FitOptions {
    /// Indirect bounces of the light transport (the solve's).
    pub indirect: u32,
    /// The turbidities tried.
    pub turbidities: Vec<f64>,
    /// Fit an added CIE overcast sky.
    pub overcast: bool,
    /// Tie the sun's three channels to the model's colour (one sun unknown, `sun_colour`
    /// white); otherwise each channel's sun is free. Tied, the albedo with estimated light on
    /// the Mitsuba survey comes within 1.15x, 1.13x, 1.23x of the true-lighting solve's error
    /// (r, g, b), against 1.32x, 1.25x, 2.08x free (docs/SKY.md).
    pub tie_sun_colour: bool,
    /// Seeds the light transport's rays ([`crate::lightbasis`]).
    pub seed: u64,
}

impl Default for FitOptions {
    fn default() -> Self {
        FitOptions {
            indirect: 2,
            turbidities: vec![2.0, 3.0, 4.5],
            overcast: true,
            tie_sun_colour: true,
            seed: 34,
        }
    }
}

/// One photo's fitted sky.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct PhotoFit {
    pub photo: String,
    pub time: String,
    pub sun_azimuth_deg: f64,
    pub sun_elevation_deg: f64,
    pub sun_direction: [f64; 3],
    pub params: SkyParams,
    /// Standard errors of `params` (the turbidity's from the curvature of the residual over
    /// the grid, 0 when the grid has one value or the minimum lies on its edge).
    pub stderr: SkyParams,
    /// Pixels used (valid and seeing the site).
    pub pixels: usize,
    /// RMS of the relative residual at the fit.
    pub relative_rms: f64,
    /// The fitted exposure factor of the photo's camera body (1 for the first body): the
    /// photograph is `body_exposure` times the site under `params` (docs/SKY.md, "Camera
    /// bodies").
    #[serde(default = "one")]
    pub body_exposure: f64,
}

fn one() -> f64 {
    1.0
}

impl PhotoFit {
    /// The light as the photograph saw it: the fitted sky times its body's exposure factor.
    pub fn seen(&self) -> SkyParams {
        let k = self.body_exposure;
        SkyParams {
            sun_scale: self.params.sun_scale * k,
            sky_scale: self.params.sky_scale * k,
            overcast_scale: self.params.overcast_scale * k,
            ..self.params
        }
    }
}

/// The record of the estimation in `report.json` (`lighting`).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct LightingRecord {
    /// Whether `[[reference]]` targets fixed the global scale; otherwise the albedo (and every
    /// scale) is known only up to one factor.
    pub absolute_scale: bool,
    /// The factor the last gauge step multiplied the fitted light scales by (and divided the
    /// albedo by): the reference's albedo over the solved one, or without a reference the one
    /// that made the mean sun scale 1.
    pub gauge: f64,
    /// The reference targets' solved albedo over their known albedo before the gauge (one
    /// value per target seen).
    pub reference_ratio: Vec<f64>,
    /// Rounds of lighting estimation done (one after each albedo iteration).
    pub rounds: u32,
    pub photos: Vec<PhotoFit>,
}

/// The scene a fit renders: the parts with the current albedo.
pub fn scene_of(state: &SolveResult) -> Result<Scene, WorkflowError> {
    Ok(state.albedo_scene()?)
}

/// The light transport a round of the fit reads, traced once (on the first round, and again
/// only when the parts change, as between a coarse and a fine stage): the site's texels'
/// hemisphere rays, and per estimated photo what its pixels see and the sun's visibility at
/// every texel ([`crate::lightbasis`]).
struct Bases {
    /// The parts' names and atlas resolutions the bases were traced for.
    key: Vec<(String, usize)>,
    transport: Transport,
    /// Per photo (the photos' order), for a photo whose light is estimated.
    photos: Vec<Option<PhotoBasis>>,
}

/// One estimated photo's bases.
struct PhotoBasis {
    texels: PhotoTexels,
    /// The direct irradiance at every texel of the photo's sun as a white disk of unit
    /// radiance.
    sun: Vec<f32>,
}

impl Bases {
    /// The bases of `state`'s parts: `current` when traced for the same parts, else traced
    /// now.
    fn update(
        current: Option<Bases>,
        state: &SolveResult,
        photos: &[igi_reflect::Photo],
        sky: &[Option<SkyPhoto>],
        opts: &FitOptions,
    ) -> Result<Bases, WorkflowError> {
        let key: Vec<(String, usize)> = state
            .parts
            .iter()
            .map(|p| (p.part.name.clone(), p.resolution()))
            .collect();
        if let Some(b) = current.filter(|b| b.key == key) {
            return Ok(b);
        }
        check_memory(state, photos, sky)?;
        let t0 = std::time::Instant::now();
        let scene = scene_of(state)?;
        let transport = Transport::new(state, &scene, opts.seed);
        let diameter = 2.0 * igi_sky::SUN_ANGULAR_RADIUS_DEG;
        let photos = photos
            .iter()
            .zip(sky)
            .enumerate()
            .map(|(i, (photo, s))| {
                s.as_ref().map(|s| {
                    let sun = SunDisk::new(Vec3::from_array(s.sun.map(|x| x as f32)), diameter);
                    let seed = opts.seed.wrapping_add(1 + 2 * i as u64);
                    PhotoBasis {
                        texels: transport.photo(&scene, &photo.camera, &photo.image, &sun, seed),
                        sun: transport.sun(&scene, &sun, seed.wrapping_add(1)),
                    }
                })
            })
            .collect();
        tracing::info!(
            "lighting estimation: light transport of {} texels ({} under another surface) traced in {:.1} s ({:.1} MB, {:.2} % of the rays dark)",
            transport.len(),
            transport.buried(),
            t0.elapsed().as_secs_f64(),
            transport.bytes() as f64 / 1e6,
            100.0 * transport.dark_fraction()
        );
        Ok(Bases {
            key,
            transport,
            photos,
        })
    }
}

/// Refuses bases whose memory ([`crate::lightbasis::memory`]) is above the limit
/// (`IGI_MAX_MEMORY`, 8 GiB by default), before they are traced.
fn check_memory(
    state: &SolveResult,
    photos: &[igi_reflect::Photo],
    sky: &[Option<SkyPhoto>],
) -> Result<(), WorkflowError> {
    let texels: u128 = state
        .parts
        .iter()
        .map(|p| p.part.cache.texels.len() as u128)
        .sum();
    let pixels: Vec<u128> = photos
        .iter()
        .zip(sky)
        .filter(|(_, s)| s.is_some())
        .map(|(p, _)| p.image.pixels.len() as u128)
        .collect();
    let what = format!(
        "the lighting estimation's light transport of {texels} texels and {} photographs",
        pixels.len()
    );
    igi_files::check_alloc_default(&what, crate::lightbasis::memory(texels, &pixels))?;
    Ok(())
}

/// A light of the fit's model in one round: the irradiance it gives every texel on the
/// current albedo (direct and bounced), and its sky bins.
struct Basis {
    irradiance: Vec<Vec3>,
    bins: Vec<Vec3>,
}

impl Basis {
    /// A sky map's basis.
    fn sky(t: &Transport, map: &HdrImage, rho: &[Vec3], bounces: u32) -> Basis {
        let bins = sky_bins(map);
        Basis {
            irradiance: t.bounced(t.sky(&bins), rho, bounces),
            bins,
        }
    }

    /// The radiance of every pixel of a photo under this light (`atlases` the parts'
    /// albedo).
    fn pixels(&self, t: &Transport, px: &PhotoTexels, atlases: &[Texture]) -> Vec<Vec3> {
        t.radiance(px, atlases, &self.irradiance, &self.bins)
    }
}

/// One photo's fit and the photo re-rendered under it.
pub struct Fitted {
    pub fit: PhotoFit,
    /// The photograph re-rendered under the fitted sky from the bases: the fitted combination
    /// of the basis images (light transport is linear in the light), so over the site's pixels
    /// its relative residual against the photograph is the fit's.
    pub render: HdrImage,
}

/// What a round's fits read: the transport, the current albedo (of every texel, and as the
/// parts' atlases) and the overcast sky's basis of the round.
struct RoundInputs<'a> {
    transport: &'a Transport,
    rho: &'a [Vec3],
    atlases: &'a [Texture],
    overcast: Option<&'a Basis>,
}

/// One photo of a group prepared for the fit: its pixels that see the site with their
/// values, the weights' floor, and its radiance under the sun and the overcast sky.
struct PhotoData<'a> {
    /// Its body's exposure factor, which its pixels were divided by.
    exposure: f64,
    id: &'a str,
    image: &'a HdrImage,
    texels: &'a PhotoTexels,
    obs: Vec<[f64; 3]>,
    /// Relative weights divide a residual by its pixel's value, at least this (5 % of the
    /// mean).
    floor: f64,
    r_sun: Vec<Vec3>,
    r_ovc: Option<Vec<Vec3>>,
}

impl<'a> PhotoData<'a> {
    /// The photo's data with its pixels divided by its body's exposure factor `exposure` (on
    /// the first body's scale).
    fn new(
        r: &RoundInputs,
        id: &'a str,
        image: &'a HdrImage,
        basis: &'a PhotoBasis,
        bounces: u32,
        exposure: f64,
    ) -> PhotoData<'a> {
        let (tr, px) = (r.transport, &basis.texels);
        let sun_direct: Vec<Vec3> = basis.sun.iter().map(|&v| Vec3::splat(v)).collect();
        let sun_e = tr.bounced(sun_direct, r.rho, bounces);
        let obs: Vec<[f64; 3]> = px
            .site
            .iter()
            .map(|&i| image.pixels[i].map(|c| c as f64 / exposure))
            .collect();
        let mean =
            obs.iter().map(|p| p.iter().sum::<f64>()).sum::<f64>() / (3 * obs.len().max(1)) as f64;
        PhotoData {
            exposure,
            id,
            image,
            texels: px,
            obs,
            floor: (0.05 * mean).max(1e-12),
            r_sun: tr.sun_radiance(px, r.atlases, &sun_e, &basis.sun),
            r_ovc: r.overcast.map(|b| b.pixels(tr, px, r.atlases)),
        }
    }

    /// The normal equations of the photo's pixels and channels (relative weights) with the
    /// clear sky's image `r_sky` and the sun disk's radiance `sun_rad`.
    fn normal(&self, r_sky: &[Vec3], sun_rad: [f64; 3], tie_sun_colour: bool) -> Normal {
        let mut n = Normal::default();
        for (j, &i) in self.texels.site.iter().enumerate() {
            for c in 0..3 {
                let b = self.obs[j][c];
                let wt = 1.0 / b.max(self.floor).powi(2);
                let mut a = [0.0; N];
                a[if tie_sun_colour { 0 } else { c }] = self.r_sun[i][c] as f64 * sun_rad[c];
                a[3] = r_sky[i][c] as f64;
                a[4] = self.r_ovc.as_ref().map_or(0.0, |r| r[i][c] as f64);
                for p in 0..N {
                    n.atb[p] += wt * a[p] * b;
                    for q in 0..N {
                        n.ata[p][q] += wt * a[p] * a[q];
                    }
                }
                n.btb += wt * b * b;
            }
        }
        n.rows = 3 * self.texels.site.len();
        n
    }

    /// The photograph re-rendered under the scales `x` (the sun's per channel), in the
    /// photograph's own units (times its body's exposure factor).
    fn model(&self, x: &[f64; N], sun_rad: [f64; 3], r_sky: &[Vec3]) -> HdrImage {
        let mut model = HdrImage::new(self.image.width, self.image.height);
        for (i, m) in model.pixels.iter_mut().enumerate() {
            for (c, v) in m.iter_mut().enumerate() {
                let o = self.r_ovc.as_ref().map_or(0.0, |r| r[i][c] as f64);
                *v = (self.exposure
                    * (x[c] * sun_rad[c] * self.r_sun[i][c] as f64
                        + x[3] * r_sky[i][c] as f64
                        + x[4] * o)) as f32;
            }
        }
        model
    }
}

/// Weighted normal equations: `A^T W A`, `A^T W b`, `b^T W b`, and the rows summed.
#[derive(Clone, Debug, Default)]
struct Normal {
    ata: Mat,
    atb: [f64; N],
    btb: f64,
    rows: usize,
}

impl Normal {
    fn add(&mut self, o: &Normal) {
        for p in 0..N {
            self.atb[p] += o.atb[p];
            for q in 0..N {
                self.ata[p][q] += o.ata[p][q];
            }
        }
        self.btb += o.btb;
        self.rows += o.rows;
    }

    /// The weighted sum of squared residuals at `x`.
    fn sse(&self, x: &[f64; N]) -> f64 {
        let quad: f64 = (0..N)
            .map(|p| x[p] * (0..N).map(|q| self.ata[p][q] * x[q]).sum::<f64>())
            .sum();
        let lin: f64 = (0..N).map(|p| x[p] * self.atb[p]).sum();
        (self.btb - 2.0 * lin + quad).max(0.0)
    }
}

/// Fits the sky shared by a group of photos taken at one time (`sky`) with the albedo fixed:
/// their pixels' normal equations summed, per turbidity of the grid.
fn fit_group(
    r: &RoundInputs,
    group: &[PhotoData],
    sky: &SkyPhoto,
    opts: &FitOptions,
) -> Result<Vec<Fitted>, WorkflowError> {
    let (w, h) = (MAP_WIDTH, MAP_WIDTH / 2);
    let overcast = r.overcast.is_some();
    let mut best: Option<Candidate> = None;
    let mut curve = Vec::new();
    for &t in &opts.turbidities {
        let clear = sky.clear_sky(t)?;
        let sun_rad = clear.sun_disk().radiance;
        let basis = Basis::sky(r.transport, &clear.latlong(w, h)?, r.rho, opts.indirect);
        let r_sky: Vec<Vec<Vec3>> = group
            .iter()
            .map(|d| basis.pixels(r.transport, d.texels, r.atlases))
            .collect();
        let normals: Vec<Normal> = group
            .iter()
            .zip(&r_sky)
            .map(|(d, rs)| d.normal(rs, sun_rad, opts.tie_sun_colour))
            .collect();
        let mut all = Normal::default();
        normals.iter().for_each(|n| all.add(n));
        let (x, sse, active) = solve_sky(&all, overcast, opts.tie_sun_colour);
        curve.push((t, sse));
        if best.as_ref().is_none_or(|b| sse < b.sse) {
            best = Some(Candidate {
                turbidity: t,
                sse,
                x,
                cov: covariance(&all.ata, &active),
                rows: all.rows,
                normals,
                r_sky,
                sun_rad,
            });
        }
    }
    let best = best.ok_or_else(|| {
        WorkflowError::Arguments("lighting estimation: no turbidity to try".into())
    })?;
    let t_se = turbidity_stderr(&curve, best.turbidity, best.s2());
    let (params, stderr) = best.params(t_se, opts.tie_sun_colour);
    Ok(group
        .iter()
        .enumerate()
        .map(|(k, d)| {
            let x = params_vector(&params);
            let fit = PhotoFit {
                photo: d.id.to_string(),
                time: sky.time.to_rfc3339(),
                sun_azimuth_deg: sky.position.azimuth_deg,
                sun_elevation_deg: sky.position.elevation_deg(),
                sun_direction: sky.sun,
                params,
                stderr,
                pixels: d.texels.site.len(),
                relative_rms: (best.normals[k].sse(&x) / best.normals[k].rows.max(1) as f64).sqrt(),
                body_exposure: d.exposure,
            };
            let render = d.model(&x, best.sun_rad, &best.r_sky[k]);
            Fitted { fit, render }
        })
        .collect())
}

/// The non-negative fit of the sky's scales: a sunny sky (sun and clear sky) or an overcast
/// one (clear and overcast skies, no sun), whichever fits better (both domes with a sun
/// confound the two smooth skies). The scales, the residual and the active set.
fn solve_sky(n: &Normal, overcast: bool, tie_sun_colour: bool) -> ([f64; N], f64, Vec<usize>) {
    let sunny_set = if tie_sun_colour { 0b01001 } else { 0b01111 };
    let sunny = nnls(&n.ata, &n.atb, n.btb, sunny_set);
    if !overcast {
        return sunny;
    }
    let cloudy = nnls(&n.ata, &n.atb, n.btb, 0b11000);
    if cloudy.1 < sunny.1 {
        cloudy
    } else {
        sunny
    }
}

/// The scales of `p` as the fit's unknowns (the sun's per channel).
fn params_vector(p: &SkyParams) -> [f64; N] {
    let s = |c: usize| p.sun_scale * p.sun_colour[c];
    [s(0), s(1), s(2), p.sky_scale, p.overcast_scale]
}

/// The best fit so far over the turbidity grid.
struct Candidate {
    turbidity: f64,
    /// Weighted sum of squared residuals.
    sse: f64,
    x: [f64; N],
    /// Inverse normal matrix on the active set.
    cov: Mat,
    /// Residuals (pixels x channels).
    rows: usize,
    /// Per photo of the group: its normal equations and its clear sky's image.
    normals: Vec<Normal>,
    r_sky: Vec<Vec<Vec3>>,
    /// The Hosek-Wilkie sun disk's radiance at this turbidity.
    sun_rad: [f64; 3],
}

impl Candidate {
    /// The residual variance.
    fn s2(&self) -> f64 {
        self.sse / self.rows.saturating_sub(3).max(1) as f64
    }

    /// The fitted parameters and their standard errors (the turbidity's `t_se`).
    fn params(&self, t_se: f64, tie_sun_colour: bool) -> (SkyParams, SkyParams) {
        let s2 = self.s2();
        let (mut x, mut cov) = (self.x, self.cov);
        if tie_sun_colour {
            // the three channels are one unknown
            x[1] = x[0];
            x[2] = x[0];
            let row = cov[0];
            cov[1..3].fill(row);
            for r in cov.iter_mut() {
                r[1] = r[0];
                r[2] = r[0];
            }
        }
        let se = |k: usize| (s2 * cov[k][k]).max(0.0).sqrt();
        let sun = (x[0] + x[1] + x[2]) / 3.0;
        let sun_var: f64 = (0..3)
            .flat_map(|p| (0..3).map(move |q| (p, q)))
            .map(|(p, q)| cov[p][q])
            .sum::<f64>()
            / 9.0;
        let colour = |c: usize| if sun > 0.0 { x[c] / sun } else { 1.0 };
        let colour_se = |c: usize| if sun > 0.0 { se(c) / sun } else { 0.0 };
        let params = SkyParams {
            turbidity: self.turbidity,
            sun_scale: sun,
            sun_colour: [colour(0), colour(1), colour(2)],
            sky_scale: x[3],
            overcast_scale: x[4],
        };
        let stderr = SkyParams {
            turbidity: t_se,
            sun_scale: (s2 * sun_var).max(0.0).sqrt(),
            sun_colour: [colour_se(0), colour_se(1), colour_se(2)],
            sky_scale: se(3),
            overcast_scale: se(4),
        };
        (params, stderr)
    }
}

/// The standard error of the turbidity from a parabola through the residuals at the grid
/// minimum and its neighbours (`sse(T) ~ sse_min + (T - T0)^2 / (2 sigma^2 var_T)`); 0 on the
/// grid's edge.
fn turbidity_stderr(curve: &[(f64, f64)], t: f64, s2: f64) -> f64 {
    let Some(k) = curve.iter().position(|c| c.0 == t) else {
        return 0.0;
    };
    if k == 0 || k + 1 >= curve.len() {
        return 0.0;
    }
    let (x0, y0) = curve[k - 1];
    let (x1, y1) = curve[k];
    let (x2, y2) = curve[k + 1];
    // second derivative of the parabola through three points
    let d2 = 2.0 * ((y2 - y1) / (x2 - x1) - (y1 - y0) / (x1 - x0)) / (x2 - x0);
    if d2 > 0.0 {
        (2.0 * s2 / d2).sqrt()
    } else {
        0.0
    }
}

/// Solves `ata x = atb` restricted to the set `active` (others zero).
fn solve_subset(ata: &Mat, atb: &[f64; N], active: &[usize]) -> Option<[f64; N]> {
    let m = active.len();
    let mut a = [[0.0f64; N + 1]; N];
    for (r, &p) in active.iter().enumerate() {
        for (c, &q) in active.iter().enumerate() {
            a[r][c] = ata[p][q];
        }
        a[r][m] = atb[p];
    }
    // Gauss-Jordan with partial pivoting
    for col in 0..m {
        let piv = (col..m).max_by(|&i, &j| a[i][col].abs().total_cmp(&a[j][col].abs()))?;
        if a[piv][col].abs() < 1e-300 {
            return None;
        }
        a.swap(col, piv);
        for r in 0..m {
            if r != col {
                let f = a[r][col] / a[col][col];
                for c in col..=m {
                    a[r][c] -= f * a[col][c];
                }
            }
        }
    }
    let mut x = [0.0; N];
    for (r, &p) in active.iter().enumerate() {
        x[p] = a[r][m] / a[r][r];
    }
    x.iter().all(|v| v.is_finite()).then_some(x)
}

/// Non-negative least squares of the unknowns in `allowed` (a bit mask) from the normal
/// equations, by trying every subset: `(x, sum of squared residuals, active set)`.
fn nnls(ata: &Mat, atb: &[f64; N], btb: f64, allowed: u32) -> ([f64; N], f64, Vec<usize>) {
    let mut best = ([0.0; N], btb, Vec::new());
    for mask in 1u32..(1 << N) {
        if mask & !allowed != 0 {
            continue;
        }
        let active: Vec<usize> = (0..N).filter(|&p| mask & (1 << p) != 0).collect();
        let Some(x) = solve_subset(ata, atb, &active) else {
            continue;
        };
        if active.iter().any(|&p| x[p] < 0.0) {
            continue;
        }
        // sse = b'b - 2 x'A'b + x'A'A x
        let mut sse = btb;
        for p in 0..N {
            sse -= 2.0 * x[p] * atb[p];
            for q in 0..N {
                sse += x[p] * ata[p][q] * x[q];
            }
        }
        let sse = sse.max(0.0);
        if sse < best.1 {
            best = (x, sse, active);
        }
    }
    best
}

/// The inverse of `ata` restricted to `active` (zero elsewhere).
fn covariance(ata: &Mat, active: &[usize]) -> Mat {
    let mut cov = [[0.0; N]; N];
    for &p in active {
        let mut e = [0.0; N];
        e[p] = 1.0;
        if let Some(col) = solve_subset(ata, &e, active) {
            for &q in active {
                cov[q][p] = col[q];
            }
        }
    }
    cov
}

/// The solved albedo over a reference target's disc (mean over its seen texels, within 0.8 of
/// the radius, on a surface facing the disc's normal, at most 5 cm off its plane) against its
/// known albedo: the mean over channels of the ratio, or `None` when no texel of it is seen.
pub fn reference_ratio(state: &SolveResult, r: &ReferenceTarget) -> Option<f64> {
    let c = DVec3::from_array(r.center);
    let n = DVec3::from_array(r.normal).normalize_or_zero();
    let mut sum = DVec3::ZERO;
    let mut count = 0usize;
    for part in &state.parts {
        for t in &part.part.cache.texels {
            let i = t.index as usize;
            if part.observations[i] == 0 {
                continue;
            }
            let p = t.position.as_dvec3() - c;
            let off = p.dot(n);
            if off.abs() > 0.05 || (p - off * n).length() > 0.8 * r.radius {
                continue;
            }
            if t.normal.as_dvec3().dot(n) < 0.9 {
                continue;
            }
            sum += part.rho[i].as_dvec3();
            count += 1;
        }
    }
    (count > 0).then(|| {
        let m = sum / count as f64;
        (m.x / r.albedo[0].max(1e-9) + m.y / r.albedo[1].max(1e-9) + m.z / r.albedo[2].max(1e-9))
            / 3.0
    })
}

/// An albedo divided by the gauge `g`, kept at most 1 as the solver keeps it (a gauge below 1
/// would lift a texel solved at 1 above it, which no scene may hold).
fn regauged(rho: Vec3, g: f32) -> Vec3 {
    (rho / g).min(Vec3::ONE)
}

/// Fixes the global scale: with references, the albedo is divided (and the light scales
/// multiplied) by the mean solved-over-known ratio of the seen targets; without, by the factor
/// that makes the mean sun scale of the photos with sun 1 (`regauged`: the albedo stays at
/// most 1). Returns (gauge, ratios).
pub fn apply_gauge(
    state: &mut SolveResult,
    fits: &mut [PhotoFit],
    references: &[ReferenceTarget],
) -> (f64, Vec<f64>) {
    let ratios: Vec<f64> = references
        .iter()
        .filter_map(|r| reference_ratio(state, r))
        .collect();
    let gauge = if !ratios.is_empty() {
        ratios.iter().sum::<f64>() / ratios.len() as f64
    } else {
        let suns: Vec<f64> = fits
            .iter()
            .map(|f| f.params.sun_scale)
            .filter(|&s| s > 0.0)
            .collect();
        if suns.is_empty() {
            1.0
        } else {
            suns.len() as f64 / suns.iter().sum::<f64>()
        }
    };
    if !(gauge.is_finite() && gauge > 0.0) {
        return (1.0, ratios);
    }
    let g = gauge as f32;
    for p in &mut state.parts {
        p.rho.iter_mut().for_each(|v| *v = regauged(*v, g));
        p.stderr
            .iter_mut()
            .filter(|v| v.x >= 0.0)
            .for_each(|v| *v /= g);
    }
    for f in fits.iter_mut() {
        for p in [&mut f.params, &mut f.stderr] {
            p.sun_scale *= gauge;
            p.sky_scale *= gauge;
            p.overcast_scale *= gauge;
        }
    }
    (gauge, ratios)
}

/// What the alternation of albedo iterations and lighting fits reads.
pub struct Estimation<'a> {
    /// Per photo (the photos' order): the sun and site of a photo whose light is estimated.
    pub sky: &'a [Option<SkyPhoto>],
    /// Per photo: the camera body that took it (photos of one body share an exposure factor).
    pub bodies: &'a [Option<String>],
    /// The survey's `[[reference]]` targets.
    pub references: &'a [ReferenceTarget],
    pub basis: Option<&'a igi_brdf::Basis>,
    pub truth: Option<&'a igi_reflect::solver::Truth>,
    pub options: &'a igi_reflect::SolveOptions,
    /// The result folder: checkpoints, and the lighting files in `lighting/`.
    pub output: &'a Path,
}

/// Iterates to the end with photos whose light is estimated: each albedo iteration is followed
/// by a round of the lighting fit, and the photos' lighting is replaced by the fitted one; the
/// solve is converged when the albedo is and the round moved no photo's light by more than
/// [`LIGHT_TOLERANCE`];
/// a checkpoint after each step, the lighting files in `RESULT/lighting/`, the record in
/// `report.json` (`lighting`). A resumed result's photos get the lighting its report recorded.
pub fn iterate(
    mut state: SolveResult,
    photos: &mut [igi_reflect::Photo],
    e: &Estimation,
    progress: &dyn igi_reflect::Progress,
) -> Result<SolveResult, WorkflowError> {
    restore_lighting(&state, photos, e.sky)?;
    let out = e.output;
    let mut bases = None;
    for k in state.report.iterations.len() as u32..e.options.max_iterations {
        let opts = igi_reflect::SolveOptions {
            max_iterations: k + 1,
            ..e.options.clone()
        };
        state = igi_reflect::solve(state, photos, e.basis, e.truth, &opts, progress, &mut |r| {
            r.write_state(out)
        })?;
        if (state.report.iterations.len() as u32) < k + 1 {
            break;
        }
        let converged = state.report.converged;
        let before = recorded(&state);
        let (record, renders) =
            estimate_round(&mut state, photos, e, k + 1, before.as_ref(), &mut bases)?;
        let moved = before.map_or(f64::INFINITY, |b| light_change(&b, &record));
        write_lighting_files(out, photos, e.sky, &record, &renders)?;
        state.report.lighting = Some(
            serde_json::to_value(&record)
                .map_err(|err| WorkflowError::Arguments(format!("lighting record: {err}")))?,
        );
        // the albedo moved with the gauge; while the light moves, the albedo under it is not
        // converged
        state.set_changed(true);
        state.report.converged = converged && moved <= LIGHT_TOLERANCE;
        state.write_state(out)?;
        if state.report.converged {
            break;
        }
    }
    Ok(state)
}

/// The largest change of a photo's light between two rounds below which the light is settled:
/// the summed change of its sun, sky and overcast scales over their sum (any change of
/// turbidity counts as unsettled).
pub const LIGHT_TOLERANCE: f64 = 0.01;

/// The lighting record of the result's report, if any.
fn recorded(state: &SolveResult) -> Option<LightingRecord> {
    serde_json::from_value(state.report.lighting.clone()?).ok()
}

/// How far the light moved between two rounds' records: the largest over the photos of the
/// summed change of the sun, sky and overcast scales over their sum before (infinite for a
/// photo whose turbidity changed or that one record lacks).
fn light_change(before: &LightingRecord, after: &LightingRecord) -> f64 {
    after
        .photos
        .iter()
        .map(|a| {
            let Some(b) = before.photos.iter().find(|b| b.photo == a.photo) else {
                return f64::INFINITY;
            };
            let (p, q) = (&b.params, &a.params);
            if p.turbidity != q.turbidity {
                return f64::INFINITY;
            }
            let d = (p.sun_scale - q.sun_scale).abs()
                + (p.sky_scale - q.sky_scale).abs()
                + (p.overcast_scale - q.overcast_scale).abs();
            d / (p.sun_scale + p.sky_scale + p.overcast_scale).max(1e-12)
        })
        .fold(0.0, f64::max)
}

/// A resumed solve's photos get the lighting its report recorded.
fn restore_lighting(
    state: &SolveResult,
    photos: &mut [igi_reflect::Photo],
    sky: &[Option<SkyPhoto>],
) -> Result<(), WorkflowError> {
    let Some(record) = recorded(state) else {
        return Ok(());
    };
    for (photo, sky) in photos.iter_mut().zip(sky) {
        if let (Some(sky), Some(f)) = (sky, record.photos.iter().find(|f| f.photo == photo.id)) {
            photo.lighting = sky.lighting(&f.seen())?;
        }
    }
    Ok(())
}

/// One round of the lighting fit after albedo iteration `round`: every estimated photo's sky
/// fitted with the albedo fixed, the global scale fixed, the photos' lighting replaced (the
/// camera bodies' factors start from the `last` round's record); the record and each fitted
/// photo's re-rendering (by photo id).
fn estimate_round(
    state: &mut SolveResult,
    photos: &mut [igi_reflect::Photo],
    e: &Estimation,
    round: u32,
    last: Option<&LightingRecord>,
    bases: &mut Option<Bases>,
) -> Result<(LightingRecord, Renders), WorkflowError> {
    let t0 = std::time::Instant::now();
    let fo = FitOptions {
        indirect: e.options.indirect,
        ..FitOptions::default()
    };
    let b = Bases::update(bases.take(), state, photos, e.sky, &fo)?;
    let rho = b.transport.albedo(state);
    let atlases = state.albedo_textures();
    let overcast = if fo.overcast {
        let (w, h) = (MAP_WIDTH, MAP_WIDTH / 2);
        let map = CieOvercast::new([1.0; 3])?.latlong(w, h)?;
        Some(Basis::sky(&b.transport, &map, &rho, fo.indirect))
    } else {
        None
    };
    let inputs = RoundInputs {
        transport: &b.transport,
        rho: &rho,
        atlases: &atlases,
        overcast: overcast.as_ref(),
    };
    let bodies = Bodies::new(e.bodies, e.sky, last, photos);
    let passes = if bodies.count() > 1 { BODY_PASSES } else { 1 };
    let (mut fits, mut renders) = (Vec::new(), Vec::new());
    let mut exposure = bodies.start.clone();
    for _ in 0..passes {
        (fits, renders) = fit_round(&inputs, &b, photos, e.sky, &bodies, &exposure, &fo)?;
        exposure = bodies.refit(&exposure, photos, &b, &fits, &renders);
    }
    // in the photos' order
    let order = |id: &str| photos.iter().position(|p| p.id == id);
    fits.sort_by_key(|f| order(&f.photo));
    *bases = Some(b);
    let (gauge, reference_ratio) = apply_gauge(state, &mut fits, e.references);
    for (photo, s) in photos.iter_mut().zip(e.sky) {
        if let (Some(s), Some(f)) = (s, fits.iter().find(|f| f.photo == photo.id)) {
            photo.lighting = s.lighting(&f.seen())?;
        }
    }
    for f in &fits {
        tracing::info!(
            "lighting round {round}: photo {}: turbidity {}, sun scale {:.4} +- {:.4}, sky scale {:.4} +- {:.4}, overcast {:.4} +- {:.4} ({} pixels, relative RMS {:.3})",
            f.photo,
            f.params.turbidity,
            f.params.sun_scale,
            f.stderr.sun_scale,
            f.params.sky_scale,
            f.stderr.sky_scale,
            f.params.overcast_scale,
            f.stderr.overcast_scale,
            f.pixels,
            f.relative_rms
        );
    }
    tracing::info!(
        "lighting round {round}: gauge {gauge:.5} ({}), {:.1} s",
        if reference_ratio.is_empty() {
            "no reference target: the albedo is known up to one scale"
        } else {
            "from the reference targets"
        },
        t0.elapsed().as_secs_f64()
    );
    Ok((
        LightingRecord {
            absolute_scale: !reference_ratio.is_empty(),
            gauge,
            reference_ratio,
            rounds: round,
            photos: fits,
        },
        renders,
    ))
}

/// Each fitted photo's re-rendering, by photo id.
type Renders = Vec<(String, HdrImage)>;

/// Passes of the sky fit and the camera bodies' exposure factors per round when there are
/// several bodies (each round starts from the last round's factors).
const BODY_PASSES: usize = 3;

/// Every time group's sky fitted once, each photo's pixels divided by its body's factor in
/// `exposure`: the fits and the re-renderings (by photo id).
fn fit_round(
    inputs: &RoundInputs,
    b: &Bases,
    photos: &[igi_reflect::Photo],
    sky: &[Option<SkyPhoto>],
    bodies: &Bodies,
    exposure: &[f64],
    fo: &FitOptions,
) -> Result<(Vec<PhotoFit>, Renders), WorkflowError> {
    let (mut fits, mut renders) = (Vec::new(), Vec::new());
    for group in time_groups(sky) {
        let data: Vec<PhotoData> = group
            .iter()
            .filter_map(|&i| {
                let pb = b.photos[i].as_ref()?;
                let (p, k) = (&photos[i], exposure[bodies.of[i]]);
                Some(PhotoData::new(inputs, &p.id, &p.image, pb, fo.indirect, k))
            })
            .collect();
        let Some(s) = sky[group[0]].as_ref() else {
            continue;
        };
        for f in fit_group(inputs, &data, s, fo)? {
            renders.push((f.fit.photo.clone(), f.render));
            fits.push(f.fit);
        }
    }
    Ok((fits, renders))
}

/// The camera bodies of the estimated photos: the first body met is the reference (factor
/// 1); each other body's exposure factor is fitted, photos of one time tying it to the others.
struct Bodies {
    /// Per photo: its body's index (0 for a photo whose light is not estimated).
    of: Vec<usize>,
    count: usize,
    /// The factors the round starts from: the last round's, else 1.
    start: Vec<f64>,
}

impl Bodies {
    fn new(
        bodies: &[Option<String>],
        sky: &[Option<SkyPhoto>],
        last: Option<&LightingRecord>,
        photos: &[igi_reflect::Photo],
    ) -> Bodies {
        let mut names: Vec<Option<String>> = Vec::new();
        let mut of = vec![0; sky.len()];
        for (i, s) in sky.iter().enumerate() {
            if s.is_none() {
                continue;
            }
            let name = bodies.get(i).cloned().flatten();
            of[i] = names.iter().position(|n| *n == name).unwrap_or_else(|| {
                names.push(name);
                names.len() - 1
            });
        }
        let mut start = vec![1.0; names.len().max(1)];
        for (i, p) in photos.iter().enumerate() {
            let f = last.and_then(|r| r.photos.iter().find(|f| f.photo == p.id));
            if let (Some(f), Some(_)) = (f, &sky[i]) {
                start[of[i]] = f.body_exposure;
            }
        }
        Bodies {
            of,
            count: names.len(),
            start,
        }
    }

    fn count(&self) -> usize {
        self.count
    }

    /// Each body's factor but the reference's, refitted: the weighted least-squares scale
    /// between its photos' pixels and their re-renderings on the reference's scale (the fit's
    /// relative weights, over the pixels that see the site).
    fn refit(
        &self,
        exposure: &[f64],
        photos: &[igi_reflect::Photo],
        bases: &Bases,
        fits: &[PhotoFit],
        renders: &[(String, HdrImage)],
    ) -> Vec<f64> {
        let mut num = vec![0.0f64; exposure.len()];
        let mut den = vec![0.0f64; exposure.len()];
        for (i, p) in photos.iter().enumerate() {
            let (Some(f), Some((_, r)), Some(pb)) = (
                fits.iter().find(|f| f.photo == p.id),
                renders.iter().find(|r| r.0 == p.id),
                &bases.photos[i],
            ) else {
                continue;
            };
            let body = self.of[i];
            let site = &pb.texels.site;
            let mean = site
                .iter()
                .map(|&j| p.image.pixels[j].iter().map(|&c| c as f64).sum::<f64>())
                .sum::<f64>()
                / (3 * site.len().max(1)) as f64;
            for &j in site {
                for c in 0..3 {
                    let (obs, pred) = (p.image.pixels[j][c] as f64, r.pixels[j][c] as f64);
                    let pred = pred / f.body_exposure;
                    let w = 1.0 / obs.max(0.05 * mean).powi(2);
                    num[body] += w * pred * obs;
                    den[body] += w * pred * pred;
                }
            }
        }
        (0..exposure.len())
            .map(|b| match b == 0 || den[b] <= 0.0 {
                true => exposure[b],
                false => num[b] / den[b],
            })
            .collect()
    }
}

/// The estimated photos grouped by their time (the same instant: they share one sky), each
/// group in the photos' order, the groups in the order of their first photo.
fn time_groups(sky: &[Option<SkyPhoto>]) -> Vec<Vec<usize>> {
    let mut groups: Vec<Vec<usize>> = Vec::new();
    for (i, s) in sky.iter().enumerate() {
        let Some(s) = s else { continue };
        let instant = |k: usize| {
            sky[k]
                .as_ref()
                .map(|o| (o.time.unix_seconds(), o.time.nanos()))
        };
        match groups
            .iter_mut()
            .find(|g| instant(g[0]) == Some((s.time.unix_seconds(), s.time.nanos())))
        {
            Some(g) => g.push(i),
            None => groups.push(vec![i]),
        }
    }
    groups
}

/// Each estimated photo's lighting as a contract lighting file `RESULT/lighting/ID.toml`
/// (with its map `ID.exr`), its re-rendering under it `ID_render.exr` and the picture `ID.png`
/// (photograph | re-rendering | sky, [`crate::lightfit_picture`]), each written atomically.
fn write_lighting_files(
    out: &Path,
    photos: &[igi_reflect::Photo],
    sky: &[Option<SkyPhoto>],
    record: &LightingRecord,
    renders: &[(String, HdrImage)],
) -> Result<(), WorkflowError> {
    let dir = out.join("lighting");
    std::fs::create_dir_all(&dir)
        .map_err(|err| WorkflowError::file(&dir, format!("cannot create the folder: {err}")))?;
    for (photo, s) in photos.iter().zip(sky) {
        if let (Some(s), Some(f)) = (s, record.photos.iter().find(|f| f.photo == photo.id)) {
            s.write_lighting(&dir, &photo.id, &f.params)?;
            let Some((_, render)) = renders.iter().find(|r| r.0 == photo.id) else {
                continue;
            };
            igi_imaging::io::write_exr(&dir.join(format!("{}_render.exr", photo.id)), render)?;
            let (map, sun) = s.map_and_sun(&f.params)?;
            let picture = crate::lightfit_picture::lighting_picture(
                &photo.image,
                render,
                &map,
                sun.map(|s| s.direction),
            );
            igi_imaging::write_png_tonemapped(
                &dir.join(format!("{}.png", photo.id)),
                &picture,
                1.0,
            )?;
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Normal equations of rows `a` (3 columns, padded to `N`) and right-hand side `b`.
    fn normal(a: &[[f64; 3]], b: &[f64]) -> (Mat, [f64; N], f64) {
        let mut ata = [[0.0; N]; N];
        let mut atb = [0.0; N];
        let mut btb = 0.0;
        for (r, bi) in a.iter().zip(b) {
            for p in 0..3 {
                atb[p] += r[p] * bi;
                for q in 0..3 {
                    ata[p][q] += r[p] * r[q];
                }
            }
            btb += bi * bi;
        }
        (ata, atb, btb)
    }

    #[test]
    fn nnls_recovers_an_exact_combination_and_clamps_a_negative_one() {
        // columns a0 = (1,0,1,2), a1 = (0,1,1,0), a2 = (1,1,0,1); b = 2 a0 + 0.5 a1
        let a = [
            [1.0, 0.0, 1.0],
            [0.0, 1.0, 1.0],
            [1.0, 1.0, 0.0],
            [2.0, 0.0, 1.0],
        ];
        let x_true = [2.0, 0.5, 0.0];
        let b: Vec<f64> = a
            .iter()
            .map(|r| (0..3).map(|k| r[k] * x_true[k]).sum())
            .collect();
        let (ata, atb, btb) = normal(&a, &b);
        let (x, sse, _) = nnls(&ata, &atb, btb, 0b111);
        for k in 0..3 {
            assert!((x[k] - x_true[k]).abs() < 1e-9, "{x:?}");
        }
        assert!(sse < 1e-12);
        // b = a0 - a2: the unconstrained fit has x2 = -1; the non-negative one none below zero
        let b2: Vec<f64> = a.iter().map(|r| r[0] - r[2]).collect();
        let (ata, atb2, btb2) = normal(&a, &b2);
        let (x2, sse2, _) = nnls(&ata, &atb2, btb2, 0b111);
        assert!(x2.iter().all(|&v| v >= 0.0), "{x2:?}");
        assert!(sse2 > 0.0 && sse2 <= btb2);
    }

    /// A gauge below 1 lifts the albedo, at most to 1 (a texel the solver clamped at 1 stays
    /// a valid albedo for `igi render`); above 1 it only lowers it.
    #[test]
    fn the_gauge_keeps_the_albedo_at_most_one() {
        let v = |x: f32, y: f32, z: f32| Vec3::new(x, y, z);
        assert_eq!(
            regauged(v(1.0, 0.5, 0.2), 0.98),
            v(1.0, 0.5 / 0.98, 0.2 / 0.98)
        );
        assert_eq!(regauged(v(0.9, 0.6, 0.0), 0.5), v(1.0, 1.0, 0.0));
        assert_eq!(regauged(v(1.0, 0.5, 0.2), 2.0), v(0.5, 0.25, 0.1));
    }

    /// Photos taken at the same instant share a group, whatever their UTC offset; photos
    /// without estimated light belong to none.
    #[test]
    fn photos_are_grouped_by_their_instant() {
        let site = SiteLocation {
            latitude_deg: 48.85,
            longitude_deg: 2.35,
            north: [0.0, 1.0, 0.0],
        };
        let at = |t: &str| {
            let time = PhotoTime::parse_rfc3339(t).unwrap();
            Some(SkyPhoto::new(time, site).unwrap().unwrap())
        };
        let sky = [
            at("2026-06-21T11:00:00+02:00"),
            at("2026-06-21T15:00:00+02:00"),
            at("2026-06-21T09:00:00Z"),
            None,
            at("2026-06-21T15:00:00+02:00"),
            at("2026-06-21T15:00:01+02:00"),
        ];
        assert_eq!(time_groups(&sky), vec![vec![0, 2], vec![1, 4], vec![5]]);
    }

    /// The light's change between rounds: the summed change of the scales over their sum
    /// before, the largest over the photos; a new turbidity or a photo one round lacks is
    /// unsettled.
    #[test]
    fn the_light_change_between_rounds() {
        let fit = |id: &str, t: f64, sun: f64, sky: f64, ovc: f64| PhotoFit {
            photo: id.into(),
            time: String::new(),
            sun_azimuth_deg: 0.0,
            sun_elevation_deg: 0.0,
            sun_direction: [0.0, 0.0, 1.0],
            params: SkyParams {
                turbidity: t,
                sun_scale: sun,
                sky_scale: sky,
                overcast_scale: ovc,
                ..SkyParams::default()
            },
            stderr: SkyParams::default(),
            pixels: 1,
            relative_rms: 0.0,
            body_exposure: 1.0,
        };
        let rec = |photos| LightingRecord {
            photos,
            ..LightingRecord::default()
        };
        let before = rec(vec![
            fit("a", 3.0, 1.0, 1.0, 0.0),
            fit("b", 2.0, 0.0, 0.0, 2.0),
        ]);
        let after = rec(vec![
            fit("a", 3.0, 1.01, 0.98, 0.0),
            fit("b", 2.0, 0.0, 0.0, 2.01),
        ]);
        // a: (0.01 + 0.02) / 2; b: 0.01 / 2
        assert!((light_change(&before, &after) - 0.015).abs() < 1e-12);
        let turned = rec(vec![
            fit("a", 4.5, 1.0, 1.0, 0.0),
            fit("b", 2.0, 0.0, 0.0, 2.0),
        ]);
        assert_eq!(light_change(&before, &turned), f64::INFINITY);
        let new = rec(vec![fit("c", 3.0, 1.0, 1.0, 0.0)]);
        assert_eq!(light_change(&before, &new), f64::INFINITY);
        assert_eq!(light_change(&before, &before), 0.0);
    }

    #[test]
    fn turbidity_stderr_of_a_parabola() {
        // sse = 10 + (T - 3)^2 * 4, s2 = 2: d2 = 8, se = sqrt(2 * 2 / 8)
        let curve: Vec<(f64, f64)> = [2.0, 3.0, 4.5]
            .iter()
            .map(|&t| (t, 10.0 + 4.0 * (t - 3.0f64).powi(2)))
            .collect();
        let se = turbidity_stderr(&curve, 3.0, 2.0);
        assert!((se - 0.5f64.sqrt()).abs() < 1e-12, "{se}");
        assert_eq!(turbidity_stderr(&curve, 2.0, 2.0), 0.0);
    }
}
