//! # igi-import
//!
//! Photogrammetry models as survey folders: COLMAP sparse models (text and binary), Metashape's
//! camera XML and nerfstudio's `transforms.json` converted to the contract's cameras and aligned
//! to the scan by ground control points; each photo's time and exposure from its EXIF.
//!
//! * [`source`]: what every format becomes ([`CameraSet`]: posed images named as the tool
//!   names its photos) and [`ModelFormat`].
//! * [`metashape`]: Metashape's camera XML ([`read_metashape`]: principal point
//!   `w/2 + cx - 0.5`, `fx = f + b1`, OpenCV's `p1, p2` = Metashape's `P2, P1`; camera,
//!   component and chunk transforms; skew, `k4`, `p3`, `p4` and non-frame sensors refused).
//! * [`nerfstudio`]: `transforms.json` ([`read_nerfstudio`]: OpenGL axes flipped to OpenCV's,
//!   principal point minus 0.5, intrinsics global or per frame, `applied_transform` undone).
//!
//! * [`model`]: the model as read ([`ColmapModel`]: cameras, images, 3D points), COLMAP's
//!   camera models, and the conversion of an image to the contract camera
//!   ([`model::contract_camera`]): SIMPLE_PINHOLE, PINHOLE, SIMPLE_RADIAL, RADIAL, OPENCV and
//!   FULL_OPENCV with k4 = k5 = k6 = 0 convert exactly to OpenCV's (k1, k2, p1, p2, k3); any
//!   other model is refused by name. COLMAP puts the centre of the top-left pixel at
//!   (0.5, 0.5), the contract at (0, 0): the principal point moves by -0.5 px. COLMAP's poses
//!   are world to camera with Hamilton quaternions (w, x, y, z) and OpenCV's camera axes.
//! * [`text`], [`binary`]: the readers (errors name the file and the line, or the byte offset;
//!   counts are checked against the bytes left before anything is allocated) and writers of
//!   `cameras`, `images`, `points3D`.
//! * [`colmap`]: a sparse folder read whole, `.bin` preferred over `.txt`; `rigs` and `frames`
//!   are ignored.
//! * [`align`]: control points triangulated from their observations, the similarity
//!   `x_scan = s R x_model + t` fitted by Umeyama's method in a deterministic RANSAC and
//!   refitted on the inliers, per-point residuals in metres and pixels.
//! * [`icp`]: the optional refinement of the alignment by trimmed ICP of the model's sparse
//!   points against the site mesh (scale included; closest points on the mesh's triangles
//!   found through a kiddo k-d tree of surface samples).
//! * [`survey`]: `igi import colmap` itself ([`import_colmap`], any [`ModelFormat`]):
//!   everything checked (each photo's EXIF read for its `time` and `exposure`), then
//!   `cameras/NAME.json`, `alignment.json` and `survey.toml` written atomically.

pub mod align;
pub mod binary;
pub mod colmap;
mod error;
pub mod icp;
pub mod metashape;
pub mod model;
pub mod nerfstudio;
pub mod source;
pub mod survey;
pub mod text;

pub use align::{AlignOptions, Alignment, Similarity};
pub use binary::write_binary;
pub use colmap::read_model;
pub use error::ImportError;
pub use metashape::read_metashape;
pub use model::ColmapModel;
pub use nerfstudio::read_nerfstudio;
pub use source::{CameraSet, ModelFormat, PosedImage};
pub use survey::{import_colmap, read_cameras, ColmapImport, ImportReport};
pub use text::write_text;

#[cfg(test)]
mod tests;
#[cfg(test)]
mod tests_exif;
#[cfg(test)]
mod tests_formats;
#[cfg(test)]
mod tests_icp;
#[cfg(test)]
mod tests_pycolmap;
