//! The integration tests of `igi-probe` in one test target (`cargo test -p igi-probe --test
//! integration`; one area with `... --test integration AREA::`), so the crate links one test
//! binary instead of one per file.

mod fiducials;
mod mitsuba_board;
mod real_data;
mod stability;
mod sun_accuracy;
