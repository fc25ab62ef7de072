#!/usr/bin/env bash
# The procedural colonnade site (igi_geometry::procedural::colonnade_site) as binary PLY:
# OUT/site.ply (stylobate, columns, wall, architrave) and OUT/terrain.ply.
# Triangles grow as DETAIL^2: 1 -> 5.4 thousand, 75 -> 27.2 million (20.7 M site + 6.5 M terrain;
# the prepare scale test).
# usage: datasets/gen_site.sh OUT [DETAIL] [SEED]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo run --release -q -p igi-geometry --example gen_site -- "${1:?usage: gen_site.sh OUT [DETAIL] [SEED]}" "${2:-1}" "${3:-1}"
