#!/usr/bin/env bash
# Time and peak memory of solving a prepared site with many voxels (docs/BENCHMARKS.md,
# "Prepared site: costs per voxel"): the embedded demo's stylobate and terrain prepared in
# 1.2 m voxels (96 voxels plus the terrain, 256 x 256 atlases), solved from the demo's eight
# survey photographs (`igi solve --spp 4,16 --iterations 2 --deblur 4 --seed 3`), then the same
# site frozen for a cluster (`igi cluster submit --dry-run`) and two of its tasks run by hand
# (`igi cluster task`). Prints `/usr/bin/time` lines (wall seconds, peak KiB).
# usage: datasets/prepared_scaling.sh OUT [IGI]   (IGI: default target/release/igi; an older
#        build for a comparison; the demo, 45 s, runs once into OUT/demo)
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(realpath -m "${1:?usage: prepared_scaling.sh OUT [IGI]}")
igi=$(realpath "${2:-target/release/igi}")
mkdir -p "$out"
[ -f "$out/demo/demo.json" ] || "$igi" -q demo -o "$out/demo" >/dev/null
survey=$out/demo/survey
rm -rf "$out/site.igi" "$out/solve" "$out/cluster"
"$igi" -q prepare "$survey/geometry/stylobate.ply" --terrain "$survey/geometry/terrain.ply" \
  --atlas 256 --voxel 1.2 -o "$out/site.igi"
python3 - "$survey" "$out" <<'EOF'
import re, sys
survey, out = sys.argv[1], sys.argv[2]
t = open(f"{survey}/survey.toml").read()
photos = re.sub(r'(image|camera|lighting) = "([^"/][^"]*)"',
                lambda m: f'{m.group(1)} = "{survey}/{m.group(2)}"', t[t.index("[[photo]]"):])
open(f"{out}/survey.toml", "w").write(f'[site]\nprepared = "{out}/site.igi"\n\n{photos}')
EOF
/usr/bin/time -f "solve (97 groups, 2 iterations): %e s, peak %M KiB" "$igi" -q solve \
  "$out/survey.toml" -o "$out/solve" --spp 4,16 --iterations 2 --deblur 4 --seed 3 >/dev/null
"$igi" -q cluster submit "$out/survey.toml" -o "$out/cluster" --dry-run --spp 4,16 \
  --iterations 2 --seed 3 >/dev/null
for i in 40 96; do
  /usr/bin/time -f "cluster task $i: %e s, peak %M KiB" "$igi" -q cluster task "$out/cluster" --index "$i" >/dev/null
done
