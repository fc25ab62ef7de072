//! A photograph's EXIF: when it was taken and how it was exposed (issue 33).
//!
//! [`read_exif`] reads, through `kamadak-exif`, the fields igi uses from a JPEG, TIFF, PNG,
//! WebP or HEIF container: `DateTimeOriginal` and `OffsetTimeOriginal` (the local time and its
//! UTC offset), `GPSDateStamp` and `GPSTimeStamp` (UTC), `ExposureTime`, `FNumber` and the ISO
//! speed (`PhotographicSensitivity`), and the camera body (`Make`, `Model`,
//! `BodySerialNumber`). Text fields are kept as written (EXIF's padding of NULs and
//! spaces trimmed); `igi_formats::time` turns them into an instant. [`PhotoExif::exposure`]
//! puts photographs taken at different settings on one radiometric scale.
//!
//! Canon's CR3 raw files are ISO base media, a container kamadak-exif does not read: their
//! EXIF is three TIFF blocks in a Canon `uuid` box of `moov` (`CMT1` the primary IFD, `CMT2`
//! the Exif IFD, `CMT4` the GPS IFD; Laurent Clevy's description of the format), which
//! [`read_exif`] finds itself and hands to kamadak-exif one by one.

use crate::ImagingError;
use exif::{Context, Field, In, Tag, Value};
use std::io::{Read, Seek, SeekFrom};
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
    let mut r = std::io::BufReader::new(f);
    let no_exif = |source| ImagingError::NoExif {
        path: path.to_path_buf(),
        source,
    };
    let ex = if is_cr3(&mut r).map_err(|e| ImagingError::io(path, e))? {
        cr3_fields(&mut r).map_err(no_exif)?
    } else {
        let ex = exif::Reader::new()
            .read_from_container(&mut r)
            .map_err(no_exif)?;
        Fields(ex.fields().cloned().collect())
    };
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

/// The fields of a photograph's primary image, from whichever container held them.
struct Fields(Vec<Field>);

impl Fields {
    fn get(&self, tag: Tag) -> Option<&Field> {
        self.0
            .iter()
            .find(|f| f.tag == tag && f.ifd_num == In::PRIMARY)
    }
}

/// Whether the file is a CR3 (an ISO base media `ftyp` box of brand `crx `); rewinds.
fn is_cr3(r: &mut (impl Read + Seek)) -> std::io::Result<bool> {
    let mut head = [0u8; 12];
    let n = r.read(&mut head)?;
    r.seek(SeekFrom::Start(0))?;
    Ok(n == 12 && &head[4..8] == b"ftyp" && &head[8..12] == b"crx ")
}

/// Canon's `uuid` box of a CR3's `moov`, which holds the `CMT` blocks.
const CANON_UUID: [u8; 16] = [
    0x85, 0xc0, 0xb6, 0x87, 0x82, 0x0f, 0x11, 0xe0, 0x81, 0x11, 0xf4, 0xce, 0x46, 0x2b, 0x6a, 0x48,
];

/// The largest `moov` box read (a CR3's is tens of kilobytes).
const MAX_MOOV: u64 = 64 << 20;

/// A CR3's EXIF: `CMT1`, `CMT2` and `CMT4` of Canon's `uuid` box in `moov`, each a TIFF whose
/// first IFD holds the primary, Exif and GPS fields.
fn cr3_fields(r: &mut (impl Read + Seek)) -> Result<Fields, exif::Error> {
    let moov = read_moov(r)?;
    let canon = boxes(&moov)
        .find(|(t, b)| t == b"uuid" && b.starts_with(&CANON_UUID))
        .ok_or(exif::Error::NotFound("a CR3 without Canon's uuid box"))?
        .1;
    let mut fields = Vec::new();
    for (block, context) in [
        (b"CMT1", Context::Tiff),
        (b"CMT2", Context::Exif),
        (b"CMT4", Context::Gps),
    ] {
        let Some((_, tiff)) = boxes(&canon[16..]).find(|(t, _)| t == block) else {
            continue;
        };
        let ex = exif::Reader::new().read_raw(tiff.to_vec())?;
        fields.extend(
            ex.fields()
                .filter(|f| f.ifd_num == In::PRIMARY)
                .map(|f| Field {
                    tag: Tag(context, f.tag.number()),
                    ..f.clone()
                }),
        );
    }
    if fields.is_empty() {
        return Err(exif::Error::NotFound(
            "a CR3 without CMT1, CMT2 or CMT4 blocks",
        ));
    }
    Ok(Fields(fields))
}

/// The payload of a CR3's top-level `moov` box, the boxes before it skipped (not read).
fn read_moov(r: &mut (impl Read + Seek)) -> Result<Vec<u8>, exif::Error> {
    let bad = exif::Error::InvalidFormat;
    loop {
        let mut head = [0u8; 8];
        r.read_exact(&mut head)
            .map_err(|_| exif::Error::NotFound("a CR3 without a moov box"))?;
        let size = u64::from(u32::from_be_bytes([head[0], head[1], head[2], head[3]]));
        let (size, header) = match size {
            1 => {
                let mut large = [0u8; 8];
                r.read_exact(&mut large)?;
                (u64::from_be_bytes(large), 16)
            }
            _ => (size, 8),
        };
        if size < header {
            return Err(bad("a CR3 box shorter than its header"));
        }
        if &head[4..8] == b"moov" {
            if size > MAX_MOOV {
                return Err(bad("a CR3 moov box over 64 MiB"));
            }
            let mut payload = vec![0u8; (size - header) as usize];
            r.read_exact(&mut payload)
                .map_err(|_| bad("a CR3 cut short inside its moov box"))?;
            return Ok(payload);
        }
        let skip = i64::try_from(size - header).map_err(|_| bad("a CR3 box beyond 2^63 bytes"))?;
        r.seek(SeekFrom::Current(skip))?;
    }
}

/// The boxes of an ISO base media byte range, as (type, payload); stops at the first box that
/// does not fit (or whose size is 0: to the end of the file, which no inner box uses).
fn boxes(data: &[u8]) -> impl Iterator<Item = ([u8; 4], &[u8])> {
    let mut at = 0usize;
    std::iter::from_fn(move || {
        let head = data.get(at..at + 8)?;
        let size = u32::from_be_bytes([head[0], head[1], head[2], head[3]]) as usize;
        let kind = [head[4], head[5], head[6], head[7]];
        let payload = data
            .get(at + 8..at.checked_add(size)?)
            .filter(|_| size >= 8)?;
        at += size;
        Some((kind, payload))
    })
}

/// `Make`, `Model` and `#BodySerialNumber`, those present, joined by spaces (the model often
/// repeats the make: then once); `None` when none is.
fn body(ex: &Fields) -> Option<String> {
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
fn text(ex: &Fields, tag: Tag) -> Option<String> {
    let f = ex.get(tag)?;
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
fn positive(ex: &Fields, tag: Tag, path: &Path) -> Result<Option<f64>, ImagingError> {
    let Some(f) = ex.get(tag) else {
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
fn gps_utc(ex: &Fields) -> Option<String> {
    let date = text(ex, Tag::GPSDateStamp)?;
    let f = ex.get(Tag::GPSTimeStamp)?;
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

    /// A Canon EOS R6 CR3 (its first 33,392 bytes, the `ftyp` and `moov` boxes: provenance in
    /// datasets/README.md) against what two independent readers give for the whole file:
    /// ExifTool 12.57 (`exiftool -a -G1 -s`) and the nom-exif project's listing (its
    /// testdata/canon-r6.cr3.sorted.txt, which leaves out the GPS and serial fields).
    #[test]
    fn a_canon_cr3_reads_its_exif_from_canons_cmt_blocks() {
        let e = read_exif(&igi_testkit::fixture("raw/canon_r6_header.cr3")).unwrap();
        let want = PhotoExif {
            date_time_original: Some("2025:09:06 20:24:47".into()),
            offset_time_original: Some("-08:00".into()),
            gps_utc: Some("2025:09:07 03:19:17".into()),
            exposure_time_s: Some(0.01),
            f_number: Some(2.8),
            iso: Some(25600.0),
            body: Some("Canon EOS R6 #072021007989".into()),
        };
        assert_eq!(e, want);
    }

    /// A CR3 cut inside its `moov`, without Canon's box, or with a box claiming 2^64 bytes is
    /// refused naming the file (and the last never loops or reads past the end).
    #[test]
    fn a_damaged_cr3_is_an_error_naming_it() {
        let whole = std::fs::read(igi_testkit::fixture("raw/canon_r6_header.cr3")).unwrap();
        let dir = tempfile::tempdir().unwrap();
        let mut huge = whole[..24].to_vec();
        huge.extend_from_slice(&[0, 0, 0, 1, b'f', b'r', b'e', b'e']);
        huge.extend_from_slice(&u64::MAX.to_be_bytes());
        let mut no_canon = whole.clone();
        no_canon[40..56].fill(0); // the uuid of Canon's box (at 32, after its 8-byte header)
        for (name, bytes, problem) in [
            ("cut.cr3", &whole[..20_000], "cut short inside its moov box"),
            ("huge.cr3", &huge[..], "beyond 2^63 bytes"),
            ("no_canon.cr3", &no_canon[..], "without Canon's uuid box"),
        ] {
            let path = dir.path().join(name);
            std::fs::write(&path, bytes).unwrap();
            let e = read_exif(&path).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains(problem), "{e}");
        }
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
