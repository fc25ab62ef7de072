//! `igi export --format ply|obj|mitsuba|gltf`: the recovered site as files other tools open.

use crate::lobefit::GltfFit;
use crate::ExportError;
use glam::Vec3;
use igi_brdf::Lobe;
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
    /// One binary glTF 2.0 file, `scene.glb` ([`crate::gltf`]).
    Gltf,
}

impl ExportFormat {
    /// The name on the command line.
    pub fn name(self) -> &'static str {
        match self {
            ExportFormat::Ply => "ply",
            ExportFormat::Obj => "obj",
            ExportFormat::Mitsuba => "mitsuba",
            ExportFormat::Gltf => "gltf",
        }
    }
}

impl std::str::FromStr for ExportFormat {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        match s {
            "ply" => Ok(ExportFormat::Ply),
            "obj" => Ok(ExportFormat::Obj),
            "mitsuba" => Ok(ExportFormat::Mitsuba),
            "gltf" | "glb" => Ok(ExportFormat::Gltf),
            _ => Err(format!(
                "unknown export format `{s}` (ply, obj, mitsuba or gltf)"
            )),
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

/// What [`export`] wrote.
#[derive(Clone, Debug)]
pub struct Exported {
    /// Every file written into the output folder (`export.json` last).
    pub files: Vec<PathBuf>,
    /// For glTF, per part: its name, the number of lobes the fit approximated (per texel or
    /// constant) and the fit ([`crate::lobefit`]); empty for the other formats.
    pub materials: Vec<(String, usize, GltfFit)>,
}

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
/// `datasets/mitsuba/outdoor_reference.py` verifies against Mitsuba. For `Gltf`, `scene.glb`
/// ([`crate::gltf`]) in place of the meshes and `scene.toml`, beside the same textures.
///
/// The output folder is checked first ([`crate::outdir`]: not the result folder nor inside it;
/// new, empty, or an earlier igi export only, which is then replaced whole), the export is
/// written into a staging folder and moved into place complete, with `export.json` listing it.
pub fn export(
    result_dir: &Path,
    format: ExportFormat,
    out: &Path,
) -> Result<Exported, ExportError> {
    let kind = crate::folders::folder_kind(result_dir)?;
    if kind != crate::FolderKind::Result {
        if format != ExportFormat::Gltf {
            return Err(ExportError::GltfOnly {
                dir: result_dir.to_path_buf(),
                kind: kind.name(),
                format: format.name(),
            });
        }
        let plan = crate::outdir::check(result_dir, out)?;
        let glb = folder_glb(result_dir)?;
        plan.begin()?;
        let glb_path = plan.staging.join("scene.glb");
        if let Err(e) = igi_files::write_atomic(&glb_path, |tmp| {
            std::fs::write(tmp, &glb.bytes)
                .map_err(|e| ExportError::file(&glb_path, format!("cannot write: {e}")))
        }) {
            plan.abandon();
            return Err(e);
        }
        let files = plan.commit(format.name(), result_dir)?;
        return Ok(Exported {
            files,
            materials: Vec::new(),
        });
    }
    let plan = crate::outdir::check(result_dir, out)?;
    let res = SolveResult::load(result_dir)?;
    plan.begin()?;
    let materials = match write_export(&res, result_dir, format, &plan.staging) {
        Ok(m) => m,
        Err(e) => {
            plan.abandon();
            return Err(e);
        }
    };
    let files = plan.commit(format.name(), result_dir)?;
    Ok(Exported { files, materials })
}

/// Writes the export of `res` into the (staging) folder `out`.
fn write_export(
    res: &SolveResult,
    result_dir: &Path,
    format: ExportFormat,
    out: &Path,
) -> Result<Vec<(String, usize, GltfFit)>, ExportError> {
    if format == ExportFormat::Gltf {
        return write_gltf(res, result_dir, out);
    }
    let mut scene = SceneFile::default();
    let mut shapes = String::new();
    let mut lobe_maps = 0;
    for (i, p) in res.parts.iter().map(|p| &p.part).enumerate() {
        let (albedo, maps) = part_textures(res, result_dir, i)?;
        write_textures(res, i, &albedo, &maps, out)?;
        let per_texel = maps.len();
        lobe_maps += per_texel;
        let mesh = match format {
            ExportFormat::Ply | ExportFormat::Mitsuba | ExportFormat::Gltf => {
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
    }
    let sp = out.join("scene.toml");
    scene.write(
        &sp,
        &[
            "Recovered reflectance (igi export). Render with:",
            "igi render THIS_FILE --lighting L.toml --camera C.json --spp N -o out.exr",
        ],
    )?;
    if format == ExportFormat::Mitsuba {
        let lobes = if lobe_maps == 0 {
            "The result has no specular lobes: the scene is complete.".to_string()
        } else {
            format!("APPROXIMATION: Mitsuba 3 has no Lafortune BSDF, so each part is its diffuse term only; the {lobe_maps} per-texel specular lobe maps (NAME_lobeK_rho.exr, NAME_lobeK_shape.exr; igi render scene.toml renders them) are left out, so highlights and grazing-angle reflection are missing.")
        };
        let xml = format!(
            "<scene version=\"3.0.0\">\n  <!-- igi export: recovered reflectance; world Z up, metres. Add a sensor and emitters to render (datasets/mitsuba/export_reference.py does). -->\n  <!-- {lobes} -->\n  <integrator type=\"path\"><integer name=\"max_depth\" value=\"4\"/></integrator>\n{shapes}</scene>\n"
        );
        write_text(&out.join("scene.xml"), &xml)?;
    }
    Ok(Vec::new())
}

/// The mean lobes of per-texel lobe maps over the covered texels: each lobe's colour averaged,
/// its shape (Cxy, Cz, N) averaged weighted by the colour's luminance.
fn mean_lobes(maps: &[(HdrImage, HdrImage)], covered: &[usize]) -> Vec<Lobe> {
    maps.iter()
        .map(|(rho, shape)| {
            let (mut sum, mut w, mut sh) = (Vec3::ZERO, 0.0f64, [0.0f64; 3]);
            for &k in covered {
                let r = Vec3::from(rho.pixels[k]);
                let l = igi_brdf::luminance(r).max(0.0) as f64;
                sum += r;
                w += l;
                for c in 0..3 {
                    sh[c] += l * shape.pixels[k][c] as f64;
                }
            }
            let n = covered.len().max(1) as f32;
            if w > 0.0 {
                Lobe {
                    rho: sum / n,
                    cxy: (sh[0] / w) as f32,
                    cz: (sh[1] / w) as f32,
                    n: (sh[2] / w) as f32,
                }
            } else {
                Lobe {
                    rho: Vec3::ZERO,
                    cxy: -1.0,
                    cz: 1.0,
                    n: 1.0,
                }
            }
        })
        .collect()
}

/// A result as one binary glTF file, in memory ([`result_glb`]).
#[derive(Clone, Debug)]
pub struct ResultGlb {
    /// The GLB bytes, exactly those `igi export --format gltf` writes as `scene.glb`.
    pub bytes: Vec<u8>,
    /// Per part: its name, the number of lobes the fit approximated and the fit
    /// ([`crate::lobefit`]).
    pub materials: Vec<(String, usize, GltfFit)>,
    /// Per part, in the parts' order: its standard-error picture (`NAME_stderr.png` of the
    /// export) as PNG bytes.
    pub stderr_png: Vec<Vec<u8>>,
}

/// The result folder `result_dir` as the GLB `igi export --format gltf` writes (docs/EXPORT.md,
/// "glTF"), in memory, with the fit of each part's lobes: what `igi view` serves.
pub fn result_glb(result_dir: &Path) -> Result<ResultGlb, ExportError> {
    let res = SolveResult::load(result_dir)?;
    let (glb, _) = gltf_of(&res, result_dir)?;
    Ok(glb)
}

/// A folder of any kind as one GLB, in memory.
#[derive(Clone, Debug)]
pub struct FolderGlb {
    pub kind: crate::FolderKind,
    pub bytes: Vec<u8>,
    /// For a result, the GLB and its fits ([`ResultGlb`]); `None` otherwise.
    pub result: Option<ResultGlb>,
    /// For a light field, the field as loaded and its median texture's scale (its 99th
    /// percentile to 1, [`crate::folders::median_texture`]); `None` otherwise.
    pub light_field: Option<(igi_lightfield::SurfaceLightField, f32)>,
    /// What the GLB holds, for a summary (`part wall`, `12000 surfels`, ...).
    pub summary: Vec<String>,
}

/// `dir` (a result, hull or light field: [`crate::folder_kind`]) as the GLB `igi export --format
/// gltf` writes.
pub fn folder_glb(dir: &Path) -> Result<FolderGlb, ExportError> {
    let kind = crate::folders::folder_kind(dir)?;
    match kind {
        crate::FolderKind::Result => {
            let r = result_glb(dir)?;
            Ok(FolderGlb {
                kind,
                bytes: r.bytes.clone(),
                summary: r
                    .materials
                    .iter()
                    .map(|m| format!("part {}", m.0))
                    .collect(),
                result: Some(r),
                light_field: None,
            })
        }
        crate::FolderKind::Hull => {
            let (bytes, summary) = crate::folders::hull_glb(dir)?;
            Ok(FolderGlb {
                kind,
                bytes,
                result: None,
                light_field: None,
                summary,
            })
        }
        crate::FolderKind::LightField => {
            let (bytes, summary, field) = crate::folders::light_field_glb(dir)?;
            Ok(FolderGlb {
                kind,
                bytes,
                result: None,
                light_field: Some(field),
                summary,
            })
        }
    }
}

/// The glTF materials of the parts of `res` that `want` picks ([`PartsGltf`]).
fn parts_gltf<'a>(
    res: &'a SolveResult,
    result_dir: &Path,
    want: &dyn Fn(usize) -> bool,
) -> Result<crate::gltf::PartsGltf<'a>, ExportError> {
    let glb_path = result_dir.to_path_buf();
    let mut meshes = Vec::new();
    let mut textures = Vec::new();
    let mut fits = Vec::new();
    let mut extras = Vec::new();
    let mut stderr_png = Vec::new();
    for (i, pr) in res.parts.iter().enumerate() {
        if !want(i) {
            continue;
        }
        let p = &pr.part;
        let (albedo, maps) = part_textures(res, result_dir, i)?;
        let se = stderr_picture(&pr.stderr, p.resolution());
        stderr_png.push(crate::gltf::albedo_png(&glb_path, &se)?);
        let covered: Vec<usize> = p.cache.texels.iter().map(|t| t.index as usize).collect();
        let mean_rho =
            covered.iter().map(|&k| pr.rho[k]).sum::<Vec3>() / covered.len().max(1) as f32;
        let (lobes, mut ex) = if maps.is_empty() {
            let l = pr.lobes.clone();
            let ex = serde_json::json!({ "lobes": crate::gltf::lobes_json(&l) });
            (l, ex)
        } else {
            let l = mean_lobes(&maps, &covered);
            let names: Vec<_> = (0..maps.len())
                .map(|k| {
                    serde_json::json!({
                        "rho": format!("{}_lobe{k}_rho.exr", p.name),
                        "shape": format!("{}_lobe{k}_shape.exr", p.name),
                    })
                })
                .collect();
            let ex = serde_json::json!({
                "lobe_maps": names,
                "lobe_maps_note": "per texel: lobe k's RGB colour in _rho.exr, its Cxy, Cz, N in the channels of _shape.exr (atlas rows top first, igi's v up)",
                "mean_lobes": crate::gltf::lobes_json(&l),
            });
            (l, ex)
        };
        let fit = crate::lobefit::fit_gltf(mean_rho, &lobes);
        ex["albedo"] = format!("{}_albedo.exr", p.name).into();
        ex["brdf"] = "Lafortune: f = rho_d / pi + sum_l rho_l max(0, Cxy (ux vx + uy vy) + Cz uz vz)^N_l (local frame, z the normal)".into();
        ex["fit"] = if lobes.is_empty() {
            serde_json::json!({
                "model": "pure diffuse: the result has no lobes, so roughness 1 and specular 0 are exact",
                "rel_rms": 0.0,
            })
        } else {
            serde_json::json!({
                "model": "glTF metallic-roughness (metallic 0) with KHR_materials_specular, least squares to the Lafortune BRDF with base colour the part's mean albedo",
                "base_color": mean_rho.to_array(),
                "rel_rms": fit.rel_rms,
                "pairs": crate::lobefit::FIT_PAIRS,
                "error": "relative RMS of f cos(theta_i) over the pairs, weighted by solid angle",
                "retroreflective": format!("{} retroreflective lobe(s) folded: the fit's target includes them, glTF has no such lobe, what it cannot express is in rel_rms", fit.retroreflective_lobes),
            })
        };
        meshes.push(p.full_mesh()?);
        textures.push((albedo, maps));
        fits.push((p.name.clone(), lobes.len(), fit));
        extras.push(ex);
    }
    Ok(crate::gltf::PartsGltf {
        meshes,
        textures,
        fits,
        extras,
        stderr_png,
    })
}

/// The GLB of `res` and each part's textures (the albedo atlas and the lobe maps).
#[allow(clippy::type_complexity)]
fn gltf_of(
    res: &SolveResult,
    result_dir: &Path,
) -> Result<(ResultGlb, Vec<(HdrImage, Vec<(HdrImage, HdrImage)>)>), ExportError> {
    let glb_path = result_dir.to_path_buf();
    let crate::gltf::PartsGltf {
        meshes,
        textures,
        fits,
        extras,
        stderr_png,
    } = parts_gltf(res, result_dir, &|_| true)?;
    let parts: Vec<crate::gltf::GlbPart> = res
        .parts
        .iter()
        .enumerate()
        .map(|(i, p)| crate::gltf::GlbPart {
            name: p.name(),
            mesh: &meshes[i],
            albedo: &textures[i].0,
            fit: fits[i].2,
            extras: extras[i].clone(),
        })
        .collect();
    let asset = serde_json::json!({
        "result": result_dir.display().to_string(),
        "axes": "igi world Z up (metres); the root node rotates it to glTF's Y up",
        "texcoord": "v_gltf = 1 - v_igi (igi's atlas origin is the bottom-left)",
    });
    let bytes = crate::gltf::glb_bytes(&glb_path, &parts, asset)?;
    Ok((
        ResultGlb {
            bytes,
            materials: fits,
            stderr_png,
        },
        textures,
    ))
}

/// A result as 3D Tiles 1.1 ([`crate::tiles`]): per part and level one GLB, handed to
/// `on_part` with the part's index and textures; returns the tileset and the fits.
#[allow(clippy::type_complexity)]
fn tiles_of(
    res: &SolveResult,
    result_dir: &Path,
    on_part: &mut dyn FnMut(
        usize,
        &(HdrImage, Vec<(HdrImage, HdrImage)>),
        Vec<(String, Vec<u8>)>,
    ) -> Result<(), ExportError>,
) -> Result<crate::tiles::ResultTiles, ExportError> {
    let mut set = crate::tiles::TilesetBuilder::open(res, result_dir)?;
    for i in 0..res.parts.len() {
        let g = parts_gltf(res, result_dir, &|k| k == i)?;
        let glbs = set.add(&res.parts[i].part, g.as_glb_part(0))?;
        on_part(i, &g.textures[0], glbs)?;
        set.keep(g);
    }
    Ok(set.finish())
}

/// A result as 3D Tiles 1.1 in memory ([`crate::tiles`]): the tileset and the GLBs by file
/// name, as `igi export --format gltf` writes them for a prepared site; what `igi view` serves.
#[allow(clippy::type_complexity)]
pub fn result_tiles(
    result_dir: &Path,
) -> Result<(crate::tiles::ResultTiles, Vec<(String, Vec<u8>)>), ExportError> {
    let res = SolveResult::load(result_dir)?;
    let mut files = Vec::new();
    let set = tiles_of(&res, result_dir, &mut |_, _, glbs| {
        files.extend(glbs);
        Ok(())
    })?;
    Ok((set, files))
}

/// `scene.glb` and the textures beside it (or, for a prepared site or a result too large for
/// one GLB, `tileset.json` and a GLB per part and level: [`crate::tiles`]); returns the fit
/// per part.
fn write_gltf(
    res: &SolveResult,
    result_dir: &Path,
    out: &Path,
) -> Result<Vec<(String, usize, GltfFit)>, ExportError> {
    if crate::tiles::needs_tiles(res) {
        let set = tiles_of(res, result_dir, &mut |i, (albedo, maps), glbs| {
            write_textures(res, i, albedo, maps, out)?;
            glbs.iter()
                .try_for_each(|(name, bytes)| crate::tiles::write_file(&out.join(name), bytes))
        })?;
        set.write(out)?;
        return Ok(set.materials);
    }
    let (glb, textures) = gltf_of(res, result_dir)?;
    for (i, (albedo, maps)) in textures.iter().enumerate() {
        write_textures(res, i, albedo, maps, out)?;
    }
    let glb_path = out.join("scene.glb");
    igi_files::write_atomic(&glb_path, |tmp| {
        std::fs::write(tmp, &glb.bytes)
            .map_err(|e| ExportError::file(&glb_path, format!("cannot write: {e}")))
    })?;
    Ok(glb.materials)
}

/// Part `i`'s albedo atlas and the lobe maps (colour, shape) the result holds, read from
/// `result_dir/parts`.
#[allow(clippy::type_complexity)]
fn part_textures(
    res: &SolveResult,
    result_dir: &Path,
    i: usize,
) -> Result<(HdrImage, Vec<(HdrImage, HdrImage)>), ExportError> {
    let p = &res.parts[i];
    let r = p.resolution();
    let mut tex = HdrImage::new(r, r);
    for (k, px) in tex.pixels.iter_mut().enumerate() {
        *px = p.rho[k].to_array();
    }
    let mut maps = Vec::new();
    // the lobe maps the result wrote (a loaded result does not keep its basis)
    let mut k = 0;
    loop {
        let name = |suffix: &str| format!("{}_lobe{k}_{suffix}.exr", p.name());
        let src = result_dir.join("parts");
        if !src.join(name("rho")).is_file() {
            break;
        }
        let mut pair = Vec::new();
        for suffix in ["rho", "shape"] {
            let im = read_image(&src.join(name(suffix)))?;
            if (im.width, im.height) != (r, r) {
                return Err(ExportError::file(
                    src.join(name(suffix)),
                    format!("is {}x{}, the part's atlas {r}x{r}", im.width, im.height),
                ));
            }
            pair.push(im);
        }
        let [rho, shape] = <[HdrImage; 2]>::try_from(pair)
            .map_err(|_| ExportError::file(src.join(name("rho")), "lobe map pair incomplete"))?;
        maps.push((rho, shape));
        k += 1;
    }
    Ok((tex, maps))
}

/// Writes part `i`'s albedo (EXR and PNG preview), its standard-error picture and its lobe
/// maps into `out`.
fn write_textures(
    res: &SolveResult,
    i: usize,
    albedo: &HdrImage,
    maps: &[(HdrImage, HdrImage)],
    out: &Path,
) -> Result<(), ExportError> {
    let p = &res.parts[i].part;
    write_exr(&out.join(format!("{}_albedo.exr", p.name)), albedo)?;
    igi_imaging::write_png_tonemapped(&out.join(format!("{}_albedo.png", p.name)), albedo, 1.0)?;
    let se_png = out.join(format!("{}_stderr.png", p.name));
    igi_imaging::write_png_tonemapped(
        &se_png,
        &stderr_picture(&res.parts[i].stderr, p.resolution()),
        1.0,
    )?;
    for (k, (rho, shape)) in maps.iter().enumerate() {
        write_exr(&out.join(format!("{}_lobe{k}_rho.exr", p.name)), rho)?;
        write_exr(&out.join(format!("{}_lobe{k}_shape.exr", p.name)), shape)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_mean_lobe_averages_colour_and_weighs_shape_by_luminance() {
        // three texels, two covered: lobe colours grey 0.2 and 0.6; shapes n = 10 and n = 50
        let mut rho = HdrImage::new(3, 1);
        let mut shape = HdrImage::new(3, 1);
        rho.pixels = vec![[0.2; 3], [0.6; 3], [9.0; 3]];
        shape.pixels = vec![[-1.0, 1.0, 10.0], [-0.5, 0.8, 50.0], [5.0, 5.0, 5.0]];
        let m = mean_lobes(&[(rho, shape)], &[0, 1]);
        assert_eq!(m.len(), 1);
        assert!((m[0].rho - Vec3::splat(0.4)).abs().max_element() < 1e-6);
        // luminance weights 0.2 and 0.6: n = (0.2 * 10 + 0.6 * 50) / 0.8 = 40
        assert!((m[0].n - 40.0).abs() < 1e-4, "{:?}", m[0]);
        assert!((m[0].cxy - (-0.625)).abs() < 1e-5, "{:?}", m[0]);
        assert!((m[0].cz - 0.85).abs() < 1e-5, "{:?}", m[0]);
        // a lobe dark everywhere reflects nothing
        let dark = mean_lobes(&[(HdrImage::new(2, 1), HdrImage::new(2, 1))], &[0, 1]);
        assert_eq!(dark[0].rho, Vec3::ZERO);
    }
}
