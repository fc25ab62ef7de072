//! Merging exposure brackets into linear radiance.
//!
//! * [`merge_linear`]: brackets from a linear sensor (values proportional to exposure,
//!   normalised so that 1 is full scale). Each pixel/channel is the hat-weighted mean of
//!   `value / time` over the brackets where the value lies strictly inside
//!   `(noise_floor, saturation)`.
//! * [`recover_response`] + [`merge_ldr`]: 8-bit brackets through an unknown monotonic
//!   camera response. Debevec & Malik 1997: least squares for `g(Z) = ln E + ln t` on sampled
//!   pixels with hat weights and a second-difference smoothness term (weight `lambda`), per
//!   channel, scale fixed by `g(128) = 0`; then the hat-weighted mean of `g(Z) - ln t`.
//!
//! A pixel whose channels are usable in no bracket is marked invalid in the output mask
//! (its value is the best bound available: the shortest exposure for saturated pixels, the
//! longest one for pixels under the noise floor).

use crate::error::HdrError;
use crate::{HdrImage, ImagingError};
use nalgebra::{DMatrix, DVector};
use rand::{Rng, SeedableRng};
use std::path::{Path, PathBuf};

/// Number of 8-bit code values.
pub const LEVELS: usize = 256;

/// Parse an exposure time: a decimal number of seconds or a fraction such as `1/250`.
pub fn parse_time(s: &str) -> Result<f64, ImagingError> {
    let s = s.trim();
    let bad = || HdrError::TimeSyntax(s.to_string());
    let v = match s.split_once('/') {
        Some((a, b)) => {
            a.trim().parse::<f64>().map_err(|_| bad())?
                / b.trim().parse::<f64>().map_err(|_| bad())?
        }
        None => s.parse::<f64>().map_err(|_| bad())?,
    };
    if !(v.is_finite() && v > 0.0) {
        return Err(HdrError::TimeValue(s.to_string()).into());
    }
    Ok(v)
}

/// Read a whitespace/line separated list of exposure times (e.g. `shutter_times.txt`).
pub fn read_times_file(path: &Path) -> Result<Vec<f64>, ImagingError> {
    let text = std::fs::read_to_string(path).map_err(|e| ImagingError::io(path, e))?;
    text.split_whitespace()
        .map(|t| {
            parse_time(t).map_err(|e| ImagingError::InFile {
                path: path.to_path_buf(),
                source: Box::new(e),
            })
        })
        .collect()
}

/// The EXIF `ExposureTime` of an image file (JPEG/TIFF/PNG/...), read by
/// [`crate::exif::read_exif`].
pub fn exif_exposure_time(path: &Path) -> Result<f64, ImagingError> {
    crate::exif::read_exif(path)?
        .exposure_time_s
        .ok_or_else(|| ImagingError::Exif {
            path: path.to_path_buf(),
            msg: "EXIF has no ExposureTime; give the exposure times explicitly".into(),
        })
}

/// Check a bracket set: at least one image, all the same size, one positive finite time per
/// image, times strictly monotonic (increasing or decreasing; no duplicates).
/// `names` label the images in error messages.
pub fn validate_brackets(
    images: &[HdrImage],
    times: &[f64],
    names: &[PathBuf],
) -> Result<(), ImagingError> {
    let name = |i: usize| {
        names
            .get(i)
            .map(|p| p.display().to_string())
            .unwrap_or_else(|| format!("bracket {i}"))
    };
    if images.is_empty() {
        return Err(HdrError::NoBrackets.into());
    }
    if times.len() != images.len() {
        return Err(HdrError::TimeCount {
            images: images.len(),
            times: times.len(),
        }
        .into());
    }
    let (w, h) = (images[0].width, images[0].height);
    for (i, im) in images.iter().enumerate() {
        if (im.width, im.height) != (w, h) {
            return Err(HdrError::Sizes {
                name: name(i),
                size: (im.width, im.height),
                first: name(0),
                first_size: (w, h),
            }
            .into());
        }
    }
    for (i, &t) in times.iter().enumerate() {
        if !(t.is_finite() && t > 0.0) {
            return Err(HdrError::BracketTime {
                name: name(i),
                time: t,
            }
            .into());
        }
    }
    if times.len() > 1 {
        let inc = times[1] > times[0];
        for i in 1..times.len() {
            let ok = if inc {
                times[i] > times[i - 1]
            } else {
                times[i] < times[i - 1]
            };
            if !ok {
                return Err(HdrError::Order {
                    name: name(i),
                    time: times[i],
                    previous: times[i - 1],
                }
                .into());
            }
        }
    }
    // the same picture at two exposure times: one of the times is wrong, or the same file was
    // given twice (the merge would read it as a scene whose radiance changed with the time)
    for i in 1..images.len() {
        if let Some(j) = (0..i).find(|&j| same_pixels(&images[i], &images[j])) {
            return Err(HdrError::SameImage {
                name: name(i),
                first: name(j),
            }
            .into());
        }
    }
    Ok(())
}

/// Whether two images hold the same pixels (values and validity), bit for bit.
fn same_pixels(a: &HdrImage, b: &HdrImage) -> bool {
    let bits = |p: &[f32; 3]| p.map(f32::to_bits);
    (a.width, a.height) == (b.width, b.height)
        && a.valid == b.valid
        && a.pixels
            .iter()
            .zip(&b.pixels)
            .all(|(p, q)| bits(p) == bits(q))
}

/// Range of usable linear sensor values.
#[derive(Clone, Copy, Debug)]
pub struct LinearParams {
    /// Values at or below this are noise (default 0.002).
    pub noise_floor: f32,
    /// Values at or above this are saturated (default 0.98).
    pub saturation: f32,
}

impl Default for LinearParams {
    fn default() -> Self {
        LinearParams {
            noise_floor: 0.002,
            saturation: 0.98,
        }
    }
}

fn hat(z: f32, lo: f32, hi: f32) -> f32 {
    if z <= lo || z >= hi {
        0.0
    } else {
        let mid = 0.5 * (lo + hi);
        if z <= mid {
            z - lo
        } else {
            hi - z
        }
    }
}

/// Index of the shortest and the longest exposure.
fn extreme_indices(times: &[f64]) -> (usize, usize) {
    let mut s = 0;
    let mut l = 0;
    for (i, &t) in times.iter().enumerate() {
        if t < times[s] {
            s = i;
        }
        if t > times[l] {
            l = i;
        }
    }
    (s, l)
}

/// Summary of a merge.
#[derive(Clone, Debug, serde::Serialize)]
pub struct MergeStats {
    pub exposures: usize,
    pub width: usize,
    pub height: usize,
    pub valid_fraction: f64,
}

/// Merge linear-sensor brackets (see the module docs).
pub fn merge_linear(
    images: &[HdrImage],
    times: &[f64],
    p: LinearParams,
) -> Result<(HdrImage, MergeStats), ImagingError> {
    validate_brackets(images, times, &[])?;
    if !(p.noise_floor < p.saturation) {
        return Err(HdrError::Levels {
            noise_floor: p.noise_floor,
            saturation: p.saturation,
        }
        .into());
    }
    let (short, long) = extreme_indices(times);
    Ok(merge_per_channel(images, |i, c| {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (im, &t) in images.iter().zip(times) {
            if !im.valid[i] {
                continue;
            }
            let z = im.pixels[i][c];
            let wt = hat(z, p.noise_floor, p.saturation) as f64;
            num += wt * z as f64 / t;
            den += wt;
        }
        if den > 0.0 {
            Ok((num / den) as f32)
        } else {
            // bound: saturated everywhere -> shortest exposure, dark everywhere -> longest
            let zs = images[short].pixels[i][c];
            Err(if zs >= p.saturation {
                (zs as f64 / times[short]) as f32
            } else {
                (images[long].pixels[i][c].max(0.0) as f64 / times[long]) as f32
            })
        }
    }))
}

/// Usable range for [`merge_slope`], in the images' own units (for a 10-bit sensor stored as
/// [0, 1]: 5/1023 .. 1000/1023, the paper's 5..1000).
#[derive(Clone, Copy, Debug)]
pub struct SlopeParams {
    pub lo: f32,
    pub hi: f32,
}

impl Default for SlopeParams {
    fn default() -> Self {
        SlopeParams {
            lo: 5.0 / 1023.0,
            hi: 1000.0 / 1023.0,
        }
    }
}

/// Matusik et al. 2002's turntable HDR: per pixel and channel, the least-squares line
/// `value = offset + slope * time` through the brackets whose value lies in `[lo, hi]`; the
/// slope is the radiance. With a single usable bracket the line goes through the origin
/// (`value / time`); with none the pixel is invalid (its value the shortest exposure's
/// `value / time` for saturated pixels, else 0).
pub fn merge_slope(
    images: &[HdrImage],
    times: &[f64],
    p: SlopeParams,
) -> Result<(HdrImage, MergeStats), ImagingError> {
    validate_brackets(images, times, &[])?;
    if !(p.lo < p.hi) {
        return Err(HdrError::SlopeRange { lo: p.lo, hi: p.hi }.into());
    }
    let (short, _) = extreme_indices(times);
    Ok(merge_per_channel(images, |i, c| {
        let pts: Vec<(f64, f64)> = images
            .iter()
            .zip(times)
            .filter(|(im, _)| im.valid[i] && (p.lo..=p.hi).contains(&im.pixels[i][c]))
            .map(|(im, &t)| (t, im.pixels[i][c] as f64))
            .collect();
        match slope_through(&pts) {
            Some(s) => Ok(s as f32),
            None => {
                let zs = images[short].pixels[i][c];
                Err(if zs > p.hi {
                    (zs as f64 / times[short]) as f32
                } else {
                    0.0
                })
            }
        }
    }))
}

/// The merged image of same-sized `images`: channel `c` of pixel `i` is `value(i, c)`, `Ok`
/// when the brackets determine it and `Err(bound)` when they do not (the pixel is then
/// invalid, its value the bound); with the merge's summary.
fn merge_per_channel(
    images: &[HdrImage],
    mut value: impl FnMut(usize, usize) -> Result<f32, f32>,
) -> (HdrImage, MergeStats) {
    let (w, h) = (images[0].width, images[0].height);
    let mut out = HdrImage::new(w, h);
    for i in 0..w * h {
        let mut ok = true;
        for c in 0..3 {
            out.pixels[i][c] = value(i, c).unwrap_or_else(|bound| {
                ok = false;
                bound
            });
        }
        out.valid[i] = ok;
    }
    let stats = MergeStats {
        exposures: images.len(),
        width: w,
        height: h,
        valid_fraction: out.valid_fraction(),
    };
    (out, stats)
}

/// Least-squares slope of `v = a + b t` through the points (through the origin for one point).
fn slope_through(pts: &[(f64, f64)]) -> Option<f64> {
    match pts.len() {
        0 => None,
        1 => Some(pts[0].1 / pts[0].0),
        n => {
            let n = n as f64;
            let mt = pts.iter().map(|p| p.0).sum::<f64>() / n;
            let mv = pts.iter().map(|p| p.1).sum::<f64>() / n;
            let stt: f64 = pts.iter().map(|p| (p.0 - mt) * (p.0 - mt)).sum();
            let stv: f64 = pts.iter().map(|p| (p.0 - mt) * (p.1 - mv)).sum();
            (stt > 0.0).then(|| stv / stt)
        }
    }
}

/// Debevec-Malik weight of an 8-bit code value (0 at 0 and 255, peak in the middle).
pub fn debevec_weight(z: u8) -> f64 {
    let z = z as f64;
    if z <= 127.5 {
        z
    } else {
        255.0 - z
    }
}

/// 8-bit code value of a stored image value in [0, 1].
#[inline]
pub fn code_value(v: f32) -> u8 {
    (v * 255.0).round().clamp(0.0, 255.0) as u8
}

/// A recovered camera response: `g[c][z] = ln(exposure)` giving code value `z` in channel `c`,
/// with `g[c][128] = 0`.
#[derive(Clone, Debug)]
pub struct Response {
    pub g: [Vec<f64>; 3],
    pub lambda: f64,
}

impl Response {
    /// The identity-like response of a linear 8-bit sensor, `g(z) = ln(z / 128)` (z >= 1).
    pub fn linear() -> Self {
        let g: Vec<f64> = (0..LEVELS)
            .map(|z| ((z.max(1)) as f64 / 128.0).ln())
            .collect();
        Response {
            g: [g.clone(), g.clone(), g],
            lambda: 0.0,
        }
    }

    /// True if every channel's `g` is non-decreasing over codes `lo..=hi`.
    pub fn is_monotonic_in(&self, lo: u8, hi: u8) -> bool {
        self.g
            .iter()
            .all(|g| (lo as usize..hi as usize).all(|z| g[z + 1] >= g[z]))
    }

    /// True if every channel's `g` is non-decreasing over all 256 codes.
    pub fn is_monotonic(&self) -> bool {
        self.is_monotonic_in(0, 255)
    }

    /// Relative exposure of code `z` in channel `c` (`exp g`).
    pub fn exposure(&self, c: usize, z: u8) -> f64 {
        self.g[c][z as usize].exp()
    }

    /// CSV with header `z,g_r,g_g,g_b` (natural log of exposure), written atomically.
    pub fn write_csv(&self, path: &Path) -> Result<(), ImagingError> {
        let mut s = String::from("z,g_r,g_g,g_b\n");
        for z in 0..LEVELS {
            s.push_str(&format!(
                "{z},{},{},{}\n",
                self.g[0][z], self.g[1][z], self.g[2][z]
            ));
        }
        Ok(igi_files::write_text_atomic(path, &s)?)
    }
}

/// Options of the Debevec-Malik response recovery.
#[derive(Clone, Copy, Debug)]
pub struct ResponseParams {
    /// Smoothness weight (the paper's lambda); default 50.
    pub lambda: f64,
    /// Number of sampled pixel locations; default 1000.
    pub samples: usize,
    /// Seed for the sample selection.
    pub seed: u64,
}

impl Default for ResponseParams {
    fn default() -> Self {
        ResponseParams {
            lambda: 50.0,
            samples: 1000,
            seed: 1,
        }
    }
}

fn select_samples(images: &[HdrImage], times: &[f64], c: usize, n: usize, seed: u64) -> Vec<usize> {
    // Stratify by code value in the middle exposure, so the samples span the response;
    // prefer pixels not saturated/black in that exposure.
    let mut order: Vec<usize> = (0..times.len()).collect();
    order.sort_by(|&a, &b| times[a].partial_cmp(&times[b]).unwrap());
    let mid = &images[order[order.len() / 2]];
    let mut buckets: Vec<Vec<usize>> = vec![Vec::new(); LEVELS];
    for i in 0..mid.pixels.len() {
        if images.iter().all(|im| im.valid[i]) {
            buckets[code_value(mid.pixels[i][c]) as usize].push(i);
        }
    }
    let mut rng =
        rand_pcg::Pcg64::seed_from_u64(seed ^ (c as u64).wrapping_mul(0x9E37_79B9_7F4A_7C15));
    let nonempty: Vec<usize> = (0..LEVELS).filter(|&z| !buckets[z].is_empty()).collect();
    if nonempty.is_empty() {
        return Vec::new();
    }
    // the picks as a set over the pixels (ascending, without repeats), so that memory is one
    // flag a pixel however large `n` is; once every candidate is picked, further picks could
    // only repeat one, so the loop stops (the same set as picking all `n`)
    let candidates: usize = buckets.iter().map(Vec::len).sum();
    let mut picked = vec![false; mid.pixels.len()];
    let mut count = 0;
    for k in 0..n {
        if count == candidates {
            break;
        }
        let target = k * nonempty.len() / n;
        let b = &buckets[nonempty[target]];
        let i = b[rng.gen_range(0..b.len())];
        count += usize::from(!picked[i]);
        picked[i] = true;
    }
    (0..picked.len()).filter(|&i| picked[i]).collect()
}

/// Recover the camera response from 8-bit brackets (Debevec & Malik 1997), per channel.
pub fn recover_response(
    images: &[HdrImage],
    times: &[f64],
    p: ResponseParams,
) -> Result<Response, ImagingError> {
    validate_brackets(images, times, &[])?;
    if images.len() < 2 {
        return Err(ImagingError::InvalidInput(
            "response recovery needs at least 2 brackets".into(),
        ));
    }
    if !(p.lambda >= 0.0 && p.lambda.is_finite()) || p.samples < 2 {
        return Err(HdrError::ResponseParams {
            lambda: p.lambda,
            samples: p.samples,
        }
        .into());
    }
    let mut g: [Vec<f64>; 3] = Default::default();
    for (c, gc) in g.iter_mut().enumerate() {
        let samples = select_samples(images, times, c, p.samples, p.seed);
        *gc = channel_response(images, times, c, &samples, p.lambda)?;
    }
    Ok(Response {
        g,
        lambda: p.lambda,
    })
}

/// The log response `g` of channel `c` from the pixels `samples`.
fn channel_response(
    images: &[HdrImage],
    times: &[f64],
    c: usize,
    samples: &[usize],
    lambda: f64,
) -> Result<Vec<f64>, ImagingError> {
    let (mut s_mat, rhs) = response_data_equations(images, times, c, samples);
    s_mat[(128, 128)] += 1.0; // g(128) = 0 row (imposed exactly below)
    for z in 1..LEVELS - 1 {
        let w = lambda * debevec_weight(z as u8);
        let row = [(z - 1, w), (z, -2.0 * w), (z + 1, w)];
        for &(za, va) in &row {
            for &(zb, vb) in &row {
                s_mat[(za, zb)] += va * vb;
            }
        }
    }
    let x = s_mat
        .svd(true, true)
        .solve(&rhs, 1e-12)
        .map_err(HdrError::Solve)?;
    // The data and smoothness rows are invariant under g += const; the weighted g(128) = 0
    // row picks the constant only approximately, so impose it exactly.
    let g128 = x[128];
    let gc: Vec<f64> = x.iter().take(LEVELS).map(|v| v - g128).collect();
    if gc.iter().any(|v| !v.is_finite()) {
        return Err(ImagingError::InvalidInput(
            "response recovery produced non-finite values".into(),
        ));
    }
    Ok(gc)
}

/// Normal equations of the Debevec-Malik data rows with the per-sample unknowns ln E_i
/// eliminated (their block is diagonal): a 256x256 Schur complement in g and its right-hand
/// side.
fn response_data_equations(
    images: &[HdrImage],
    times: &[f64],
    c: usize,
    samples: &[usize],
) -> (DMatrix<f64>, DVector<f64>) {
    let lt: Vec<f64> = times.iter().map(|t| t.ln()).collect();
    let mut s_mat = DMatrix::<f64>::zeros(LEVELS, LEVELS);
    let mut rhs = DVector::<f64>::zeros(LEVELS);
    let mut ci = [0.0f64; LEVELS];
    for &pix in samples {
        let mut touched: Vec<usize> = Vec::with_capacity(images.len());
        let (mut d, mut be) = (0.0f64, 0.0f64);
        for (im, l) in images.iter().zip(&lt) {
            let z = code_value(im.pixels[pix][c]) as usize;
            let w2 = debevec_weight(z as u8).powi(2);
            s_mat[(z, z)] += w2;
            rhs[z] += w2 * l;
            if ci[z] == 0.0 {
                touched.push(z);
            }
            ci[z] -= w2;
            d += w2;
            be -= w2 * l;
        }
        if d > 0.0 {
            for &za in &touched {
                for &zb in &touched {
                    s_mat[(za, zb)] -= ci[za] * ci[zb] / d;
                }
                rhs[za] -= ci[za] * be / d;
            }
        }
        for &z in &touched {
            ci[z] = 0.0;
        }
    }
    (s_mat, rhs)
}

/// Merge 8-bit brackets with a known response (see the module docs).
pub fn merge_ldr(
    images: &[HdrImage],
    times: &[f64],
    resp: &Response,
) -> Result<(HdrImage, MergeStats), ImagingError> {
    validate_brackets(images, times, &[])?;
    let (short, long) = extreme_indices(times);
    let ln_t: Vec<f64> = times.iter().map(|t| t.ln()).collect();
    Ok(merge_per_channel(images, |i, c| {
        let (mut num, mut den) = (0.0f64, 0.0f64);
        for (im, lt) in images.iter().zip(&ln_t) {
            if !im.valid[i] {
                continue;
            }
            let z = code_value(im.pixels[i][c]);
            let wt = debevec_weight(z);
            num += wt * (resp.g[c][z as usize] - lt);
            den += wt;
        }
        if den > 0.0 {
            Ok((num / den).exp() as f32)
        } else {
            let zs = code_value(images[short].pixels[i][c]);
            let ln_e = if zs == 255 {
                resp.g[c][255] - ln_t[short]
            } else {
                resp.g[c][code_value(images[long].pixels[i][c]) as usize] - ln_t[long]
            };
            Err(ln_e.exp() as f32)
        }
    }))
}

#[cfg(test)]
mod tests {
    #[test]
    fn slope_merge_recovers_radiance_despite_a_dark_offset_and_saturation() {
        // 10-bit sensor: value = (offset + L t) quantised, clipped at 1023
        let times = [1.0, 4.0, 16.0, 64.0];
        let radiance = [0.5f64, 5.0, 40.0];
        let offset = 3.0;
        let imgs: Vec<HdrImage> = times
            .iter()
            .map(|&t| {
                let mut im = HdrImage::new(3, 1);
                for (x, &l) in radiance.iter().enumerate() {
                    let code = ((offset + l * t).round()).min(1023.0);
                    im.set(x, 0, [(code / 1023.0) as f32; 3]);
                }
                im
            })
            .collect();
        let (out, stats) = merge_slope(&imgs, &times, SlopeParams::default()).unwrap();
        assert_eq!(stats.valid_fraction, 1.0);
        for (x, &l) in radiance.iter().enumerate() {
            let got = out.get(x, 0)[0] as f64 * 1023.0;
            assert!((got / l - 1.0).abs() < 0.02, "pixel {x}: {got} vs {l}");
        }
        // a pixel saturated in every bracket is invalid, not NaN
        let mut sat = imgs.clone();
        for im in &mut sat {
            im.set(0, 0, [1.0; 3]);
        }
        let (out, _) = merge_slope(&sat, &times, SlopeParams::default()).unwrap();
        assert!(!out.is_valid(0, 0) && out.get(0, 0)[0].is_finite());
        assert!(merge_slope(&imgs, &times, SlopeParams { lo: 0.5, hi: 0.1 }).is_err());
    }

    use super::*;

    /// Smooth radiance field spanning ~2300:1 (11 stops), different per channel. Every pixel
    /// reaches a code of at least ~170 in the longest of the 12 brackets (a pixel whose best
    /// code is below ~80 carries > 1% 8-bit quantisation error whatever the method).
    fn radiance(x: usize, y: usize, w: usize, h: usize) -> [f64; 3] {
        let u = x as f64 / (w - 1) as f64;
        let v = y as f64 / (h - 1) as f64;
        let base = (-5.0 + 6.8 * u).exp() * (1.0 + 0.3 * (7.0 * v).sin());
        [base, base * (0.7 + 0.3 * v), base * (1.2 - 0.4 * u)]
    }

    /// A nonlinear camera response (exposure -> [0, 1]), different per channel.
    fn camera_curve(c: usize, x: f64) -> f64 {
        let gamma = [2.2, 1.9, 2.5][c];
        let y = (x / (1.0 + x * 0.25)).powf(1.0 / gamma);
        y.min(1.0)
    }

    fn render(w: usize, h: usize, times: &[f64]) -> Vec<HdrImage> {
        times
            .iter()
            .map(|&t| {
                let mut im = HdrImage::new(w, h);
                for y in 0..h {
                    for x in 0..w {
                        let e = radiance(x, y, w, h);
                        let mut p = [0.0f32; 3];
                        for c in 0..3 {
                            p[c] = ((camera_curve(c, e[c] * t) * 255.0).round() / 255.0) as f32;
                        }
                        im.set(x, y, p);
                    }
                }
                im
            })
            .collect()
    }

    #[test]
    fn debevec_recovers_synthetic_radiance_within_2_percent() {
        let (w, h) = (160, 100);
        let times: Vec<f64> = (0..12).map(|k| 2f64.powi(k - 4)).collect(); // 1/16 .. 128 s
        let imgs = render(w, h, &times);
        let resp = recover_response(&imgs, &times, ResponseParams::default()).unwrap();
        assert!(resp.is_monotonic_in(2, 253), "response not monotonic");
        for c in 0..3 {
            assert!(resp.g[c][128].abs() < 1e-9);
        }
        let (merged, stats) = merge_ldr(&imgs, &times, &resp).unwrap();
        assert_eq!(stats.exposures, 12);
        // One scalar per channel (Debevec leaves the scale free): least squares in log space.
        let mut worst = 0.0f64;
        let mut errs = Vec::new();
        for c in 0..3 {
            let mut lsum = 0.0;
            let mut n = 0.0;
            for y in 0..h {
                for x in 0..w {
                    if merged.is_valid(x, y) {
                        lsum += (radiance(x, y, w, h)[c] / merged.get(x, y)[c] as f64).ln();
                        n += 1.0;
                    }
                }
            }
            let s = (lsum / n).exp();
            for y in 0..h {
                for x in 0..w {
                    if merged.is_valid(x, y) {
                        let r =
                            (merged.get(x, y)[c] as f64 * s / radiance(x, y, w, h)[c] - 1.0).abs();
                        worst = worst.max(r);
                        errs.push(r);
                    }
                }
            }
        }
        errs.sort_by(|a, b| a.partial_cmp(b).unwrap());
        let p99 = errs[errs.len() * 99 / 100];
        eprintln!(
            "synthetic Debevec: valid {:.4}, max rel err {worst:.4}, p99 {p99:.4}",
            stats.valid_fraction
        );
        assert!(stats.valid_fraction > 0.95);
        // reached: max 1.43 %, p99 0.79 % (lambda 50, 1000 samples, seed 1)
        assert!(worst < 0.02, "max relative error {worst}");
    }

    #[test]
    fn linear_merge_recovers_radiance_and_masks_unusable_pixels() {
        let (w, h) = (64, 8);
        let times = [0.01, 0.1, 1.0];
        let p = LinearParams::default();
        let field = |x: usize| 10f64.powf(-3.5 + 6.0 * x as f64 / (w - 1) as f64); // 3e-4 .. 3e2
        let imgs: Vec<HdrImage> = times
            .iter()
            .map(|&t| {
                let mut im = HdrImage::new(w, h);
                for y in 0..h {
                    for x in 0..w {
                        let v = |k: f64| (field(x) * k * t).min(1.0) as f32;
                        im.set(x, y, [v(1.0), v(0.5), v(0.25)]);
                    }
                }
                im
            })
            .collect();
        let (m, stats) = merge_linear(&imgs, &times, p).unwrap();
        for x in 0..w {
            let e = field(x);
            let usable = |k: f64| {
                (0..3).all(|i| {
                    let z = (e * k * times[i]).min(1.0);
                    z > p.noise_floor as f64 && z < p.saturation as f64
                })
            };
            // valid iff every channel is usable in at least one bracket
            let expect_valid = (0..3).all(|c| {
                let k = [1.0, 0.5, 0.25][c];
                (0..3).any(|i| {
                    let z = (e * k * times[i]).min(1.0);
                    z > p.noise_floor as f64 && z < p.saturation as f64
                })
            });
            let _ = usable;
            assert_eq!(m.is_valid(x, 0), expect_valid, "x={x} e={e}");
            if expect_valid {
                let got = m.get(x, 0);
                for (c, k) in [1.0, 0.5, 0.25].iter().enumerate() {
                    assert!(
                        (got[c] as f64 / (e * k) - 1.0).abs() < 1e-5,
                        "x={x} c={c} got {got:?} e {e}"
                    );
                }
            }
            assert!(m.get(x, 0).iter().all(|v| v.is_finite()));
        }
        // the brightest columns saturate everywhere and the darkest are under the floor
        assert!(!m.is_valid(w - 1, 0) && !m.is_valid(0, 0));
        assert!(stats.valid_fraction > 0.5 && stats.valid_fraction < 1.0);
    }

    #[test]
    fn bracket_validation_errors() {
        let a = HdrImage::new(4, 4);
        let b = HdrImage::new(4, 5);
        let names = vec![
            PathBuf::from("a.png"),
            PathBuf::from("b.png"),
            PathBuf::from("c.png"),
        ];
        let e = validate_brackets(&[a.clone(), b], &[1.0, 2.0], &names)
            .unwrap_err()
            .to_string();
        assert!(e.contains("b.png") && e.contains("different sizes"), "{e}");
        let e = validate_brackets(&[a.clone(), a.clone(), a.clone()], &[1.0, 2.0, 2.0], &names)
            .unwrap_err()
            .to_string();
        assert!(e.contains("c.png") && e.contains("monotonic"), "{e}");
        let e = validate_brackets(&[a.clone(), a.clone(), a.clone()], &[1.0, 0.5, 2.0], &names)
            .unwrap_err()
            .to_string();
        assert!(e.contains("c.png") && e.contains("monotonic"), "{e}");
        let e = validate_brackets(&[a.clone(), a.clone()], &[1.0], &names)
            .unwrap_err()
            .to_string();
        assert!(e.contains("missing exposure times"), "{e}");
        let e = validate_brackets(&[a.clone(), a.clone()], &[1.0, -2.0], &names)
            .unwrap_err()
            .to_string();
        assert!(e.contains("b.png") && e.contains("positive"), "{e}");
        // the same picture as three brackets (issue 36): refused, naming both files
        let e = validate_brackets(&[a.clone(), a.clone(), a.clone()], &[4.0, 2.0, 1.0], &names)
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("b.png") && e.contains("the same picture as a.png"),
            "{e}"
        );
        let scaled = |k: f32| {
            let mut im = a.clone();
            im.pixels.iter_mut().for_each(|p| *p = p.map(|c| c * k + k));
            im
        };
        validate_brackets(
            &[a.clone(), scaled(0.5), scaled(0.25)],
            &[4.0, 2.0, 1.0],
            &names,
        )
        .unwrap();
        assert!((parse_time("1/1024").unwrap() - 1.0 / 1024.0).abs() < 1e-15);
        assert!(parse_time("0").is_err() && parse_time("x").is_err() && parse_time("1/0").is_err());
    }

    #[test]
    fn exif_exposure_time_of_real_jpegs() {
        let dir = igi_testkit::shared_data("mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7");
        for (f, t) in [
            ("ball_10.JPG", 0.1),
            ("ball_40.JPG", 0.025),
            ("ball_160.JPG", 0.00625),
        ] {
            let got = exif_exposure_time(&dir.join(f)).unwrap();
            assert!((got - t).abs() < 1e-9, "{f}: {got}");
        }
        let png = igi_testkit::shared_data("hdr_bracketed/memorial/memorial0061.png");
        let e = exif_exposure_time(&png).unwrap_err().to_string();
        assert!(e.contains("memorial0061.png"), "{e}");
    }

    #[test]
    fn memorial_church_response_and_consistency() {
        let dir = igi_testkit::shared_data("hdr_bracketed/memorial");
        let times = read_times_file(&dir.join("shutter_times.txt")).unwrap();
        assert_eq!(times.len(), 16);
        let imgs: Vec<HdrImage> = (61..=76)
            .map(|k| crate::read_image(&dir.join(format!("memorial{k:04}.png"))).unwrap())
            .collect();
        let resp = recover_response(&imgs, &times, ResponseParams::default()).unwrap();
        assert!(resp.is_monotonic(), "memorial response not monotonic");
        // Two mid exposures, linearised, agree on pixels unsaturated in both.
        // The brackets are scanned film: per pixel they disagree by grain and a slight
        // misregistration (per-pixel median |diff| is ~15%), so compare (a) the total
        // linearised exposure over pixels that are unsaturated (codes 30..=230) in both and
        // (b) 8x8 block means, both scaled by the exposure-time ratio.
        let (w, h) = (imgs[0].width, imgs[0].height);
        let bs = 8;
        let mut worst_global = 0.0f64;
        let mut worst_block_median = 0.0f64;
        for j in 3..7 {
            let k = j + 1;
            let (mut gj, mut gk) = (0.0f64, 0.0f64);
            let mut rel = Vec::new();
            for c in 0..3 {
                for by in 0..h / bs {
                    for bx in 0..w / bs {
                        let (mut sj, mut sk, mut all) = (0.0, 0.0, true);
                        for y in by * bs..(by + 1) * bs {
                            for x in bx * bs..(bx + 1) * bs {
                                let zj = code_value(imgs[j].get(x, y)[c]);
                                let zk = code_value(imgs[k].get(x, y)[c]);
                                let ej = resp.exposure(c, zj) / times[j];
                                let ek = resp.exposure(c, zk) / times[k];
                                if (30..=230).contains(&zj) && (30..=230).contains(&zk) {
                                    gj += ej;
                                    gk += ek;
                                } else {
                                    all = false;
                                }
                                sj += ej;
                                sk += ek;
                            }
                        }
                        if all {
                            rel.push((sj / sk - 1.0).abs());
                        }
                    }
                }
            }
            rel.sort_by(|a, b| a.partial_cmp(b).unwrap());
            let med = rel[rel.len() / 2];
            let global = (gj / gk - 1.0).abs();
            eprintln!("memorial t={} vs t={}: global |rel diff| {global:.4}, 8x8 blocks: {} median |rel diff| {med:.4}", times[j], times[k], rel.len());
            assert!(rel.len() > 50);
            worst_global = worst_global.max(global);
            worst_block_median = worst_block_median.max(med);
        }
        eprintln!(
            "memorial: worst global {worst_global:.4}, worst block median {worst_block_median:.4}"
        );
        assert!(
            worst_global < 0.05,
            "global relative difference {worst_global}"
        );
        assert!(
            worst_block_median < 0.05,
            "block median relative difference {worst_block_median}"
        );
        let (merged, stats) = merge_ldr(&imgs, &times, &resp).unwrap();
        eprintln!("memorial merge: valid fraction {:.4}", stats.valid_fraction);
        assert!(stats.valid_fraction > 0.99);
        assert!(merged
            .pixels
            .iter()
            .all(|p| p.iter().all(|v| v.is_finite() && *v > 0.0)));
    }
}
