//! PLY reading (ASCII, binary little and big endian) and writing (binary little endian).

use crate::atomic::write_atomic_with;
use crate::error::GeometryError;
use crate::mesh::TriMesh;
use std::io::{BufRead, BufReader, Write};
use std::path::Path;

#[derive(Clone, Copy, Debug, PartialEq)]
enum Encoding {
    Ascii,
    BinLe,
    BinBe,
}

#[derive(Clone, Copy, Debug, PartialEq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn parse(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }
    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }
    /// Full-scale value for colour normalisation of integer types.
    fn color_scale(self) -> f64 {
        match self {
            Scalar::U8 | Scalar::I8 => 255.0,
            Scalar::U16 | Scalar::I16 => 65535.0,
            Scalar::U32 | Scalar::I32 => 4294967295.0,
            Scalar::F32 | Scalar::F64 => 1.0,
        }
    }
    fn decode(self, b: &[u8], enc: Encoding) -> f64 {
        macro_rules! rd {
            ($t:ty, $n:expr) => {{
                let a: [u8; $n] = b[..$n].try_into().unwrap();
                (if enc == Encoding::BinBe {
                    <$t>::from_be_bytes(a)
                } else {
                    <$t>::from_le_bytes(a)
                }) as f64
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => rd!(i16, 2),
            Scalar::U16 => rd!(u16, 2),
            Scalar::I32 => rd!(i32, 4),
            Scalar::U32 => rd!(u32, 4),
            Scalar::F32 => rd!(f32, 4),
            Scalar::F64 => rd!(f64, 8),
        }
    }
}

#[derive(Clone, Debug)]
struct Property {
    name: String,
    /// `Some(count type)` for a list property.
    list: Option<Scalar>,
    ty: Scalar,
}

#[derive(Clone, Debug)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Property>,
}

struct Header {
    enc: Encoding,
    elements: Vec<Element>,
}

/// Read one header line into `line` (without its line ending); false at the end of the file.
/// Header lines are ASCII; this reads bytes up to '\n' so binary data after the header is
/// untouched.
fn read_header_line<R: BufRead>(
    r: &mut R,
    path: &Path,
    line: &mut String,
) -> Result<bool, GeometryError> {
    line.clear();
    let mut buf = Vec::new();
    let n = r
        .read_until(b'\n', &mut buf)
        .map_err(|e| GeometryError::io(path, e))?;
    if n == 0 {
        return Ok(false);
    }
    if buf.len() > 4096 {
        return Err(GeometryError::format(
            path,
            "PLY header line longer than 4096 bytes",
        ));
    }
    *line = String::from_utf8_lossy(&buf)
        .trim_end_matches(['\n', '\r'])
        .to_string();
    Ok(true)
}

fn read_header<R: BufRead>(r: &mut R, path: &Path) -> Result<Header, GeometryError> {
    let mut line = String::new();
    if !read_header_line(r, path, &mut line)? || line.trim() != "ply" {
        return Err(GeometryError::format(
            path,
            "not a PLY file (first line is not `ply`)",
        ));
    }
    let mut enc = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        if !read_header_line(r, path, &mut line)? {
            return Err(GeometryError::format(
                path,
                "truncated PLY header (no `end_header`)",
            ));
        }
        let toks: Vec<&str> = line.split_whitespace().collect();
        match toks.first().copied() {
            None | Some("comment") | Some("obj_info") => {}
            Some("format") => enc = Some(parse_format(&toks, path)?),
            Some("element") => elements.push(parse_element(&toks, &line, path)?),
            Some("property") => {
                let Some(el) = elements.last_mut() else {
                    return Err(GeometryError::format(
                        path,
                        "PLY property before any element",
                    ));
                };
                el.props.push(parse_property(&toks, &line, path)?);
            }
            Some("end_header") => break,
            Some(other) => {
                return Err(GeometryError::format(
                    path,
                    format!("unknown PLY header keyword `{other}`"),
                ))
            }
        }
    }
    let enc = enc.ok_or_else(|| GeometryError::format(path, "PLY header has no `format` line"))?;
    Ok(Header { enc, elements })
}

/// The encoding of a `format` line.
fn parse_format(toks: &[&str], path: &Path) -> Result<Encoding, GeometryError> {
    match toks.get(1).copied() {
        Some("ascii") => Ok(Encoding::Ascii),
        Some("binary_little_endian") => Ok(Encoding::BinLe),
        Some("binary_big_endian") => Ok(Encoding::BinBe),
        other => Err(GeometryError::format(
            path,
            format!("unknown PLY format {other:?}"),
        )),
    }
}

/// An `element NAME COUNT` line, with no properties yet.
fn parse_element(toks: &[&str], line: &str, path: &Path) -> Result<Element, GeometryError> {
    let (Some(name), Some(count)) = (
        toks.get(1),
        toks.get(2).and_then(|c| c.parse::<usize>().ok()),
    ) else {
        return Err(GeometryError::format(
            path,
            format!("bad PLY element line `{line}`"),
        ));
    };
    Ok(Element {
        name: name.to_string(),
        count,
        props: Vec::new(),
    })
}

/// A `property TYPE NAME` or `property list COUNT_TYPE TYPE NAME` line.
fn parse_property(toks: &[&str], line: &str, path: &Path) -> Result<Property, GeometryError> {
    let bad = || GeometryError::format(path, format!("bad PLY property line `{line}`"));
    if toks.get(1) == Some(&"list") {
        let ct = toks.get(2).and_then(|s| Scalar::parse(s)).ok_or_else(bad)?;
        let ty = toks.get(3).and_then(|s| Scalar::parse(s)).ok_or_else(bad)?;
        if matches!(ct, Scalar::F32 | Scalar::F64) {
            return Err(bad());
        }
        Ok(Property {
            name: toks.get(4).ok_or_else(bad)?.to_string(),
            list: Some(ct),
            ty,
        })
    } else {
        let ty = toks.get(1).and_then(|s| Scalar::parse(s)).ok_or_else(bad)?;
        Ok(Property {
            name: toks.get(2).ok_or_else(bad)?.to_string(),
            list: None,
            ty,
        })
    }
}

/// Where each needed vertex attribute sits in a vertex record.
#[derive(Default)]
struct VertexLayout {
    pos: [Option<usize>; 3],
    nrm: [Option<usize>; 3],
    uv: [Option<usize>; 2],
    col: [Option<usize>; 3],
    col_scale: [f64; 3],
    /// Every other scalar property (index into the record).
    extra: Vec<usize>,
}

fn vertex_layout(el: &Element, path: &Path) -> Result<VertexLayout, GeometryError> {
    let mut l = VertexLayout {
        col_scale: [1.0; 3],
        ..Default::default()
    };
    for (i, p) in el.props.iter().enumerate() {
        let slot = match p.name.as_str() {
            "x" => &mut l.pos[0],
            "y" => &mut l.pos[1],
            "z" => &mut l.pos[2],
            "nx" => &mut l.nrm[0],
            "ny" => &mut l.nrm[1],
            "nz" => &mut l.nrm[2],
            "u" | "s" | "texture_u" | "texture_s" => &mut l.uv[0],
            "v" | "t" | "texture_v" | "texture_t" => &mut l.uv[1],
            "red" | "r" | "diffuse_red" => {
                l.col_scale[0] = p.ty.color_scale();
                &mut l.col[0]
            }
            "green" | "g" | "diffuse_green" => {
                l.col_scale[1] = p.ty.color_scale();
                &mut l.col[1]
            }
            "blue" | "b" | "diffuse_blue" => {
                l.col_scale[2] = p.ty.color_scale();
                &mut l.col[2]
            }
            _ => {
                if p.list.is_none() {
                    l.extra.push(i);
                }
                continue;
            }
        };
        if p.list.is_some() {
            return Err(GeometryError::format(
                path,
                format!("vertex property `{}` is a list", p.name),
            ));
        }
        *slot = Some(i);
    }
    if l.pos.iter().any(|p| p.is_none()) {
        return Err(GeometryError::format(
            path,
            "PLY vertex element lacks x, y or z",
        ));
    }
    Ok(l)
}

/// Source of property values: ASCII tokens or binary bytes.
enum Source<R: BufRead> {
    Ascii {
        r: R,
        line: String,
        toks: Vec<String>,
        pos: usize,
    },
    Binary {
        r: R,
        enc: Encoding,
    },
}

enum Eof {
    End,
    Io(std::io::Error),
    /// An ASCII token that does not parse as a number.
    NotANumber {
        token: String,
        source: std::num::ParseFloatError,
    },
}

impl<R: BufRead> Source<R> {
    fn scalar(&mut self, ty: Scalar) -> Result<f64, Eof> {
        match self {
            Source::Ascii { r, line, toks, pos } => {
                while *pos >= toks.len() {
                    line.clear();
                    let n = r.read_line(line).map_err(Eof::Io)?;
                    if n == 0 {
                        return Err(Eof::End);
                    }
                    *toks = line.split_whitespace().map(str::to_string).collect();
                    *pos = 0;
                }
                let t = &toks[*pos];
                *pos += 1;
                t.parse::<f64>().map_err(|source| Eof::NotANumber {
                    token: t.clone(),
                    source,
                })
            }
            Source::Binary { r, enc } => {
                let mut b = [0u8; 8];
                let n = ty.size();
                r.read_exact(&mut b[..n]).map_err(|e| {
                    if e.kind() == std::io::ErrorKind::UnexpectedEof {
                        Eof::End
                    } else {
                        Eof::Io(e)
                    }
                })?;
                Ok(ty.decode(&b[..n], *enc))
            }
        }
    }

    /// Read a fixed-size binary record (all scalar properties) in one go.
    fn record(&mut self, buf: &mut [u8]) -> Result<(), Eof> {
        match self {
            Source::Binary { r, .. } => r.read_exact(buf).map_err(|e| {
                if e.kind() == std::io::ErrorKind::UnexpectedEof {
                    Eof::End
                } else {
                    Eof::Io(e)
                }
            }),
            Source::Ascii { .. } => unreachable!("record() is binary only"),
        }
    }

    /// True if anything but whitespace remains.
    fn has_trailing_data(&mut self) -> Result<bool, std::io::Error> {
        match self {
            Source::Ascii { r, line, toks, pos } => {
                if *pos < toks.len() {
                    return Ok(true);
                }
                loop {
                    line.clear();
                    if r.read_line(line)? == 0 {
                        return Ok(false);
                    }
                    if !line.trim().is_empty() {
                        return Ok(true);
                    }
                }
            }
            Source::Binary { r, .. } => Ok(!r.fill_buf()?.is_empty()),
        }
    }
}

/// Read a PLY file (ASCII or binary, either byte order). Unknown elements and properties are
/// skipped; polygons are fan-triangulated; the result is validated.
pub fn read_ply(path: &Path) -> Result<TriMesh, GeometryError> {
    let (mesh, _) = read_ply_unchecked(path)?;
    mesh.validate().map_err(|e| e.in_file(path))?;
    Ok(mesh)
}

/// Extra scalar vertex properties by name (those that are not positions, normals, UVs or colours).
pub(crate) type ExtraProperties = Vec<(String, Vec<f32>)>;

/// How many elements of `el` to reserve room for: its declared count, but never more than a
/// file of `file_len` bytes can hold (each element takes at least its fixed-size fields in
/// binary, or a digit and a separator per property in ASCII), so a header that lies about its
/// counts cannot make the reader allocate beyond the file's size.
fn capacity_for(el: &Element, enc: Encoding, file_len: u64) -> usize {
    let min_bytes = match enc {
        Encoding::Ascii => 2 * el.props.len(),
        _ => el.props.iter().map(|p| p.list.unwrap_or(p.ty).size()).sum(),
    };
    let fits = file_len / min_bytes.max(1) as u64;
    el.count.min(usize::try_from(fits).unwrap_or(usize::MAX))
}

/// Read a PLY file without validating the mesh (a point cloud has no faces); also returns the
/// vertex element's other scalar properties.
pub(crate) fn read_ply_unchecked(path: &Path) -> Result<(TriMesh, ExtraProperties), GeometryError> {
    read_ply_with(path, None)
}

/// Faces handed over in chunks as they are read: the vertex table read so far (the mesh's
/// `indices` empty) and the next triangles, numbered from the given triangle index.
pub(crate) type FaceSink<'a> =
    &'a mut dyn FnMut(&TriMesh, usize, &[[u32; 3]]) -> Result<(), GeometryError>;

/// Triangles per chunk handed to a [`FaceSink`].
pub(crate) const FACE_CHUNK: usize = 1 << 16;

/// Read a PLY mesh, handing the faces to `sink` in chunks of [`FACE_CHUNK`] triangles (once the
/// vertices are read) instead of keeping them: the returned mesh holds the vertex table only.
/// Nothing is validated here (the sink checks the indices).
pub(crate) fn read_ply_chunked(path: &Path, sink: FaceSink) -> Result<TriMesh, GeometryError> {
    Ok(read_ply_with(path, Some(sink))?.0)
}

fn read_ply_with(
    path: &Path,
    sink: Option<FaceSink>,
) -> Result<(TriMesh, ExtraProperties), GeometryError> {
    let f = std::fs::File::open(path).map_err(|e| GeometryError::io(path, e))?;
    let file_len = f.metadata().map_err(|e| GeometryError::io(path, e))?.len();
    let mut r = BufReader::with_capacity(1 << 20, f);
    let header = read_header(&mut r, path)?;
    let src = match header.enc {
        Encoding::Ascii => Source::Ascii {
            r,
            line: String::new(),
            toks: Vec::new(),
            pos: 0,
        },
        enc => Source::Binary { r, enc },
    };
    let mut body = Body {
        src,
        path,
        enc: header.enc,
        file_len,
        sink,
        flushed: 0,
        saw_vertex: false,
    };
    let mut mesh = TriMesh::default();
    let mut extras: ExtraProperties = Vec::new();
    let mut saw_vertex = false;
    let mut saw_face = false;
    for el in &header.elements {
        match el.name.as_str() {
            "vertex" if !saw_vertex => {
                saw_vertex = true;
                extras = body.read_vertices(el, &mut mesh)?;
                body.saw_vertex = true;
            }
            "face" if !saw_face => {
                saw_face = true;
                body.read_faces(el, &mut mesh)?;
            }
            _ => body.skip_element(el)?,
        }
    }
    if !saw_vertex {
        return Err(GeometryError::format(path, "PLY has no vertex element"));
    }
    body.check_no_trailing_data()?;
    body.flush(&mut mesh, 0)?;
    Ok((mesh, extras))
}

/// The data after a PLY header, read element by element.
struct Body<'a, 's, R: BufRead> {
    src: Source<R>,
    path: &'a Path,
    enc: Encoding,
    file_len: u64,
    /// Where faces go in chunks, if not into the mesh.
    sink: Option<FaceSink<'s>>,
    /// Triangles already handed to the sink.
    flushed: usize,
    /// The vertex element has been read (faces are handed over only then).
    saw_vertex: bool,
}

/// The error for a failed read in element `i` of `el`.
fn element_error(path: &Path, el: &Element, e: Eof, i: usize) -> GeometryError {
    match e {
        Eof::End => GeometryError::format(
            path,
            format!(
                "truncated PLY: the header declares {} {} elements but the data ends in element {i}",
                el.count, el.name
            ),
        ),
        Eof::Io(e) => GeometryError::io(path, e),
        Eof::NotANumber { token, source } => GeometryError::PlyNumber {
            path: path.to_path_buf(),
            element: el.name.clone(),
            index: i,
            token,
            source,
        },
    }
}

/// Scratch space for reading the scalar values of one vertex record.
struct VertexRecord {
    /// Every property is a scalar, so a binary record has a fixed size.
    fixed: bool,
    offsets: Vec<usize>,
    buf: Vec<u8>,
    vals: Vec<f64>,
}

impl VertexRecord {
    fn new(el: &Element) -> VertexRecord {
        let offsets: Vec<usize> = el
            .props
            .iter()
            .scan(0usize, |o, p| {
                let cur = *o;
                *o += p.ty.size();
                Some(cur)
            })
            .collect();
        let rec_size: usize = el.props.iter().map(|p| p.ty.size()).sum();
        VertexRecord {
            fixed: el.props.iter().all(|p| p.list.is_none()),
            offsets,
            buf: vec![0u8; rec_size],
            vals: vec![0.0f64; el.props.len()],
        }
    }
}

impl<R: BufRead> Body<'_, '_, R> {
    /// Hands the triangles in `mesh.indices` to the sink (if any) once there are at least
    /// `min` of them and the vertices are read.
    fn flush(&mut self, mesh: &mut TriMesh, min: usize) -> Result<(), GeometryError> {
        let Some(sink) = self.sink.as_mut() else {
            return Ok(());
        };
        if !self.saw_vertex || mesh.indices.len() < min.max(1) {
            return Ok(());
        }
        let chunk = std::mem::take(&mut mesh.indices);
        sink(mesh, self.flushed, &chunk)?;
        self.flushed += chunk.len();
        mesh.indices = chunk;
        mesh.indices.clear();
        Ok(())
    }

    /// One scalar of element `i` of `el`.
    fn scalar(&mut self, el: &Element, ty: Scalar, i: usize) -> Result<f64, GeometryError> {
        let path = self.path;
        self.src
            .scalar(ty)
            .map_err(|e| element_error(path, el, e, i))
    }

    /// Read a list property's values and drop them.
    fn skip_list(
        &mut self,
        el: &Element,
        p: &Property,
        ct: Scalar,
        i: usize,
    ) -> Result<(), GeometryError> {
        let n = self.scalar(el, ct, i)?;
        for _ in 0..n as usize {
            self.scalar(el, p.ty, i)?;
        }
        Ok(())
    }

    /// Read vertex `i` into `rec.vals` (lists read as 0).
    fn read_vertex_record(
        &mut self,
        el: &Element,
        rec: &mut VertexRecord,
        i: usize,
    ) -> Result<(), GeometryError> {
        if rec.fixed && self.enc != Encoding::Ascii {
            let path = self.path;
            self.src
                .record(&mut rec.buf)
                .map_err(|e| element_error(path, el, e, i))?;
            for (k, p) in el.props.iter().enumerate() {
                rec.vals[k] = p.ty.decode(&rec.buf[rec.offsets[k]..], self.enc);
            }
        } else {
            for (k, p) in el.props.iter().enumerate() {
                if let Some(ct) = p.list {
                    self.skip_list(el, p, ct, i)?;
                    rec.vals[k] = 0.0;
                } else {
                    rec.vals[k] = self.scalar(el, p.ty, i)?;
                }
            }
        }
        Ok(())
    }

    /// Read the vertex element into `mesh`'s positions and whichever of normals, UVs and
    /// colours it has; returns its other scalar properties.
    fn read_vertices(
        &mut self,
        el: &Element,
        mesh: &mut TriMesh,
    ) -> Result<ExtraProperties, GeometryError> {
        let l = vertex_layout(el, self.path)?;
        let has_n = l.nrm.iter().all(Option::is_some);
        let has_uv = l.uv.iter().all(Option::is_some);
        let has_c = l.col.iter().all(Option::is_some);
        let cap = capacity_for(el, self.enc, self.file_len);
        mesh.positions.reserve_exact(cap);
        let mut normals = Vec::with_capacity(if has_n { cap } else { 0 });
        let mut uvs = Vec::with_capacity(if has_uv { cap } else { 0 });
        let mut colors = Vec::with_capacity(if has_c { cap } else { 0 });
        let mut rec = VertexRecord::new(el);
        let mut extras: ExtraProperties = l
            .extra
            .iter()
            .map(|&k| (el.props[k].name.clone(), Vec::with_capacity(cap)))
            .collect();
        for i in 0..el.count {
            self.read_vertex_record(el, &mut rec, i)?;
            let vals = &rec.vals;
            let g = |s: Option<usize>| vals[s.unwrap()];
            mesh.positions
                .push([g(l.pos[0]) as f32, g(l.pos[1]) as f32, g(l.pos[2]) as f32]);
            if has_n {
                normals.push([g(l.nrm[0]) as f32, g(l.nrm[1]) as f32, g(l.nrm[2]) as f32]);
            }
            if has_uv {
                uvs.push([g(l.uv[0]) as f32, g(l.uv[1]) as f32]);
            }
            for (e, &k) in extras.iter_mut().zip(&l.extra) {
                e.1.push(vals[k] as f32);
            }
            if has_c {
                colors.push([
                    (g(l.col[0]) / l.col_scale[0]) as f32,
                    (g(l.col[1]) / l.col_scale[1]) as f32,
                    (g(l.col[2]) / l.col_scale[2]) as f32,
                ]);
            }
        }
        mesh.normals = has_n.then_some(normals);
        mesh.uvs = has_uv.then_some(uvs);
        mesh.colors = has_c.then_some(colors);
        Ok(extras)
    }

    /// Read the face element, fan-triangulating each polygon into `mesh.indices`.
    fn read_faces(&mut self, el: &Element, mesh: &mut TriMesh) -> Result<(), GeometryError> {
        let path = self.path;
        let vi = el
            .props
            .iter()
            .position(|p| {
                p.list.is_some() && (p.name == "vertex_indices" || p.name == "vertex_index")
            })
            .ok_or_else(|| {
                GeometryError::format(path, "PLY face element has no vertex_indices list")
            })?;
        if self.sink.is_none() {
            mesh.indices
                .reserve(capacity_for(el, self.enc, self.file_len));
        }
        let mut poly: Vec<u32> = Vec::with_capacity(8);
        for i in 0..el.count {
            for (k, p) in el.props.iter().enumerate() {
                let Some(ct) = p.list else {
                    self.scalar(el, p.ty, i)?;
                    continue;
                };
                self.read_polygon(el, p, ct, i, k == vi, &mut poly)?;
                if k == vi {
                    if poly.len() < 3 {
                        return Err(GeometryError::format(
                            path,
                            format!("face {i} has {} vertices (need at least 3)", poly.len()),
                        ));
                    }
                    for j in 1..poly.len() - 1 {
                        mesh.indices.push([poly[0], poly[j], poly[j + 1]]);
                    }
                }
            }
            if mesh.indices.len() >= FACE_CHUNK {
                self.flush(mesh, FACE_CHUNK)?;
            }
        }
        Ok(())
    }

    /// Read a list property of face `i`; when `keep`, its values are vertex indices, checked and
    /// stored in `poly`.
    fn read_polygon(
        &mut self,
        el: &Element,
        p: &Property,
        ct: Scalar,
        i: usize,
        keep: bool,
        poly: &mut Vec<u32>,
    ) -> Result<(), GeometryError> {
        let n = self.scalar(el, ct, i)?;
        if !(0.0..=1e6).contains(&n) {
            return Err(GeometryError::format(
                self.path,
                format!("face {i}: bad list length {n}"),
            ));
        }
        poly.clear();
        for _ in 0..n as usize {
            let v = self.scalar(el, p.ty, i)?;
            if keep {
                if v < 0.0 || v.fract() != 0.0 || v > u32::MAX as f64 {
                    return Err(GeometryError::format(
                        self.path,
                        format!("face {i}: vertex index {v} out of range"),
                    ));
                }
                poly.push(v as u32);
            }
        }
        Ok(())
    }

    /// Read an element we do not use and drop it.
    fn skip_element(&mut self, el: &Element) -> Result<(), GeometryError> {
        for i in 0..el.count {
            for p in &el.props {
                if let Some(ct) = p.list {
                    self.skip_list(el, p, ct, i)?;
                } else {
                    self.scalar(el, p.ty, i)?;
                }
            }
        }
        Ok(())
    }

    fn check_no_trailing_data(&mut self) -> Result<(), GeometryError> {
        if self
            .src
            .has_trailing_data()
            .map_err(|e| GeometryError::io(self.path, e))?
        {
            return Err(GeometryError::format(
                self.path,
                "data continues after the last element the header declares: the element counts do not match the data",
            ));
        }
        Ok(())
    }
}

/// Write a binary little-endian PLY (x y z, then nx ny nz, u v, red green blue as floats when
/// present; faces as `list uchar int vertex_indices`), atomically.
pub fn write_ply(path: &Path, mesh: &TriMesh) -> Result<(), GeometryError> {
    mesh.validate().map_err(|e| e.in_file(path))?;
    if mesh.positions.len() > i32::MAX as usize {
        return Err(GeometryError::format(
            path,
            "too many vertices for a PLY with int indices",
        ));
    }
    write_atomic_with(path, |w| {
        let mut h =
            String::from("ply\nformat binary_little_endian 1.0\ncomment written by igi-geometry\n");
        h += &format!(
            "element vertex {}\nproperty float x\nproperty float y\nproperty float z\n",
            mesh.positions.len()
        );
        if mesh.normals.is_some() {
            h += "property float nx\nproperty float ny\nproperty float nz\n";
        }
        if mesh.uvs.is_some() {
            h += "property float u\nproperty float v\n";
        }
        if mesh.colors.is_some() {
            h += "property float red\nproperty float green\nproperty float blue\n";
        }
        h += &format!(
            "element face {}\nproperty list uchar int vertex_indices\nend_header\n",
            mesh.indices.len()
        );
        w.write_all(h.as_bytes())?;
        let mut rec = Vec::with_capacity(44);
        for i in 0..mesh.positions.len() {
            rec.clear();
            let mut put = |v: &[f32]| crate::ply::push_le_f32(&mut rec, v);
            put(&mesh.positions[i]);
            if let Some(n) = &mesh.normals {
                put(&n[i]);
            }
            if let Some(t) = &mesh.uvs {
                put(&t[i]);
            }
            if let Some(c) = &mesh.colors {
                put(&c[i]);
            }
            w.write_all(&rec)?;
        }
        let mut rec = [0u8; 13];
        rec[0] = 3;
        for t in &mesh.indices {
            for k in 0..3 {
                rec[1 + 4 * k..5 + 4 * k].copy_from_slice(&(t[k] as i32).to_le_bytes());
            }
            w.write_all(&rec)?;
        }
        Ok(())
    })
}

/// Appends the little-endian bytes of `v` to a binary PLY record.
pub(crate) fn push_le_f32(rec: &mut Vec<u8>, v: &[f32]) {
    for x in v {
        rec.extend_from_slice(&x.to_le_bytes());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn write(dir: &Path, name: &str, bytes: &[u8]) -> std::path::PathBuf {
        let p = dir.join(name);
        std::fs::File::create(&p).unwrap().write_all(bytes).unwrap();
        p
    }

    const ASCII: &str = "ply\nformat ascii 1.0\ncomment hi\nelement vertex 4\nproperty float x\nproperty float y\n\
property float z\nproperty float confidence\nproperty uchar red\nproperty uchar green\nproperty uchar blue\n\
element face 1\nproperty list uchar int vertex_indices\nend_header\n\
0 0 0 0.5 255 0 0\n1 0 0 0.5 0 255 0\n1 1 0 0.5 0 0 255\n0 1 0 0.5 51 51 51\n4 0 1 2 3\n";

    #[test]
    fn ascii_quad_with_extra_property_and_colours() {
        let d = tempfile::tempdir().unwrap();
        let p = write(d.path(), "q.ply", ASCII.as_bytes());
        let m = read_ply(&p).unwrap();
        assert_eq!(
            m.positions,
            vec![
                [0.0, 0.0, 0.0],
                [1.0, 0.0, 0.0],
                [1.0, 1.0, 0.0],
                [0.0, 1.0, 0.0]
            ]
        );
        assert_eq!(m.indices, vec![[0, 1, 2], [0, 2, 3]]);
        let c = m.colors.unwrap();
        assert_eq!(c[0], [1.0, 0.0, 0.0]);
        assert!((c[3][1] - 0.2).abs() < 1e-6);
        assert!(m.normals.is_none() && m.uvs.is_none());
    }

    fn binary(big: bool) -> Vec<u8> {
        let fmt = if big {
            "binary_big_endian"
        } else {
            "binary_little_endian"
        };
        let mut b = format!(
            "ply\nformat {fmt} 1.0\nelement vertex 3\nproperty double x\nproperty double y\nproperty double z\n\
property short flags\nproperty float s\nproperty float t\nelement face 1\nproperty uchar tag\n\
property list uchar uint vertex_index\nproperty list uchar float texcoord\nelement junk 2\nproperty list int char data\nend_header\n"
        )
        .into_bytes();
        macro_rules! put {
            ($v:expr) => {
                if big {
                    b.extend_from_slice(&$v.to_be_bytes())
                } else {
                    b.extend_from_slice(&$v.to_le_bytes())
                }
            };
        }
        let pts = [[0.0f64, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 3.0, 1.0]];
        for (i, p) in pts.iter().enumerate() {
            for x in p {
                put!(*x);
            }
            put!(7i16);
            put!(i as f32 * 0.25f32);
            put!(0.5f32);
        }
        b.push(9); // tag
        b.push(3);
        for i in 0..3u32 {
            put!(i);
        }
        b.push(6);
        for _ in 0..6 {
            put!(0.0f32);
        }
        for n in [2i32, 0] {
            put!(n);
            b.extend(std::iter::repeat_n(1, n as usize));
        }
        b
    }

    #[test]
    fn binary_both_endians_skip_unknown_properties_and_elements() {
        let d = tempfile::tempdir().unwrap();
        for big in [false, true] {
            let p = write(d.path(), "b.ply", &binary(big));
            let m = read_ply(&p).unwrap();
            assert_eq!(
                m.positions,
                vec![[0.0, 0.0, 1.0], [2.0, 0.0, 1.0], [0.0, 3.0, 1.0]]
            );
            assert_eq!(m.uvs.unwrap(), vec![[0.0, 0.5], [0.25, 0.5], [0.5, 0.5]]);
            assert_eq!(m.indices, vec![[0, 1, 2]]);
        }
    }

    #[test]
    fn a_header_declaring_billions_of_elements_is_truncated_not_an_allocation() {
        // found by igi-fuzz: `element vertex 2147483647` made the reader reserve 24 GiB
        let d = tempfile::tempdir().unwrap();
        for (name, claim, lie) in [
            ("v.ply", "element vertex 4", "element vertex 2147483647"),
            ("f.ply", "element face 1", "element face 2147483647"),
        ] {
            let p = write(d.path(), name, ASCII.replace(claim, lie).as_bytes());
            let e = read_ply(&p).unwrap_err().to_string();
            assert!(e.contains(name) && e.contains("truncated"), "{e}");
        }
        assert_eq!(
            capacity_for(
                &Element {
                    name: "vertex".into(),
                    count: usize::MAX,
                    props: vec![
                        Property {
                            name: "x".into(),
                            list: None,
                            ty: Scalar::F32
                        };
                        3
                    ],
                },
                Encoding::BinLe,
                1200
            ),
            100
        );
    }

    #[test]
    fn truncated_and_mismatched_files_are_reported() {
        let d = tempfile::tempdir().unwrap();
        let full = binary(false);
        let p = write(d.path(), "t.ply", &full[..full.len() - 5]);
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(e.contains("t.ply") && e.contains("truncated"), "{e}");
        // ascii: declares 5 vertices, has 4 (the face line is then read as a vertex, the face is missing)
        let bad = ASCII.replace("element vertex 4", "element vertex 5");
        let p = write(d.path(), "c.ply", bad.as_bytes());
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(e.contains("c.ply") && e.contains("truncated"), "{e}");
        // declares fewer vertices than present: trailing data
        let bad = ASCII
            .replace("element vertex 4", "element vertex 3")
            .replace("4 0 1 2 3", "3 0 1 2");
        let p = write(d.path(), "m.ply", bad.as_bytes());
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(e.contains("m.ply"), "{e}");
        // index out of range
        let bad = ASCII.replace("4 0 1 2 3", "4 0 1 2 9");
        let p = write(d.path(), "i.ply", bad.as_bytes());
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(e.contains("i.ply") && e.contains("index 9"), "{e}");
        // NaN
        let bad = ASCII.replace("1 1 0 0.5", "1 nan 0 0.5");
        let p = write(d.path(), "n.ply", bad.as_bytes());
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(
            e.contains("n.ply") && e.contains("vertex 2 has a non-finite"),
            "{e}"
        );
        // empty
        let p = write(
            d.path(),
            "e.ply",
            b"ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\nelement face 0\nproperty list uchar int vertex_indices\nend_header\n",
        );
        let e = read_ply(&p).unwrap_err().to_string();
        assert!(e.contains("e.ply") && e.contains("empty mesh"), "{e}");
        // header without end
        let p = write(
            d.path(),
            "h.ply",
            b"ply\nformat ascii 1.0\nelement vertex 3\n",
        );
        assert!(read_ply(&p).unwrap_err().to_string().contains("end_header"));
        let p = write(d.path(), "x.ply", b"solid stl\n");
        assert!(read_ply(&p).unwrap_err().to_string().contains("not a PLY"));
    }

    #[test]
    fn write_read_round_trip_is_exact() {
        let d = tempfile::tempdir().unwrap();
        let m = TriMesh {
            positions: vec![[0.1, 0.2, 0.3], [1.5, -2.25, 1e-7], [3.0, 1.0, -4.0]],
            normals: Some(vec![[0.0, 0.0, 1.0], [0.6, 0.8, 0.0], [1.0, 0.0, 0.0]]),
            uvs: Some(vec![[0.0, 1.0], [0.3, 0.7], [1.0, 0.0]]),
            colors: Some(vec![[0.1, 0.2, 0.3], [0.4, 0.5, 0.6], [0.7, 0.8, 0.9]]),
            indices: vec![[0, 1, 2], [2, 1, 0]],
        };
        let p = d.path().join("r.ply");
        write_ply(&p, &m).unwrap();
        assert_eq!(read_ply(&p).unwrap(), m);
        // no temp file left behind
        assert_eq!(std::fs::read_dir(d.path()).unwrap().count(), 1);
    }

    #[test]
    fn stanford_bunny_res4_reads() {
        let p = Path::new(concat!(
            env!("CARGO_MANIFEST_DIR"),
            "/../../../shared/data/meshes/stanford_bunny/reconstruction/bun_zipper_res4.ply"
        ));
        let m = read_ply(p).unwrap();
        assert_eq!(m.positions.len(), 453);
        assert_eq!(m.indices.len(), 948);
        let (lo, hi) = m.bounds().unwrap();
        // the bunny is about 0.15 m across
        assert!(hi[0] - lo[0] > 0.1 && hi[0] - lo[0] < 0.2, "{lo:?} {hi:?}");
    }
}
