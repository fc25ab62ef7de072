//! Photo time and exposure from the EXIF of real JPEGs (../shared/data's mirror-ball
//! photographs: a Sony ILCE-6400 with OffsetTimeOriginal, an iPhone 7 without), imported
//! through a COLMAP model written here, checked against the EXIF bytes parsed by this test's
//! own minimal TIFF reader (not `igi_imaging::exif`).

use std::path::{Path, PathBuf};

use glam::DVec3;
use igi_camera::WorldToCamera;

use crate::model::{matrix_to_quat, CameraModel, ColmapCamera, ColmapImage, ColmapModel};
use crate::{import_colmap, write_text, AlignOptions, ColmapImport, ModelFormat};

/// The fields of one JPEG's EXIF this test checks.
#[derive(Debug, Default)]
struct Raw {
    date_time_original: Option<String>,
    offset_time_original: Option<String>,
    exposure_time: Option<f64>,
    f_number: Option<f64>,
    iso: Option<u32>,
    gps: bool,
}

/// Reads the APP1 `Exif\0\0` segment of a JPEG and the IFD0, Exif and GPS IFD entries this
/// test needs, by the TIFF 6.0 / EXIF 2.32 layout.
fn parse_exif(path: &Path) -> Raw {
    let b = std::fs::read(path).unwrap();
    assert_eq!(&b[..2], &[0xFF, 0xD8], "{}: not a JPEG", path.display());
    let mut i = 2;
    let tiff = loop {
        assert!(i + 4 <= b.len(), "{}: no EXIF segment", path.display());
        let (marker, len) = (
            b[i + 1],
            usize::from(u16::from_be_bytes([b[i + 2], b[i + 3]])),
        );
        if marker == 0xE1 && &b[i + 4..i + 10] == b"Exif\0\0" {
            break &b[i + 10..i + 2 + len];
        }
        i += 2 + len;
    };
    let le = &tiff[..2] == b"II";
    let u16_at = |o: usize| {
        let x = [tiff[o], tiff[o + 1]];
        if le {
            u16::from_le_bytes(x)
        } else {
            u16::from_be_bytes(x)
        }
    };
    let u32_at = |o: usize| {
        let x = [tiff[o], tiff[o + 1], tiff[o + 2], tiff[o + 3]];
        if le {
            u32::from_le_bytes(x)
        } else {
            u32::from_be_bytes(x)
        }
    };
    // (tag, type, count, value offset or inline offset) of each entry of the IFD at `o`
    let entries = |o: usize| -> Vec<(u16, u16, u32, usize)> {
        (0..usize::from(u16_at(o)))
            .map(|k| {
                let e = o + 2 + 12 * k;
                let (ty, n) = (u16_at(e + 2), u32_at(e + 4));
                let size = match ty {
                    2 | 1 | 7 => 1,
                    3 => 2,
                    4 | 9 => 4,
                    _ => 8,
                } * n as usize;
                let at = if size <= 4 {
                    e + 8
                } else {
                    u32_at(e + 8) as usize
                };
                (u16_at(e), ty, n, at)
            })
            .collect()
    };
    let ascii = |at: usize, n: u32| {
        let s = &tiff[at..at + n as usize];
        String::from_utf8_lossy(s)
            .trim_end_matches('\0')
            .trim()
            .to_string()
    };
    let rational = |at: usize| f64::from(u32_at(at)) / f64::from(u32_at(at + 4));
    let mut raw = Raw::default();
    let ifd0 = entries(u32_at(4) as usize);
    for &(tag, _, _, at) in &ifd0 {
        if tag == 0x8825 {
            raw.gps = !entries(u32_at(at) as usize).is_empty();
        }
    }
    let exif_ifd = ifd0
        .iter()
        .find(|e| e.0 == 0x8769)
        .map(|e| u32_at(e.3) as usize);
    for (tag, ty, n, at) in entries(exif_ifd.expect("an Exif IFD")) {
        match tag {
            0x829A => raw.exposure_time = Some(rational(at)),
            0x829D => raw.f_number = Some(rational(at)),
            0x8827 => {
                raw.iso = Some(if ty == 3 {
                    u32::from(u16_at(at))
                } else {
                    u32_at(at)
                })
            }
            0x9003 => raw.date_time_original = Some(ascii(at, n)),
            0x9011 => raw.offset_time_original = Some(ascii(at, n)),
            _ => {}
        }
    }
    raw
}

/// `YYYY:MM:DD HH:MM:SS` and `+HH:MM` as RFC 3339.
fn rfc3339(dt: &str, offset: &str) -> String {
    let (d, t) = dt.split_once(' ').unwrap();
    format!("{}T{t}{offset}", d.replace(':', "-"))
}

const SONY: &str = "mirror_ball_ldr/olapietka_sony_a6400";
const IPHONE: &str = "mirror_ball_ldr/uiuc_cs445_kagrawal_iphone7";

/// A COLMAP model (text) of one camera per photo named `names`, a folder of symlinks to the
/// photos, a mesh; the import job.
fn job(root: &Path, photos: &[(&str, &str)]) -> ColmapImport {
    let mut m = ColmapModel::default();
    m.cameras.push(ColmapCamera {
        id: 1,
        model: CameraModel::Pinhole,
        width: 1500,
        height: 1000,
        params: vec![1200.0, 1200.0, 750.0, 500.0],
    });
    let images = root.join("photos");
    std::fs::create_dir_all(&images).unwrap();
    for (k, (dir, name)) in photos.iter().enumerate() {
        let eye = DVec3::new(k as f64, -5.0, 1.5);
        let pose = WorldToCamera::look_at(eye, DVec3::new(0.0, 0.0, 1.0), DVec3::Z).unwrap();
        m.images.push(ColmapImage {
            id: k as u32 + 1,
            q: matrix_to_quat(pose.r),
            t: pose.t.to_array(),
            camera_id: 1,
            name: (*name).to_string(),
            points2d: vec![],
        });
        let target: PathBuf = igi_testkit::shared_data(dir).join(name);
        std::os::unix::fs::symlink(&target, images.join(name)).unwrap();
    }
    let sparse = root.join("sparse");
    std::fs::create_dir_all(&sparse).unwrap();
    write_text(&m, &sparse).unwrap();
    std::fs::write(root.join("site.ply"), b"ply\n").unwrap();
    ColmapImport {
        format: ModelFormat::Colmap,
        sparse,
        images,
        control: None,
        lighting: None,
        meshes: vec![root.join("site.ply")],
        output: root.join("survey"),
        align: AlignOptions::default(),
        icp: None,
    }
}

#[test]
fn time_and_exposure_come_from_the_exif_of_real_jpegs() {
    let photos = [
        (SONY, "raw0.jpg"),
        (SONY, "raw1.jpg"),
        (SONY, "raw2.jpg"),
        (SONY, "raw3.jpg"),
        (IPHONE, "ball_10.JPG"),
        (IPHONE, "ball_160.JPG"),
    ];
    let dir = tempfile::tempdir().unwrap();
    let j = job(dir.path(), &photos);
    let r = import_colmap(&j).unwrap();
    let survey: igi_formats::survey::SurveyFile =
        igi_formats::TomlFile::read(&j.output.join("survey.toml")).unwrap();
    let mut times = 0;
    for ((d, name), p) in photos.iter().zip(&survey.photo) {
        let raw = parse_exif(&igi_testkit::shared_data(d).join(name));
        let (t, n, iso) = (
            raw.exposure_time.unwrap(),
            raw.f_number.unwrap(),
            f64::from(raw.iso.unwrap()),
        );
        let want = t * iso / 100.0 / (n * n);
        let got = p.exposure.unwrap();
        assert!(
            (got / want - 1.0).abs() < 1e-12,
            "{name}: exposure {got} vs {want}"
        );
        eprintln!(
            "{name}: t {t} s, f/{n}, ISO {iso}: exposure {got:.6e}; time {:?} (EXIF {:?} {:?}, GPS {})",
            p.time, raw.date_time_original, raw.offset_time_original, raw.gps
        );
        match (&raw.date_time_original, &raw.offset_time_original) {
            (Some(dt), Some(off)) => {
                assert_eq!(p.time.as_deref(), Some(rfc3339(dt, off).as_str()), "{name}");
                times += 1;
            }
            _ => {
                assert!(
                    !raw.gps,
                    "{name}: this test's photos without an offset have no GPS time"
                );
                assert_eq!(
                    p.time, None,
                    "{name}: no offset, no GPS: no time is guessed"
                );
                assert!(
                    r.exif_notes
                        .iter()
                        .any(|(id, n)| name.starts_with(id.as_str())
                            && n.contains("time left out: the UTC offset is unknown")),
                    "{name}: {:?}",
                    r.exif_notes
                );
            }
        }
    }
    // the Sony's four carry their offset (+02:00), the iPhone's two do not
    assert_eq!((times, r.times, r.exposures), (4, 4, 6));
    // each camera's photos name one body, from its make and model (CATALOGUE.md: a Sony
    // ILCE-6400, an iPhone 7), and the two bodies differ
    let body = |k: usize| survey.photo[k].body.clone().unwrap_or_default();
    eprintln!("bodies: {:?} / {:?}", body(0), body(4));
    assert!((1..4).all(|k| body(k) == body(0)) && body(5) == body(4));
    assert!(
        body(0).contains("SONY") && body(0).contains("ILCE-6400"),
        "{}",
        body(0)
    );
    assert!(
        body(4).contains("Apple") && body(4).contains("iPhone 7"),
        "{}",
        body(4)
    );
    // raw1 (0.1 s) against raw3 (0.00625 s) at the same f/5.6, ISO 1600: 16 times
    let e = |k: usize| survey.photo[k].exposure.unwrap();
    assert!((e(1) / e(3) - 16.0).abs() < 1e-12);
}

#[test]
fn exposure_is_left_out_of_every_photo_when_one_has_none() {
    // rec1.jpg, the Sony's crop, carries no EXIF
    let photos = [(SONY, "raw1.jpg"), (SONY, "rec1.jpg")];
    let dir = tempfile::tempdir().unwrap();
    let j = job(dir.path(), &photos);
    let r = import_colmap(&j).unwrap();
    assert_eq!((r.times, r.exposures), (1, 0));
    let notes: Vec<String> = r
        .exif_notes
        .iter()
        .map(|(i, n)| format!("{i}: {n}"))
        .collect();
    assert!(
        notes.iter().any(|n| n.starts_with("rec1: no EXIF data"))
            && notes
                .iter()
                .any(|n| n.starts_with("raw1: exposure left out")),
        "{notes:?}"
    );
    let survey: igi_formats::survey::SurveyFile =
        igi_formats::TomlFile::read(&j.output.join("survey.toml")).unwrap();
    assert!(survey.photo.iter().all(|p| p.exposure.is_none()));
    assert_eq!(
        survey.photo[0].time.as_deref(),
        Some("2023-04-06T16:51:33+02:00")
    );
}
