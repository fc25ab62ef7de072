//! The triangle mesh type shared by the whole toolkit.

use crate::error::{GeometryError, MeshInvariant};

/// An indexed triangle mesh with optional per-vertex attributes.
///
/// Every attribute vector, when present, has one entry per position. Coordinates are world
/// metres (Z up) unless the producer says otherwise; UVs follow the OBJ convention
/// ((0, 0) bottom-left of the texture, v up); colours are linear RGB in [0, 1].
#[derive(Clone, Debug, Default, PartialEq)]
pub struct TriMesh {
    pub positions: Vec<[f32; 3]>,
    pub normals: Option<Vec<[f32; 3]>>,
    pub uvs: Option<Vec<[f32; 2]>>,
    pub colors: Option<Vec<[f32; 3]>>,
    pub indices: Vec<[u32; 3]>,
}

impl TriMesh {
    /// Number of triangles.
    pub fn triangle_count(&self) -> usize {
        self.indices.len()
    }

    /// Number of vertices.
    pub fn vertex_count(&self) -> usize {
        self.positions.len()
    }

    /// The three corner positions of triangle `t`.
    pub fn triangle(&self, t: usize) -> [[f32; 3]; 3] {
        let [a, b, c] = self.indices[t];
        [
            self.positions[a as usize],
            self.positions[b as usize],
            self.positions[c as usize],
        ]
    }

    /// Area of triangle `t` in square metres (computed in f64).
    pub fn triangle_area(&self, t: usize) -> f64 {
        let [a, b, c] = self.triangle(t);
        tri_area(a, b, c)
    }

    /// Sum of all triangle areas (f64).
    pub fn total_area(&self) -> f64 {
        (0..self.indices.len()).map(|t| self.triangle_area(t)).sum()
    }

    /// Axis-aligned bounds (min, max) of the positions; `None` for a mesh without vertices.
    pub fn bounds(&self) -> Option<([f32; 3], [f32; 3])> {
        let first = *self.positions.first()?;
        let mut lo = first;
        let mut hi = first;
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        Some((lo, hi))
    }

    /// Area-weighted smooth vertex normals from the faces. A vertex that touches only
    /// degenerate faces (or none) gets +Z.
    pub fn compute_vertex_normals(&mut self) {
        let mut acc = vec![[0.0f64; 3]; self.positions.len()];
        accumulate_face_normals(&self.positions, &self.indices, &mut acc);
        self.normals = Some(finish_normals(acc));
    }

    /// Check the invariants: at least one triangle, finite coordinates and attributes,
    /// attributes of the right length, indices in range.
    pub fn validate(&self) -> Result<(), GeometryError> {
        let nv = self.positions.len();
        if nv == 0 || self.indices.is_empty() {
            return Err(MeshInvariant::Empty {
                vertices: nv,
                triangles: self.indices.len(),
            }
            .into());
        }
        self.validate_vertices()?;
        check_indices(&self.indices, 0, nv)
    }

    /// The vertex half of [`TriMesh::validate`]: finite coordinates and attributes, attributes
    /// of the right length.
    pub(crate) fn validate_vertices(&self) -> Result<(), GeometryError> {
        let nv = self.positions.len();
        if let Some(i) = self
            .positions
            .iter()
            .position(|p| !p.iter().all(|x| x.is_finite()))
        {
            return Err(MeshInvariant::NonFiniteVertex {
                vertex: i,
                position: self.positions[i],
            }
            .into());
        }
        fn check<const N: usize>(
            name: &str,
            a: &Option<Vec<[f32; N]>>,
            nv: usize,
        ) -> Result<(), GeometryError> {
            if let Some(a) = a {
                if a.len() != nv {
                    return Err(MeshInvariant::AttributeLength {
                        name: name.to_string(),
                        entries: a.len(),
                        count: nv,
                        element: "vertices",
                    }
                    .into());
                }
                if let Some(i) = a.iter().position(|p| !p.iter().all(|x| x.is_finite())) {
                    return Err(MeshInvariant::NonFiniteAttribute {
                        name: name.to_string(),
                        element: "vertex",
                        index: i,
                    }
                    .into());
                }
            }
            Ok(())
        }
        check("normals", &self.normals, nv)?;
        check("uvs", &self.uvs, nv)?;
        check("colors", &self.colors, nv)
    }

    /// Append another mesh (attributes kept only when both meshes have them).
    pub fn append(&mut self, other: &TriMesh) {
        let base = self.positions.len() as u32;
        let self_empty = self.positions.is_empty();
        fn merge<T: Copy>(a: &mut Option<Vec<T>>, b: &Option<Vec<T>>, first: bool) {
            match (a.as_mut(), b) {
                (Some(x), Some(y)) => x.extend_from_slice(y),
                (None, Some(y)) if first => *a = Some(y.clone()),
                _ => *a = None,
            }
        }
        merge(&mut self.normals, &other.normals, self_empty);
        merge(&mut self.uvs, &other.uvs, self_empty);
        merge(&mut self.colors, &other.colors, self_empty);
        self.positions.extend_from_slice(&other.positions);
        self.indices
            .extend(other.indices.iter().map(|t| t.map(|i| i + base)));
    }
}

/// Adds each triangle's area-weighted normal to its corners' sums in `acc` (the first half of
/// [`TriMesh::compute_vertex_normals`], which a streamed mesh runs chunk by chunk).
pub(crate) fn accumulate_face_normals(
    positions: &[[f32; 3]],
    indices: &[[u32; 3]],
    acc: &mut [[f64; 3]],
) {
    for tri in indices {
        let [a, b, c] = tri.map(|i| positions[i as usize].map(f64::from));
        // cross product has length 2*area: area weighting for free
        let n = cross(sub(b, a), sub(c, a));
        for &i in tri {
            let s = &mut acc[i as usize];
            for k in 0..3 {
                s[k] += n[k];
            }
        }
    }
}

/// The unit vertex normals of the sums from [`accumulate_face_normals`] (+Z where a sum is 0).
pub(crate) fn finish_normals(acc: Vec<[f64; 3]>) -> Vec<[f32; 3]> {
    acc.into_iter()
        .map(|n| {
            let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            if l > 0.0 && l.is_finite() {
                [(n[0] / l) as f32, (n[1] / l) as f32, (n[2] / l) as f32]
            } else {
                [0.0, 0.0, 1.0]
            }
        })
        .collect()
}

/// Checks that `indices` (triangles numbered from `first`) refer to the `nv` vertices.
pub(crate) fn check_indices(
    indices: &[[u32; 3]],
    first: usize,
    nv: usize,
) -> Result<(), GeometryError> {
    for (t, tri) in indices.iter().enumerate() {
        if let Some(&i) = tri.iter().find(|&&i| i as usize >= nv) {
            return Err(MeshInvariant::IndexOutOfRange {
                triangle: first + t,
                index: i,
                vertices: nv,
            }
            .into());
        }
    }
    Ok(())
}

pub(crate) fn sub(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

pub(crate) fn cross(a: [f64; 3], b: [f64; 3]) -> [f64; 3] {
    [
        a[1] * b[2] - a[2] * b[1],
        a[2] * b[0] - a[0] * b[2],
        a[0] * b[1] - a[1] * b[0],
    ]
}

pub(crate) fn norm(a: [f64; 3]) -> f64 {
    (a[0] * a[0] + a[1] * a[1] + a[2] * a[2]).sqrt()
}

/// The triangles of a row-major grid of `(nu + 1) x (nv + 1)` vertices numbered from `base`:
/// two per cell, `[a, a + 1, a + w + 1]` and `[a, a + w + 1, a + w]` with `w = nu + 1`.
pub fn grid_triangles(base: u32, nu: usize, nv: usize) -> impl Iterator<Item = [u32; 3]> {
    let w = (nu + 1) as u32;
    (0..nv as u32).flat_map(move |j| {
        (0..nu as u32).flat_map(move |i| {
            let a = base + j * w + i;
            [[a, a + 1, a + w + 1], [a, a + w + 1, a + w]]
        })
    })
}

/// Area of a triangle given by f32 corners, in f64.
pub fn tri_area(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> f64 {
    let (a, b, c) = (a.map(f64::from), b.map(f64::from), c.map(f64::from));
    0.5 * norm(cross(sub(b, a), sub(c, a)))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn quad() -> TriMesh {
        TriMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [2.0, 3.0, 0.0],
                [0.0, 3.0, 0.0],
            ],
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        }
    }

    #[test]
    fn area_and_normals_of_a_quad() {
        let mut m = quad();
        assert!((m.total_area() - 6.0).abs() < 1e-12);
        m.compute_vertex_normals();
        for n in m.normals.as_ref().unwrap() {
            assert_eq!(*n, [0.0, 0.0, 1.0]);
        }
        m.validate().unwrap();
    }

    #[test]
    fn normals_of_a_tent_are_area_weighted() {
        // two faces sharing edge (0,1): one in plane z=0 (area 1), one vertical (area 3)
        let mut m = TriMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [0.0, 2.0, 0.0],
                [0.0, 0.0, -6.0],
            ],
            indices: vec![[0, 1, 2], [0, 3, 1]],
            ..Default::default()
        };
        m.compute_vertex_normals();
        let n0 = m.normals.as_ref().unwrap()[0];
        // face normals: +z*2 (2*area 1) and (0,-1,0)*6 -> (0,-6,2)/|.|
        let l = (36.0f32 + 4.0).sqrt();
        assert!(
            (n0[1] + 6.0 / l).abs() < 1e-6 && (n0[2] - 2.0 / l).abs() < 1e-6,
            "{n0:?}"
        );
        // vertex 2 touches only the flat face
        assert_eq!(m.normals.as_ref().unwrap()[2], [0.0, 0.0, 1.0]);
    }

    #[test]
    fn validate_catches_each_problem() {
        let mut m = quad();
        m.indices[1][2] = 4;
        let e = m.validate().unwrap_err().to_string();
        assert!(
            e.contains("index 4") && e.contains("only 4 vertices"),
            "{e}"
        );
        let mut m = quad();
        m.positions[2][1] = f32::NAN;
        assert!(m
            .validate()
            .unwrap_err()
            .to_string()
            .contains("vertex 2 has a non-finite"));
        let m = TriMesh::default();
        assert!(m.validate().unwrap_err().to_string().contains("empty mesh"));
        let mut m = quad();
        m.uvs = Some(vec![[0.0, 0.0]; 3]);
        assert!(m
            .validate()
            .unwrap_err()
            .to_string()
            .contains("uvs has 3 entries for 4 vertices"));
        let mut m = quad();
        m.normals = Some(vec![[0.0, 0.0, f32::INFINITY]; 4]);
        assert!(m
            .validate()
            .unwrap_err()
            .to_string()
            .contains("normals of vertex 0"));
    }

    #[test]
    fn append_offsets_indices_and_drops_missing_attributes() {
        let mut a = quad();
        a.uvs = Some(vec![[0.5, 0.5]; 4]);
        let b = quad();
        a.append(&b);
        assert_eq!(a.indices[3], [4, 6, 7]);
        assert_eq!(a.positions.len(), 8);
        assert!(a.uvs.is_none());
        let mut e = TriMesh::default();
        let mut c = quad();
        c.uvs = Some(vec![[0.5, 0.5]; 4]);
        e.append(&c);
        assert_eq!(e.uvs.as_ref().unwrap().len(), 4);
    }
}
