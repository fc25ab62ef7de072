//! Wavefront OBJ reading and writing.

use crate::atomic::write_atomic_with;
use crate::error::GeometryError;
use crate::mesh::TriMesh;
use std::collections::HashMap;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

/// Read an OBJ file: `v x y z [r g b]`, `vt u v`, `vn x y z`, `f` with corners `a`, `a/b`,
/// `a//c`, `a/b/c` (1-based, negative = relative to the end). Polygons are fan-triangulated.
/// Corners with distinct (position, uv, normal) triples become distinct vertices ("unwelded");
/// a file whose faces use positions only keeps its vertex order.
pub fn read_obj(path: &Path) -> Result<TriMesh, GeometryError> {
    let f = std::fs::File::open(path).map_err(|e| GeometryError::io(path, e))?;
    let mut r = BufReader::with_capacity(1 << 20, f);
    let mut obj = ObjData::default();
    let mut corners: Vec<[u32; 3]> = Vec::with_capacity(8);
    // one line buffer for the whole file (its line ending is whitespace to the parser)
    let mut line = String::new();
    for ln in 1.. {
        line.clear();
        if r.read_line(&mut line)
            .map_err(|e| GeometryError::io(path, e))?
            == 0
        {
            break;
        }
        obj.parse_line(&line, ln, path, &mut corners)?;
    }
    let mesh = obj.into_mesh();
    mesh.validate().map_err(|e| e.in_file(path))?;
    Ok(mesh)
}

/// What an OBJ file declares, before vertices are unwelded.
#[derive(Default)]
struct ObjData {
    pos: Vec<[f32; 3]>,
    col: Vec<[f32; 3]>,
    tex: Vec<[f32; 2]>,
    nrm: Vec<[f32; 3]>,
    /// corners as (v, vt, vn) 0-based, u32::MAX = absent
    faces: Vec<[[u32; 3]; 3]>,
    any_vt: bool,
    any_vn: bool,
}

/// An error on line `ln` of an OBJ file.
fn obj_line_error(path: &Path, ln: usize, m: &str) -> GeometryError {
    GeometryError::format(path, format!("line {ln}: {m}"))
}

impl ObjData {
    /// Parse line `ln` (1-based); `corners` is scratch space for a face's corners.
    fn parse_line(
        &mut self,
        line: &str,
        ln: usize,
        path: &Path,
        corners: &mut Vec<[u32; 3]>,
    ) -> Result<(), GeometryError> {
        let bad = |m: &str| obj_line_error(path, ln, m);
        let line = line.split('#').next().unwrap_or("");
        let mut it = line.split_whitespace();
        let Some(key) = it.next() else { return Ok(()) };
        // the first six numbers (zeros past the last) and how many there are, without a Vec
        let nums = |it: std::str::SplitWhitespace,
                    min: usize|
         -> Result<([f32; 6], usize), GeometryError> {
            let mut v = [0.0f32; 6];
            let mut n = 0;
            for t in it {
                let x = t.parse::<f32>().map_err(|_| {
                    bad(&format!(
                        "`{}` has a value that is not a number",
                        line.trim()
                    ))
                })?;
                if n < v.len() {
                    v[n] = x;
                }
                n += 1;
            }
            if n < min {
                return Err(bad(&format!("`{key}` needs {min} numbers")));
            }
            Ok((v, n))
        };
        match key {
            "v" => {
                let (v, n) = nums(it, 3)?;
                self.pos.push([v[0], v[1], v[2]]);
                if n >= 6 {
                    self.col.push([v[3], v[4], v[5]]);
                }
            }
            "vt" => {
                let (v, _) = nums(it, 1)?;
                self.tex.push([v[0], v[1]]);
            }
            "vn" => {
                let (v, _) = nums(it, 3)?;
                self.nrm.push([v[0], v[1], v[2]]);
            }
            "f" => self.parse_face(it, ln, path, corners)?,
            _ => {} // o, g, s, usemtl, mtllib, l, p...: not geometry we keep
        }
        Ok(())
    }

    /// Parse the corners of an `f` line and fan-triangulate them.
    fn parse_face(
        &mut self,
        it: std::str::SplitWhitespace,
        ln: usize,
        path: &Path,
        corners: &mut Vec<[u32; 3]>,
    ) -> Result<(), GeometryError> {
        corners.clear();
        for tok in it {
            let idx = self.parse_corner(tok, ln, path)?;
            self.any_vt |= idx[1] != u32::MAX;
            self.any_vn |= idx[2] != u32::MAX;
            corners.push(idx);
        }
        if corners.len() < 3 {
            return Err(obj_line_error(path, ln, "face with fewer than 3 corners"));
        }
        for j in 1..corners.len() - 1 {
            self.faces.push([corners[0], corners[j], corners[j + 1]]);
        }
        Ok(())
    }

    /// A face corner `a`, `a/b`, `a//c` or `a/b/c` as 0-based (v, vt, vn), u32::MAX = absent.
    fn parse_corner(&self, tok: &str, ln: usize, path: &Path) -> Result<[u32; 3], GeometryError> {
        let bad = |m: &str| obj_line_error(path, ln, m);
        let mut parts = tok.split('/');
        let mut idx = [u32::MAX; 3];
        let lens = [self.pos.len(), self.tex.len(), self.nrm.len()];
        for (k, slot) in idx.iter_mut().enumerate() {
            match parts.next() {
                None | Some("") if k > 0 => {}
                None | Some("") => {
                    return Err(bad(&format!("face corner `{tok}` has no vertex index")))
                }
                Some(s) => {
                    let i: i64 = s
                        .parse()
                        .map_err(|_| bad(&format!("bad face index `{s}`")))?;
                    let n = lens[k] as i64;
                    let j = if i > 0 { i - 1 } else { n + i };
                    if i == 0 || j < 0 || j >= n {
                        let what = ["vertex", "texture coordinate", "normal"][k];
                        return Err(bad(&format!(
                            "face {what} index {i} out of range ({n} defined so far)"
                        )));
                    }
                    *slot = j as u32;
                }
            }
        }
        Ok(idx)
    }

    /// The mesh: positions in file order when faces use positions only, else one vertex per
    /// distinct (position, uv, normal) corner.
    fn into_mesh(self) -> TriMesh {
        let colors_ok = !self.col.is_empty() && self.col.len() == self.pos.len();
        let mut mesh = TriMesh::default();
        if !self.any_vt && !self.any_vn {
            mesh.positions = self.pos;
            mesh.colors = colors_ok.then_some(self.col);
            mesh.indices = self
                .faces
                .iter()
                .map(|f| [f[0][0], f[1][0], f[2][0]])
                .collect();
            return mesh;
        }
        let mut map: HashMap<[u32; 3], u32> = HashMap::new();
        let mut uvs = Vec::new();
        let mut nv = Vec::new();
        let mut cv = Vec::new();
        for f in &self.faces {
            let mut tri = [0u32; 3];
            for (k, c) in f.iter().enumerate() {
                tri[k] = *map.entry(*c).or_insert_with(|| {
                    let id = mesh.positions.len() as u32;
                    mesh.positions.push(self.pos[c[0] as usize]);
                    if colors_ok {
                        cv.push(self.col[c[0] as usize]);
                    }
                    uvs.push(if c[1] == u32::MAX {
                        [0.0, 0.0]
                    } else {
                        self.tex[c[1] as usize]
                    });
                    nv.push(if c[2] == u32::MAX {
                        [0.0, 0.0, 0.0]
                    } else {
                        self.nrm[c[2] as usize]
                    });
                    id
                });
            }
            mesh.indices.push(tri);
        }
        mesh.uvs = self.any_vt.then_some(uvs);
        mesh.normals = self.any_vn.then_some(nv);
        mesh.colors = colors_ok.then_some(cv);
        mesh
    }
}

/// Write an OBJ file (atomically): `v` (with r g b when the mesh has colours), `vt`, `vn`,
/// and faces `a/a/a` since attributes are per vertex.
pub fn write_obj(path: &Path, mesh: &TriMesh) -> Result<(), GeometryError> {
    mesh.validate().map_err(|e| e.in_file(path))?;
    write_atomic_with(path, |w| {
        writeln!(w, "# written by igi-geometry")?;
        for (i, p) in mesh.positions.iter().enumerate() {
            match &mesh.colors {
                Some(c) => {
                    let c = c[i];
                    writeln!(w, "v {} {} {} {} {} {}", p[0], p[1], p[2], c[0], c[1], c[2])?
                }
                None => writeln!(w, "v {} {} {}", p[0], p[1], p[2])?,
            }
        }
        if let Some(t) = &mesh.uvs {
            for t in t {
                writeln!(w, "vt {} {}", t[0], t[1])?;
            }
        }
        if let Some(n) = &mesh.normals {
            for n in n {
                writeln!(w, "vn {} {} {}", n[0], n[1], n[2])?;
            }
        }
        let (has_t, has_n) = (mesh.uvs.is_some(), mesh.normals.is_some());
        for t in &mesh.indices {
            let [a, b, c] = t.map(|i| i + 1);
            match (has_t, has_n) {
                (false, false) => writeln!(w, "f {a} {b} {c}")?,
                (true, false) => writeln!(w, "f {a}/{a} {b}/{b} {c}/{c}")?,
                (false, true) => writeln!(w, "f {a}//{a} {b}//{b} {c}//{c}")?,
                (true, true) => writeln!(w, "f {a}/{a}/{a} {b}/{b}/{b} {c}/{c}/{c}")?,
            }
        }
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, s: &str) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::write(&p, s).unwrap();
        p
    }

    #[test]
    fn all_corner_forms_and_negative_indices_unweld() {
        let d = tempfile::tempdir().unwrap();
        let s = "# cube corner\nv 0 0 0\nv 1 0 0\nv 1 1 0\nv 0 1 0\nvt 0 0\nvt 1 0\nvt 1 1\nvt 0 1\nvn 0 0 1\n\
o x\ng y\nusemtl m\nf 1/1/1 2/2/1 3/3/1 4/4/1\nf -4/1 -2/3 -1/2\n";
        let p = write(d.path(), "a.obj", s);
        let m = read_obj(&p).unwrap();
        // first quad: 4 unique corners; second triangle: (1,1,-) new, (3,3,-) new, (4,2,-) new
        assert_eq!(m.positions.len(), 7);
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3], [4, 5, 6]]);
        assert_eq!(m.uvs.as_ref().unwrap()[6], [1.0, 0.0]);
        assert_eq!(m.positions[6], [0.0, 1.0, 0.0]);
        assert_eq!(m.normals.as_ref().unwrap()[0], [0.0, 0.0, 1.0]);
        let s =
            "v 0 0 0 1 0 0\nv 1 0 0 0 1 0\nv 0 1 0 0 0 1\nvn 0 0 1\nf 1//1 2//1 3//1\nf 3 2 1\n";
        let m = read_obj(&write(d.path(), "b.obj", s)).unwrap();
        assert_eq!(m.indices.len(), 2);
        assert!(m.uvs.is_none());
        assert_eq!(m.colors.as_ref().unwrap()[2], [0.0, 0.0, 1.0]);
        let s = "v 0 0 0\nv 1 0 0\nv 0 1 0\nv 5 5 5\nf 1 2 3\n";
        let m = read_obj(&write(d.path(), "c.obj", s)).unwrap();
        assert_eq!(
            m.positions.len(),
            4,
            "position-only files keep their vertices"
        );
    }

    #[test]
    fn bad_obj_is_reported_with_file_and_line() {
        let d = tempfile::tempdir().unwrap();
        let e = read_obj(&write(
            d.path(),
            "r.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 4\n",
        ))
        .unwrap_err()
        .to_string();
        assert!(
            e.contains("r.obj") && e.contains("line 4") && e.contains("index 4 out of range"),
            "{e}"
        );
        let e = read_obj(&write(d.path(), "n.obj", "v 0 x 0\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("n.obj") && e.contains("line 1"), "{e}");
        let e = read_obj(&write(d.path(), "e.obj", "# nothing\n"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("e.obj") && e.contains("empty"), "{e}");
        let e = read_obj(&write(
            d.path(),
            "z.obj",
            "v 0 0 0\nv 1 0 0\nv 0 1 0\nf 0 1 2\n",
        ))
        .unwrap_err()
        .to_string();
        assert!(e.contains("index 0"), "{e}");
    }

    #[test]
    fn write_read_round_trip() {
        let d = tempfile::tempdir().unwrap();
        let m = TriMesh {
            positions: vec![[0.1, 0.2, 0.3], [1.5, -2.25, 1e-7], [3.0, 1.0, -4.0]],
            normals: Some(vec![[0.0, 0.0, 1.0], [0.6, 0.8, 0.0], [1.0, 0.0, 0.0]]),
            uvs: Some(vec![[0.0, 1.0], [0.3, 0.7], [1.0, 0.0]]),
            colors: None,
            indices: vec![[0, 1, 2]],
        };
        let p = d.path().join("r.obj");
        write_obj(&p, &m).unwrap();
        assert_eq!(read_obj(&p).unwrap(), m, "f32 Display round-trips exactly");
    }
}
