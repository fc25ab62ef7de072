//! One module per subcommand.

pub mod camera;
pub mod compare;
pub mod demo;
pub mod hdr;
pub mod planned;
pub mod prepare;
pub mod render;
