#!/usr/bin/env bash
# Runs every test of the workspace, with every feature (OpenCV included).
# Installs the system packages it needs first. Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
# compile every target (benches and examples too, in test mode) so none can rot, then run the tests
cargo test --workspace --all-features --all-targets --no-run
cargo test --workspace --all-features
