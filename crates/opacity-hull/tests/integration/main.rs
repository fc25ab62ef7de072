//! The integration tests of `igi-opacity-hull` in one test target (`cargo test -p igi-opacity-hull --test
//! integration`; one area with `... --test integration AREA::`), so the crate links one test
//! binary instead of one per file.

mod middlebury;
mod mitsuba_straws;
mod paper_rig;
mod relight;
mod synthetic_matting;
mod thin_parts;
