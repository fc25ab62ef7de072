//! A photograph loaded into memory: what the solver reads of it (the survey folder that names
//! it is resolved and loaded by `igi-workflow`).

/// A photograph with its camera and the lighting it was taken under.
pub struct Photo {
    pub id: String,
    pub image: igi_imaging::HdrImage,
    pub camera: igi_camera::Camera,
    pub lighting: igi_render::Lighting,
}
