//! The RAW decoder against LibRaw on a real camera file: `_DSC2164.ARW`, a Sony ILCE-7RM3
//! photograph that `bash scripts/deps.sh test` fetches (the MIT-licensed PyPI package
//! libraw-cffi 0.19.0 ships it as a test file). datasets/raw_reference.py wrote
//! datasets/fixtures/raw/dsc2164_libraw.json from it with rawpy 0.28.0 (LibRaw 0.22.2) and
//! exifread 3.5.1: the file's levels, white balance and colour matrix, its EXIF, and LibRaw's
//! linear Rec. 709 image as 64 x 64 block means (docs/IMAGING.md, "Camera RAW").

use crate::exif::read_exif;
use crate::raw::{camera_to_rgb, read_raw};
use serde::Deserialize;

#[derive(Deserialize)]
struct Reference {
    bytes: usize,
    exif: ReferenceExif,
    width: usize,
    height: usize,
    wb: [f32; 3],
    xyz_to_cam: [[f32; 3]; 3],
    block: usize,
    blocks: Vec<Vec<[f64; 3]>>,
    block_max: Vec<Vec<f64>>,
}

#[derive(Deserialize)]
struct ReferenceExif {
    make: String,
    model: String,
    date_time_original: String,
    offset_time_original: String,
    exposure_time_s: f64,
    f_number: f64,
    iso: f64,
}

fn reference() -> Reference {
    let path = igi_testkit::fixture("raw/dsc2164_libraw.json");
    serde_json::from_slice(&std::fs::read(&path).unwrap()).unwrap()
}

/// Relative RMSE and median ratio of igi's block means against LibRaw's, over every block
/// channel LibRaw puts at 0.05 or more in a block without a clipped pixel; and their count.
fn against_libraw(img: &crate::HdrImage, r: &Reference) -> (f64, f64, usize) {
    let b = r.block;
    let (mut sq, mut sq_ref, mut ratios) = (0.0, 0.0, Vec::new());
    for (by, row) in r.blocks.iter().enumerate() {
        for (bx, want) in row.iter().enumerate() {
            if r.block_max[by][bx] >= 0.99 {
                continue;
            }
            let mut sum = [0.0f64; 3];
            for y in by * b..(by + 1) * b {
                for x in bx * b..(bx + 1) * b {
                    let p = img.pixels[y * img.width + x];
                    (0..3).for_each(|c| sum[c] += p[c] as f64);
                }
            }
            for c in 0..3 {
                if want[c] >= 0.05 {
                    let got = sum[c] / (b * b) as f64;
                    sq += (got - want[c]).powi(2);
                    sq_ref += want[c].powi(2);
                    ratios.push(got / want[c]);
                }
            }
        }
    }
    ratios.sort_by(f64::total_cmp);
    let median = ratios.get(ratios.len() / 2).copied().unwrap_or(f64::NAN);
    ((sq / sq_ref).sqrt(), median, ratios.len())
}

#[test]
fn a_real_sony_arw_decodes_as_libraw_does() {
    let path = igi_testkit::fetched_data("raw/_DSC2164.ARW");
    let r = reference();
    // scripts/deps.sh checks its SHA-256 (the fixture's `sha256`)
    let len = std::fs::metadata(&path).unwrap().len() as usize;
    assert_eq!(
        len,
        r.bytes,
        "{} is not the file the reference was made from",
        path.display()
    );

    let photo = read_raw(&path).unwrap();
    assert_eq!((photo.image.width, photo.image.height), (r.width, r.height));
    for k in 0..3 {
        assert!(
            (photo.wb[k] - r.wb[k]).abs() < 1e-5,
            "wb {:?} against LibRaw's {:?}",
            photo.wb,
            r.wb
        );
    }
    let m = camera_to_rgb(r.xyz_to_cam).unwrap();
    for (a, b) in photo.cam_to_rgb.iter().flatten().zip(m.iter().flatten()) {
        assert!(
            (a - b).abs() < 1e-4,
            "{:?} against LibRaw's {m:?}",
            photo.cam_to_rgb
        );
    }
    let (rmse, median, n) = against_libraw(&photo.image, &r);
    eprintln!("against LibRaw: {n} block channels, relative RMSE {rmse:.4}, median ratio {median:.4}, {} clipped", photo.clipped);
    assert!(n >= 1000, "only {n} block channels compared");
    // measured: 0.0036 and 0.9986 (LibRaw demosaics bilinearly, rawler by PPG); one pixel out
    // of register gives 0.0063 to 0.0098, LibRaw's own white level 16383 a ratio of 1.069
    assert!(rmse < 0.005, "relative RMSE {rmse} against LibRaw");
    assert!(
        (median - 1.0).abs() < 0.005,
        "median ratio {median} to LibRaw"
    );

    // the photograph reader of surveys takes it as linear, the same pixels
    let p = crate::photo::read_photo(&path, &crate::photo::Transfer::Default).unwrap();
    assert_eq!(p.applied, crate::photo::Applied::Linear);
    assert_eq!(p.clipped, photo.clipped);
    assert!(p.image.pixels == photo.image.pixels && p.image.valid == photo.image.valid);

    let e = read_exif(&path).unwrap();
    let x = &r.exif;
    assert_eq!(
        e.date_time_original.as_deref(),
        Some(x.date_time_original.as_str())
    );
    assert_eq!(
        e.offset_time_original.as_deref(),
        Some(x.offset_time_original.as_str())
    );
    assert!((e.exposure_time_s.unwrap() - x.exposure_time_s).abs() < 1e-12);
    assert!((e.f_number.unwrap() - x.f_number).abs() < 1e-12);
    assert_eq!(e.iso, Some(x.iso));
    let body = e.body.unwrap();
    assert!(
        body.starts_with(&format!("{} {}", x.make, x.model)),
        "{body}"
    );
}
