#!/usr/bin/env bash
# The surface light field of the real Middlebury dino (docs/LIGHTFIELD.md, "Real data"): the
# sparse-ring set imported as a multi-view capture; each held-out view left out of the capture;
# the visual hull of the other 14 views as the mesh; the field built from those 14 views by
# pointwise fairing, PFA (q = 2) and the median alone, and rendered at the held-out camera
# against its photo (`igi compare`: PSNR over the pixels the field covers, peak = the photo's
# maximum). The nearest-camera baseline is `igi hull render --k 1` of the same hull (each surfel
# coloured by the nearest of the 14 cameras that sees it), judged on the pixels the faired field
# covers (`igi compare --within`).
#
# usage: datasets/slf_dino.sh OUT [ATLAS] [HELD-OUT VIEW...]   (default 1024; dinoSR0004 0007 0012)
# needs ../shared/data (multiview/dinoSparseRing) and a release build (cargo build --release -p igi)
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(realpath -m "${1:?usage: slf_dino.sh OUT [ATLAS] [VIEW...]}")
atlas=${2:-1024}
shift $(( $# >= 2 ? 2 : 1 ))
held=("$@")
[ ${#held[@]} -gt 0 ] || held=(dinoSR0004 dinoSR0007 dinoSR0012)
igi=$PWD/target/release/igi
set_dir=$(realpath ../shared/data/multiview/dinoSparseRing)
mkdir -p "$out"
[ -f "$out/rig/rig.toml" ] || "$igi" -q hull import-middlebury "$set_dir" -o "$out/rig" >/dev/null
photo_of() {
  python3 -c "
import os, tomllib
r = tomllib.load(open('$out/rig/rig.toml', 'rb'))
print(os.path.join('$out/rig', [x for x in r['view'] if x['id'] == '$1'][0]['photo']))"
}
for v in "${held[@]}"; do
  python3 - "$out/rig/rig.toml" "$v" "$out/rig/without_$v.toml" <<'EOF'
import sys
text, view, dst = open(sys.argv[1]).read(), sys.argv[2], sys.argv[3]
head, *views = text.split("[[view]]")
keep = [b for b in views if f'id = "{view}"' not in b]
assert len(keep) == len(views) - 1, f"{view} is not a view of the rig"
open(dst, "w").write(head + "".join("[[view]]" + b for b in keep))
EOF
  hull=$out/hull_without_$v
  [ -f "$hull/hull.ply" ] || "$igi" -q hull build "$out/rig/without_$v.toml" -o "$hull" >/dev/null
  photo=$(photo_of "$v")
  for m in fair pfa median; do
    d=$out/slf_${v}_$m
    /usr/bin/time -f "$v $m build: %e s, peak %M KiB" "$igi" -q slf build "$out/rig/without_$v.toml" \
      --mesh "$hull/hull.ply" --simplify 0.02 --atlas "$atlas" --method "$m" -o "$d" --json \
      > "$d.json"
    "$igi" -q slf render "$d" --camera "$out/rig/cameras/$v.json" -o "$d.exr" >/dev/null
    psnr=$("$igi" compare "$d.exr" "$photo" --json | python3 -c "import json,sys; c = json.load(sys.stdin); print(round(c['psnr_db'], 2), c['pixels'])")
    python3 - "$d.json" "$v" "$m" "$psnr" <<'EOF'
import json, sys
r = json.load(open(sys.argv[1]))
g = r["extra"]["gather"]
psnr, pixels = sys.argv[4].split()
print(f"{sys.argv[2]} {sys.argv[3]:>6}: held-out PSNR {psnr} dB over {pixels} pixels; {g['points']} points "
      f"({g['unseen_points']} unseen), {g['samples']} samples, texel {r['extra']['atlas_texel_m'] * 1000:.2f} mm, "
      f"pixel footprint {g['median_pixel_footprint'] * 1000:.2f} mm, colour {r['colour_bytes']} B")
EOF
  done
  "$igi" -q hull render "$hull" --camera "$out/rig/cameras/$v.json" --k 1 -o "$out/nearest_$v.exr" >/dev/null
  "$igi" compare "$out/nearest_$v.exr" "$photo" --within "$out/slf_${v}_fair.exr" --json \
    | python3 -c "import json,sys; c = json.load(sys.stdin); print(f'$v nearest camera: held-out PSNR {c[\"psnr_db\"]:.2f} dB over {c[\"pixels\"]} pixels')"
done
