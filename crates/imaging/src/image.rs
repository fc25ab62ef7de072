//! The in-memory linear HDR image.

/// Linear RGB image, row-major with row 0 at the top. `valid[i] == false` marks
/// saturated or otherwise unusable pixels (their `pixels` value is finite, usually 0).
#[derive(Clone, Debug, PartialEq)]
pub struct HdrImage {
    pub width: usize,
    pub height: usize,
    pub pixels: Vec<[f32; 3]>,
    pub valid: Vec<bool>,
}

impl HdrImage {
    /// Black image, all pixels valid.
    pub fn new(width: usize, height: usize) -> Self {
        HdrImage {
            width,
            height,
            pixels: vec![[0.0; 3]; width * height],
            valid: vec![true; width * height],
        }
    }

    #[inline]
    pub fn index(&self, x: usize, y: usize) -> usize {
        debug_assert!(x < self.width && y < self.height);
        y * self.width + x
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize) -> [f32; 3] {
        self.pixels[self.index(x, y)]
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: [f32; 3]) {
        let i = self.index(x, y);
        self.pixels[i] = v;
    }

    #[inline]
    pub fn is_valid(&self, x: usize, y: usize) -> bool {
        self.valid[self.index(x, y)]
    }

    /// Fraction of valid pixels (1 for an empty image).
    pub fn valid_fraction(&self) -> f64 {
        if self.valid.is_empty() {
            return 1.0;
        }
        self.valid.iter().filter(|v| **v).count() as f64 / self.valid.len() as f64
    }

    /// Bilinear lookup at continuous pixel coordinates (pixel centres at integers).
    /// `None` if the point lies outside `[0, W-1] x [0, H-1]` or any tap with non-zero
    /// weight is invalid.
    pub fn bilinear(&self, x: f32, y: f32) -> Option<[f32; 3]> {
        if !(x.is_finite() && y.is_finite()) || self.width == 0 || self.height == 0 {
            return None;
        }
        if x < 0.0 || y < 0.0 || x > (self.width - 1) as f32 || y > (self.height - 1) as f32 {
            return None;
        }
        // x, y >= 0 here: truncation is floor, without a libm call
        let x0 = (x as usize).min(self.width - 1);
        let y0 = (y as usize).min(self.height - 1);
        let fx = x - x0 as f32;
        let fy = y - y0 as f32;
        let mut out = [0.0f32; 3];
        for (dy, wy) in [(0usize, 1.0 - fy), (1, fy)] {
            if wy <= 0.0 {
                continue;
            }
            for (dx, wx) in [(0usize, 1.0 - fx), (1, fx)] {
                if wx <= 0.0 {
                    continue;
                }
                let (xx, yy) = (x0 + dx, y0 + dy);
                if xx >= self.width || yy >= self.height {
                    return None;
                }
                let i = yy * self.width + xx;
                if !self.valid[i] {
                    return None;
                }
                let w = wx * wy;
                for (o, v) in out.iter_mut().zip(self.pixels[i]) {
                    *o += w * v;
                }
            }
        }
        Some(out)
    }

    /// Multiply every pixel by `s`.
    pub fn scale(&mut self, s: f32) {
        for p in &mut self.pixels {
            for c in p.iter_mut() {
                *c *= s;
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn psnr_inside_counts_only_the_mask() {
        let mut a = HdrImage::new(2, 1);
        let b = HdrImage::new(2, 1);
        a.pixels[0] = [0.1, 0.1, 0.1];
        a.pixels[1] = [9.0, 9.0, 9.0];
        // MSE 0.01 inside at peak 1: 20 dB; the outside pixel is ignored
        let db = a.psnr_inside(&b, &[true, false], 1.0).unwrap();
        assert!((db - 20.0).abs() < 1e-5, "{db}");
        assert_eq!(
            a.psnr_inside(&b, &[false, true], 1.0).map(|x| x < 0.0),
            Some(true)
        );
        assert!(a.psnr_inside(&b, &[false, false], 1.0).is_none());
        assert!(b.psnr_inside(&b, &[true, true], 1.0).unwrap().is_infinite());
    }

    #[test]
    fn bilinear_interpolates_linear_ramp_exactly() {
        let mut im = HdrImage::new(4, 3);
        for y in 0..3 {
            for x in 0..4 {
                im.set(x, y, [x as f32, y as f32, (2 * x + 3 * y) as f32]);
            }
        }
        let v = im.bilinear(1.25, 0.5).unwrap();
        assert!(
            (v[0] - 1.25).abs() < 1e-6 && (v[1] - 0.5).abs() < 1e-6 && (v[2] - 4.0).abs() < 1e-5
        );
        // Exactly on the last pixel centre is inside.
        let v = im.bilinear(3.0, 2.0).unwrap();
        assert_eq!(v, [3.0, 2.0, 12.0]);
        assert!(im.bilinear(3.01, 1.0).is_none());
        assert!(im.bilinear(-0.01, 1.0).is_none());
        assert!(im.bilinear(f32::NAN, 1.0).is_none());
    }

    #[test]
    fn bilinear_rejects_invalid_taps_with_weight() {
        let mut im = HdrImage::new(3, 3);
        let i = im.index(1, 1);
        im.valid[i] = false;
        assert!(im.bilinear(0.5, 0.5).is_none());
        // zero weight on the invalid tap is fine
        assert!(im.bilinear(0.0, 1.0).is_some());
        assert!((im.valid_fraction() - 8.0 / 9.0).abs() < 1e-12);
    }
}
