//! A COLMAP sparse folder read whole: `cameras`, `images` and (when present) `points3D`, each
//! from its `.bin` when there is one, else its `.txt`. The `rigs` and `frames` files of current
//! COLMAP are left alone (each image's own pose is all a survey needs).

use std::path::{Path, PathBuf};

use crate::error::ImportError;
use crate::model::ColmapModel;
use crate::{binary, text};

/// `DIR/NAME.bin` if it exists, else `DIR/NAME.txt` if it exists.
fn pick(dir: &Path, name: &str) -> Option<PathBuf> {
    ["bin", "txt"]
        .map(|ext| dir.join(format!("{name}.{ext}")))
        .into_iter()
        .find(|p| p.is_file())
}

fn is_bin(p: &Path) -> bool {
    p.extension().is_some_and(|e| e == "bin")
}

/// The model of a sparse folder and the files it was read from (in the order read).
pub fn read_model(dir: &Path) -> Result<(ColmapModel, Vec<PathBuf>), ImportError> {
    if !dir.is_dir() {
        return Err(ImportError::Input {
            path: dir.to_path_buf(),
            problem: "not a folder (a COLMAP sparse model: cameras, images, points3D)".into(),
        });
    }
    let missing = |what| ImportError::MissingModelFile {
        dir: dir.to_path_buf(),
        what,
    };
    let cams = pick(dir, "cameras").ok_or_else(|| missing("cameras"))?;
    let imgs = pick(dir, "images").ok_or_else(|| missing("images"))?;
    let mut model = ColmapModel {
        cameras: if is_bin(&cams) {
            binary::read_cameras(&cams)?
        } else {
            text::read_cameras(&cams)?
        },
        images: if is_bin(&imgs) {
            binary::read_images(&imgs)?
        } else {
            text::read_images(&imgs)?
        },
        points: Vec::new(),
    };
    let mut read = vec![cams, imgs];
    if let Some(pts) = pick(dir, "points3D") {
        model.points = if is_bin(&pts) {
            binary::read_points(&pts)?
        } else {
            text::read_points(&pts)?
        };
        read.push(pts);
    }
    Ok((model, read))
}
