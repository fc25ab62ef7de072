#!/usr/bin/env bash
# The main job on the embedded default scene. Installs only what the demo needs (Embree 3, a
# font), builds igi in release mode without optional features and runs `igi demo`, writing its
# pictures and report to ./out/demo (or $1).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh demo
cargo build --release --bin igi
./target/release/igi demo -o "${1:-out/demo}"
