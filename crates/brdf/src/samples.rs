//! BRDF sample CSV (FORMATS.md): `material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b`,
//! directions in the sample's local frame (z = normal), `r, g, b` = pi times the BRDF value.

use std::path::Path;

use glam::Vec3;

use crate::BrdfError;

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

#[derive(Clone, Debug, PartialEq)]
pub struct PairRow {
    pub extra: Vec<String>,
    pub light: Vec3,
    pub view: Vec3,
}

const DIR_COLS: [&str; 6] = [
    "light_x", "light_y", "light_z", "view_x", "view_y", "view_z",
];

fn read_text(path: &Path) -> Result<String, BrdfError> {
    std::fs::read_to_string(path).map_err(|source| BrdfError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn parse_err(path: &Path, line: usize, msg: impl Into<String>) -> BrdfError {
    BrdfError::Parse {
        path: path.to_path_buf(),
        line,
        msg: msg.into(),
    }
}

/// The largest BRDF value a sample may have (sr^-1): a mirror-like lobe of exponent 10^5
/// peaks near 10^4; larger values can only be unit mistakes and would overflow the fit.
pub const MAX_BRDF: f32 = 1e6;

/// Non-empty, non-comment lines with their 1-based line numbers.
fn lines(text: &str) -> impl Iterator<Item = (usize, &str)> {
    // a UTF-8 byte-order mark (spreadsheet exports) is not part of the first column's name
    text.strip_prefix('\u{feff}')
        .unwrap_or(text)
        .lines()
        .enumerate()
        .map(|(i, l)| (i + 1, l.trim()))
        .filter(|(_, l)| !l.is_empty() && !l.starts_with('#'))
}

fn split(l: &str) -> Vec<&str> {
    l.split(',').map(|c| c.trim()).collect()
}

fn column(path: &Path, line: usize, header: &[&str], name: &str) -> Result<usize, BrdfError> {
    header
        .iter()
        .position(|h| h.eq_ignore_ascii_case(name))
        .ok_or_else(|| {
            parse_err(
                path,
                line,
                format!("header lacks column `{name}` (have: {})", header.join(",")),
            )
        })
}

fn number(
    path: &Path,
    line: usize,
    cells: &[&str],
    idx: usize,
    name: &str,
) -> Result<f32, BrdfError> {
    let cell = cells.get(idx).ok_or_else(|| {
        parse_err(
            path,
            line,
            format!("missing value for `{name}` ({} cells)", cells.len()),
        )
    })?;
    let v: f32 = cell
        .parse()
        .map_err(|_| parse_err(path, line, format!("`{name}` = `{cell}` is not a number")))?;
    if !v.is_finite() {
        return Err(parse_err(
            path,
            line,
            format!("`{name}` = `{cell}` is not finite"),
        ));
    }
    Ok(v)
}

fn direction(path: &Path, line: usize, v: Vec3, what: &str) -> Result<Vec3, BrdfError> {
    let len = v.length();
    if (len - 1.0).abs() > 0.02 {
        return Err(parse_err(
            path,
            line,
            format!("{what} direction {v:?} is not a unit vector (length {len:.4})"),
        ));
    }
    Ok(v / len)
}

fn read_dirs(
    path: &Path,
    line: usize,
    cells: &[&str],
    idx: &[usize],
) -> Result<(Vec3, Vec3), BrdfError> {
    let mut d = [0.0f32; 6];
    for k in 0..6 {
        d[k] = number(path, line, cells, idx[k], DIR_COLS[k])?;
    }
    let light = direction(path, line, Vec3::new(d[0], d[1], d[2]), "light")?;
    let view = direction(path, line, Vec3::new(d[3], d[4], d[5]), "view")?;
    Ok((light, view))
}

/// Parse a samples CSV. Errors name the file and line. Directions must be unit length (within 2%;
/// they are renormalised); values must be finite and non-negative; the light and the view must be
/// above the surface (z > 0).
pub fn read_samples(path: &Path) -> Result<Vec<BrdfSample>, BrdfError> {
    parse_samples(&read_text(path)?, path)
}

/// [`read_samples`] on text already in memory (`path` is used in error messages).
pub fn parse_samples(text: &str, path: &Path) -> Result<Vec<BrdfSample>, BrdfError> {
    let mut it = lines(text);
    let (hl, header) = it.next().ok_or_else(|| BrdfError::File {
        path: path.into(),
        msg: "empty file (no header)".into(),
    })?;
    let header = split(header);
    let im = column(path, hl, &header, "material")?;
    let idx: Vec<usize> = DIR_COLS
        .iter()
        .map(|c| column(path, hl, &header, c))
        .collect::<Result<_, _>>()?;
    let ic: Vec<usize> = ["r", "g", "b"]
        .iter()
        .map(|c| column(path, hl, &header, c))
        .collect::<Result<_, _>>()?;
    let mut out = Vec::new();
    for (line, l) in it {
        let cells = split(l);
        if cells.len() != header.len() {
            return Err(parse_err(
                path,
                line,
                format!("{} cells, header has {}", cells.len(), header.len()),
            ));
        }
        let material = cells[im].to_string();
        if material.is_empty() {
            return Err(parse_err(path, line, "empty material name"));
        }
        let (light, view) = read_dirs(path, line, &cells, &idx)?;
        if light.z <= 0.0 || view.z <= 0.0 {
            return Err(parse_err(
                path,
                line,
                "light or view direction below the surface (z <= 0)",
            ));
        }
        let mut v = [0.0f32; 3];
        for k in 0..3 {
            v[k] = number(path, line, &cells, ic[k], ["r", "g", "b"][k])?;
            if v[k] < 0.0 {
                return Err(parse_err(
                    path,
                    line,
                    format!("negative reflectance {}", v[k]),
                ));
            }
            if v[k] > MAX_BRDF {
                return Err(parse_err(
                    path,
                    line,
                    format!("BRDF value {} is beyond {MAX_BRDF:e} sr^-1 (no measured surface comes near; check the units)", v[k]),
                ));
            }
        }
        out.push(BrdfSample {
            material,
            light,
            view,
            value: Vec3::from(v),
        });
    }
    if out.is_empty() {
        return Err(BrdfError::File {
            path: path.into(),
            msg: "no samples after the header".into(),
        });
    }
    Ok(out)
}

/// Group samples by material, in order of first appearance.
pub fn group_by_material(samples: &[BrdfSample]) -> Vec<(String, Vec<BrdfSample>)> {
    let mut groups: Vec<(String, Vec<BrdfSample>)> = Vec::new();
    for s in samples {
        match groups.iter_mut().find(|(m, _)| *m == s.material) {
            Some((_, g)) => g.push(s.clone()),
            None => groups.push((s.material.clone(), vec![s.clone()])),
        }
    }
    groups
}

/// Parse a pairs CSV: needs the six direction columns; other columns (except r, g, b, which the
/// output replaces) are kept. Directions below the surface are allowed (the BRDF is 0 there).
pub fn read_pairs(path: &Path) -> Result<PairTable, BrdfError> {
    let text = read_text(path)?;
    let mut it = lines(&text);
    let (hl, header) = it.next().ok_or_else(|| BrdfError::File {
        path: path.into(),
        msg: "empty file (no header)".into(),
    })?;
    let header = split(header);
    let idx: Vec<usize> = DIR_COLS
        .iter()
        .map(|c| column(path, hl, &header, c))
        .collect::<Result<_, _>>()?;
    let is_value = |h: &str| ["r", "g", "b"].iter().any(|c| h.eq_ignore_ascii_case(c));
    let keep: Vec<usize> = (0..header.len())
        .filter(|i| !idx.contains(i) && !is_value(header[*i]))
        .collect();
    let mut rows = Vec::new();
    for (line, l) in it {
        let cells = split(l);
        if cells.len() != header.len() {
            return Err(parse_err(
                path,
                line,
                format!("{} cells, header has {}", cells.len(), header.len()),
            ));
        }
        let (light, view) = read_dirs(path, line, &cells, &idx)?;
        rows.push(PairRow {
            extra: keep.iter().map(|&i| cells[i].to_string()).collect(),
            light,
            view,
        });
    }
    Ok(PairTable {
        extra_header: keep.iter().map(|&i| header[i].to_string()).collect(),
        rows,
    })
}

/// Write the pairs with `r, g, b` values (pi times the BRDF) as CSV text.
pub fn pairs_to_csv(table: &PairTable, values: &[Vec3]) -> String {
    let mut s = String::new();
    for h in &table.extra_header {
        s.push_str(h);
        s.push(',');
    }
    s.push_str("light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n");
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
    let mut s = String::from("material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n");
    for x in samples {
        let (l, w, v) = (x.light, x.view, x.value);
        s.push_str(&format!(
            "{},{},{},{},{},{},{},{},{},{}\n",
            x.material, l.x, l.y, l.z, w.x, w.y, w.z, v.x, v.y, v.z
        ));
    }
    s
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
        let g = group_by_material(&s);
        assert_eq!(g.len(), 2);
        assert_eq!(g[0].0, "white");
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
