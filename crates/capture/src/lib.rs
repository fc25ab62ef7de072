//! # igi-capture
//!
//! The photogrammetry of photographed rigs: a calibrated camera looks at a planar target with
//! fiducials and at spheres whose surfaces reflect the light to be measured. Two recipes are
//! built on it: the lighting-capture board (igi-probe: mirror, black and diffuse spheres, Debevec
//! et al. 2004, section 3.3) and the hand-held BRDF sample frame ([`sample_frame`], section 3.2.1).
//!
//! * [`fiducial`]: planar fiducial targets: the pose from user-marked points (pure Rust,
//!   [`igi_camera::planar`]) or from ArUco markers matched by id (OpenCV through
//!   [`igi_camera::cv`], feature `opencv`).
//! * [`sphere`]: a sphere seen by a calibrated camera: ray-sphere intersection, the mirror
//!   reflection, the surface point that reflects a given direction (Newton's method, exact for a
//!   camera at finite distance), the outline and the pixels the sphere covers.
//! * [`highlight`]: a bright source's highlight on a glossy sphere to sub-pixel precision (the
//!   frame's lamp: blob centroid; the board's sun: window centroid then [`spot`] fit).
//! * [`spot`]: a point's spot blurred by a Gaussian lens and integrated over square pixels,
//!   fitted by least squares.
//! * [`sample_frame`]: the sample-frame recipe: from one photograph, the camera pose, the light
//!   position and intensity, an orthographic view of the sample and [`igi_brdf::BrdfSample`]s.
//! * [`refine`]: a camera's pose refined by matching the model's edges to a photograph's.
//! * [`job`]: the jobs of `igi camera refine` ([`job::refine_file`]) and `igi brdf measure`
//!   ([`job::measure_files`]), each one call from a request of paths and options.
//!
//! Conventions: OpenCV cameras (`igi_camera::Camera`), world frame of the rig's own target
//! (the sample frame: z up out of its plane), double precision geometry, linear radiance.

mod error;
pub mod fiducial;
pub mod highlight;
pub mod job;
pub mod refine;
pub mod sample_frame;
pub mod sphere;
pub mod spot;

pub use error::{CaptureError, SphereError};
pub use sample_frame::{measure_photo, MeasureOptions, PhotoMeasurement, PoseInput, SampleFrame};
pub use sphere::{BoardSphere, SphereKind, SphereView};
