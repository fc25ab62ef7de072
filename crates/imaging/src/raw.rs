//! Camera RAW files (DNG and the raw formats of common cameras) decoded to linear RGB, behind
//! the optional `raw` feature (the decoder is `rawler`, LGPL-2.1, of the dnglab project).
//!
//! The pipeline (docs/IMAGING.md, "Camera RAW"):
//!
//! 1. `rawler` decodes the file; its black level is subtracted and each photosite scaled by
//!    its white level (`(v - black) / (white - black)`), the colour filter array demosaiced
//!    (PPG for Bayer sensors, bilinear for X-Trans), and the image cropped to the file's
//!    active area and default crop. This is linear camera RGB, 1 at the sensor's white level.
//! 2. A pixel with any camera channel at or above [`RAW_CLIP`] is clipped: invalid and 0.
//! 3. The file's white balance (`wb`, e.g. `1 / AsShotNeutral` in a DNG) multiplies each
//!    camera channel, and the file's colour matrix (XYZ to camera, the D65 one, else another
//!    Bradford-adapted to D65) takes camera RGB to linear Rec. 709 / sRGB primaries:
//!    `rgb = inverse(normalize_rows(xyz_to_cam * SRGB_TO_XYZ_D65)) * (wb * cam)` (the
//!    convention of dcraw and rawler: a white-balanced camera white is RGB white). Unlike
//!    rawler's own `Calibrate` step nothing is clipped or compressed: the result stays linear
//!    above 1.
//!
//! The orientation flag is not applied (photogrammetry tools pose the pixel grid as stored).
//! Four-colour filter arrays and monochrome sensors are refused by name.

use crate::{HdrImage, ImagingError};
use std::path::Path;

/// The file extensions read as camera RAW (lower case).
pub const RAW_EXTENSIONS: &[&str] = &[
    "dng", "cr2", "cr3", "crw", "nef", "nrw", "arw", "srf", "sr2", "raf", "orf", "rw2", "pef",
    "srw", "3fr", "iiq", "erf", "mef", "mos", "kdc", "dcr", "x3f",
];

/// Whether `path`'s extension is one of [`RAW_EXTENSIONS`].
pub fn is_raw_path(path: &Path) -> bool {
    path.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .is_some_and(|e| RAW_EXTENSIONS.contains(&e.as_str()))
}

/// A camera channel (scaled so that the white level is 1) at or above this is clipped.
pub const RAW_CLIP: f32 = 0.999;

/// A RAW file decoded: linear RGB (Rec. 709 primaries), clipped pixels invalid.
#[derive(Clone, Debug)]
pub struct RawPhoto {
    pub image: HdrImage,
    /// Pixels masked as clipped.
    pub clipped: usize,
    /// The white balance applied to camera R, G, B.
    pub wb: [f32; 3],
    /// Camera RGB (white balanced) to linear Rec. 709 RGB, rows.
    pub cam_to_rgb: [[f32; 3]; 3],
}

/// The sRGB (Rec. 709) primaries to XYZ, D65 white (IEC 61966-2-1).
pub const SRGB_TO_XYZ_D65: [[f64; 3]; 3] = [
    [0.4124564, 0.3575761, 0.1804375],
    [0.2126729, 0.7151522, 0.0721750],
    [0.0193339, 0.1191920, 0.9503041],
];

/// The matrix taking white-balanced camera RGB to linear Rec. 709 RGB, from the file's XYZ to
/// camera matrix (rows: camera R, G, B): `inverse(normalize_rows(xyz_to_cam * SRGB_TO_XYZ))`.
/// `None` when the matrix is singular or not finite.
pub fn camera_to_rgb(xyz_to_cam: [[f32; 3]; 3]) -> Option<[[f32; 3]; 3]> {
    let x = nalgebra::Matrix3::from_fn(|r, c| xyz_to_cam[r][c] as f64);
    let s = nalgebra::Matrix3::from_fn(|r, c| SRGB_TO_XYZ_D65[r][c]);
    let mut rgb_to_cam = x * s;
    for r in 0..3 {
        let sum: f64 = rgb_to_cam.row(r).sum();
        if !(sum.abs() > 1e-12) {
            return None;
        }
        for c in 0..3 {
            rgb_to_cam[(r, c)] /= sum;
        }
    }
    // rows sum to 1: a determinant this small is a singular matrix, not a camera
    if !(rgb_to_cam.determinant().abs() > 1e-9) {
        return None;
    }
    let inv = rgb_to_cam.try_inverse()?;
    let out: [[f32; 3]; 3] = std::array::from_fn(|r| std::array::from_fn(|c| inv[(r, c)] as f32));
    out.iter().flatten().all(|v| v.is_finite()).then_some(out)
}

#[cfg(feature = "raw")]
fn fail(path: &Path, msg: impl Into<String>) -> ImagingError {
    ImagingError::Decode {
        path: path.to_path_buf(),
        msg: msg.into(),
    }
}

/// Reads the camera RAW file `path` (module docs). Without the `raw` feature this is an error
/// saying so.
#[cfg(not(feature = "raw"))]
pub fn read_raw(path: &Path) -> Result<RawPhoto, ImagingError> {
    Err(ImagingError::Decode {
        path: path.to_path_buf(),
        msg: "is a camera RAW file, and this igi was built without the `raw` feature \
              (cargo build --features raw); convert it to a 16-bit linear TIFF instead"
            .into(),
    })
}

/// Reads the camera RAW file `path` (module docs).
#[cfg(feature = "raw")]
pub fn read_raw(path: &Path) -> Result<RawPhoto, ImagingError> {
    use rawler::imgop::develop::{Intermediate, ProcessingStep, RawDevelop};
    use rawler::imgop::xyz::Illuminant;

    if !path.is_file() {
        return Err(ImagingError::Io {
            path: path.to_path_buf(),
            source: std::io::Error::new(std::io::ErrorKind::NotFound, "no such file"),
        });
    }
    // rawler has `todo!()`s and panics on some malformed files: a panic is this file's error.
    let decoded = std::panic::catch_unwind(|| -> Result<_, String> {
        let raw = rawler::decode_file(path).map_err(|e| e.to_string())?;
        let dev = RawDevelop::new_with(&[
            ProcessingStep::Rescale,
            ProcessingStep::Demosaic,
            ProcessingStep::FujiRotate,
            ProcessingStep::CropActiveArea,
            ProcessingStep::CropDefault,
        ]);
        let img = dev.develop_intermediate(&raw).map_err(|e| e.to_string())?;
        Ok((raw, img))
    });
    let (raw, img) = match decoded {
        Ok(Ok(v)) => v,
        Ok(Err(e)) => return Err(fail(path, format!("camera RAW: {e}"))),
        Err(_) => return Err(fail(path, "camera RAW: the decoder failed on this file")),
    };
    let cam = match img {
        Intermediate::ThreeColor(c) => c,
        Intermediate::Monochrome(_) => {
            return Err(fail(
                path,
                "camera RAW from a monochrome sensor is not supported",
            ))
        }
        Intermediate::FourColor(_) => {
            return Err(fail(
                path,
                "camera RAW with a four-colour filter array (e.g. CYGM) is not supported",
            ))
        }
    };
    let wb = if raw.wb_coeffs[..3].iter().all(|w| w.is_finite() && *w > 0.0) {
        [raw.wb_coeffs[0], raw.wb_coeffs[1], raw.wb_coeffs[2]]
    } else {
        [1.0; 3]
    };
    let order = [
        Illuminant::D65,
        Illuminant::D50,
        Illuminant::D55,
        Illuminant::D75,
        Illuminant::Daylight,
        Illuminant::A,
        Illuminant::B,
        Illuminant::C,
        Illuminant::Flash,
    ];
    let (illu, flat) = raw
        .color_matrix_find_first(order)
        .ok_or_else(|| fail(path, "camera RAW without a colour matrix"))?;
    let m = rawler::imgop::matrix::transform_1d::<3, 3>(&flat).ok_or_else(|| {
        fail(
            path,
            format!(
                "camera RAW colour matrix has {} entries, not 9 (only three-colour sensors are supported)",
                flat.len()
            ),
        )
    })?;
    let m = if illu == Illuminant::D65 {
        m
    } else {
        rawler::imgop::chromatic_adaption::adapt_bradford(&illu, &Illuminant::D65, &m)
    };
    let cam_to_rgb = camera_to_rgb(m)
        .ok_or_else(|| fail(path, "camera RAW colour matrix is singular or not finite"))?;
    let mut image = HdrImage::new(cam.width, cam.height);
    let mut clipped = 0;
    for (i, p) in cam.data.iter().enumerate() {
        if p.iter().any(|v| !v.is_finite()) {
            return Err(fail(path, format!("camera RAW pixel {i} is not finite")));
        }
        if p.iter().any(|&v| v >= RAW_CLIP) {
            image.valid[i] = false;
            clipped += 1;
            continue;
        }
        let c: [f32; 3] = std::array::from_fn(|k| p[k].max(0.0) * wb[k]);
        image.pixels[i] = std::array::from_fn(|r| {
            (cam_to_rgb[r][0] * c[0] + cam_to_rgb[r][1] * c[1] + cam_to_rgb[r][2] * c[2]).max(0.0)
        });
    }
    Ok(RawPhoto {
        image,
        clipped,
        wb,
        cam_to_rgb,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A Sony-like XYZ to camera matrix (rows camera R, G, B), as a DNG's ColorMatrix1 holds.
    const XYZ_TO_CAM: [[f32; 3]; 3] = [
        [0.5991, -0.1456, -0.0455],
        [-0.4764, 1.2135, 0.2980],
        [-0.0863, 0.1697, 0.5922],
    ];

    #[test]
    fn the_camera_to_rgb_matrix_maps_camera_white_to_rgb_white_and_inverts_the_file_matrix() {
        let m = camera_to_rgb(XYZ_TO_CAM).unwrap();
        for r in 0..3 {
            let sum: f32 = m[r].iter().sum();
            assert!((sum - 1.0).abs() < 1e-5, "row {r} sums to {sum}");
        }
        // a singular matrix is refused
        assert!(camera_to_rgb([[1.0, 0.0, 0.0], [2.0, 0.0, 0.0], [0.0, 0.0, 1.0]]).is_none());
    }

    #[test]
    fn raw_extensions_are_recognised_in_any_case() {
        assert!(is_raw_path(Path::new("a/IMG_0001.DNG")));
        assert!(is_raw_path(Path::new("DSC0001.arw")));
        assert!(!is_raw_path(Path::new("DSC0001.tif")));
        assert!(!is_raw_path(Path::new("noext")));
    }

    #[cfg(not(feature = "raw"))]
    #[test]
    fn without_the_feature_a_raw_file_is_refused_by_name() {
        let e = read_raw(Path::new("shots/IMG_1.dng"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("shots/IMG_1.dng") && e.contains("`raw` feature"),
            "{e}"
        );
    }

    /// A minimal uncompressed Bayer (RGGB) DNG, 16 bits per photosite, little-endian.
    #[cfg(feature = "raw")]
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn write_dng(
        path: &Path,
        w: u32,
        h: u32,
        photosites: &[u16],
        black: u16,
        white: u16,
        xyz_to_cam: [[f32; 3]; 3],
        neutral: [f32; 3],
    ) {
        // (tag, type, count, value bytes)
        let mut entries: Vec<(u16, u16, u32, Vec<u8>)> = Vec::new();
        let short = |v: &[u16]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let long = |v: &[u32]| v.iter().flat_map(|x| x.to_le_bytes()).collect::<Vec<u8>>();
        let ascii = |s: &str| {
            let mut b = s.as_bytes().to_vec();
            b.push(0);
            b
        };
        let srational = |v: &[f32]| {
            v.iter()
                .flat_map(|x| {
                    let n = (x * 10000.0).round() as i32;
                    [n.to_le_bytes(), 10000i32.to_le_bytes()].concat()
                })
                .collect::<Vec<u8>>()
        };
        let rational = |v: &[f32]| {
            v.iter()
                .flat_map(|x| {
                    let n = (x * 1_000_000.0).round() as u32;
                    [n.to_le_bytes(), 1_000_000u32.to_le_bytes()].concat()
                })
                .collect::<Vec<u8>>()
        };
        let data_len = photosites.len() as u32 * 2;
        entries.push((254, 4, 1, long(&[0])));
        entries.push((256, 4, 1, long(&[w])));
        entries.push((257, 4, 1, long(&[h])));
        entries.push((258, 3, 1, short(&[16])));
        entries.push((259, 3, 1, short(&[1])));
        entries.push((262, 3, 1, short(&[32803])));
        entries.push((271, 2, 4, ascii("igi")));
        entries.push((272, 2, 10, ascii("synthetic")));
        entries.push((273, 4, 1, long(&[0]))); // patched below
        entries.push((274, 3, 1, short(&[1])));
        entries.push((277, 3, 1, short(&[1])));
        entries.push((278, 4, 1, long(&[h])));
        entries.push((279, 4, 1, long(&[data_len])));
        entries.push((284, 3, 1, short(&[1])));
        entries.push((33421, 3, 2, short(&[2, 2])));
        entries.push((33422, 1, 4, vec![0, 1, 1, 2]));
        entries.push((50706, 1, 4, vec![1, 4, 0, 0]));
        entries.push((50708, 2, 14, ascii("igi synthetic")));
        entries.push((50714, 3, 1, short(&[black])));
        entries.push((50717, 3, 1, short(&[white])));
        let flat: Vec<f32> = xyz_to_cam.iter().flatten().copied().collect();
        entries.push((50721, 10, 9, srational(&flat)));
        entries.push((50728, 5, 3, rational(&neutral)));
        entries.push((50778, 3, 1, short(&[21])));
        let ifd_len = 2 + entries.len() as u32 * 12 + 4;
        let mut extra_at = 8 + ifd_len;
        let extra_total: u32 = entries
            .iter()
            .filter(|e| e.3.len() > 4)
            .map(|e| e.3.len() as u32)
            .sum();
        let data_at = extra_at + extra_total;
        let mut head = b"II".to_vec();
        head.extend(42u16.to_le_bytes());
        head.extend(8u32.to_le_bytes());
        head.extend((entries.len() as u16).to_le_bytes());
        let mut extra = Vec::new();
        for (tag, typ, count, mut bytes) in entries {
            if tag == 273 {
                bytes = long(&[data_at]);
            }
            head.extend(tag.to_le_bytes());
            head.extend(typ.to_le_bytes());
            head.extend(count.to_le_bytes());
            if bytes.len() <= 4 {
                bytes.resize(4, 0);
                head.extend(bytes);
            } else {
                head.extend(extra_at.to_le_bytes());
                extra_at += bytes.len() as u32;
                extra.extend(bytes);
            }
        }
        head.extend(0u32.to_le_bytes());
        head.extend(extra);
        assert_eq!(head.len() as u32, data_at);
        head.extend(photosites.iter().flat_map(|v| v.to_le_bytes()));
        std::fs::write(path, head).unwrap();
    }

    /// A DNG of flat colour patches made from known linear RGB through the inverse of the
    /// pipeline (RGB to white-balanced camera RGB, divided by the white balance, scaled to the
    /// black and white levels, mosaiced RGGB) decodes back to that RGB; a saturated patch is
    /// masked.
    #[cfg(feature = "raw")]
    #[test]
    fn a_synthetic_dng_decodes_to_the_linear_rgb_it_was_made_from() {
        let (w, h, black, white) = (64u32, 48u32, 512u16, 15000u16);
        let neutral = [0.45f32, 1.0, 0.62];
        let wb = neutral.map(|n| 1.0 / n);
        let cam_to_rgb = camera_to_rgb(XYZ_TO_CAM).unwrap();
        let m = nalgebra::Matrix3::from_fn(|r, c| cam_to_rgb[r][c] as f64);
        let rgb_to_cam = m.try_inverse().unwrap();
        // four 32 x 24 patches: three colours and one saturated in green
        let patches: [[f64; 3]; 4] = [
            [0.20, 0.10, 0.05],
            [0.05, 0.30, 0.12],
            [0.10, 0.12, 0.40],
            [2.0, 2.0, 2.0],
        ];
        let patch = |x: u32, y: u32| (x / 32 + 2 * (y / 24)) as usize;
        let mut sites = vec![0u16; (w * h) as usize];
        for y in 0..h {
            for x in 0..w {
                let rgb = nalgebra::Vector3::from(patches[patch(x, y)]);
                let cam = rgb_to_cam * rgb;
                let ch = match (y % 2, x % 2) {
                    (0, 0) => 0,
                    (1, 1) => 2,
                    _ => 1,
                };
                let v = cam[ch] / wb[ch] as f64;
                let code = black as f64 + v * (white - black) as f64;
                sites[(y * w + x) as usize] = code.round().clamp(0.0, 65535.0) as u16;
            }
        }
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("patches.dng");
        write_dng(&path, w, h, &sites, black, white, XYZ_TO_CAM, neutral);
        let r = read_raw(&path).unwrap();
        assert_eq!((r.image.width, r.image.height), (w as usize, h as usize));
        for k in 0..3 {
            assert!((r.wb[k] - wb[k]).abs() < 1e-4, "wb {:?} vs {wb:?}", r.wb);
        }
        let mut worst = 0.0f64;
        for y in 0..h {
            for x in 0..w {
                let (px, py) = (x % 32, y % 24);
                if !(4..28).contains(&px) || !(4..20).contains(&py) {
                    continue; // the demosaic mixes patches near their borders
                }
                let i = (y * w + x) as usize;
                let p = patch(x, y);
                if p == 3 {
                    assert!(!r.image.valid[i], "saturated pixel ({x}, {y}) is valid");
                    continue;
                }
                assert!(r.image.valid[i]);
                for c in 0..3 {
                    let got = r.image.pixels[i][c] as f64;
                    worst = worst.max((got - patches[p][c]).abs() / patches[p][c]);
                }
            }
        }
        eprintln!("worst relative error in the patches' interiors: {worst:.2e}");
        // 16-bit codes of values around 0.05..0.4: quantisation is below 1e-3 relative
        assert!(worst < 2e-3, "{worst}");
        assert!(r.clipped >= 24 * 16, "{} clipped", r.clipped);
        // the photo reader takes it, linear
        let p = crate::photo::read_photo(&path, &crate::photo::Transfer::Default).unwrap();
        assert_eq!(p.applied, crate::photo::Applied::Linear);
        assert_eq!(p.clipped, r.clipped);
        let e = crate::photo::read_photo(&path, &crate::photo::Transfer::Srgb)
            .unwrap_err()
            .to_string();
        assert!(e.contains("patches.dng") && e.contains("camera RAW"), "{e}");
    }

    #[cfg(feature = "raw")]
    #[test]
    fn a_file_that_is_not_a_raw_is_refused_naming_it() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("broken.dng");
        std::fs::write(&path, b"II*\0garbage").unwrap();
        let e = read_raw(&path).unwrap_err().to_string();
        assert!(e.contains("broken.dng") && e.contains("camera RAW"), "{e}");
        let e = read_raw(&dir.path().join("none.nef"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("none.nef"), "{e}");
    }
}
