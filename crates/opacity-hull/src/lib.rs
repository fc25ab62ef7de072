//! # igi-opacity-hull
//!
//! The turntable 3D-photography pipeline of Matusik et al. 2002, *Image-Based 3D Photography
//! using Opacity Hulls*, on the shared camera, HDR, rig and mesh code of `igi-imaging` and
//! `igi-geometry` (it never depends on the solver):
//!
//! * [`backdrop`]: the Eq. 1 backdrop patterns and alpha by Eq. 2 (maximum over lambda; pixels
//!   where the backdrop pair carries no signal are invalid).
//! * [`views`]: a rig's views loaded with their mattes and carving silhouettes (alpha > 0.05;
//!   invalid and out-of-frame pixels unknown).
//! * [`carve`]: octree carving of a cell grid over the bounding box.
//! * [`contour`]: where the hull's surface lies between a kept and a carved cell centre: the
//!   signed distance to the mattes' alpha-0.5 contours.
//! * [`hull`]: the visual hull (carving + marching cubes), reprojection IoU, leave-one-out,
//!   volume against the number of views (Fig. 12).
//! * [`raster`]: triangle rasterisation into a camera (coverage and depth).
//! * [`surfel`]: surfels on the hull's vertices, their radii by the vertices' spacing, with
//!   per-view visibility and opacity.
//! * [`render`]: unstructured-lumigraph weights (Eq. 4) and order-independent surfel splatting
//!   to RGBA.
//! * [`reflectance`]: the surface reflectance field: light images kept in the 8 x 8 blocks the
//!   surfels project into, PCA per block across the lights under a global RMS budget, Eq. 3
//!   relighting on the coefficients, the `reflectance/` store.
//! * [`lightweights`]: each light's weight under a lighting file, the environment integrated
//!   over its Voronoi cell of directions plus the sun.
//! * [`build`]: the `igi hull build` pipeline, the hull folder, loading it for rendering (with
//!   the photos, or relit).
//! * [`job`]: `igi hull build` and `igi hull render` as one call each, from a request of paths
//!   and options.
//! * [`warp`]: the nearest input photo warped to a new camera through the hull (the baseline a
//!   new view must beat).
//! * [`middlebury`]: importer for the Middlebury multi-view sets.

mod error;

pub mod backdrop;
pub mod build;
pub mod carve;
pub mod contour;
pub mod hull;
pub mod job;
pub mod lightweights;
pub mod middlebury;
pub mod raster;
pub mod reflectance;
pub mod render;
pub mod surfel;
pub mod views;
pub mod warp;

pub use error::HullError;
