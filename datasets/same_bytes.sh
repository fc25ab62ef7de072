#!/usr/bin/env bash
# Same bytes across a refactor (issue 31): runs two igi binaries on the demo (--quick), the
# fixture survey (--atlas 32 and --atlas auto), a prepared site (the demo's stylobate and terrain
# in 4 m voxels), the dino's opacity hull and its surface light field, the ply / obj / mitsuba
# exports and `igi sample`, then compares every file with `cmp`. Files that hold timings or
# absolute paths (report.json, run.json, demo.json, manifest.json, hull.json, scene.toml of a
# prepared site, convergence.png, the lock) are listed but expected to differ.
# usage: datasets/same_bytes.sh OLD_IGI NEW_IGI OUT   (needs ../shared/data for the dino)
set -euo pipefail
cd "$(dirname "$0")/.."
old=$(realpath "$1"); new=$(realpath "$2"); out=$(realpath -m "$3")
run() {
  local igi=$1 o=$2
  mkdir -p "$o"
  "$igi" -q demo --quick -o "$o/demo" >/dev/null
  "$igi" -q solve datasets/fixtures/survey -o "$o/survey" --iterations 2 --spp 4,8 --atlas 32 >/dev/null
  "$igi" -q solve datasets/fixtures/survey -o "$o/survey-auto" --iterations 1 --spp 4 --atlas-max 64 >/dev/null
  local s=$o/demo/survey
  "$igi" -q prepare "$s/geometry/stylobate.ply" --terrain "$s/geometry/terrain.ply" --atlas 32 --voxel 4 -o "$o/site.igi" >/dev/null
  python3 - "$s" "$o" <<'PY'
import re, sys
survey, out = sys.argv[1], sys.argv[2]
t = open(f"{survey}/survey.toml").read()
photos = re.sub(r'(image|camera|lighting) = "([^"/][^"]*)"',
                lambda m: f'{m.group(1)} = "{survey}/{m.group(2)}"', t[t.index("[[photo]]"):])
open(f"{out}/prepared.toml", "w").write(f'[site]\nprepared = "{out}/site.igi"\n\n{photos}')
PY
  "$igi" -q solve "$o/prepared.toml" -o "$o/prepared" --spp 4,8 --iterations 2 --seed 3 >/dev/null
  "$igi" -q hull import-middlebury ../shared/data/multiview/dinoSparseRing -o "$o/rig" >/dev/null
  "$igi" -q hull build "$o/rig/rig.toml" -o "$o/hull" >/dev/null
  "$igi" -q slf build "$o/rig/rig.toml" --mesh "$o/hull/hull.ply" --atlas 1024 -o "$o/slf" >/dev/null
  for f in ply obj mitsuba; do "$igi" -q export "$o/survey" --format "$f" -o "$o/export-$f" >/dev/null; done
  printf 'x,y,z,nx,ny,nz\n0,0,0,0,0,1\n1,0.5,0,0,0,1\n' > "$o/points.csv"
  "$igi" -q sample "$o/survey" --points "$o/points.csv" -o "$o/sample.csv" >/dev/null
}
rm -rf "$out"
run "$old" "$out/old"
run "$new" "$out/new"
differ=0 same=0 expected=0
while IFS= read -r f; do
  if [ ! -f "$out/new/$f" ]; then echo "missing in new: $f"; differ=$((differ + 1))
  elif cmp -s "$out/old/$f" "$out/new/$f"; then same=$((same + 1))
  elif [[ $f =~ (report|run|demo|manifest|hull)\.json$|convergence\.png$|igi-lock$|prepared/scene\.toml$|prepared\.toml$ ]]; then
    expected=$((expected + 1))
  else echo "differs: $f"; differ=$((differ + 1)); fi
done < <(cd "$out/old" && find . -type f | sort)
echo "$same files identical, $expected with timings or paths, $differ differ"
[ "$differ" -eq 0 ]
