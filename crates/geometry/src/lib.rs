//! `igi-geometry`: meshes and the multiresolution site store of the igi toolkit.
//!
//! - [`TriMesh`], the indexed triangle mesh every crate shares, with [`read_mesh`] (PLY ASCII
//!   and binary of either byte order, OBJ), [`write_ply`] (binary little endian) and
//!   [`write_obj`]; writes are atomic (temp file + rename).
//! - [`points`]: [`PointCloud`] (points or surfels: normal, colour, radius, named scalar
//!   properties) with PLY I/O for vertex-only files.
//! - [`marching`]: marching cubes from a scalar grid to a [`TriMesh`].
//! - [`procedural`]: the embedded default site (terrain, steps, columns, wall, architrave) at any
//!   tessellation density.
//! - [`repair`]: degenerate and duplicate triangles removed, non-manifold edges counted.
//! - [`voxel`]: the voxel lattice and the exact clipping of a mesh into voxels (neighbouring
//!   voxels share bit-identical boundary vertices).
//! - [`atlas`]: per-voxel texture atlases (projected charts, shelf packing) and the world
//!   position / normal texel caches.
//! - [`unwrap`]: automatic UV unwrapping by the vendored xatlas (segmented, parameterised,
//!   packed charts for scans and hull meshes), used by `atlas::build_atlas_with`.
//! - [`texels`]: the covered texels of an atlas (texel centres on the surface) and the
//!   dilation of texel values into neighbours (hole filling, gutters).
//! - [`levels`]: multiresolution levels by meshoptimizer edge collapse with the voxel faces locked.
//! - [`stream`]: a site mesh read in chunks and binned into per-voxel spill files on disk, for
//!   [`store::prepare_streamed`] (`igi prepare`), whose memory follows the voxel, not the site.
//! - [`store`]: `prepare` writes a site folder; [`store::SiteStore`] loads "this voxel high,
//!   neighbours medium, the rest low".
//! - [`job`]: `igi prepare` and `igi info` as one call each, from a request of paths and
//!   options.
//!
//! Conventions: world Z up, metres; UVs as in OBJ ((0,0) bottom-left, v up); colours linear RGB
//! in [0, 1].

pub mod atlas;
mod atomic;
pub mod error;
pub mod job;
pub mod levels;
pub mod marching;
pub mod mesh;
pub mod obj;
pub mod ply;
pub mod points;
pub mod procedural;
pub mod repair;
pub mod store;
pub mod stream;
pub mod texels;
pub mod unwrap;
pub mod voxel;

pub use error::{GeometryError, MeshInvariant};
pub use marching::{marching_cubes, Grid};
pub use mesh::TriMesh;
pub use obj::{read_obj, write_obj};
pub use ply::{read_ply, write_ply};
pub use points::{read_points_ply, write_points_ply, PointCloud};
pub use store::{
    check_prepare_output, prepare, prepare_run, prepare_streamed, Manifest, PrepareOptions,
    PrepareRun, SiteStore,
};
pub use stream::SiteSpill;
pub use voxel::{VoxelGrid, VoxelId, VoxelLimit};

use std::path::Path;

/// Read a `.ply` or `.obj` mesh (chosen by extension, case-insensitive) and validate it.
pub fn read_mesh(path: &Path) -> Result<TriMesh, GeometryError> {
    match path
        .extension()
        .and_then(|e| e.to_str())
        .map(str::to_ascii_lowercase)
        .as_deref()
    {
        Some("ply") => read_ply(path),
        Some("obj") => read_obj(path),
        _ => Err(GeometryError::UnknownFormat {
            path: path.to_path_buf(),
        }),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn unknown_extension_is_refused_by_name() {
        let e = read_mesh(Path::new("/tmp/site.stl"))
            .unwrap_err()
            .to_string();
        assert!(
            e.contains("site.stl") && e.contains("unknown mesh format"),
            "{e}"
        );
    }

    #[test]
    fn missing_file_names_the_file() {
        let e = read_mesh(Path::new("/nonexistent/x.ply"))
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/x.ply"), "{e}");
    }
}
