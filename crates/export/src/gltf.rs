//! `igi export --format gltf`: one binary glTF 2.0 file (`scene.glb`) of a result, with a mesh
//! and a material per part (docs/EXPORT.md, "glTF").
//!
//! * Axes: igi's world is Z up, glTF's Y up. The positions stay in igi's frame; the root node
//!   carries the rotation of -90 degrees about X that takes Z up to Y up (igi (x, y, z) is glTF
//!   (x, z, -y)), so the file's coordinates are the result's.
//! * Texture coordinates: igi's atlas has (0, 0) at the bottom-left (FORMATS.md), glTF's at the
//!   top-left, so `v_gltf = 1 - v`; the image rows are the atlas rows (row 0 at the top).
//! * Base colour: the albedo atlas as an 8-bit sRGB PNG inside the GLB (the linear EXR atlases
//!   are written beside it, as for the other formats).
//! * Lobes: glTF's metallic-roughness BRDF with `KHR_materials_specular` fitted per part
//!   ([`crate::lobefit`]); the exact Lafortune parameters (or the lobe maps' file names) and
//!   the fit's error in the material's `extras.igi`.

use crate::lobefit::GltfFit;
use crate::ExportError;
use igi_brdf::Lobe;
use igi_geometry::TriMesh;
use igi_imaging::HdrImage;
use serde_json::{json, Value};
use std::path::Path;

/// The root node's rotation (x, y, z, w): -90 degrees about X, igi's Z up to glTF's Y up.
pub const Z_UP_TO_Y_UP: [f32; 4] = [
    -std::f32::consts::FRAC_1_SQRT_2,
    0.0,
    0.0,
    std::f32::consts::FRAC_1_SQRT_2,
];

/// The largest GLB a reader must accept (glTF 2.0: lengths are 32-bit; many readers stop at
/// 2 GiB).
pub const GLB_MAX_BYTES: u64 = 1 << 31;

/// One part of the GLB.
pub struct GlbPart<'a> {
    pub name: &'a str,
    pub mesh: &'a TriMesh,
    /// The albedo atlas (linear RGB, row 0 at the top).
    pub albedo: &'a HdrImage,
    /// The part's mean albedo (the base colour the lobe fit assumed).
    pub fit: GltfFit,
    /// What `extras.igi` of the material holds (the exact lobes, file names).
    pub extras: Value,
}

/// What the glTF of some parts of a result needs, in the parts' order: each part's mesh
/// (level 0), textures (the albedo atlas and the lobe maps, colour and shape), fit (its name,
/// the number of lobes fitted, the fit), material extras and standard-error picture (PNG).
#[allow(clippy::type_complexity)]
pub(crate) struct PartsGltf<'a> {
    pub meshes: Vec<std::borrow::Cow<'a, TriMesh>>,
    pub textures: Vec<(HdrImage, Vec<(HdrImage, HdrImage)>)>,
    pub fits: Vec<(String, usize, GltfFit)>,
    pub extras: Vec<Value>,
    pub stderr_png: Vec<Vec<u8>>,
}

impl PartsGltf<'_> {
    /// Part `k` (of those held) as a [`GlbPart`] with its level-0 mesh.
    pub fn as_glb_part(&self, k: usize) -> GlbPart<'_> {
        GlbPart {
            name: &self.fits[k].0,
            mesh: &self.meshes[k],
            albedo: &self.textures[k].0,
            fit: self.fits[k].2,
            extras: self.extras[k].clone(),
        }
    }
}

/// The exact Lafortune lobes as JSON (`extras`).
pub fn lobes_json(lobes: &[Lobe]) -> Value {
    Value::Array(
        lobes
            .iter()
            .map(|l| {
                json!({
                    "rho": l.rho.to_array(), "cxy": l.cxy, "cz": l.cz, "n": l.n,
                    "kind": if l.cxy > 0.0 && l.cz > 0.0 { "retroreflective" } else { "specular" },
                })
            })
            .collect(),
    )
}

/// The albedo atlas as 8-bit sRGB PNG bytes (clipped to [0, 1]; NaN as 0).
pub fn albedo_png(path: &Path, img: &HdrImage) -> Result<Vec<u8>, ExportError> {
    igi_imaging::png_tonemapped(path, img, 1.0)
        .map_err(|e| ExportError::file(path, format!("cannot encode the albedo PNG: {e}")))
}

/// The binary chunk and the JSON lists being built.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Appends `bytes` as a buffer view (4-byte aligned); returns its index.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(4) {
            self.bin.push(0);
        }
        let mut v = json!({"buffer": 0, "byteOffset": self.bin.len(), "byteLength": bytes.len()});
        if let Some(t) = target {
            v["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.views.push(v);
        self.views.len() - 1
    }

    /// A float accessor of `n`-component vectors; with `bounds`, its min and max.
    fn floats(&mut self, data: &[f32], n: usize, kind: &str, bounds: bool) -> usize {
        let bytes: Vec<u8> = data.iter().flat_map(|f| f.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34962));
        let mut a = json!({"bufferView": view, "componentType": 5126, "count": data.len() / n, "type": kind});
        if bounds {
            let mut lo = vec![f32::INFINITY; n];
            let mut hi = vec![f32::NEG_INFINITY; n];
            for c in data.chunks(n) {
                for k in 0..n {
                    lo[k] = lo[k].min(c[k]);
                    hi[k] = hi[k].max(c[k]);
                }
            }
            a["min"] = json!(lo);
            a["max"] = json!(hi);
        }
        self.accessors.push(a);
        self.accessors.len() - 1
    }

    fn indices(&mut self, idx: &[[u32; 3]]) -> usize {
        let bytes: Vec<u8> = idx.iter().flatten().flat_map(|i| i.to_le_bytes()).collect();
        let view = self.view(&bytes, Some(34963));
        self.accessors.push(json!({"bufferView": view, "componentType": 5125, "count": idx.len() * 3, "type": "SCALAR"}));
        self.accessors.len() - 1
    }
}

/// The mesh's unit vertex normals (computed when the mesh has none; a vertex whose normal
/// cannot be normalised gets +Z, igi's up).
fn unit_normals(mesh: &TriMesh) -> Vec<f32> {
    let computed;
    let normals = match &mesh.normals {
        Some(n) if n.len() == mesh.positions.len() => n,
        _ => {
            let mut m = TriMesh {
                positions: mesh.positions.clone(),
                indices: mesh.indices.clone(),
                ..TriMesh::default()
            };
            m.compute_vertex_normals();
            computed = m.normals.unwrap_or_default();
            &computed
        }
    };
    (0..mesh.positions.len())
        .flat_map(|i| {
            let n = normals.get(i).copied().unwrap_or([0.0; 3]);
            let n = glam::Vec3::from(n).normalize_or(glam::Vec3::Z);
            n.to_array()
        })
        .collect()
}

/// The GLB bytes of `parts` (module overview); `path` names the file in errors.
pub fn glb_bytes(
    path: &Path,
    parts: &[GlbPart],
    asset_extras: Value,
) -> Result<Vec<u8>, ExportError> {
    let items: Vec<GlbItem> = parts.iter().map(GlbItem::Part).collect();
    glb_of_items(path, &items, "igi result (Z up to Y up)", asset_extras)
}

/// One node of a GLB: a result's part, an unlit textured mesh (a light field's median
/// radiance), an untextured mesh (a hull's surface) or points (a hull's surfels).
pub enum GlbItem<'a> {
    /// A result's part: its albedo as base colour, its lobes fitted ([`GlbPart`]).
    Part(&'a GlbPart<'a>),
    /// A mesh with atlas UVs whose texture is shown as it is (`KHR_materials_unlit`): a light
    /// field's median radiance, tone-mapped to sRGB.
    Unlit {
        name: &'a str,
        mesh: &'a TriMesh,
        image: &'a HdrImage,
        extras: Value,
    },
    /// A mesh without texture, grey and lit (a hull's surface).
    Plain {
        name: &'a str,
        mesh: &'a TriMesh,
        extras: Value,
    },
    /// Points (`mode` 0) with their colour and opacity (`COLOR_0`, linear RGBA in `[0, 1]`),
    /// drawn unlit (`KHR_materials_unlit`): a hull's surfels.
    Points {
        name: &'a str,
        positions: &'a [[f32; 3]],
        normals: &'a [[f32; 3]],
        colors: &'a [[f32; 4]],
        extras: Value,
    },
}

/// The GLB bytes of `items` under one root node named `root` that turns igi's Z up to glTF's
/// Y up; `path` names the file in errors.
pub fn glb_of_items(
    path: &Path,
    items: &[GlbItem],
    root: &str,
    asset_extras: Value,
) -> Result<Vec<u8>, ExportError> {
    let mut b = Builder::default();
    let (mut meshes, mut materials, mut textures, mut images, mut nodes) =
        (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    let mut children = Vec::new();
    let (mut specular, mut unlit) = (false, false);
    for (i, item) in items.iter().enumerate() {
        let name = match item {
            GlbItem::Part(p) => p.name,
            GlbItem::Unlit { name, .. }
            | GlbItem::Plain { name, .. }
            | GlbItem::Points { name, .. } => name,
        };
        let primitive = match item {
            GlbItem::Points {
                positions,
                normals,
                colors,
                extras,
                ..
            } => {
                let pos: Vec<f32> = positions.iter().flatten().copied().collect();
                let nor: Vec<f32> = normals
                    .iter()
                    .flat_map(|n| glam::Vec3::from(*n).normalize_or(glam::Vec3::Z).to_array())
                    .collect();
                let col: Vec<f32> = colors
                    .iter()
                    .flatten()
                    .map(|c| {
                        if c.is_finite() {
                            c.clamp(0.0, 1.0)
                        } else {
                            0.0
                        }
                    })
                    .collect();
                let a_pos = b.floats(&pos, 3, "VEC3", true);
                let mut attributes =
                    json!({"POSITION": a_pos, "COLOR_0": b.floats(&col, 4, "VEC4", false)});
                if normals.len() == positions.len() {
                    attributes["NORMAL"] = json!(b.floats(&nor, 3, "VEC3", false));
                }
                unlit = true;
                materials.push(json!({
                    "name": name,
                    "pbrMetallicRoughness": {"baseColorFactor": [1.0, 1.0, 1.0, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                    "alphaMode": "BLEND",
                    "extensions": {"KHR_materials_unlit": {}},
                    "extras": {"igi": extras},
                }));
                json!({"attributes": attributes, "material": materials.len() - 1, "mode": 0})
            }
            GlbItem::Part(GlbPart { mesh, .. })
            | GlbItem::Unlit { mesh, .. }
            | GlbItem::Plain { mesh, .. } => {
                let m = *mesh;
                let pos: Vec<f32> = m.positions.iter().flatten().copied().collect();
                let normals = unit_normals(m);
                let a_pos = b.floats(&pos, 3, "VEC3", true);
                let a_nor = b.floats(&normals, 3, "VEC3", false);
                let mut attributes = json!({"POSITION": a_pos, "NORMAL": a_nor});
                let image = match item {
                    GlbItem::Part(p) => Some(p.albedo),
                    GlbItem::Unlit { image, .. } => Some(*image),
                    _ => None,
                };
                if let Some(image) = image {
                    let Some(uvs) = m.uvs.as_ref().filter(|u| u.len() == m.positions.len()) else {
                        return Err(ExportError::file(
                            path,
                            format!("part {name}: its mesh has no atlas UVs"),
                        ));
                    };
                    let uv: Vec<f32> = uvs.iter().flat_map(|t| [t[0], 1.0 - t[1]]).collect();
                    attributes["TEXCOORD_0"] = json!(b.floats(&uv, 2, "VEC2", false));
                    let png = albedo_png(path, image)?;
                    let view = b.view(&png, None);
                    images.push(json!({"bufferView": view, "mimeType": "image/png", "name": format!("{name}_albedo")}));
                    textures.push(json!({"source": images.len() - 1, "sampler": 0}));
                }
                let texture = textures.len().wrapping_sub(1);
                materials.push(match item {
                    GlbItem::Part(p) => {
                        specular = true;
                        let f = &p.fit;
                        json!({
                            "name": name,
                            "doubleSided": true,
                            "pbrMetallicRoughness": {
                                "baseColorTexture": {"index": texture},
                                "metallicFactor": 0.0,
                                "roughnessFactor": f.roughness,
                            },
                            "extensions": {"KHR_materials_specular": {
                                "specularFactor": f.specular,
                                "specularColorFactor": f.specular_color,
                            }},
                            "extras": {"igi": p.extras},
                        })
                    }
                    GlbItem::Unlit { extras, .. } => {
                        unlit = true;
                        json!({
                            "name": name,
                            "doubleSided": true,
                            "pbrMetallicRoughness": {"baseColorTexture": {"index": texture}, "metallicFactor": 0.0, "roughnessFactor": 1.0},
                            "extensions": {"KHR_materials_unlit": {}},
                            "extras": {"igi": extras},
                        })
                    }
                    GlbItem::Plain { extras, .. } => json!({
                        "name": name,
                        "doubleSided": true,
                        "pbrMetallicRoughness": {"baseColorFactor": [0.6, 0.6, 0.6, 1.0], "metallicFactor": 0.0, "roughnessFactor": 1.0},
                        "extras": {"igi": extras},
                    }),
                    GlbItem::Points { .. } => unreachable!("points are handled above"),
                });
                let a_idx = b.indices(&m.indices);
                json!({"attributes": attributes, "indices": a_idx, "material": materials.len() - 1, "mode": 4})
            }
        };
        meshes.push(json!({"name": name, "primitives": [primitive]}));
        nodes.push(json!({"name": name, "mesh": i}));
        children.push(i + 1);
    }
    let mut all_nodes = vec![json!({
        "name": root,
        "rotation": Z_UP_TO_Y_UP,
        "children": children,
    })];
    all_nodes.extend(nodes);
    let used: Vec<&str> = [
        (specular, "KHR_materials_specular"),
        (unlit, "KHR_materials_unlit"),
    ]
    .into_iter()
    .filter_map(|(u, e)| u.then_some(e))
    .collect();
    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    let mut doc = json!({
        "asset": {"version": "2.0", "generator": concat!("igi export ", env!("CARGO_PKG_VERSION")), "extras": {"igi": asset_extras}},
        "extensionsUsed": used,
        "scene": 0,
        "scenes": [{"name": root.split(" (").next().unwrap_or(root), "nodes": [0]}],
        "nodes": all_nodes,
        "meshes": meshes,
        "materials": materials,
        "textures": textures,
        "images": images,
        "samplers": [{"magFilter": 9729, "minFilter": 9729, "wrapS": 33071, "wrapT": 33071}],
        "accessors": b.accessors,
        "bufferViews": b.views,
        "buffers": [{"byteLength": b.bin.len()}],
    });
    if textures.is_empty() {
        for k in ["textures", "images", "samplers"] {
            doc.as_object_mut().map(|o| o.remove(k));
        }
    }
    if used.is_empty() {
        doc.as_object_mut().map(|o| o.remove("extensionsUsed"));
    }
    if items.is_empty() {
        for k in [
            "meshes",
            "materials",
            "textures",
            "images",
            "samplers",
            "accessors",
            "bufferViews",
            "buffers",
        ] {
            doc.as_object_mut().map(|o| o.remove(k));
        }
    }
    let mut js = serde_json::to_vec(&doc)
        .map_err(|e| ExportError::file(path, format!("cannot write the glTF JSON: {e}")))?;
    while !js.len().is_multiple_of(4) {
        js.push(b' ');
    }
    let total = 12
        + 8
        + js.len() as u64
        + if b.bin.is_empty() {
            0
        } else {
            8 + b.bin.len() as u64
        };
    if total > GLB_MAX_BYTES {
        return Err(ExportError::file(
            path,
            format!(
                "the GLB would be {:.2} GiB, more than glTF readers accept (2 GiB); a result this large exports as 3D Tiles (per-part GLBs and tileset.json)",
                total as f64 / (1u64 << 30) as f64
            ),
        ));
    }
    let mut out = Vec::with_capacity(total as usize);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(total as u32).to_le_bytes());
    out.extend_from_slice(&(js.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&js);
    if !b.bin.is_empty() {
        out.extend_from_slice(&(b.bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(&b.bin);
    }
    Ok(out)
}
