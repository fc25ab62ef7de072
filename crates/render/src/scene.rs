//! Renderable scene: triangle meshes with materials, the Embree accelerator, and the scene
//! built from a parsed scene file (`igi_formats::scene`, FORMATS.md "Scene file (TOML)").
//!
//! Materials are Lafortune BRDFs: a diffuse albedo (constant or a texture) plus constant lobes
//! per object. Texture lookup rule: FORMATS.md UV convention (texel row i, column j centred at
//! ((j + 0.5) / W, 1 - (i + 0.5) / H)), **bilinear with clamp-to-edge** (UVs outside [0, 1] are
//! clamped, and the outer half texel repeats the edge texel).
//!
//! Shading normal: interpolated vertex normals when the mesh has them (flipped to the side of
//! the geometric normal), else the geometric normal. The geometric normal offsets ray origins.
//! Zero-area (or non-finite) triangles are dropped at load and counted.

use crate::lighting::Lighting;
use crate::{MeshProblem, RenderError};
use glam::{DVec3, Vec2, Vec3};
use igi_brdf::{LafortuneRef, Lobe};
use igi_formats::scene::{AlbedoEntry, LobeMapEntry, ObjectEntry, SceneFile};
use igi_formats::TomlFile;
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use igi_raycast::{Hit, RtScene};
use std::path::{Path, PathBuf};

/// An RGB texture for per-texel parameters (linear values).
#[derive(Clone, Debug)]
pub struct Texture {
    pub width: usize,
    pub height: usize,
    /// Row-major, row 0 at the top (v = 1).
    pub texels: Vec<Vec3>,
}

impl Texture {
    pub fn from_image(img: &HdrImage) -> Self {
        Texture {
            width: img.width,
            height: img.height,
            texels: img.pixels.iter().map(|p| Vec3::from_array(*p)).collect(),
        }
    }

    /// Bilinear lookup with clamp-to-edge, FORMATS.md UV convention.
    #[inline]
    pub fn lookup(&self, uv: Vec2) -> Vec3 {
        let (w, h) = (self.width, self.height);
        let (u, v) = igi_geometry::texels::clamp_uv(uv);
        let x = (u * w as f32 - 0.5).clamp(0.0, (w - 1) as f32);
        let y = ((1.0 - v) * h as f32 - 0.5).clamp(0.0, (h - 1) as f32);
        // x, y >= 0 after the clamp: truncation is floor (and without SSE4.1, floor() is a
        // libm call, 1 % of a solve's profile)
        let (x0, y0) = (x as usize, y as usize);
        let (x1, y1) = ((x0 + 1).min(w - 1), (y0 + 1).min(h - 1));
        let (fx, fy) = (x - x0 as f32, y - y0 as f32);
        let t = |r: usize, c: usize| self.texels[r * w + c];
        let top = t(y0, x0) * (1.0 - fx) + t(y0, x1) * fx;
        let bot = t(y1, x0) * (1.0 - fx) + t(y1, x1) * fx;
        top * (1.0 - fy) + bot * fy
    }
}

/// Diffuse albedo of an object.
#[derive(Clone, Debug)]
pub enum Albedo {
    Constant(Vec3),
    Texture(Texture),
}

/// Per-texel Lafortune lobes: `per_texel` lobes for every texel of a `width x height` map (the
/// texel layout of FORMATS.md textures), looked up at the nearest texel (lobe exponents do not
/// interpolate meaningfully).
#[derive(Clone, Debug, PartialEq)]
pub struct LobeMap {
    pub width: usize,
    pub height: usize,
    pub per_texel: usize,
    /// Texel-major: the lobes of texel `row * width + column` are
    /// `lobes[texel * per_texel..(texel + 1) * per_texel]`.
    pub lobes: Vec<Lobe>,
}

impl LobeMap {
    /// The lobes of the texel nearest `uv`.
    #[inline]
    pub fn at(&self, uv: Vec2) -> &[Lobe] {
        let i = igi_geometry::texels::texel_at(uv, self.width, self.height) * self.per_texel;
        &self.lobes[i..i + self.per_texel]
    }

    /// Reads the maps of a scene file's `lobe_maps`: per lobe a `rho` EXR (RGB) and a `shape`
    /// EXR (Cxy, Cz, N in its three channels), all of one size.
    pub fn from_images(maps: &[(HdrImage, HdrImage)]) -> Result<LobeMap, LobeMapError> {
        let Some((first, _)) = maps.first() else {
            return Err(LobeMapError::NoMaps);
        };
        let (w, h) = (first.width, first.height);
        if w == 0 || h == 0 {
            return Err(LobeMapError::Empty);
        }
        for (k, (rho, shape)) in maps.iter().enumerate() {
            for im in [rho, shape] {
                if im.width != w || im.height != h {
                    return Err(LobeMapError::Size {
                        lobe: k,
                        size: (im.width, im.height),
                        first: (w, h),
                    });
                }
            }
        }
        let k = maps.len();
        let mut lobes = Vec::with_capacity(w * h * k);
        for i in 0..w * h {
            for (li, (rho, shape)) in maps.iter().enumerate() {
                let [cxy, cz, n] = shape.pixels[i];
                let lobe = Lobe {
                    rho: Vec3::from_array(rho.pixels[i]),
                    cxy,
                    cz,
                    n,
                };
                if !lobe.is_valid() {
                    return Err(LobeMapError::Texel {
                        lobe: li,
                        texel: i,
                        value: lobe,
                    });
                }
                lobes.push(lobe);
            }
        }
        Ok(LobeMap {
            width: w,
            height: h,
            per_texel: k,
            lobes,
        })
    }

    /// The maps for [`from_images`](Self::from_images): per lobe `(rho, shape)`.
    pub fn to_images(&self) -> Vec<(HdrImage, HdrImage)> {
        (0..self.per_texel)
            .map(|li| {
                let (mut rho, mut shape) = (
                    HdrImage::new(self.width, self.height),
                    HdrImage::new(self.width, self.height),
                );
                for i in 0..self.width * self.height {
                    let l = &self.lobes[i * self.per_texel + li];
                    rho.pixels[i] = l.rho.to_array();
                    shape.pixels[i] = [l.cxy, l.cz, l.n];
                }
                (rho, shape)
            })
            .collect()
    }
}

/// Why per-texel lobe maps cannot be used.
#[derive(Debug, thiserror::Error)]
pub enum LobeMapError {
    #[error("no lobe maps")]
    NoMaps,
    #[error("empty lobe map")]
    Empty,
    #[error("lobe {lobe}: map is {}x{}, the first is {}x{}", size.0, size.1, first.0, first.1)]
    Size {
        lobe: usize,
        size: (usize, usize),
        first: (usize, usize),
    },
    #[error("lobe {lobe}: texel {texel} has invalid parameters (rho {}, cxy {}, cz {}, n {})", value.rho, value.cxy, value.cz, value.n)]
    Texel {
        lobe: usize,
        texel: usize,
        value: Lobe,
    },
}

/// Material of an object: Lafortune with per-texel (or constant) `rho_d` and constant or
/// per-texel lobes.
#[derive(Clone, Debug)]
pub struct Material {
    pub albedo: Albedo,
    /// Lobes everywhere on the object (ignored where `lobe_map` is given).
    pub lobes: Vec<Lobe>,
    /// Per-texel lobes (as the solver infers them from each texel's `rho_d`).
    pub lobe_map: Option<LobeMap>,
}

impl Material {
    pub fn lambertian(rho_d: Vec3) -> Self {
        Material {
            albedo: Albedo::Constant(rho_d),
            lobes: Vec::new(),
            lobe_map: None,
        }
    }

    /// The BRDF at texture coordinate `uv`.
    #[inline]
    pub fn brdf_at(&self, uv: Vec2) -> LafortuneRef<'_> {
        let rho_d = match &self.albedo {
            Albedo::Constant(c) => *c,
            Albedo::Texture(t) => t.lookup(uv),
        };
        let lobes = match &self.lobe_map {
            Some(m) => m.at(uv),
            None => &self.lobes,
        };
        LafortuneRef { rho_d, lobes }
    }
}

/// One object: a mesh (degenerate triangles removed) and its material.
#[derive(Clone, Debug)]
pub struct Object {
    pub name: String,
    pub positions: Vec<Vec3>,
    pub normals: Option<Vec<Vec3>>,
    pub uvs: Option<Vec<Vec2>>,
    /// Kept triangles; Embree's primitive id indexes this list.
    pub triangles: Vec<[u32; 3]>,
    pub material: Material,
}

impl Object {
    /// The object `name` of a scene: `mesh` checked against `material`, its zero-area and
    /// non-finite triangles dropped (their number returned beside it), its normals unit length.
    fn from_mesh(
        name: String,
        mesh: &TriMesh,
        material: Material,
    ) -> Result<(Object, usize), RenderError> {
        check_mesh(&name, mesh, &material)?;
        let positions: Vec<Vec3> = mesh
            .positions
            .iter()
            .map(|p| Vec3::from_array(*p))
            .collect();
        let (triangles, skipped) = kept_triangles(&name, &mesh.indices, &positions)?;
        let normals = mesh.normals.as_ref().map(|n| {
            n.iter()
                .map(|v| unit_or_zero(Vec3::from_array(*v)))
                .collect()
        });
        let uvs = mesh
            .uvs
            .as_ref()
            .map(|t| t.iter().map(|v| Vec2::from_array(*v)).collect());
        let object = Object {
            name,
            positions,
            normals,
            uvs,
            triangles,
            material,
        };
        Ok((object, skipped))
    }
}

/// Per-vertex attributes must match the vertex count; a texture needs UVs.
fn check_mesh(name: &str, mesh: &TriMesh, material: &Material) -> Result<(), RenderError> {
    let nv = mesh.positions.len();
    if let Some(n) = &mesh.normals {
        if n.len() != nv {
            let problem = MeshProblem::Normals {
                normals: n.len(),
                vertices: nv,
            };
            return Err(mesh_error(name, problem));
        }
    }
    if let Some(t) = &mesh.uvs {
        if t.len() != nv {
            let problem = MeshProblem::Uvs {
                uvs: t.len(),
                vertices: nv,
            };
            return Err(mesh_error(name, problem));
        }
    }
    if matches!(material.albedo, Albedo::Texture(_)) && mesh.uvs.is_none() {
        return Err(mesh_error(name, MeshProblem::TextureWithoutUvs));
    }
    Ok(())
}

/// The triangles with finite corners and non-zero area, and how many others were dropped; an
/// index out of range is an error.
fn kept_triangles(
    name: &str,
    indices: &[[u32; 3]],
    positions: &[Vec3],
) -> Result<(Vec<[u32; 3]>, usize), RenderError> {
    let nv = positions.len();
    let mut triangles = Vec::with_capacity(indices.len());
    let mut skipped = 0;
    for (k, tri) in indices.iter().enumerate() {
        if tri.iter().any(|&i| i as usize >= nv) {
            let problem = MeshProblem::IndexOutOfRange {
                triangle: k,
                indices: *tri,
                vertices: nv,
            };
            return Err(mesh_error(name, problem));
        }
        let [a, b, c] = tri.map(|i| positions[i as usize]);
        let cross = (b - a).cross(c - a);
        if !(a.is_finite() && b.is_finite() && c.is_finite())
            || !(cross.length_squared() > 0.0)
            || !cross.is_finite()
        {
            skipped += 1;
            continue;
        }
        triangles.push(*tri);
    }
    Ok((triangles, skipped))
}

/// `v` normalised, or zero when it is zero or not finite.
fn unit_or_zero(v: Vec3) -> Vec3 {
    if v.is_finite() && v.length_squared() > 0.0 {
        v.normalize()
    } else {
        Vec3::ZERO
    }
}

/// A point on a surface of the scene, as the queries of the solver take it.
#[derive(Clone, Copy, Debug)]
pub struct SurfacePoint {
    pub position: Vec3,
    /// Unit geometric normal (winding order: (v1 - v0) x (v2 - v0)).
    pub ng: Vec3,
    /// Unit shading normal, on the same side as `ng`.
    pub ns: Vec3,
    /// Texture coordinates (0 when the mesh has none).
    pub uv: Vec2,
    /// Object index.
    pub object: u32,
    /// Triangle index within the object's kept triangles.
    pub prim: u32,
}

/// Triangle meshes with materials and the Embree accelerator.
pub struct Scene {
    pub objects: Vec<Object>,
    rt: RtScene,
    /// Number of zero-area or non-finite triangles dropped at load.
    pub skipped_triangles: usize,
}

impl Scene {
    /// Builds a scene from meshes and materials. Triangles with zero area or non-finite
    /// corners are dropped (counted in `skipped_triangles`); indices out of range are an error.
    pub fn new(objects: Vec<(String, TriMesh, Material)>) -> Result<Self, RenderError> {
        let mut out = Vec::with_capacity(objects.len());
        let mut skipped = 0usize;
        for (name, mesh, material) in objects {
            let (object, dropped) = Object::from_mesh(name, &mesh, material)?;
            skipped += dropped;
            out.push(object);
        }
        let pos_arrays: Vec<Vec<[f32; 3]>> = out
            .iter()
            .map(|o| o.positions.iter().map(|p| p.to_array()).collect())
            .collect();
        let meshes: Vec<(&[[f32; 3]], &[[u32; 3]])> = out
            .iter()
            .zip(&pos_arrays)
            .map(|(o, p)| (p.as_slice(), o.triangles.as_slice()))
            .collect();
        let rt = RtScene::new(&meshes)?;
        if skipped > 0 {
            tracing::info!("skipped {skipped} degenerate triangles");
        }
        Ok(Scene {
            objects: out,
            rt,
            skipped_triangles: skipped,
        })
    }

    /// The Embree accelerator (for benchmarks and low-level queries).
    pub fn rt(&self) -> &RtScene {
        &self.rt
    }

    /// Total number of kept triangles.
    pub fn triangle_count(&self) -> usize {
        self.objects.iter().map(|o| o.triangles.len()).sum()
    }

    /// Closest surface hit along a ray.
    #[inline]
    pub fn intersect(&self, origin: Vec3, dir: Vec3) -> Option<Hit> {
        self.rt.intersect(origin, dir, 0.0, f32::INFINITY)
    }

    /// Whether the segment `origin + t dir`, t in (0, tfar), is blocked.
    #[inline]
    pub fn occluded(&self, origin: Vec3, dir: Vec3, tfar: f32) -> bool {
        self.rt.occluded(origin, dir, 0.0, tfar)
    }

    /// The surface at a point `p` that should lie on it: what a ray from `p + n reach` back
    /// along `-n` meets within `2 reach`, else the same from the other side (`n` a unit normal
    /// there, either orientation).
    pub fn surface_near(&self, p: Vec3, n: Vec3, reach: f32) -> Option<SurfacePoint> {
        [n, -n].into_iter().find_map(|d| {
            let h = self.intersect(p + d * reach, -d)?;
            (h.t <= 2.0 * reach).then(|| self.surface_point(&h))
        })
    }

    /// The surface point of a hit.
    #[inline]
    pub fn surface_point(&self, hit: &Hit) -> SurfacePoint {
        self.point_on(hit.geom, hit.prim, hit.bary)
    }

    /// The surface point at barycentrics `bary` (b1, b2) of triangle `prim` of object `object`.
    #[inline]
    pub fn point_on(&self, object: u32, prim: u32, bary: Vec2) -> SurfacePoint {
        let o = &self.objects[object as usize];
        let [i0, i1, i2] = o.triangles[prim as usize].map(|i| i as usize);
        let (b1, b2) = (bary.x, bary.y);
        let b0 = 1.0 - b1 - b2;
        let (p0, p1, p2) = (o.positions[i0], o.positions[i1], o.positions[i2]);
        let position = p0 * b0 + p1 * b1 + p2 * b2;
        let ng = (p1 - p0).cross(p2 - p0).normalize();
        let ns = match &o.normals {
            Some(n) => {
                let s = n[i0] * b0 + n[i1] * b1 + n[i2] * b2;
                if s.length_squared() > 1e-12 {
                    let s = s.normalize();
                    if s.dot(ng) < 0.0 {
                        -s
                    } else {
                        s
                    }
                } else {
                    ng
                }
            }
            None => ng,
        };
        let uv = match &o.uvs {
            Some(t) => t[i0] * b0 + t[i1] * b1 + t[i2] * b2,
            None => Vec2::ZERO,
        };
        SurfacePoint {
            position,
            ng,
            ns,
            uv,
            object,
            prim,
        }
    }

    /// The first surface point along a ray, if any (for the solver: where a texel's ray lands).
    pub fn trace_point(&self, origin: Vec3, dir: Vec3) -> Option<SurfacePoint> {
        self.intersect(origin, dir.normalize())
            .map(|h| self.surface_point(&h))
    }

    /// Loads a scene file and the lighting file it names. Relative paths are relative to the
    /// scene file's folder.
    pub fn load(path: &Path) -> Result<(Scene, Lighting), RenderError> {
        if path.is_dir() {
            return Err(RenderError::File {
                path: path.to_path_buf(),
                msg: "is a directory, not a scene file (re-lighting a solve result is not supported yet)".into(),
            });
        }
        Self::from_file(&SceneFile::read(path)?, path)
    }

    /// Builds the scene (and its lighting) a parsed scene file describes: reads the meshes,
    /// textures, lobe maps and lighting file it names, relative to the folder of `path` (the
    /// file it came from, which errors name), and checks every value.
    pub fn from_file(f: &SceneFile, path: &Path) -> Result<(Scene, Lighting), RenderError> {
        let dir = path.parent().unwrap_or(Path::new("."));
        let lighting = match &f.lighting {
            Some(l) => Lighting::load(&dir.join(l))?,
            None => Lighting::default(),
        };
        if f.object.is_empty() {
            return Err(RenderError::File {
                path: path.to_path_buf(),
                msg: "no [[object]] in the scene".into(),
            });
        }
        let objects = f
            .object
            .iter()
            .enumerate()
            .map(|(k, o)| load_object(path, k, o))
            .collect::<Result<Vec<_>, _>>()?;
        let scene = Scene::new(objects).map_err(|e| RenderError::Scene {
            path: path.to_path_buf(),
            source: Box::new(e),
        })?;
        Ok((scene, lighting))
    }
}

/// Object `k` of scene file `path`: its mesh and material, read and checked.
fn load_object(
    path: &Path,
    k: usize,
    o: &ObjectEntry,
) -> Result<(String, TriMesh, Material), RenderError> {
    let ctx = ObjectContext { path, k };
    let mesh_path = ctx.dir().join(&o.mesh);
    let mesh = igi_geometry::read_mesh(&mesh_path)
        .map_err(|e| ctx.in_object(format!("mesh {}", mesh_path.display()), e.into()))?;
    let albedo = ctx.albedo(&o.albedo)?;
    let lobes: Vec<Lobe> = o
        .lobes
        .iter()
        .map(|l| Lobe {
            rho: DVec3::from_array(l.rho).as_vec3(),
            cxy: l.cxy as f32,
            cz: l.cz as f32,
            n: l.n as f32,
        })
        .collect();
    if let Some((li, l)) = lobes.iter().enumerate().find(|(_, l)| !l.is_valid()) {
        return Err(ctx.file_err(format!("lobe {li} {l:?} has invalid parameters")));
    }
    check_energy(&ctx, &albedo, &lobes)?;
    let lobe_map = ctx.lobe_map(&o.lobe_maps)?;
    let material = Material {
        albedo,
        lobes,
        lobe_map,
    };
    Ok((mesh_path.display().to_string(), mesh, material))
}

/// The brightest texel of `img` (its index and largest channel).
fn brightest_texel(img: &HdrImage) -> (usize, f32) {
    let top = |p: &[f32; 3]| p.iter().copied().fold(0.0f32, f32::max);
    img.pixels
        .iter()
        .enumerate()
        .map(|(i, p)| (i, top(p)))
        .fold((0, 0.0), |a, b| if b.1 > a.1 { b } else { a })
}

/// Refuses an object whose constant lobes, beside its largest diffuse albedo, reflect more
/// light than they receive at some view angle (the directional albedo of the Lafortune BRDF
/// above 1 in a channel, with [`igi_brdf::Lafortune::is_energy_conserving`]'s 1 % for its
/// estimate). Per-texel lobe maps are the solver's, inferred from each texel's albedo.
fn check_energy(ctx: &ObjectContext, albedo: &Albedo, lobes: &[Lobe]) -> Result<(), RenderError> {
    if lobes.is_empty() {
        return Ok(());
    }
    let rho_d = match albedo {
        Albedo::Constant(c) => *c,
        Albedo::Texture(t) => t.texels.iter().fold(Vec3::ZERO, |a, &b| a.max(b)),
    };
    let brdf = igi_brdf::Lafortune {
        rho_d,
        lobes: lobes.to_vec(),
    };
    if brdf.is_energy_conserving() {
        return Ok(());
    }
    let a = brdf.max_albedo();
    Err(ctx.file_err(format!(
        "its lobes with its albedo reflect up to {:.3} {:.3} {:.3} (r, g, b) of the light they receive at some view angle: more than 1 (lower the lobes' rho, or the albedo)",
        a.x, a.y, a.z
    )))
}

/// Object `k` of scene file `path`, for reading what it names and for its errors.
struct ObjectContext<'p> {
    path: &'p Path,
    k: usize,
}

impl ObjectContext<'_> {
    /// The folder relative paths start from.
    fn dir(&self) -> &Path {
        self.path.parent().unwrap_or(Path::new("."))
    }

    /// A file the object names could not be read (`what` names it).
    fn in_object(
        &self,
        what: String,
        source: Box<dyn std::error::Error + Send + Sync>,
    ) -> RenderError {
        RenderError::in_file(self.path, format!("object {}: {what}", self.k), source)
    }

    /// A value of the object is unusable.
    fn file_err(&self, msg: String) -> RenderError {
        RenderError::File {
            path: self.path.to_path_buf(),
            msg: format!("object {}: {msg}", self.k),
        }
    }

    /// The albedo: a constant (finite, in [0, 1]) or a texture read and checked texel by texel.
    fn albedo(&self, entry: &AlbedoEntry) -> Result<Albedo, RenderError> {
        match entry {
            AlbedoEntry::Constant(c) => {
                let c = DVec3::from_array(*c).as_vec3();
                if !c.is_finite() || c.min_element() < 0.0 {
                    return Err(self.file_err(format!("albedo {c:?} must be finite and >= 0")));
                }
                if c.max_element() > 1.0 {
                    return Err(self.file_err(format!(
                        "albedo {c:?} must be at most 1 in each channel (a diffuse surface cannot reflect more light than it receives)"
                    )));
                }
                Ok(Albedo::Constant(c))
            }
            AlbedoEntry::Texture(t) => {
                let tp = self.dir().join(t);
                let img = igi_imaging::read_image(&tp).map_err(|e| {
                    self.in_object(format!("albedo texture {}", tp.display()), e.into())
                })?;
                if img
                    .pixels
                    .iter()
                    .any(|p| p.iter().any(|c| !c.is_finite() || *c < 0.0))
                {
                    return Err(self.file_err(format!(
                        "albedo texture {} has negative or non-finite texels",
                        tp.display()
                    )));
                }
                let (i, top) = brightest_texel(&img);
                if top > 1.0 {
                    return Err(self.file_err(format!(
                        "albedo texture {} has texels above 1 (the largest, {top}, at column {} row {}): a diffuse albedo is at most 1 in each channel (a linear texture; was it saved as radiance, or scaled?)",
                        tp.display(),
                        i % img.width,
                        i / img.width
                    )));
                }
                Ok(Albedo::Texture(Texture::from_image(&img)))
            }
        }
    }

    /// The per-texel lobes of the object's `lobe_maps`, if it has any.
    fn lobe_map(&self, maps: &[LobeMapEntry]) -> Result<Option<LobeMap>, RenderError> {
        if maps.is_empty() {
            return Ok(None);
        }
        let mut imgs = Vec::new();
        for (li, m) in maps.iter().enumerate() {
            let read = |p: &PathBuf| {
                let full = self.dir().join(p);
                igi_imaging::read_image(&full).map_err(|e| {
                    self.in_object(format!("lobe map {li} {}", full.display()), e.into())
                })
            };
            imgs.push((read(&m.rho)?, read(&m.shape)?));
        }
        LobeMap::from_images(&imgs)
            .map(Some)
            .map_err(|e| RenderError::in_file(self.path, format!("object {}", self.k), e.into()))
    }
}

fn mesh_error(object: &str, problem: MeshProblem) -> RenderError {
    RenderError::Mesh {
        object: object.to_string(),
        problem,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::integrator_tests::quad;

    /// Each unusable mesh is refused with a typed error naming the object.
    #[test]
    fn unusable_meshes_name_the_object_and_the_problem() {
        let grey = || Material::lambertian(Vec3::splat(0.5));
        let err = |mesh: TriMesh, material: Material| match Scene::new(vec![(
            "wall".into(),
            mesh,
            material,
        )]) {
            Err(e @ RenderError::Mesh { .. }) => e.to_string(),
            Err(e) => panic!("not a mesh error: {e}"),
            Ok(_) => panic!("accepted"),
        };
        let mut m = quad(0.0, 1.0);
        m.normals = Some(vec![[0.0, 0.0, 1.0]]);
        assert_eq!(err(m, grey()), "wall: 1 normals for 4 vertices");
        let mut m = quad(0.0, 1.0);
        m.uvs = Some(vec![[0.0, 0.0]; 3]);
        assert_eq!(err(m, grey()), "wall: 3 UVs for 4 vertices");
        let texture = Material {
            albedo: Albedo::Texture(Texture::from_image(&igi_imaging::HdrImage::new(2, 2))),
            lobes: vec![],
            lobe_map: None,
        };
        let mut m = quad(0.0, 1.0);
        m.uvs = None;
        assert_eq!(
            err(m, texture),
            "wall: an albedo texture needs UVs, and the mesh has none"
        );
        let mut m = quad(0.0, 1.0);
        m.indices[1] = [0, 2, 9];
        assert_eq!(
            err(m, grey()),
            "wall: triangle 1 has vertex index [0, 2, 9] out of range (4 vertices)"
        );
    }

    #[test]
    fn texture_lookup_follows_formats_uv_convention() {
        // 2 x 2 texture: top row (v = 1) red, green; bottom row blue, white.
        let t = Texture {
            width: 2,
            height: 2,
            texels: vec![Vec3::X, Vec3::Y, Vec3::Z, Vec3::ONE],
        };
        // Texel (row 0, col 0) centre: (0.25, 0.75).
        assert!(t.lookup(Vec2::new(0.25, 0.75)).abs_diff_eq(Vec3::X, 1e-6));
        assert!(t.lookup(Vec2::new(0.75, 0.75)).abs_diff_eq(Vec3::Y, 1e-6));
        assert!(t.lookup(Vec2::new(0.25, 0.25)).abs_diff_eq(Vec3::Z, 1e-6));
        // Clamp to edge: the corner and beyond repeat the corner texel.
        assert!(t.lookup(Vec2::new(0.0, 1.0)).abs_diff_eq(Vec3::X, 1e-6));
        assert!(t.lookup(Vec2::new(-3.0, 7.0)).abs_diff_eq(Vec3::X, 1e-6));
        // Centre: average of all four.
        assert!(t
            .lookup(Vec2::new(0.5, 0.5))
            .abs_diff_eq(Vec3::new(0.5, 0.5, 0.5), 1e-6));
        assert!(t.lookup(Vec2::new(f32::NAN, 0.5)).is_finite());
    }

    #[test]
    fn lobe_maps_look_up_the_nearest_texel_and_round_trip_through_images() {
        let lobe = |n: f32| Lobe {
            rho: Vec3::new(0.1, 0.2, 0.3) * n,
            cxy: -1.0,
            cz: 1.0,
            n,
        };
        // 2x2 texels, two lobes each; texel (row i, column j) gets exponents 10 (2i + j) + 1, + 2
        let lobes: Vec<Lobe> = (0..4)
            .flat_map(|t| [lobe(10.0 * t as f32 + 1.0), lobe(10.0 * t as f32 + 2.0)])
            .collect();
        let m = LobeMap {
            width: 2,
            height: 2,
            per_texel: 2,
            lobes,
        };
        // u right, v up: (0.25, 0.75) is row 0 column 0; (0.75, 0.25) is row 1 column 1
        assert_eq!(m.at(Vec2::new(0.25, 0.75))[0].n, 1.0);
        assert_eq!(m.at(Vec2::new(0.75, 0.75))[1].n, 12.0);
        assert_eq!(m.at(Vec2::new(0.75, 0.25))[0].n, 31.0);
        assert_eq!(m.at(Vec2::new(2.0, -1.0))[0].n, 31.0, "clamped");
        let back = LobeMap::from_images(&m.to_images()).unwrap();
        assert_eq!(back, m);
        let mut imgs = m.to_images();
        imgs[1].1 = HdrImage::new(3, 2);
        assert!(LobeMap::from_images(&imgs)
            .unwrap_err()
            .to_string()
            .contains("3x2"));
        let mut imgs = m.to_images();
        imgs[0].1.pixels[0][2] = -1.0;
        assert!(LobeMap::from_images(&imgs)
            .unwrap_err()
            .to_string()
            .contains("invalid"));
        let material = Material {
            albedo: Albedo::Constant(Vec3::splat(0.5)),
            lobes: vec![lobe(99.0)],
            lobe_map: Some(m),
        };
        assert_eq!(
            material.brdf_at(Vec2::new(0.75, 0.25)).lobes[1].n,
            32.0,
            "the map overrides constant lobes"
        );
    }

    #[test]
    fn degenerate_and_duplicate_triangles_are_handled() {
        let mut m = quad(0.0, 1.0);
        m.positions.push([5.0, 5.0, 0.0]);
        m.positions.push([f32::NAN, 0.0, 0.0]);
        m.uvs.as_mut().unwrap().extend([[0.0, 0.0], [0.0, 0.0]]);
        m.indices.push([0, 0, 1]); // repeated vertex
        m.indices.push([0, 1, 4]); // a valid triangle that uses the extra vertex: kept
        m.indices.push([1, 2, 5]); // NaN corner
        m.indices.push([0, 1, 2]); // duplicate
        let s = Scene::new(vec![(
            "m".into(),
            m,
            Material::lambertian(Vec3::splat(0.5)),
        )])
        .unwrap();
        assert_eq!(s.skipped_triangles, 2);
        assert_eq!(s.triangle_count(), 4);
        let h = s.intersect(Vec3::new(0.3, 0.2, 1.0), -Vec3::Z).unwrap();
        let sp = s.surface_point(&h);
        assert!(sp.position.abs_diff_eq(Vec3::new(0.3, 0.2, 0.0), 1e-5));
        assert!(sp.ng.abs_diff_eq(Vec3::Z, 1e-6) && sp.ns.abs_diff_eq(Vec3::Z, 1e-6));
        assert!(sp.uv.abs_diff_eq(Vec2::new(0.65, 0.6), 1e-5));
        // Index out of range is a clear error.
        let mut bad = quad(0.0, 1.0);
        bad.indices.push([0, 1, 9]);
        let e = Scene::new(vec![(
            "bad.ply".into(),
            bad,
            Material::lambertian(Vec3::ONE),
        )])
        .err()
        .unwrap()
        .to_string();
        assert!(e.contains("bad.ply") && e.contains("out of range"), "{e}");
    }

    #[test]
    fn interpolated_shading_normals_face_the_geometric_side() {
        let mut m = quad(0.0, 1.0);
        let tilt = Vec3::new(0.3, 0.0, -1.0).normalize(); // points below: must be flipped
        m.normals = Some(vec![tilt.to_array(); 4]);
        let s = Scene::new(vec![("m".into(), m, Material::lambertian(Vec3::ONE))]).unwrap();
        let sp = s.trace_point(Vec3::new(0.0, 0.0, 1.0), -Vec3::Z).unwrap();
        assert!(sp.ns.abs_diff_eq(-tilt, 1e-6), "{:?}", sp.ns);
    }

    #[test]
    fn scene_file_loads_with_relative_paths_and_reports_errors() {
        let dir = tempfile::tempdir().unwrap();
        std::fs::create_dir_all(dir.path().join("geometry")).unwrap();
        std::fs::create_dir_all(dir.path().join("lighting")).unwrap();
        igi_geometry::write_ply(&dir.path().join("geometry/ground.ply"), &quad(0.0, 2.0)).unwrap();
        let mut tex = HdrImage::new(2, 2);
        tex.set(0, 0, [0.9, 0.1, 0.1]);
        igi_imaging::write_exr(&dir.path().join("geometry/tex.exr"), &tex).unwrap();
        std::fs::write(
            dir.path().join("lighting/noon.toml"),
            "[sun]\ndirection = [0, 0, 1]\nradiance = [1000, 1000, 1000]\n",
        )
        .unwrap();
        let p = dir.path().join("scene.toml");
        std::fs::write(
            &p,
            r#"lighting = "lighting/noon.toml"
[[object]]
mesh = "geometry/ground.ply"
albedo = [0.2, 0.3, 0.4]
[[object]]
mesh = "geometry/ground.ply"
albedo = "geometry/tex.exr"
lobes = [ { rho = [0.1, 0.1, 0.1], cxy = -0.9, cz = 1.0, n = 30.0 } ]
"#,
        )
        .unwrap();
        let (s, l) = Scene::load(&p).unwrap();
        assert_eq!(s.objects.len(), 2);
        assert!(l.sun.is_some() && l.environment.is_none());
        assert!(
            matches!(s.objects[0].material.albedo, Albedo::Constant(c) if c == Vec3::new(0.2, 0.3, 0.4))
        );
        assert_eq!(s.objects[1].material.lobes.len(), 1);
        assert_eq!(s.objects[1].material.lobes[0].n, 30.0);
        match &s.objects[1].material.albedo {
            Albedo::Texture(t) => assert!(t
                .lookup(Vec2::new(0.0, 1.0))
                .abs_diff_eq(Vec3::new(0.9, 0.1, 0.1), 1e-6)),
            _ => panic!("expected a texture"),
        }
        // Errors name the scene file and the problem.
        std::fs::write(
            &p,
            "[[object]]\nmesh = \"geometry/none.ply\"\nalbedo = [1, 1, 1]\n",
        )
        .unwrap();
        let e = Scene::load(&p).err().unwrap().to_string();
        assert!(e.contains("scene.toml") && e.contains("none.ply"), "{e}");
        std::fs::write(
            &p,
            "[[object]]\nmesh = \"geometry/ground.ply\"\nalbedo = [1, -1, 1]\n",
        )
        .unwrap();
        let e = Scene::load(&p).err().unwrap().to_string();
        assert!(e.contains("scene.toml") && e.contains("albedo"), "{e}");
        // issue 36 item 7: albedo 5 reflects five times the light it receives
        std::fs::write(
            &p,
            "[[object]]\nmesh = \"geometry/ground.ply\"\nalbedo = [5, 0.5, 0.5]\n",
        )
        .unwrap();
        let e = Scene::load(&p).err().unwrap().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("object ") && e.contains("at most 1"),
            "{e}"
        );
        // a texture that holds radiance, or was scaled: 1.5 at column 1, row 0
        tex.set(1, 0, [0.2, 1.5, 0.2]);
        igi_imaging::write_exr(&dir.path().join("geometry/hot.exr"), &tex).unwrap();
        std::fs::write(
            &p,
            "[[object]]\nmesh = \"geometry/ground.ply\"\nalbedo = \"geometry/hot.exr\"\n",
        )
        .unwrap();
        let e = Scene::load(&p).err().unwrap().to_string();
        assert!(
            e.contains("hot.exr") && e.contains("above 1") && e.contains("1.5, at column 1 row 0"),
            "{e}"
        );
        // lobes that reflect more than they receive: a Lambertian 0.5 and a mirror-like lobe of
        // rho 5 and n 10 (its directional albedo about rho * 2 pi / (n + 2), 2.6 near normal)
        let lobes = |rho: f64| {
            format!(
                "[[object]]\nmesh = \"geometry/ground.ply\"\nalbedo = [0.5, 0.5, 0.5]\nlobes = [ {{ rho = [{rho}, {rho}, {rho}], cxy = -1.0, cz = 1.0, n = 10.0 }} ]\n"
            )
        };
        std::fs::write(&p, lobes(5.0)).unwrap();
        let e = Scene::load(&p).err().unwrap().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("object 0") && e.contains("more than 1"),
            "{e}"
        );
        std::fs::write(&p, lobes(0.2)).unwrap();
        assert!(Scene::load(&p).is_ok(), "a conserving lobe loads");
        std::fs::write(&p, "lighting = 3\n").unwrap();
        let e = Scene::load(&p).err().unwrap().to_string();
        assert!(
            e.contains("scene.toml") && e.contains("not a valid scene file"),
            "{e}"
        );
        let e = Scene::load(dir.path()).err().unwrap().to_string();
        assert!(e.contains("not a scene file"), "{e}");
    }
}
