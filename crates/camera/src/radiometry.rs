//! Radiometric calibration: lens falloff (vignetting), 3x3 colour matrices, the colour checker
//! (reference values and patch sampling from its four corners), and the camera radiometry file
//! that `igi camera radiometry` writes and surveys apply to every photograph on load.

use crate::{CameraError, RadiometryError};
use glam::DVec2;
use igi_formats::radiometry::{FalloffTerms, RadiometryFile};
use igi_imaging::HdrImage;
use nalgebra::{DMatrix, DVector, Matrix3};
use std::path::Path;

pub use igi_formats::radiometry::RadiometryFit;

/// Radial falloff `f(r) = 1 + a2 r^2 + a4 r^4 + a6 r^6`, `r` = distance from the image
/// centre divided by the half-diagonal (so r = 1 at the corners), f(0) = 1.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct Falloff {
    pub a2: f64,
    pub a4: f64,
    pub a6: f64,
}

impl Falloff {
    /// `f(r)`, evaluated by the file model's polynomial (`FalloffTerms::eval`).
    pub fn eval(&self, r: f64) -> f64 {
        self.terms().eval(r)
    }

    /// The coefficients as the radiometry file holds them.
    fn terms(&self) -> FalloffTerms {
        FalloffTerms {
            a2: self.a2,
            a4: self.a4,
            a6: self.a6,
        }
    }

    /// Normalised radius of pixel (x, y) (pixel centres at integers) in a `w` x `h` image.
    pub fn radius(x: f64, y: f64, w: usize, h: usize) -> f64 {
        let cx = (w as f64 - 1.0) * 0.5;
        let cy = (h as f64 - 1.0) * 0.5;
        let half_diag = 0.5 * ((w * w + h * h) as f64).sqrt();
        ((x - cx).powi(2) + (y - cy).powi(2)).sqrt() / half_diag
    }

    /// Least-squares fit of `value = s f(r)` (centre value `s` free) to `(r, value)` samples.
    /// Returns the falloff and `s`.
    pub fn fit(samples: &[(f64, f64)]) -> Result<(Falloff, f64), CameraError> {
        if samples.len() < 4 {
            return Err(RadiometryError::FewSamples(samples.len()).into());
        }
        if samples
            .iter()
            .any(|(r, v)| !r.is_finite() || !v.is_finite())
        {
            return Err(CameraError::InvalidInput(
                "falloff samples contain NaN or infinite values".into(),
            ));
        }
        let mut a = DMatrix::<f64>::zeros(samples.len(), 4);
        let mut b = DVector::<f64>::zeros(samples.len());
        for (i, &(r, v)) in samples.iter().enumerate() {
            let r2 = r * r;
            a[(i, 0)] = 1.0;
            a[(i, 1)] = r2;
            a[(i, 2)] = r2 * r2;
            a[(i, 3)] = r2 * r2 * r2;
            b[i] = v;
        }
        let x = a.svd(true, true).solve(&b, 1e-12).map_err(|e| {
            CameraError::from(RadiometryError::Solve {
                what: "falloff",
                msg: e.to_string(),
            })
        })?;
        let s = x[0];
        if !(s.abs() > 0.0) || !s.is_finite() {
            return Err(CameraError::InvalidInput(
                "falloff fit: centre value is zero (flat field too dark?)".into(),
            ));
        }
        Ok((
            Falloff {
                a2: x[1] / s,
                a4: x[2] / s,
                a6: x[3] / s,
            },
            s,
        ))
    }

    /// Fit to a flat-field image (mean of the three channels of every valid pixel).
    pub fn fit_image(flat: &HdrImage) -> Result<(Falloff, f64), CameraError> {
        let mut samples = Vec::with_capacity(flat.pixels.len());
        for y in 0..flat.height {
            for x in 0..flat.width {
                if flat.is_valid(x, y) {
                    let p = flat.get(x, y);
                    samples.push((
                        Self::radius(x as f64, y as f64, flat.width, flat.height),
                        (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0,
                    ));
                }
            }
        }
        Self::fit(&samples)
    }

    /// The forward model: multiply `img` by the falloff in place (what the lens does; for
    /// synthetic photographs).
    pub fn vignette(&self, img: &mut HdrImage) {
        for y in 0..img.height {
            for x in 0..img.width {
                let f = self
                    .eval(Self::radius(x as f64, y as f64, img.width, img.height))
                    .max(0.0) as f32;
                let i = img.index(x, y);
                img.pixels[i] = img.pixels[i].map(|c| c * f);
            }
        }
    }

    /// Divide the falloff out of `img` in place (pixels where f(r) <= 0 become invalid).
    pub fn apply(&self, img: &mut HdrImage) {
        for y in 0..img.height {
            for x in 0..img.width {
                let f = self.eval(Self::radius(x as f64, y as f64, img.width, img.height));
                let i = img.index(x, y);
                if f > 1e-6 {
                    for c in 0..3 {
                        img.pixels[i][c] = (img.pixels[i][c] as f64 / f) as f32;
                    }
                } else {
                    img.pixels[i] = [0.0; 3];
                    img.valid[i] = false;
                }
            }
        }
    }
}

/// Least-squares 3x3 colour matrix `M` with `target ~= M * source` (e.g. camera RGB of
/// colour-checker patches -> their reference linear RGB). Needs at least 3 pairs spanning
/// colour space.
pub fn fit_color_matrix(
    source: &[[f64; 3]],
    target: &[[f64; 3]],
) -> Result<[[f64; 3]; 3], CameraError> {
    if source.len() != target.len() {
        return Err(RadiometryError::PatchCount {
            patches: source.len(),
            targets: target.len(),
        }
        .into());
    }
    if source.len() < 3 {
        return Err(CameraError::InvalidInput(
            "colour matrix needs at least 3 patches".into(),
        ));
    }
    if source
        .iter()
        .chain(target)
        .flatten()
        .any(|v| !v.is_finite())
    {
        return Err(CameraError::InvalidInput(
            "colour patches contain NaN or infinite values".into(),
        ));
    }
    let n = source.len();
    let a = DMatrix::<f64>::from_fn(n, 3, |i, j| source[i][j]);
    let svd = a.clone().svd(true, true);
    let sv = &svd.singular_values;
    let (smax, smin) = (sv.max(), sv.min());
    if !(smin > smax * 1e-9) {
        return Err(CameraError::InvalidInput(
            "colour patches are degenerate (do not span RGB)".into(),
        ));
    }
    let mut m = [[0.0; 3]; 3];
    for r in 0..3 {
        let b = DVector::<f64>::from_fn(n, |i, _| target[i][r]);
        let x = svd.solve(&b, 1e-12).map_err(|e| {
            CameraError::from(RadiometryError::Solve {
                what: "colour matrix",
                msg: e.to_string(),
            })
        })?;
        m[r] = [x[0], x[1], x[2]];
    }
    Ok(m)
}

/// Apply a colour matrix to every pixel in place.
pub fn apply_color_matrix(img: &mut HdrImage, m: &[[f64; 3]; 3]) {
    let mm = Matrix3::from_fn(|r, c| m[r][c] as f32);
    for p in &mut img.pixels {
        let v = mm * nalgebra::Vector3::new(p[0], p[1], p[2]);
        *p = [v.x, v.y, v.z];
    }
}

/// Fit one falloff to several flat-field photographs of the same lens setting: each is
/// normalised by its own fitted centre value, then all samples are fitted together (every
/// `stride`-th pixel so that at most about 200 000 samples are used). Returns the falloff and
/// the RMS of the relative residual `v / (s f(r)) - 1`.
pub fn fit_falloff_flats(flats: &[HdrImage]) -> Result<(Falloff, f64), CameraError> {
    let first = flats
        .first()
        .ok_or_else(|| CameraError::from(RadiometryError::NoFlats))?;
    if let Some(k) = flats
        .iter()
        .position(|f| f.width != first.width || f.height != first.height)
    {
        return Err(RadiometryError::FlatSize {
            index: k + 1,
            size: (flats[k].width, flats[k].height),
            first: (first.width, first.height),
        }
        .into());
    }
    let n = first.width * first.height;
    let stride = (n * flats.len()).div_ceil(200_000).max(1);
    let mut samples = Vec::new();
    for flat in flats {
        let (_, s) = Falloff::fit_image(flat)?;
        for i in (0..n).step_by(stride) {
            if flat.valid[i] {
                let (x, y) = ((i % flat.width) as f64, (i / flat.width) as f64);
                let p = flat.pixels[i];
                let v = (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0;
                samples.push((Falloff::radius(x, y, flat.width, flat.height), v / s));
            }
        }
    }
    let (f, s) = Falloff::fit(&samples)?;
    let ss: f64 = samples
        .iter()
        .map(|(r, v)| (v / (s * f.eval(*r)) - 1.0).powi(2))
        .sum();
    Ok((f, (ss / samples.len() as f64).sqrt()))
}

/// The 24 patches of the ColorChecker Classic in reading order (row 0 from dark skin to
/// bluish green, ..., row 3 from white to black), as 8-bit sRGB (the published D50-adapted
/// sRGB values); [`checker_reference`] linearises them.
const CHECKER_SRGB8: [[u8; 3]; 24] = [
    [115, 82, 68],
    [194, 150, 130],
    [98, 122, 157],
    [87, 108, 67],
    [133, 128, 177],
    [103, 189, 170],
    [214, 126, 44],
    [80, 91, 166],
    [193, 90, 99],
    [94, 60, 108],
    [157, 188, 64],
    [224, 163, 46],
    [56, 61, 150],
    [70, 148, 73],
    [175, 54, 60],
    [231, 199, 31],
    [187, 86, 149],
    [8, 133, 161],
    [243, 243, 242],
    [200, 200, 200],
    [160, 160, 160],
    [122, 122, 121],
    [85, 85, 85],
    [52, 52, 52],
];

/// Columns and rows of the ColorChecker Classic patch grid.
pub const CHECKER_COLS: usize = 6;
pub const CHECKER_ROWS: usize = 4;

/// Linear-RGB reflectance of the 24 ColorChecker Classic patches in reading order.
pub fn checker_reference() -> [[f64; 3]; 24] {
    CHECKER_SRGB8.map(|p| p.map(|c| igi_imaging::io::srgb_to_linear(c as f32 / 255.0) as f64))
}

/// Chart coordinates (patch pitches, x along a row, y down the columns) of the patch grid's
/// outer corners in the order top-left (dark skin), top-right (bluish green), bottom-right
/// (black), bottom-left (white).
fn checker_grid_corners() -> [DVec2; 4] {
    let (w, h) = (CHECKER_COLS as f64, CHECKER_ROWS as f64);
    [
        DVec2::ZERO,
        DVec2::new(w, 0.0),
        DVec2::new(w, h),
        DVec2::new(0.0, h),
    ]
}

/// Mean camera RGB of each of the 24 patches, given the image positions of the patch grid's
/// four outer corners (top-left at dark skin, top-right, bottom-right at black, bottom-left at
/// white). Each patch is sampled on a 9 x 9 grid over its central 60 % (away from the black
/// gaps); a patch with fewer than half of its samples valid and inside the image is an error.
pub fn sample_checker(img: &HdrImage, corners: &[DVec2; 4]) -> Result<Vec<[f64; 3]>, CameraError> {
    let h = crate::planar::homography_dlt(&checker_grid_corners(), corners)?;
    let mut out = Vec::with_capacity(24);
    for k in 0..CHECKER_COLS * CHECKER_ROWS {
        let centre = DVec2::new(
            (k % CHECKER_COLS) as f64 + 0.5,
            (k / CHECKER_COLS) as f64 + 0.5,
        );
        let (mut sum, mut n) = ([0.0f64; 3], 0usize);
        for j in 0..9 {
            for i in 0..9 {
                let q = centre + 0.3 * DVec2::new(i as f64 / 4.0 - 1.0, j as f64 / 4.0 - 1.0);
                let v = crate::planar::apply_homography(&h, q)
                    .and_then(|p| img.bilinear(p.x as f32, p.y as f32));
                if let Some(v) = v {
                    for c in 0..3 {
                        sum[c] += v[c] as f64;
                    }
                    n += 1;
                }
            }
        }
        if n < 41 {
            return Err(RadiometryError::Patch {
                index: k + 1,
                usable: n,
            }
            .into());
        }
        out.push(sum.map(|s| s / n as f64));
    }
    Ok(out)
}

/// A synthetic photograph of the ColorChecker Classic for tests: a `w` x `h` image of
/// `background` radiance with the 24 patches (each `reference * white`, 80 % of its cell, the
/// rest black gap) inside the grid whose outer corners are `corners` (see [`sample_checker`]).
/// Each pixel is the mean of 4 x 4 sub-samples.
pub fn render_checker(
    w: usize,
    h: usize,
    corners: &[DVec2; 4],
    white: f64,
    background: f64,
) -> Result<HdrImage, CameraError> {
    let to_chart = crate::planar::homography_dlt(corners, &checker_grid_corners())?;
    let reference = checker_reference();
    let mut img = HdrImage::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let mut sum = [0.0f64; 3];
            for s in 0..16 {
                let p = DVec2::new(
                    x as f64 + ((s % 4) as f64 + 0.5) / 4.0 - 0.5,
                    y as f64 + ((s / 4) as f64 + 0.5) / 4.0 - 0.5,
                );
                let v = match crate::planar::apply_homography(&to_chart, p) {
                    Some(q)
                        if q.x >= 0.0
                            && q.y >= 0.0
                            && q.x < CHECKER_COLS as f64
                            && q.y < CHECKER_ROWS as f64 =>
                    {
                        let (fx, fy) = (q.x.fract(), q.y.fract());
                        if (0.1..0.9).contains(&fx) && (0.1..0.9).contains(&fy) {
                            reference[q.y as usize * CHECKER_COLS + q.x as usize].map(|c| c * white)
                        } else {
                            [0.01 * white; 3]
                        }
                    }
                    _ => [background; 3],
                };
                for c in 0..3 {
                    sum[c] += v[c] / 16.0;
                }
            }
            img.set(x, y, sum.map(|c| c as f32));
        }
    }
    Ok(img)
}

/// How far the chart box of OpenCV's `mcc` detector lies outside the patch grid, in patch
/// pitches. Its ColorChecker Classic model (`MCC24`) has 2.5-unit patches at a 2.75-unit pitch
/// and a box 0.25 units outside the outer patches, so the box is the patch grid of
/// [`sample_checker`] (cells one pitch wide, the patch centred in each) grown by half a gap,
/// 0.125 units, on every side. The box follows from the patch centres the detector matched,
/// not from the patches' size.
pub const MCC_BOX_MARGIN: f64 = 0.125 / 2.75;

/// The patch grid's outer corners (in [`sample_checker`]'s order) from the four corners of a
/// detected chart box (see [`MCC_BOX_MARGIN`]) given in any order around the chart. Which box
/// corner is the dark-skin one is decided by the colours: of the four rotations of the box (a
/// photographed chart is never mirrored), the one whose 24 sampled patches a colour matrix
/// ([`fit_checker_matrix`]) fits best. Returns the corners and that fit's RMS relative error;
/// [`RadiometryError::CheckerNotFound`] when no rotation gives 24 usable patches.
pub fn checker_corners_from_box(
    img: &HdrImage,
    chart_box: &[DVec2; 4],
) -> Result<([DVec2; 4], f64), CameraError> {
    let mut b = *chart_box;
    if signed_area(&b) < 0.0 {
        b.reverse(); // clockwise on the image (y down), as the grid corners are
    }
    let (m, w, h) = (MCC_BOX_MARGIN, CHECKER_COLS as f64, CHECKER_ROWS as f64);
    let box_in_grid = [
        DVec2::new(-m, -m),
        DVec2::new(w + m, -m),
        DVec2::new(w + m, h + m),
        DVec2::new(-m, h + m),
    ];
    let mut best: Option<([DVec2; 4], f64)> = None;
    for r in 0..4 {
        let dst = [0, 1, 2, 3].map(|k| b[(k + r) % 4]);
        let Ok(hm) = crate::planar::homography_dlt(&box_in_grid, &dst) else {
            continue;
        };
        let grid: Option<Vec<DVec2>> = checker_grid_corners()
            .iter()
            .map(|c| crate::planar::apply_homography(&hm, *c))
            .collect();
        let Some(g) = grid else { continue };
        let corners = [g[0], g[1], g[2], g[3]];
        let fit = sample_checker(img, &corners).and_then(|p| fit_checker_matrix(&p, None));
        if let Ok((_, rms)) = fit {
            if best.is_none_or(|(_, e)| rms < e) {
                best = Some((corners, rms));
            }
        }
    }
    best.ok_or_else(|| RadiometryError::CheckerNotFound.into())
}

/// Refines patch-grid corners that are good to about a tenth of a patch (a detector's) by the
/// patches' centroids. Each patch's colour is the mean over its centre, the gap's the median at
/// the 15 inner grid crossings; the pixels of the patch's cell nearer the patch colour than
/// halfway to the gap's are the patch, and their centroid its centre. Patches too close to the
/// gap's colour (the contrast under a fifth of the patch's brightness) are left out; a
/// homography from the 24 grid centres to the others gives the new corners. Three rounds; the
/// input comes back unchanged where fewer than 8 patches are usable.
pub fn refine_checker_corners(img: &HdrImage, corners: &[DVec2; 4]) -> [DVec2; 4] {
    let mut c = *corners;
    for _ in 0..3 {
        match refine_checker_once(img, &c) {
            Some(next) => c = next,
            None => break,
        }
    }
    c
}

fn refine_checker_once(img: &HdrImage, corners: &[DVec2; 4]) -> Option<[DVec2; 4]> {
    use crate::planar::{apply_homography, homography_dlt};
    let to_img = homography_dlt(&checker_grid_corners(), corners).ok()?;
    let to_grid = homography_dlt(corners, &checker_grid_corners()).ok()?;
    let at = |x: f64, y: f64| {
        apply_homography(&to_img, DVec2::new(x, y))
            .and_then(|p| img.bilinear(p.x as f32, p.y as f32))
            .map(|v| v.map(|c| c as f64))
    };
    let crossings: Vec<[f64; 3]> = (1..CHECKER_COLS)
        .flat_map(|i| (1..CHECKER_ROWS).map(move |j| (i as f64, j as f64)))
        .filter_map(|(x, y)| at(x, y))
        .collect();
    if crossings.is_empty() {
        return None;
    }
    let gap = [0, 1, 2].map(|ch| {
        let mut v: Vec<f64> = crossings.iter().map(|p| p[ch]).collect();
        igi_imaging::color::median_in_place(&mut v)
    });
    let (mut centres, mut found) = (Vec::new(), Vec::new());
    for k in 0..CHECKER_COLS * CHECKER_ROWS {
        let cell = DVec2::new((k % CHECKER_COLS) as f64, (k / CHECKER_COLS) as f64);
        if let Some(p) = patch_centroid(img, &to_img, &to_grid, cell, gap) {
            centres.push(cell + DVec2::splat(0.5));
            found.push(p);
        }
    }
    if found.len() < 8 {
        return None;
    }
    let h = homography_dlt(&centres, &found).ok()?;
    let g = checker_grid_corners().map(|q| apply_homography(&h, q));
    let next = [g[0]?, g[1]?, g[2]?, g[3]?];
    // a move beyond a quarter of a patch pitch is not a refinement: keep the input
    let pitch = (corners[1] - corners[0]).length() / CHECKER_COLS as f64;
    let moved = next.iter().zip(corners).map(|(a, b)| (*a - *b).length());
    moved
        .fold(0.0, f64::max)
        .le(&(0.25 * pitch))
        .then_some(next)
}

/// Centroid (pixels) of the patch in grid cell `cell` (its top-left corner in grid units), or
/// `None` when the patch cannot be told from the gap colour `gap`.
fn patch_centroid(
    img: &HdrImage,
    to_img: &glam::DMat3,
    to_grid: &glam::DMat3,
    cell: DVec2,
    gap: [f64; 3],
) -> Option<DVec2> {
    use crate::planar::apply_homography;
    let mut colour = [0.0; 3];
    for j in 0..5 {
        for i in 0..5 {
            let q = cell + DVec2::new(0.3 + 0.1 * i as f64, 0.3 + 0.1 * j as f64);
            let p = apply_homography(to_img, q)?;
            let v = img.bilinear(p.x as f32, p.y as f32)?;
            (0..3).for_each(|ch| colour[ch] += v[ch] as f64 / 25.0);
        }
    }
    let dist =
        |a: [f64; 3], b: [f64; 3]| (0..3).map(|ch| (a[ch] - b[ch]).powi(2)).sum::<f64>().sqrt();
    let contrast = dist(colour, gap);
    if !(contrast > 0.2 * dist(colour, [0.0; 3])) {
        return None;
    }
    let cell_px: Vec<DVec2> = [(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]
        .iter()
        .map(|&(x, y)| apply_homography(to_img, cell + DVec2::new(x, y)))
        .collect::<Option<_>>()?;
    let lo = cell_px
        .iter()
        .fold(DVec2::INFINITY, |a, p| a.min(*p))
        .floor()
        .max(DVec2::ZERO);
    let hi = cell_px
        .iter()
        .fold(DVec2::NEG_INFINITY, |a, p| a.max(*p))
        .ceil();
    let hi = hi.min(DVec2::new(img.width as f64 - 1.0, img.height as f64 - 1.0));
    let (mut sum, mut n) = (DVec2::ZERO, 0usize);
    for y in lo.y as usize..=hi.y.max(lo.y) as usize {
        for x in lo.x as usize..=hi.x.max(lo.x) as usize {
            let p = DVec2::new(x as f64, y as f64);
            let inside = apply_homography(to_grid, p).is_some_and(|g| {
                let f = g - cell;
                (0.0..1.0).contains(&f.x) && (0.0..1.0).contains(&f.y)
            });
            let v = img.get(x, y).map(|c| c as f64);
            if inside && img.is_valid(x, y) && dist(v, colour) < 0.5 * contrast {
                sum += p;
                n += 1;
            }
        }
    }
    let area = (cell_px[2] - cell_px[0])
        .perp_dot(cell_px[3] - cell_px[1])
        .abs()
        * 0.5;
    (n as f64 > 0.25 * area).then(|| sum / n as f64)
}

/// Twice the signed area of a quadrilateral (shoelace); positive when its corners run
/// clockwise on an image whose y axis points down.
fn signed_area(q: &[DVec2; 4]) -> f64 {
    (0..4).map(|i| q[i].perp_dot(q[(i + 1) % 4])).sum()
}

/// The neutral patches (white to black) of the ColorChecker Classic, by index.
const CHECKER_NEUTRALS: std::ops::Range<usize> = 18..24;

/// The colour matrix from the camera RGB of the 24 patches. With `white` (the radiance a
/// perfect white diffuser shows under the chart's light, in the units the photographs should
/// have), the matrix maps camera RGB to absolute radiance: `reference * white`. Without it the
/// chart's brightness is unknown, and the matrix is scaled so that the neutral patches keep
/// their luminance (colour is corrected, exposure left alone). Returns the matrix and the RMS
/// relative error of the corrected patches.
pub fn fit_checker_matrix(
    camera_rgb: &[[f64; 3]],
    white: Option<f64>,
) -> Result<([[f64; 3]; 3], f64), CameraError> {
    if camera_rgb.len() != CHECKER_COLS * CHECKER_ROWS {
        return Err(RadiometryError::CheckerPatches(camera_rgb.len()).into());
    }
    if let Some(w) = white {
        if !(w > 0.0) || !w.is_finite() {
            return Err(RadiometryError::White(w).into());
        }
    }
    let reference = checker_reference();
    let target: Vec<[f64; 3]> = reference
        .iter()
        .map(|r| r.map(|c| c * white.unwrap_or(1.0)))
        .collect();
    let mut m = fit_color_matrix(camera_rgb, &target)?;
    if white.is_none() {
        let (mut before, mut after) = (0.0, 0.0);
        for k in CHECKER_NEUTRALS {
            before += igi_imaging::color::luminance_f64(camera_rgb[k]);
            after += igi_imaging::color::luminance_f64(mat_vec(&m, &camera_rgb[k]));
        }
        if !(after > 0.0) || !(before > 0.0) {
            return Err(CameraError::InvalidInput(
                "colour checker: the neutral patches are black".into(),
            ));
        }
        m = m.map(|row| row.map(|v| v * before / after));
    }
    let scale = igi_imaging::color::luminance_f64(mat_vec(&m, &camera_rgb[18]))
        / igi_imaging::color::luminance_f64(reference[18]);
    let ss: f64 = camera_rgb
        .iter()
        .zip(&reference)
        .flat_map(|(s, r)| {
            let c = mat_vec(&m, s);
            (0..3).map(move |i| ((c[i] - r[i] * scale) / (r[i] * scale).max(1e-3 * scale)).powi(2))
        })
        .sum();
    Ok((m, (ss / (3.0 * camera_rgb.len() as f64)).sqrt()))
}

fn mat_vec(m: &[[f64; 3]; 3], v: &[f64; 3]) -> [f64; 3] {
    [0, 1, 2].map(|r| m[r][0] * v[0] + m[r][1] * v[1] + m[r][2] * v[2])
}

/// A camera's radiometric calibration (the camera radiometry file, JSON, read and written by
/// `igi_formats::radiometry`): the lens falloff divided out first, then the colour matrix
/// applied (`corrected = M * (raw / f(r))`).
#[derive(Clone, Debug, PartialEq)]
pub struct CameraRadiometry {
    /// Image size the calibration was fitted at; photographs must have the same aspect ratio
    /// (the falloff's radius is normalised by the half-diagonal, so any size of that shape works).
    pub width: usize,
    pub height: usize,
    pub falloff: Option<Falloff>,
    pub color_matrix: Option<[[f64; 3]; 3]>,
    /// How the fit went (informative; ignored when applying).
    pub fit: RadiometryFit,
}

impl CameraRadiometry {
    /// Reads and checks a camera radiometry file (naming it in every error).
    pub fn load(path: &Path) -> Result<CameraRadiometry, CameraError> {
        Ok(Self::from_file(RadiometryFile::read(path)?))
    }

    /// The calibration a (checked) radiometry file holds.
    pub fn from_file(file: RadiometryFile) -> CameraRadiometry {
        CameraRadiometry {
            width: file.width,
            height: file.height,
            falloff: file.falloff.map(|f| Falloff {
                a2: f.a2,
                a4: f.a4,
                a6: f.a6,
            }),
            color_matrix: file.color_matrix,
            fit: file.fit,
        }
    }

    /// The radiometry file of this calibration.
    pub fn to_file(&self) -> RadiometryFile {
        RadiometryFile {
            width: self.width,
            height: self.height,
            falloff: self.falloff.map(|f| f.terms()),
            color_matrix: self.color_matrix,
            fit: self.fit.clone(),
        }
    }

    /// Checks the calibration and writes the file atomically (pretty JSON).
    pub fn save(&self, path: &Path) -> Result<(), CameraError> {
        Ok(self.to_file().write(path)?)
    }

    /// Whether an image of `w` x `h` has the calibration's aspect ratio (within 1 %).
    pub fn fits_size(&self, w: usize, h: usize) -> bool {
        let a = (w as f64 / h as f64) / (self.width as f64 / self.height as f64);
        (a - 1.0).abs() < 0.01
    }

    /// Corrects a photograph in place: falloff divided out, then the colour matrix.
    /// Negative values the matrix may produce (noise in dark pixels) are clamped to zero.
    pub fn apply(&self, img: &mut HdrImage) {
        if let Some(f) = &self.falloff {
            f.apply(img);
        }
        if let Some(m) = &self.color_matrix {
            apply_color_matrix(img, m);
            for p in &mut img.pixels {
                *p = p.map(|c| c.max(0.0));
            }
        }
    }
}

/// The inputs of a radiometry fit: flat fields (any number, possibly none) and a photographed
/// colour checker with its four patch-grid corners (optional).
pub struct RadiometryInputs<'a> {
    pub flats: &'a [HdrImage],
    pub checker: Option<(&'a HdrImage, [DVec2; 4])>,
    /// Radiance of a perfect white under the chart's light (absolute calibration), if known.
    pub white: Option<f64>,
}

/// Fits the falloff (from the flat fields) and the colour matrix (from the checker, after the
/// falloff is divided out of it). At least one of the two must be given; all images must have
/// the same size.
pub fn fit_radiometry(inputs: &RadiometryInputs) -> Result<CameraRadiometry, CameraError> {
    let size = match (inputs.flats.first(), &inputs.checker) {
        (Some(f), _) => (f.width, f.height),
        (None, Some((c, _))) => (c.width, c.height),
        (None, None) => return Err(RadiometryError::NothingToFit.into()),
    };
    if let Some((c, _)) = &inputs.checker {
        if (c.width, c.height) != size {
            return Err(RadiometryError::CheckerSize {
                size: (c.width, c.height),
                flats: size,
            }
            .into());
        }
    }
    let (falloff, falloff_rms) = match inputs.flats.is_empty() {
        true => (None, None),
        false => fit_falloff_flats(inputs.flats).map(|(f, rms)| (Some(f), Some(rms)))?,
    };
    let (color_matrix, color_rms) = match &inputs.checker {
        None => (None, None),
        Some((img, corners)) => {
            let mut img = (*img).clone();
            if let Some(f) = &falloff {
                f.apply(&mut img);
            }
            let patches = sample_checker(&img, corners)?;
            let (m, rms) = fit_checker_matrix(&patches, inputs.white)?;
            (Some(m), Some(rms))
        }
    };
    Ok(CameraRadiometry {
        width: size.0,
        height: size.1,
        falloff,
        color_matrix,
        fit: RadiometryFit {
            flat_fields: inputs.flats.len(),
            falloff_rms,
            color_rms,
            white: inputs.white,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn falloff_fit_recovers_known_polynomial() {
        let truth = Falloff {
            a2: -0.35,
            a4: 0.08,
            a6: -0.03,
        };
        let (w, h) = (120, 80);
        let mut flat = HdrImage::new(w, h);
        let mut rng = rand_pcg::Pcg64::seed_from_u64(11);
        for y in 0..h {
            for x in 0..w {
                let f = truth.eval(Falloff::radius(x as f64, y as f64, w, h));
                let v = (0.7 * f * (1.0 + rng.gen_range(-0.002..0.002))) as f32;
                flat.set(x, y, [v, v, v]);
            }
        }
        let (fit, s) = Falloff::fit_image(&flat).unwrap();
        assert!((s - 0.7).abs() < 1e-3, "{s}");
        for r in [0.0, 0.3, 0.6, 0.9, 1.0] {
            assert!(
                (fit.eval(r) - truth.eval(r)).abs() < 2e-3,
                "r={r}: {} vs {}",
                fit.eval(r),
                truth.eval(r)
            );
        }
        assert!((fit.a2 - truth.a2).abs() < 0.02, "{fit:?}");
        // corners: r = 1 exactly at the outer pixel corner; the corner pixel centre is just inside
        assert!(Falloff::radius(0.0, 0.0, w, h) < 1.0 && Falloff::radius(0.0, 0.0, w, h) > 0.98);
        fit.apply(&mut flat);
        for p in &flat.pixels {
            assert!((p[0] / 0.7 - 1.0).abs() < 0.006, "{p:?}");
        }
        assert!(Falloff::fit(&[(0.0, 1.0)]).is_err());
    }

    fn noisy(img: &mut HdrImage, rel: f64, seed: u64) {
        let mut rng = rand_pcg::Pcg64::seed_from_u64(seed);
        for p in &mut img.pixels {
            *p = p.map(|c| (c as f64 * (1.0 + rng.gen_range(-rel..rel))) as f32);
        }
    }

    const CROSSTALK: [[f64; 3]; 3] = [[0.8, 0.15, 0.05], [0.1, 0.75, 0.15], [0.05, 0.2, 0.7]];
    const TRUE_FALLOFF: Falloff = Falloff {
        a2: -0.4,
        a4: 0.1,
        a6: -0.05,
    };
    const CHECKER_CORNERS: [DVec2; 4] = [
        DVec2::new(20.0, 18.0),
        DVec2::new(145.0, 25.0),
        DVec2::new(140.0, 105.0),
        DVec2::new(15.0, 98.0),
    ];

    /// The test camera: vignetting by [`TRUE_FALLOFF`], then [`CROSSTALK`].
    fn through_camera(img: &mut HdrImage) {
        TRUE_FALLOFF.vignette(img);
        apply_color_matrix(img, &CROSSTALK);
    }

    /// Two noisy flat fields and a noisy checker of white radiance `white`, `w x h`.
    fn calibration_photos(w: usize, h: usize, white: f64) -> (Vec<HdrImage>, HdrImage) {
        let mut flats = Vec::new();
        for (k, level) in [0.4f32, 0.9].iter().enumerate() {
            let mut f = HdrImage::new(w, h);
            f.pixels.iter_mut().for_each(|p| *p = [*level; 3]);
            through_camera(&mut f);
            noisy(&mut f, 0.003, k as u64);
            flats.push(f);
        }
        let mut checker = render_checker(w, h, &CHECKER_CORNERS, white, 0.3).unwrap();
        through_camera(&mut checker);
        noisy(&mut checker, 0.003, 9);
        (flats, checker)
    }

    /// The fitted falloff and matrix against the truth and the inverse crosstalk.
    fn check_fit(cal: &CameraRadiometry) {
        let f = cal.falloff.unwrap();
        for r in [0.0, 0.5, 0.8, 1.0] {
            assert!(
                (f.eval(r) - TRUE_FALLOFF.eval(r)).abs() < 3e-3,
                "falloff at {r}: {} vs {}",
                f.eval(r),
                TRUE_FALLOFF.eval(r)
            );
        }
        let inv = Matrix3::from_fn(|r, c| CROSSTALK[r][c])
            .try_inverse()
            .unwrap();
        let m = cal.color_matrix.unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!(
                    (m[r][c] - inv[(r, c)]).abs() < 0.03,
                    "matrix {m:?} vs inverse {inv}"
                );
            }
        }
        assert!(
            cal.fit.color_rms.unwrap() < 0.03 && cal.fit.falloff_rms.unwrap() < 0.003,
            "{:?}",
            cal.fit
        );
    }

    /// Saves and loads `cal`, then corrects a photograph through the test camera back to
    /// within 2 % of the scene.
    fn check_round_trip_and_correction(cal: &CameraRadiometry, w: usize, h: usize) {
        let mut scene = HdrImage::new(w, h);
        for (i, p) in scene.pixels.iter_mut().enumerate() {
            *p = [
                0.2 + 0.5 * (i % w) as f32 / w as f32,
                0.6,
                0.1 + 0.6 * (i / w) as f32 / h as f32,
            ];
        }
        let mut photo = scene.clone();
        through_camera(&mut photo);
        let dir = tempfile::tempdir().unwrap();
        let file = dir.path().join("radiometry.json");
        cal.save(&file).unwrap();
        let back = CameraRadiometry::load(&file).unwrap();
        let (bm, cm) = (back.color_matrix.unwrap(), cal.color_matrix.unwrap());
        assert!(
            bm.iter()
                .flatten()
                .zip(cm.iter().flatten())
                .all(|(a, b)| (a - b).abs() < 1e-12),
            "JSON round trip"
        );
        assert_eq!(back.falloff, cal.falloff);
        back.apply(&mut photo);
        for (a, b) in photo.pixels.iter().zip(&scene.pixels) {
            for c in 0..3 {
                assert!((a[c] / b[c] - 1.0).abs() < 0.02, "{a:?} vs {b:?}");
            }
        }
    }

    /// Flat fields and a checker photographed through a vignetting lens with colour crosstalk:
    /// the fit recovers the falloff and the inverse of the crosstalk, and the calibration file
    /// corrects a photograph back to the truth.
    #[test]
    fn radiometry_fit_recovers_falloff_and_inverse_crosstalk() {
        let (w, h) = (160, 120);
        let white = 2.5;
        let (flats, checker) = calibration_photos(w, h, white);
        let cal = fit_radiometry(&RadiometryInputs {
            flats: &flats,
            checker: Some((&checker, CHECKER_CORNERS)),
            white: Some(white),
        })
        .unwrap();
        check_fit(&cal);
        // a photograph through the same camera is corrected back to within 1 %
        check_round_trip_and_correction(&cal, w, h);
        // without the white radiance the matrix keeps the grey patches' luminance
        let rel = fit_radiometry(&RadiometryInputs {
            flats: &flats,
            checker: Some((&checker, CHECKER_CORNERS)),
            white: None,
        })
        .unwrap();
        let cm = rel.color_matrix.unwrap();
        let g = [0.3, 0.3, 0.3];
        let mixed = mat_vec(&CROSSTALK, &g);
        assert!(
            (igi_imaging::color::luminance_f64(mat_vec(&cm, &mixed))
                / igi_imaging::color::luminance_f64(mixed)
                - 1.0)
                .abs()
                < 0.03
        );
    }

    /// The box a detector reports (the grid grown by [`MCC_BOX_MARGIN`]), in any rotation and
    /// either direction, gives back the grid corners with dark skin first: for an upright chart,
    /// one upside down and one on its side, through a camera with colour crosstalk.
    #[test]
    fn checker_orientation_from_a_box_in_any_corner_order() {
        let mix = [[0.8, 0.15, 0.05], [0.1, 0.75, 0.15], [0.05, 0.2, 0.7]];
        let upright = [
            DVec2::new(30.0, 25.0),
            DVec2::new(205.0, 35.0),
            DVec2::new(200.0, 150.0),
            DVec2::new(25.0, 140.0),
        ];
        let turned = [upright[2], upright[3], upright[0], upright[1]];
        let side = [
            DVec2::new(170.0, 10.0),
            DVec2::new(175.0, 170.0),
            DVec2::new(60.0, 165.0),
            DVec2::new(55.0, 15.0),
        ];
        for truth in [upright, turned, side] {
            let mut img = render_checker(240, 180, &truth, 1.5, 0.25).unwrap();
            apply_color_matrix(&mut img, &mix);
            noisy(&mut img, 0.01, 3);
            let to_img = crate::planar::homography_dlt(&checker_grid_corners(), &truth).unwrap();
            let (m, w, h) = (MCC_BOX_MARGIN, 6.0, 4.0);
            let bx = [(-m, -m), (w + m, -m), (w + m, h + m), (-m, h + m)]
                .map(|(x, y)| crate::planar::apply_homography(&to_img, DVec2::new(x, y)).unwrap());
            for r in 0..4 {
                for reverse in [false, true] {
                    let mut given = [0, 1, 2, 3].map(|k| bx[(k + r) % 4]);
                    if reverse {
                        given.reverse();
                    }
                    let (c, rms) = checker_corners_from_box(&img, &given).unwrap();
                    for (a, b) in c.iter().zip(&truth) {
                        assert!((*a - *b).length() < 1e-6, "{c:?} vs {truth:?}");
                    }
                    assert!(rms < 0.05, "{rms}");
                }
            }
        }
        // a box around a featureless image: no rotation gives 24 usable patches
        let blank = HdrImage::new(240, 180);
        let far = [
            DVec2::new(300.0, 10.0),
            DVec2::new(400.0, 10.0),
            DVec2::new(400.0, 90.0),
            DVec2::new(300.0, 90.0),
        ];
        assert!(matches!(
            checker_corners_from_box(&blank, &far),
            Err(CameraError::RadiometryFit(RadiometryError::CheckerNotFound))
        ));
    }

    /// Corners off by 2-4 px (a detector's error on a 57 px pitch) come back to within a
    /// fraction of a pixel, on a noisy photo through a camera with crosstalk.
    #[test]
    fn checker_corners_refined_by_patch_centroids() {
        let mix = [[0.8, 0.15, 0.05], [0.1, 0.75, 0.15], [0.05, 0.2, 0.7]];
        let truth = [
            DVec2::new(150.0, 118.0),
            DVec2::new(492.0, 135.0),
            DVec2::new(480.0, 372.0),
            DVec2::new(138.0, 350.0),
        ];
        let mut img = render_checker(640, 480, &truth, 1.2, 0.18).unwrap();
        apply_color_matrix(&mut img, &mix);
        noisy(&mut img, 0.02, 4);
        let off = [(2.8, -2.9), (0.4, 3.9), (-2.2, 2.7), (-2.4, -2.2)];
        let start: [DVec2; 4] = [0, 1, 2, 3].map(|k| truth[k] + DVec2::new(off[k].0, off[k].1));
        let refined = refine_checker_corners(&img, &start);
        let err = refined
            .iter()
            .zip(&truth)
            .map(|(a, b)| (*a - *b).length())
            .fold(0.0, f64::max);
        eprintln!("refined corners {refined:?}, max error {err:.3} px");
        assert!(err < 0.3, "{refined:?} vs {truth:?}: {err} px");
        // already at the truth: stays there
        let again = refine_checker_corners(&img, &truth);
        assert!(again
            .iter()
            .zip(&truth)
            .all(|(a, b)| (*a - *b).length() < 0.3));
        // nothing to refine against: the input comes back
        let blank = HdrImage::new(640, 480);
        assert_eq!(refine_checker_corners(&blank, &start), start);
    }

    #[test]
    fn radiometry_rejects_bad_inputs_and_files() {
        assert!(fit_radiometry(&RadiometryInputs {
            flats: &[],
            checker: None,
            white: None
        })
        .is_err());
        let flats = [HdrImage::new(10, 10), HdrImage::new(12, 10)];
        assert!(fit_falloff_flats(&flats).is_err());
        // a chart outside the image
        let img = HdrImage::new(40, 30);
        let far = [
            DVec2::new(100.0, 100.0),
            DVec2::new(160.0, 100.0),
            DVec2::new(160.0, 140.0),
            DVec2::new(100.0, 140.0),
        ];
        assert!(sample_checker(&img, &far).is_err());
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.json");
        for bad in [
            "{",
            r#"{"width": 4, "height": 3, "falloff": null, "color_matrix": null}"#,
            r#"{"width": 4, "height": 3, "falloff": {"a2": -2.0, "a4": 0.0, "a6": 0.0}, "color_matrix": null}"#,
            r#"{"width": 4, "height": 3, "falloff": null, "color_matrix": [[1,0,0],[0,1,0],[0,0,0]]}"#,
            r#"{"width": 4, "height": 3, "falloff": null, "color_matrix": [[1,0,0],[0,1,0],[0,0,1]], "extra": 1}"#,
        ] {
            std::fs::write(&p, bad).unwrap();
            let e = CameraRadiometry::load(&p).unwrap_err().to_string();
            assert!(e.contains("r.json"), "{e}");
        }
        std::fs::write(&p, r#"{"width": 4, "height": 3, "falloff": null, "color_matrix": [[1,0,0],[0,1,0],[0,0,1]]}"#).unwrap();
        let ok = CameraRadiometry::load(&p).unwrap();
        assert!(ok.fits_size(400, 300) && !ok.fits_size(400, 400));
    }

    #[test]
    fn color_matrix_recovered_from_noisy_patches() {
        let m = [[1.6, -0.4, -0.2], [-0.3, 1.5, -0.2], [0.05, -0.5, 1.45]];
        let mut rng = rand_pcg::Pcg64::seed_from_u64(5);
        let mut src = Vec::new();
        let mut dst = Vec::new();
        for _ in 0..24 {
            let s = [
                rng.gen_range(0.02..0.9),
                rng.gen_range(0.02..0.9),
                rng.gen_range(0.02..0.9),
            ];
            let mut t = [0.0; 3];
            for r in 0..3 {
                t[r] = (0..3).map(|c| m[r][c] * s[c]).sum::<f64>()
                    * (1.0 + rng.gen_range(-0.005..0.005));
            }
            src.push(s);
            dst.push(t);
        }
        let fit = fit_color_matrix(&src, &dst).unwrap();
        for r in 0..3 {
            for c in 0..3 {
                assert!((fit[r][c] - m[r][c]).abs() < 0.02, "{fit:?}");
            }
        }
        let mut img = HdrImage::new(1, 1);
        img.pixels[0] = [1.0, 0.0, 0.0];
        apply_color_matrix(&mut img, &m);
        assert!((img.pixels[0][0] - 1.6).abs() < 1e-6 && (img.pixels[0][2] - 0.05).abs() < 1e-6);
        // degenerate: all grey patches
        let grey: Vec<[f64; 3]> = (1..6).map(|i| [i as f64 * 0.1; 3]).collect();
        assert!(fit_color_matrix(&grey, &grey).is_err());
        assert!(fit_color_matrix(&src[..2], &dst[..2]).is_err());
    }
}
