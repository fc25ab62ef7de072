#!/usr/bin/env bash
# The procedural colonnade site (igi_geometry::procedural::colonnade_site) as binary PLY:
# OUT/site.ply (stylobate, columns, wall, architrave) and OUT/terrain.ply; with GRID > 1 a
# GRID x GRID field of colonnades 20 m apart on one terrain (igi_geometry::procedural::colonnade_field).
# Triangles grow as DETAIL^2 GRID^2: 1 -> 5.4 thousand, 75 -> 27.2 million (20.7 M site + 6.5 M
# terrain); DETAIL 25 GRID 3 -> 23.6 million over 80 x 80 m (20.7 M site + 2.9 M terrain; the
# prepare scale test, docs/BENCHMARKS.md); DETAIL 31 GRID 5 -> 98.9 million (88.9 M site, the
# paper's 89 M, + 10.0 M terrain; the streaming prepare test of issue 37, 2.6 GB of PLY).
# usage: datasets/gen_site.sh OUT [DETAIL] [SEED] [GRID]
set -euo pipefail
cd "$(dirname "$0")/.."
cargo run --release -q -p igi-geometry --example gen_site -- "${1:?usage: gen_site.sh OUT [DETAIL] [SEED] [GRID]}" "${2:-1}" "${3:-1}" "${4:-1}"
