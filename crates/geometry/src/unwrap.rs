//! Automatic UV unwrapping: the pure-Rust `uvunwrap` crate ([`unwrap_uvunwrap`], igi's default
//! for scans and hull meshes: fewer charts, denser atlases, faster, bit-identical at any thread
//! count) and xatlas ([`unwrap`], for comparison, docs/GEOMETRY.md "Unwrappers compared").
//!
//! xatlas (vendored in `crates/geometry/xatlas`, MIT, Jonathan Young,
//! github.com/jpcy/xatlas at f700c77): chart segmentation grown by normal deviation, roundness
//! and straightness, LSCM / piecewise parameterisation, and packing with padding. These are the
//! only bindings: its C API (`xatlas_c.h`) declared by hand, called through one safe function.
//!
//! xatlas is compiled single-threaded (build.rs), so the same mesh gives the same bytes. The
//! atlas is packed at a texel scale that fits one `resolution x resolution` square: xatlas's own
//! estimate first, then shrunk by the overshoot until the packed atlas fits.

use crate::error::GeometryError;
use std::ffi::c_void;

#[repr(C)]
struct XChart {
    face_array: *mut u32,
    atlas_index: u32,
    face_count: u32,
    kind: u32,
    material: u32,
}

#[repr(C)]
struct XVertex {
    atlas_index: i32,
    chart_index: i32,
    uv: [f32; 2],
    xref: u32,
}

#[repr(C)]
struct XMesh {
    chart_array: *mut XChart,
    index_array: *mut u32,
    vertex_array: *mut XVertex,
    chart_count: u32,
    index_count: u32,
    vertex_count: u32,
}

#[repr(C)]
struct XAtlas {
    image: *mut u32,
    meshes: *mut XMesh,
    utilization: *mut f32,
    width: u32,
    height: u32,
    atlas_count: u32,
    chart_count: u32,
    mesh_count: u32,
    texels_per_unit: f32,
}

#[repr(C)]
struct XMeshDecl {
    vertex_position_data: *const c_void,
    vertex_normal_data: *const c_void,
    vertex_uv_data: *const c_void,
    index_data: *const c_void,
    face_ignore_data: *const bool,
    face_material_data: *const u32,
    face_vertex_count: *const u8,
    vertex_count: u32,
    vertex_position_stride: u32,
    vertex_normal_stride: u32,
    vertex_uv_stride: u32,
    index_count: u32,
    index_offset: i32,
    face_count: u32,
    /// 1: 32-bit indices
    index_format: u32,
    epsilon: f32,
}

#[repr(C)]
struct XChartOptions {
    param_func: *const c_void,
    max_chart_area: f32,
    max_boundary_length: f32,
    normal_deviation_weight: f32,
    roundness_weight: f32,
    straightness_weight: f32,
    normal_seam_weight: f32,
    texture_seam_weight: f32,
    max_cost: f32,
    max_iterations: u32,
    use_input_mesh_uvs: bool,
    fix_winding: bool,
}

#[repr(C)]
struct XPackOptions {
    max_chart_size: u32,
    padding: u32,
    texels_per_unit: f32,
    resolution: u32,
    bilinear: bool,
    block_align: bool,
    brute_force: bool,
    create_image: bool,
    rotate_charts_to_axis: bool,
    rotate_charts: bool,
}

extern "C" {
    fn xatlasCreate() -> *mut XAtlas;
    fn xatlasDestroy(atlas: *mut XAtlas);
    fn xatlasAddMesh(atlas: *mut XAtlas, decl: *const XMeshDecl, mesh_count_hint: u32) -> u32;
    fn xatlasComputeCharts(atlas: *mut XAtlas, options: *const XChartOptions);
    fn xatlasPackCharts(atlas: *mut XAtlas, options: *const XPackOptions);
    fn xatlasMeshDeclInit(decl: *mut XMeshDecl);
    fn xatlasChartOptionsInit(options: *mut XChartOptions);
    fn xatlasPackOptionsInit(options: *mut XPackOptions);
}

/// Destroys the xatlas atlas when dropped.
struct Handle(*mut XAtlas);

impl Drop for Handle {
    fn drop(&mut self) {
        // SAFETY: the pointer came from xatlasCreate and is destroyed once.
        unsafe { xatlasDestroy(self.0) }
    }
}

/// The unwrapped mesh: vertices split along chart seams, in the input's face order.
#[derive(Clone, Debug, PartialEq)]
pub struct Unwrapped {
    /// Input vertex of every output vertex.
    pub xref: Vec<u32>,
    /// Texel-space position of every output vertex (0 to `resolution`; texel `(x, y)` spans
    /// `[x, x + 1) x [y, y + 1)`).
    pub texel_xy: Vec<[f32; 2]>,
    /// Output vertex indices, one triangle per input triangle, same order.
    pub indices: Vec<[u32; 3]>,
    /// Chart of every triangle; [`NO_CHART`] for a triangle xatlas left out (zero area).
    pub chart_of: Vec<u32>,
    pub charts: usize,
    /// Texels per unit of length (the same for every chart, up to each chart's stretch).
    pub texels_per_unit: f64,
    /// Width and height actually used by the packed charts, texels (at most `resolution`).
    pub used: [u32; 2],
}

/// The chart of a triangle xatlas did not place.
pub const NO_CHART: u32 = u32::MAX - 1;

/// Unwraps a triangle mesh with `uvunwrap` (segmentation in a 70-degree normal cone, LSCM +
/// ARAP, shape packing) into one `resolution x resolution` atlas at the highest density that
/// fits, `padding` empty texels around each chart.
pub fn unwrap_uvunwrap(
    positions: &[[f32; 3]],
    indices: &[[u32; 3]],
    resolution: u32,
    padding: u32,
) -> Result<Unwrapped, GeometryError> {
    let bad = |m: String| GeometryError::InvalidArgument(m);
    let flat: Vec<u32> = indices.iter().flatten().copied().collect();
    let input = uvunwrap::MeshInput::new(positions, &flat);
    let opts = uvunwrap::Options {
        padding,
        density: uvunwrap::Density::Auto {
            page_size: resolution,
        },
        ..uvunwrap::Options::default()
    };
    let a = uvunwrap::generate(&[input], &opts).map_err(|e| bad(format!("uvunwrap: {e}")))?;
    if a.page_count != 1 || a.width > resolution || a.height > resolution {
        return Err(bad(format!(
            "uvunwrap: {} charts do not fit one {resolution}x{resolution} atlas with {padding}-texel padding; raise the atlas resolution",
            a.chart_count
        )));
    }
    let m = &a.meshes[0];
    let (w, h) = (a.width as f32, a.height as f32);
    let chart_of = m
        .indices
        .chunks_exact(3)
        .map(|t| {
            t.iter()
                .find_map(|&i| m.vertices[i as usize].chart)
                .unwrap_or(NO_CHART)
        })
        .collect();
    Ok(Unwrapped {
        xref: m.vertices.iter().map(|v| v.xref).collect(),
        texel_xy: m
            .vertices
            .iter()
            .map(|v| [v.uv[0] * w, v.uv[1] * h])
            .collect(),
        indices: m
            .indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
        chart_of,
        charts: a.chart_count as usize,
        texels_per_unit: a.texels_per_unit as f64,
        used: [a.width, a.height],
    })
}

/// Unwraps a triangle mesh with xatlas into one `resolution x resolution` atlas with `padding` empty texels
/// around each chart (plus the texels bilinear lookups need).
pub fn unwrap(
    positions: &[[f32; 3]],
    indices: &[[u32; 3]],
    resolution: u32,
    padding: u32,
) -> Result<Unwrapped, GeometryError> {
    let bad = |m: String| GeometryError::InvalidArgument(m);
    if positions.is_empty() || indices.is_empty() {
        return Err(bad("xatlas: empty mesh".into()));
    }
    let nv = u32::try_from(positions.len()).map_err(|_| bad("xatlas: too many vertices".into()))?;
    let ni = u32::try_from(indices.len() * 3).map_err(|_| bad("xatlas: too many faces".into()))?;
    if let Some(t) = indices.iter().position(|t| t.iter().any(|&i| i >= nv)) {
        return Err(bad(format!(
            "xatlas: triangle {t} indexes a missing vertex"
        )));
    }
    // SAFETY: every pointer handed to xatlas points into a live slice of the declared length
    // and stride; xatlas copies the mesh in AddMesh; output arrays are read within the counts
    // xatlas reports, before the handle (which owns them) is dropped.
    unsafe {
        let h = Handle(xatlasCreate());
        if h.0.is_null() {
            return Err(bad("xatlas: could not create an atlas".into()));
        }
        let mut decl: XMeshDecl = std::mem::zeroed();
        xatlasMeshDeclInit(&mut decl);
        decl.vertex_position_data = positions.as_ptr().cast();
        decl.vertex_count = nv;
        decl.vertex_position_stride = 12;
        decl.index_data = indices.as_ptr().cast();
        decl.index_count = ni;
        decl.index_format = 1;
        let err = xatlasAddMesh(h.0, &decl, 1);
        if err != 0 {
            return Err(bad(format!("xatlas could not add the mesh (error {err})")));
        }
        let mut chart_opts: XChartOptions = std::mem::zeroed();
        xatlasChartOptionsInit(&mut chart_opts);
        xatlasComputeCharts(h.0, &chart_opts);
        let mut pack: XPackOptions = std::mem::zeroed();
        xatlasPackOptionsInit(&mut pack);
        pack.padding = padding;
        pack.resolution = resolution;
        // first pass: xatlas estimates the texel scale for the resolution (one unbounded atlas)
        xatlasPackCharts(h.0, &pack);
        let mut tpu = (*h.0).texels_per_unit;
        let mut fits = false;
        for _ in 0..30 {
            let (w, hgt) = ((*h.0).width, (*h.0).height);
            if (*h.0).atlas_count <= 1 && w <= resolution && hgt <= resolution && w > 0 {
                fits = true;
                break;
            }
            let over = w.max(hgt).max(1) as f32 / resolution as f32;
            tpu *= (0.98 / over).min(0.98);
            if !(tpu.is_finite() && tpu > 0.0) {
                break;
            }
            pack.texels_per_unit = tpu;
            pack.resolution = 0;
            xatlasPackCharts(h.0, &pack);
        }
        let a = &*h.0;
        if !fits || a.mesh_count != 1 {
            return Err(bad(format!(
                "xatlas: {} charts do not fit a {resolution}x{resolution} atlas with {padding}-texel padding; raise the atlas resolution",
                a.chart_count
            )));
        }
        let m = &*a.meshes;
        let verts = std::slice::from_raw_parts(m.vertex_array, m.vertex_count as usize);
        let idx = std::slice::from_raw_parts(m.index_array, m.index_count as usize);
        let charts = std::slice::from_raw_parts(m.chart_array, m.chart_count as usize);
        if idx.len() != indices.len() * 3 {
            return Err(bad(format!(
                "xatlas returned {} indices for {} triangles",
                idx.len(),
                indices.len()
            )));
        }
        let mut chart_of = vec![NO_CHART; indices.len()];
        for (c, ch) in charts.iter().enumerate() {
            for &f in std::slice::from_raw_parts(ch.face_array, ch.face_count as usize) {
                if let Some(slot) = chart_of.get_mut(f as usize) {
                    *slot = c as u32;
                }
            }
        }
        Ok(Unwrapped {
            xref: verts.iter().map(|v| v.xref).collect(),
            texel_xy: verts.iter().map(|v| v.uv).collect(),
            indices: idx.chunks_exact(3).map(|t| [t[0], t[1], t[2]]).collect(),
            chart_of,
            charts: charts.len(),
            texels_per_unit: a.texels_per_unit as f64,
            used: [a.width, a.height],
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube, 12 triangles, 8 shared vertices.
    fn cube() -> (Vec<[f32; 3]>, Vec<[u32; 3]>) {
        let p = (0..8)
            .map(|i| [(i & 1) as f32, ((i >> 1) & 1) as f32, ((i >> 2) & 1) as f32])
            .collect();
        let quads = [
            [0, 2, 3, 1],
            [4, 5, 7, 6],
            [0, 1, 5, 4],
            [2, 6, 7, 3],
            [0, 4, 6, 2],
            [1, 3, 7, 5],
        ];
        let t = quads
            .iter()
            .flat_map(|q| [[q[0], q[1], q[2]], [q[0], q[2], q[3]]])
            .collect();
        (p, t)
    }

    #[test]
    fn cube_unwraps_into_the_atlas_deterministically() {
        let (p, t) = cube();
        let u = unwrap(&p, &t, 64, 2).unwrap();
        assert_eq!(u.indices.len(), 12);
        assert!(u.charts >= 1 && u.charts <= 6, "{} charts", u.charts);
        assert!(u.chart_of.iter().all(|&c| (c as usize) < u.charts));
        assert!(u.used[0] <= 64 && u.used[1] <= 64, "{:?}", u.used);
        for (o, xy) in u.texel_xy.iter().enumerate() {
            assert!((0.0..=64.0).contains(&xy[0]) && (0.0..=64.0).contains(&xy[1]));
            assert!(u.xref[o] < 8);
        }
        // each triangle's texel area over its surface area (1/2) is tpu^2 up to stretch
        for (t, tri) in u.indices.iter().enumerate() {
            let [a, b, c] = tri.map(|i| u.texel_xy[i as usize]);
            let area = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs();
            let want = 0.5 * u.texels_per_unit * u.texels_per_unit;
            assert!(
                (area as f64 / want - 1.0).abs() < 0.05,
                "triangle {t}: {area} texels against {want}"
            );
        }
        assert_eq!(unwrap(&p, &t, 64, 2).unwrap(), u);
    }

    #[test]
    fn cube_unwraps_with_uvunwrap_deterministically() {
        let (p, t) = cube();
        let u = unwrap_uvunwrap(&p, &t, 64, 2).unwrap();
        assert_eq!(u.indices.len(), 12);
        assert!(u.charts >= 1 && u.charts <= 6, "{} charts", u.charts);
        assert!(u.chart_of.iter().all(|&c| (c as usize) < u.charts));
        for (t, tri) in u.indices.iter().enumerate() {
            let [a, b, c] = tri.map(|i| u.texel_xy[i as usize]);
            let area = 0.5 * ((b[0] - a[0]) * (c[1] - a[1]) - (c[0] - a[0]) * (b[1] - a[1])).abs();
            let want = 0.5 * u.texels_per_unit * u.texels_per_unit;
            assert!(
                (area as f64 / want - 1.0).abs() < 0.05,
                "triangle {t}: {area} texels against {want}"
            );
        }
        assert_eq!(unwrap_uvunwrap(&p, &t, 64, 2).unwrap(), u);
    }

    #[test]
    fn bad_index_is_refused() {
        let (p, mut t) = cube();
        t[3][1] = 99;
        let e = unwrap(&p, &t, 64, 2).unwrap_err().to_string();
        assert!(e.contains("triangle 3"), "{e}");
    }
}
