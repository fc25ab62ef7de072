#!/usr/bin/env bash
# Kill -9 `igi prepare` and `igi solve` at random moments, resume each to the end, and check
# that the result is byte-identical to an uninterrupted run and that no temporary file is left.
#
#   scripts/kill9.sh [KILLS]        (default 20 kills per command; IGI=path/to/igi, SEED=n,
#                                    KINDS="prepare solve"; copy the binary first if you may
#                                    rebuild it meanwhile: a run must not change binaries)
#
# prepare: the bunny (res2) from ../shared/data in 2 cm voxels, 64-texel atlases; every file
# of the site folder is compared. solve: the survey fixture (3 iterations, tolerance 0); every
# atlas, mesh, scene.toml and run.json is compared, and report.json with its wall-clock fields
# removed (convergence.png plots error against run time, so it is left out).
# Each trial kills one run 1 to 3 times at random moments (uniform over the uninterrupted run
# time), then resumes it to the end; a kill counts only when it hit a running process.
set -euo pipefail
cd "$(dirname "$0")/.."
KILLS=${1:-20}
IGI=${IGI:-target/debug/igi}
SEED=${SEED:-1}
RANDOM=$SEED
MESH=${MESH:-../shared/data/meshes/stanford_bunny/reconstruction/bun_zipper_res2.ply}
SURVEY=datasets/fixtures/survey
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# each runs igi by `exec`, always inside a subshell `( ... )`, so that the pid of a background
# run is igi's own and SIGKILL reaches igi (killing a shell function's subshell would leave igi
# running on, and the next run would then write the same folder beside it)
prepare() { exec "$IGI" -q prepare "$MESH" --voxel 0.02 --atlas 64 -o "$1" >/dev/null; }
solve() { exec "$IGI" -q solve "$SURVEY" --atlas 32 --spp 4,8 --iterations 3 --tolerance 0 --indirect 1 -o "$1" >/dev/null; }

# seconds (float) of an uninterrupted run
timed() {
  local t0 t1
  t0=$(date +%s.%N); ( "$@" ) 2>/dev/null; t1=$(date +%s.%N)
  python3 -c "print($t1 - $t0)"
}

normalise_report() {
  python3 - "$1" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
for it in r.get("iterations", []):
    it.pop("wall_s", None); it.pop("cumulative_s", None)
print(json.dumps(r, sort_keys=True))
EOF
}

compare() { # kind ref out
  local kind=$1 ref=$2 out=$3
  if [ "$kind" = prepare ]; then
    diff -r "$ref" "$out" >/dev/null || { echo "DIFFERENT: $out"; diff -rq "$ref" "$out" | head; return 1; }
  else
    diff -r -x report.json -x convergence.png "$ref" "$out" >/dev/null || { echo "DIFFERENT: $out"; diff -rq -x report.json -x convergence.png "$ref" "$out" | head; return 1; }
    [ "$(normalise_report "$ref/report.json")" = "$(normalise_report "$out/report.json")" ] || { echo "DIFFERENT report: $out"; return 1; }
  fi
  local left
  left=$(find "$out" -name '.*.tmp*' | wc -l)
  [ "$left" -eq 0 ] || { echo "TEMP FILES LEFT in $out:"; find "$out" -name '.*.tmp*'; return 1; }
}

for kind in ${KINDS:-prepare solve}; do
  ref="$work/$kind-ref"
  secs=$(timed $kind "$ref")
  echo "$kind: uninterrupted run $secs s"
  kills=0; trials=0
  while [ "$kills" -lt "$KILLS" ]; do
    trials=$((trials + 1))
    out="$work/$kind-$trials"
    for _ in $(seq 1 $((1 + RANDOM % 3))); do
      delay=$(python3 -c "import random; random.seed($RANDOM); print(round(random.uniform(0.02, $secs), 3))")
      ( $kind "$out" ) 2>/dev/null &
      pid=$!
      sleep "$delay"
      if kill -0 "$pid" 2>/dev/null; then
        kill -9 "$pid" 2>/dev/null && kills=$((kills + 1))
      fi
      wait "$pid" 2>/dev/null || true
    done
    ( $kind "$out" ) 2>/dev/null || { echo "resume of $out failed"; exit 1; }
    compare "$kind" "$ref" "$out"
    rm -rf "$out"
  done
  echo "$kind: $kills kills in $trials trials, every resume byte-identical, no temp file left"
done
