//! The materials JSON written by `igi brdf fit` and read by eval/infer and the solver:
//! `{ "materials": { name: { "rho_d": [..], "lobes": [ {rho, cxy, cz, n} ...], "rms": .., "stderr": {...} } } }`.

use std::collections::BTreeMap;
use std::path::Path;

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::{BrdfError, FitReport, Lafortune, Lobe, Stderr};

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

impl MaterialEntry {
    pub fn brdf(&self) -> Lafortune {
        Lafortune {
            rho_d: self.rho_d,
            lobes: self.lobes.clone(),
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
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
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

    /// Read and validate (finite, non-negative colours, non-negative exponents, at least one material).
    pub fn read(path: &Path) -> Result<Self, BrdfError> {
        let text = std::fs::read_to_string(path).map_err(|source| BrdfError::Io {
            path: path.into(),
            source,
        })?;
        Self::parse(&text, path)
    }

    /// [`Self::read`] on text in memory (`path` names it in errors).
    pub fn parse(text: &str, path: &Path) -> Result<Self, BrdfError> {
        let err = |msg: String| BrdfError::File {
            path: path.into(),
            msg,
        };
        let m: MaterialsFile =
            serde_json::from_str(text).map_err(|e| err(format!("not a materials JSON: {e}")))?;
        if m.materials.is_empty() {
            return Err(err("no materials".into()));
        }
        for (name, e) in &m.materials {
            if !e.rho_d.is_finite() || e.rho_d.min_element() < 0.0 {
                return Err(err(format!(
                    "material `{name}`: rho_d {:?} must be finite and non-negative",
                    e.rho_d
                )));
            }
            for (i, l) in e.lobes.iter().enumerate() {
                let ok = l.rho.is_finite()
                    && l.rho.min_element() >= 0.0
                    && l.cxy.is_finite()
                    && l.cz.is_finite()
                    && l.n.is_finite()
                    && l.n >= 0.0;
                if !ok {
                    return Err(err(format!(
                        "material `{name}`, lobe {i}: {l:?} needs finite values, rho >= 0, n >= 0"
                    )));
                }
            }
        }
        Ok(m)
    }

    pub fn to_json(&self) -> String {
        serde_json::to_string_pretty(self).expect("materials serialise") + "\n"
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
