//! The picture of a photo whose light was estimated (issue 34 item 4, docs/SKY.md "Outputs"):
//! the photograph | its re-rendering under the fitted sky with the solved albedo | the fitted
//! sky as a lat-long of the whole sphere (zenith at the top, azimuth from +X toward +Y, the
//! sun ringed in red). The photograph and the re-rendering share one exposure (the
//! photograph's median luminance at 0.18, as `igi probe`'s pictures); the sky has its own.

use glam::Vec3;
use igi_imaging::auto_exposure;
use igi_imaging::latlong::direction_to_pixel;
use igi_imaging::HdrImage;

/// Black columns between the panels.
const GAP: usize = 4;

/// The three panels side by side, exposed for display (write it with exposure 1). The
/// re-rendering must have the photograph's size; the sky panel is `2 H x H` for photographs
/// `H` high, sampled from `sky` (nearest pixel). Invalid (masked) photograph pixels are dark
/// magenta.
pub fn lighting_picture(
    photo: &HdrImage,
    render: &HdrImage,
    sky: &HdrImage,
    sun: Option<[f64; 3]>,
) -> HdrImage {
    let (w, h) = (photo.width, photo.height);
    let sw = 2 * h;
    let mut out = HdrImage::new(2 * w + sw + 2 * GAP, h);
    let e = auto_exposure(photo);
    for y in 0..h {
        for x in 0..w {
            let i = y * w + x;
            let p = if photo.valid[i] {
                photo.pixels[i].map(|c| c * e)
            } else {
                [0.25, 0.0, 0.25]
            };
            out.set(x, y, p);
            if x < render.width && y < render.height {
                out.set(w + GAP + x, y, render.get(x, y).map(|c| c * e));
            }
        }
    }
    // the sky's exposure from its upper half (the ground below is not the sky's)
    let upper = HdrImage {
        height: sky.height / 2,
        pixels: sky.pixels[..sky.width * (sky.height / 2)].to_vec(),
        valid: vec![true; sky.width * (sky.height / 2)],
        width: sky.width,
    };
    let es = auto_exposure(&upper);
    let x0 = 2 * (w + GAP);
    for y in 0..h {
        for x in 0..sw {
            let mx = (x * sky.width / sw).min(sky.width - 1);
            let my = (y * sky.height / h).min(sky.height - 1);
            out.set(x0 + x, y, sky.get(mx, my).map(|c| c * es));
        }
    }
    if let Some(s) = sun {
        let d = Vec3::new(s[0] as f32, s[1] as f32, s[2] as f32);
        let (cx, cy) = direction_to_pixel(d, sw, h);
        let r = (h as f32 / 16.0).max(3.0);
        for y in 0..h {
            for x in 0..sw {
                let dx = (x as f32 - cx).abs();
                // the ring wraps around the map's seam
                let dx = dx.min(sw as f32 - dx);
                let dist = (dx * dx + (y as f32 - cy).powi(2)).sqrt();
                if (dist - r).abs() <= 1.0 {
                    out.set(x0 + x, y, [1.0, 0.0, 0.0]);
                }
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn panels_side_by_side_and_the_sun_ringed() {
        let mut photo = HdrImage::new(20, 10);
        photo.pixels.iter_mut().for_each(|p| *p = [2.0; 3]);
        photo.valid[0] = false;
        let render = photo.clone();
        let mut sky = HdrImage::new(64, 32);
        sky.pixels.iter_mut().for_each(|p| *p = [0.5; 3]);
        // the sun straight up the +X meridian at 45 degrees
        let s = std::f64::consts::FRAC_1_SQRT_2;
        let pic = lighting_picture(&photo, &render, &sky, Some([s, 0.0, s]));
        assert_eq!((pic.width, pic.height), (2 * 20 + 20 + 2 * GAP, 10));
        // photograph and re-rendering at one exposure (median at 0.18)
        assert!(
            (pic.get(5, 5)[1] - 0.18).abs() < 1e-4,
            "{:?}",
            pic.get(5, 5)
        );
        assert_eq!(pic.get(5, 5), pic.get(20 + GAP + 5, 5));
        assert_eq!(pic.get(0, 0), [0.25, 0.0, 0.25]);
        // the sky panel at its own exposure, the sun's ring red
        let x0 = 2 * (20 + GAP);
        assert!((pic.get(x0 + 10, 8)[1] - 0.18).abs() < 1e-4);
        let red = (0..20)
            .flat_map(|x| (0..10).map(move |y| (x, y)))
            .filter(|&(x, y)| pic.get(x0 + x, y) == [1.0, 0.0, 0.0])
            .count();
        assert!(red > 0);
    }
}
