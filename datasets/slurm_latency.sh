#!/usr/bin/env bash
# Scheduling latency of `igi cluster` on the one-node loopback Slurm (docs/SOLVER.md, "Scale"):
# the survey fixture's block prepared in 12 voxels plus the terrain (tests/cli/cli_cluster.rs's
# layout), three iterations at --spp 4,8 and --max-parallel 2, then the timeline of every
# task's done.json and every merge log (seconds after the first script) and the tasks' own
# time. Needs root, slurm-wlm and munge (scripts/deps.sh test) and a debug build (cargo build).
# usage: datasets/slurm_latency.sh OUT
set -euo pipefail
cd "$(dirname "$0")/.."
out=$(realpath -m "${1:?usage: slurm_latency.sh OUT}")
igi=$PWD/target/debug/igi
f=$PWD/datasets/fixtures/survey
rm -rf "$out" && mkdir -p "$out"
"$igi" -q prepare "$f/geometry/block.ply" --terrain "$f/geometry/ground.ply" --voxel 1.5 \
  --atlas 16 -o "$out/site" >/dev/null
python3 - "$f" "$out" <<'EOF'
import sys
f, out = sys.argv[1], sys.argv[2]
t = open(f"{f}/survey.toml").read()
photos = t[t.index("[[photo]]"):].replace('= "', f'= "{f}/')
open(f"{out}/survey.toml", "w").write(f'[site]\nprepared = "{out}/site"\n\n{photos}')
EOF
IGI_SLURM_PORT=${IGI_SLURM_PORT:-23817} bash scripts/slurm-loopback.sh start "$out/slurm" >/dev/null
trap 'bash scripts/slurm-loopback.sh stop "$out/slurm"' EXIT
export SLURM_CONF=$out/slurm/slurm.conf
t0=$(date +%s.%N)
"$igi" -q cluster submit "$out/survey.toml" -o "$out/res" --iterations 3 --spp 4,8 --tolerance 0 \
  --indirect 1 --max-parallel 2 >/dev/null
until "$igi" cluster status "$out/res" --json |
  python3 -c "import json,sys; sys.exit(0 if json.load(sys.stdin)['finished'] else 1)"; do
  sleep 0.2
done
echo "submit to finished: $(echo "$(date +%s.%N) - $t0" | bc) s"
python3 - "$out/res" <<'EOF'
import glob, json, os, sys
res = sys.argv[1]
ev = [(os.path.getmtime(f), "done  " + f.split("/")[-3] + " " + f.split("/")[-2])
      for f in glob.glob(f"{res}/cluster/iter_*/*/done.json")]
ev += [(os.path.getmtime(f), "merge " + f.split("/")[-3]) for f in glob.glob(f"{res}/cluster/iter_*/logs/merge-*.out")]
ev.append((os.path.getmtime(f"{res}/cluster/iter_1/tasks-0.sh"), "script iter_1"))
ev.sort()
for t, e in ev:
    print(f"{t - ev[0][0]:7.2f} {e}")
for k in (1, 2, 3):
    s = [json.load(open(f))["wall_s"] for f in glob.glob(f"{res}/cluster/iter_{k}/*/done.json")]
    print(f"iteration {k}: {len(s)} tasks, {sum(s):.2f} s of task time, slowest {max(s):.2f} s")
EOF
