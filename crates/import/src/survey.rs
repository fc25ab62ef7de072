//! `igi import colmap`: a photogrammetry model (COLMAP, Metashape's camera XML, nerfstudio's
//! `transforms.json`: [`ModelFormat`]) as a survey folder. Everything is read and checked first
//! (the output folder, the model, each camera, each image file, the mesh, the lighting file, the
//! control points and the alignment); only then is anything written, each file atomically:
//! `cameras/NAME.json` per image, `alignment.json`, and `survey.toml` last. With
//! [`ColmapImport::icp`] the control-point alignment is refined by trimmed ICP of the model's
//! sparse points against the mesh ([`crate::icp`]) before the cameras are moved.

use std::collections::HashMap;
use std::path::{Path, PathBuf};

use igi_camera::Camera;
use igi_formats::lighting::LightingFile;
use igi_formats::survey::{PhotoEntry, SiteSection, SurveyFile};
use igi_formats::TomlFile;
use serde::Serialize;
use serde_json::json;

use crate::align::{align, AlignOptions, Alignment, Similarity};
use crate::colmap::read_model;
use crate::error::ImportError;
use crate::icp::{compose, icp, Icp, IcpOptions, IcpReport, Surface};
use crate::source::{colmap_cameras, CameraSet, ModelFormat};

/// What `igi import colmap` is asked to do.
#[derive(Clone, Debug)]
pub struct ColmapImport {
    /// What `sparse` is.
    pub format: ModelFormat,
    /// The sparse model folder (`cameras`, `images`, `points3D` as `.bin` or `.txt`); with
    /// [`ModelFormat::Metashape`] the cameras XML file, with [`ModelFormat::Nerfstudio`]
    /// `transforms.json` or its folder.
    pub sparse: PathBuf,
    /// The folder of the photographs the model names.
    pub images: PathBuf,
    /// Ground control points (CSV) aligning the model to the scan.
    pub control: Option<PathBuf>,
    /// A lighting file given to every photo.
    pub lighting: Option<PathBuf>,
    /// The site's meshes (the scan; one or more, as a survey's `meshes`).
    pub meshes: Vec<PathBuf>,
    /// The survey folder to write (absent or empty).
    pub output: PathBuf,
    pub align: AlignOptions,
    /// Refine the control-point alignment by ICP of the sparse points against `meshes`
    /// (COLMAP models with `--control` only).
    pub icp: Option<IcpOptions>,
}

/// What was read and written.
#[derive(Clone, Debug, Serialize)]
pub struct ImportReport {
    /// `colmap`, `metashape` or `nerfstudio`.
    pub format: &'static str,
    /// The model files read (`.bin` preferred over `.txt`).
    pub read: Vec<PathBuf>,
    pub cameras: usize,
    pub images: usize,
    pub points3d: usize,
    /// Images the model lists without a pose (left out).
    pub unposed: Vec<String>,
    /// `scan` (aligned by control points) or `model` (COLMAP's own frame).
    pub frame: &'static str,
    pub scale: f64,
    /// Metres, when aligned.
    pub rms_m: Option<f64>,
    pub max_residual_m: Option<f64>,
    /// Control points left out of the fit (residual above the bound).
    pub outliers: Vec<String>,
    /// The ICP refinement, when asked for.
    pub icp: Option<IcpReport>,
    /// Whether every photo has a lighting file.
    pub lighting: bool,
    /// Photos given a `time` from their EXIF.
    pub times: usize,
    /// Photos given an `exposure` from their EXIF.
    pub exposures: usize,
    /// Per photo (by id), why its time or exposure was left out, or what was assumed.
    pub exif_notes: Vec<(String, String)>,
    pub survey: PathBuf,
}

/// One photo to write: its id (the image's file stem), image file and camera, and what its
/// EXIF says of when it was taken and how it was exposed.
struct Photo {
    id: String,
    image: PathBuf,
    camera: Camera,
    exif: PhotoExifInfo,
}

/// What a photo's EXIF gives the survey: its `time` (RFC 3339 with the UTC offset) and its
/// `exposure` (t x ISO/100 / N^2), each `None` with the reason in `notes`.
#[derive(Clone, Debug, Default)]
struct PhotoExifInfo {
    time: Option<String>,
    exposure: Option<f64>,
    /// The camera body (EXIF make, model, serial).
    body: Option<String>,
    notes: Vec<String>,
}

/// A photo's time and exposure from its EXIF. A file without EXIF (or one that is not an image
/// format EXIF can live in) gives neither; a `DateTimeOriginal` without `OffsetTimeOriginal`
/// and without a GPS time gives no time (its instant is unknown: nothing is guessed); a missing
/// f-number or ISO is noted (`PhotoExif::exposure` counts it as f/1, ISO 100). A malformed EXIF
/// field or date is refused, naming the file.
fn photo_exif(image: &Path) -> Result<PhotoExifInfo, ImportError> {
    use igi_formats::TimeProblem;
    let mut out = PhotoExifInfo::default();
    let exif = match igi_imaging::exif::read_exif(image) {
        Ok(e) => e,
        Err(igi_imaging::ImagingError::NoExif { .. }) => {
            out.notes.push("no EXIF data: no time, no exposure".into());
            return Ok(out);
        }
        Err(e) => return Err(input_error(image, format!("its EXIF cannot be read: {e}"))),
    };
    if let Some(note) = igi_formats::PhotoTime::exif_clock_gps_note(&exif) {
        out.notes.push(note);
    }
    match igi_formats::PhotoTime::from_photo_exif(&exif) {
        Ok(t) => out.time = Some(t.to_rfc3339()),
        Err(p @ (TimeProblem::UnknownOffset | TimeProblem::NoExifTime | TimeProblem::Blank)) => {
            out.notes.push(format!("time left out: {p}"))
        }
        Err(p) => {
            return Err(input_error(
                image,
                format!("its EXIF time cannot be read: {p}"),
            ))
        }
    }
    out.exposure = exif.exposure();
    out.body = exif.body.clone();
    match out.exposure {
        None => out.notes.push("no EXIF ExposureTime: no exposure".into()),
        Some(_) => {
            for (missing, what) in [
                (exif.f_number.is_none(), "FNumber (taken as f/1)"),
                (exif.iso.is_none(), "ISO (taken as 100)"),
            ] {
                if missing {
                    out.notes.push(format!("exposure without EXIF {what}"));
                }
            }
        }
    }
    Ok(out)
}

fn input_error(path: &Path, problem: impl Into<String>) -> ImportError {
    ImportError::Input {
        path: path.to_path_buf(),
        problem: problem.into(),
    }
}

/// Refuses an output folder that holds anything (or that cannot become a folder).
fn check_output(out: &Path) -> Result<(), ImportError> {
    igi_files::check_output_folder(out)?;
    if out.is_dir() {
        let mut entries = std::fs::read_dir(out).map_err(|source| ImportError::Read {
            path: out.to_path_buf(),
            what: "the output folder",
            source,
        })?;
        if entries.next().is_some() {
            return Err(ImportError::Output {
                path: out.to_path_buf(),
                problem: "output folder is not empty (choose a new or empty folder)".into(),
            });
        }
    }
    Ok(())
}

/// The image file of a model's image name: `DIR/NAME`, else `DIR/FILE_NAME` (a nerfstudio
/// `file_path` relative to its own folder), else, for a name without an extension (a Metashape
/// label), the one file of `DIR` whose stem it is.
fn find_image(dir: &Path, name: &str) -> Option<PathBuf> {
    let direct = dir.join(name);
    if direct.is_file() {
        return Some(direct);
    }
    let file = Path::new(name).file_name()?;
    let flat = dir.join(file);
    if flat.is_file() {
        return Some(flat);
    }
    if Path::new(name).extension().is_some() {
        return None;
    }
    let mut hits = std::fs::read_dir(dir)
        .ok()?
        .filter_map(Result::ok)
        .map(|e| e.path())
        .filter(|p| p.is_file() && p.file_stem() == Some(file));
    let one = hits.next()?;
    hits.next().is_none().then_some(one)
}

/// Each image's contract camera (model frame), its file checked to exist and its stem unique.
fn photos(set: &CameraSet, images_dir: &Path) -> Result<Vec<Photo>, ImportError> {
    let images_file = set.images_file.as_path();
    let mut out: Vec<Photo> = Vec::with_capacity(set.images.len());
    for img in &set.images {
        let stem = Path::new(&img.name)
            .file_stem()
            .map(|s| s.to_string_lossy().into_owned());
        let id = stem.filter(|s| !s.is_empty()).ok_or_else(|| {
            input_error(
                images_file,
                format!("image `{}` has no file name", img.name),
            )
        })?;
        if let Some(other) = out.iter().find(|p| p.id == id) {
            let problem = format!("images `{}` and `{}` share the name `{id}`: camera files are named by the image's stem", other.image.display(), img.name);
            return Err(input_error(images_file, problem));
        }
        let image = find_image(images_dir, &img.name).ok_or_else(|| {
            input_error(
                &images_dir.join(&img.name),
                format!(
                    "image `{}` of the model ({}) is not in --images",
                    img.name,
                    images_file.display()
                ),
            )
        })?;
        let exif = photo_exif(&image)?;
        out.push(Photo {
            id,
            image,
            camera: img.camera.clone(),
            exif,
        });
    }
    // exposures put photos on one scale only when every photo has one
    if out.iter().any(|p| p.exif.exposure.is_none())
        && out.iter().any(|p| p.exif.exposure.is_some())
    {
        for p in &mut out {
            if p.exif.exposure.take().is_some() {
                p.exif.notes.push(
                    "exposure left out: not every photo has one, and a photo without one would \
                     count as exposure 1"
                        .into(),
                );
            }
        }
    }
    Ok(out)
}

/// The alignment of the control file, if given (cameras in the model frame by image name, and
/// by file name where that is unambiguous).
fn alignment(
    job: &ColmapImport,
    photos: &[Photo],
    set: &CameraSet,
) -> Result<Option<Alignment>, ImportError> {
    let Some(path) = &job.control else {
        return Ok(None);
    };
    let obs = igi_formats::control::read_control_points(path)?;
    let mut cams: HashMap<String, Camera> = HashMap::new();
    for (i, p) in set.images.iter().zip(photos) {
        if let Some(f) = Path::new(&i.name).file_name() {
            cams.insert(f.to_string_lossy().into_owned(), p.camera.clone());
        }
    }
    for (i, p) in set.images.iter().zip(photos) {
        cams.insert(i.name.clone(), p.camera.clone());
    }
    align(path, &obs, &cams, job.align).map(Some)
}

/// The model's cameras, read as `job.format` says.
pub fn read_cameras(format: ModelFormat, path: &Path) -> Result<CameraSet, ImportError> {
    match format {
        ModelFormat::Colmap => {
            let (model, read) = read_model(path)?;
            colmap_cameras(&model, read)
        }
        ModelFormat::Metashape => crate::metashape::read_metashape(path),
        ModelFormat::Nerfstudio => crate::nerfstudio::read_nerfstudio(path),
    }
}

/// Checks everything, then writes the survey folder.
pub fn import_colmap(job: &ColmapImport) -> Result<ImportReport, ImportError> {
    check_output(&job.output)?;
    let set = read_cameras(job.format, &job.sparse)?;
    let mut photos = photos(&set, &job.images)?;
    if photos.is_empty() {
        return Err(input_error(
            &set.images_file,
            "the model has no registered (posed) image",
        ));
    }
    if job.meshes.is_empty() {
        return Err(input_error(&job.output, "no site mesh given (--mesh)"));
    }
    if let Some(m) = job.meshes.iter().find(|m| !m.is_file()) {
        return Err(input_error(m, "site mesh not found (--mesh)"));
    }
    if let Some(l) = &job.lighting {
        LightingFile::read(l)?;
    }
    let aligned = alignment(job, &photos, &set)?;
    let mut sim = aligned
        .as_ref()
        .map_or(Similarity::identity(), |a| a.similarity);
    let refined = refine(job, &set, aligned.is_some(), &sim)?;
    if let Some(r) = &refined {
        sim = compose(&r.correction, &sim);
    }
    photos
        .iter_mut()
        .for_each(|p| p.camera = sim.camera(&p.camera));
    write_folder(job, &photos, aligned.as_ref(), refined.as_ref(), &sim)?;
    let mut r = report(job, set, aligned.as_ref(), sim);
    r.icp = refined.as_ref().map(IcpReport::from);
    r.times = photos.iter().filter(|p| p.exif.time.is_some()).count();
    r.exposures = photos.iter().filter(|p| p.exif.exposure.is_some()).count();
    r.exif_notes = photos
        .iter()
        .flat_map(|p| p.exif.notes.iter().map(|n| (p.id.clone(), n.clone())))
        .collect();
    Ok(r)
}

/// The ICP refinement of `sim` (the control points' similarity) when asked for.
fn refine(
    job: &ColmapImport,
    set: &CameraSet,
    aligned: bool,
    sim: &Similarity,
) -> Result<Option<Icp>, ImportError> {
    let Some(opts) = &job.icp else {
        return Ok(None);
    };
    if !aligned {
        return Err(input_error(
            &job.sparse,
            "--icp refines the alignment by control points: give --control as well",
        ));
    }
    if set.points.is_empty() {
        return Err(input_error(
            &set.images_file,
            "the model has no sparse 3D points for --icp (COLMAP's points3D)",
        ));
    }
    let mut mesh = igi_geometry::TriMesh::default();
    for m in &job.meshes {
        mesh.append(&igi_geometry::read_mesh(m)?);
    }
    let err = |source| ImportError::Icp {
        meshes: job.meshes.clone(),
        source,
    };
    let surface = Surface::new(&mesh.positions, &mesh.indices, opts.spacing).map_err(err)?;
    let points: Vec<glam::DVec3> = set.points.iter().map(|p| sim.apply(*p)).collect();
    icp(&points, &surface, opts).map(Some).map_err(err)
}

fn report(
    job: &ColmapImport,
    set: CameraSet,
    a: Option<&Alignment>,
    sim: Similarity,
) -> ImportReport {
    ImportReport {
        format: job.format.name(),
        read: set.read,
        cameras: set.cameras,
        images: set.images.len(),
        points3d: set.points3d,
        unposed: set.unposed,
        frame: if a.is_some() { "scan" } else { "model" },
        scale: sim.scale,
        rms_m: a.map(|a| a.rms_m),
        max_residual_m: a.map(|a| a.max_residual_m),
        icp: None,
        outliers: a.map_or(Vec::new(), |a| {
            a.points
                .iter()
                .filter(|p| !p.inlier)
                .map(|p| p.name.clone())
                .collect()
        }),
        lighting: job.lighting.is_some(),
        times: 0,
        exposures: 0,
        exif_notes: Vec::new(),
        survey: job.output.join("survey.toml"),
    }
}

/// Writes cameras, alignment.json and survey.toml; on failure removes what it wrote.
fn write_folder(
    job: &ColmapImport,
    photos: &[Photo],
    a: Option<&Alignment>,
    refined: Option<&Icp>,
    sim: &Similarity,
) -> Result<(), ImportError> {
    let out = &job.output;
    let existed = out.exists();
    let result = write_files(job, photos, a, refined, sim);
    if result.is_err() {
        if existed {
            let _ = std::fs::remove_dir_all(out.join("cameras"));
            let _ = std::fs::remove_file(out.join("alignment.json"));
        } else {
            let _ = std::fs::remove_dir_all(out);
        }
    }
    result
}

fn write_files(
    job: &ColmapImport,
    photos: &[Photo],
    a: Option<&Alignment>,
    refined: Option<&Icp>,
    sim: &Similarity,
) -> Result<(), ImportError> {
    let out = &job.output;
    let cams = out.join("cameras");
    std::fs::create_dir_all(&cams).map_err(|source| ImportError::Write {
        path: cams.clone(),
        source,
    })?;
    for p in photos {
        p.camera.save(&cams.join(format!("{}.json", p.id)))?;
    }
    let text =
        serde_json::to_string_pretty(&alignment_json(job, a, refined, sim)).unwrap_or_default();
    igi_files::write_text_atomic(&out.join("alignment.json"), &(text + "\n"))?;
    let survey = survey_file(job, photos)?;
    let written = format!(
        "written by `igi import colmap --format {}`",
        job.format.name()
    );
    let header = [
        written.as_str(),
        "cameras: one contract camera per image of the model",
    ];
    survey.write(&out.join("survey.toml"), &header)?;
    Ok(())
}

/// The survey naming the mesh, each photo, its camera and (when given) the lighting file.
fn survey_file(job: &ColmapImport, photos: &[Photo]) -> Result<SurveyFile, ImportError> {
    let base = std::fs::canonicalize(&job.output).map_err(|source| ImportError::Read {
        path: job.output.clone(),
        what: "the output folder",
        source,
    })?;
    // the folder made absolute, the file's own name kept: a photo that is a symlink stays
    // the name under --images, not its target
    let rel = |p: &Path| -> Result<PathBuf, ImportError> {
        let abs = igi_files::resolve_folder_of(p).map_err(|source| ImportError::Read {
            path: p.to_path_buf(),
            what: "an input",
            source,
        })?;
        Ok(igi_files::relative_to(&abs, &base).unwrap_or(abs))
    };
    let lighting = job.lighting.as_deref().map(rel).transpose()?;
    let photo = photos
        .iter()
        .map(|p| {
            Ok(PhotoEntry {
                id: p.id.clone(),
                image: rel(&p.image)?,
                camera: PathBuf::from(format!("cameras/{}.json", p.id)),
                lighting: lighting.clone(),
                time: p.exif.time.clone(),
                exposure: p.exif.exposure,
                body: p.exif.body.clone(),
                ..PhotoEntry::default()
            })
        })
        .collect::<Result<Vec<_>, ImportError>>()?;
    let meshes = job
        .meshes
        .iter()
        .map(|m| rel(m))
        .collect::<Result<Vec<_>, _>>()?;
    let site = match meshes.as_slice() {
        [one] => SiteSection {
            mesh: Some(one.clone()),
            ..SiteSection::default()
        },
        _ => SiteSection {
            meshes,
            ..SiteSection::default()
        },
    };
    Ok(SurveyFile {
        site,
        photo,
        ..SurveyFile::default()
    })
}

fn alignment_json(
    job: &ColmapImport,
    a: Option<&Alignment>,
    refined: Option<&Icp>,
    sim: &Similarity,
) -> serde_json::Value {
    let Some(a) = a else {
        return json!({
            "frame": "model",
            "format": job.format,
            "note": "no --control: the cameras are in the model's own frame (arbitrary scale, orientation and origin), not the scan's",
        });
    };
    let rows_of = |s: &Similarity| s.rotation.transpose().to_cols_array_2d();
    let rows = rows_of(sim);
    let s = sim;
    let icp = refined.map(|r| {
        let c = &a.similarity;
        json!({
            "refinement": IcpReport::from(r),
            "control_points_only": {
                "scale": c.scale,
                "rotation": rows_of(c),
                "translation": c.translation.to_array(),
            },
        })
    });
    json!({
        "frame": "scan",
        "format": job.format,
        "control": job.control,
        "transform": "x_scan = scale * rotation * x_model + translation",
        "scale": s.scale,
        "rotation": rows,
        "translation": s.translation.to_array(),
        "spread_m": a.spread_m,
        "max_residual_m": a.max_residual_m,
        "rms_m": a.rms_m,
        "points": a.points,
        "points_note": "residuals of the control points' own fit (icp.control_points_only when --icp refined it)",
        "icp": icp,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The Canon CR3 of datasets/fixtures/raw: time, exposure and body from its EXIF, and a
    /// note that its clock runs 65 min 30 s ahead of its GPS stamp.
    #[test]
    fn a_cr3_whose_clock_is_an_hour_off_its_gps_time_is_noted() {
        let info = photo_exif(&igi_testkit::fixture("raw/canon_r6_header.cr3")).unwrap();
        assert_eq!(info.time.as_deref(), Some("2025-09-06T20:24:47-08:00"));
        let want = 0.01 * 256.0 / (2.8 * 2.8);
        assert!((info.exposure.unwrap() - want).abs() < 1e-12, "{info:?}");
        assert_eq!(info.body.as_deref(), Some("Canon EOS R6 #072021007989"));
        assert_eq!(info.notes.len(), 1, "{info:?}");
        assert!(
            info.notes[0].contains("65 min 30 s ahead of its GPS time"),
            "{info:?}"
        );
    }
}
