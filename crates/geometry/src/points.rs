//! Point clouds and surfels (points with a normal and a splat radius), with PLY I/O.
//!
//! [`TriMesh`](crate::TriMesh) refuses a file without faces; a [`PointCloud`] is the type for
//! vertex-only PLY files. It keeps any extra scalar vertex property by name (the opacity hull
//! stores per-surfel opacity and visibility words this way). Written as binary little-endian
//! PLY with float properties: `x y z`, then `nx ny nz`, `red green blue` (linear, [0, 1]),
//! `radius` when present, then the extra properties in order.

use crate::atomic::write_atomic_with;
use crate::error::{GeometryError, MeshInvariant};
use std::io::Write;
use std::path::Path;

/// A set of points, optionally with normals, colours, splat radii and named scalar properties.
/// Every attribute, when present, has one entry per position.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct PointCloud {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub colors: Option<Vec<[f32; 3]>>,
    /// Splat radius of each point (a surfel's disk), metres.
    pub radii: Option<Vec<f32>>,
    /// Other scalar per-point properties by name, in file order.
    pub properties: Vec<(String, Vec<f32>)>,
}

impl PointCloud {
    /// Number of points.
    pub fn len(&self) -> usize {
        self.positions.len()
    }

    /// True when there are no points.
    pub fn is_empty(&self) -> bool {
        self.positions.is_empty()
    }

    /// The named extra property, if present.
    pub fn property(&self, name: &str) -> Option<&[f32]> {
        self.properties
            .iter()
            .find(|(n, _)| n == name)
            .map(|(_, v)| v.as_slice())
    }

    /// Check that the cloud is non-empty, every value is finite, every attribute has one entry
    /// per point and property names are unique PLY identifiers that do not clash with the
    /// standard ones.
    pub fn validate(&self) -> Result<(), GeometryError> {
        let n = self.positions.len();
        let bad = |m: MeshInvariant| Err(GeometryError::InvalidMesh(m));
        let length = |name: &str, entries: usize| MeshInvariant::AttributeLength {
            name: name.to_string(),
            entries,
            count: n,
            element: "points",
        };
        let not_finite = |name: &str, index: usize| MeshInvariant::NonFiniteAttribute {
            name: name.to_string(),
            element: "point",
            index,
        };
        if n == 0 {
            return bad(MeshInvariant::EmptyCloud);
        }
        let finite3 = |name: &str, a: &[[f32; 3]]| -> Result<(), GeometryError> {
            if a.len() != n {
                return bad(length(name, a.len()));
            }
            match a.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
                Some(i) => bad(not_finite(name, i)),
                None => Ok(()),
            }
        };
        finite3("positions", &self.positions)?;
        if let Some(v) = &self.normals {
            finite3("normals", v)?;
        }
        if let Some(v) = &self.colors {
            finite3("colors", v)?;
        }
        let mut names = vec![
            "x", "y", "z", "nx", "ny", "nz", "red", "green", "blue", "radius",
        ];
        let radii = self
            .radii
            .as_ref()
            .map(|r| ("radius".to_string(), r.clone()));
        for (name, v) in radii.iter().chain(&self.properties) {
            if v.len() != n {
                return bad(length(name, v.len()));
            }
            if let Some(i) = v.iter().position(|x| !x.is_finite()) {
                return bad(not_finite(name, i));
            }
        }
        for (name, _) in &self.properties {
            let ok =
                !name.is_empty() && name.chars().all(|c| c.is_ascii_alphanumeric() || c == '_');
            if !ok || names.contains(&name.as_str()) {
                return bad(MeshInvariant::PropertyName(name.clone()));
            }
            names.push(name);
        }
        Ok(())
    }
}

/// Read the vertices of a PLY file (ASCII or binary; faces, if any, are ignored) as a point
/// cloud: normals, colours, `radius` and every other scalar vertex property.
pub fn read_points_ply(path: &Path) -> Result<PointCloud, GeometryError> {
    let (mesh, mut extras) = crate::ply::read_ply_unchecked(path)?;
    let radii = extras
        .iter()
        .position(|(n, _)| n == "radius")
        .map(|i| extras.remove(i).1);
    let cloud = PointCloud {
        positions: mesh.positions,
        normals: mesh.normals,
        colors: mesh.colors,
        radii,
        properties: extras,
    };
    cloud.validate().map_err(|e| e.in_file(path))?;
    Ok(cloud)
}

/// Write a point cloud as a binary little-endian PLY without faces, atomically.
pub fn write_points_ply(path: &Path, cloud: &PointCloud) -> Result<(), GeometryError> {
    cloud.validate().map_err(|e| e.in_file(path))?;
    write_atomic_with(path, |w| {
        let mut h = String::from(
            "ply\nformat binary_little_endian 1.0\ncomment written by igi-geometry (point cloud)\n",
        );
        h += &format!(
            "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
            cloud.len()
        );
        if cloud.normals.is_some() {
            h += "property float nx\nproperty float ny\nproperty float nz\n";
        }
        if cloud.colors.is_some() {
            h += "property float red\nproperty float green\nproperty float blue\n";
        }
        if cloud.radii.is_some() {
            h += "property float radius\n";
        }
        for (name, _) in &cloud.properties {
            h += &format!("property float {name}\n");
        }
        h += "end_header\n";
        w.write_all(h.as_bytes())?;
        let mut rec = Vec::with_capacity(64);
        for i in 0..cloud.len() {
            rec.clear();
            let mut put = |v: &[f32]| crate::ply::push_le_f32(&mut rec, v);
            put(&cloud.positions[i]);
            if let Some(n) = &cloud.normals {
                put(&n[i]);
            }
            if let Some(c) = &cloud.colors {
                put(&c[i]);
            }
            if let Some(r) = &cloud.radii {
                put(&[r[i]]);
            }
            for (_, v) in &cloud.properties {
                put(&[v[i]]);
            }
            w.write_all(&rec)?;
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn cloud() -> PointCloud {
        PointCloud {
            positions: vec![[0.0, 1.0, 2.0], [-1.5, 0.25, 1e-7]],
            normals: Some(vec![[0.0, 0.0, 1.0], [1.0, 0.0, 0.0]]),
            colors: Some(vec![[0.1, 0.2, 0.3], [1.0, 0.5, 0.0]]),
            radii: Some(vec![0.01, 0.02]),
            properties: vec![
                ("alpha".into(), vec![0.5, 1.0]),
                ("vis0".into(), vec![16777215.0, 3.0]),
            ],
        }
    }

    #[test]
    fn binary_round_trip_is_exact_and_a_mesh_reader_refuses_it() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("s.ply");
        write_points_ply(&p, &cloud()).unwrap();
        assert_eq!(read_points_ply(&p).unwrap(), cloud());
        assert_eq!(
            read_points_ply(&p).unwrap().property("vis0"),
            Some(&[16777215.0f32, 3.0][..])
        );
        let e = crate::read_ply(&p).unwrap_err().to_string();
        assert!(e.contains("empty mesh"), "{e}");
    }

    #[test]
    fn ascii_points_and_mesh_vertices_read() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("a.ply");
        std::fs::write(&p, "ply\nformat ascii 1.0\nelement vertex 2\nproperty float x\nproperty float y\nproperty float z\nproperty float radius\nproperty float confidence\nend_header\n1 2 3 0.5 0.9\n4 5 6 0.25 0.1\n").unwrap();
        let c = read_points_ply(&p).unwrap();
        assert_eq!(c.positions, vec![[1.0, 2.0, 3.0], [4.0, 5.0, 6.0]]);
        assert_eq!(c.radii, Some(vec![0.5, 0.25]));
        assert_eq!(c.property("confidence"), Some(&[0.9f32, 0.1][..]));
        assert!(c.normals.is_none() && c.colors.is_none());
    }

    #[test]
    fn invalid_clouds_are_refused_before_writing() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("bad.ply");
        let mut c = cloud();
        c.radii = Some(vec![0.1]);
        let e = write_points_ply(&p, &c).unwrap_err().to_string();
        assert!(
            e.contains("bad.ply") && e.contains("radius has 1 entries for 2 points"),
            "{e}"
        );
        assert!(!p.exists());
        let mut c = cloud();
        c.positions[1][0] = f32::NAN;
        assert!(write_points_ply(&p, &c)
            .unwrap_err()
            .to_string()
            .contains("positions of point 1"));
        let mut c = cloud();
        c.properties[0].0 = "red".into();
        assert!(write_points_ply(&p, &c).is_err());
        assert!(write_points_ply(&p, &PointCloud::default())
            .unwrap_err()
            .to_string()
            .contains("empty point cloud"));
        assert!(!p.exists());
    }
}
