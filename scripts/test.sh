#!/usr/bin/env bash
# Runs every CI gate and every test of the workspace, with every feature (OpenCV included).
# Installs the system packages it needs first. Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh test
# One build from scratch: incremental caches (about 20 GB here) and full debug info (about
# 300 MB a test binary) buy nothing; line tables keep file:line in backtraces.
export CARGO_INCREMENTAL=0
export CARGO_PROFILE_DEV_DEBUG=line-tables-only
export CARGO_PROFILE_TEST_DEBUG=line-tables-only
stage() { echo "== $1 ($(date -u +%H:%M:%S))"; }
stage "format"
cargo fmt --all --check
stage "clippy, every target and feature"
cargo clippy --workspace --all-targets --all-features -- -D warnings
stage "build without default features"
cargo check --workspace --no-default-features
stage "docs"
RUSTDOCFLAGS="-D warnings" cargo doc --workspace --no-deps --all-features
stage "compile every target (benches and examples too, in test mode) so none can rot"
cargo test --workspace --all-features --all-targets --no-run
stage "tests"
cargo test --workspace --all-features
stage "done"
