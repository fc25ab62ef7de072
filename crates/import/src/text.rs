//! COLMAP's text model (`cameras.txt`, `images.txt`, `points3D.txt`): read, and written (for
//! tests and for other tools). `#` lines are comments; `images.txt` holds two lines per image,
//! the second (x, y, point3D_id triples) possibly empty. Errors name the file and the line.

use std::fmt::Write as _;
use std::path::Path;
use std::str::FromStr;

use crate::error::ImportError;
use crate::model::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint};

/// The numbered lines of a text file, for a reader that wants a line at a time.
struct Lines<'a> {
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
}

impl<'a> Lines<'a> {
    fn new(text: &'a str) -> Self {
        Lines {
            lines: text.lines().enumerate(),
        }
    }
    /// The next line that is neither empty nor a comment, trimmed, with its number.
    fn next_record(&mut self) -> Option<(usize, &'a str)> {
        self.lines
            .by_ref()
            .map(|(i, l)| (i + 1, l.trim()))
            .find(|(_, l)| !l.is_empty() && !l.starts_with('#'))
    }
    /// The next line whatever it holds (`None` at the end of the file).
    fn next_raw(&mut self) -> Option<(usize, &'a str)> {
        self.lines.next().map(|(i, l)| (i + 1, l.trim()))
    }
}

/// Parses token `i` of `tokens` as `T`, naming `what` and the line on failure.
fn field<T: FromStr>(
    path: &Path,
    line: usize,
    tokens: &[&str],
    i: usize,
    what: &str,
) -> Result<T, ImportError> {
    let tok = tokens.get(i).ok_or_else(|| {
        ImportError::text(path, line, format!("missing {what} (field {})", i + 1))
    })?;
    tok.parse().map_err(|_| {
        ImportError::text(
            path,
            line,
            format!("{what} = `{tok}` is not a valid number"),
        )
    })
}

fn read_to_string(path: &Path, what: &'static str) -> Result<String, ImportError> {
    std::fs::read_to_string(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        what,
        source,
    })
}

/// Reads `cameras.txt`: `CAMERA_ID MODEL WIDTH HEIGHT PARAMS...` per line.
pub fn read_cameras(path: &Path) -> Result<Vec<ColmapCamera>, ImportError> {
    let text = read_to_string(path, "COLMAP cameras")?;
    let mut lines = Lines::new(&text);
    let mut out = Vec::new();
    while let Some((n, line)) = lines.next_record() {
        let tok: Vec<&str> = line.split_whitespace().collect();
        let name = tok.get(1).copied().unwrap_or("");
        let model = CameraModel::from_name(name)
            .ok_or_else(|| ImportError::text(path, n, format!("unknown camera model `{name}`")))?;
        let params = (4..tok.len())
            .map(|i| field(path, n, &tok, i, "parameter"))
            .collect::<Result<Vec<f64>, _>>()?;
        if params.len() != model.num_params() {
            let problem = format!(
                "{name} takes {} parameters, the line has {}",
                model.num_params(),
                params.len()
            );
            return Err(ImportError::text(path, n, problem));
        }
        out.push(ColmapCamera {
            id: field(path, n, &tok, 0, "CAMERA_ID")?,
            model,
            width: field(path, n, &tok, 2, "WIDTH")?,
            height: field(path, n, &tok, 3, "HEIGHT")?,
            params,
        });
    }
    Ok(out)
}

/// Parses an image's first line: `IMAGE_ID QW QX QY QZ TX TY TZ CAMERA_ID NAME`.
fn image_header(path: &Path, n: usize, line: &str) -> Result<ColmapImage, ImportError> {
    let tok: Vec<&str> = line.splitn(10, char::is_whitespace).collect();
    let f = |i: usize, what: &str| field::<f64>(path, n, &tok, i, what);
    let name = tok.get(9).map(|s| s.trim()).unwrap_or("");
    if name.is_empty() {
        return Err(ImportError::text(path, n, "missing NAME (field 10)"));
    }
    Ok(ColmapImage {
        id: field(path, n, &tok, 0, "IMAGE_ID")?,
        q: [f(1, "QW")?, f(2, "QX")?, f(3, "QY")?, f(4, "QZ")?],
        t: [f(5, "TX")?, f(6, "TY")?, f(7, "TZ")?],
        camera_id: field(path, n, &tok, 8, "CAMERA_ID")?,
        name: name.to_string(),
        points2d: Vec::new(),
    })
}

/// Parses an image's second line: `X Y POINT3D_ID` triples.
fn image_points(path: &Path, n: usize, line: &str) -> Result<Vec<([f64; 2], i64)>, ImportError> {
    let tok: Vec<&str> = line.split_whitespace().collect();
    if !tok.len().is_multiple_of(3) {
        let problem = format!("{} fields: 2D points are X Y POINT3D_ID triples", tok.len());
        return Err(ImportError::text(path, n, problem));
    }
    (0..tok.len() / 3)
        .map(|k| {
            let xy = [
                field(path, n, &tok, 3 * k, "X")?,
                field(path, n, &tok, 3 * k + 1, "Y")?,
            ];
            Ok((xy, field(path, n, &tok, 3 * k + 2, "POINT3D_ID")?))
        })
        .collect()
}

/// Reads `images.txt`: two lines per image.
pub fn read_images(path: &Path) -> Result<Vec<ColmapImage>, ImportError> {
    let text = read_to_string(path, "COLMAP images")?;
    let mut lines = Lines::new(&text);
    let mut out = Vec::new();
    while let Some((n, line)) = lines.next_record() {
        let mut img = image_header(path, n, line)?;
        let (m, points) = lines.next_raw().unwrap_or((n + 1, ""));
        img.points2d = image_points(path, m, points)?;
        out.push(img);
    }
    Ok(out)
}

/// Reads `points3D.txt`: `POINT3D_ID X Y Z R G B ERROR TRACK[] as (IMAGE_ID POINT2D_IDX)`.
pub fn read_points(path: &Path) -> Result<Vec<ColmapPoint>, ImportError> {
    let text = read_to_string(path, "COLMAP points3D")?;
    let mut lines = Lines::new(&text);
    let mut out = Vec::new();
    while let Some((n, line)) = lines.next_record() {
        let tok: Vec<&str> = line.split_whitespace().collect();
        let f = |i: usize, what: &str| field::<f64>(path, n, &tok, i, what);
        let c = |i: usize, what: &str| field::<u8>(path, n, &tok, i, what);
        if tok.len() < 8 || !(tok.len() - 8).is_multiple_of(2) {
            let problem = format!(
                "{} fields: a point is 8 fields and (IMAGE_ID POINT2D_IDX) pairs",
                tok.len()
            );
            return Err(ImportError::text(path, n, problem));
        }
        let track = (0..(tok.len() - 8) / 2)
            .map(|k| {
                Ok((
                    field(path, n, &tok, 8 + 2 * k, "IMAGE_ID")?,
                    field(path, n, &tok, 9 + 2 * k, "POINT2D_IDX")?,
                ))
            })
            .collect::<Result<Vec<_>, ImportError>>()?;
        out.push(ColmapPoint {
            id: field(path, n, &tok, 0, "POINT3D_ID")?,
            xyz: [f(1, "X")?, f(2, "Y")?, f(3, "Z")?],
            rgb: [c(4, "R")?, c(5, "G")?, c(6, "B")?],
            error: f(7, "ERROR")?,
            track,
        });
    }
    Ok(out)
}

/// The three files' text, as COLMAP writes them (numbers in Rust's shortest round-trip form).
pub fn to_text(model: &ColmapModel) -> [String; 3] {
    let mut cams = String::from("# Camera list with one line of data per camera:\n");
    for c in &model.cameras {
        let _ = write!(cams, "{} {} {} {}", c.id, c.model.name(), c.width, c.height);
        c.params.iter().for_each(|p| {
            let _ = write!(cams, " {p:?}");
        });
        cams.push('\n');
    }
    let mut imgs = String::from("# Image list with two lines of data per image:\n");
    for i in &model.images {
        let ([qw, qx, qy, qz], [tx, ty, tz]) = (i.q, i.t);
        let _ = writeln!(
            imgs,
            "{} {qw:?} {qx:?} {qy:?} {qz:?} {tx:?} {ty:?} {tz:?} {} {}",
            i.id, i.camera_id, i.name
        );
        let pts: Vec<String> = i
            .points2d
            .iter()
            .map(|([x, y], id)| format!("{x:?} {y:?} {id}"))
            .collect();
        imgs.push_str(&pts.join(" "));
        imgs.push('\n');
    }
    let mut pts = String::from("# 3D point list with one line of data per point:\n");
    for p in &model.points {
        let ([x, y, z], [r, g, b]) = (p.xyz, p.rgb);
        let _ = write!(pts, "{} {x:?} {y:?} {z:?} {r} {g} {b} {:?}", p.id, p.error);
        p.track.iter().for_each(|(i, k)| {
            let _ = write!(pts, " {i} {k}");
        });
        pts.push('\n');
    }
    [cams, imgs, pts]
}

/// Writes `cameras.txt`, `images.txt` and `points3D.txt` into `dir` (atomically, each).
pub fn write_text(model: &ColmapModel, dir: &Path) -> Result<(), ImportError> {
    let [c, i, p] = to_text(model);
    for (name, text) in [("cameras.txt", c), ("images.txt", i), ("points3D.txt", p)] {
        igi_files::write_text_atomic(&dir.join(name), &text)?;
    }
    Ok(())
}
