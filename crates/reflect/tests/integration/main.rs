//! The integration tests of `igi-reflect` in one test target (`cargo test -p igi-reflect --test
//! integration`; one area with `... --test integration AREA::`), so the crate links one test
//! binary instead of one per file.

mod pose_refine;
mod prepared;
mod synthetic;
