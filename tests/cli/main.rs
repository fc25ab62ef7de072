//! The integration tests of the `igi` binary and of the workflows that need it: one test target
//! (`cargo test -p igi --test cli`), one module per area, so the workspace links one test
//! binary here instead of one per file. Run one area with `cargo test -p igi --test cli
//! cli_solve::`.

mod cli_atlas;
mod cli_brdf;
mod cli_camera_calib;
mod cli_cluster;
mod cli_demo_no_probes;
mod cli_geometry;
mod cli_gltf;
mod cli_harden;
mod cli_hull;
mod cli_imaging;
mod cli_import;
mod cli_photos;
mod cli_probe;
mod cli_radiometry_detect;
mod cli_render;
mod cli_sky;
mod cli_slf;
mod cli_slf_dino;
mod cli_solve;
mod cli_view;
mod mitsuba_export;
mod mitsuba_reference;
mod mitsuba_survey;
