#!/usr/bin/env bash
# The cluster scale measurement of docs/SOLVER.md ("Scale"): the 20 M-triangle colonnade field
# (datasets/gen_site.sh OUT 25 1 3) prepared at the default 4.3 m voxels, photographed from
# eight directions by igi's own renderer under the survey fixture's three skies, frozen as a
# cluster run (`igi cluster submit --dry-run`), and then single tasks run by hand under
# /usr/bin/time: each task's done.json records its peak memory and the bytes it read.
#
# usage: datasets/scale_field.sh OUT [INDEX...]     (default indices: the middle voxel, the
#        heaviest voxel and the terrain; needs a release build: cargo build --release -p igi
#        -p igi-geometry --example gen_site)
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(realpath -m "${1:?usage: scale_field.sh OUT [INDEX...]}")
shift
igi=$PWD/target/release/igi
fixture=$PWD/datasets/fixtures/survey
mkdir -p "$out"/{cameras,photos,scenes}

[ -f "$out/field/site.ply" ] || datasets/gen_site.sh "$out/field" 25 1 3
if [ ! -f "$out/field.igi/manifest.json" ]; then
  /usr/bin/time -f "prepare: %e s, peak %M KiB" \
    "$igi" -q prepare "$out/field/site.ply" --terrain "$out/field/terrain.ply" -o "$out/field.igi"
fi

# eight cameras on a ring 70 m out and 25 m up, looking at the field's centre
python3 - "$out/cameras" <<'EOF'
import json, math, sys
for k in range(8):
    a = 2 * math.pi * k / 8 + 0.3
    c = [70 * math.cos(a), 70 * math.sin(a), 25.0]
    f = [-c[0], -c[1], 2.0 - c[2]]
    n = math.sqrt(sum(x * x for x in f)); f = [x / n for x in f]
    r = [f[1], -f[0], 0.0]; n = math.hypot(r[0], r[1]); r = [x / n for x in r]
    d = [f[1] * r[2] - f[2] * r[1], f[2] * r[0] - f[0] * r[2], f[0] * r[1] - f[1] * r[0]]
    R = [r, d, f]  # camera x right, y down, z forward
    t = [-sum(R[i][j] * c[j] for j in range(3)) for i in range(3)]
    cam = {"width": 480, "height": 320, "K": [[400, 0, 239.5], [0, 400, 159.5], [0, 0, 1]],
           "R": R, "t": t}
    json.dump(cam, open(f"{sys.argv[1]}/v{k}.json", "w"))
EOF

skies=(sunny lowsun overcast)
{
  echo "[site]"
  echo "prepared = \"$out/field.igi\""
} > "$out/survey.toml"
for k in 0 1 2 3 4 5 6 7; do
  sky=${skies[$((k % 3))]}
  scene=$out/scenes/$sky.toml
  cat > "$scene" <<EOF
lighting = "$fixture/lighting/$sky.toml"
[[object]]
mesh = "$out/field/site.ply"
albedo = [0.55, 0.50, 0.42]
[[object]]
mesh = "$out/field/terrain.ply"
albedo = [0.30, 0.27, 0.22]
EOF
  [ -f "$out/photos/v$k.exr" ] ||
    "$igi" -q render "$scene" --camera "$out/cameras/v$k.json" --spp 16 --indirect 1 \
      --seed "$k" -o "$out/photos/v$k.exr"
  cat >> "$out/survey.toml" <<EOF

[[photo]]
id = "v$k-$sky"
image = "photos/v$k.exr"
camera = "cameras/v$k.json"
lighting = "$fixture/lighting/$sky.toml"
EOF
done

if [ ! -f "$out/result/cluster/cluster.json" ]; then
  /usr/bin/time -f "submit --dry-run (first checkpoint of every part): %e s, peak %M KiB" \
    "$igi" -q cluster submit "$out/survey.toml" -o "$out/result" --dry-run \
    --spp 4,16 --iterations 2 --indirect 1 >/dev/null
fi
groups=$(python3 -c "import json,sys; print(len(json.load(open(sys.argv[1]))['groups']))" "$out/result/cluster/cluster.json")
echo "groups (array indices): $groups"
if [ $# -eq 0 ]; then
  # the middle voxel, the heaviest voxel and the terrain
  set -- $(python3 - "$out" <<'EOF'
import json, sys
out = sys.argv[1]
groups = json.load(open(f"{out}/result/cluster/cluster.json"))["groups"]
man = json.load(open(f"{out}/field.igi/manifest.json"))
vox = [v for v in man["voxels"] if v.get("voxel") is not None]
name = lambda v: "_".join(str(x) for x in v["voxel"])
heavy = max(vox, key=lambda v: v["triangles"][0])
mid = min(vox, key=lambda v: sum(abs(x) for x in v["voxel"][:2]) + 0.1 * v["voxel"][2])
print(groups.index(name(mid)), groups.index(name(heavy)), groups.index("terrain"))
EOF
)
fi
for i in "$@"; do
  /usr/bin/time -f "task $i: %e s wall, %U s user, peak %M KiB" \
    "$igi" -q cluster task "$out/result" --index "$i"
done
python3 - "$out" <<'EOF'
import glob, json, sys
for f in sorted(glob.glob(f"{sys.argv[1]}/result/cluster/iter_1/*/done.json")):
    d = json.load(open(f))
    u = d["usage"]
    print(f"{d['group']:>10}: {d['wall_s']:.1f} s, peak {u['peak_rss_bytes'] / 2**20:.0f} MiB, "
          f"read {u['read_bytes'] / 2**20:.1f} MiB, observations {d['sums']['observations']}")
EOF
