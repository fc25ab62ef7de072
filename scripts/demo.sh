#!/usr/bin/env bash
# The main job on the embedded default scene. Installs what it needs, builds igi in release
# mode and runs `igi demo`, writing its pictures and report to ./out/demo (or $1).
set -euo pipefail
cd "$(dirname "$0")/.."
bash scripts/deps.sh
cargo build --release --all-features --bin igi
./target/release/igi demo -o "${1:-out/demo}"
