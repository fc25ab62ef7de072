//! `materials.json`, written by `igi brdf fit` and read by `igi brdf eval`/`infer` and the
//! solver: `{ "materials": { name: { "rho_d": [..], "lobes": [ {rho, cxy, cz, n} ...], "rms": ..,
//! "stderr": {...} } } }`. Parsed and checked here (values `f32` as the BRDF holds them, written
//! in their shortest decimals); `igi_brdf::MaterialsFile` builds its BRDFs from it.

use crate::FormatsError;
use glam::Vec3;
use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;
use std::path::Path;

/// One Lafortune lobe as written: colour `rho`, coefficients `cxy`, `cz` and exponent `n`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Lobe {
    pub rho: Vec3,
    pub cxy: f32,
    pub cz: f32,
    pub n: f32,
}

impl Lobe {
    /// Whether the parameters can be a lobe: finite, non-negative colour, finite coefficients
    /// and a finite, non-negative exponent (the one rule: `igi_brdf::Lobe::is_valid` asks it).
    pub fn is_valid(&self) -> bool {
        self.rho.is_finite()
            && self.rho.min_element() >= 0.0
            && self.cxy.is_finite()
            && self.cz.is_finite()
            && self.n.is_finite()
            && self.n >= 0.0
    }
}

/// Standard errors of one lobe, in the units of the fitted parameters (`cz` is fixed, so it
/// has none).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct LobeStderr {
    pub rho: [f64; 3],
    pub cxy: f64,
    pub n: f64,
}

/// Standard errors of a fit, laid out like the material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stderr {
    pub rho_d: [f64; 3],
    pub lobes: Vec<LobeStderr>,
}

/// One material: the BRDF and, when it came from a fit, its quality figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct MaterialEntry {
    pub rho_d: Vec3,
    pub lobes: Vec<Lobe>,
    /// RMS of the relative residuals of the fit.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms: Option<f64>,
    /// RMS of the absolute residuals (pi times the BRDF).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub rms_abs: Option<f64>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub samples: Option<usize>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stderr: Option<Stderr>,
}

/// A materials file: named materials, sorted by name.
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct MaterialsFile {
    pub materials: BTreeMap<String, MaterialEntry>,
}

/// Why a materials file cannot be used; [`FormatsError::Materials`] names the file.
#[derive(Debug, thiserror::Error)]
pub enum MaterialsProblem {
    /// The text is not the JSON of a materials file.
    #[error("not a materials JSON: {0}")]
    Json(serde_json::Error),
    #[error("no materials")]
    Empty,
    #[error("material `{name}`: rho_d {rho_d:?} must be finite and non-negative")]
    RhoD { name: String, rho_d: Vec3 },
    #[error("material `{name}`, lobe {index}: {lobe:?} needs finite values, rho >= 0, n >= 0")]
    Lobe {
        name: String,
        index: usize,
        lobe: Lobe,
    },
}

impl MaterialsFile {
    /// The materials file in JSON `text`, checked ([`check`](Self::check)).
    pub fn parse(text: &str) -> Result<MaterialsFile, MaterialsProblem> {
        let m: MaterialsFile = serde_json::from_str(text).map_err(MaterialsProblem::Json)?;
        m.check()?;
        Ok(m)
    }

    /// At least one material; finite, non-negative colours; finite coefficients and
    /// non-negative exponents.
    pub fn check(&self) -> Result<(), MaterialsProblem> {
        if self.materials.is_empty() {
            return Err(MaterialsProblem::Empty);
        }
        for (name, e) in &self.materials {
            if !e.rho_d.is_finite() || e.rho_d.min_element() < 0.0 {
                return Err(MaterialsProblem::RhoD {
                    name: name.clone(),
                    rho_d: e.rho_d,
                });
            }
            for (index, l) in e.lobes.iter().enumerate() {
                if !l.is_valid() {
                    return Err(MaterialsProblem::Lobe {
                        name: name.clone(),
                        index,
                        lobe: *l,
                    });
                }
            }
        }
        Ok(())
    }

    /// The file's text: pretty JSON, each `f32` in its shortest decimal, a final newline.
    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("materials serialise") + "\n"
    }

    /// Reads and checks the file at `path` (every error names it).
    pub fn read(path: &Path) -> Result<MaterialsFile, FormatsError> {
        let text = std::fs::read_to_string(path).map_err(|source| FormatsError::Open {
            path: path.to_path_buf(),
            source,
        })?;
        Self::parse_at(&text, path)
    }

    /// [`parse`](Self::parse) of text read from `path` (which errors name).
    pub fn parse_at(text: &str, path: &Path) -> Result<MaterialsFile, FormatsError> {
        Self::parse(text).map_err(|problem| FormatsError::Materials {
            path: path.to_path_buf(),
            problem: Box::new(problem),
        })
    }

    /// Writes the file atomically (as it is: a fit's materials are written even when one of
    /// them would not pass [`check`](Self::check), so that the fit is not lost).
    pub fn write(&self, path: &Path) -> Result<(), FormatsError> {
        igi_files::write_text_atomic(path, &self.to_json())
            .map_err(|e| FormatsError::Write(Box::new(e)))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn f32_values_written_short_and_read_back() {
        let text = r#"{"materials":{"a":{"rho_d":[0.1,0.4,0.3],"lobes":[{"rho":[1,1,1],"cxy":-1,"cz":1,"n":30.5}],"rms":0.01}}}"#;
        let m = MaterialsFile::parse(text).unwrap();
        let out = m.to_json();
        assert!(
            out.contains("0.1,\n") && out.contains("\"n\": 30.5"),
            "{out}"
        );
        assert!(out.ends_with("}\n"));
        assert_eq!(MaterialsFile::parse(&out).unwrap(), m);
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("m.json");
        let e = MaterialsFile::read(&p).unwrap_err().to_string();
        assert!(e.starts_with(&format!("{}: ", p.display())), "{e}");
        m.write(&p).unwrap();
        assert_eq!(MaterialsFile::read(&p).unwrap(), m);
        std::fs::write(&p, r#"{"materials":{}}"#).unwrap();
        let e = MaterialsFile::read(&p).unwrap_err().to_string();
        assert_eq!(e, format!("{}: no materials", p.display()));
    }
}
