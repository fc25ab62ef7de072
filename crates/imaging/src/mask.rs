//! Binary masks (silhouettes): thresholding, disk dilation and erosion, hole filling up to an
//! area, the report of a mask touching the image frame, IoU, PNG I/O.
//!
//! Row-major with row 0 at the top, like [`HdrImage`]. Morphology uses a Euclidean disk of
//! radius `r` pixels (offsets with `dx^2 + dy^2 <= r^2`); pixels outside the frame count as
//! background for dilation and as foreground for erosion (so erosion does not eat a silhouette
//! that leaves the frame).

use crate::{HdrImage, ImagingError};
use std::path::Path;

/// A binary image: `true` is the object.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    pub width: usize,
    pub height: usize,
    pub data: Vec<bool>,
}

/// How many mask pixels lie on each border row or column of the frame.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct FrameContact {
    pub top: usize,
    pub bottom: usize,
    pub left: usize,
    pub right: usize,
}

impl FrameContact {
    /// True when any border pixel is set.
    pub fn touches(&self) -> bool {
        self.top + self.bottom + self.left + self.right > 0
    }
}

impl Mask {
    /// All-background mask.
    pub fn new(width: usize, height: usize) -> Mask {
        Mask {
            width,
            height,
            data: vec![false; width * height],
        }
    }

    #[inline]
    pub fn get(&self, x: usize, y: usize) -> bool {
        self.data[y * self.width + x]
    }

    #[inline]
    pub fn set(&mut self, x: usize, y: usize, v: bool) {
        self.data[y * self.width + x] = v;
    }

    /// Pixels whose largest channel exceeds `t` (invalid pixels are background).
    pub fn threshold(img: &HdrImage, t: f32) -> Mask {
        let data = img
            .pixels
            .iter()
            .zip(&img.valid)
            .map(|(p, &ok)| ok && p[0].max(p[1]).max(p[2]) > t)
            .collect();
        Mask {
            width: img.width,
            height: img.height,
            data,
        }
    }

    /// Read a mask image: non-zero pixels are the object (FORMATS.md).
    pub fn load(path: &Path) -> Result<Mask, ImagingError> {
        Ok(Self::threshold(&crate::read_image(path)?, 0.0))
    }

    /// Write as an 8-bit greyscale PNG (255 object, 0 background), atomically.
    pub fn save_png(&self, path: &Path) -> Result<(), ImagingError> {
        let bytes: Vec<u8> = self.data.iter().map(|&b| if b { 255 } else { 0 }).collect();
        let img = ::image::GrayImage::from_raw(self.width as u32, self.height as u32, bytes)
            .ok_or_else(|| ImagingError::Encode {
                path: path.to_path_buf(),
                msg: "mask size does not match its data".into(),
            })?;
        igi_files::write_atomic(path, |tmp| {
            img.save_with_format(tmp, ::image::ImageFormat::Png)
                .map_err(|e| ImagingError::encode_failed(path, e))
        })
    }

    /// Number of object pixels.
    pub fn count(&self) -> usize {
        self.data.iter().filter(|b| **b).count()
    }

    /// Intersection over union with a mask of the same size (1 when both are empty).
    pub fn iou(&self, other: &Mask) -> f64 {
        assert_eq!(
            (self.width, self.height),
            (other.width, other.height),
            "IoU of masks of different sizes"
        );
        let (mut inter, mut union) = (0usize, 0usize);
        for (a, b) in self.data.iter().zip(&other.data) {
            inter += (*a && *b) as usize;
            union += (*a || *b) as usize;
        }
        if union == 0 {
            1.0
        } else {
            inter as f64 / union as f64
        }
    }

    /// Dilation by a disk of radius `r` pixels.
    pub fn dilate(&self, r: f64) -> Mask {
        self.morph(r, true)
    }

    /// Erosion by a disk of radius `r` pixels (outside the frame counts as object).
    pub fn erode(&self, r: f64) -> Mask {
        self.morph(r, false)
    }

    /// Dilation (`grow`) stamps the disk around every object pixel that has a background
    /// 4-neighbour; erosion does the same to the complement.
    fn morph(&self, r: f64, grow: bool) -> Mask {
        let offs = disk_offsets(r);
        let (w, h) = (self.width as i64, self.height as i64);
        let src = |x: i64, y: i64| -> bool {
            if x < 0 || y < 0 || x >= w || y >= h {
                !grow
            } else {
                self.data[(y * w + x) as usize] == grow
            }
        };
        let mut out = self.clone();
        for y in 0..h {
            for x in 0..w {
                if !src(x, y) {
                    continue;
                }
                let edge = [(1, 0), (-1, 0), (0, 1), (0, -1)]
                    .iter()
                    .any(|(dx, dy)| !src(x + dx, y + dy));
                if !edge {
                    continue;
                }
                for &(dx, dy) in &offs {
                    let (xx, yy) = (x + dx, y + dy);
                    if xx >= 0 && yy >= 0 && xx < w && yy < h {
                        out.data[(yy * w + xx) as usize] = grow;
                    }
                }
            }
        }
        out
    }

    /// Fill every background region that does not touch the frame and has at most `max_area`
    /// pixels (4-connected regions). Returns the number of pixels filled.
    pub fn fill_holes(&mut self, max_area: usize) -> usize {
        let (w, h) = (self.width, self.height);
        let mut seen = vec![false; w * h];
        let mut filled = 0;
        let mut stack = Vec::new();
        let mut region = Vec::new();
        for start in 0..w * h {
            if self.data[start] || seen[start] {
                continue;
            }
            region.clear();
            let mut on_frame = false;
            seen[start] = true;
            stack.push(start);
            while let Some(i) = stack.pop() {
                region.push(i);
                let (x, y) = (i % w, i / w);
                on_frame |= x == 0 || y == 0 || x + 1 == w || y + 1 == h;
                let mut visit = |j: usize| {
                    if !self.data[j] && !seen[j] {
                        seen[j] = true;
                        stack.push(j);
                    }
                };
                if x > 0 {
                    visit(i - 1);
                }
                if x + 1 < w {
                    visit(i + 1);
                }
                if y > 0 {
                    visit(i - w);
                }
                if y + 1 < h {
                    visit(i + w);
                }
            }
            if !on_frame && region.len() <= max_area {
                for &i in &region {
                    self.data[i] = true;
                }
                filled += region.len();
            }
        }
        filled
    }

    /// Object pixels on each border of the frame.
    pub fn frame_contact(&self) -> FrameContact {
        let (w, h) = (self.width, self.height);
        if w == 0 || h == 0 {
            return FrameContact::default();
        }
        let row = |y: usize| (0..w).filter(|&x| self.get(x, y)).count();
        let col = |x: usize| (0..h).filter(|&y| self.get(x, y)).count();
        FrameContact {
            top: row(0),
            bottom: row(h - 1),
            left: col(0),
            right: col(w - 1),
        }
    }
}

/// Integer offsets of a Euclidean disk of radius `r` (always includes (0, 0)).
fn disk_offsets(r: f64) -> Vec<(i64, i64)> {
    let ri = r.max(0.0).floor() as i64;
    let mut v = Vec::new();
    for dy in -ri..=ri {
        for dx in -ri..=ri {
            if ((dx * dx + dy * dy) as f64) <= r * r {
                v.push((dx, dy));
            }
        }
    }
    if v.is_empty() {
        v.push((0, 0));
    }
    v
}

#[cfg(test)]
mod tests {
    use super::*;

    fn dot(w: usize, h: usize, pts: &[(usize, usize)]) -> Mask {
        let mut m = Mask::new(w, h);
        for &(x, y) in pts {
            m.set(x, y, true);
        }
        m
    }

    #[test]
    fn dilating_a_point_gives_the_disk_and_erosion_undoes_it() {
        let m = dot(41, 41, &[(20, 20)]);
        let d = m.dilate(10.0);
        // number of lattice points with x^2 + y^2 <= 100 is 317
        assert_eq!(d.count(), 317);
        assert!(d.get(30, 20) && d.get(20, 10) && !d.get(28, 28) && d.get(27, 27));
        let e = d.erode(10.0);
        assert_eq!(e, m);
        // erosion of a disk by a smaller disk leaves the smaller-radius disk
        let e = d.erode(7.0);
        assert_eq!(e.count(), dot(41, 41, &[(20, 20)]).dilate(3.0).count());
    }

    #[test]
    fn erosion_keeps_objects_that_leave_the_frame() {
        let mut m = Mask::new(10, 10);
        for y in 0..10 {
            for x in 0..4 {
                m.set(x, y, true);
            }
        }
        let e = m.erode(2.0);
        // the left border is not eaten, the right edge moves in by 2
        assert!(e.get(0, 0) && e.get(1, 5) && !e.get(2, 5) && !e.get(3, 5));
        let c = m.frame_contact();
        assert_eq!(
            c,
            FrameContact {
                top: 4,
                bottom: 4,
                left: 10,
                right: 0
            }
        );
        assert!(c.touches());
        assert!(!dot(5, 5, &[(2, 2)]).frame_contact().touches());
    }

    #[test]
    fn fill_holes_fills_small_enclosed_regions_only() {
        let mut m = Mask::new(12, 12);
        for y in 1..11 {
            for x in 1..11 {
                m.set(x, y, true);
            }
        }
        // a 2x2 hole and a 3x3 hole inside; a notch open to the frame
        for (x, y) in [(3, 3), (4, 3), (3, 4), (4, 4)] {
            m.set(x, y, false);
        }
        for y in 6..9 {
            for x in 6..9 {
                m.set(x, y, false);
            }
        }
        let before = m.count();
        assert_eq!(m.fill_holes(4), 4);
        assert_eq!(m.count(), before + 4);
        assert!(m.get(3, 3) && !m.get(7, 7));
        assert_eq!(m.fill_holes(9), 9);
        assert!(m.get(7, 7) && !m.get(0, 0));
    }

    #[test]
    fn threshold_iou_and_png_round_trip() {
        let mut img = HdrImage::new(4, 2);
        img.set(1, 0, [0.0, 0.3, 0.0]);
        img.set(2, 1, [0.5, 0.5, 0.5]);
        let i = img.index(3, 1);
        img.pixels[i] = [1.0; 3];
        img.valid[i] = false;
        let m = Mask::threshold(&img, 0.19);
        assert_eq!(
            m.data,
            vec![false, true, false, false, false, false, true, false]
        );
        let other = dot(4, 2, &[(1, 0), (0, 0)]);
        assert!((m.iou(&other) - 1.0 / 3.0).abs() < 1e-12);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.png");
        m.save_png(&p).unwrap();
        assert_eq!(Mask::load(&p).unwrap(), m);
    }
}
