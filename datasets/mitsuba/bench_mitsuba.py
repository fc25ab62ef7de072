#!/usr/bin/env python3
"""Side-by-side timing on the outdoor reference scene, in ONE run on one machine: Mitsuba 3
`scalar_rgb`, Mitsuba 3 `llvm_ad_rgb` and `igi render`, at equal samples per pixel, each with its
wall time and RMSE against the committed high-spp reference (datasets/fixtures/outdoor).

Needs Debian's libllvm19 for llvm_ad_rgb (DRJIT_LIBLLVM_PATH is set from `dpkg -L libllvm19`
when not given) and a release build of igi (`cargo build --release --bin igi`).
Usage: python3 datasets/mitsuba/bench_mitsuba.py [--spp 16 64 256] [--igi target/release/igi]
Writes datasets/fixtures/outdoor/timings.json and prints a Markdown table.
"""

import argparse
import glob
import json
import os
import subprocess
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
FIX = os.path.join(ROOT, "datasets", "fixtures", "outdoor")


def llvm_path():
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    out = subprocess.run(["dpkg", "-L", "libllvm19"], capture_output=True, text=True).stdout
    libs = [l for l in out.split() if "libLLVM" in l and ".so" in l]
    return libs[0] if libs else None


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--spp", type=int, nargs="+", default=[16, 64, 256])
    ap.add_argument("--igi", default=os.path.join(ROOT, "target", "release", "igi"))
    ap.add_argument("--out", default=os.path.join(FIX, "timings.json"))
    args = ap.parse_args()
    lib = llvm_path()
    if lib:
        os.environ["DRJIT_LIBLLVM_PATH"] = lib
    sys.path.insert(0, HERE)
    import mitsuba as mi
    import outdoor_reference as ref

    reference = ref.read_exr(os.path.join(FIX, "reference.exr")).astype(np.float64)

    def rmse(img):
        return float(np.sqrt(np.mean((np.asarray(img, np.float64) - reference) ** 2)))

    rows = []
    for variant in ["scalar_rgb", "llvm_ad_rgb"]:
        try:
            mi.set_variant(variant)
        except Exception as e:  # llvm missing: report, keep going
            print(f"{variant}: unavailable ({e})", file=sys.stderr)
            continue
        scene = mi.load_dict(ref.scene_dict(FIX, spp=1))
        t0 = time.time()
        mi.render(scene, spp=1, seed=0)  # warm-up (JIT compilation for llvm)
        warm = time.time() - t0
        for spp in args.spp:
            t0 = time.time()
            img = np.array(mi.render(scene, spp=spp, seed=101), dtype=np.float64)
            rows.append({"renderer": f"mitsuba {variant}", "spp": spp, "seconds": time.time() - t0,
                         "rmse": rmse(img), "warmup_seconds": warm})
            print(rows[-1], flush=True)
    with tempfile.TemporaryDirectory() as tmp:
        for spp in args.spp:
            out = os.path.join(tmp, f"igi{spp}.exr")
            t0 = time.time()
            subprocess.run([args.igi, "render", os.path.join(FIX, "scene.toml"), "--camera",
                            os.path.join(FIX, "camera.json"), "--spp", str(spp), "--seed", "101",
                            "--quiet", "-o", out], check=True)
            secs = time.time() - t0
            rows.append({"renderer": "igi render", "spp": spp, "seconds": secs, "rmse": rmse(ref.read_exr(out))})
            print(rows[-1], flush=True)
    meta = {"cores": os.cpu_count(), "mitsuba": mi.__version__, "reference": "datasets/fixtures/outdoor/reference.exr",
            "note": "igi times include process start and scene load; Mitsuba times are mi.render only (after a warm-up)",
            "rows": rows}
    with open(args.out + ".tmp", "w") as f:
        json.dump(meta, f, indent=2)
    os.replace(args.out + ".tmp", args.out)
    print("| renderer | spp | wall s | RMSE vs reference |\n|---|---:|---:|---:|")
    for r in rows:
        print(f"| {r['renderer']} | {r['spp']} | {r['seconds']:.2f} | {r['rmse']:.4g} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
