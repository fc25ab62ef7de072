//! A photograph's EXIF: when it was taken and how it was exposed (issue 33).
//!
//! [`read_exif`] reads, through `kamadak-exif`, the fields igi uses from a JPEG, TIFF, PNG,
//! WebP or HEIF container: `DateTimeOriginal` and `OffsetTimeOriginal` (the local time and its
//! UTC offset), `GPSDateStamp` and `GPSTimeStamp` (UTC), `ExposureTime`, `FNumber` and the ISO
//! speed (`PhotographicSensitivity`), and the camera body (`Make`, `Model`,
//! `BodySerialNumber`). Text fields are kept as written (EXIF's padding of NULs and
//! spaces trimmed); `igi_formats::time` turns them into an instant. [`PhotoExif::exposure`]
//! puts photographs taken at different settings on one radiometric scale.

use crate::ImagingError;
use exif::{Exif, In, Tag, Value};
use std::path::Path;

/// The EXIF fields of one photograph that igi uses; each `None` when the file does not hold it.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PhotoExif {
    /// `DateTimeOriginal`, `YYYY:MM:DD HH:MM:SS` in the camera's local time.
    pub date_time_original: Option<String>,
    /// `OffsetTimeOriginal`, `+HH:MM`: the UTC offset of `date_time_original`.
    pub offset_time_original: Option<String>,
    /// `GPSDateStamp` and `GPSTimeStamp` as `YYYY:MM:DD HH:MM:SS` (UTC, whole seconds).
    pub gps_utc: Option<String>,
    /// `ExposureTime` in seconds.
    pub exposure_time_s: Option<f64>,
    /// `FNumber`.
    pub f_number: Option<f64>,
    /// `PhotographicSensitivity` (ISO speed).
    pub iso: Option<f64>,
    /// The camera body: `Make`, `Model` and `#BodySerialNumber`, those present, joined by
    /// spaces.
    pub body: Option<String>,
}

impl PhotoExif {
    /// The photograph's exposure relative to 1 s at f/1 and ISO 100: exposure time x (ISO /
    /// 100) / f-number^2, the factor by which the same scene radiance gives larger pixel
    /// values. A missing f-number or ISO counts as unchanged between the photographs (1 and
    /// 100); `None` without an exposure time.
    pub fn exposure(&self) -> Option<f64> {
        let t = self.exposure_time_s?;
        let n = self.f_number.unwrap_or(1.0);
        let iso = self.iso.unwrap_or(100.0);
        Some(t * (iso / 100.0) / (n * n))
    }
}

/// The EXIF fields of the image at `path` ([`PhotoExif`]). A file without EXIF data is
/// [`ImagingError::NoExif`]; a field of the wrong type or a non-positive number is
/// [`ImagingError::Exif`], naming the field.
pub fn read_exif(path: &Path) -> Result<PhotoExif, ImagingError> {
    let f = std::fs::File::open(path).map_err(|e| ImagingError::io(path, e))?;
    let ex = exif::Reader::new()
        .read_from_container(&mut std::io::BufReader::new(f))
        .map_err(|source| ImagingError::NoExif {
            path: path.to_path_buf(),
            source,
        })?;
    let number = |tag| positive(&ex, tag, path);
    Ok(PhotoExif {
        date_time_original: text(&ex, Tag::DateTimeOriginal),
        offset_time_original: text(&ex, Tag::OffsetTimeOriginal),
        gps_utc: gps_utc(&ex),
        exposure_time_s: number(Tag::ExposureTime)?,
        f_number: number(Tag::FNumber)?,
        iso: number(Tag::PhotographicSensitivity)?,
        body: body(&ex),
    })
}

/// `Make`, `Model` and `#BodySerialNumber`, those present, joined by spaces (the model often
/// repeats the make: then once); `None` when none is.
fn body(ex: &Exif) -> Option<String> {
    let make = text(ex, Tag::Make);
    let model = text(ex, Tag::Model).map(|m| match &make {
        Some(k) if m.starts_with(k.as_str()) => m[k.len()..].trim().to_string(),
        _ => m,
    });
    let serial = text(ex, Tag::BodySerialNumber).map(|s| format!("#{s}"));
    let parts: Vec<String> = [make, model, serial]
        .into_iter()
        .flatten()
        .filter(|s| !s.is_empty())
        .collect();
    (!parts.is_empty()).then(|| parts.join(" "))
}

/// An ASCII field, its padding trimmed; `None` when absent or blank.
fn text(ex: &Exif, tag: Tag) -> Option<String> {
    let f = ex.get_field(tag, In::PRIMARY)?;
    let Value::Ascii(parts) = &f.value else {
        return None;
    };
    let s: String = parts
        .iter()
        .map(|p| String::from_utf8_lossy(p).into_owned())
        .collect::<Vec<_>>()
        .join(" ");
    let s = s.trim_matches(|c: char| c == '\0' || c.is_whitespace());
    (!s.is_empty()).then(|| s.to_string())
}

/// A numeric field as a positive number (the first value of a rational or integer list).
fn positive(ex: &Exif, tag: Tag, path: &Path) -> Result<Option<f64>, ImagingError> {
    let Some(f) = ex.get_field(tag, In::PRIMARY) else {
        return Ok(None);
    };
    let err = |msg: String| ImagingError::Exif {
        path: path.to_path_buf(),
        msg,
    };
    let v = match &f.value {
        Value::Rational(v) if !v.is_empty() => v[0].to_f64(),
        Value::SRational(v) if !v.is_empty() => v[0].to_f64(),
        Value::Short(v) if !v.is_empty() => f64::from(v[0]),
        Value::Long(v) if !v.is_empty() => f64::from(v[0]),
        other => return Err(err(format!("{tag} has an unexpected type: {other:?}"))),
    };
    if !(v.is_finite() && v > 0.0) {
        return Err(err(format!("{tag} {v} is not a positive number")));
    }
    Ok(Some(v))
}

/// `GPSDateStamp` (`YYYY:MM:DD`) with `GPSTimeStamp` (hours, minutes, seconds as rationals)
/// as `YYYY:MM:DD HH:MM:SS`, UTC; `None` unless both are present and readable.
fn gps_utc(ex: &Exif) -> Option<String> {
    let date = text(ex, Tag::GPSDateStamp)?;
    let f = ex.get_field(Tag::GPSTimeStamp, In::PRIMARY)?;
    let Value::Rational(hms) = &f.value else {
        return None;
    };
    let [h, m, s] = [hms.first()?, hms.get(1)?, hms.get(2)?].map(|r| r.to_f64());
    let ok = |x: f64, max: f64| x.is_finite() && (0.0..max).contains(&x);
    (ok(h, 24.0) && ok(m, 60.0) && ok(s, 61.0)).then(|| {
        format!(
            "{date} {:02}:{:02}:{:02}",
            h as u32,
            m as u32,
            s.floor() as u32
        )
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The real photographs of ../shared/data/CATALOGUE.md: an iPhone 7 (f/1.8, ISO 100) and a
    /// Sony ILCE-6400 (f/5.6, ISO 1600), each at 0.1, 0.025 and 0.00625 s.
    #[test]
    fn exposure_of_real_jpegs() {
        let cases = [
            (
                "mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7",
                "ball_10.JPG",
                0.1,
                1.8,
                100.0,
            ),
            (
                "mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7",
                "ball_40.JPG",
                0.025,
                1.8,
                100.0,
            ),
            (
                "mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7",
                "ball_160.JPG",
                0.00625,
                1.8,
                100.0,
            ),
            (
                "mirror_ball_ldr/olapietka_sony_a6400",
                "raw1.jpg",
                0.1,
                5.6,
                1600.0,
            ),
            (
                "mirror_ball_ldr/olapietka_sony_a6400",
                "raw2.jpg",
                0.025,
                5.6,
                1600.0,
            ),
            (
                "mirror_ball_ldr/olapietka_sony_a6400",
                "raw3.jpg",
                0.00625,
                5.6,
                1600.0,
            ),
        ];
        for (dir, f, t, n, iso) in cases {
            let p = igi_testkit::shared_data(dir).join(f);
            let e = read_exif(&p).unwrap();
            assert!((e.exposure_time_s.unwrap() - t).abs() < 1e-9, "{f}: {e:?}");
            assert!((e.f_number.unwrap() - n).abs() < 1e-6, "{f}: {e:?}");
            assert_eq!(e.iso, Some(iso), "{f}: {e:?}");
            let want = t * iso / 100.0 / (n * n);
            assert!(
                (e.exposure().unwrap() / want - 1.0).abs() < 1e-9,
                "{f}: {e:?}"
            );
            // each holds when it was taken, as EXIF writes it
            let when = e.date_time_original.as_deref().unwrap_or_default();
            assert!(
                when.len() == 19 && when.as_bytes()[4] == b':' && when.as_bytes()[10] == b' ',
                "{f}: {e:?}"
            );
        }
        // the Sony's brackets: 16 times the exposure between the first and the last
        let sony = |f: &str| {
            read_exif(&igi_testkit::shared_data("mirror_ball_ldr/olapietka_sony_a6400").join(f))
                .unwrap()
                .exposure()
                .unwrap()
        };
        assert!((sony("raw1.jpg") / sony("raw3.jpg") - 16.0).abs() < 1e-9);
    }

    #[test]
    fn a_file_without_exif_is_an_error_naming_it() {
        let png = igi_testkit::shared_data("hdr_bracketed/memorial/memorial0061.png");
        let e = read_exif(&png).unwrap_err().to_string();
        assert!(
            e.contains("memorial0061.png") && e.contains("no EXIF"),
            "{e}"
        );
    }

    #[test]
    fn exposure_without_aperture_or_iso_counts_them_unchanged() {
        let e = PhotoExif {
            exposure_time_s: Some(0.01),
            ..PhotoExif::default()
        };
        assert_eq!(e.exposure(), Some(0.01));
        assert_eq!(PhotoExif::default().exposure(), None);
    }
}
