#!/usr/bin/env bash
# Runs every test of the workspace, with every feature (OpenCV included).
# Installs the system packages it needs first. Usage: bash scripts/test.sh
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
cargo build --workspace --all-features --all-targets
cargo test --workspace --all-features
