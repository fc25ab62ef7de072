//! `igi-formats`: the files igi reads and writes that other tools script against
//! (`docs/FORMATS.md`), as typed serde models with one reader and one writer each.
//!
//! Parse first, build after (as Mitsuba does): these types hold what a file says, paths as
//! written (relative to the file's folder) and numbers as parsed; the crates that use them
//! (`igi-render` for lighting and scene files, `igi-reflect` for surveys) resolve the paths,
//! validate the values and build their own objects.
//!
//! - [`lighting`]: the lighting file ([`LightingFile`]: `[environment]` lat-long map, `[sun]`
//!   disk).
//! - [`scene`]: the scene file ([`SceneFile`]: `lighting`, `[[object]]` meshes with albedo and
//!   lobes).
//! - [`survey`]: `survey.toml` ([`SurveyFile`]: `[site]` with the site's location and true
//!   north, `[[photo]]` with its time, `[[reference]]` targets of known albedo, `[brdf]`,
//!   `[radiometry]`); [`SurveyFile::check_site_and_references`] checks those values.
//! - [`time`]: when a photo was taken ([`PhotoTime`]): RFC 3339 with its UTC offset
//!   ([`PhotoTime::parse_rfc3339`]) or EXIF's date and offset ([`PhotoTime::from_exif`]), as a
//!   UTC instant and its UTC calendar fields ([`PhotoTime::utc`]) for a solar-position
//!   algorithm.
//! - [`board`]: the lighting-capture board (JSON, [`BoardFile`]: spheres and fiducials), read
//!   with [`BoardFile::read`] and written with [`BoardFile::write`].
//!
//! Each reads with [`TomlFile::read`] and writes with [`TomlFile::write`] (atomically, after an
//! optional comment header); the trait is the one reader and one writer of every TOML kind.
//! - [`camera`]: the camera file (JSON, [`CameraFile`]: values kept as JSON so that
//!   `igi-camera`, which checks and builds the camera, gives each problem its own message),
//!   parsed with [`CameraFile::parse`] and written with [`CameraFile::write`].
//!
//! Numbers are `f64` as TOML holds them; a reader that wants `f32` casts, which is what serde
//! does when it reads a TOML float into an `f32`. Writers of `f32` data pass it through
//! [`f32_decimal`], so a file shows `0.1` rather than `0.10000000149011612`.
//!
//! - [`radiometry`]: the camera radiometry file (JSON, [`RadiometryFile`]: image size, lens
//!   falloff, colour matrix, the fit's diagnostics), read and checked with
//!   [`RadiometryFile::read`], written with [`RadiometryFile::write`].
//! - [`rig`]: the multi-view capture file `rig.toml` ([`RigFile`]: the object's box, the
//!   views with their camera, photo, mask, matting pairs and light images; paths as written),
//!   read and checked with [`RigFile::read`], written with [`RigFile::write`].
//! - [`materials`]: `materials.json`, the fitted BRDFs ([`MaterialsFile`]: named materials
//!   with `rho_d`, lobes and the fit's figures, `f32` values written in their shortest
//!   decimals), read and checked with [`MaterialsFile::read`], written with
//!   [`MaterialsFile::write`].
//! - [`brdf_samples`]: the BRDF-sample CSV and the direction-pair table ([`BrdfSample`],
//!   [`PairTable`]; [`brdf_samples::read_samples`], [`brdf_samples::write_samples`]), read
//!   through `igi_imaging::csv`.
//! - [`control`]: the ground-control-point CSV `name,x,y,z,image,u,v`
//!   ([`ControlObservation`]; [`control::read_control_points`],
//!   [`control::write_control_points`]), read through `igi_imaging::csv`: one row per
//!   observation of a surveyed point in a photo.

pub mod board;
pub mod brdf_samples;
pub mod camera;
pub mod control;
pub mod lighting;
pub mod materials;
pub mod points;
pub mod radiometry;
pub mod rig;
pub mod scene;
pub mod survey;
pub mod time;

pub use board::BoardFile;
pub use brdf_samples::{BrdfSample, PairRow, PairTable};
pub use camera::CameraFile;
pub use control::ControlObservation;
pub use lighting::LightingFile;
pub use materials::MaterialsFile;
pub use radiometry::RadiometryFile;
pub use rig::RigFile;
pub use scene::SceneFile;
pub use survey::{ReferenceTarget, SurveyFile};
pub use time::{PhotoTime, TimeProblem};

use serde::de::DeserializeOwned;
use serde::Serialize;
use std::fmt;
use std::path::{Path, PathBuf};

/// Which kind of file an error is about (it names the file's role in messages).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum FileKind {
    Lighting,
    Scene,
    Survey,
    Board,
    BrdfSamples,
    BrdfPairs,
    ControlPoints,
    Points,
    Rig,
}

impl fmt::Display for FileKind {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            FileKind::Lighting => "lighting file",
            FileKind::Scene => "scene file",
            FileKind::Survey => "survey file",
            FileKind::Board => "board file",
            FileKind::BrdfSamples => "BRDF-sample file",
            FileKind::BrdfPairs => "direction-pair file",
            FileKind::ControlPoints => "control-point file",
            FileKind::Points => "point table",
            FileKind::Rig => "rig file",
        })
    }
}

impl FileKind {
    /// The noun after "cannot read" (the survey's message has always said "survey").
    fn read_noun(self) -> &'static str {
        match self {
            FileKind::Lighting => "lighting file",
            FileKind::Scene => "scene file",
            FileKind::Survey => "survey",
            FileKind::Board => "board file",
            FileKind::BrdfSamples => "BRDF samples",
            FileKind::BrdfPairs => "direction pairs",
            FileKind::ControlPoints => "control points",
            FileKind::Points => "points",
            FileKind::Rig => "rig file",
        }
    }
}

/// Errors of reading and writing the interchange files. Every message names the file. The
/// sources are boxed so that the error stays small (it travels inside other crates' errors).
#[derive(Debug, thiserror::Error)]
pub enum FormatsError {
    /// The file cannot be read (missing, a folder, not UTF-8).
    #[error("{path}: cannot read {}: {source}", kind.read_noun())]
    Read {
        path: PathBuf,
        kind: FileKind,
        #[source]
        source: std::io::Error,
    },
    /// The file is not valid TOML of its kind (a missing key, a wrong type, an unknown key).
    #[error("{path}: not a valid {kind}: {source}")]
    Parse {
        path: PathBuf,
        kind: FileKind,
        #[source]
        source: Box<toml::de::Error>,
    },
    /// The file is not valid JSON of its kind (a missing key, a wrong type, an unknown key).
    #[error("{path}: not a valid {kind}: {source}")]
    ParseJson {
        path: PathBuf,
        kind: FileKind,
        #[source]
        source: Box<serde_json::Error>,
    },
    /// A value cannot be written as TOML (a path that is not UTF-8).
    #[error("{path}: cannot write {kind}: {source}")]
    Serialize {
        path: PathBuf,
        kind: FileKind,
        #[source]
        source: Box<toml::ser::Error>,
    },
    /// A CSV table's structure: no header, a missing column, a cell that is not a number.
    #[error(transparent)]
    Csv(Box<igi_imaging::csv::CsvError>),
    /// A row of a BRDF-sample or pair table that cannot mean a measurement.
    #[error("{path}:{line}: {problem}")]
    Sample {
        path: PathBuf,
        line: usize,
        problem: brdf_samples::SampleProblem,
    },
    /// A value of a survey file that cannot mean what its key says (the site location, a
    /// photo's time, a reference target): from [`SurveyFile::check_site_and_references`].
    #[error("{path}: {problem}")]
    SurveyValue {
        path: PathBuf,
        #[source]
        problem: Box<survey::SurveyProblem>,
    },
    /// A row of a ground-control-point table that cannot mean an observation, or a value that
    /// cannot be written as one.
    #[error("{path}:{line}: {problem}")]
    Control {
        path: PathBuf,
        line: usize,
        problem: Box<control::ControlProblem>,
    },
    /// A row of a point table whose values mean nothing (`point`: its number, from 1).
    #[error("{}: point {point} {problem}", path.display())]
    PointValue {
        path: PathBuf,
        point: usize,
        problem: String,
    },
    /// A table that holds no rows (`what`: of what).
    #[error("{path}: no {what}")]
    NoRows { path: PathBuf, what: &'static str },
    /// A file that cannot be read (missing, a folder, not UTF-8), for the files whose message
    /// has always been the path and the system's reason alone (radiometry, rig, materials).
    #[error("{path}: {source}")]
    Open {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A camera radiometry file that cannot be used (not its JSON, or values no calibration
    /// can hold): from [`RadiometryFile::read`] and [`RadiometryFile::write`].
    #[error("{path}: invalid camera radiometry file: {problem}")]
    Radiometry {
        path: PathBuf,
        problem: Box<radiometry::RadiometryProblem>,
    },
    /// A rig file that cannot be used (not its TOML, or values no capture can hold): from
    /// [`RigFile::read`]; the problem names the view it concerns.
    #[error("{path}: {problem}")]
    Rig {
        path: PathBuf,
        problem: Box<rig::RigProblem>,
    },
    /// A materials file that cannot be used (not its JSON, no material, a colour or lobe no
    /// BRDF can hold): from [`MaterialsFile::read`].
    #[error("{path}: {problem}")]
    Materials {
        path: PathBuf,
        problem: Box<materials::MaterialsProblem>,
    },
    /// Writing the file failed (the atomic writer names the file).
    #[error(transparent)]
    Write(Box<igi_files::FilesError>),
}

impl From<igi_imaging::csv::CsvError> for FormatsError {
    fn from(e: igi_imaging::csv::CsvError) -> Self {
        FormatsError::Csv(Box::new(e))
    }
}

/// A file with one reader and one writer: the TOML text of a serde model.
pub trait TomlFile: Serialize + DeserializeOwned {
    /// Which file this is (errors name it).
    const KIND: FileKind;

    /// Reads and parses the file at `path`; no path in it is resolved or opened.
    fn read(path: &Path) -> Result<Self, FormatsError> {
        let text = std::fs::read_to_string(path).map_err(|source| FormatsError::Read {
            path: path.to_path_buf(),
            kind: Self::KIND,
            source,
        })?;
        toml::from_str(&text).map_err(|source| FormatsError::Parse {
            path: path.to_path_buf(),
            kind: Self::KIND,
            source: Box::new(source),
        })
    }

    /// The text [`write`](Self::write) writes: each `header` line as a `# ` comment, a blank
    /// line after them, then the TOML (tables in field order).
    fn to_toml(&self, header: &[&str]) -> Result<String, toml::ser::Error> {
        let body = toml::to_string(self)?;
        let mut text = String::new();
        for line in header {
            text.push_str("# ");
            text.push_str(line);
            text.push('\n');
        }
        if !header.is_empty() {
            text.push('\n');
        }
        text.push_str(&body);
        Ok(text)
    }

    /// Writes the file atomically (a temporary file renamed into place), after `header`.
    fn write(&self, path: &Path, header: &[&str]) -> Result<(), FormatsError> {
        let text = self
            .to_toml(header)
            .map_err(|source| FormatsError::Serialize {
                path: path.to_path_buf(),
                kind: Self::KIND,
                source: Box::new(source),
            })?;
        igi_files::write_text_atomic(path, &text).map_err(|e| FormatsError::Write(Box::new(e)))
    }
}

/// The `f64` nearest the shortest decimal that reads back as `x`: written to a file it shows
/// `0.1`, not `0.10000000149011612`, and a reader casting to `f32` gets `x` back (TOML floats
/// are read as `f64` and cast, whichever type the reader asks for).
pub fn f32_decimal(x: f32) -> f64 {
    if x.is_finite() {
        x.to_string().parse().unwrap_or(x as f64)
    } else {
        x as f64
    }
}

/// [`f32_decimal`] of each component.
pub fn f32_decimals(v: [f32; 3]) -> [f64; 3] {
    v.map(f32_decimal)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_decimals_read_back_exactly_and_print_short() {
        for x in [
            0.1f32, 0.53, 1.0, -0.0, 1e-30, 3.4e38, 0.70710677, 123456.79,
        ] {
            let d = f32_decimal(x);
            assert_eq!((d as f32).to_bits(), x.to_bits(), "{x}");
            assert_eq!(d.to_string(), x.to_string(), "{x}");
        }
        assert!(f32_decimal(f32::NAN).is_nan());
        assert_eq!(f32_decimal(f32::INFINITY), f64::INFINITY);
    }
}
