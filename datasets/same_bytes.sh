#!/usr/bin/env bash
# Same bytes across a refactor (issue 31): runs two igi binaries on the demo (--quick), the
# fixture survey (--atlas 32 and --atlas auto), a prepared site (the demo's stylobate and terrain
# in 4 m voxels), the dino's opacity hull and its surface light field, the ply / obj / mitsuba
# exports and `igi sample`, then compares every file with `cmp`. Files that hold timings or
# absolute paths (report.json, run.json, demo.json, manifest.json, hull.json, scene.toml of a
# prepared site, convergence.png, the lock) are listed but expected to differ. The commands whose
# work moved into the libraries (render, compare, hdr merge, brdf, probe, camera undistort,
# hull render, slf render, info) also run from inside OUT, their standard output kept as *.out
# (the output folder's path replaced by OUT; *.timed.out hold timings and are expected to differ)
# and the messages of failing invocations as *.err.
# usage: datasets/same_bytes.sh OLD_IGI NEW_IGI OUT   (needs ../shared/data for the dino)
set -euo pipefail
cd "$(dirname "$0")/.."
old=$(realpath "$1"); new=$(realpath "$2"); out=$(realpath -m "$3"); repo=$(pwd)
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
  (cd "$o" && moved "$igi" "$o")
}
# the commands of issue 31's last part, run inside OUT ($2): outputs, stdout, error messages
moved() {
  local igi=$1 o=$2 f=$repo/datasets/fixtures n=0
  out() { sed "s#$o#OUT#g" > "$1"; }
  err() {
    n=$((n + 1))
    "$igi" -q "$@" > /dev/null 2> "err_$n.raw" && echo "unexpected success: $*" >&2
    sed -e "s#$o#OUT#g" -e "s#$(basename "$igi")#igi#g" "err_$n.raw" > "err_$n.err"
    rm "err_$n.raw"
  }
  "$igi" -q render "$f/outdoor/scene.toml" --camera "$f/outdoor/camera.json" --spp 4 --seed 2 -o render.exr --stderr render_se.exr | out render.timed.out
  "$igi" -q render "$f/outdoor/scene.toml" --camera "$f/outdoor/camera.json" --spp 16 --adaptive -o render_adaptive.hdr | out render_adaptive.timed.out
  "$igi" -q compare render.exr "$f/outdoor/reference.exr" --stderr-a render_se.exr --diff diff.png | out compare.out
  "$igi" -q compare render.exr "$f/outdoor/reference.exr" --json | out compare_json.out
  "$igi" -q hdr merge "$f"/board/sunny/bracket_{0,1,2}.png --times-file "$f/board/sunny/times.txt" --response-out response.csv --json -o merged.exr | out hdr.out
  "$igi" -q hdr merge "$f"/board/sunny/bracket_{0,1,2}.png --times 0.25 1/32 1/256 --linear --json -o merged_linear.hdr | out hdr_linear.out
  "$igi" -q brdf fit "$f/brdf/samples.csv" -o materials.json | out brdf_fit.out
  local material; material=$(python3 -c 'import json,sys; print(sorted(json.load(open("materials.json"))["materials"])[0])')
  "$igi" -q brdf eval materials.json --material "$material" --pairs "$f/brdf/heldout.csv" -o eval.csv
  "$igi" -q brdf infer materials.json --rho 0.3,0.2,0.1 | out infer.out
  "$igi" -q brdf infer materials.json --rho 0.1,0.2,0.3 -o inferred.json
  mkdir -p probe
  "$igi" -q probe "$f/board/sunny/board.exr" --camera "$f/board/sunny/camera.json" --board "$f/board/sunny/board.json" --map-width 64 --hemi-size 64 -o probe/lighting.toml 2>&1 | out probe.out
  "$igi" -q camera undistort "$f/board/sunny/board.exr" --camera "$f/board/sunny/camera.json" --camera-out undistorted.json -o undistorted.exr
  "$igi" -q hull render hull --camera rig/cameras/$(ls rig/cameras | head -1) --json -o hull_view.exr | out hull_render.timed.out
  "$igi" -q slf render slf --camera rig/cameras/$(ls rig/cameras | head -1) --bias 0.4 -o slf_view.exr | out slf_render.timed.out
  "$igi" -q info site.igi --json | out info.out
  "$igi" -q info site.igi --load-voxel middle | out info_load.timed.out
  err compare render.exr "$f/outdoor/reference.exr" --within render.exr
  err compare render.exr missing.exr
  err hdr merge "$f"/board/sunny/bracket_{0,1}.png --times 1 -o merged.png
  err hdr merge "$f"/board/sunny/bracket_{0,1}.png --times 1 -o merged2.exr
  err hdr merge "$f"/board/sunny/bracket_{0,1}.png -o merged3.exr
  err hdr merge "$f"/board/sunny/bracket_{0,1}.png --times 1 2 --linear --response-out r.csv -o merged4.exr
  err camera undistort "$f/board/sunny/board.exr" --camera "$f/board/sunny/camera.json" -o undistorted.png
  err camera radiometry -o radiometry.json
  err camera radiometry --checker "$f/board/sunny/board.exr" --corners 1,2,3 -o radiometry.json
  err camera radiometry --flat "$f/outdoor/sky.exr" --corners 1,2,3,4,5,6,7,8 -o radiometry.json
  err camera radiometry --flat "$f/board/sunny/board.exr" --flat "$f/outdoor/sky.exr" -o radiometry.json
  err camera calibrate "$f/board/sunny/board.exr" --board 9 --square 0.02 -o cal.json
  err camera calibrate "$f/board/sunny/board.exr" --board 9x6 --square=-1 -o cal.json
  err camera refine "$f/board/sunny/board.exr" --camera "$f/outdoor/camera.json" --mesh "$f/outdoor/wall.ply" -o refined.json
  err camera refine "$f/board/sunny/board.exr" --camera "$f/outdoor/camera.json" --mesh "$f/outdoor/wall.ply" --search 0 -o refined.json
  err camera pose --camera "$f/outdoor/camera.json" --points "$f/brdf/samples.csv" -o posed.json
  err render "$f/outdoor/scene.toml" --camera "$f/outdoor/camera.json" --spp 0 -o r.exr
  err render "$f/outdoor/scene.toml" --camera "$f/outdoor/camera.json" --spp 8 --adaptive -o r.exr
  err render "$f/outdoor/scene.toml" --camera "$f/outdoor/camera.json" -o r.tif
  err render hull --camera "$f/outdoor/camera.json" -o r.exr
  err render hull --camera "$f/outdoor/camera.json" --lighting "$f/outdoor/lighting.toml" -o r.exr
  err brdf fit "$f/brdf/samples.csv" --max-gain 0.5 -o m.json
  err brdf fit "$f/brdf/samples.csv" --coverage-cap=-1 -o m.json
  err brdf eval materials.json --material none --pairs "$f/brdf/heldout.csv" -o e.csv
  err brdf infer materials.json --rho 1,2
  err brdf cluster "$f/brdf/samples.csv" -k 2 -o c.json
  err brdf measure "$f/brdf/samples.csv" --camera "$f/outdoor/camera.json" --photo a.exr --photo b.exr --corners 1,2 -o s.csv
  err probe "$f/board/sunny/board.exr" --camera "$f/board/sunny/camera.json" --board "$f/board/sunny/board.json" -o probe/lighting.txt
  err probe "$f/board/sunny/board.exr" --camera "$f/board/sunny/camera.json" --board "$f/board/sunny/board.json" --sun-mask-px=-1 -o probe/l2.toml
  err probe calibrate-mirror "$f/brdf/samples.csv"
  err prepare "$f/outdoor/wall.ply" --origin 1,2 -o site2.igi
  err prepare "$f/outdoor/wall.ply" --origin 1,x,3 -o site2.igi
  err prepare "$f/outdoor/wall.ply" --max-memory 0 -o site2.igi
  err info site.igi --load-voxel 1,2
  err info site.igi --load-voxel 1,b,2
  err slf render slf --camera "$f/outdoor/camera.json" --bias 2 -o s.exr
  err slf render slf --camera "$f/outdoor/camera.json" --mesh "$f/outdoor/wall.ply" -o s.exr
  err slf build rig/rig.toml --mesh "$f/outdoor/wall.ply" --level 9 -o slf2
  err hull render hull --camera "$f/outdoor/camera.json" --lighting "$f/outdoor/lighting.toml" -o h.exr
  err hull build "$f/outdoor/scene.toml" -o hull2
}
rm -rf "$out"
run "$old" "$out/old"
run "$new" "$out/new"
differ=0 same=0 expected=0
while IFS= read -r f; do
  if [ ! -f "$out/new/$f" ]; then echo "missing in new: $f"; differ=$((differ + 1))
  elif cmp -s "$out/old/$f" "$out/new/$f"; then same=$((same + 1))
  elif [[ $f =~ (report|run|demo|manifest|hull)\.json$|convergence\.png$|igi-lock$|prepared/scene\.toml$|prepared\.toml$|\.timed\.out$ ]]; then
    expected=$((expected + 1))
  else echo "differs: $f"; differ=$((differ + 1)); fi
done < <(cd "$out/old" && find . -type f | sort)
echo "$same files identical, $expected with timings or paths, $differ differ"
[ "$differ" -eq 0 ]
