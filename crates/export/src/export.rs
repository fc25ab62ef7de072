//! `igi export --format ply|obj|mitsuba`: the recovered site as files other tools open.

use crate::ExportError;
use glam::Vec3;
use igi_files::write_text_atomic as write_text;
use igi_formats::scene::SceneFile;
use igi_formats::TomlFile;
use igi_geometry::{write_obj, write_ply};
use igi_imaging::{read_image, write_exr, HdrImage};
use igi_reflect::SolveResult;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// Export formats of `igi export`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum ExportFormat {
    Ply,
    Obj,
    Mitsuba,
}

impl std::str::FromStr for ExportFormat {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "ply" => Ok(ExportFormat::Ply),
            "obj" => Ok(ExportFormat::Obj),
            "mitsuba" => Ok(ExportFormat::Mitsuba),
            _ => Err(format!("unknown export format `{s}` (ply, obj or mitsuba)")),
        }
    }
}

/// The picture of a part's standard-error atlas that `igi export` writes: grey, black at 0 and
/// white at [`STDERR_PICTURE_MAX`] or more (the luminance of the per-channel standard error),
/// magenta where unknown.
fn stderr_picture(stderr: &[Vec3], r: usize) -> HdrImage {
    let mut im = HdrImage::new(r, r);
    for (px, s) in im.pixels.iter_mut().zip(stderr) {
        *px = if s.min_element() >= 0.0 {
            [(igi_brdf::luminance(*s) / STDERR_PICTURE_MAX).min(1.0); 3]
        } else {
            [1.0, 0.0, 1.0]
        };
    }
    im
}

/// The standard error shown white in `NAME_stderr.png` of `igi export`.
pub const STDERR_PICTURE_MAX: f32 = 0.05;

/// Writes the recovered site into `out` (layout in docs/SOLVER.md, "Export"): per part the mesh
/// with atlas UVs (`NAME.ply`, or `NAME.obj` with `NAME.mtl`), the linear albedo texture
/// `NAME_albedo.exr` with an sRGB preview, `NAME_stderr.png` (a picture of the albedo's standard
/// error, see `stderr_picture`) and, when the result infers lobes from a BRDF basis, the
/// per-texel lobe maps `NAME_lobeK_rho.exr` (RGB) and `NAME_lobeK_shape.exr` (Cxy, Cz, N); and
/// `scene.toml`, an igi scene file (FORMATS.md) of all of it, so `igi render OUT/scene.toml`
/// renders the export as `igi render RESULT_DIR` renders the result. For `Mitsuba` also
/// `scene.xml`: diffuse bitmap textures only, since Mitsuba 3 has no Lafortune BSDF (the file
/// says so and names the lobe maps it leaves out). Mitsuba reads the EXR as linear; its bitmap
/// lookup has v = 0 at the top row, so `to_uv` flips v to FORMATS.md's convention, as
/// `datasets/mitsuba/outdoor_reference.py` verifies against Mitsuba. Returns the files written.
pub fn export(
    result_dir: &Path,
    format: ExportFormat,
    out: &Path,
) -> Result<Vec<PathBuf>, ExportError> {
    let res = SolveResult::load(result_dir)?;
    std::fs::create_dir_all(out)
        .map_err(|e| ExportError::file(out, format!("cannot create folder: {e}")))?;
    let mut written = Vec::new();
    let mut scene = SceneFile::default();
    let mut shapes = String::new();
    let mut lobe_maps = 0;
    for (i, p) in res.parts.iter().enumerate() {
        let (files, per_texel) = export_textures(&res, result_dir, i, out)?;
        lobe_maps += per_texel;
        written.extend(files);
        let mesh = match format {
            ExportFormat::Ply | ExportFormat::Mitsuba => {
                let mp = out.join(format!("{}.ply", p.name));
                write_ply(&mp, &*p.full_mesh()?)?;
                let _ = writeln!(
                    shapes,
                    "  <shape type=\"ply\">\n    <string name=\"filename\" value=\"{0}.ply\"/>\n    <bsdf type=\"twosided\"><bsdf type=\"diffuse\">\n      <texture type=\"bitmap\" name=\"reflectance\"><string name=\"filename\" value=\"{0}_albedo.exr\"/><boolean name=\"raw\" value=\"true\"/><string name=\"filter_type\" value=\"bilinear\"/><string name=\"wrap_mode\" value=\"clamp\"/>\n        <transform name=\"to_uv\"><scale x=\"1\" y=\"-1\"/><translate x=\"0\" y=\"1\"/></transform></texture>\n    </bsdf></bsdf>\n  </shape>",
                    p.name
                );
                mp
            }
            ExportFormat::Obj => {
                let mp = out.join(format!("{}.obj", p.name));
                write_obj(&mp, &*p.full_mesh()?)?;
                let mtl = format!("newmtl {0}\nKd 1 1 1\nmap_Kd {0}_albedo.png\n", p.name);
                write_text(&out.join(format!("{}.mtl", p.name)), &mtl)?;
                mp
            }
        };
        let mesh_name = mesh.file_name().map(|n| n.to_string_lossy().into_owned());
        let albedo = format!("{}_albedo.exr", p.name);
        let mesh_name = mesh_name.unwrap_or_default();
        scene
            .object
            .push(res.object_entry(i, &mesh_name, &albedo, "", per_texel));
        written.push(mesh);
    }
    let sp = out.join("scene.toml");
    scene.write(
        &sp,
        &[
            "Recovered reflectance (igi export). Render with:",
            "igi render THIS_FILE --lighting L.toml --camera C.json --spp N -o out.exr",
        ],
    )?;
    written.push(sp);
    if format == ExportFormat::Mitsuba {
        let lobes = if lobe_maps == 0 {
            "The result has no specular lobes: the scene is complete.".to_string()
        } else {
            format!("APPROXIMATION: Mitsuba 3 has no Lafortune BSDF, so each part is its diffuse term only; the {lobe_maps} per-texel specular lobe maps (NAME_lobeK_rho.exr, NAME_lobeK_shape.exr; igi render scene.toml renders them) are left out, so highlights and grazing-angle reflection are missing.")
        };
        let xml = format!(
            "<scene version=\"3.0.0\">\n  <!-- igi export: recovered reflectance; world Z up, metres. Add a sensor and emitters to render (datasets/mitsuba/export_reference.py does). -->\n  <!-- {lobes} -->\n  <integrator type=\"path\"><integer name=\"max_depth\" value=\"4\"/></integrator>\n{shapes}</scene>\n"
        );
        let xp = out.join("scene.xml");
        write_text(&xp, &xml)?;
        written.push(xp);
    }
    Ok(written)
}

/// Writes part `i`'s albedo (EXR and PNG preview), its standard-error picture and the lobe maps
/// the result holds into `out`; returns the standard-error picture, the albedo EXR and the lobe
/// maps, and the number of lobes per texel.
fn export_textures(
    res: &SolveResult,
    result_dir: &Path,
    i: usize,
    out: &Path,
) -> Result<(Vec<PathBuf>, usize), ExportError> {
    let p = &res.parts[i];
    let r = p.resolution();
    let mut tex = HdrImage::new(r, r);
    for (k, px) in tex.pixels.iter_mut().enumerate() {
        *px = res.rho[i][k].to_array();
    }
    let albedo = out.join(format!("{}_albedo.exr", p.name));
    write_exr(&albedo, &tex)?;
    igi_imaging::write_png_tonemapped(&out.join(format!("{}_albedo.png", p.name)), &tex, 1.0)?;
    let se_png = out.join(format!("{}_stderr.png", p.name));
    igi_imaging::write_png_tonemapped(&se_png, &stderr_picture(&res.stderr[i], r), 1.0)?;
    let mut written = vec![se_png, albedo];
    // the lobe maps the result wrote (a loaded result does not keep its basis)
    let mut k = 0;
    loop {
        let name = |suffix: &str| format!("{}_lobe{k}_{suffix}.exr", p.name);
        let src = result_dir.join("parts");
        if !src.join(name("rho")).is_file() {
            break;
        }
        for suffix in ["rho", "shape"] {
            let im = read_image(&src.join(name(suffix)))?;
            if (im.width, im.height) != (r, r) {
                return Err(ExportError::file(
                    src.join(name(suffix)),
                    format!("is {}x{}, the part's atlas {r}x{r}", im.width, im.height),
                ));
            }
            let f = out.join(name(suffix));
            write_exr(&f, &im)?;
            written.push(f);
        }
        k += 1;
    }
    Ok((written, k))
}
