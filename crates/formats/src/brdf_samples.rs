//! The BRDF-sample CSV (FORMATS.md, "BRDF samples"):
//! `material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b`, directions in the sample's
//! local frame (z = normal), `r, g, b` = pi times the BRDF value; and the direction-pair table
//! `igi brdf eval` reads (the six direction columns plus any others, passed through).
//!
//! Read through `igi_imaging::csv` (header by name, comments, errors naming file and line);
//! written atomically. The values are checked here because they are what the file means:
//! directions of unit length (within 2 %, then renormalised), above the surface for samples,
//! values finite, non-negative and below [`MAX_BRDF`].

use std::fmt;
use std::path::Path;

use glam::Vec3;
use igi_imaging::csv::{Row, Table};

use crate::{FileKind, FormatsError};

/// One measurement: directions toward the light and the viewer (local frame), and `pi * f`.
#[derive(Clone, Debug, PartialEq)]
pub struct BrdfSample {
    pub material: String,
    pub light: Vec3,
    pub view: Vec3,
    /// pi times the BRDF value, per channel (1 for a perfect white Lambertian).
    pub value: Vec3,
}

/// A direction-pair table: the direction columns of the samples CSV plus any other columns,
/// kept verbatim so that `igi brdf eval` can pass them through.
#[derive(Clone, Debug, PartialEq)]
pub struct PairTable {
    /// Header of the columns kept verbatim (everything except the six direction columns and r, g, b).
    pub extra_header: Vec<String>,
    pub rows: Vec<PairRow>,
}

/// One row of a [`PairTable`].
#[derive(Clone, Debug, PartialEq)]
pub struct PairRow {
    pub extra: Vec<String>,
    pub light: Vec3,
    pub view: Vec3,
}

/// The largest BRDF value a sample may have (sr^-1): a mirror-like lobe of exponent 10^5
/// peaks near 10^4; larger values can only be unit mistakes and would overflow the fit.
pub const MAX_BRDF: f32 = 1e6;

const DIR_COLS: [&str; 6] = [
    "light_x", "light_y", "light_z", "view_x", "view_y", "view_z",
];
const RGB_COLS: [&str; 3] = ["r", "g", "b"];
const SAMPLE_HEADER: &str = "material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n";

/// What a row of a BRDF-sample or pair table means that it cannot.
#[derive(Clone, Debug, PartialEq)]
pub enum SampleProblem {
    /// A direction is not of unit length (within 2 %).
    NotUnit {
        what: &'static str,
        v: Vec3,
        len: f32,
    },
    /// The light or the view is below the surface.
    BelowSurface,
    /// A reflectance value is negative.
    Negative(f32),
    /// A BRDF value beyond [`MAX_BRDF`].
    TooLarge(f32),
    /// The material cell is empty.
    EmptyMaterial,
}

impl fmt::Display for SampleProblem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            SampleProblem::NotUnit { what, v, len } => write!(
                f,
                "{what} direction {v:?} is not a unit vector (length {len:.4})"
            ),
            SampleProblem::BelowSurface => {
                f.write_str("light or view direction below the surface (z <= 0)")
            }
            SampleProblem::Negative(v) => write!(f, "negative reflectance {v}"),
            SampleProblem::TooLarge(v) => write!(
                f,
                "BRDF value {v} is beyond {MAX_BRDF:e} sr^-1 (no measured surface comes near; check the units)"
            ),
            SampleProblem::EmptyMaterial => f.write_str("empty material name"),
        }
    }
}

fn read_text(path: &Path, kind: FileKind) -> Result<String, FormatsError> {
    std::fs::read_to_string(path).map_err(|source| FormatsError::Read {
        path: path.to_path_buf(),
        kind,
        source,
    })
}

fn sample_error(path: &Path, line: usize, problem: SampleProblem) -> FormatsError {
    FormatsError::Sample {
        path: path.to_path_buf(),
        line,
        problem,
    }
}

/// Reads a samples CSV. Errors name the file and line. Directions must be unit length (within
/// 2 %; they are renormalised); values must be finite, non-negative and at most [`MAX_BRDF`];
/// the light and the view must be above the surface (z > 0).
pub fn read_samples(path: &Path) -> Result<Vec<BrdfSample>, FormatsError> {
    parse_samples(&read_text(path, FileKind::BrdfSamples)?, path)
}

/// [`read_samples`] on text already in memory (`path` is used in error messages).
pub fn parse_samples(text: &str, path: &Path) -> Result<Vec<BrdfSample>, FormatsError> {
    let table = Table::parse(text, path)?;
    let material = table.column("material")?;
    let dirs = table.columns(&DIR_COLS)?;
    let rgb = table.columns(&RGB_COLS)?;
    table.require_rows("samples")?;
    let sample = |row: &Row| -> Result<BrdfSample, FormatsError> {
        let material = row.cells[material].to_string();
        if material.is_empty() {
            return Err(sample_error(path, row.line, SampleProblem::EmptyMaterial));
        }
        let (light, view) = directions(&table, row, &dirs)?;
        if light.z <= 0.0 || view.z <= 0.0 {
            return Err(sample_error(path, row.line, SampleProblem::BelowSurface));
        }
        let value = value(&table, row, &rgb)?;
        Ok(BrdfSample {
            material,
            light,
            view,
            value,
        })
    };
    table.rows().iter().map(sample).collect()
}

/// The `r, g, b` cells of `row`: finite, non-negative, at most [`MAX_BRDF`].
fn value(table: &Table, row: &Row, idx: &[usize]) -> Result<Vec3, FormatsError> {
    let mut v = [0.0f32; 3];
    for k in 0..3 {
        v[k] = table.number_f32(row, idx[k], RGB_COLS[k])?;
        let problem = if v[k] < 0.0 {
            SampleProblem::Negative(v[k])
        } else if v[k] > MAX_BRDF {
            SampleProblem::TooLarge(v[k])
        } else {
            continue;
        };
        return Err(sample_error(table.path(), row.line, problem));
    }
    Ok(Vec3::from(v))
}

/// The light and view directions of `row` (columns `idx`, in [`DIR_COLS`] order), renormalised.
fn directions(table: &Table, row: &Row, idx: &[usize]) -> Result<(Vec3, Vec3), FormatsError> {
    let mut d = [0.0f32; 6];
    for k in 0..6 {
        d[k] = table.number_f32(row, idx[k], DIR_COLS[k])?;
    }
    let unit = |v: Vec3, what: &'static str| {
        let len = v.length();
        if (len - 1.0).abs() > 0.02 {
            let problem = SampleProblem::NotUnit { what, v, len };
            return Err(sample_error(table.path(), row.line, problem));
        }
        Ok(v / len)
    };
    let light = unit(Vec3::new(d[0], d[1], d[2]), "light")?;
    let view = unit(Vec3::new(d[3], d[4], d[5]), "view")?;
    Ok((light, view))
}

/// Reads a pairs CSV: needs the six direction columns; other columns (except r, g, b, which the
/// output replaces) are kept. Directions below the surface are allowed (the BRDF is 0 there).
pub fn read_pairs(path: &Path) -> Result<PairTable, FormatsError> {
    let text = read_text(path, FileKind::BrdfPairs)?;
    let table = Table::parse(&text, path)?;
    let dirs = table.columns(&DIR_COLS)?;
    let header = table.header();
    let is_value = |h: &str| RGB_COLS.iter().any(|c| h.eq_ignore_ascii_case(c));
    let keep: Vec<usize> = (0..header.len())
        .filter(|i| !dirs.contains(i) && !is_value(header[*i]))
        .collect();
    let rows = table.rows().iter().map(|row| {
        let (light, view) = directions(&table, row, &dirs)?;
        let extra = keep.iter().map(|&i| row.cells[i].to_string()).collect();
        Ok(PairRow { extra, light, view })
    });
    Ok(PairTable {
        extra_header: keep.iter().map(|&i| header[i].to_string()).collect(),
        rows: rows.collect::<Result<_, FormatsError>>()?,
    })
}

/// The pairs with `r, g, b` values (pi times the BRDF) as CSV text.
pub fn pairs_to_csv(table: &PairTable, values: &[Vec3]) -> String {
    let mut s = String::new();
    for h in &table.extra_header {
        s.push_str(h);
        s.push(',');
    }
    s.push_str(&SAMPLE_HEADER["material,".len()..]);
    for (row, v) in table.rows.iter().zip(values) {
        for e in &row.extra {
            s.push_str(e);
            s.push(',');
        }
        let (l, w) = (row.light, row.view);
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{}\n",
            l.x, l.y, l.z, w.x, w.y, w.z, v.x, v.y, v.z
        ));
    }
    s
}

/// Samples as CSV text (the FORMATS.md layout).
pub fn samples_to_csv(samples: &[BrdfSample]) -> String {
    let mut s = String::from(SAMPLE_HEADER);
    for x in samples {
        let (l, w, v) = (x.light, x.view, x.value);
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{}\n",
            x.material, l.x, l.y, l.z, w.x, w.y, w.z, v.x, v.y, v.z
        ));
    }
    s
}

/// Writes [`samples_to_csv`] to `path` atomically.
pub fn write_samples(path: &Path, samples: &[BrdfSample]) -> Result<(), FormatsError> {
    write_csv(path, &samples_to_csv(samples))
}

/// Writes [`pairs_to_csv`] to `path` atomically.
pub fn write_pairs(path: &Path, table: &PairTable, values: &[Vec3]) -> Result<(), FormatsError> {
    write_csv(path, &pairs_to_csv(table, values))
}

fn write_csv(path: &Path, text: &str) -> Result<(), FormatsError> {
    igi_files::write_text_atomic(path, text).map_err(|e| FormatsError::Write(Box::new(e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn parses_and_round_trips() {
        let text = "material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n\
                    # comment\n\
                    white,0,0,1,0.6,0,0.8,1,1,1\n\
                    dark,0.6,0,0.8,0,0,1,0.01,0.02,0.03\n";
        let s = parse_samples(text, Path::new("x.csv")).unwrap();
        assert_eq!(s.len(), 2);
        assert_eq!(s[1].material, "dark");
        assert_eq!(s[1].light, Vec3::new(0.6, 0.0, 0.8));
        assert_eq!(s[1].value, Vec3::new(0.01, 0.02, 0.03));
        let again = parse_samples(&samples_to_csv(&s), Path::new("y.csv")).unwrap();
        assert_eq!(again, s);
    }

    #[test]
    fn errors_name_file_line_and_problem() {
        let h = "material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n";
        let cases = [
            (
                format!("{h}a,0,0,1,0,0,1,0.5,x,0.5\n"),
                "x.csv:2: `g` = `x` is not a number",
            ),
            (
                format!("{h}a,0,0,1,0,0,1,0.5,0.5\n"),
                "x.csv:2: 9 cells, header has 10",
            ),
            (
                format!("{h}a,0,0,2,0,0,1,0.5,0.5,0.5\n"),
                "x.csv:2: light direction",
            ),
            (
                format!("{h}a,0,0,1,0,0,-1,0.5,0.5,0.5\n"),
                "x.csv:2: light or view direction below",
            ),
            (
                format!("{h}a,0,0,1,0,0,1,-0.5,0.5,0.5\n"),
                "x.csv:2: negative reflectance",
            ),
            (
                format!("{h}\na,0,0,1,0,0,1,NaN,0.5,0.5\n"),
                "x.csv:3: `r` = `NaN` is not finite",
            ),
            (
                "material,light_x,light_y,view_x,view_y,view_z,r,g,b\n".to_string(),
                "x.csv:1: header lacks column `light_z`",
            ),
            (h.to_string(), "x.csv: no samples"),
            (String::new(), "x.csv: empty file"),
        ];
        for (text, want) in cases {
            let e = parse_samples(&text, Path::new("x.csv"))
                .unwrap_err()
                .to_string();
            assert!(e.starts_with(want), "got `{e}`, want `{want}`");
        }
    }
}
