//! The camera radiometry file (JSON) that `igi camera radiometry` writes and surveys apply to
//! every photograph on load: the image size of the fit, the lens falloff, the colour matrix and
//! the fit's diagnostics. Parsed and checked here; `igi_camera::radiometry::CameraRadiometry`
//! is built from it and applies it.

use crate::FormatsError;
use std::path::Path;

/// A camera radiometry file as written: the lens falloff divided out first, then the colour
/// matrix applied (`corrected = M * (raw / f(r))`).
#[derive(Clone, Debug, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadiometryFile {
    /// Image size the calibration was fitted at.
    pub width: usize,
    pub height: usize,
    pub falloff: Option<FalloffTerms>,
    pub color_matrix: Option<[[f64; 3]; 3]>,
    /// How the fit went (informative; ignored when applying).
    #[serde(default)]
    pub fit: RadiometryFit,
}

/// The falloff's coefficients: `f(r) = 1 + a2 r^2 + a4 r^4 + a6 r^6`, `r` the distance from
/// the image centre divided by the half-diagonal.
#[derive(Clone, Copy, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FalloffTerms {
    pub a2: f64,
    pub a4: f64,
    pub a6: f64,
}

impl FalloffTerms {
    /// `f(r)`.
    pub fn eval(&self, r: f64) -> f64 {
        let r2 = r * r;
        1.0 + r2 * (self.a2 + r2 * (self.a4 + r2 * self.a6))
    }
}

/// Diagnostics of a radiometry fit, stored in the file.
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize, serde::Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RadiometryFit {
    pub flat_fields: usize,
    /// RMS relative residual of the flat fields after the falloff fit.
    pub falloff_rms: Option<f64>,
    /// RMS relative error of the 24 corrected checker patches.
    pub color_rms: Option<f64>,
    /// The chart's white radiance when given (absolute calibration), else null.
    pub white: Option<f64>,
}

/// Why a camera radiometry file cannot be used; [`FormatsError::Radiometry`] names the file.
#[derive(Debug, thiserror::Error)]
pub enum RadiometryProblem {
    /// The text is not the JSON of a radiometry file.
    #[error("not a camera radiometry file: {0}")]
    Json(serde_json::Error),
    #[error("image size {width}x{height} is empty")]
    EmptySize { width: usize, height: usize },
    #[error("holds neither a falloff nor a colour matrix")]
    Nothing,
    #[error("falloff coefficients are not finite")]
    FalloffNotFinite,
    #[error("falloff f(r) is not positive at r = {r} (f = {f})")]
    FalloffNotPositive { r: f64, f: f64 },
    #[error("colour matrix holds a non-finite value")]
    MatrixNotFinite,
    #[error("colour matrix is singular")]
    Singular,
}

impl RadiometryFile {
    /// The radiometry file in JSON `text`, checked ([`check`](Self::check)).
    pub fn parse(text: &str) -> Result<RadiometryFile, RadiometryProblem> {
        let r: RadiometryFile = serde_json::from_str(text).map_err(RadiometryProblem::Json)?;
        r.check()?;
        Ok(r)
    }

    /// The checks of a usable calibration: a non-empty size, a falloff or a colour matrix, a
    /// falloff with finite coefficients that stays positive up to the corners (r <= 1), a
    /// finite, invertible colour matrix.
    pub fn check(&self) -> Result<(), RadiometryProblem> {
        if self.width == 0 || self.height == 0 {
            return Err(RadiometryProblem::EmptySize {
                width: self.width,
                height: self.height,
            });
        }
        if self.falloff.is_none() && self.color_matrix.is_none() {
            return Err(RadiometryProblem::Nothing);
        }
        if let Some(f) = &self.falloff {
            if ![f.a2, f.a4, f.a6].iter().all(|v| v.is_finite()) {
                return Err(RadiometryProblem::FalloffNotFinite);
            }
            if let Some(r) = (0..=100)
                .map(|i| i as f64 / 100.0)
                .find(|r| !(f.eval(*r) > 1e-3))
            {
                return Err(RadiometryProblem::FalloffNotPositive { r, f: f.eval(r) });
            }
        }
        if let Some(m) = &self.color_matrix {
            if !m.iter().flatten().all(|v| v.is_finite()) {
                return Err(RadiometryProblem::MatrixNotFinite);
            }
            if glam::DMat3::from_cols_array_2d(m).determinant().abs() < 1e-9 {
                return Err(RadiometryProblem::Singular);
            }
        }
        Ok(())
    }

    /// The file's text: pretty JSON and a final newline.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("radiometry serialises") + "\n"
    }

    /// Reads and checks the file at `path` (naming it in every error).
    pub fn read(path: &Path) -> Result<RadiometryFile, FormatsError> {
        let text = std::fs::read_to_string(path).map_err(|source| FormatsError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse(&text).map_err(|problem| radiometry_error(path, problem))
    }

    /// Checks the calibration, then writes the file atomically.
    pub fn write(&self, path: &Path) -> Result<(), FormatsError> {
        self.check()
            .map_err(|problem| radiometry_error(path, problem))?;
        igi_files::write_text_atomic(path, &self.to_json())
            .map_err(|e| FormatsError::Write(Box::new(e)))
    }
}

fn radiometry_error(path: &Path, problem: RadiometryProblem) -> FormatsError {
    FormatsError::Radiometry {
        path: path.to_path_buf(),
        problem: Box::new(problem),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn checks_name_the_problem_and_the_file() {
        let ok = r#"{"width": 4, "height": 3, "falloff": null, "color_matrix": [[1,0,0],[0,1,0],[0,0,1]]}"#;
        let f = RadiometryFile::parse(ok).unwrap();
        assert_eq!(f.fit, RadiometryFit::default());
        assert_eq!(RadiometryFile::parse(&f.to_json()).unwrap(), f);
        for (bad, says) in [
            ("{", "not a camera radiometry file"),
            (
                r#"{"width": 0, "height": 3, "falloff": null, "color_matrix": [[1,0,0],[0,1,0],[0,0,1]]}"#,
                "image size 0x3 is empty",
            ),
            (
                r#"{"width": 4, "height": 3, "falloff": null, "color_matrix": null}"#,
                "neither",
            ),
            (
                r#"{"width": 4, "height": 3, "falloff": {"a2": -2.0, "a4": 0.0, "a6": 0.0}, "color_matrix": null}"#,
                "falloff f(r) is not positive at r = 0.71",
            ),
            (
                r#"{"width": 4, "height": 3, "falloff": null, "color_matrix": [[1,0,0],[0,1,0],[0,0,0]]}"#,
                "singular",
            ),
            (&ok.replace('}', r#", "extra": 1}"#), "unknown field"),
        ] {
            let e = RadiometryFile::parse(bad).unwrap_err().to_string();
            assert!(e.contains(says), "{e}");
        }
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("r.json");
        let e = RadiometryFile::read(&p).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", p.display())), "{e}");
        std::fs::write(&p, "{").unwrap();
        let e = RadiometryFile::read(&p).unwrap_err().to_string();
        assert!(
            e.starts_with(&format!(
                "{}: invalid camera radiometry file: not a camera radiometry file",
                p.display()
            )),
            "{e}"
        );
        let mut singular = f.clone();
        singular.color_matrix = Some([[0.0; 3]; 3]);
        assert!(singular.write(&p).is_err());
        f.write(&p).unwrap();
        assert_eq!(std::fs::read_to_string(&p).unwrap(), f.to_json());
        assert_eq!(RadiometryFile::read(&p).unwrap(), f);
    }
}
