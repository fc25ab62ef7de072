#!/usr/bin/env bash
# Kill -9 `igi prepare`, `igi solve`, `igi hull build`, `igi slf build` and `igi render` at
# random moments, run each again to the end, and check that the result is byte-identical to an
# uninterrupted run and that no temporary file, staging folder or lock file is left.
#
#   scripts/kill9.sh [KILLS]        (default 20 kills per command; IGI=path/to/igi, SEED=n,
#                                    KINDS="prepare solve hull slf render"; copy the binary
#                                    first if you may rebuild it meanwhile: a run must not
#                                    change binaries)
#
# prepare: the bunny (res2) from ../shared/data in 2 cm voxels, 64-texel atlases; every file
# of the site folder is compared. solve: the survey fixture (3 iterations, tolerance 0); every
# atlas, mesh, scene.toml and run.json is compared, and report.json with its wall-clock fields
# removed (convergence.png plots error against run time, so it is left out).
# hull: the Middlebury dino (../shared/data/multiview/dinoSparseRing, imported once) built at
# 256 cells; slf: the same rig on the hull's mesh (1 % of its triangles), 256-texel atlas; both are written whole
# under a staging name and renamed, so a rerun starts afresh: every file is compared, and no
# `.OUT.partial-*` or `.OUT.igi-lock` may be left beside the output. render: the outdoor
# fixture at 16 spp; the image (and its --stderr) compared, no temporary file left beside it.
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
DINO=${DINO:-../shared/data/multiview/dinoSparseRing}
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
KINDS=${KINDS:-prepare solve hull slf render}
case " $KINDS " in
  *" hull "*|*" slf "*)
    "$IGI" -q hull import-middlebury "$DINO" -o "$work/rig" >/dev/null
    "$IGI" -q hull build "$work/rig/rig.toml" -o "$work/dino-hull" --resolution 256 >/dev/null ;;
esac

# each runs igi by `exec`, always inside a subshell `( ... )`, so that the pid of a background
# run is igi's own and SIGKILL reaches igi (killing a shell function's subshell would leave igi
# running on, and the next run would then write the same folder beside it)
prepare() { exec "$IGI" -q prepare "$MESH" --voxel 0.02 --atlas 64 -o "$1" >/dev/null; }
solve() { exec "$IGI" -q solve "$SURVEY" --atlas 32 --spp 4,8 --iterations 3 --tolerance 0 --indirect 1 -o "$1" >/dev/null; }
hull() { exec "$IGI" -q hull build "$work/rig/rig.toml" --resolution 256 -o "$1" >/dev/null; }
slf() { exec "$IGI" -q slf build "$work/rig/rig.toml" --mesh "$work/dino-hull/hull.ply" --atlas 256 --simplify 0.01 -o "$1" >/dev/null; }
# render writes one file: the "folder" is made here and holds the image and its --stderr
render() { mkdir -p "$1"; exec "$IGI" -q render datasets/fixtures/outdoor/scene.toml --camera datasets/fixtures/outdoor/camera.json --spp 16 --stderr "$1/se.exr" -o "$1/out.exr" >/dev/null; }

# seconds (float) of an uninterrupted run
timed() {
  local t0 t1
  t0=$(date +%s.%N); ( "$@" ) 2>/dev/null || return 1; t1=$(date +%s.%N)
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
  if [ "$kind" = hull ] || [ "$kind" = slf ]; then
    # the report holds the rig's path, the same for both; the printed times are not stored
    diff -r "$ref" "$out" >/dev/null || { echo "DIFFERENT: $out"; diff -rq "$ref" "$out" | head; return 1; }
    local name; name=$(basename "$out")
    if ls -A "$(dirname "$out")" | grep -q "^\.$name\.\(partial\|igi-lock\)"; then
      echo "STAGING OR LOCK LEFT beside $out:"; ls -A "$(dirname "$out")" | grep "^\.$name\."; return 1
    fi
  elif [ "$kind" = prepare ] || [ "$kind" = render ]; then
    diff -r "$ref" "$out" >/dev/null || { echo "DIFFERENT: $out"; diff -rq "$ref" "$out" | head; return 1; }
  else
    diff -r -x report.json -x convergence.png "$ref" "$out" >/dev/null || { echo "DIFFERENT: $out"; diff -rq -x report.json -x convergence.png "$ref" "$out" | head; return 1; }
    [ "$(normalise_report "$ref/report.json")" = "$(normalise_report "$out/report.json")" ] || { echo "DIFFERENT report: $out"; return 1; }
  fi
  local left
  left=$(find "$out" -name '.*.tmp*' | wc -l)
  [ "$left" -eq 0 ] || { echo "TEMP FILES LEFT in $out:"; find "$out" -name '.*.tmp*'; return 1; }
}

for kind in $KINDS; do
  ref="$work/$kind-ref"
  secs=$(timed $kind "$ref") || { echo "$kind: the uninterrupted run failed"; exit 1; }
  echo "$kind: uninterrupted run $secs s"
  kills=0; trials=0
  while [ "$kills" -lt "$KILLS" ]; do
    trials=$((trials + 1))
    out="$work/$kind-$trials"
    for _ in $(seq 1 $((1 + RANDOM % 3))); do
      # a build that finished before its kill is done: hull and slf builds replace nothing
      # (the output must be absent or empty), so they are not run over a finished output
      if [ "$kind" = hull ] || [ "$kind" = slf ]; then [ -e "$out" ] && break; fi
      delay=$(python3 -c "import random; random.seed($RANDOM); print(round(random.uniform(0.02, $secs), 3))")
      ( $kind "$out" ) 2>/dev/null &
      pid=$!
      sleep "$delay"
      if kill -0 "$pid" 2>/dev/null; then
        kill -9 "$pid" 2>/dev/null && kills=$((kills + 1))
      fi
      wait "$pid" 2>/dev/null || true
    done
    if [ "$kind" = hull ] || [ "$kind" = slf ] && [ -e "$out" ]; then :; else
      ( $kind "$out" ) 2>"$work/err" || { echo "resume of $out failed:"; cat "$work/err"; exit 1; }
    fi
    compare "$kind" "$ref" "$out"
    rm -rf "$out"
  done
  echo "$kind: $kills kills in $trials trials, every resume byte-identical, no temp file left"
done
