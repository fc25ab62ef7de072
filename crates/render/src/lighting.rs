//! Natural light: a lat-long environment map and the sun as a small disk (FORMATS.md
//! "Lighting file").
//!
//! - Environment radiance `L_env(d) = scale * bilinear(map, direction_to_pixel(d))`, wrapping in
//!   azimuth and clamping at the poles. It is importance-sampled with a [`Distribution2D`] over
//!   the map's pixels weighted by sin(theta) (marginal over rows, conditional over columns); the
//!   weight of a pixel is the largest luminance in its 3x3 neighbourhood, so every direction
//!   with non-zero bilinear radiance has non-zero pdf. Solid-angle pdf =
//!   `pdf_uv / (2 pi^2 sin theta)`.
//! - Sun: radiance `L_sun` inside the cone of half-angle `angular_diameter / 2` around
//!   `direction`, sampled uniformly in that cone (pdf = 1 / solid angle). Membership is tested
//!   with `|d x s|^2 <= sin^2(half angle)`, which keeps full f32 precision for a 0.53 degree disk.

use crate::fastmath;
use crate::sampling::{sample_cone_in, Distribution2D};
use crate::RenderError;
use glam::{Vec2, Vec3};
use igi_brdf::luminance;
use igi_brdf::Frame;
use igi_formats::lighting::{
    check_sun, disk_one_minus_cos, scaled_radiance, LightingFile, LightingRadiance,
};
use igi_formats::TomlFile;
use igi_imaging::HdrImage;
use std::f32::consts::PI;
use std::path::Path;

/// A direction sampled from a light.
#[derive(Clone, Copy, Debug)]
pub struct LightSample {
    /// Unit direction from the shading point toward the light.
    pub wi: Vec3,
    /// Radiance arriving along `-wi` from this light (unoccluded).
    pub radiance: Vec3,
    /// Solid-angle pdf of `wi`.
    pub pdf: f32,
}

/// Lat-long environment map with its sampling distribution.
#[derive(Clone, Debug)]
pub struct Environment {
    w: usize,
    h: usize,
    /// Radiance, already multiplied by `scale`, row-major, row 0 at the zenith.
    texels: Vec<Vec3>,
    dist: Distribution2D,
    /// False when the map is black everywhere (nothing to sample).
    nonzero: bool,
}

impl Environment {
    /// From a lat-long image and a scale. Non-finite or negative texels are an error
    /// (`igi_formats::lighting::scaled_radiance`).
    pub fn from_image(img: &HdrImage, scale: f32) -> Result<Self, RenderError> {
        let texels = scaled_radiance(img, scale)?;
        Ok(Self::from_scaled(img.width, img.height, &texels))
    }

    /// From radiance already scaled and checked (`igi_formats::lighting::LightingRadiance`).
    pub fn from_scaled(w: usize, h: usize, texels: &[[f32; 3]]) -> Self {
        Self::from_texels(w, h, texels.iter().map(|&t| Vec3::from_array(t)).collect())
    }

    /// A constant environment (every direction has radiance `l`).
    pub fn constant(l: Vec3) -> Self {
        let (w, h) = (32, 16);
        Self::from_texels(w, h, vec![l; w * h])
    }

    fn from_texels(w: usize, h: usize, texels: Vec<Vec3>) -> Self {
        let lum: Vec<f32> = texels
            .iter()
            .map(|&t| luminance(t).max(t.max_element() * 1e-3))
            .collect();
        let mut func = vec![0f32; w * h];
        for i in 0..h {
            let sin_t = (PI * (i as f32 + 0.5) / h as f32).sin();
            for j in 0..w {
                let mut m = 0f32;
                for di in -1i64..=1 {
                    let ii = (i as i64 + di).clamp(0, h as i64 - 1) as usize;
                    for dj in -1i64..=1 {
                        let jj = (j as i64 + dj).rem_euclid(w as i64) as usize;
                        m = m.max(lum[ii * w + jj]);
                    }
                }
                func[i * w + j] = m * sin_t;
            }
        }
        let nonzero = func.iter().any(|&f| f > 0.0);
        let dist = Distribution2D::new(&func, w, h);
        Environment {
            w,
            h,
            texels,
            dist,
            nonzero,
        }
    }

    pub fn width(&self) -> usize {
        self.w
    }

    pub fn height(&self) -> usize {
        self.h
    }

    /// Whether any direction has non-zero radiance.
    pub fn is_nonzero(&self) -> bool {
        self.nonzero
    }

    #[inline]
    fn texel(&self, row: usize, col: usize) -> Vec3 {
        self.texels[row * self.w + col]
    }

    /// Radiance arriving from direction `d` (unit): bilinear, wrapping in azimuth, clamped at
    /// the poles.
    #[inline]
    pub fn eval(&self, d: Vec3) -> Vec3 {
        let (u, v) = fastmath::direction_to_uv(d);
        self.eval_uv(u, v)
    }

    /// Bilinear radiance at lat-long coordinates (u, v) in [0, 1] (pixel x = u W - 0.5,
    /// y = v H - 0.5; wrap in x, clamp in y).
    #[inline]
    pub fn eval_uv(&self, u: f32, v: f32) -> Vec3 {
        let x = u * self.w as f32 - 0.5;
        let y = v * self.h as f32 - 0.5;
        // floor() without a libm call (x, y >= -0.5 here): truncation, minus one below zero.
        let fl = |a: f32| if a < 0.0 { -1.0 } else { (a as u32) as f32 };
        let (x0f, y0f) = (fl(x), fl(y));
        let (fx, fy) = (x - x0f, y - y0f);
        // x in [-0.5, W - 0.5]: the cell left of column 0 is the last column.
        let x0 = if x0f < 0.0 {
            self.w - 1
        } else {
            (x0f as usize).min(self.w - 1)
        };
        let x1 = if x0 + 1 == self.w { 0 } else { x0 + 1 };
        let y0 = if y0f < 0.0 {
            0
        } else {
            (y0f as usize).min(self.h - 1)
        };
        let y1 = (y0 + 1).min(self.h - 1);
        let fy = if y0f < 0.0 { 0.0 } else { fy };
        let top = self.texel(y0, x0) * (1.0 - fx) + self.texel(y0, x1) * fx;
        let bot = self.texel(y1, x0) * (1.0 - fx) + self.texel(y1, x1) * fx;
        top * (1.0 - fy) + bot * fy
    }

    /// Solid-angle pdf with which [`Self::sample`] returns `d`.
    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        if !self.nonzero {
            return 0.0;
        }
        let (u, v) = fastmath::direction_to_uv(d);
        self.pdf_uv(d, u, v)
    }

    #[inline]
    fn pdf_uv(&self, d: Vec3, u: f32, v: f32) -> f32 {
        let sin_t = (1.0 - d.z * d.z).max(0.0).sqrt();
        if sin_t <= 0.0 || !self.nonzero {
            return 0.0;
        }
        self.dist.pdf(Vec2::new(u, v)) / (2.0 * PI * PI * sin_t)
    }

    /// Radiance and pdf of direction `d` with one lat-long conversion.
    #[inline]
    pub fn eval_pdf(&self, d: Vec3) -> (Vec3, f32) {
        let (u, v) = fastmath::direction_to_uv(d);
        (self.eval_uv(u, v), self.pdf_uv(d, u, v))
    }

    /// Importance-samples a direction from two uniform numbers (alias table: fast, but
    /// neighbouring `s` may land far apart).
    #[inline]
    pub fn sample(&self, s: Vec2) -> Option<LightSample> {
        self.sample_from(s, false)
    }

    /// [`Self::sample`] through the inverse cdfs, monotone in `s`: stratified numbers give
    /// stratified directions.
    #[inline]
    pub fn sample_monotone(&self, s: Vec2) -> Option<LightSample> {
        self.sample_from(s, true)
    }

    #[inline]
    fn sample_from(&self, s: Vec2, monotone: bool) -> Option<LightSample> {
        if !self.nonzero {
            return None;
        }
        let (uv, pdf_uv) = if monotone {
            self.dist.sample_inverse_cdf(s)
        } else {
            self.dist.sample(s)
        };
        let (wi, sin_t) = fastmath::uv_to_direction(uv.x, uv.y);
        if !(pdf_uv > 0.0) || !(sin_t > 0.0) {
            return None;
        }
        let pdf = pdf_uv / (2.0 * PI * PI * sin_t);
        Some(LightSample {
            wi,
            radiance: self.eval_uv(uv.x, uv.y),
            pdf,
        })
    }

    /// The sampling distribution (for tests and diagnostics).
    pub fn distribution(&self) -> &Distribution2D {
        &self.dist
    }
}

/// The sun: a disk of uniform radiance.
#[derive(Clone, Copy, Debug)]
pub struct Sun {
    /// Unit vector from the scene toward the sun.
    pub direction: Vec3,
    /// Radiance of the disk.
    pub radiance: Vec3,
    /// Angular diameter in radians.
    pub angular_diameter: f32,
    one_minus_cos: f32,
    sin2_max: f32,
    solid_angle: f32,
    frame: Frame,
}

impl Sun {
    /// `direction` need not be unit; `angular_diameter_deg` in (0, 180).
    pub fn new(
        direction: Vec3,
        radiance: Vec3,
        angular_diameter_deg: f32,
    ) -> Result<Self, RenderError> {
        check_sun(
            direction.to_array(),
            radiance.to_array(),
            angular_diameter_deg,
        )?;
        let len = direction.length();
        let half = (angular_diameter_deg as f64).to_radians() / 2.0;
        let omc = disk_one_minus_cos(angular_diameter_deg as f64); // 1 - cos(half)
        Ok(Sun {
            direction: direction / len,
            radiance,
            angular_diameter: (2.0 * half) as f32,
            one_minus_cos: omc as f32,
            sin2_max: half.sin().powi(2) as f32,
            solid_angle: (2.0 * std::f64::consts::PI * omc) as f32,
            frame: Frame::from_normal(direction / len),
        })
    }

    /// Solid angle of the disk (sr).
    pub fn solid_angle(&self) -> f32 {
        self.solid_angle
    }

    /// Whether the unit direction `d` points into the disk.
    #[inline]
    pub fn contains(&self, d: Vec3) -> bool {
        d.dot(self.direction) > 0.0 && d.cross(self.direction).length_squared() <= self.sin2_max
    }

    /// Radiance seen along unit direction `d`.
    #[inline]
    pub fn eval(&self, d: Vec3) -> Vec3 {
        if self.contains(d) {
            self.radiance
        } else {
            Vec3::ZERO
        }
    }

    #[inline]
    pub fn pdf(&self, d: Vec3) -> f32 {
        if self.contains(d) {
            1.0 / self.solid_angle
        } else {
            0.0
        }
    }

    /// Uniform direction in the disk's cone.
    #[inline]
    pub fn sample(&self, u: Vec2) -> LightSample {
        LightSample {
            wi: sample_cone_in(&self.frame, self.one_minus_cos, u),
            radiance: self.radiance,
            pdf: 1.0 / self.solid_angle,
        }
    }
}

pub use igi_formats::lighting::MAX_RADIANCE;

/// Environment plus sun. Either may be absent (black sky / hidden sun).
#[derive(Clone, Debug, Default)]
pub struct Lighting {
    pub environment: Option<Environment>,
    pub sun: Option<Sun>,
}

impl Lighting {
    /// Reads a lighting file (FORMATS.md) and builds it; the map path is relative to the
    /// file's folder.
    pub fn load(path: &Path) -> Result<Self, RenderError> {
        Self::from_file(&LightingFile::read(path)?, path)
    }

    /// Builds the lighting a parsed lighting file describes: reads its map (relative to the
    /// folder of `path`, the file it came from, which errors name) and checks every value.
    pub fn from_file(f: &LightingFile, path: &Path) -> Result<Self, RenderError> {
        let r = LightingRadiance::from_file(f, path)?;
        let environment = r
            .environment
            .map(|(w, h, texels)| Environment::from_scaled(w, h, &texels));
        let sun = match r.sun {
            None => None,
            Some(s) => Some(
                Sun::new(
                    Vec3::from_array(s.direction),
                    Vec3::from_array(s.radiance),
                    s.angular_diameter_deg,
                )
                .map_err(|e| RenderError::in_file(path, "[sun]", e.into()))?,
            ),
        };
        Ok(Lighting { environment, sun })
    }

    /// Refuses lighting that can only render black: none at all (a scene file without
    /// `lighting`, and no other lighting given).
    pub fn check_lights_something(&self) -> Result<(), RenderError> {
        if self.environment.is_none() && self.sun.is_none() {
            return Err(RenderError::NoLighting);
        }
        Ok(())
    }

    /// The largest luminance a photograph lit by this light can plausibly show over most of
    /// its pixels: the brighter of a white Lambertian surface facing every light at once
    /// (the irradiance of the whole sphere of sky plus the sun, over pi: no surface receives
    /// more) and the brightest direction of the sky itself (a photograph may show sky). Only a
    /// mirror-like highlight or the sun's disk is brighter, never a photograph's median.
    pub fn brightest_plausible(&self) -> f32 {
        let mut irradiance = 0.0f64;
        let mut sky_max = 0.0f32;
        if let Some(e) = &self.environment {
            for row in 0..e.h {
                let omega = f64::from(igi_imaging::latlong::pixel_solid_angle(row, e.w, e.h));
                for col in 0..e.w {
                    let l = luminance(e.texel(row, col));
                    irradiance += f64::from(l) * omega;
                    sky_max = sky_max.max(l);
                }
            }
        }
        if let Some(s) = &self.sun {
            irradiance += f64::from(luminance(s.radiance)) * f64::from(s.solid_angle);
        }
        ((irradiance / std::f64::consts::PI) as f32).max(sky_max)
    }

    /// What may not mean what the user wants, for stderr and reports: a sun below the horizon
    /// (it lights nothing above the ground plane), an environment that is black everywhere.
    pub fn warnings(&self) -> Vec<String> {
        let mut w = Vec::new();
        if let Some(s) = &self.sun {
            if s.direction.z < 0.0 {
                let elev = s.direction.z.asin().to_degrees();
                w.push(format!("the sun is below the horizon (elevation {elev:.1} deg): it lights only what faces downward"));
            }
            if s.radiance.max_element() == 0.0 {
                w.push("the sun has zero radiance".into());
            }
        }
        if let Some(e) = &self.environment {
            if !e.is_nonzero() {
                w.push("the environment map is black everywhere".into());
            }
        }
        w
    }

    /// A uniform sky of radiance `l` and no sun.
    pub fn uniform(l: Vec3) -> Self {
        Lighting {
            environment: Some(Environment::constant(l)),
            sun: None,
        }
    }

    /// Radiance seen along a ray that leaves the scene: environment plus the sun disk.
    #[inline]
    pub fn escaped(&self, d: Vec3) -> Vec3 {
        let mut l = Vec3::ZERO;
        if let Some(e) = &self.environment {
            l += e.eval(d);
        }
        if let Some(s) = &self.sun {
            l += s.eval(d);
        }
        l
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sampling::Rng;
    use igi_imaging::latlong;

    fn test_map(w: usize, h: usize) -> HdrImage {
        let mut img = HdrImage::new(w, h);
        for i in 0..h {
            for j in 0..w {
                let v = 0.1
                    + ((i * 7 + j * 13) % 10) as f32
                    + if (i, j) == (3, 5) { 200.0 } else { 0.0 };
                img.set(j, i, [v, 0.5 * v, 0.25 * v]);
            }
        }
        img
    }

    /// A uniform sky of luminance L: the whole sphere's irradiance 4 pi L over pi is 4 L (the
    /// pixel solid angles sum to 4 pi); a sun of luminance Ls and disk Omega adds Ls Omega / pi;
    /// a sky brighter than that bound somewhere sets it by itself.
    #[test]
    fn the_brightest_plausible_radiance_is_the_analytic_bound() {
        let sky = Lighting::uniform(Vec3::splat(2.0));
        assert!((sky.brightest_plausible() / 8.0 - 1.0).abs() < 1e-4);
        let sun = Sun::new(Vec3::new(0.3, 0.2, 1.0), Vec3::splat(1e5), 0.53).unwrap();
        let want = 8.0 + 1e5 * sun.solid_angle() / PI;
        let both = Lighting {
            environment: sky.environment.clone(),
            sun: Some(sun),
        };
        assert!((both.brightest_plausible() / want - 1.0).abs() < 1e-4);
        let mut map = HdrImage::new(64, 32);
        map.set(10, 5, [1e6, 1e6, 1e6]);
        let spot = Lighting {
            environment: Some(Environment::from_image(&map, 1.0).unwrap()),
            sun: None,
        };
        assert!((spot.brightest_plausible() / 1e6 - 1.0).abs() < 1e-5);
        assert_eq!(Lighting::default().brightest_plausible(), 0.0);
    }

    #[test]
    fn env_pdf_integrates_to_one_over_the_sphere() {
        let env = Environment::from_image(&test_map(24, 12), 1.0).unwrap();
        // Midpoint rule on a fine (theta, phi) grid: sum pdf * sin theta dtheta dphi.
        let (nt, np) = (600, 1200);
        let mut total = 0.0f64;
        for a in 0..nt {
            let th = PI as f64 * (a as f64 + 0.5) / nt as f64;
            for b in 0..np {
                let ph = 2.0 * PI as f64 * (b as f64 + 0.5) / np as f64;
                let d = Vec3::new(
                    (th.sin() * ph.cos()) as f32,
                    (th.sin() * ph.sin()) as f32,
                    th.cos() as f32,
                );
                total += env.pdf(d) as f64
                    * th.sin()
                    * (PI as f64 / nt as f64)
                    * (2.0 * PI as f64 / np as f64);
            }
        }
        assert!((total - 1.0).abs() < 2e-3, "integral of pdf = {total}");
    }

    /// Chi-square goodness of fit of the sampler against its own pdf, binned in (theta, phi).
    #[test]
    fn env_sampler_passes_chi_square() {
        let env = Environment::from_image(&test_map(16, 8), 1.0).unwrap();
        let (bt, bp) = (10usize, 20usize);
        let n = 200_000usize;
        let mut counts = vec![0f64; bt * bp];
        let mut rng = Rng::new(11, 0);
        let mut mismatched = 0;
        for _ in 0..n {
            let s = env.sample(rng.uniform2()).unwrap();
            assert!((s.wi.length() - 1.0).abs() < 1e-5);
            // The returned pdf is pdf(wi), except when f32 rounding moves a sample that lies on
            // a cell boundary into the neighbouring cell.
            if (s.pdf - env.pdf(s.wi)).abs() > 1e-4 * s.pdf {
                mismatched += 1;
            }
            let (u, v) = latlong::direction_to_uv(s.wi);
            let a = ((v * bt as f32) as usize).min(bt - 1);
            let b = ((u * bp as f32) as usize).min(bp - 1);
            counts[a * bp + b] += 1.0;
        }
        assert!(
            mismatched < n / 1000,
            "{mismatched} samples with pdf != pdf(wi)"
        );
        // Expected counts: integrate the pdf over each bin (fine midpoint rule).
        let sub = 16;
        let mut chi2 = 0.0;
        let mut dof = 0;
        let mut pooled_obs = 0.0;
        let mut pooled_exp = 0.0;
        for a in 0..bt {
            for b in 0..bp {
                let mut p = 0.0f64;
                for sa in 0..sub {
                    let th = PI as f64 * (a as f64 + (sa as f64 + 0.5) / sub as f64) / bt as f64;
                    for sb in 0..sub {
                        let ph = 2.0 * PI as f64 * (b as f64 + (sb as f64 + 0.5) / sub as f64)
                            / bp as f64;
                        let d = Vec3::new(
                            (th.sin() * ph.cos()) as f32,
                            (th.sin() * ph.sin()) as f32,
                            th.cos() as f32,
                        );
                        p += env.pdf(d) as f64 * th.sin();
                    }
                }
                p *= (PI as f64 / bt as f64) * (2.0 * PI as f64 / bp as f64) / (sub * sub) as f64;
                let e = p * n as f64;
                if e < 5.0 {
                    pooled_obs += counts[a * bp + b];
                    pooled_exp += e;
                } else {
                    chi2 += (counts[a * bp + b] - e).powi(2) / e;
                    dof += 1;
                }
            }
        }
        if pooled_exp > 5.0 {
            chi2 += (pooled_obs - pooled_exp).powi(2) / pooled_exp;
            dof += 1;
        }
        // dof - 1 degrees of freedom; mean dof, sd sqrt(2 dof): allow 5 sd.
        let k = (dof - 1) as f64;
        assert!(
            chi2 < k + 5.0 * (2.0 * k).sqrt(),
            "chi2 = {chi2} with {k} dof"
        );
        assert!(dof > 150, "too few bins kept: {dof}");
    }

    #[test]
    fn env_eval_matches_texels_at_pixel_centres_and_wraps() {
        let img = test_map(16, 8);
        let env = Environment::from_image(&img, 2.0).unwrap();
        for (i, j) in [(0, 0), (3, 5), (7, 15), (4, 8)] {
            let d = latlong::pixel_center_direction(i, j, 16, 8);
            let expect = Vec3::from_array(img.get(j, i)) * 2.0;
            assert!(
                (env.eval(d) - expect).length() < 1e-3 * expect.length(),
                "({i},{j})"
            );
        }
        // Halfway between the last and the first column (phi = 0): average of the two.
        let d = latlong::uv_to_direction(0.0, (2.5) / 8.0);
        let expect =
            (Vec3::from_array(img.get(15, 2)) + Vec3::from_array(img.get(0, 2))) * 0.5 * 2.0;
        assert!(
            (env.eval(d) - expect).length() < 1e-3 * expect.length(),
            "{:?} vs {expect:?}",
            env.eval(d)
        );
    }

    #[test]
    fn sun_cone_sampling_and_membership() {
        let sun = Sun::new(Vec3::new(1.0, 2.0, 3.0), Vec3::new(1e5, 9e4, 8e4), 0.53).unwrap();
        let half = (0.53f64 / 2.0).to_radians();
        let omega = 2.0 * std::f64::consts::PI * (1.0 - half.cos());
        assert!(((sun.solid_angle() as f64) - omega).abs() < 1e-4 * omega);
        assert!((omega - 6.72e-5).abs() < 0.01e-5, "{omega}");
        let mut rng = Rng::new(5, 0);
        let mut inside = 0;
        for _ in 0..10_000 {
            let s = sun.sample(rng.uniform2());
            if sun.contains(s.wi) {
                inside += 1;
            }
            assert_eq!(s.pdf, 1.0 / sun.solid_angle());
        }
        // Sampled directions are inside the disk (allow a handful of boundary roundings).
        assert!(inside >= 9_990, "{inside}");
        assert!(sun.contains(sun.direction));
        // Just inside / just outside the rim.
        let (s, _) = (igi_brdf::Frame::from_normal(sun.direction).s, 0);
        let rot = |a: f64| (sun.direction * (a.cos() as f32) + s * (a.sin() as f32)).normalize();
        assert!(sun.contains(rot(half * 0.98)));
        assert!(!sun.contains(rot(half * 1.02)));
        assert!(!sun.contains(-sun.direction));
        assert!(Sun::new(Vec3::ZERO, Vec3::ONE, 0.5).is_err());
        assert!(Sun::new(Vec3::Z, Vec3::ONE, 0.0).is_err());
    }

    #[test]
    fn lighting_file_loads_with_relative_map_and_reports_errors() {
        let dir = tempfile::tempdir().unwrap();
        let sub = dir.path().join("sky");
        std::fs::create_dir(&sub).unwrap();
        igi_imaging::write_exr(&sub.join("map.exr"), &test_map(16, 8)).unwrap();
        let p = dir.path().join("noon.toml");
        std::fs::write(
            &p,
            "[environment]\nmap = \"sky/map.exr\"\nscale = 0.5\n[sun]\ndirection = [0, 0, 2]\nradiance = [10, 20, 30]\nangular_diameter_deg = 0.53\n",
        )
        .unwrap();
        let l = Lighting::load(&p).unwrap();
        let env = l.environment.as_ref().unwrap();
        assert_eq!((env.width(), env.height()), (16, 8));
        let d = latlong::pixel_center_direction(3, 5, 16, 8);
        assert!(
            (env.eval(d).x - 0.5 * (200.0 + 0.1 + ((3 * 7 + 5 * 13) % 10) as f32)).abs() < 1e-2
        );
        let sun = l.sun.unwrap();
        assert!(sun.direction.abs_diff_eq(Vec3::Z, 1e-6));
        assert_eq!(
            l.escaped(Vec3::Z),
            env.eval(Vec3::Z) + Vec3::new(10.0, 20.0, 30.0)
        );

        std::fs::write(&p, "[environment]\nmap = \"nope.exr\"\n").unwrap();
        let e = Lighting::load(&p).unwrap_err().to_string();
        assert!(e.contains("noon.toml") && e.contains("nope.exr"), "{e}");
        std::fs::write(&p, "[sun]\ndirection = [0, 0, 0]\nradiance = [1, 1, 1]\n").unwrap();
        let e = Lighting::load(&p).unwrap_err().to_string();
        assert!(e.contains("noon.toml") && e.contains("direction"), "{e}");
        std::fs::write(&p, "[sun]\ndirection = [0, 0, 1]\n").unwrap();
        let e = Lighting::load(&p).unwrap_err().to_string();
        assert!(e.contains("noon.toml") && e.contains("radiance"), "{e}");
        let e = Lighting::load(&dir.path().join("missing.toml"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing.toml"), "{e}");
        // No sections: nothing would light the scene, an error (it was a silent black render).
        std::fs::write(&p, "").unwrap();
        let e = Lighting::load(&p).unwrap_err().to_string();
        assert!(
            e.contains("noon.toml") && e.contains("neither [environment] nor [sun]"),
            "{e}"
        );
        // a sun of 1e30 overflows the estimates: refused; one below the horizon is a warning
        std::fs::write(
            &p,
            "[sun]\ndirection = [0, 0, 1]\nradiance = [1e30, 1, 1]\n",
        )
        .unwrap();
        let e = Lighting::load(&p).unwrap_err().to_string();
        assert!(e.contains("noon.toml") && e.contains("at most 1e15"), "{e}");
        std::fs::write(
            &p,
            "[sun]\ndirection = [0, 1, -0.5]\nradiance = [1, 1, 1]\n",
        )
        .unwrap();
        let w = Lighting::load(&p).unwrap().warnings();
        assert!(
            w.len() == 1 && w[0].contains("below the horizon (elevation -26.6 deg)"),
            "{w:?}"
        );
    }
}
