//! One module per subcommand.

pub mod brdf;
pub mod camera;
pub mod cluster;
pub mod compare;
pub mod demo;
pub mod hdr;
pub mod hull;
pub mod import;
pub mod prepare;
pub mod probe;
pub mod render;
pub mod sky;
pub mod slf;
pub mod solve;
pub mod values;
pub mod view;
