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
pub mod slf;
pub mod solve;

/// Refuses an output path whose extension (any case) is not `ext`: "PATH: output must be .EXT".
pub fn require_extension(path: &std::path::Path, ext: &str) -> anyhow::Result<()> {
    let found = path.extension().map(|e| e.to_string_lossy().to_lowercase());
    if found.as_deref() != Some(ext) {
        anyhow::bail!("{}: output must be .{ext}", path.display());
    }
    Ok(())
}
