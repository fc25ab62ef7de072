//! Per-voxel texture atlases and their texel caches.
//!
//! No maintained Rust binding of xatlas was available (the `xatlas-rs` crate is a 2019
//! wrapper with bindings generated on Windows), so this is a simple, honest chart packer:
//! triangles are grouped by the dominant axis of their normal (six directions), each
//! connected group of same-direction triangles becomes a chart, projected orthographically on
//! its axis plane (at one common scale, so every texel has the same size in metres), and the
//! chart rectangles are shelf-packed with gutters. The largest scale that fits the atlas
//! resolution is chosen. Projection distorts areas by at most sqrt(3) (a normal at least
//! 1/sqrt(3) along its dominant axis).
//!
//! The texel caches hold, for each texel whose centre lies on a triangle, the world position
//! and the interpolated normal; gutter texels around each chart are dilated from the chart's
//! own texels so bilinear lookups inside a chart never mix in another chart.

use crate::error::GeometryError;
use crate::mesh::{cross, sub, TriMesh};
use igi_imaging::HdrImage;
use std::collections::HashMap;

/// Atlas settings.
#[derive(Clone, Copy, Debug)]
pub struct AtlasOptions {
    /// Width and height in texels (default 512).
    pub resolution: u32,
    /// Empty texels kept around each chart (default 2; bilinear lookups need at least 1).
    pub gutter: u32,
}

impl Default for AtlasOptions {
    fn default() -> Self {
        AtlasOptions {
            resolution: 512,
            gutter: 2,
        }
    }
}

/// A mesh with atlas UVs and its texel caches.
pub struct Atlas {
    /// The input mesh with vertices split along chart borders and `uvs` set.
    pub mesh: TriMesh,
    pub resolution: usize,
    /// Edge length of one texel in metres (on the projection plane).
    pub texel_size: f64,
    pub charts: usize,
    /// World position per texel; `valid` marks covered and dilated (gutter) texels.
    pub position: HdrImage,
    /// Unit normal per texel; same validity as `position`.
    pub normal: HdrImage,
    /// 1 where the texel centre lies on the surface, 0.5 on dilated gutter texels, 0 elsewhere.
    pub coverage: HdrImage,
    /// Texels whose centre lies on the surface.
    pub covered_texels: usize,
    /// Texels claimed by two charts (0 unless a chart's projection folds over itself).
    pub overlap_texels: usize,
}

impl Atlas {
    /// Fraction of the atlas's texels that are on the surface.
    pub fn coverage_fraction(&self) -> f64 {
        self.covered_texels as f64 / (self.resolution * self.resolution) as f64
    }
}

struct Chart {
    axis: usize,
    sign: f64,
    tris: Vec<u32>,
    lo: [f64; 2],
    hi: [f64; 2],
    /// placement (texel column, row) of the padded rectangle
    at: [usize; 2],
}

fn project(p: [f32; 3], axis: usize, sign: f64) -> [f64; 2] {
    [p[(axis + 1) % 3] as f64 * sign, p[(axis + 2) % 3] as f64]
}

fn find(parent: &mut [u32], mut x: u32) -> u32 {
    while parent[x as usize] != x {
        parent[x as usize] = parent[parent[x as usize] as usize];
        x = parent[x as usize];
    }
    x
}

/// Shelf-pack rectangles of the given texel sizes into a `res x res` square; positions or None.
fn shelf_pack(sizes: &[[usize; 2]], order: &[usize], res: usize) -> Option<Vec<[usize; 2]>> {
    let mut at = vec![[0usize; 2]; sizes.len()];
    let (mut x, mut y, mut row_h) = (0usize, 0usize, 0usize);
    for &c in order {
        let [w, h] = sizes[c];
        if w > res {
            return None;
        }
        if x + w > res {
            y += row_h;
            x = 0;
            row_h = 0;
        }
        if y + h > res {
            return None;
        }
        at[c] = [x, y];
        x += w;
        row_h = row_h.max(h);
    }
    Some(at)
}

/// Build the atlas of one mesh (which must have normals).
pub fn build_atlas(mesh: &TriMesh, opts: AtlasOptions) -> Result<Atlas, GeometryError> {
    let res = opts.resolution as usize;
    let g = opts.gutter as usize;
    if res < 8 {
        return Err(GeometryError::InvalidArgument(format!(
            "atlas resolution {res} is too small (minimum 8)"
        )));
    }
    let label = face_labels(mesh);
    let (mut charts, chart_of) = group_charts(mesh, &label);
    let scale = pack_charts(&mut charts, res, g)?;
    let (out, texel_xy) = split_vertices(mesh, &charts, scale, res, g);
    Ok(fill_caches(
        out,
        &texel_xy,
        &chart_of,
        charts.len(),
        scale,
        res,
        g,
    ))
}

/// How the charts of an atlas are made.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Unwrapper {
    /// Six-axis projected charts, shelf-packed ([`build_atlas`]): exact for boxy, voxel-clipped
    /// site geometry, tens of thousands of charts on a scan or hull mesh.
    #[default]
    Projected,
    /// `uvunwrap`'s segmented, parameterised (LSCM + ARAP) and shape-packed charts
    /// ([`crate::unwrap::unwrap_uvunwrap`]): for scans and hull meshes.
    Uvunwrap,
    /// xatlas's charts ([`crate::unwrap::unwrap`]), kept for comparison.
    Xatlas,
}

impl std::str::FromStr for Unwrapper {
    type Err = GeometryError;
    fn from_str(s: &str) -> Result<Self, GeometryError> {
        match s {
            "projected" => Ok(Unwrapper::Projected),
            "uvunwrap" => Ok(Unwrapper::Uvunwrap),
            "xatlas" => Ok(Unwrapper::Xatlas),
            _ => Err(GeometryError::InvalidArgument(format!(
                "unknown unwrapper `{s}` (expected projected, uvunwrap or xatlas)"
            ))),
        }
    }
}

/// Build the atlas of one mesh with the chosen unwrapper.
pub fn build_atlas_with(
    mesh: &TriMesh,
    opts: AtlasOptions,
    unwrapper: Unwrapper,
) -> Result<Atlas, GeometryError> {
    match unwrapper {
        Unwrapper::Projected => build_atlas(mesh, opts),
        u => build_atlas_unwrapped(mesh, opts, u),
    }
}

/// The atlas of an unwrapper's charts (vertices split along its seams, normals interpolated from
/// the input's, computed when it has none); `texel_size` is the unwrapper's common texel scale
/// (each chart is scaled to it by its own surface over parametric area).
fn build_atlas_unwrapped(
    mesh: &TriMesh,
    opts: AtlasOptions,
    unwrapper: Unwrapper,
) -> Result<Atlas, GeometryError> {
    let res = opts.resolution as usize;
    let g = opts.gutter as usize;
    if res < 8 {
        return Err(GeometryError::InvalidArgument(format!(
            "atlas resolution {res} is too small (minimum 8)"
        )));
    }
    let unwrap = match unwrapper {
        Unwrapper::Xatlas => crate::unwrap::unwrap,
        _ => crate::unwrap::unwrap_uvunwrap,
    };
    let u = unwrap(&mesh.positions, &mesh.indices, opts.resolution, opts.gutter)?;
    let computed;
    let normals = match &mesh.normals {
        Some(n) => n,
        None => {
            let mut m = mesh.clone();
            m.compute_vertex_normals();
            computed = m.normals.unwrap_or_default();
            &computed
        }
    };
    let pick = |x: &[[f32; 3]]| u.xref.iter().map(|&i| x[i as usize]).collect::<Vec<_>>();
    let texel_xy: Vec<[f64; 2]> = u.texel_xy.iter().map(|p| p.map(f64::from)).collect();
    let out = TriMesh {
        positions: pick(&mesh.positions),
        normals: Some(pick(normals)),
        colors: mesh.colors.as_ref().map(|c| pick(c)),
        uvs: Some(
            texel_xy
                .iter()
                .map(|p| [(p[0] / res as f64) as f32, (1.0 - p[1] / res as f64) as f32])
                .collect(),
        ),
        indices: u.indices,
    };
    let scale = u.texels_per_unit;
    Ok(fill_caches(
        out,
        &texel_xy,
        &u.chart_of,
        u.charts,
        scale,
        res,
        g,
    ))
}

/// Rasterise the texel caches of a mesh laid out in texel space (`chart_of`: each triangle's
/// chart, [`crate::unwrap::NO_CHART`] for one left out; `scale`: texels per metre).
fn fill_caches(
    out: TriMesh,
    texel_xy: &[[f64; 2]],
    chart_of: &[u32],
    charts: usize,
    scale: f64,
    res: usize,
    g: usize,
) -> Atlas {
    let layout = Layout {
        mesh: &out,
        normals: out.normals.as_ref().unwrap(),
        texel_xy,
        chart_of,
        res,
    };
    let mut cache = TexelCache::new(res);
    let overlap = rasterise_texel_centres(&layout, &mut cache);
    cover_thin_triangles(&layout, &mut cache);
    let covered: Vec<bool> = cache.owner.iter().map(|&o| o != u32::MAX).collect();
    let covered_texels = covered.iter().filter(|c| **c).count();
    extend_into_gutters(&layout, &covered, scale, g, &mut cache);
    dilate_into_gutters(&mut cache, g);
    let coverage = cache.mark_validity(&covered);
    Atlas {
        mesh: out,
        resolution: res,
        texel_size: 1.0 / scale,
        charts,
        position: cache.position,
        normal: cache.normal,
        coverage,
        covered_texels,
        overlap_texels: overlap,
    }
}

/// The dominant direction of each face's normal, as `2 * axis + (1 when negative)`.
fn face_labels(mesh: &TriMesh) -> Vec<u8> {
    (0..mesh.indices.len())
        .map(|t| {
            let [a, b, c] = mesh.triangle(t).map(|p| p.map(f64::from));
            let n = cross(sub(b, a), sub(c, a));
            let axis = (0..3)
                .max_by(|&i, &j| n[i].abs().total_cmp(&n[j].abs()))
                .unwrap();
            (axis * 2 + usize::from(n[axis] < 0.0)) as u8
        })
        .collect()
}

/// Union-find forest over the faces: faces that share an edge (by position, not index) and a
/// direction label are joined.
fn join_same_direction_faces(mesh: &TriMesh, label: &[u8]) -> Vec<u32> {
    let nt = mesh.indices.len();
    let mut canon: HashMap<[u32; 3], u32> = HashMap::with_capacity(mesh.positions.len());
    let cid: Vec<u32> = mesh
        .positions
        .iter()
        .enumerate()
        .map(|(i, p)| *canon.entry(p.map(f32::to_bits)).or_insert(i as u32))
        .collect();
    drop(canon);
    let mut edges: Vec<(u64, u32)> = Vec::with_capacity(nt * 3);
    for (t, tri) in mesh.indices.iter().enumerate() {
        for k in 0..3 {
            let (a, b) = (cid[tri[k] as usize], cid[tri[(k + 1) % 3] as usize]);
            let key = ((a.min(b) as u64) << 32) | a.max(b) as u64;
            edges.push((key, t as u32));
        }
    }
    edges.sort_unstable();
    let mut parent: Vec<u32> = (0..nt as u32).collect();
    for w in edges.windows(2) {
        if w[0].0 == w[1].0 && label[w[0].1 as usize] == label[w[1].1 as usize] {
            let (a, b) = (find(&mut parent, w[0].1), find(&mut parent, w[1].1));
            if a != b {
                parent[a.max(b) as usize] = a.min(b);
            }
        }
    }
    parent
}

/// Connected components of same-direction faces as charts with their projected bounds (in
/// order of first face), and the chart of each face.
fn group_charts(mesh: &TriMesh, label: &[u8]) -> (Vec<Chart>, Vec<u32>) {
    let nt = mesh.indices.len();
    let mut parent = join_same_direction_faces(mesh, label);
    let mut chart_of_root: HashMap<u32, usize> = HashMap::new();
    let mut charts: Vec<Chart> = Vec::new();
    let mut chart_of = vec![0u32; nt];
    for t in 0..nt {
        let r = find(&mut parent, t as u32);
        let c = *chart_of_root.entry(r).or_insert_with(|| {
            let l = label[t] as usize;
            charts.push(Chart {
                axis: l / 2,
                sign: if l.is_multiple_of(2) { 1.0 } else { -1.0 },
                tris: Vec::new(),
                lo: [f64::INFINITY; 2],
                hi: [f64::NEG_INFINITY; 2],
                at: [0; 2],
            });
            charts.len() - 1
        });
        chart_of[t] = c as u32;
        let ch = &mut charts[c];
        ch.tris.push(t as u32);
        for &i in &mesh.indices[t] {
            let q = project(mesh.positions[i as usize], ch.axis, ch.sign);
            for k in 0..2 {
                ch.lo[k] = ch.lo[k].min(q[k]);
                ch.hi[k] = ch.hi[k].max(q[k]);
            }
        }
    }
    (charts, chart_of)
}

/// Find the largest scale (texels per metre) at which the charts' padded rectangles pack into
/// the atlas, place the charts there and return the scale.
fn pack_charts(charts: &mut [Chart], res: usize, g: usize) -> Result<f64, GeometryError> {
    let sizes_at = |s: f64| -> Vec<[usize; 2]> {
        charts
            .iter()
            .map(|c| [0, 1].map(|k| ((c.hi[k] - c.lo[k]) * s).ceil() as usize + 1 + 2 * g))
            .collect()
    };
    let area: f64 = charts
        .iter()
        .map(|c| (c.hi[0] - c.lo[0]).max(1e-9) * (c.hi[1] - c.lo[1]).max(1e-9))
        .sum();
    let try_pack = |s: f64| -> Option<Vec<[usize; 2]>> {
        let sizes = sizes_at(s);
        let mut order: Vec<usize> = (0..charts.len()).collect();
        order.sort_by(|&a, &b| {
            sizes[b][1]
                .cmp(&sizes[a][1])
                .then(sizes[b][0].cmp(&sizes[a][0]))
        });
        shelf_pack(&sizes, &order, res)
    };
    let mut s = res as f64 * (0.6 / area).sqrt();
    let mut best: Option<(f64, Vec<[usize; 2]>)> = None;
    for _ in 0..200 {
        match try_pack(s) {
            Some(at) => {
                best = Some((s, at));
                s *= 1.03;
            }
            None if best.is_some() => break,
            None => s *= 0.9,
        }
        if s < 1e-9 {
            break;
        }
    }
    let (scale, at) = best.ok_or_else(|| {
        GeometryError::InvalidArgument(format!(
            "{} charts do not fit a {res}x{res} atlas with {g}-texel gutters; raise the atlas resolution",
            charts.len()
        ))
    })?;
    for (c, a) in charts.iter_mut().zip(&at) {
        c.at = *a;
    }
    Ok(scale)
}

/// Split vertices per chart and set UVs; also returns each new vertex's texel-space
/// coordinates (X right, Y down). The output mesh has normals (computed when the input had none).
fn split_vertices(
    mesh: &TriMesh,
    charts: &[Chart],
    scale: f64,
    res: usize,
    g: usize,
) -> (TriMesh, Vec<[f64; 2]>) {
    let mut out = TriMesh::default();
    let mut normals = Vec::new();
    let mut colors = Vec::new();
    let mut uvs = Vec::new();
    let mut texel_xy: Vec<[f64; 2]> = Vec::new();
    let mut remap: HashMap<(u32, u32), u32> = HashMap::new();
    let src_n = mesh.normals.as_ref();
    out.indices = vec![[0; 3]; mesh.indices.len()];
    for (ci, ch) in charts.iter().enumerate() {
        for &t in &ch.tris {
            let tri = mesh.indices[t as usize];
            let mut nt3 = [0u32; 3];
            for k in 0..3 {
                let v = tri[k];
                nt3[k] = *remap.entry((v, ci as u32)).or_insert_with(|| {
                    let p = mesh.positions[v as usize];
                    let q = project(p, ch.axis, ch.sign);
                    let x = (ch.at[0] + g) as f64 + 0.5 + (q[0] - ch.lo[0]) * scale;
                    let y = (ch.at[1] + g) as f64 + 0.5 + (ch.hi[1] - q[1]) * scale;
                    out.positions.push(p);
                    if let Some(n) = src_n {
                        normals.push(n[v as usize]);
                    }
                    if let Some(c) = &mesh.colors {
                        colors.push(c[v as usize]);
                    }
                    uvs.push([(x / res as f64) as f32, (1.0 - y / res as f64) as f32]);
                    texel_xy.push([x, y]);
                    (out.positions.len() - 1) as u32
                });
            }
            out.indices[t as usize] = nt3;
        }
    }
    drop(remap);
    out.normals = src_n.map(|_| normals);
    out.colors = mesh.colors.as_ref().map(|_| colors);
    out.uvs = Some(uvs);
    if out.normals.is_none() {
        out.compute_vertex_normals();
    }
    (out, texel_xy)
}

/// The split mesh laid out in texel space, as the cache-filling steps read it.
struct Layout<'a> {
    mesh: &'a TriMesh,
    normals: &'a [[f32; 3]],
    /// Texel-space coordinates of each vertex (X right, Y down).
    texel_xy: &'a [[f64; 2]],
    chart_of: &'a [u32],
    res: usize,
}

impl Layout<'_> {
    fn texel_triangle(&self, t: usize) -> [[f64; 2]; 3] {
        self.mesh.indices[t].map(|i| self.texel_xy[i as usize])
    }

    fn positions(&self, t: usize) -> [[f64; 3]; 3] {
        self.mesh.indices[t].map(|i| self.mesh.positions[i as usize].map(f64::from))
    }

    fn normals(&self, t: usize) -> [[f64; 3]; 3] {
        self.mesh.indices[t].map(|i| self.normals[i as usize].map(f64::from))
    }
}

/// The texel caches being filled, and the chart owning each texel (`u32::MAX`: none yet).
struct TexelCache {
    res: usize,
    position: HdrImage,
    normal: HdrImage,
    owner: Vec<u32>,
}

impl TexelCache {
    fn new(res: usize) -> TexelCache {
        TexelCache {
            res,
            position: HdrImage::new(res, res),
            normal: HdrImage::new(res, res),
            owner: vec![u32::MAX; res * res],
        }
    }

    /// Mark owned texels valid in both caches and return the coverage image (1 on the
    /// surface, 0.5 in the gutters, 0 elsewhere).
    fn mark_validity(&mut self, covered: &[bool]) -> HdrImage {
        let res = self.res;
        let mut coverage = HdrImage::new(res, res);
        for i in 0..res * res {
            let filled = self.owner[i] != u32::MAX;
            self.position.valid[i] = filled;
            self.normal.valid[i] = filled;
            let v = if covered[i] {
                1.0
            } else if filled {
                0.5
            } else {
                0.0
            };
            coverage.pixels[i] = [v; 3];
        }
        coverage
    }
}

/// Fill every texel whose centre lies on a triangle; returns the texels claimed by two charts.
fn rasterise_texel_centres(layout: &Layout, cache: &mut TexelCache) -> usize {
    let res = layout.res;
    let mut overlap = 0usize;
    for t in 0..layout.mesh.indices.len() {
        let c = layout.chart_of[t];
        if c == crate::unwrap::NO_CHART {
            continue;
        }
        let [a, b, cc] = layout.texel_triangle(t);
        let den = (b[1] - cc[1]) * (a[0] - cc[0]) + (cc[0] - b[0]) * (a[1] - cc[1]);
        if den.abs() < 1e-18 {
            continue;
        }
        let x0 = (a[0].min(b[0]).min(cc[0]) - 0.5).floor().max(0.0) as usize;
        let x1 = ((a[0].max(b[0]).max(cc[0]) - 0.5).ceil() as usize).min(res - 1);
        let y0 = (a[1].min(b[1]).min(cc[1]) - 0.5).floor().max(0.0) as usize;
        let y1 = ((a[1].max(b[1]).max(cc[1]) - 0.5).ceil() as usize).min(res - 1);
        let [pa, pb, pc] = layout.positions(t);
        let [na, nb, nc] = layout.normals(t);
        for y in y0..=y1 {
            for x in x0..=x1 {
                let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
                let l1 = ((b[1] - cc[1]) * (px - cc[0]) + (cc[0] - b[0]) * (py - cc[1])) / den;
                let l2 = ((cc[1] - a[1]) * (px - cc[0]) + (a[0] - cc[0]) * (py - cc[1])) / den;
                let l3 = 1.0 - l1 - l2;
                let eps = -1e-7;
                if l1 < eps || l2 < eps || l3 < eps {
                    continue;
                }
                let i = y * res + x;
                if cache.owner[i] != u32::MAX && cache.owner[i] != c {
                    overlap += 1;
                    continue;
                }
                cache.owner[i] = c;
                let p = [0, 1, 2].map(|k| (l1 * pa[k] + l2 * pb[k] + l3 * pc[k]) as f32);
                let n = [0, 1, 2].map(|k| l1 * na[k] + l2 * nb[k] + l3 * nc[k]);
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                let n = if l > 0.0 {
                    n.map(|v| (v / l) as f32)
                } else {
                    na.map(|v| v as f32)
                };
                cache.position.pixels[i] = p;
                cache.normal.pixels[i] = n;
            }
        }
    }
    overlap
}

/// Triangles too thin to contain a texel centre: the texels holding their corners and centroid
/// are covered too, with the triangle's surface point closest (in the atlas plane) to the texel
/// centre.
fn cover_thin_triangles(layout: &Layout, cache: &mut TexelCache) {
    let res = layout.res;
    for t in 0..layout.mesh.indices.len() {
        let c = layout.chart_of[t];
        if c == crate::unwrap::NO_CHART {
            continue;
        }
        let xy = layout.texel_triangle(t);
        let ps = layout.positions(t);
        let ns = layout.normals(t);
        let cxy = [0, 1].map(|k| (xy[0][k] + xy[1][k] + xy[2][k]) / 3.0);
        for q in [cxy, xy[0], xy[1], xy[2]] {
            let (x, y) = (
                q[0].floor().clamp(0.0, (res - 1) as f64) as usize,
                q[1].floor().clamp(0.0, (res - 1) as f64) as usize,
            );
            let i = y * res + x;
            if cache.owner[i] != u32::MAX {
                continue;
            }
            let (_, cl) = closest_on_triangle([x as f64 + 0.5, y as f64 + 0.5], xy);
            let l = barycentric(cl, xy)
                .unwrap_or([1.0 / 3.0; 3])
                .map(|v| v.clamp(0.0, 1.0));
            let sum = l[0] + l[1] + l[2];
            let l = l.map(|v| v / sum);
            let p = [0, 1, 2].map(|k| (l[0] * ps[0][k] + l[1] * ps[1][k] + l[2] * ps[2][k]) as f32);
            let n = [0, 1, 2].map(|k| l[0] * ns[0][k] + l[1] * ns[1][k] + l[2] * ns[2][k]);
            let ln = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
            cache.owner[i] = c;
            cache.position.pixels[i] = p;
            cache.normal.pixels[i] = if ln > 0.0 {
                n.map(|v| (v / ln) as f32)
            } else {
                ns[0].map(|v| v as f32)
            };
        }
    }
}

/// Gutters: a texel within g + 1 texels of a chart takes the chart's nearest triangle extended
/// affinely to the texel centre, so the caches continue the surface across chart borders and
/// bilinear lookups there reproduce it (a sliver whose extension would run far off falls back
/// to its closest point).
fn extend_into_gutters(
    layout: &Layout,
    covered: &[bool],
    scale: f64,
    g: usize,
    cache: &mut TexelCache,
) {
    let res = layout.res;
    let reach = (g + 1) as f64;
    let mut best = vec![f64::INFINITY; res * res];
    for t in 0..layout.mesh.indices.len() {
        let c = layout.chart_of[t];
        if c == crate::unwrap::NO_CHART {
            continue;
        }
        let xy = layout.texel_triangle(t);
        let [a, b, cc] = xy;
        let den = (b[1] - cc[1]) * (a[0] - cc[0]) + (cc[0] - b[0]) * (a[1] - cc[1]);
        if den.abs() < 1e-18 {
            continue;
        }
        let lo = |k: usize| (a[k].min(b[k]).min(cc[k]) - 0.5 - reach).floor().max(0.0) as usize;
        let hi = |k: usize| {
            ((a[k].max(b[k]).max(cc[k]) - 0.5 + reach).ceil().max(0.0) as usize).min(res - 1)
        };
        let [pa, pb, pc] = layout.positions(t);
        let ns = layout.normals(t);
        for y in lo(1)..=hi(1) {
            for x in lo(0)..=hi(0) {
                let i = y * res + x;
                if covered[i] {
                    continue;
                }
                let q = [x as f64 + 0.5, y as f64 + 0.5];
                let (d, closest) = closest_on_triangle(q, xy);
                if d > reach || d >= best[i] {
                    continue;
                }
                let bary = |p: [f64; 2]| barycentric(p, xy).unwrap_or([1.0 / 3.0; 3]);
                let at =
                    |l: [f64; 3]| [0, 1, 2].map(|k| l[0] * pa[k] + l[1] * pb[k] + l[2] * pc[k]);
                let lc = bary(closest);
                let pc0 = at(lc);
                let mut p = at(bary(q));
                let run =
                    ((p[0] - pc0[0]).powi(2) + (p[1] - pc0[1]).powi(2) + (p[2] - pc0[2]).powi(2))
                        .sqrt();
                if run > 2.0 * 3f64.sqrt() * d / scale {
                    p = pc0;
                }
                let n = [0, 1, 2].map(|k| lc[0] * ns[0][k] + lc[1] * ns[1][k] + lc[2] * ns[2][k]);
                let l = (n[0] * n[0] + n[1] * n[1] + n[2] * n[2]).sqrt();
                best[i] = d;
                cache.owner[i] = c;
                cache.position.pixels[i] = p.map(|v| v as f32);
                cache.normal.pixels[i] = if l > 0.0 {
                    n.map(|v| (v / l) as f32)
                } else {
                    ns[0].map(|v| v as f32)
                };
            }
        }
    }
}

/// Anything the extension did not reach: dilate each chart into its gutter, g + 1 rings.
fn dilate_into_gutters(cache: &mut TexelCache, g: usize) {
    let res = cache.res;
    for _ in 0..=g {
        let prev = cache.owner.clone();
        for y in 0..res {
            for x in 0..res {
                let i = y * res + x;
                if prev[i] != u32::MAX {
                    continue;
                }
                let mut chart = u32::MAX;
                let (mut sp, mut sn, mut cnt) = ([0.0f32; 3], [0.0f32; 3], 0.0f32);
                for j in crate::texels::window3x3(x, y, res) {
                    if prev[j] == u32::MAX || (chart != u32::MAX && prev[j] != chart) {
                        continue;
                    }
                    chart = prev[j];
                    for k in 0..3 {
                        sp[k] += cache.position.pixels[j][k];
                        sn[k] += cache.normal.pixels[j][k];
                    }
                    cnt += 1.0;
                }
                if cnt > 0.0 {
                    cache.owner[i] = chart;
                    cache.position.pixels[i] = sp.map(|v| v / cnt);
                    let l = (sn[0] * sn[0] + sn[1] * sn[1] + sn[2] * sn[2]).sqrt();
                    cache.normal.pixels[i] = if l > 0.0 {
                        sn.map(|v| v / l)
                    } else {
                        [0.0, 0.0, 1.0]
                    };
                }
            }
        }
    }
}

/// Barycentric coordinates of `p` in a triangle of the atlas plane (None when degenerate); they
/// may be negative outside it.
fn barycentric(p: [f64; 2], t: [[f64; 2]; 3]) -> Option<[f64; 3]> {
    let [a, b, c] = t;
    let den = (b[1] - c[1]) * (a[0] - c[0]) + (c[0] - b[0]) * (a[1] - c[1]);
    if den.abs() < 1e-18 {
        return None;
    }
    let l1 = ((b[1] - c[1]) * (p[0] - c[0]) + (c[0] - b[0]) * (p[1] - c[1])) / den;
    let l2 = ((c[1] - a[1]) * (p[0] - c[0]) + (a[0] - c[0]) * (p[1] - c[1])) / den;
    Some([l1, l2, 1.0 - l1 - l2])
}

/// Distance (in texels) from `q` to a triangle in the atlas plane, and the closest point.
fn closest_on_triangle(q: [f64; 2], t: [[f64; 2]; 3]) -> (f64, [f64; 2]) {
    let cross = |o: [f64; 2], a: [f64; 2], b: [f64; 2]| {
        (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])
    };
    let s = [
        cross(t[0], t[1], q),
        cross(t[1], t[2], q),
        cross(t[2], t[0], q),
    ];
    if (s[0] >= 0.0 && s[1] >= 0.0 && s[2] >= 0.0) || (s[0] <= 0.0 && s[1] <= 0.0 && s[2] <= 0.0) {
        return (0.0, q);
    }
    let mut best = (f64::INFINITY, q);
    for k in 0..3 {
        let (a, b) = (t[k], t[(k + 1) % 3]);
        let ab = [b[0] - a[0], b[1] - a[1]];
        let l2 = ab[0] * ab[0] + ab[1] * ab[1];
        let u = if l2 > 0.0 {
            (((q[0] - a[0]) * ab[0] + (q[1] - a[1]) * ab[1]) / l2).clamp(0.0, 1.0)
        } else {
            0.0
        };
        let p = [a[0] + u * ab[0], a[1] + u * ab[1]];
        let d = ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2)).sqrt();
        if d < best.0 {
            best = (d, p);
        }
    }
    best
}

/// Continuous pixel coordinates (centre of the top-left texel at (0, 0), as
/// `HdrImage::bilinear` expects) of a UV in an atlas of `res` texels.
pub fn uv_to_pixel(uv: [f32; 2], res: usize) -> [f32; 2] {
    [uv[0] * res as f32 - 0.5, (1.0 - uv[1]) * res as f32 - 0.5]
}

#[cfg(test)]
mod tests {
    use super::*;

    fn sample_points(m: &TriMesh, n_per_tri: usize) -> Vec<([f64; 3], [f32; 2], usize)> {
        let mut out = Vec::new();
        let mut s = 12345u64;
        let mut rnd = || {
            s = s
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((s >> 11) as f64) / (1u64 << 53) as f64
        };
        for t in 0..m.indices.len() {
            for _ in 0..n_per_tri {
                let (mut a, mut b) = (rnd(), rnd());
                if a + b > 1.0 {
                    a = 1.0 - a;
                    b = 1.0 - b;
                }
                let tri = m.indices[t];
                let [p0, p1, p2] = tri.map(|i| m.positions[i as usize].map(f64::from));
                let [u0, u1, u2] = tri.map(|i| m.uvs.as_ref().unwrap()[i as usize].map(f64::from));
                let c = 1.0 - a - b;
                let p = [0, 1, 2].map(|k| c * p0[k] + a * p1[k] + b * p2[k]);
                let uv = [0, 1].map(|k| (c * u0[k] + a * u1[k] + b * u2[k]) as f32);
                out.push((p, uv, t));
            }
        }
        out
    }

    #[test]
    fn caches_reproduce_surface_positions_within_half_a_texel() {
        let site = crate::procedural::colonnade_site(5, 1);
        for name in ["column_02", "stylobate", "wall"] {
            let m = &site.iter().find(|(n, _)| n == name).unwrap().1;
            let atlas = build_atlas(m, AtlasOptions::default()).unwrap();
            assert_eq!(atlas.overlap_texels, 0, "{name}");
            assert!(
                atlas.coverage_fraction() > 0.2,
                "{name}: coverage {}",
                atlas.coverage_fraction()
            );
            let ts = atlas.texel_size;
            let mut worst = 0.0f64;
            let mut bilinear_worst = 0.0f64;
            for (p, uv, _) in sample_points(&atlas.mesh, 4) {
                let [x, y] = uv_to_pixel(uv, atlas.resolution);
                let (j, i) = (x.round() as usize, y.round() as usize);
                assert!(
                    atlas.position.is_valid(j, i),
                    "{name}: texel under a surface point is empty"
                );
                let q = atlas.position.get(j, i).map(f64::from);
                let d =
                    ((q[0] - p[0]).powi(2) + (q[1] - p[1]).powi(2) + (q[2] - p[2]).powi(2)).sqrt();
                worst = worst.max(d);
                // bilinear lookups never hit an empty texel
                let b = atlas
                    .position
                    .bilinear(x, y)
                    .expect("bilinear tap outside the chart");
                let d = ((b[0] as f64 - p[0]).powi(2)
                    + (b[1] as f64 - p[1]).powi(2)
                    + (b[2] as f64 - p[2]).powi(2))
                .sqrt();
                bilinear_worst = bilinear_worst.max(d);
            }
            // the nearest texel centre is within half a texel diagonal on the projection plane;
            // projection stretches distances by at most sqrt(3)
            let bound = 0.5 * ts * 2f64.sqrt() * 3f64.sqrt();
            assert!(worst <= bound, "{name}: {worst} > {bound} (texel {ts})");
            // the gutters continue the surface, so a bilinear lookup at a point's UV
            // reproduces it within half a texel even at chart borders
            assert!(
                bilinear_worst <= 0.5 * ts,
                "{name}: bilinear {bilinear_worst} (texel {ts})"
            );
        }
    }

    #[test]
    fn a_flat_square_fills_the_atlas_at_the_expected_texel_size() {
        let m = TriMesh {
            positions: vec![
                [0.0, 0.0, 0.0],
                [2.0, 0.0, 0.0],
                [2.0, 2.0, 0.0],
                [0.0, 2.0, 0.0],
            ],
            normals: Some(vec![[0.0, 0.0, 1.0]; 4]),
            indices: vec![[0, 1, 2], [0, 2, 3]],
            ..Default::default()
        };
        let a = build_atlas(
            &m,
            AtlasOptions {
                resolution: 64,
                gutter: 2,
            },
        )
        .unwrap();
        assert_eq!(a.charts, 1);
        // one chart of 2 m: ceil(2 s) + 1 + 4 <= 64 -> s <= 29.5 texels per metre
        assert!(
            a.texel_size >= 2.0 / 59.0 - 1e-9 && a.texel_size < 2.0 / 50.0,
            "{}",
            a.texel_size
        );
        let side = (2.0 / a.texel_size).floor() as usize + 1;
        assert!(
            a.covered_texels >= (side - 1) * (side - 1)
                && a.covered_texels <= (side + 1) * (side + 1)
        );
        // the normal cache is +z wherever valid
        for i in 0..64 * 64 {
            if a.normal.valid[i] {
                assert_eq!(a.normal.pixels[i], [0.0, 0.0, 1.0]);
            }
        }
    }
}
