//! COLMAP's binary model (`cameras.bin`, `images.bin`, `points3D.bin`, little-endian): read,
//! and written (for tests and for other tools). Every count is checked against the bytes left
//! in the file (each record has a least size) before anything is allocated for it; errors name
//! the file and the byte offset.

use std::path::Path;

use crate::error::ImportError;
use crate::model::{CameraModel, ColmapCamera, ColmapImage, ColmapModel, ColmapPoint};

/// Least bytes of one record: camera (id, model, width, height), image (id, q, t, camera id,
/// an empty name's NUL, point count), point (id, xyz, rgb, error, track length).
const CAMERA_MIN: usize = 4 + 4 + 8 + 8;
const IMAGE_MIN: usize = 4 + 32 + 24 + 4 + 1 + 8;
const POINT_MIN: usize = 8 + 24 + 3 + 8 + 8;
const POINT2D_SIZE: usize = 24;
const TRACK_SIZE: usize = 8;

/// A read position in a binary file held in memory.
struct Reader<'a> {
    path: &'a Path,
    data: &'a [u8],
    pos: usize,
}

impl<'a> Reader<'a> {
    fn error(&self, offset: usize, problem: impl Into<String>) -> ImportError {
        ImportError::Binary {
            path: self.path.to_path_buf(),
            offset: offset as u64,
            problem: problem.into(),
        }
    }
    fn bytes<const N: usize>(&mut self, what: &str) -> Result<[u8; N], ImportError> {
        let end = self.pos.checked_add(N).filter(|&e| e <= self.data.len());
        let end = end.ok_or_else(|| {
            let left = self.data.len() - self.pos;
            self.error(
                self.pos,
                format!("file truncated: {what} needs {N} bytes, {left} left"),
            )
        })?;
        let mut b = [0u8; N];
        b.copy_from_slice(&self.data[self.pos..end]);
        self.pos = end;
        Ok(b)
    }
    fn u64(&mut self, what: &str) -> Result<u64, ImportError> {
        Ok(u64::from_le_bytes(self.bytes(what)?))
    }
    fn i64(&mut self, what: &str) -> Result<i64, ImportError> {
        Ok(i64::from_le_bytes(self.bytes(what)?))
    }
    fn i32(&mut self, what: &str) -> Result<i32, ImportError> {
        Ok(i32::from_le_bytes(self.bytes(what)?))
    }
    fn u32(&mut self, what: &str) -> Result<u32, ImportError> {
        Ok(u32::from_le_bytes(self.bytes(what)?))
    }
    fn f64(&mut self, what: &str) -> Result<f64, ImportError> {
        Ok(f64::from_le_bytes(self.bytes(what)?))
    }
    fn f64s<const N: usize>(&mut self, what: &str) -> Result<[f64; N], ImportError> {
        let mut out = [0.0; N];
        for x in &mut out {
            *x = self.f64(what)?;
        }
        Ok(out)
    }
    /// A count of records of at least `min` bytes each, refused unless they fit in the bytes
    /// left (so no absurd count allocates).
    fn count(&mut self, what: &str, min: usize) -> Result<usize, ImportError> {
        let at = self.pos;
        let n = self.u64(what)?;
        let left = self.data.len() - self.pos;
        let fits = usize::try_from(n)
            .ok()
            .and_then(|n| n.checked_mul(min))
            .is_some_and(|b| b <= left);
        if !fits {
            return Err(self.error(at, format!("{what} = {n}, but {left} bytes left hold at most {} (each at least {min} bytes)", left / min)));
        }
        Ok(n as usize)
    }
    /// A NUL-terminated UTF-8 string.
    fn cstr(&mut self, what: &str) -> Result<String, ImportError> {
        let at = self.pos;
        let len = self.data[at..]
            .iter()
            .position(|&b| b == 0)
            .ok_or_else(|| {
                self.error(at, format!("file truncated: {what} has no terminating NUL"))
            })?;
        let s = std::str::from_utf8(&self.data[at..at + len])
            .map_err(|_| self.error(at, format!("{what} is not UTF-8")))?;
        self.pos = at + len + 1;
        Ok(s.to_string())
    }
    fn finish(&self) -> Result<(), ImportError> {
        let left = self.data.len() - self.pos;
        if left != 0 {
            return Err(self.error(self.pos, format!("{left} bytes after the last record")));
        }
        Ok(())
    }
}

fn read_file(path: &Path, what: &'static str) -> Result<Vec<u8>, ImportError> {
    std::fs::read(path).map_err(|source| ImportError::Read {
        path: path.to_path_buf(),
        what,
        source,
    })
}

fn camera(r: &mut Reader) -> Result<ColmapCamera, ImportError> {
    let id = r.u32("camera_id")?;
    let at = r.pos;
    let model_id = r.i32("model_id")?;
    let model = CameraModel::from_id(model_id).ok_or_else(|| {
        r.error(
            at,
            format!("camera {id}: unknown camera model id {model_id}"),
        )
    })?;
    let (width, height) = (r.u64("width")?, r.u64("height")?);
    let params = (0..model.num_params())
        .map(|_| r.f64("params"))
        .collect::<Result<_, _>>()?;
    Ok(ColmapCamera {
        id,
        model,
        width,
        height,
        params,
    })
}

/// Reads `cameras.bin`.
pub fn read_cameras(path: &Path) -> Result<Vec<ColmapCamera>, ImportError> {
    let data = read_file(path, "COLMAP cameras")?;
    let mut r = Reader {
        path,
        data: &data,
        pos: 0,
    };
    let n = r.count("number of cameras", CAMERA_MIN)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push(camera(&mut r)?);
    }
    r.finish()?;
    Ok(out)
}

fn image(r: &mut Reader) -> Result<ColmapImage, ImportError> {
    let id = r.u32("image_id")?;
    let q = r.f64s::<4>("qvec")?;
    let t = r.f64s::<3>("tvec")?;
    let camera_id = r.u32("camera_id")?;
    let name = r.cstr("name")?;
    let n = r.count("number of 2D points", POINT2D_SIZE)?;
    let mut points2d = Vec::with_capacity(n);
    for _ in 0..n {
        let xy = r.f64s::<2>("2D point")?;
        points2d.push((xy, r.i64("point3D_id")?));
    }
    Ok(ColmapImage {
        id,
        q,
        t,
        camera_id,
        name,
        points2d,
    })
}

/// Reads `images.bin`.
pub fn read_images(path: &Path) -> Result<Vec<ColmapImage>, ImportError> {
    let data = read_file(path, "COLMAP images")?;
    let mut r = Reader {
        path,
        data: &data,
        pos: 0,
    };
    let n = r.count("number of images", IMAGE_MIN)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push(image(&mut r)?);
    }
    r.finish()?;
    Ok(out)
}

fn point(r: &mut Reader) -> Result<ColmapPoint, ImportError> {
    let id = r.u64("point3D_id")?;
    let xyz = r.f64s::<3>("xyz")?;
    let rgb = r.bytes::<3>("rgb")?;
    let error = r.f64("error")?;
    let n = r.count("track length", TRACK_SIZE)?;
    let mut track = Vec::with_capacity(n);
    for _ in 0..n {
        track.push((r.u32("track image_id")?, r.u32("track point2D_idx")?));
    }
    Ok(ColmapPoint {
        id,
        xyz,
        rgb,
        error,
        track,
    })
}

/// Reads `points3D.bin`.
pub fn read_points(path: &Path) -> Result<Vec<ColmapPoint>, ImportError> {
    let data = read_file(path, "COLMAP points3D")?;
    let mut r = Reader {
        path,
        data: &data,
        pos: 0,
    };
    let n = r.count("number of points", POINT_MIN)?;
    let mut out = Vec::with_capacity(n);
    for _ in 0..n {
        out.push(point(&mut r)?);
    }
    r.finish()?;
    Ok(out)
}

fn put_f64s(b: &mut Vec<u8>, xs: &[f64]) {
    xs.iter()
        .for_each(|x| b.extend_from_slice(&x.to_le_bytes()));
}

/// The three files' bytes, as COLMAP writes them.
pub fn to_binary(model: &ColmapModel) -> [Vec<u8>; 3] {
    let mut c = (model.cameras.len() as u64).to_le_bytes().to_vec();
    for cam in &model.cameras {
        c.extend_from_slice(&cam.id.to_le_bytes());
        c.extend_from_slice(&cam.model.id().to_le_bytes());
        c.extend_from_slice(&cam.width.to_le_bytes());
        c.extend_from_slice(&cam.height.to_le_bytes());
        put_f64s(&mut c, &cam.params);
    }
    let mut i = (model.images.len() as u64).to_le_bytes().to_vec();
    for img in &model.images {
        i.extend_from_slice(&img.id.to_le_bytes());
        put_f64s(&mut i, &img.q);
        put_f64s(&mut i, &img.t);
        i.extend_from_slice(&img.camera_id.to_le_bytes());
        i.extend_from_slice(img.name.as_bytes());
        i.push(0);
        i.extend_from_slice(&(img.points2d.len() as u64).to_le_bytes());
        for (xy, id) in &img.points2d {
            put_f64s(&mut i, xy);
            i.extend_from_slice(&id.to_le_bytes());
        }
    }
    let mut p = (model.points.len() as u64).to_le_bytes().to_vec();
    for pt in &model.points {
        p.extend_from_slice(&pt.id.to_le_bytes());
        put_f64s(&mut p, &pt.xyz);
        p.extend_from_slice(&pt.rgb);
        put_f64s(&mut p, &[pt.error]);
        p.extend_from_slice(&(pt.track.len() as u64).to_le_bytes());
        for (im, k) in &pt.track {
            p.extend_from_slice(&im.to_le_bytes());
            p.extend_from_slice(&k.to_le_bytes());
        }
    }
    [c, i, p]
}

/// Writes `cameras.bin`, `images.bin` and `points3D.bin` into `dir` (atomically, each).
pub fn write_binary(model: &ColmapModel, dir: &Path) -> Result<(), ImportError> {
    let [c, i, p] = to_binary(model);
    for (name, bytes) in [("cameras.bin", c), ("images.bin", i), ("points3D.bin", p)] {
        let path = dir.join(name);
        igi_files::write_atomic(&path, |tmp| {
            std::fs::write(tmp, &bytes).map_err(|source| ImportError::Write {
                path: path.clone(),
                source,
            })
        })?;
    }
    Ok(())
}
