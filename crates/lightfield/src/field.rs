//! The surface light field: per grid point (covered atlas texel) a median colour, a normal and
//! a lumisphere coded one of four ways; rendering (per pixel the surface point, the reflected
//! view direction, the lumisphere value plus the median) and editing (the bias function on the
//! output values; a rotated or deformed mesh with the same texture coordinates, whose new
//! normals reflect the view directions).

use crate::lumisphere::{eval_bary, reflect_about_normal, AngleGain, Bary, Octahedron};
use crate::pfa::Pfa;
use crate::quantize::Codebook;
use crate::LightFieldError;
use glam::{Mat3, Vec2, Vec3};
use igi_camera::Camera;
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use igi_raycast::RtScene;
use rayon::prelude::*;

/// How the lumispheres are coded.
#[derive(Clone, Debug)]
pub enum Coding {
    /// Pointwise faired: one lumisphere per point.
    Faired(Vec<Vec<Vec3>>),
    /// Function quantization: a codebook and an index per point.
    Quantized(Codebook),
    /// Principal function analysis: prototypes and barycentric weights per point.
    Pfa(Pfa),
    /// The median (diffuse) texture only.
    MedianOnly,
}

impl Coding {
    pub fn name(&self) -> &'static str {
        match self {
            Coding::Faired(_) => "fair",
            Coding::Quantized(_) => "fq",
            Coding::Pfa(_) => "pfa",
            Coding::MedianOnly => "median",
        }
    }
}

/// A surface light field over the covered texels of a mesh's atlas.
#[derive(Clone, Debug)]
pub struct SurfaceLightField {
    pub oct: Octahedron,
    /// Atlas resolution.
    pub resolution: usize,
    /// Atlas texel index (`row * resolution + column`) of every grid point.
    pub texels: Vec<u32>,
    pub median: Vec<Vec3>,
    pub normal: Vec<Vec3>,
    pub coding: Coding,
    /// The view-angle gain each lumisphere value is multiplied by (at n . w of the view).
    pub gain: AngleGain,
    /// Grid point of every atlas texel (gutters take a neighbouring point; `u32::MAX`: none).
    point_of_texel: Vec<u32>,
}

/// Rendering options.
#[derive(Clone, Copy, Debug)]
pub struct RenderSlfOptions {
    /// Perlin's bias b applied to every output value x / white: x^(ln b / ln 0.5) (0.5 is the identity).
    pub bias: f32,
    /// The value mapped to 1 before the bias.
    pub white: f32,
}

impl Default for RenderSlfOptions {
    fn default() -> Self {
        RenderSlfOptions {
            bias: 0.5,
            white: 1.0,
        }
    }
}

/// Perlin's bias function on [0, 1] (values outside are clamped): b(0.5) = identity.
pub fn bias(b: f32, x: f32) -> f32 {
    let x = if x.is_nan() { 0.0 } else { x.clamp(0.0, 1.0) };
    if (b - 0.5).abs() < 1e-7 {
        return x;
    }
    x.powf(b.clamp(1e-4, 1.0 - 1e-4).ln() / 0.5f32.ln())
}

impl SurfaceLightField {
    pub fn new(
        oct: Octahedron,
        resolution: usize,
        texels: Vec<u32>,
        median: Vec<Vec3>,
        normal: Vec<Vec3>,
        coding: Coding,
    ) -> Self {
        let point_of_texel = texel_map(resolution, &texels);
        SurfaceLightField {
            oct,
            resolution,
            texels,
            median,
            normal,
            coding,
            gain: AngleGain::default(),
            point_of_texel,
        }
    }

    /// The field with this view-angle gain (the one its lumispheres were fitted under).
    pub fn with_gain(mut self, gain: AngleGain) -> Self {
        self.gain = gain;
        self
    }

    /// The lumisphere value (median removed, before the view-angle gain) of point `p` in
    /// reflected direction `r`.
    pub fn lumisphere_value(&self, p: usize, r: Vec3) -> Vec3 {
        self.lumisphere_value_at(p, &self.oct.locate(r))
    }

    /// The lumisphere value (median removed) of point `p` at a located direction `b`.
    fn lumisphere_value_at(&self, p: usize, b: &Bary) -> Vec3 {
        match &self.coding {
            Coding::MedianOnly => Vec3::ZERO,
            Coding::Faired(f) => eval_bary(&f[p], b),
            Coding::Quantized(c) => eval_bary(&c.codewords[c.index[p] as usize], b),
            Coding::Pfa(pfa) => pfa
                .prototypes
                .iter()
                .zip(&pfa.coefficients[p])
                .map(|(pr, a)| eval_bary(pr, b) * *a)
                .sum(),
        }
    }

    /// The outgoing colour at texture coordinate `uv` toward unit direction `w` with surface
    /// normal `n`: the bilinear blend of the four nearest texels' grid points (each its median
    /// plus its lumisphere at the one reflected direction times the view-angle gain at n . w),
    /// over the covered texels among them;
    /// the nearest texel's point (gutters included) where none is covered, `None` where that
    /// has none either.
    pub fn radiance_at(&self, uv: Vec2, w: Vec3, n: Vec3) -> Option<Vec3> {
        let res = self.resolution;
        let (u, v) = igi_geometry::texels::clamp_uv(uv);
        let x = u * res as f32 - 0.5;
        let y = (1.0 - v) * res as f32 - 0.5;
        let (x0, y0) = (x.floor(), y.floor());
        let (fx, fy) = (x - x0, y - y0);
        let b = self.oct.locate(reflect_about_normal(w, n));
        let g = self.gain.at(n.dot(w));
        let (mut sum, mut wsum) = (Vec3::ZERO, 0.0f32);
        for (dy, wy) in [(0, 1.0 - fy), (1, fy)] {
            for (dx, wx) in [(0, 1.0 - fx), (1, fx)] {
                let (tx, ty) = (x0 as i64 + dx, y0 as i64 + dy);
                let wt = wx * wy;
                if wt <= 0.0 || tx < 0 || ty < 0 || tx >= res as i64 || ty >= res as i64 {
                    continue;
                }
                let t = ty as usize * res + tx as usize;
                let p = self.point_of_texel[t];
                // only covered texels (a gutter texel borrows a neighbour's point, which may
                // belong to another chart, elsewhere on the surface)
                if p == u32::MAX || self.texels[p as usize] as usize != t {
                    continue;
                }
                let p = p as usize;
                sum += (self.median[p] + self.lumisphere_value_at(p, &b) * g) * wt;
                wsum += wt;
            }
        }
        if wsum > 0.0 {
            Some((sum / wsum).max(Vec3::ZERO))
        } else {
            self.point_at(uv).map(|p| self.radiance(p, w, n))
        }
    }

    /// The outgoing colour of point `p` toward unit direction `w` with surface normal `n`.
    pub fn radiance(&self, p: usize, w: Vec3, n: Vec3) -> Vec3 {
        let l = self.lumisphere_value(p, reflect_about_normal(w, n));
        (self.median[p] + l * self.gain.at(n.dot(w))).max(Vec3::ZERO)
    }

    /// The grid point at a texture coordinate (nearest texel), if any.
    pub fn point_at(&self, uv: Vec2) -> Option<usize> {
        let r = self.resolution;
        let p = self.point_of_texel[igi_geometry::texels::texel_at(uv, r, r)];
        (p != u32::MAX).then_some(p as usize)
    }

    /// Renders `mesh` (the atlas mesh, or a rotated / deformed copy with the same triangles and
    /// UVs) through `camera`. Returns the colour and the alpha (1 where the mesh is hit). To
    /// render many frames of one mesh, make its [`FieldRenderer`] once.
    pub fn render(
        &self,
        mesh: &TriMesh,
        camera: &Camera,
        opts: &RenderSlfOptions,
    ) -> Result<(HdrImage, Vec<f32>), LightFieldError> {
        Ok(self.renderer(mesh)?.render(camera, opts))
    }

    /// The per-mesh state of rendering: the Embree scene and the unit vertex normals.
    pub fn renderer<'a>(&'a self, mesh: &'a TriMesh) -> Result<FieldRenderer<'a>, LightFieldError> {
        let (uvs, normals) = render_attributes(mesh)?;
        let scene = RtScene::new(&[(mesh.positions.as_slice(), mesh.indices.as_slice())])
            .map_err(LightFieldError::Raycast)?;
        Ok(FieldRenderer {
            field: self,
            mesh,
            uvs,
            normals,
            scene,
        })
    }
}

/// A field ready to render one mesh through any camera (the scene built once).
pub struct FieldRenderer<'a> {
    field: &'a SurfaceLightField,
    mesh: &'a TriMesh,
    uvs: &'a [[f32; 2]],
    normals: Vec<Vec3>,
    scene: RtScene,
}

impl FieldRenderer<'_> {
    /// The colour and the alpha (1 where the mesh is hit, 0 elsewhere) through `camera`; rows
    /// in parallel, each written in place.
    pub fn render(&self, camera: &Camera, opts: &RenderSlfOptions) -> (HdrImage, Vec<f32>) {
        let (w, h) = (camera.width as usize, camera.height as usize);
        let rays = Rays::new(camera);
        let mut img = HdrImage::new(w, h);
        let mut alpha = vec![0.0f32; w * h];
        img.pixels
            .par_chunks_mut(w)
            .zip(alpha.par_chunks_mut(w))
            .enumerate()
            .for_each(|(y, (row, arow))| {
                for (x, (c, a)) in row.iter_mut().zip(arow.iter_mut()).enumerate() {
                    (*c, *a) = self.shade_pixel(rays.ray(x, y), opts);
                }
            });
        (img, alpha)
    }

    /// The colour and alpha of the ray from `o` in unit direction `d`.
    fn shade_pixel(&self, (o, d): (Vec3, Vec3), opts: &RenderSlfOptions) -> ([f32; 3], f32) {
        let Some(hit) = self.scene.intersect(o, d, 0.0, f32::INFINITY) else {
            return ([0.0; 3], 0.0);
        };
        let tri = self.mesh.indices[hit.prim as usize];
        let bw = [1.0 - hit.bary.x - hit.bary.y, hit.bary.x, hit.bary.y];
        let mut uv = Vec2::ZERO;
        let mut n = Vec3::ZERO;
        for k in 0..3 {
            uv += Vec2::from_array(self.uvs[tri[k] as usize]) * bw[k];
            n += self.normals[tri[k] as usize] * bw[k];
        }
        let n = n.normalize_or(hit.ng.normalize_or(Vec3::Z));
        let [a, b, c] = tri.map(|i| Vec3::from_array(self.mesh.positions[i as usize]));
        let face = (b - a).cross(c - a);
        // the face normal turned to the side of the vertex normals (whatever the winding)
        let face = if face.dot(n) < 0.0 { -face } else { face };
        if face.dot(d) > 0.0 {
            // the back of the surface (its inside, through a hole of an open mesh): no view
            // photographed it (the gather keeps only points facing the camera), so it has no
            // light field; it occludes what lies behind and shows black, as an unlit inside does
            return ([0.0; 3], 1.0);
        }
        let Some(c) = self.field.radiance_at(uv, -d, n) else {
            return ([0.0; 3], 1.0);
        };
        let c = if (opts.bias - 0.5).abs() < 1e-7 {
            c
        } else {
            c.to_array()
                .map(|v| opts.white * bias(opts.bias, v / opts.white))
                .into()
        };
        (c.to_array(), 1.0)
    }
}

/// The pixel rays of a camera: without lens distortion, from the camera-to-world rotation and
/// the intrinsics computed once per frame (in f32); with distortion, `Camera::pixel_ray`.
struct Rays<'a> {
    camera: &'a Camera,
    pinhole: Option<(Mat3, Vec3)>,
}

impl<'a> Rays<'a> {
    fn new(camera: &'a Camera) -> Self {
        let c2w = camera.pose.inverse();
        let pinhole = camera
            .intrinsics
            .dist
            .is_zero()
            .then(|| (c2w.r.as_mat3(), c2w.t.as_vec3()));
        Rays { camera, pinhole }
    }

    /// Origin and unit direction of the ray through pixel (x, y).
    fn ray(&self, x: usize, y: usize) -> (Vec3, Vec3) {
        let i = &self.camera.intrinsics;
        match self.pinhole {
            Some((r, o)) => {
                let p = Vec3::new(
                    ((x as f64 - i.cx) / i.fx) as f32,
                    ((y as f64 - i.cy) / i.fy) as f32,
                    1.0,
                );
                (o, (r * p).normalize())
            }
            None => {
                let (o, d) = self.camera.pixel_ray(x as f64, y as f64);
                (o.as_vec3(), d.as_vec3())
            }
        }
    }
}

/// The UVs and unit vertex normals of a mesh to render (normals computed when absent).
fn render_attributes(mesh: &TriMesh) -> Result<(&[[f32; 2]], Vec<Vec3>), LightFieldError> {
    let uvs = mesh.uvs.as_deref().ok_or(LightFieldError::MeshWithoutUvs)?;
    let normals = match &mesh.normals {
        Some(n) => n
            .iter()
            .map(|v| Vec3::from_array(*v).normalize_or(Vec3::Z))
            .collect(),
        None => {
            let mut m = mesh.clone();
            m.compute_vertex_normals();
            m.normals
                .unwrap_or_default()
                .iter()
                .map(|v| Vec3::from_array(*v).normalize_or(Vec3::Z))
                .collect()
        }
    };
    Ok((uvs, normals))
}

/// Grid point per atlas texel, grown four rings into the gutters (first known 4-neighbour).
fn texel_map(res: usize, texels: &[u32]) -> Vec<u32> {
    let mut map = igi_geometry::texels::number_table(res, texels.iter().copied().zip(0..));
    for _ in 0..4 {
        let prev = map.clone();
        for y in 0..res {
            for x in 0..res {
                if prev[y * res + x] != u32::MAX {
                    continue;
                }
                let nb = [
                    (x.wrapping_sub(1), y),
                    (x + 1, y),
                    (x, y.wrapping_sub(1)),
                    (x, y + 1),
                ];
                if let Some(v) = nb
                    .iter()
                    .filter(|(a, b)| *a < res && *b < res)
                    .map(|(a, b)| prev[b * res + a])
                    .find(|v| *v != u32::MAX)
                {
                    map[y * res + x] = v;
                }
            }
        }
    }
    map
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bias_one_half_is_the_identity_and_bias_bends_the_midtones() {
        for x in [0.0, 0.1, 0.5, 0.9, 1.0] {
            assert_eq!(bias(0.5, x), x);
        }
        assert!((bias(0.25, 0.5) - 0.25).abs() < 1e-6, "b(0.5) = b");
        assert!((bias(0.8, 0.5) - 0.8).abs() < 1e-6);
        assert_eq!(bias(0.3, 1.0), 1.0);
        assert_eq!(bias(0.3, -1.0), 0.0);
        assert_eq!(bias(0.3, f32::NAN), 0.0, "never NaN");
    }
}
