//! Image file I/O: read any supported image, write EXR, Radiance HDR and tone-mapped PNG
//! (atomically, through `igi_files`).

use crate::{HdrImage, ImagingError};
use std::path::Path;

fn ext_of(path: &Path) -> String {
    path.extension()
        .map(|e| e.to_string_lossy().to_lowercase())
        .unwrap_or_default()
}

/// An image file's width and height from its header, without decoding the pixels (EXR:
/// the first part's layer size; other formats: the image crate's header read).
pub fn image_size(path: &Path) -> Result<(usize, usize), ImagingError> {
    if ext_of(path) == "exr" {
        let meta = exr::meta::MetaData::read_from_file(path, false)
            .map_err(|e| ImagingError::decode_failed(path, e))?;
        let h = meta.headers.first().ok_or_else(|| ImagingError::Decode {
            path: path.to_path_buf(),
            msg: "no image part".into(),
        })?;
        return Ok((h.layer_size.0, h.layer_size.1));
    }
    let (w, h) = image::image_dimensions(path).map_err(|e| ImagingError::decode_failed(path, e))?;
    Ok((w as usize, h as usize))
}

/// Read an image as linear `f32` RGB. EXR (RGB, RGBA, B/G/R in any order, half or float, any
/// compression; a channel named `valid` becomes the mask; a luminance-only `Y` image is
/// replicated), Radiance `.hdr`, and PNG/JPEG/TIFF (8/16-bit scaled to [0, 1] as stored, no
/// sRGB decoding). NaN or infinite values are rejected with an error naming the file.
pub fn read_image(path: &Path) -> Result<HdrImage, ImagingError> {
    let ext = ext_of(path);
    match ext.as_str() {
        "exr" | "hdr" | "png" | "jpg" | "jpeg" | "tif" | "tiff" => {}
        _ => {
            return Err(ImagingError::UnknownFormat {
                path: path.to_path_buf(),
                ext,
            })
        }
    }
    if !path.exists() {
        return Err(ImagingError::io(
            path,
            std::io::Error::new(std::io::ErrorKind::NotFound, "file not found"),
        ));
    }
    let img = if ext == "exr" {
        read_exr(path)?
    } else {
        read_with_image_crate(path)?
    };
    check_finite(path, &img)?;
    Ok(img)
}

fn check_finite(path: &Path, img: &HdrImage) -> Result<(), ImagingError> {
    let mut bad = 0usize;
    let mut first = None;
    for (i, p) in img.pixels.iter().enumerate() {
        if !p.iter().all(|c| c.is_finite()) {
            bad += 1;
            if first.is_none() {
                first = Some((i % img.width.max(1), i / img.width.max(1), *p));
            }
        }
    }
    if let Some((x, y, v)) = first {
        return Err(ImagingError::BadPixels {
            path: path.to_path_buf(),
            msg: format!(
                "{bad} pixel(s) with NaN or infinite values, first at (x={x}, y={y}) = {v:?}"
            ),
        });
    }
    Ok(())
}

/// Reads the header of a PNG, JPEG or TIFF file and refuses, before the decoder allocates
/// anything, one that declares more pixels than [`MAX_IMAGE_PIXELS`] or whose decoding would
/// take more memory than `igi_files::max_alloc` (the decoded pixels, their `f32` copy and the
/// image: 28 bytes a pixel at most).
fn check_image_header(path: &Path) -> Result<(), ImagingError> {
    let (w, h) = ::image::ImageReader::open(path)
        .map_err(|e| ImagingError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| ImagingError::io(path, e))?
        .into_dimensions()
        .map_err(|e| ImagingError::decode_failed(path, e))?;
    let (w, h) = (w as u128, h as u128);
    if w * h > MAX_IMAGE_PIXELS as u128 {
        return Err(ImagingError::Decode {
            path: path.to_path_buf(),
            msg: format!(
                "declares {w} x {h} pixels, more than the {} Mpixel limit",
                MAX_IMAGE_PIXELS / 1_000_000
            ),
        });
    }
    igi_files::check_alloc_default(
        &format!("decoding {} ({w} x {h} pixels)", path.display()),
        w * h * 28,
    )?;
    Ok(())
}

fn read_with_image_crate(path: &Path) -> Result<HdrImage, ImagingError> {
    let dynimg = decode_with_image_crate(path)?;
    let rgb = dynimg.into_rgb32f();
    let (w, h) = (rgb.width() as usize, rgb.height() as usize);
    let mut out = HdrImage::new(w, h);
    for (i, p) in rgb.pixels().enumerate() {
        out.pixels[i] = p.0;
    }
    Ok(out)
}

/// Decodes a PNG, JPEG or TIFF file as stored (its bit depth kept), the header checked against
/// the pixel and memory limits first.
pub(crate) fn decode_with_image_crate(path: &Path) -> Result<::image::DynamicImage, ImagingError> {
    let dec = |e: ::image::ImageError| ImagingError::decode_failed(path, e);
    check_image_header(path)?;
    let mut reader = ::image::ImageReader::open(path)
        .map_err(|e| ImagingError::io(path, e))?
        .with_guessed_format()
        .map_err(|e| ImagingError::io(path, e))?;
    // the decoder's own guard as well: no allocation above the limit checked above
    let mut limits = ::image::Limits::default();
    limits.max_image_width = Some(1 << 20);
    limits.max_image_height = Some(1 << 20);
    limits.max_alloc = Some(igi_files::max_alloc()?);
    reader.limits(limits);
    reader.decode().map_err(dec)
}

/// The most a deflate stream (ZIP, the best-compressing EXR codec on uniform data) can shrink
/// its input, rounded up: 1032:1.
const MAX_EXR_COMPRESSION: u128 = 1100;

/// The most pixels an image (or a camera file, `camera::MAX_CAMERA_PIXELS`) may have: 2^29
/// (536 Mpixel); an HDR image that size needs 6.5 GiB.
pub const MAX_IMAGE_PIXELS: u64 = 1 << 29;

/// Reads the EXR headers and refuses, before the decoder allocates anything, a file that
/// declares more pixels than [`MAX_IMAGE_PIXELS`] or more uncompressed pixel
/// bytes than its size could hold at the best compression any EXR codec reaches (a header that
/// lies about its size would otherwise make the decoder allocate gigabytes for a 1 kB file).
fn check_exr_header(path: &Path) -> Result<(), ImagingError> {
    let dec = |msg: String| ImagingError::Decode {
        path: path.to_path_buf(),
        msg,
    };
    let file_len = std::fs::metadata(path)
        .map_err(|e| ImagingError::io(path, e))?
        .len() as u128;
    let meta = exr::meta::MetaData::read_from_file(path, false)
        .map_err(|e| ImagingError::decode_failed(path, e))?;
    for h in meta.headers.iter() {
        if h.deep {
            return Err(dec("deep-data EXR files are not supported".into()));
        }
        let (w, hh) = (h.layer_size.0 as u128, h.layer_size.1 as u128);
        if w * hh > MAX_IMAGE_PIXELS as u128 {
            return Err(dec(format!(
                "declares {w} x {hh} pixels, more than the {} Mpixel limit",
                MAX_IMAGE_PIXELS / 1_000_000
            )));
        }
        let sample_bytes: u128 = h
            .channels
            .list
            .iter()
            .map(|c| c.sample_type.bytes_per_sample() as u128)
            .sum();
        if w * hh * sample_bytes > MAX_EXR_COMPRESSION * file_len + (1 << 20) {
            return Err(dec(format!(
                "declares {w} x {hh} pixels of {} channel(s), more than a file of {file_len} bytes can hold (truncated or corrupt header)",
                h.channels.list.len()
            )));
        }
    }
    Ok(())
}

fn read_exr(path: &Path) -> Result<HdrImage, ImagingError> {
    use exr::prelude::*;
    let dec = |msg: String| ImagingError::Decode {
        path: path.to_path_buf(),
        msg,
    };
    check_exr_header(path)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .all_layers()
        .all_attributes()
        .from_file(path)
        .map_err(|e| ImagingError::decode_failed(path, e))?;
    let base =
        |name: &str| -> String { name.rsplit('.').next().unwrap_or(name).to_ascii_lowercase() };
    for layer in &image.layer_data {
        let chans = &layer.channel_data.list;
        let find = |n: &str| chans.iter().find(|c| base(&c.name.to_string()) == n);
        let (r, g, b) = match (find("r"), find("g"), find("b"), find("y")) {
            (Some(r), Some(g), Some(b), _) => (r, g, b),
            (_, _, _, Some(y)) => (y, y, y),
            _ => continue,
        };
        let (w, h) = (layer.size.width(), layer.size.height());
        let n = w * h;
        let mut out = HdrImage::new(w, h);
        for (c, ch) in [r, g, b].into_iter().enumerate() {
            if ch.sample_data.len() != n {
                return Err(dec(format!(
                    "channel {} has {} samples, expected {}",
                    ch.name,
                    ch.sample_data.len(),
                    n
                )));
            }
            for (i, v) in ch.sample_data.values_as_f32().enumerate() {
                out.pixels[i][c] = v;
            }
        }
        if let Some(m) = find("valid") {
            if m.sample_data.len() == n {
                for (i, v) in m.sample_data.values_as_f32().enumerate() {
                    out.valid[i] = v > 0.5;
                }
            }
        }
        return Ok(out);
    }
    let names: Vec<String> = image
        .layer_data
        .iter()
        .flat_map(|l| l.channel_data.list.iter().map(|c| c.name.to_string()))
        .collect();
    Err(dec(format!(
        "no R,G,B or Y channels found (channels: {names:?})"
    )))
}

fn check_dims(path: &Path, img: &HdrImage) -> Result<(), ImagingError> {
    if img.width == 0
        || img.height == 0
        || img.pixels.len() != img.width * img.height
        || img.valid.len() != img.pixels.len()
    {
        return Err(ImagingError::Encode {
            path: path.to_path_buf(),
            msg: format!(
                "inconsistent image: {}x{} with {} pixels and {} mask entries",
                img.width,
                img.height,
                img.pixels.len(),
                img.valid.len()
            ),
        });
    }
    Ok(())
}

/// Write a linear `f32` RGB OpenEXR file (ZIP compression), atomically. If any pixel is invalid an
/// extra channel `valid` (0/1) carries the mask. Non-finite values are refused.
pub fn write_exr(path: &Path, img: &HdrImage) -> Result<(), ImagingError> {
    write_exr_channels(path, img, None)
}

/// Write an RGBA OpenEXR file (FORMATS.md: colour premultiplied by alpha, the EXR convention;
/// the caller passes premultiplied colour), atomically. `alpha` has one value per pixel.
pub fn write_exr_rgba(path: &Path, img: &HdrImage, alpha: &[f32]) -> Result<(), ImagingError> {
    if alpha.len() != img.pixels.len() || alpha.iter().any(|a| !a.is_finite()) {
        return Err(ImagingError::Encode {
            path: path.to_path_buf(),
            msg: format!(
                "alpha has {} finite values for {} pixels",
                alpha.iter().filter(|a| a.is_finite()).count(),
                img.pixels.len()
            ),
        });
    }
    write_exr_channels(path, img, Some(alpha))
}

/// The alpha channel (`A`) of an EXR file, or `None` when it has none.
pub fn read_exr_alpha(path: &Path) -> Result<Option<Vec<f32>>, ImagingError> {
    use exr::prelude::*;
    check_exr_header(path)?;
    let image = read()
        .no_deep_data()
        .largest_resolution_level()
        .all_channels()
        .first_valid_layer()
        .all_attributes()
        .from_file(path)
        .map_err(|e| ImagingError::decode_failed(path, e))?;
    let chans = &image.layer_data.channel_data.list;
    Ok(chans
        .iter()
        .find(|c| c.name.to_string().rsplit('.').next() == Some("A"))
        .map(|c| c.sample_data.values_as_f32().collect()))
}

fn write_exr_channels(
    path: &Path,
    img: &HdrImage,
    alpha: Option<&[f32]>,
) -> Result<(), ImagingError> {
    use exr::prelude::*;
    check_dims(path, img)?;
    check_finite(path, img)?;
    let mut list: Vec<AnyChannel<FlatSamples>> = (0..3)
        .map(|c| {
            let name = ["R", "G", "B"][c];
            AnyChannel::new(
                name,
                FlatSamples::F32(img.pixels.iter().map(|p| p[c]).collect()),
            )
        })
        .collect();
    if let Some(a) = alpha {
        list.push(AnyChannel::new("A", FlatSamples::F32(a.to_vec())));
    }
    if img.valid.iter().any(|v| !v) {
        list.push(AnyChannel::new(
            "valid",
            FlatSamples::F32(
                img.valid
                    .iter()
                    .map(|&v| if v { 1.0 } else { 0.0 })
                    .collect(),
            ),
        ));
    }
    let layer = Layer::new(
        (img.width, img.height),
        LayerAttributes::default(),
        Encoding::SMALL_LOSSLESS,
        AnyChannels::sort(SmallVec::from_vec(list)),
    );
    let image = Image::from_layer(layer);
    igi_files::write_atomic(path, |tmp| {
        image
            .write()
            .to_file(tmp)
            .map_err(|e| ImagingError::encode_failed(path, e))
    })
}

/// Write a Radiance RGBE `.hdr` file, atomically. Negative values are clamped to 0.
pub fn write_hdr(path: &Path, img: &HdrImage) -> Result<(), ImagingError> {
    check_dims(path, img)?;
    check_finite(path, img)?;
    let data: Vec<::image::Rgb<f32>> = img
        .pixels
        .iter()
        .map(|p| ::image::Rgb([p[0].max(0.0), p[1].max(0.0), p[2].max(0.0)]))
        .collect();
    igi_files::write_atomic(path, |tmp| {
        let f = std::fs::File::create(tmp).map_err(|e| ImagingError::io(path, e))?;
        let w = std::io::BufWriter::new(f);
        ::image::codecs::hdr::HdrEncoder::new(w)
            .encode(&data, img.width, img.height)
            .map_err(|e| ImagingError::encode_failed(path, e))
    })
}

/// sRGB transfer function (linear [0, 1] -> encoded [0, 1]).
pub fn linear_to_srgb(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.003_130_8 {
        12.92 * x
    } else {
        1.055 * x.powf(1.0 / 2.4) - 0.055
    }
}

/// Inverse sRGB transfer function (encoded [0, 1] -> linear).
pub fn srgb_to_linear(x: f32) -> f32 {
    let x = x.clamp(0.0, 1.0);
    if x <= 0.040_45 {
        x / 12.92
    } else {
        ((x + 0.055) / 1.055).powf(2.4)
    }
}

/// Write an 8-bit sRGB PNG preview: pixel * `exposure`, clipped to [0, 1], sRGB-encoded.
pub fn write_png_tonemapped(
    path: &Path,
    img: &HdrImage,
    exposure: f32,
) -> Result<(), ImagingError> {
    let png = png_tonemapped(path, img, exposure)?;
    igi_files::write_atomic(path, |tmp| {
        std::fs::write(tmp, &png).map_err(|e| ImagingError::io(path, e))
    })
}

/// The bytes of [`write_png_tonemapped`]'s PNG (pixel * `exposure`, clipped to [0, 1],
/// sRGB-encoded, NaN and infinities as 0), made in memory; `name` names the picture in errors.
pub fn png_tonemapped(name: &Path, img: &HdrImage, exposure: f32) -> Result<Vec<u8>, ImagingError> {
    use ::image::ImageEncoder;
    check_dims(name, img)?;
    if !exposure.is_finite() {
        return Err(ImagingError::InvalidInput(format!(
            "{}: exposure {exposure} is not finite",
            name.display()
        )));
    }
    let mut buf = Vec::with_capacity(img.pixels.len() * 3);
    for p in &img.pixels {
        for c in p {
            let v = if c.is_finite() { c * exposure } else { 0.0 };
            buf.push((linear_to_srgb(v) * 255.0 + 0.5) as u8);
        }
    }
    let mut png = Vec::new();
    ::image::codecs::png::PngEncoder::new(&mut png)
        .write_image(
            &buf,
            img.width as u32,
            img.height as u32,
            ::image::ExtendedColorType::Rgb8,
        )
        .map_err(|e| ImagingError::encode_failed(name, e))?;
    Ok(png)
}

/// The exposure that puts the median luminance of the valid pixels at 0.18 (1 for an image
/// with none, or a median that is 0 or not finite): pictures of linear radiance for people.
pub fn auto_exposure(img: &HdrImage) -> f32 {
    let mut l: Vec<f64> = img
        .pixels
        .iter()
        .zip(&img.valid)
        .filter(|(_, v)| **v)
        .map(|(p, _)| crate::color::luminance_f64(p.map(f64::from)))
        .collect();
    if l.is_empty() {
        return 1.0;
    }
    let m = crate::color::median_in_place(&mut l);
    if m > 0.0 && m.is_finite() {
        (0.18 / m) as f32
    } else {
        1.0
    }
}

#[cfg(test)]
mod tests {
    #[test]
    fn rgba_exr_round_trips_alpha() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        let mut img = HdrImage::new(3, 2);
        img.set(1, 0, [0.25, 0.5, 0.125]);
        let alpha = vec![0.0, 0.5, 1.0, 0.25, 0.0, 1.0];
        write_exr_rgba(&p, &img, &alpha).unwrap();
        assert_eq!(read_exr_alpha(&p).unwrap(), Some(alpha));
        assert_eq!(read_image(&p).unwrap(), img);
        assert!(write_exr_rgba(&p, &img, &[0.0; 5]).is_err());
        let q = dir.path().join("b.exr");
        write_exr(&q, &img).unwrap();
        assert_eq!(read_exr_alpha(&q).unwrap(), None);
    }

    use super::*;

    fn test_image() -> HdrImage {
        let mut im = HdrImage::new(5, 3);
        for y in 0..3 {
            for x in 0..5 {
                im.set(
                    x,
                    y,
                    [
                        x as f32 * 0.5,
                        y as f32 * 100.0 + 0.25,
                        1e-3 * (x + y) as f32,
                    ],
                );
            }
        }
        im
    }

    #[test]
    fn image_size_reads_headers_of_exr_and_png() {
        let dir = tempfile::tempdir().unwrap();
        let img = HdrImage::new(7, 3);
        let (exr, png) = (dir.path().join("a.exr"), dir.path().join("a.png"));
        write_exr(&exr, &img).unwrap();
        write_png_tonemapped(&png, &img, 1.0).unwrap();
        assert_eq!(image_size(&exr).unwrap(), (7, 3));
        assert_eq!(image_size(&png).unwrap(), (7, 3));
        let bad = dir.path().join("b.exr");
        std::fs::write(&bad, b"not an exr").unwrap();
        assert!(image_size(&bad).unwrap_err().to_string().contains("b.exr"));
    }

    #[test]
    fn exr_round_trip_with_mask() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.exr");
        let mut im = test_image();
        write_exr(&p, &im).unwrap();
        let back = read_image(&p).unwrap();
        assert_eq!(back, im);
        im.valid[7] = false;
        im.pixels[7] = [0.0; 3];
        write_exr(&p, &im).unwrap();
        let back = read_image(&p).unwrap();
        assert_eq!(back, im);
        // no temp files left
        assert_eq!(std::fs::read_dir(dir.path()).unwrap().count(), 1);
    }

    #[test]
    fn hdr_round_trip_within_rgbe_precision() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.hdr");
        let im = test_image();
        write_hdr(&p, &im).unwrap();
        let back = read_image(&p).unwrap();
        for (a, b) in im.pixels.iter().zip(&back.pixels) {
            let m = a.iter().cloned().fold(0.0f32, f32::max);
            for c in 0..3 {
                // RGBE: 8-bit mantissa relative to the largest channel
                assert!(
                    (a[c] - b[c]).abs() <= m * 1.0 / 128.0 + 1e-6,
                    "{a:?} vs {b:?}"
                );
            }
        }
    }

    #[test]
    fn png_preview_is_srgb_encoded() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.png");
        let mut im = HdrImage::new(2, 1);
        im.set(0, 0, [0.5, 0.0, 10.0]);
        im.set(1, 0, [0.002, 1.0, -1.0]);
        write_png_tonemapped(&p, &im, 1.0).unwrap();
        let back = read_image(&p).unwrap();
        assert!((back.get(0, 0)[0] - 188.0 / 255.0).abs() < 1e-6); // sRGB(0.5) = 0.7354 -> 188
        assert_eq!(back.get(0, 0)[2], 1.0);
        assert_eq!(back.get(1, 0)[2], 0.0);
        assert!((back.get(1, 0)[0] - 7.0 / 255.0).abs() < 1e-6); // 12.92*0.002*255 = 6.6 -> 7
        assert!((srgb_to_linear(linear_to_srgb(0.3)) - 0.3).abs() < 1e-6);
    }

    #[test]
    fn errors_name_file_and_problem() {
        let e = read_image(Path::new("/nonexistent/x.exr"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("/nonexistent/x.exr") && e.contains("not found"),
            "{e}"
        );
        let e = read_image(Path::new("/tmp/foo.bmpx"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("foo.bmpx") && e.contains("unknown image format"),
            "{e}"
        );
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("garbage.png");
        std::fs::write(&p, b"not a png").unwrap();
        let e = read_image(&p).unwrap_err().to_string();
        assert!(e.contains("garbage.png"), "{e}");
    }

    #[test]
    fn exr_headers_that_lie_about_their_size_are_refused_before_decoding() {
        // found by igi-fuzz: a 660-byte file whose data window made the decoder allocate 23 GB
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("small.exr");
        write_exr(&p, &HdrImage::new(8, 8)).unwrap();
        let bytes = std::fs::read(&p).unwrap();
        let key = b"dataWindow\0box2i\0";
        let at = bytes.windows(key.len()).position(|w| w == key).unwrap() + key.len() + 4;
        let patched = |xmax: i32, ymax: i32| {
            let mut b = bytes.clone();
            b[at + 8..at + 12].copy_from_slice(&xmax.to_le_bytes());
            b[at + 12..at + 16].copy_from_slice(&ymax.to_le_bytes());
            let q = dir.path().join(format!("lie{xmax}.exr"));
            std::fs::write(&q, b).unwrap();
            q
        };
        assert!(
            read_image(&patched(7, 7)).is_ok(),
            "the unpatched window reads"
        );
        let e = read_image(&patched(59_999, 59_999))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("lie59999.exr") && e.contains("Mpixel limit"),
            "{e}"
        );
        let e = read_image(&patched(2_999, 2_999)).unwrap_err().to_string();
        assert!(e.contains("lie2999.exr") && e.contains("can hold"), "{e}");
        let e = read_exr_alpha(&patched(2_999, 2_999))
            .unwrap_err()
            .to_string();
        assert!(e.contains("can hold"), "{e}");
    }

    #[test]
    fn nan_in_exr_is_rejected() {
        use exr::prelude::*;
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("nan.exr");
        write_rgb_file(&p, 4, 4, |x, y| {
            if (x, y) == (2, 1) {
                (f32::NAN, 0.0, 0.0)
            } else {
                (1.0, 1.0, 1.0)
            }
        })
        .unwrap();
        let e = read_image(&p).unwrap_err().to_string();
        assert!(
            e.contains("nan.exr") && e.contains("NaN") && e.contains("x=2, y=1"),
            "{e}"
        );
        // and we refuse to write such data, leaving nothing behind
        let mut im = HdrImage::new(2, 2);
        im.pixels[0][1] = f32::INFINITY;
        let q = dir.path().join("out.exr");
        assert!(write_exr(&q, &im).is_err());
        assert!(!q.exists());
    }

    #[test]
    fn reads_real_bgr_half_piz_exr_and_rgbe_probe() {
        let exr = igi_testkit::shared_data("light_probes/pbrt_v2/grace_latlong.exr");
        let im = read_image(&exr).unwrap();
        assert_eq!((im.width, im.height), (1024, 512));
        let mean: f64 = im
            .pixels
            .iter()
            .map(|p| (p[0] + p[1] + p[2]) as f64 / 3.0)
            .sum::<f64>()
            / im.pixels.len() as f64;
        assert!(mean > 0.01 && mean < 100.0, "mean {mean}");
        assert!(im.pixels.iter().all(|p| p.iter().all(|c| *c >= 0.0)));
        // Grace cathedral is warm (tungsten-lit): R channel mean exceeds B: checks channel order
        let (r, b): (f64, f64) = im
            .pixels
            .iter()
            .fold((0.0, 0.0), |a, p| (a.0 + p[0] as f64, a.1 + p[2] as f64));
        assert!(r > b * 1.1, "r {r} b {b}");
        let hdr = igi_testkit::shared_data("light_probes/probulator_latlong_256x128/grace.hdr");
        let im2 = read_image(&hdr).unwrap();
        assert_eq!((im2.width, im2.height), (256, 128));
    }
}
