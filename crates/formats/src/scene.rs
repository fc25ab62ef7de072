//! The scene file (`docs/FORMATS.md`, "Scene file"): a lighting file and objects, each a mesh
//! with a diffuse albedo (a constant or a texture) and constant or per-texel Lafortune lobes.
//!
//! ```toml
//! lighting = "lighting/noon.toml"
//!
//! [[object]]
//! mesh = "geometry/wall.ply"
//! albedo = "textures/wall.exr"        # or [r, g, b]
//! lobes = [ { rho = [0.1, 0.1, 0.1], cxy = -0.9, cz = 1.0, n = 30.0 } ]
//! # or, per texel (igi's extension): lobe_maps = [ { rho = "l0_rho.exr", shape = "l0_shape.exr" } ]
//! ```
//! Written by [`TomlFile::write`], nested lists of tables come out as `[[object.lobes]]` and
//! `[[object.lobe_maps]]` sections, which TOML reads as the same lists.

use crate::{FileKind, TomlFile};
use serde::{Deserialize, Serialize};
use std::path::PathBuf;

/// A scene file as written (paths relative to its folder).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
pub struct SceneFile {
    /// The lighting file; none means the renderer must be given lighting.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub lighting: Option<PathBuf>,
    #[serde(default)]
    pub object: Vec<ObjectEntry>,
}

/// `[[object]]`: a mesh and its material.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ObjectEntry {
    /// PLY or OBJ; UVs required when a texture is used.
    pub mesh: PathBuf,
    pub albedo: AlbedoEntry,
    /// Constant Lafortune lobes (ignored where `lobe_maps` is given).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lobes: Vec<LobeEntry>,
    /// Per-texel lobes (an extension of the interchange contract), overriding `lobes`.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub lobe_maps: Vec<LobeMapEntry>,
}

/// A diffuse albedo: a constant `[r, g, b]` or the path of a linear RGB texture.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(
    untagged,
    expecting = "an albedo: three numbers [r, g, b] or the path of a texture image"
)]
pub enum AlbedoEntry {
    Constant([f64; 3]),
    Texture(PathBuf),
}

/// One constant Lafortune lobe: colour `rho`, coefficients `cxy`, `cz`, exponent `n`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct LobeEntry {
    pub rho: [f64; 3],
    pub cxy: f64,
    pub cz: f64,
    pub n: f64,
}

/// One per-texel lobe: `rho` an RGB EXR, `shape` an EXR with (Cxy, Cz, N) in its channels.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LobeMapEntry {
    pub rho: PathBuf,
    pub shape: PathBuf,
}

impl TomlFile for SceneFile {
    const KIND: FileKind = FileKind::Scene;
}

#[cfg(test)]
mod tests {
    use super::*;

    fn textured(mesh: &str, albedo: &str) -> ObjectEntry {
        ObjectEntry {
            mesh: mesh.into(),
            albedo: AlbedoEntry::Texture(albedo.into()),
            lobes: vec![],
            lobe_maps: vec![],
        }
    }

    #[test]
    fn writes_the_export_layout_byte_for_byte() {
        let f = SceneFile {
            lighting: None,
            object: vec![
                textured("ground.ply", "ground_albedo.exr"),
                textured("block.ply", "block_albedo.exr"),
            ],
        };
        let text = f.to_toml(&["Recovered", "second line"]).unwrap();
        assert_eq!(
            text,
            "# Recovered\n# second line\n\n[[object]]\nmesh = \"ground.ply\"\nalbedo = \"ground_albedo.exr\"\n\n[[object]]\nmesh = \"block.ply\"\nalbedo = \"block_albedo.exr\"\n"
        );
    }

    #[test]
    fn lobes_maps_and_constants_round_trip() {
        let f = SceneFile {
            lighting: Some("lighting/noon.toml".into()),
            object: vec![
                ObjectEntry {
                    mesh: "a \"quoted\" name.ply".into(),
                    albedo: AlbedoEntry::Constant([0.3, 0.28, 0.25]),
                    lobes: vec![LobeEntry {
                        rho: [0.1, 0.1, 0.1],
                        cxy: -0.9,
                        cz: 1.0,
                        n: 30.0,
                    }],
                    lobe_maps: vec![],
                },
                ObjectEntry {
                    lobe_maps: vec![LobeMapEntry {
                        rho: "w_lobe0_rho.exr".into(),
                        shape: "w_lobe0_shape.exr".into(),
                    }],
                    ..textured("w.ply", "w.exr")
                },
            ],
        };
        let text = f.to_toml(&[]).unwrap();
        let back: SceneFile = toml::from_str(&text).unwrap();
        assert_eq!(back, f, "{text}");
        assert!(
            text.starts_with("lighting = \"lighting/noon.toml\"\n"),
            "{text}"
        );
    }

    #[test]
    fn the_documented_inline_form_reads_and_bad_albedo_says_what_it_expects() {
        let f: SceneFile = toml::from_str(
            "[[object]]\nmesh = \"m.ply\"\nalbedo = [1, 0.5, 0]\nlobes = [ { rho = [0.1, 0.1, 0.1], cxy = -0.9, cz = 1.0, n = 30 } ]\n",
        )
        .unwrap();
        assert_eq!(f.object[0].albedo, AlbedoEntry::Constant([1.0, 0.5, 0.0]));
        assert_eq!(f.object[0].lobes[0].n, 30.0);
        let e = toml::from_str::<SceneFile>("[[object]]\nmesh = \"m.ply\"\nalbedo = 3\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("three numbers [r, g, b]"), "{e}");
    }
}
