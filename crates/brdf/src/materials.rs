//! The materials JSON written by `igi brdf fit` and read by eval/infer and the solver:
//! `{ "materials": { name: { "rho_d": [..], "lobes": [ {rho, cxy, cz, n} ...], "rms": .., "stderr": {...} } } }`.
//! Read, checked and written by `igi_formats::materials`; the BRDFs are built from it here.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;
use igi_formats::materials as file;

use crate::{BrdfError, FitReport, Lafortune, Lobe, Stderr};

/// One material: the BRDF and, when it came from a fit, its quality figures.
#[derive(Clone, Debug, PartialEq)]
pub struct MaterialEntry {
    pub rho_d: Vec3,
    pub lobes: Vec<Lobe>,
    /// RMS of the relative residuals of the fit.
    pub rms: Option<f64>,
    /// RMS of the absolute residuals (pi times the BRDF).
    pub rms_abs: Option<f64>,
    pub samples: Option<usize>,
    pub stderr: Option<Stderr>,
}

impl MaterialEntry {
    pub fn brdf(&self) -> Lafortune {
        Lafortune {
            rho_d: self.rho_d,
            lobes: self.lobes.clone(),
        }
    }

    /// The material a (checked) file entry holds.
    pub fn from_file(e: file::MaterialEntry) -> MaterialEntry {
        MaterialEntry {
            rho_d: e.rho_d,
            lobes: e
                .lobes
                .iter()
                .map(|l| Lobe {
                    rho: l.rho,
                    cxy: l.cxy,
                    cz: l.cz,
                    n: l.n,
                })
                .collect(),
            rms: e.rms,
            rms_abs: e.rms_abs,
            samples: e.samples,
            stderr: e.stderr,
        }
    }

    /// The file entry of this material.
    pub fn to_file(&self) -> file::MaterialEntry {
        file::MaterialEntry {
            rho_d: self.rho_d,
            lobes: self
                .lobes
                .iter()
                .map(|l| file::Lobe {
                    rho: l.rho,
                    cxy: l.cxy,
                    cz: l.cz,
                    n: l.n,
                })
                .collect(),
            rms: self.rms,
            rms_abs: self.rms_abs,
            samples: self.samples,
            stderr: self.stderr.clone(),
        }
    }
}

impl From<&FitReport> for MaterialEntry {
    fn from(r: &FitReport) -> Self {
        MaterialEntry {
            rho_d: r.brdf.rho_d,
            lobes: r.brdf.lobes.clone(),
            rms: Some(r.rms),
            rms_abs: Some(r.rms_abs),
            samples: Some(r.samples),
            stderr: Some(r.stderr.clone()),
        }
    }
}

/// A set of named materials (sorted by name).
#[derive(Clone, Debug, Default, PartialEq)]
pub struct MaterialsFile {
    pub materials: BTreeMap<String, MaterialEntry>,
}

impl MaterialsFile {
    pub fn from_reports(reports: &[FitReport]) -> Self {
        MaterialsFile {
            materials: reports
                .iter()
                .map(|r| (r.material.clone(), MaterialEntry::from(r)))
                .collect(),
        }
    }

    /// Read and validate (finite, non-negative colours, non-negative exponents, at least one
    /// material) through `igi_formats::materials`.
    pub fn read(path: &Path) -> Result<Self, BrdfError> {
        Ok(Self::from_file(file::MaterialsFile::read(path)?))
    }

    /// [`Self::read`] on text in memory (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, BrdfError> {
        Ok(Self::from_file(file::MaterialsFile::parse_at(text, path)?))
    }

    /// The materials a (checked) materials file holds.
    pub fn from_file(f: file::MaterialsFile) -> Self {
        MaterialsFile {
            materials: f
                .materials
                .into_iter()
                .map(|(k, e)| (k, MaterialEntry::from_file(e)))
                .collect(),
        }
    }

    /// The materials file of these materials.
    pub fn to_file(&self) -> file::MaterialsFile {
        file::MaterialsFile {
            materials: self
                .materials
                .iter()
                .map(|(k, e)| (k.clone(), e.to_file()))
                .collect(),
        }
    }

    /// The file's text (pretty JSON, a final newline).
    pub fn to_json(&self) -> String {
        self.to_file().to_json()
    }

    /// Writes the file atomically (a failure to write says "cannot write", as it always has).
    pub fn write(&self, path: &Path) -> Result<(), BrdfError> {
        self.to_file().write(path).map_err(|e| match e {
            igi_formats::FormatsError::Write(e) => BrdfError::File {
                path: path.into(),
                msg: format!("cannot write: {e}"),
            },
            e => e.into(),
        })
    }

    /// The named material, or an error listing the available names.
    pub fn get(&self, name: &str) -> Result<Lafortune, BrdfError> {
        self.materials
            .get(name)
            .map(|e| e.brdf())
            .ok_or_else(|| BrdfError::NoMaterial {
                name: name.to_string(),
                have: self
                    .materials
                    .keys()
                    .cloned()
                    .collect::<Vec<_>>()
                    .join(", "),
            })
    }

    /// All materials as (name, BRDF), sorted by name.
    pub fn brdfs(&self) -> Vec<(String, Lafortune)> {
        self.materials
            .iter()
            .map(|(k, e)| (k.clone(), e.brdf()))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn json_round_trip_and_layout() {
        let mut f = MaterialsFile::default();
        f.materials.insert(
            "marble".into(),
            MaterialEntry {
                rho_d: Vec3::new(0.5, 0.4, 0.3),
                lobes: vec![Lobe {
                    rho: Vec3::splat(2.0),
                    cxy: -1.0,
                    cz: 1.0,
                    n: 30.0,
                }],
                rms: Some(0.01),
                rms_abs: None,
                samples: Some(80),
                stderr: None,
            },
        );
        let text = f.to_json();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        assert_eq!(
            v["materials"]["marble"]["rho_d"][1].as_f64().unwrap() as f32,
            0.4
        );
        assert_eq!(
            v["materials"]["marble"]["lobes"][0]["n"].as_f64().unwrap(),
            30.0
        );
        assert_eq!(
            v["materials"]["marble"]["lobes"][0]["cxy"]
                .as_f64()
                .unwrap(),
            -1.0
        );
        assert_eq!(MaterialsFile::parse(&text, Path::new("m.json")).unwrap(), f);
        assert_eq!(f.get("marble").unwrap().lobes.len(), 1);
        assert!(f.get("x").unwrap_err().to_string().contains("have: marble"));
    }

    #[test]
    fn rejects_bad_files() {
        let p = Path::new("m.json");
        let e = MaterialsFile::parse("{", p).unwrap_err().to_string();
        assert!(e.starts_with("m.json: not a materials JSON"), "{e}");
        let e = MaterialsFile::parse(r#"{"materials":{}}"#, p)
            .unwrap_err()
            .to_string();
        assert!(e.contains("no materials"), "{e}");
        let e = MaterialsFile::parse(
            r#"{"materials":{"a":{"rho_d":[0.1,-0.2,0.3],"lobes":[]}}}"#,
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("material `a`: rho_d"), "{e}");
        let e = MaterialsFile::parse(
            r#"{"materials":{"a":{"rho_d":[0.1,0.2,0.3],"lobes":[{"rho":[1,1,1],"cxy":-1,"cz":1,"n":-3}]}}}"#,
            p,
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("lobe 0"), "{e}");
    }
}
