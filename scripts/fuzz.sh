#!/usr/bin/env bash
# Fuzz every user-fed parser for a fixed number of executions (default 1,000,000 each), one
# target at a time, and print a CSV line of counts per target (docs/RELIABILITY.md).
#
#   scripts/fuzz.sh [EXECUTIONS] [TARGET...]     (targets: ply obj exr hdr camera lighting
#                                                 scene survey board brdf colmap-txt colmap-bin
#                                                 metashape nerfstudio exif control slf hull; default all)
# Crashing, hanging (> 1 s) or memory-hungry (> 2 GiB) inputs are saved in
# target/fuzz-crashes (replay one with `target/release/igi-fuzz TARGET --replay FILE`); the exit status is non-zero when there was any.
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-1000000}
shift || true
TARGETS=${*:-ply obj exr hdr camera lighting scene survey board brdf colmap-txt colmap-bin metashape nerfstudio exif control slf hull}
# the inputs are rewritten once per execution: keep them in memory where there is a tmpfs
WORK=${WORK:-$( [ -d /dev/shm ] && echo /dev/shm/igi-fuzz || echo target/fuzz-work )}
cargo build --release -p igi-fuzz
status=0
for t in $TARGETS; do
  target/release/igi-fuzz "$t" --runs "$RUNS" --seed 1 --work "$WORK" \
    --crashes target/fuzz-crashes | sed -n '2p' || status=1
done
rm -rf "$WORK"
exit $status
