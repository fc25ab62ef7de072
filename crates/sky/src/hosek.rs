//! The Hosek-Wilkie 2012 clear sky and its 2013 solar disk, in linear Rec. 709 RGB.
//!
//! A port of the authors' reference implementation, version 1.4a (`ArHosekSkyModel.c`, Lukas
//! Hosek and Alexander Wilkie, 3-clause BSD licence, `crates/sky/LICENSE-hosek-wilkie`), with
//! its data copied exactly into `hosek_data.rs` by `datasets/sky/gen_data.py`:
//!
//! - the sky ([`HosekWilkie`]): per channel the radiance `F(theta, gamma) L_M`, where
//!   `F = (1 + A exp(B / (cos theta + 0.01))) (C + D exp(E gamma) +
//!   F cos^2 gamma + G chi(H, gamma) + I sqrt(cos theta))` (the reference's order of the nine coefficients
//!   is A, B, C, D, E, F, G, I, H: index 7 multiplies `sqrt(cos theta)` and index 8 is the
//!   Mie term's `g`), with `chi(g, gamma) = (1 + cos^2 gamma) / (1 + g^2 - 2 g cos gamma)^1.5`.
//!   The nine coefficients and `L_M` are interpolated from the RGB dataset by the quintic
//!   Bezier in `(elevation / 90 deg)^(1/3)`, linearly in turbidity (1 to 10) and in ground
//!   albedo (0 to 1). `theta` is the view direction's zenith angle, `gamma` its angle from
//!   the sun; the model holds above the horizon only.
//! - the sun ([`solar_radiance_spectral`], [`solar_radiance_rgb`],
//!   [`solar_irradiance_rgb`]): the reference's spectral solar radiance
//!   (`arhosekskymodel_solar_radiance_internal2`: per 40 nm band 320 to 720 nm and turbidity,
//!   a piecewise cubic in the sun's elevation, times the band's fifth-order limb darkening in
//!   the cosine across the disk, the disk being 0.51 degrees wide), turned into CIE XYZ with
//!   the CIE 1931 2-degree colour matching functions (the trapezoid rule on 1 nm steps over
//!   360 to 720 nm, where the model ends) and into linear Rec. 709 RGB by [`XYZ_TO_RGB`].
//!
//! Units: the RGB sky data are the reference's own fit "with sRGB primaries and a linear gamma
//! ramp" to its spectral sky in W m^-2 sr^-1 nm^-1 weighted by the colour matching functions,
//! so 683 lm/W times the luminance `0.2126 R + 0.7152 G + 0.0722 B` is candela per square
//! metre; the sun is integrated the same way and shares those units (docs/SKY.md).

use crate::cie_data::{CIE_1931, CIE_FIRST_NM};
use crate::hosek_data::{LIMB_DARKENING, RGB_COEFFS, RGB_RADIANCES, SOLAR};
use crate::SkyError;
use std::f64::consts::{FRAC_PI_2, PI};

/// The angular radius of the reference's solar disk, radians (0.51 degrees across).
pub const MODEL_SOLAR_RADIUS_RAD: f64 = 0.51 * (PI / 180.0) / 2.0;

/// Linear Rec. 709 (sRGB) RGB from CIE XYZ, white D65 (X, Y, Z) = (0.95047, 1, 1.08883):
/// the usual matrix (Lindbloom), rows R, G, B.
pub const XYZ_TO_RGB: [[f64; 3]; 3] = [
    [3.2404542, -1.5371385, -0.4985314],
    [-0.9692660, 1.8760108, 0.0415560],
    [0.0556434, -0.2040259, 1.0572252],
];

/// The first and last wavelengths (nm) integrated against the colour matching functions: the
/// CMFs start at 360 nm and the model's spectrum ends at 720 nm.
pub const RGB_BAND_NM: (usize, usize) = (360, 720);

/// Checked model parameters: turbidity in [1, 10], albedo in [0, 1], solar elevation in
/// [0, 90] degrees (given in radians).
pub(crate) fn check(turbidity: f64, albedo: [f64; 3], elevation_rad: f64) -> Result<(), SkyError> {
    if !(1.0..=10.0).contains(&turbidity) {
        return Err(SkyError::Turbidity(turbidity));
    }
    if !albedo.iter().all(|a| (0.0..=1.0).contains(a)) {
        return Err(SkyError::Albedo(albedo));
    }
    // a hair of tolerance for directions normalised in floating point
    if !(-1e-12..=FRAC_PI_2 + 1e-12).contains(&elevation_rad) {
        return Err(SkyError::SolarElevation(elevation_rad.to_degrees()));
    }
    Ok(())
}

/// Bernstein weights of the quintic Bezier at `s` in [0, 1].
fn quintic(s: f64) -> [f64; 6] {
    let t = 1.0 - s;
    [
        t.powi(5),
        5.0 * t.powi(4) * s,
        10.0 * t.powi(3) * s * s,
        10.0 * t * t * s.powi(3),
        5.0 * t * s.powi(4),
        s.powi(5),
    ]
}

/// `ArHosekSkyModel_CookConfiguration` / `CookRadianceConfiguration`: value `i` of a dataset
/// holding `n` values per control point (9 coefficients, or 1 radiance), blended in elevation
/// (`bezier`), turbidity and albedo.
fn cook(data: &[f64], n: usize, i: usize, turbidity: f64, albedo: f64, bezier: &[f64; 6]) -> f64 {
    let t_int = (turbidity as usize).clamp(1, 10);
    let t_rem = turbidity - t_int as f64;
    let block = |alb: usize, t_idx: usize| -> f64 {
        let base = n * 6 * 10 * alb + n * 6 * t_idx;
        (0..6).map(|k| bezier[k] * data[base + n * k + i]).sum()
    };
    let mut v = (1.0 - albedo) * (1.0 - t_rem) * block(0, t_int - 1)
        + albedo * (1.0 - t_rem) * block(1, t_int - 1);
    if t_int < 10 {
        v += (1.0 - albedo) * t_rem * block(0, t_int) + albedo * t_rem * block(1, t_int);
    }
    v
}

/// The Hosek-Wilkie RGB sky for one turbidity, ground albedo (per channel) and solar
/// elevation: its nine coefficients and radiance scale per channel.
#[derive(Clone, Debug, PartialEq)]
pub struct HosekWilkie {
    turbidity: f64,
    albedo: [f64; 3],
    solar_elevation_rad: f64,
    coeffs: [[f64; 9]; 3],
    scale: [f64; 3],
}

impl HosekWilkie {
    /// The sky for these parameters, refused when one is out of the model's range.
    pub fn new(
        turbidity: f64,
        albedo: [f64; 3],
        solar_elevation_rad: f64,
    ) -> Result<Self, SkyError> {
        check(turbidity, albedo, solar_elevation_rad)?;
        let elevation = solar_elevation_rad.clamp(0.0, FRAC_PI_2);
        let bezier = quintic((elevation / FRAC_PI_2).powf(1.0 / 3.0));
        let mut coeffs = [[0.0; 9]; 3];
        let mut scale = [0.0; 3];
        for c in 0..3 {
            for i in 0..9 {
                coeffs[c][i] = cook(&RGB_COEFFS[c], 9, i, turbidity, albedo[c], &bezier);
            }
            scale[c] = cook(&RGB_RADIANCES[c], 1, 0, turbidity, albedo[c], &bezier);
        }
        Ok(HosekWilkie {
            turbidity,
            albedo,
            solar_elevation_rad: elevation,
            coeffs,
            scale,
        })
    }

    /// Atmospheric turbidity, 1 (very clear) to 10 (hazy).
    pub fn turbidity(&self) -> f64 {
        self.turbidity
    }

    /// Ground albedo per channel, 0 to 1.
    pub fn albedo(&self) -> [f64; 3] {
        self.albedo
    }

    /// The sun's elevation above the horizon, radians, 0 to pi/2.
    pub fn solar_elevation_rad(&self) -> f64 {
        self.solar_elevation_rad
    }

    /// The model's nine coefficients per channel, in the reference's order (A, B, C, D, E, F,
    /// G, I, H: index 7 multiplies `sqrt(cos theta)`, index 8 is the Mie term's `g`).
    pub fn coefficients(&self) -> [[f64; 9]; 3] {
        self.coeffs
    }

    /// The model's radiance scale `L_M` per channel.
    pub fn radiance_scale(&self) -> [f64; 3] {
        self.scale
    }

    /// `F(theta, gamma)` of one channel (`ArHosekSkyModel_GetRadianceInternal`), unscaled.
    pub fn f(&self, channel: usize, theta: f64, gamma: f64) -> f64 {
        let c = &self.coeffs[channel];
        let (cos_t, cos_g) = (theta.cos(), gamma.cos());
        let exp_m = (c[4] * gamma).exp();
        let ray_m = cos_g * cos_g;
        let mie_m = (1.0 + cos_g * cos_g) / (1.0 + c[8] * c[8] - 2.0 * c[8] * cos_g).powf(1.5);
        let zenith = cos_t.max(0.0).sqrt();
        (1.0 + c[0] * (c[1] / (cos_t + 0.01)).exp())
            * (c[2] + c[3] * exp_m + c[5] * ray_m + c[6] * mie_m + c[7] * zenith)
    }

    /// The sky's RGB radiance toward zenith angle `theta` at angle `gamma` from the sun
    /// (radians): `F(theta, gamma) L_M` per channel, as the reference's
    /// `arhosek_tristim_skymodel_radiance`, for `theta` up to pi/2 (the horizon); zero below
    /// the horizon, where the model does not hold.
    pub fn radiance(&self, theta: f64, gamma: f64) -> [f64; 3] {
        if !(theta <= FRAC_PI_2) {
            return [0.0; 3];
        }
        std::array::from_fn(|c| self.f(c, theta, gamma) * self.scale[c])
    }
}

/// `arhosekskymodel_sr_internal`: the solar radiance at the disk's centre in waveband `wl`
/// (0: 320 nm, ..., 10: 720 nm) for turbidity index `turb` (0: turbidity 1) at elevation
/// `elevation` (radians, >= 0).
fn solar_band(turb: usize, wl: usize, elevation: f64) -> f64 {
    const PIECES: usize = 45;
    const ORDER: usize = 4;
    let pos = (((2.0 * elevation / PI).powf(1.0 / 3.0) * PIECES as f64) as usize).min(PIECES - 1);
    let break_x = (pos as f64 / PIECES as f64).powi(3) * FRAC_PI_2;
    let c = &SOLAR[wl][ORDER * PIECES * turb + ORDER * pos..][..ORDER];
    let x = elevation - break_x;
    c[3] + x * c[2] + x * x * c[1] + x * x * x * c[0]
}

/// The turbidity's lower index and fraction as the reference splits it.
fn turbidity_split(turbidity: f64) -> (usize, f64) {
    let low = (turbidity as usize).clamp(1, 10) - 1;
    if low == 9 {
        (8, 1.0)
    } else {
        (low, turbidity - (low + 1) as f64)
    }
}

/// The spectral solar radiance at the disk's centre (no limb darkening) at wavelength `nm` in
/// [320, 720], turbidity in [1, 10] and elevation (radians), in W m^-2 sr^-1 nm^-1, with the
/// limb-darkening coefficients at that wavelength.
fn solar_centre(turbidity: f64, nm: f64, elevation: f64) -> (f64, [f64; 6]) {
    let elevation = elevation.clamp(0.0, FRAC_PI_2);
    let (t_low, t_frac) = turbidity_split(turbidity);
    let mut wl_low = ((nm - 320.0) / 40.0) as usize;
    let mut wl_frac = (nm % 40.0) / 40.0;
    if wl_low >= 10 {
        wl_low = 9;
        wl_frac = 1.0;
    }
    let band = |t| {
        (1.0 - wl_frac) * solar_band(t, wl_low, elevation)
            + wl_frac * solar_band(t, wl_low + 1, elevation)
    };
    let direct = (1.0 - t_frac) * band(t_low) + t_frac * band(t_low + 1);
    let ld = std::array::from_fn(|k| {
        (1.0 - wl_frac) * LIMB_DARKENING[wl_low][k] + wl_frac * LIMB_DARKENING[wl_low + 1][k]
    });
    (direct, ld)
}

/// The cosine across the disk (`sampleCosine`: 1 at the centre, 0 at the rim) at angle
/// `gamma` from the centre of a disk of angular radius `radius`; `None` outside the disk.
fn disk_cosine(gamma: f64, radius: f64) -> Option<f64> {
    let s = gamma.sin() / radius.sin();
    let c2 = 1.0 - s * s;
    (gamma.abs() < radius && c2 > 0.0).then(|| c2.sqrt())
}

/// The reference's spectral solar radiance (`arhosekskymodel_solar_radiance_internal2`) in
/// W m^-2 sr^-1 nm^-1 at wavelength `nm` (320 to 720), `gamma` radians from the centre of the
/// model's 0.51-degree disk, for the sun at `elevation` radians; zero off the disk. Turbidity
/// in [1, 10] (not checked here).
pub fn solar_radiance_spectral(turbidity: f64, nm: f64, elevation: f64, gamma: f64) -> f64 {
    match disk_cosine(gamma, MODEL_SOLAR_RADIUS_RAD) {
        None => 0.0,
        Some(mu) => {
            let (direct, ld) = solar_centre(turbidity, nm, elevation);
            direct * ld.iter().rev().fold(0.0, |acc, c| acc * mu + c)
        }
    }
}

/// Integrates `g(nm)` (XYZ weights of a spectrum) into linear RGB: the trapezoid rule on 1 nm
/// steps over [`RGB_BAND_NM`] against the CIE 1931 functions, then [`XYZ_TO_RGB`].
fn integrate_rgb(mut spectrum: impl FnMut(f64) -> f64) -> [f64; 3] {
    let (first, last) = RGB_BAND_NM;
    let mut xyz = [0.0; 3];
    for nm in first..=last {
        let w = if nm == first || nm == last { 0.5 } else { 1.0 };
        let l = w * spectrum(nm as f64);
        for (c, v) in xyz.iter_mut().enumerate() {
            *v += l * CIE_1931[c][nm - CIE_FIRST_NM];
        }
    }
    xyz_to_rgb(xyz)
}

/// Linear Rec. 709 RGB of CIE XYZ by [`XYZ_TO_RGB`].
pub fn xyz_to_rgb(xyz: [f64; 3]) -> [f64; 3] {
    std::array::from_fn(|r| (0..3).map(|c| XYZ_TO_RGB[r][c] * xyz[c]).sum())
}

/// The solar disk's RGB radiance `gamma` radians from its centre (limb-darkened; zero off the
/// model's 0.51-degree disk) for the sun at `elevation` radians: [`solar_radiance_spectral`]
/// integrated as the module describes. A very low sun's red light lies outside the Rec. 709
/// gamut: its blue channel is negative, as the matrix gives it.
pub fn solar_radiance_rgb(turbidity: f64, elevation: f64, gamma: f64) -> [f64; 3] {
    match disk_cosine(gamma, MODEL_SOLAR_RADIUS_RAD) {
        None => [0.0; 3],
        Some(mu) => integrate_rgb(|nm| {
            let (direct, ld) = solar_centre(turbidity, nm, elevation);
            direct * ld.iter().rev().fold(0.0, |acc, c| acc * mu + c)
        }),
    }
}

/// The irradiance the model's solar disk gives a surface facing it (the integral of
/// [`solar_radiance_rgb`] over the disk), RGB in the units of the sky times steradians, for the
/// sun at `elevation` radians (the centre's elevation across the whole disk).
///
/// With `s = sin gamma / sin R` and the disk cosine `mu = sqrt(1 - s^2)`,
/// `dOmega = 2 pi sin^2 R mu dmu / cos gamma`, so each limb-darkening term `c_k mu^k`
/// integrates to `2 pi sin^2 R c_k int_0^1 mu^(k+1) / cos gamma dmu`; with
/// `1 / cos gamma = 1 + sin^2 R (1 - mu^2) / 2 + O(sin^4 R)` (sin^4 R is 2e-10 here) that is
/// `1 / (k + 2) + sin^2 R (1 / (k + 2) - 1 / (k + 4)) / 2`.
pub fn solar_irradiance_rgb(turbidity: f64, elevation: f64) -> [f64; 3] {
    let a = MODEL_SOLAR_RADIUS_RAD.sin().powi(2);
    let moments: [f64; 6] = std::array::from_fn(|k| {
        let k = k as f64;
        1.0 / (k + 2.0) + 0.5 * a * (1.0 / (k + 2.0) - 1.0 / (k + 4.0))
    });
    integrate_rgb(|nm| {
        let (direct, ld) = solar_centre(turbidity, nm, elevation);
        2.0 * PI * a * direct * ld.iter().zip(&moments).map(|(c, m)| c * m).sum::<f64>()
    })
}
