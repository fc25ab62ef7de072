//! The integration tests of `igi-capture` in one test target (`cargo test -p igi-capture --test
//! integration`; one area with `... --test integration AREA::`), so the crate links one test
//! binary instead of one per file.

mod sample_frame;
mod sample_frame_aruco;
