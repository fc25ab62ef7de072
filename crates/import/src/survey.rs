//! `igi import colmap`: a COLMAP model as a survey folder. Everything is read and checked first
//! (the output folder, the model, each camera, each image file, the mesh, the lighting file, the
//! control points and the alignment); only then is anything written, each file atomically:
//! `cameras/NAME.json` per image, `alignment.json`, and `survey.toml` last.

use std::collections::HashMap;
use std::path::{Component, Path, PathBuf};

use igi_camera::Camera;
use igi_formats::lighting::LightingFile;
use igi_formats::survey::{PhotoEntry, SiteSection, SurveyFile};
use igi_formats::TomlFile;
use serde::Serialize;
use serde_json::json;

use crate::align::{align, AlignOptions, Alignment, Similarity};
use crate::colmap::read_model;
use crate::error::ImportError;
use crate::model::{contract_camera, ColmapModel};

/// What `igi import colmap` is asked to do.
#[derive(Clone, Debug)]
pub struct ColmapImport {
    /// The sparse model folder (`cameras`, `images`, `points3D` as `.bin` or `.txt`).
    pub sparse: PathBuf,
    /// The folder of the photographs the model names.
    pub images: PathBuf,
    /// Ground control points (CSV) aligning the model to the scan.
    pub control: Option<PathBuf>,
    /// A lighting file given to every photo.
    pub lighting: Option<PathBuf>,
    /// The site's mesh (the scan).
    pub mesh: PathBuf,
    /// The survey folder to write (absent or empty).
    pub output: PathBuf,
    pub align: AlignOptions,
}

/// What was read and written.
#[derive(Clone, Debug, Serialize)]
pub struct ImportReport {
    /// The model files read (`.bin` preferred over `.txt`).
    pub read: Vec<PathBuf>,
    pub cameras: usize,
    pub images: usize,
    pub points3d: usize,
    /// `scan` (aligned by control points) or `model` (COLMAP's own frame).
    pub frame: &'static str,
    pub scale: f64,
    /// Metres, when aligned.
    pub rms_m: Option<f64>,
    pub max_residual_m: Option<f64>,
    /// Control points left out of the fit (residual above the bound).
    pub outliers: Vec<String>,
    /// Whether every photo has a lighting file.
    pub lighting: bool,
    pub survey: PathBuf,
}

/// One photo to write: its id (the image's file stem), image file and camera.
struct Photo {
    id: String,
    image: PathBuf,
    camera: Camera,
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

/// Each image's contract camera (model frame) by image name, its file checked to exist and its
/// stem unique.
fn photos(
    model: &ColmapModel,
    images_file: &Path,
    images_dir: &Path,
) -> Result<Vec<Photo>, ImportError> {
    let mut out: Vec<Photo> = Vec::with_capacity(model.images.len());
    for img in &model.images {
        let camera = contract_camera(model, img).map_err(|problem| ImportError::Model {
            path: images_file.to_path_buf(),
            problem,
        })?;
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
        let image = images_dir.join(&img.name);
        if !image.is_file() {
            return Err(input_error(
                &image,
                format!("image `{}` of the model is not in --images", img.name),
            ));
        }
        out.push(Photo { id, image, camera });
    }
    Ok(out)
}

/// The alignment of the control file, if given (cameras in the model frame by image name).
fn alignment(
    job: &ColmapImport,
    photos: &[Photo],
    model: &ColmapModel,
) -> Result<Option<Alignment>, ImportError> {
    let Some(path) = &job.control else {
        return Ok(None);
    };
    let obs = igi_formats::control::read_control_points(path)?;
    let cams: HashMap<String, Camera> = model
        .images
        .iter()
        .zip(photos)
        .map(|(i, p)| (i.name.clone(), p.camera.clone()))
        .collect();
    align(path, &obs, &cams, job.align).map(Some)
}

/// Checks everything, then writes the survey folder.
pub fn import_colmap(job: &ColmapImport) -> Result<ImportReport, ImportError> {
    check_output(&job.output)?;
    let (model, read) = read_model(&job.sparse)?;
    let mut photos = photos(&model, &read[1], &job.images)?;
    if photos.is_empty() {
        return Err(input_error(&read[1], "the model has no registered image"));
    }
    if !job.mesh.is_file() {
        return Err(input_error(&job.mesh, "site mesh not found (--mesh)"));
    }
    if let Some(l) = &job.lighting {
        LightingFile::read(l)?;
    }
    let aligned = alignment(job, &photos, &model)?;
    let sim = aligned
        .as_ref()
        .map_or(Similarity::identity(), |a| a.similarity);
    photos
        .iter_mut()
        .for_each(|p| p.camera = sim.camera(&p.camera));
    write_folder(job, &photos, aligned.as_ref())?;
    Ok(report(job, &model, read, aligned.as_ref(), sim))
}

fn report(
    job: &ColmapImport,
    model: &ColmapModel,
    read: Vec<PathBuf>,
    a: Option<&Alignment>,
    sim: Similarity,
) -> ImportReport {
    ImportReport {
        read,
        cameras: model.cameras.len(),
        images: model.images.len(),
        points3d: model.points.len(),
        frame: if a.is_some() { "scan" } else { "model" },
        scale: sim.scale,
        rms_m: a.map(|a| a.rms_m),
        max_residual_m: a.map(|a| a.max_residual_m),
        outliers: a.map_or(Vec::new(), |a| {
            a.points
                .iter()
                .filter(|p| !p.inlier)
                .map(|p| p.name.clone())
                .collect()
        }),
        lighting: job.lighting.is_some(),
        survey: job.output.join("survey.toml"),
    }
}

/// Writes cameras, alignment.json and survey.toml; on failure removes what it wrote.
fn write_folder(
    job: &ColmapImport,
    photos: &[Photo],
    a: Option<&Alignment>,
) -> Result<(), ImportError> {
    let out = &job.output;
    let existed = out.exists();
    let result = write_files(job, photos, a);
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
    let text = serde_json::to_string_pretty(&alignment_json(job, a)).unwrap_or_default();
    igi_files::write_text_atomic(&out.join("alignment.json"), &(text + "\n"))?;
    let survey = survey_file(job, photos)?;
    let header = [
        "written by `igi import colmap`",
        "cameras: one contract camera per COLMAP image",
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
    let rel = |p: &Path| -> Result<PathBuf, ImportError> {
        let abs = std::fs::canonicalize(p).map_err(|source| ImportError::Read {
            path: p.to_path_buf(),
            what: "an input",
            source,
        })?;
        Ok(relative_to(&abs, &base).unwrap_or(abs))
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
                ..PhotoEntry::default()
            })
        })
        .collect::<Result<Vec<_>, ImportError>>()?;
    let site = SiteSection {
        mesh: Some(rel(&job.mesh)?),
        ..SiteSection::default()
    };
    Ok(SurveyFile {
        site,
        photo,
        ..SurveyFile::default()
    })
}

/// `target` relative to `base` (both absolute), when they share more than the root.
pub fn relative_to(target: &Path, base: &Path) -> Option<PathBuf> {
    let (t, b): (Vec<Component>, Vec<Component>) =
        (target.components().collect(), base.components().collect());
    let common = t.iter().zip(&b).take_while(|(x, y)| x == y).count();
    let shares = t[..common]
        .iter()
        .any(|c| matches!(c, Component::Normal(_)));
    if !shares {
        return None;
    }
    let mut out = PathBuf::new();
    b[common..].iter().for_each(|_| out.push(".."));
    t[common..].iter().for_each(|c| out.push(c));
    Some(out)
}

fn alignment_json(job: &ColmapImport, a: Option<&Alignment>) -> serde_json::Value {
    let Some(a) = a else {
        return json!({
            "frame": "model",
            "note": "no --control: the cameras are in the COLMAP model's own frame (arbitrary scale, orientation and origin), not the scan's",
        });
    };
    let s = &a.similarity;
    let rows = s.rotation.transpose().to_cols_array_2d();
    json!({
        "frame": "scan",
        "control": job.control,
        "transform": "x_scan = scale * rotation * x_model + translation",
        "scale": s.scale,
        "rotation": rows,
        "translation": s.translation.to_array(),
        "spread_m": a.spread_m,
        "max_residual_m": a.max_residual_m,
        "rms_m": a.rms_m,
        "points": a.points,
    })
}
