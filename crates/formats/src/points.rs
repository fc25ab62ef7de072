//! The tables of `igi sample`: surface points to query (`x,y,z,nx,ny,nz`, a header row
//! allowed) and the values it writes (`x,y,z,nx,ny,nz,r,g,b,sr,sg,sb`, the standard errors
//! empty where unknown). Both in the numeric CSV dialect of `igi_imaging::csv`.

use crate::{FileKind, FormatsError};
use glam::Vec3;
use std::fmt::Write as _;
use std::path::Path;

/// One row of `igi sample`'s output: a query point and normal, the albedo there and its
/// per-channel standard error (`None` where unknown).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct AlbedoRow {
    pub point: Vec3,
    pub normal: Vec3,
    pub rho: Vec3,
    pub stderr: Option<Vec3>,
}

/// Reads the query points (position, normal) of `igi sample`; refuses a table without rows
/// and a normal of (nearly) zero length, naming the point.
pub fn read_points(path: &Path) -> Result<Vec<(Vec3, Vec3)>, FormatsError> {
    let text = std::fs::read_to_string(path).map_err(|source| FormatsError::Read {
        path: path.to_path_buf(),
        kind: FileKind::Points,
        source,
    })?;
    let rows = igi_imaging::csv::number_rows::<f32, 6>(&text, path, "x,y,z,nx,ny,nz")?;
    if rows.is_empty() {
        return Err(FormatsError::NoRows {
            path: path.to_path_buf(),
            what: "points",
        });
    }
    let points: Vec<(Vec3, Vec3)> = rows
        .iter()
        .map(|r| (Vec3::new(r[0], r[1], r[2]), Vec3::new(r[3], r[4], r[5])))
        .collect();
    // a zero normal gives no side of the surface to look from (it was taken as +z, silently)
    if let Some(i) = points.iter().position(|(_, n)| !(n.length() > 1e-6)) {
        let (p, n) = points[i];
        return Err(FormatsError::PointValue {
            path: path.to_path_buf(),
            point: i + 1,
            problem: format!(
                "at ({}, {}, {}): normal ({}, {}, {}) has no direction (length {:e}); give the \
                 surface's normal there",
                p.x,
                p.y,
                p.z,
                n.x,
                n.y,
                n.z,
                n.length()
            ),
        });
    }
    Ok(points)
}

/// The text of `igi sample`'s output table.
pub fn albedo_rows_to_csv(rows: &[AlbedoRow]) -> String {
    let mut csv = String::from("x,y,z,nx,ny,nz,r,g,b,sr,sg,sb\n");
    for r in rows {
        let (p, n, v) = (r.point, r.normal, r.rho);
        let se = r
            .stderr
            .map_or(",,".to_string(), |s| format!("{},{},{}", s.x, s.y, s.z));
        let _ = writeln!(
            csv,
            "{},{},{},{},{},{},{},{},{},{se}",
            p.x, p.y, p.z, n.x, n.y, n.z, v.x, v.y, v.z
        );
    }
    csv
}

/// Writes `igi sample`'s output table atomically.
pub fn write_albedo_rows(path: &Path, rows: &[AlbedoRow]) -> Result<(), FormatsError> {
    igi_files::write_text_atomic(path, &albedo_rows_to_csv(rows))
        .map_err(|e| FormatsError::Write(Box::new(e)))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn points_read_and_values_write_in_the_documented_columns() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("points.csv");
        std::fs::write(
            &p,
            "x,y,z,nx,ny,nz\n1,2,3,0,0,1\n# a comment\n4,5,6,0,1,0\n",
        )
        .unwrap();
        let pts = read_points(&p).unwrap();
        assert_eq!(pts[1], (Vec3::new(4.0, 5.0, 6.0), Vec3::Y));
        let rows = [
            AlbedoRow {
                point: pts[0].0,
                normal: pts[0].1,
                rho: Vec3::new(0.5, 0.25, 0.125),
                stderr: Some(Vec3::splat(0.01)),
            },
            AlbedoRow {
                point: pts[1].0,
                normal: pts[1].1,
                rho: Vec3::ONE,
                stderr: None,
            },
        ];
        assert_eq!(
            albedo_rows_to_csv(&rows),
            "x,y,z,nx,ny,nz,r,g,b,sr,sg,sb\n1,2,3,0,0,1,0.5,0.25,0.125,0.01,0.01,0.01\n4,5,6,0,1,0,1,1,1,,,\n"
        );
        std::fs::write(&p, "x,y,z,nx,ny,nz\n").unwrap();
        let e = read_points(&p).unwrap_err().to_string();
        assert!(e.contains("points.csv") && e.contains("no points"), "{e}");
    }
}
