//! What `igi probe` writes: the lighting file and, beside it, the sky map, the measured sky,
//! the sphere hemispheres, tone-mapped pictures with the sun marked, the diffuse check and the
//! diagnostics (docs/PROBE.md, "Outputs"). Every file is written atomically.

use crate::envmap::hemisphere_pixel;
use crate::{ProbeError, ProbeResult};
use igi_files::write_text_atomic;
use igi_formats::lighting::{EnvironmentSection, LightingFile, SunSection};
use igi_formats::TomlFile;
use igi_imaging::{auto_exposure, write_exr, write_png_tonemapped, HdrImage, ImagingError};
use std::path::{Path, PathBuf};

/// `out`'s sibling `STEM_suffix` (the lighting file `sky.toml` has `sky_sky.exr` beside it).
pub fn sibling(out: &Path, suffix: &str) -> PathBuf {
    let stem = out
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_else(|| "lighting".into());
    out.with_file_name(format!("{stem}_{suffix}"))
}

/// Tone-mapped picture; invalid (masked) pixels in dark magenta, and a red ring of radius 9 px
/// around `mark` (the sun).
fn picture(
    path: &Path,
    img: &HdrImage,
    exposure: f32,
    mark: Option<(f32, f32)>,
) -> Result<(), ImagingError> {
    let mut p = img.clone();
    for (px, v) in p.pixels.iter_mut().zip(p.valid.iter_mut()) {
        if !*v {
            *px = [0.25 / exposure, 0.0, 0.25 / exposure];
            *v = true;
        }
    }
    if let Some((cx, cy)) = mark {
        for y in 0..p.height {
            for x in 0..p.width {
                let r = ((x as f32 - cx).powi(2) + (y as f32 - cy).powi(2)).sqrt();
                if (7.5..=9.5).contains(&r) {
                    p.set(x, y, [4.0 / exposure, 0.0, 0.0]);
                }
            }
        }
    }
    write_png_tonemapped(path, &p, exposure)
}

/// The diffuse sphere's check side by side: measured D | model D' + a D* | 10 x |difference|.
fn diffuse_check(measured: &HdrImage, model: &HdrImage) -> HdrImage {
    let (w, h) = (measured.width, measured.height);
    let mut side = HdrImage::new(3 * w, h);
    for y in 0..h {
        for x in 0..w {
            let k = y * w + x;
            let diff = [0, 1, 2].map(|c| 10.0 * (measured.pixels[k][c] - model.pixels[k][c]).abs());
            for (i, v) in [measured.pixels[k], model.pixels[k], diff]
                .into_iter()
                .enumerate()
            {
                let j = y * 3 * w + i * w + x;
                side.pixels[j] = v;
                side.valid[j] = measured.valid[k];
            }
        }
    }
    side
}

/// The lighting file: the sky map `sky_map` (a file name beside it) and the sun where its
/// radiance was measured.
pub fn lighting_file(r: &ProbeResult, sky_map: &str) -> LightingFile {
    LightingFile {
        environment: Some(EnvironmentSection {
            map: sky_map.into(),
            scale: 1.0,
        }),
        sun: r.diagnostics.sun.as_ref().and_then(|s| {
            s.radiance.map(|rad| SunSection {
                direction: s.direction,
                radiance: rad.map(|v| v as f64),
                angular_diameter_deg: s.angular_diameter_deg,
            })
        }),
    }
}

/// Write the lighting file `out` and everything beside it.
pub fn write_outputs(out: &Path, r: &ProbeResult) -> Result<(), ProbeError> {
    let name = |p: &Path| p.file_name().unwrap().to_string_lossy().into_owned();
    let sky_path = sibling(out, "sky.exr");
    write_exr(&sky_path, &r.sky)?;
    write_exr(&sibling(out, "sky_measured.exr"), &r.sky_measured)?;
    write_exr(&sibling(out, "mirror_hemi.exr"), &r.mirror_hemi)?;
    if let Some(b) = &r.black_hemi {
        write_exr(&sibling(out, "black_hemi.exr"), b)?;
    }
    write_pictures(out, r)?;
    let diag_path = sibling(out, "diagnostics.json");
    let json = serde_json::to_string_pretty(&r.diagnostics).expect("diagnostics serialise");
    write_text_atomic(&diag_path, &json)?;
    let header = format!("written by igi probe; diagnostics in {}", name(&diag_path));
    lighting_file(r, &name(&sky_path)).write(out, &[&header])?;
    Ok(())
}

/// The tone-mapped pictures: hemispheres and sky with the sun ringed, the diffuse check.
fn write_pictures(out: &Path, r: &ProbeResult) -> Result<(), ImagingError> {
    let exp = auto_exposure(&r.sky_measured);
    let sun_v = r
        .diagnostics
        .sun
        .as_ref()
        .map(|s| glam::DVec3::from_array(s.direction).as_vec3());
    let hemi_mark = sun_v.and_then(|s| hemisphere_pixel(s, r.mirror_hemi.width));
    picture(
        &sibling(out, "mirror_hemi.png"),
        &r.mirror_hemi,
        exp,
        hemi_mark,
    )?;
    if let Some(b) = &r.black_hemi {
        picture(
            &sibling(out, "black_hemi.png"),
            b,
            auto_exposure(b),
            hemi_mark,
        )?;
    }
    if let Some(d) = &r.diffuse_hemi {
        picture(&sibling(out, "diffuse_hemi.png"), d, auto_exposure(d), None)?;
    }
    let ll_mark = sun_v.map(|s| {
        igi_imaging::latlong::direction_to_pixel(s, r.sky_measured.width, r.sky_measured.height)
    });
    picture(&sibling(out, "sky.png"), &r.sky_measured, exp, ll_mark)?;
    if let Some((dm, model)) = &r.diffuse_compare {
        let side = diffuse_check(dm, model);
        picture(
            &sibling(out, "diffuse_check.png"),
            &side,
            auto_exposure(dm),
            None,
        )?;
    }
    Ok(())
}
