//! Photographs as cameras and raw converters write them, made linear (docs/IMAGING.md,
//! "Linearising photographs"):
//!
//! * **8-bit** PNG, JPEG or TIFF: through the camera's response recovered by Debevec-Malik
//!   ([`Transfer::Response`], the CSV `igi hdr merge --response-out` writes, read with
//!   [`read_response_csv`]), or decoded as sRGB by default. A pixel with any channel at 255
//!   (saturated) or at or below 1 (black-clipped) is clipped: marked invalid and set to 0.
//! * **16-bit** PNG or TIFF (raw converters' output): linear, `value / 65535`, unless sRGB is
//!   asked for; a pixel with any channel at 65535 is clipped.
//! * **Float** (EXR, Radiance HDR, float TIFF): linear as stored; its own validity mask kept.
//! * **Camera RAW** (DNG, CR2, NEF, ARW, ... [`crate::raw::RAW_EXTENSIONS`]): decoded by
//!   [`crate::raw::read_raw`] with the file's black and white levels, white balance and colour
//!   matrix to linear Rec. 709 RGB (the `raw` feature; without it, an error saying so); a pixel
//!   with a camera channel at the white level is clipped.
//!
//! [`read_photo`] counts the clipped pixels so that callers can report them.

use crate::hdr::{Response, LEVELS};
use crate::io::{decode_with_image_crate, srgb_to_linear};
use crate::{read_image, HdrImage, ImagingError};
use std::path::Path;

/// The highest 8-bit code taken as black-clipped (codes `0..=CLIP_LOW_8` carry no measurement).
pub const CLIP_LOW_8: u8 = 1;

/// How a photograph's stored values become linear.
#[derive(Clone, Debug, Default)]
pub enum Transfer {
    /// The file's own rule: sRGB for 8-bit, linear for 16-bit and float.
    #[default]
    Default,
    /// Decode the sRGB transfer curve (8- or 16-bit).
    Srgb,
    /// Stored values are linear: `value / max code`.
    Linear,
    /// Through a camera response recovered by Debevec-Malik (8-bit only): code `z` of channel
    /// `c` becomes `exp(g[c][z])`, on the response's own scale (`g(128) = 0`).
    Response(Response),
    /// A survey's camera response: 8-bit files through it (as [`Transfer::Response`]), 16-bit
    /// and float files by their own rule (as [`Transfer::Default`]).
    ResponseFor8Bit(Response),
}

/// The linear transfer curve a photo went through, as reported.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Applied {
    Srgb,
    Linear,
    Response,
}

impl std::fmt::Display for Applied {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Applied::Srgb => "sRGB",
            Applied::Linear => "linear",
            Applied::Response => "camera response",
        })
    }
}

/// A photograph made linear, with what it went through.
#[derive(Clone, Debug)]
pub struct LinearPhoto {
    /// Linear RGB; clipped pixels are invalid (and 0).
    pub image: HdrImage,
    /// Bits per channel as stored: 8, 16, or 32 for float.
    pub bits: u8,
    pub applied: Applied,
    /// Pixels masked as clipped by this reading (for float images: the file's invalid pixels).
    pub clipped: usize,
}

/// Reads the photograph `path` and makes it linear by `transfer` (module docs). A transfer
/// that cannot apply to the file (a response or sRGB for a float image, a response for a
/// 16-bit one) is refused naming the file.
pub fn read_photo(path: &Path, transfer: &Transfer) -> Result<LinearPhoto, ImagingError> {
    let ext = path
        .extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default();
    if crate::raw::is_raw_path(path) {
        return raw_photo(path, transfer);
    }
    if !matches!(ext.as_str(), "png" | "jpg" | "jpeg" | "tif" | "tiff") {
        let image = read_image(path)?;
        return float_photo(path, image, transfer);
    }
    if !path.exists() {
        // the same error as read_image's
        return read_image(path).map(|image| LinearPhoto {
            image,
            bits: 32,
            applied: Applied::Linear,
            clipped: 0,
        });
    }
    use ::image::DynamicImage as D;
    let dynimg = decode_with_image_crate(path)?;
    match dynimg {
        D::ImageLuma8(_) | D::ImageLumaA8(_) | D::ImageRgb8(_) | D::ImageRgba8(_) => {
            let rgb = dynimg.into_rgb8();
            let codes: Vec<[u16; 3]> = rgb.pixels().map(|p| p.0.map(u16::from)).collect::<Vec<_>>();
            let (w, h) = (rgb.width() as usize, rgb.height() as usize);
            let (lut, applied) = match transfer {
                Transfer::Default | Transfer::Srgb => (srgb_lut(255), Applied::Srgb),
                Transfer::Linear => (linear_lut(255), Applied::Linear),
                Transfer::Response(r) | Transfer::ResponseFor8Bit(r) => {
                    (response_lut(r), Applied::Response)
                }
            };
            Ok(linearise(
                w,
                h,
                &codes,
                &lut,
                CLIP_LOW_8 as u16,
                255,
                8,
                applied,
            ))
        }
        D::ImageLuma16(_) | D::ImageLumaA16(_) | D::ImageRgb16(_) | D::ImageRgba16(_) => {
            let rgb = dynimg.into_rgb16();
            let codes: Vec<[u16; 3]> = rgb.pixels().map(|p| p.0).collect();
            let (w, h) = (rgb.width() as usize, rgb.height() as usize);
            let (lut, applied) = match transfer {
                Transfer::Default | Transfer::Linear | Transfer::ResponseFor8Bit(_) => {
                    (linear_lut(65535), Applied::Linear)
                }
                Transfer::Srgb => (srgb_lut(65535), Applied::Srgb),
                Transfer::Response(_) => {
                    return Err(ImagingError::PhotoTransfer {
                        path: path.to_path_buf(),
                        msg: "is a 16-bit image, but a camera response maps 8-bit codes (16-bit photos from raw converters are linear; drop the `response`)".into(),
                    })
                }
            };
            // no black clip: a 16-bit linear value near 0 is a measurement
            Ok(linearise(w, h, &codes, &lut, 0, 65535, 16, applied))
        }
        other => {
            let rgb = other.into_rgb32f();
            let mut image = HdrImage::new(rgb.width() as usize, rgb.height() as usize);
            for (o, p) in image.pixels.iter_mut().zip(rgb.pixels()) {
                *o = p.0;
            }
            float_photo(path, image, transfer)
        }
    }
}

/// A camera RAW file: linear by its own levels; sRGB or a response is refused.
fn raw_photo(path: &Path, transfer: &Transfer) -> Result<LinearPhoto, ImagingError> {
    let what = match transfer {
        Transfer::Default | Transfer::Linear | Transfer::ResponseFor8Bit(_) => None,
        Transfer::Srgb => Some("sRGB decoding"),
        Transfer::Response(_) => Some("a camera response"),
    };
    if let Some(what) = what {
        return Err(ImagingError::PhotoTransfer {
            path: path.to_path_buf(),
            msg: format!("is a camera RAW file, linear by its own black and white levels: {what} applies to 8- and 16-bit photos only"),
        });
    }
    let r = crate::raw::read_raw(path)?;
    Ok(LinearPhoto {
        image: r.image,
        bits: 16,
        applied: Applied::Linear,
        clipped: r.clipped,
    })
}

/// A float image: linear as stored; sRGB or a response is refused.
fn float_photo(
    path: &Path,
    image: HdrImage,
    transfer: &Transfer,
) -> Result<LinearPhoto, ImagingError> {
    let what = match transfer {
        Transfer::Default | Transfer::Linear | Transfer::ResponseFor8Bit(_) => None,
        Transfer::Srgb => Some("sRGB decoding"),
        Transfer::Response(_) => Some("a camera response"),
    };
    if let Some(what) = what {
        return Err(ImagingError::PhotoTransfer {
            path: path.to_path_buf(),
            msg: format!("is a linear float image: {what} applies to 8- and 16-bit photos only"),
        });
    }
    if let Some(i) = image
        .pixels
        .iter()
        .position(|p| p.iter().any(|c| !c.is_finite()))
    {
        return Err(ImagingError::BadPixels {
            path: path.to_path_buf(),
            msg: format!("pixel {i} is not finite"),
        });
    }
    let clipped = image.valid.iter().filter(|v| !**v).count();
    Ok(LinearPhoto {
        image,
        bits: 32,
        applied: Applied::Linear,
        clipped,
    })
}

/// One linear value per code and channel.
type Lut = [Vec<f32>; 3];

fn linear_lut(max: u16) -> Lut {
    let l: Vec<f32> = (0..=max as u32).map(|z| z as f32 / max as f32).collect();
    [l.clone(), l.clone(), l]
}

fn srgb_lut(max: u16) -> Lut {
    let l: Vec<f32> = (0..=max as u32)
        .map(|z| srgb_to_linear(z as f32 / max as f32))
        .collect();
    [l.clone(), l.clone(), l]
}

fn response_lut(r: &Response) -> Lut {
    std::array::from_fn(|c| r.g[c].iter().map(|g| g.exp() as f32).collect())
}

/// Codes through `lut`; a pixel with any channel at or below `low` (when `low > 0`) or at
/// `high` is clipped: invalid and 0.
#[allow(clippy::too_many_arguments)]
fn linearise(
    w: usize,
    h: usize,
    codes: &[[u16; 3]],
    lut: &Lut,
    low: u16,
    high: u16,
    bits: u8,
    applied: Applied,
) -> LinearPhoto {
    let mut image = HdrImage::new(w, h);
    let mut clipped = 0;
    for (i, z) in codes.iter().enumerate() {
        if z.iter().any(|&c| c == high || (low > 0 && c <= low)) {
            image.valid[i] = false;
            clipped += 1;
            continue;
        }
        image.pixels[i] = std::array::from_fn(|c| lut[c][z[c] as usize]);
    }
    LinearPhoto {
        image,
        bits,
        applied,
        clipped,
    }
}

/// Reads a camera response CSV as `igi hdr merge --response-out` writes it: header
/// `z,g_r,g_g,g_b`, then 256 rows `z = 0..255` in order, `g` the natural log of the relative
/// exposure. Every `g` must be finite and non-decreasing in `z` over the codes a photo is read
/// through (`CLIP_LOW_8 + 1 ..= 254`; the clipped ends are never used); a file that is not is
/// refused naming the file and line.
pub fn read_response_csv(path: &Path) -> Result<Response, ImagingError> {
    let text = std::fs::read_to_string(path).map_err(|e| ImagingError::io(path, e))?;
    let table = crate::csv::Table::parse(&text, path)?;
    table.require_rows("response rows")?;
    let cols = table.columns(&["z", "g_r", "g_g", "g_b"])?;
    let bad = |line: usize, msg: String| ImagingError::ResponseFile {
        path: path.to_path_buf(),
        line,
        msg,
    };
    let mut g: [Vec<f64>; 3] = Default::default();
    let mut last_line = 1;
    for (k, row) in table.rows().iter().enumerate() {
        last_line = row.line;
        let z = table.number(row, cols[0], "z")?;
        if k >= LEVELS {
            return Err(bad(
                row.line,
                format!("more than {LEVELS} rows (z = 0..255 once each)"),
            ));
        }
        if z != k as f64 {
            return Err(bad(
                row.line,
                format!("z = {z}, expected {k} (rows z = 0..255 in order)"),
            ));
        }
        for (c, gc) in g.iter_mut().enumerate() {
            gc.push(table.number(row, cols[1 + c], ["g_r", "g_g", "g_b"][c])?);
        }
    }
    if g[0].len() != LEVELS {
        return Err(bad(
            last_line,
            format!(
                "the table ends at z = {}: a response has {LEVELS} rows, z = 0..255",
                g[0].len() - 1
            ),
        ));
    }
    let lo = CLIP_LOW_8 as usize + 1;
    for z in lo + 1..LEVELS - 1 {
        for (c, gc) in g.iter().enumerate() {
            if gc[z] < gc[z - 1] {
                return Err(bad(
                    table.rows()[z].line,
                    format!(
                        "{} falls from {} at z = {} to {} at z = {z}: a camera response must not decrease",
                        ["g_r", "g_g", "g_b"][c],
                        gc[z - 1],
                        z - 1,
                        gc[z]
                    ),
                ));
            }
        }
    }
    for (c, gc) in g.iter().enumerate() {
        if !(gc[LEVELS - 2] > gc[lo]) {
            return Err(bad(
                table.rows()[LEVELS - 2].line,
                format!(
                    "{} is flat over z = {lo}..254: not a response",
                    ["g_r", "g_g", "g_b"][c]
                ),
            ));
        }
    }
    Ok(Response { g, lambda: 0.0 })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, text: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }

    fn gamma_csv() -> String {
        let mut s = String::from("z,g_r,g_g,g_b\n");
        for z in 0..256 {
            let g = 2.2 * ((z.max(1)) as f64 / 128.0).ln();
            s.push_str(&format!("{z},{g},{g},{g}\n"));
        }
        s
    }

    #[test]
    fn a_written_response_reads_back_and_bad_ones_name_the_line() {
        let d = tempfile::tempdir().unwrap();
        let r = Response::linear();
        let p = d.path().join("r.csv");
        r.write_csv(&p).unwrap();
        let back = read_response_csv(&p).unwrap();
        for c in 0..3 {
            assert_eq!(back.g[c], r.g[c]);
        }
        let good = gamma_csv();
        assert!(read_response_csv(&write(d.path(), "g.csv", &good)).is_ok());
        // non-monotonic at z = 100 (line 102)
        let bad = good
            .lines()
            .map(|l| {
                if l.starts_with("100,") {
                    "100,-5,-5,-5".to_string()
                } else {
                    l.to_string()
                }
            })
            .collect::<Vec<_>>()
            .join("\n");
        let e = read_response_csv(&write(d.path(), "nm.csv", &bad))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("nm.csv:102:") && e.contains("must not decrease"),
            "{e}"
        );
        let short: String = good.lines().take(101).collect::<Vec<_>>().join("\n");
        let e = read_response_csv(&write(d.path(), "s.csv", &short))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("s.csv:101:") && e.contains("ends at z = 99"),
            "{e}"
        );
        let e = read_response_csv(&write(d.path(), "x.csv", &good.replace("\n7,", "\n7x,")))
            .unwrap_err()
            .to_string();
        assert!(e.contains("x.csv:9:") && e.contains("not a number"), "{e}");
    }

    #[test]
    fn eight_bit_codes_go_through_the_transfer_and_clipped_ones_are_masked() {
        let codes = [
            [0u16, 10, 20],
            [1, 200, 200],
            [128, 128, 128],
            [50, 255, 50],
        ];
        let p = linearise(4, 1, &codes, &srgb_lut(255), 1, 255, 8, Applied::Srgb);
        assert_eq!(p.clipped, 3);
        assert_eq!(p.image.valid, vec![false, false, true, false]);
        assert_eq!(p.image.pixels[0], [0.0; 3]);
        let v = p.image.pixels[2][0];
        assert!((v - 0.215_861).abs() < 1e-5, "{v}");
        let r = read_response_csv(&write(
            tempfile::tempdir().unwrap().path(),
            "g.csv",
            &gamma_csv(),
        ))
        .unwrap();
        let p = linearise(
            4,
            1,
            &codes,
            &response_lut(&r),
            1,
            255,
            8,
            Applied::Response,
        );
        assert!((p.image.pixels[2][1] - 1.0).abs() < 1e-6);
    }
}
