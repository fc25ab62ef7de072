//! igi-workflow's integration tests, one target (`cargo test -p igi-workflow --test
//! integration AREA::`).

mod probe_survey;
mod radiometry;
mod sunsky;
