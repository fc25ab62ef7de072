//! The integration tests of `igi-lightfield` in one test target (`cargo test -p igi-lightfield --test
//! integration`; one area with `... --test integration AREA::`), so the crate links one test
//! binary instead of one per file.

mod common;
mod editing;
mod glossy_bunny;
mod mitsuba_gloss;
