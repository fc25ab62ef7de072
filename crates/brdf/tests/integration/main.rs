//! The integration tests of `igi-brdf` in one test target (`cargo test -p igi-brdf --test
//! integration`; one area with `... --test integration AREA::`), so the crate links one test
//! binary instead of one per file.

mod mitsuba_fixtures;
mod sparse_generalise;
