#!/usr/bin/env bash
# Fuzz every user-fed parser for a fixed number of executions (default 1,000,000 each), one
# target at a time, and print a CSV line of counts per target (docs/RELIABILITY.md).
#
#   scripts/fuzz.sh [EXECUTIONS] [TARGET...]     (targets: ply obj exr hdr camera lighting
#                                                 scene survey board brdf; default all)
# Crashing, hanging (> 1 s) or memory-hungry (> 2 GiB) inputs are saved in
# target/fuzz-crashes; the exit status is non-zero when there was any.
set -euo pipefail
cd "$(dirname "$0")/.."
RUNS=${1:-1000000}
shift || true
TARGETS=${*:-ply obj exr hdr camera lighting scene survey board brdf}
cargo build --release -p igi-fuzz
status=0
for t in $TARGETS; do
  target/release/igi-fuzz "$t" --runs "$RUNS" --seed 1 --work target/fuzz-work \
    --crashes target/fuzz-crashes | sed -n '2p' || status=1
done
exit $status
