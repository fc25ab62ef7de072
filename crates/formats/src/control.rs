//! Ground control points (`docs/FORMATS.md`, "Ground control points (CSV)"): one row per
//! observation of a surveyed point in a photo, for aligning a photogrammetry model to the scan.
//!
//! ```text
//! name,x,y,z,image,u,v
//! gcp-1,12.5,3.25,0.02,IMG_0412.JPG,1834.5,902.25
//! gcp-1,12.5,3.25,0.02,IMG_0413.JPG,411,1210.75
//! ```
//! `x, y, z` are world coordinates (the scan's frame, metres), `image` the photo's file name as
//! the photogrammetry model names it, `u, v` pixel coordinates in the contract convention (the
//! centre of the top-left pixel at 0, 0). A point seen in several photos repeats its
//! coordinates.
//!
//! Read through `igi_imaging::csv` (header required, columns by name in any order and any case,
//! other columns ignored, `#` comments, blank lines, a byte-order mark); written atomically.
//! Refused: a missing column, a number that is not finite, an empty name or image, the same
//! point twice in one image, a point whose coordinates differ between rows (by more than
//! [`SAME_POINT_TOLERANCE`] of their length), a file with no observation.

use std::collections::HashMap;
use std::fmt;
use std::path::Path;

use igi_imaging::csv::Table;

use crate::{FileKind, FormatsError};

/// One observation: a surveyed point's world position and where it appears in one image.
#[derive(Clone, Debug, PartialEq)]
pub struct ControlObservation {
    pub name: String,
    /// World coordinates (metres).
    pub world: [f64; 3],
    /// The photo's file name as the photogrammetry model names it.
    pub image: String,
    /// Pixel (u, v), the centre of the top-left pixel at (0, 0).
    pub pixel: [f64; 2],
}

/// How far the rows of one point may disagree on its position: this fraction of the larger
/// position's length (the same point must repeat the same coordinates).
pub const SAME_POINT_TOLERANCE: f64 = 1e-9;

const COLUMNS: [&str; 7] = ["name", "x", "y", "z", "image", "u", "v"];
const HEADER: &str = "name,x,y,z,image,u,v\n";

/// What a row of a control-point table means that it cannot.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum ControlProblem {
    /// The `name` cell is empty.
    #[error("empty point name")]
    EmptyName,
    /// The `image` cell is empty.
    #[error("point `{name}`: empty image name")]
    EmptyImage { name: String },
    /// The same point observed twice in one image.
    #[error("point `{name}` in image `{image}` again (first on line {first_line})")]
    Duplicate {
        name: String,
        image: String,
        first_line: usize,
    },
    /// A point whose coordinates differ from an earlier row's.
    #[error(
        "point `{name}` at x,y,z = {here:?}, but line {first_line} puts it at {first:?} \
         (a point seen in several photos repeats its coordinates)"
    )]
    Moved {
        name: String,
        here: [f64; 3],
        first: [f64; 3],
        first_line: usize,
    },
    /// A name or image that a CSV cell cannot hold (writing).
    #[error("{what} {value:?} cannot be written as a CSV cell ({why})")]
    Unwritable {
        what: &'static str,
        value: String,
        why: &'static str,
    },
}

fn control_error(path: &Path, line: usize, problem: ControlProblem) -> FormatsError {
    FormatsError::Control {
        path: path.to_path_buf(),
        line,
        problem: Box::new(problem),
    }
}

/// Reads a control-point CSV; errors name the file and the line.
pub fn read_control_points(path: &Path) -> Result<Vec<ControlObservation>, FormatsError> {
    let text = std::fs::read_to_string(path).map_err(|source| FormatsError::Read {
        path: path.to_path_buf(),
        kind: FileKind::ControlPoints,
        source,
    })?;
    parse_control_points(&text, path)
}

/// [`read_control_points`] on text already in memory (`path` names it in errors).
pub fn parse_control_points(
    text: &str,
    path: &Path,
) -> Result<Vec<ControlObservation>, FormatsError> {
    let table = Table::parse(text, path)?;
    let col = table.columns(&COLUMNS)?;
    table.require_rows("control points")?;
    let mut out = Vec::with_capacity(table.rows().len());
    let mut seen: HashMap<(&str, &str), usize> = HashMap::new();
    let mut points: HashMap<&str, (usize, [f64; 3])> = HashMap::new();
    for row in table.rows() {
        let err = |problem| control_error(path, row.line, problem);
        let num = |k: usize| table.number(row, col[k], COLUMNS[k]);
        let name = row.cells[col[0]];
        if name.is_empty() {
            return Err(err(ControlProblem::EmptyName));
        }
        let world = [num(1)?, num(2)?, num(3)?];
        let image = row.cells[col[4]];
        if image.is_empty() {
            let name = name.to_string();
            return Err(err(ControlProblem::EmptyImage { name }));
        }
        let pixel = [num(5)?, num(6)?];
        if let Some(&first_line) = seen.get(&(name, image)) {
            return Err(err(ControlProblem::Duplicate {
                name: name.to_string(),
                image: image.to_string(),
                first_line,
            }));
        }
        seen.insert((name, image), row.line);
        match points.get(name) {
            Some(&(first_line, first)) if !same_point(first, world) => {
                return Err(err(ControlProblem::Moved {
                    name: name.to_string(),
                    here: world,
                    first,
                    first_line,
                }));
            }
            Some(_) => {}
            None => {
                points.insert(name, (row.line, world));
            }
        }
        out.push(ControlObservation {
            name: name.to_string(),
            world,
            image: image.to_string(),
            pixel,
        });
    }
    Ok(out)
}

/// Whether two rows' coordinates are the same point (within [`SAME_POINT_TOLERANCE`]).
fn same_point(a: [f64; 3], b: [f64; 3]) -> bool {
    let len = |v: [f64; 3]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
    let d = len([a[0] - b[0], a[1] - b[1], a[2] - b[2]]);
    d <= SAME_POINT_TOLERANCE * len(a).max(len(b))
}

/// Why `s` cannot be a cell that reads back as itself, if it cannot.
fn unwritable(s: &str) -> Option<&'static str> {
    if s.is_empty() {
        Some("it is empty")
    } else if s.contains([',', '\n', '\r']) {
        Some("it holds a comma or a line break")
    } else if s.trim() != s {
        Some("it starts or ends with white space")
    } else {
        None
    }
}

/// The observations as CSV text (the FORMATS.md layout); `path` names the file in errors.
/// A name or image that a cell cannot hold (empty, a comma, a line break, outer white space, a
/// name starting with `#`) is refused, naming the line it would have had.
pub fn control_points_to_csv(
    points: &[ControlObservation],
    path: &Path,
) -> Result<String, FormatsError> {
    let mut s = String::from(HEADER);
    for (i, p) in points.iter().enumerate() {
        let line = i + 2;
        let why_name = unwritable(&p.name).or_else(|| {
            p.name
                .starts_with('#')
                .then_some("a line starting with `#` is a comment")
        });
        for (what, value, why) in [
            ("name", &p.name, why_name),
            ("image", &p.image, unwritable(&p.image)),
        ] {
            if let Some(why) = why {
                let value = value.clone();
                return Err(control_error(
                    path,
                    line,
                    ControlProblem::Unwritable { what, value, why },
                ));
            }
        }
        let ([x, y, z], [u, v]) = (p.world, p.pixel);
        s.push_str(&format!("{},{x},{y},{z},{},{u},{v}\n", p.name, p.image));
    }
    Ok(s)
}

/// Writes [`control_points_to_csv`] to `path` atomically.
pub fn write_control_points(
    path: &Path,
    points: &[ControlObservation],
) -> Result<(), FormatsError> {
    let text = control_points_to_csv(points, path)?;
    igi_files::write_text_atomic(path, &text).map_err(|e| FormatsError::Write(Box::new(e)))
}

impl fmt::Display for ControlObservation {
    /// The observation as its CSV row (without the line break).
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let ([x, y, z], [u, v]) = (self.world, self.pixel);
        write!(f, "{},{x},{y},{z},{},{u},{v}", self.name, self.image)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str) -> Result<Vec<ControlObservation>, String> {
        parse_control_points(text, Path::new("control.csv")).map_err(|e| e.to_string())
    }

    fn obs(name: &str, world: [f64; 3], image: &str, pixel: [f64; 2]) -> ControlObservation {
        ControlObservation {
            name: name.into(),
            world,
            image: image.into(),
            pixel,
        }
    }

    #[test]
    fn reads_columns_by_name_with_comments_and_bom() {
        let text = "\u{feff}# surveyed 2026-06-21\n\
                    IMAGE, U ,v,Name,X,y,z,note\n\
                    \n\
                    IMG_0412.JPG,1834.5,902.25,gcp-1,12.5,3.25,0.02,corner\n\
                    # second photo\n\
                    IMG_0413.JPG,411,1210.75,gcp-1,12.5,3.25,0.02,\n\
                    IMG_0413.JPG,-0.5,7e2,gcp-2,-1e3,0,4500000.125,x\n";
        let got = parse(text).unwrap();
        assert_eq!(
            got,
            vec![
                obs(
                    "gcp-1",
                    [12.5, 3.25, 0.02],
                    "IMG_0412.JPG",
                    [1834.5, 902.25]
                ),
                obs(
                    "gcp-1",
                    [12.5, 3.25, 0.02],
                    "IMG_0413.JPG",
                    [411.0, 1210.75]
                ),
                obs(
                    "gcp-2",
                    [-1000.0, 0.0, 4_500_000.125],
                    "IMG_0413.JPG",
                    [-0.5, 700.0]
                ),
            ]
        );
    }

    #[test]
    fn round_trips_through_a_file() {
        let pts = vec![
            obs("a", [0.1, -2.0, 1e-12], "x.jpg", [0.0, 0.5]),
            obs(
                "b",
                [123456.789, 1.0 / 3.0, 7.0],
                "dir/y.JPG",
                [4079.0, 2715.0],
            ),
            obs("a", [0.1, -2.0, 1e-12], "dir/y.JPG", [10.25, 3.0]),
        ];
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("control.csv");
        write_control_points(&path, &pts).unwrap();
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(text.starts_with("name,x,y,z,image,u,v\na,0.1,-2,0.000000000001,x.jpg,0,0.5\n"));
        assert_eq!(read_control_points(&path).unwrap(), pts);
        assert_eq!(
            pts[1].to_string(),
            "b,123456.789,0.3333333333333333,7,dir/y.JPG,4079,2715"
        );
    }

    #[test]
    fn errors_name_file_line_and_problem() {
        let h = "name,x,y,z,image,u,v\n";
        let cases = [
            (String::new(), "control.csv: empty file (no header)"),
            (h.to_string(), "control.csv: no control points after the header"),
            (
                "name,x,y,image,u,v\na,1,2,i,3,4\n".to_string(),
                "control.csv:1: header lacks column `z` (have: name,x,y,image,u,v)",
            ),
            (
                "name,x,y,z,u,v\n".to_string(),
                "control.csv:1: header lacks column `image`",
            ),
            (format!("{h}a,1,2,3,i,4\n"), "control.csv:2: 6 cells, header has 7"),
            (
                format!("{h}a,1,2,3,i,4,5\nb,1,nan,3,i,4,5\n"),
                "control.csv:3: `y` = `nan` is not finite",
            ),
            (
                format!("{h}a,1,2,3,i,inf,5\n"),
                "control.csv:2: `u` = `inf` is not finite",
            ),
            (
                format!("{h}a,1,2,3,i,4,five\n"),
                "control.csv:2: `v` = `five` is not a number",
            ),
            (format!("{h},1,2,3,i,4,5\n"), "control.csv:2: empty point name"),
            (
                format!("{h}a,1,2,3, ,4,5\n"),
                "control.csv:2: point `a`: empty image name",
            ),
            (
                format!("{h}a,1,2,3,i,4,5\n# c\na,1,2,3,i,6,7\n"),
                "control.csv:4: point `a` in image `i` again (first on line 2)",
            ),
            (
                format!("{h}a,1,2,3,i,4,5\nb,0,0,0,i,1,1\na,1,2,3.001,j,6,7\n"),
                "control.csv:4: point `a` at x,y,z = [1.0, 2.0, 3.001], but line 2 puts it at [1.0, 2.0, 3.0]",
            ),
        ];
        for (text, want) in cases {
            let e = parse(&text).unwrap_err();
            assert!(e.starts_with(want), "got `{e}`, want `{want}`");
        }
    }

    #[test]
    fn the_same_point_may_differ_by_rounding_only() {
        let h = "name,x,y,z,image,u,v\n";
        // 1e-10 relative: the same point
        let ok = format!("{h}a,4500000,0,0,i,1,1\na,4500000.0004,0,0,j,1,1\n");
        assert_eq!(parse(&ok).unwrap().len(), 2);
        // 1e-8 relative: another point under the same name
        let bad = format!("{h}a,4500000,0,0,i,1,1\na,4500000.05,0,0,j,1,1\n");
        assert!(parse(&bad)
            .unwrap_err()
            .starts_with("control.csv:3: point `a` at"));
        // at the origin only the exact position is the same
        let zero = format!("{h}a,0,0,0,i,1,1\na,0,0,1e-12,j,1,1\n");
        assert!(parse(&zero).is_err());
    }

    #[test]
    fn refuses_to_write_what_would_not_read_back() {
        let p = Path::new("out.csv");
        let one = |name: &str, image: &str| {
            control_points_to_csv(&[obs(name, [0.0; 3], image, [0.0; 2])], p)
                .map_err(|e| e.to_string())
        };
        assert!(one("a", "b").is_ok());
        assert_eq!(
            one("a,b", "i").unwrap_err(),
            "out.csv:2: name \"a,b\" cannot be written as a CSV cell (it holds a comma or a line break)"
        );
        assert!(one("#a", "i").unwrap_err().contains("comment"));
        assert!(one("", "i").unwrap_err().contains("empty"));
        assert!(one("a", " i").unwrap_err().contains("image \" i\""));
        assert!(one("a", "i\n").is_err());
    }

    #[test]
    fn a_missing_file_is_named() {
        let e = read_control_points(Path::new("/nonexistent/control.csv"))
            .unwrap_err()
            .to_string();
        assert!(
            e.starts_with("/nonexistent/control.csv: cannot read control points"),
            "{e}"
        );
    }
}
