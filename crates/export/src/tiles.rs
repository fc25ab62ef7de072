//! `igi export --format gltf` of a prepared site (or of a result too large for one GLB): a
//! 3D Tiles 1.1 tileset (docs/EXPORT.md, "3D Tiles").
//!
//! * One GLB per part and level, `NAME_levelL.glb`: the same GLB as the single export's
//!   (the part's node under the root node that turns igi's Z up to glTF's Y up, its albedo as
//!   base colour, its fitted lobes and exact lobes in `extras`), with the mesh of that level.
//!   Level 0 is the full-resolution mesh; the coarser levels are the prepared site's
//!   (`igi prepare --levels`, `voxels/I_J_K/levelL.ply` with the same atlas UVs), when the
//!   result's parts come from one. A result without a prepared site has level 0 only.
//! * `tileset.json`: `asset.version` "1.1"; a root without content whose `transform` is the
//!   identity, whose children are the parts: per part a chain of tiles from its coarsest level
//!   to level 0, each the parent of the next finer one (`refine` "REPLACE"), with the part's
//!   bounding box (`boundingVolume.box`, igi's world frame, metres) and a `geometricError` of
//!   the level's simplification error (`manifest.json`'s `errors`, made non-increasing towards
//!   the leaves), 0 at level 0.
//! * Axes: every 3D Tiles runtime turns glTF content from Y up to Z up
//!   ([`Y_UP_TO_Z_UP`]) before the tile transforms; the GLBs' root node turns igi's Z up to
//!   glTF's Y up, so the two cancel and the tileset's frame is igi's world frame, as the
//!   bounding boxes are given. To place the site on the globe, replace the root's `transform`
//!   by the site's east-north-up to ECEF matrix.

use crate::gltf::{glb_bytes, GlbPart, PartsGltf, GLB_MAX_BYTES};
use crate::lobefit::GltfFit;
use crate::ExportError;
use glam::DVec3;
use igi_geometry::{SiteStore, TriMesh};
use igi_reflect::{Part, SolveResult};
use serde_json::{json, Value};
use std::path::{Path, PathBuf};

/// The tileset's file name.
pub const TILESET: &str = "tileset.json";

/// The matrix (column-major) by which 3D Tiles runtimes turn glTF's Y up into the tileset's
/// Z up: glTF (x, y, z) is tileset (x, -z, y).
pub const Y_UP_TO_Z_UP: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, -1.0, 0.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

/// The root tile's transform: the identity (the tileset's frame is igi's world frame).
pub const ROOT_TRANSFORM: [f64; 16] = [
    1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 0.0, 1.0,
];

/// The smallest half size of a bounding box (metres): flat parts get a box this thick.
pub const MIN_HALF_SIZE: f64 = 1e-3;

/// The file of part `name` at `level`.
pub fn tile_file(name: &str, level: usize) -> String {
    format!("{name}_level{level}.glb")
}

/// Whether `res` exports as 3D Tiles: its parts come from a prepared site, or one GLB of it
/// would pass [`GLB_MAX_BYTES`] ([`single_glb_estimate`]).
pub fn needs_tiles(res: &SolveResult) -> bool {
    res.parts.iter().any(|p| p.part.stored.is_some()) || single_glb_estimate(res) > GLB_MAX_BYTES
}

/// Whether the result folder `result_dir` exports as 3D Tiles ([`needs_tiles`]).
pub fn result_needs_tiles(result_dir: &Path) -> Result<bool, ExportError> {
    Ok(needs_tiles(&SolveResult::load(result_dir)?))
}

/// An estimate of the single GLB's size in bytes: per vertex its position, normal and UV
/// (32 bytes), per triangle 12, per atlas texel 4 (the PNG, at most a little over 3 bytes a
/// texel), plus the JSON.
pub fn single_glb_estimate(res: &SolveResult) -> u64 {
    res.parts
        .iter()
        .map(|p| {
            let r = p.resolution() as u64;
            32 * p.part.mesh.positions.len() as u64
                + 12 * p.part.mesh.indices.len() as u64
                + 4 * r * r
                + 4096
        })
        .sum()
}

/// Writes `bytes` to `path` atomically.
pub fn write_file(path: &Path, bytes: &[u8]) -> Result<(), ExportError> {
    igi_files::write_atomic(path, |tmp| {
        std::fs::write(tmp, bytes)
            .map_err(|e| ExportError::file(path, format!("cannot write: {e}")))
    })
}

/// A result's tileset ([`TILESET`]) and what the export reports.
#[derive(Clone, Debug)]
pub struct ResultTiles {
    /// The tileset JSON (module overview).
    pub tileset: Value,
    /// Per part: its name, the number of lobes fitted and the fit ([`crate::lobefit`]).
    pub materials: Vec<(String, usize, GltfFit)>,
    /// Per part: its standard-error picture (PNG bytes), as for the single GLB.
    pub stderr_png: Vec<Vec<u8>>,
    /// The number of GLBs (tiles with content).
    pub tiles: usize,
}

impl ResultTiles {
    /// Writes `tileset.json` into `out`, atomically.
    pub fn write(&self, out: &Path) -> Result<(), ExportError> {
        let text = serde_json::to_string_pretty(&self.tileset).expect("JSON") + "\n";
        write_file(&out.join(TILESET), text.as_bytes())
    }
}

/// Bounds (min, max) of a mesh's vertices.
fn bounds(mesh: &TriMesh) -> (DVec3, DVec3) {
    mesh.positions.iter().fold(
        (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY)),
        |(lo, hi), p| {
            let p = DVec3::new(p[0] as f64, p[1] as f64, p[2] as f64);
            (lo.min(p), hi.max(p))
        },
    )
}

/// A 3D Tiles `box`: centre, then the half axes along x, y and z (each at least
/// [`MIN_HALF_SIZE`]).
fn bounding_box(lo: DVec3, hi: DVec3) -> Value {
    let (c, h) = if lo.x <= hi.x {
        (
            (lo + hi) / 2.0,
            ((hi - lo) / 2.0).max(DVec3::splat(MIN_HALF_SIZE)),
        )
    } else {
        (DVec3::ZERO, DVec3::splat(MIN_HALF_SIZE))
    };
    json!({ "box": [c.x, c.y, c.z, h.x, 0.0, 0.0, 0.0, h.y, 0.0, 0.0, 0.0, h.z] })
}

/// Builds a result's tileset part by part.
pub(crate) struct TilesetBuilder {
    result_dir: PathBuf,
    store: Option<SiteStore>,
    children: Vec<Value>,
    lo: DVec3,
    hi: DVec3,
    materials: Vec<(String, usize, GltfFit)>,
    stderr_png: Vec<Vec<u8>>,
    tiles: usize,
}

impl TilesetBuilder {
    /// Opens the prepared site of `res`'s parts, if they come from one.
    pub(crate) fn open(res: &SolveResult, result_dir: &Path) -> Result<Self, ExportError> {
        let store = match res.parts.iter().find_map(|p| p.part.stored.as_ref()) {
            Some(s) => Some(SiteStore::open(&s.site)?),
            None => None,
        };
        Ok(TilesetBuilder {
            result_dir: result_dir.to_path_buf(),
            store,
            children: Vec::new(),
            lo: DVec3::splat(f64::INFINITY),
            hi: DVec3::splat(f64::NEG_INFINITY),
            materials: Vec::new(),
            stderr_png: Vec::new(),
            tiles: 0,
        })
    }

    /// The coarser levels (1, 2, ...) of a part from the prepared site, with their
    /// simplification errors; none for a part not from a prepared site.
    fn coarser_levels(&self, part: &Part) -> Result<Vec<(TriMesh, f64)>, ExportError> {
        let (Some(store), Some(s)) = (&self.store, &part.stored) else {
            return Ok(Vec::new());
        };
        let man = store.manifest();
        let entry = match s.voxel {
            Some(v) => man.voxels.iter().find(|e| e.voxel == Some(v)),
            None => man.terrain.as_ref(),
        };
        let Some(entry) = entry else {
            return Err(ExportError::file(
                store.dir(),
                format!("the prepared site has no part {}", part.name),
            ));
        };
        let folder = s.folder(store)?;
        (1..man.levels.len())
            .map(|l| {
                let mesh = igi_geometry::read_ply(&folder.join(format!("level{l}.ply")))?;
                let err = entry.errors.get(l).copied().unwrap_or(0.0);
                Ok((mesh, if err.is_finite() { err.max(0.0) } else { 0.0 }))
            })
            .collect()
    }

    /// The GLBs of `part` (its level 0 as `glb`, its coarser levels from the prepared site)
    /// by file name, and its chain of tiles in the tileset.
    pub(crate) fn add(
        &mut self,
        part: &Part,
        glb: GlbPart,
    ) -> Result<Vec<(String, Vec<u8>)>, ExportError> {
        let coarser = self.coarser_levels(part)?;
        let mut levels: Vec<(&TriMesh, f64)> = vec![(glb.mesh, 0.0)];
        levels.extend(coarser.iter().map(|(m, e)| (m, *e)));
        // the geometric error of a tile: its level's error, never below a finer level's
        let mut errors = Vec::with_capacity(levels.len());
        for (l, (_, e)) in levels.iter().enumerate() {
            errors.push(if l == 0 { 0.0 } else { e.max(errors[l - 1]) });
        }
        let (mut lo, mut hi) = (DVec3::splat(f64::INFINITY), DVec3::splat(f64::NEG_INFINITY));
        for (m, _) in &levels {
            let (a, b) = bounds(m);
            (lo, hi) = (lo.min(a), hi.max(b));
        }
        let bv = bounding_box(lo, hi);
        if lo.x <= hi.x {
            (self.lo, self.hi) = (self.lo.min(lo), self.hi.max(hi));
        }
        let mut files = Vec::with_capacity(levels.len());
        let mut tile: Option<Value> = None;
        for (l, (mesh, _)) in levels.iter().enumerate() {
            let name = tile_file(glb.name, l);
            let one = GlbPart {
                name: glb.name,
                mesh,
                albedo: glb.albedo,
                fit: glb.fit,
                extras: glb.extras.clone(),
            };
            let asset = json!({
                "result": self.result_dir.display().to_string(),
                "axes": "igi world Z up (metres); the root node rotates it to glTF's Y up",
                "texcoord": "v_gltf = 1 - v_igi (igi's atlas origin is the bottom-left)",
                "tile": { "part": glb.name, "level": l, "geometric_error": errors[l] },
            });
            files.push((
                name.clone(),
                glb_bytes(&self.result_dir.join(&name), &[one], asset)?,
            ));
            let mut t = json!({
                "boundingVolume": bv,
                "geometricError": errors[l],
                "refine": "REPLACE",
                "content": { "uri": name },
            });
            if let Some(child) = tile.take() {
                t["children"] = json!([child]);
            }
            tile = Some(t);
        }
        self.tiles += files.len();
        self.children.extend(tile);
        Ok(files)
    }

    /// Keeps the fit and standard-error picture of the part just added.
    pub(crate) fn keep(&mut self, g: PartsGltf) {
        self.materials.extend(g.fits);
        self.stderr_png.extend(g.stderr_png);
    }

    /// The tileset: a root without content over the parts' chains.
    pub(crate) fn finish(self) -> ResultTiles {
        let (lo, hi) = if self.lo.x <= self.hi.x {
            (self.lo, self.hi)
        } else {
            (DVec3::ZERO, DVec3::ZERO)
        };
        // nothing drawn at all is wrong by the site's size
        let top = self
            .children
            .iter()
            .filter_map(|c| c["geometricError"].as_f64())
            .fold((hi - lo).length().max(MIN_HALF_SIZE), f64::max);
        let tileset = json!({
            "asset": {
                "version": "1.1",
                "generator": "igi export",
                "extras": { "igi": {
                    "result": self.result_dir.display().to_string(),
                    "axes": "the tileset's frame is igi's world frame (Z up, metres): the GLBs' root node turns Z up to glTF's Y up and 3D Tiles turns glTF's Y up back to Z up; the root transform is the identity (replace it by the site's east-north-up to ECEF matrix to place it on the globe)",
                    "levels": "per part a chain from its coarsest level to level 0 (the full mesh); geometricError is the level's simplification error in metres",
                }},
            },
            "geometricError": top,
            "root": {
                "transform": ROOT_TRANSFORM,
                "boundingVolume": bounding_box(lo, hi),
                "geometricError": top,
                "refine": "REPLACE",
                "children": self.children,
            },
        });
        ResultTiles {
            tileset,
            materials: self.materials,
            stderr_png: self.stderr_png,
            tiles: self.tiles,
        }
    }
}
