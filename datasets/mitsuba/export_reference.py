#!/usr/bin/env python3
"""Mitsuba 3 render of an `igi export --format mitsuba` scene, the reference for
tests/cli/mitsuba_export.rs (issue 16, item 6: the exported scene agrees with `igi render RESULT_DIR`).

Steps (OUT defaults to datasets/fixtures/export):
  1. `igi solve` the Mitsuba survey fixture (datasets/fixtures/survey: diffuse, no BRDF samples)
     into OUT/result with small atlases: a diffuse result of igi's own, committed;
  2. `igi export OUT/result --format mitsuba -o OUT/export` (committed, so the test can check
     that today's export writes the same bytes the reference was rendered from);
  3. loads OUT/export/scene.xml with Mitsuba itself (its shapes, textures, to_uv flip and
     integrator exactly as exported), adds the held-out camera and lighting of the survey
     fixture (sensor, envmap and sun disk converted as in survey_reference.py), and renders M
     independent images: OUT/reference.exr (mean) and OUT/reference_stderr.exr (standard error
     of the mean), and OUT/reference_meta.json.

Mitsuba is only a generator of committed fixtures, never a dependency of igi.
Usage: python3 datasets/mitsuba/export_reference.py [--igi target/release/igi] [--out DIR]
           [--renders M] [--spp N]
"""

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import survey_reference as sr  # noqa: E402  (sets DRJIT_LIBLLVM_PATH, camera and lighting converters)
import outdoor_reference as ref  # noqa: E402
import mitsuba as mi  # noqa: E402
import numpy as np  # noqa: E402

ROOT = sr.ROOT
SURVEY = os.path.join(ROOT, "datasets", "fixtures", "survey")
SOLVE = ["--atlas", "48", "--iterations", "2", "--spp", "4,16", "--indirect", "2", "--seed", "7"]


def run(cmd):
    print("+", " ".join(cmd), flush=True)
    subprocess.run(cmd, check=True)


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--igi", default=os.path.join(ROOT, "target", "release", "igi"))
    ap.add_argument("--out", default=os.path.join(ROOT, "datasets", "fixtures", "export"))
    ap.add_argument("--renders", type=int, default=8)
    ap.add_argument("--spp", type=int, default=1024)
    a = ap.parse_args()
    out = os.path.abspath(a.out)
    os.makedirs(out, exist_ok=True)
    for d in ("result", "export"):
        shutil.rmtree(os.path.join(out, d), ignore_errors=True)
    run([a.igi, "-q", "solve", os.path.join(SURVEY, "survey.toml"), "-o", os.path.join(out, "result")] + SOLVE)
    run([a.igi, "-q", "export", os.path.join(out, "result"), "--format", "mitsuba", "-o", os.path.join(out, "export")])
    # run.json records this machine's absolute input paths; a result loads without it
    os.remove(os.path.join(out, "result", "run.json"))
    for f in os.listdir(os.path.join(out, "export")):
        # previews, not part of the Mitsuba scene; export.json names this machine's result path
        if f.endswith(".png") or f == "export.json":
            os.remove(os.path.join(out, "export", f))

    variant = "llvm_ad_rgb" if sr.llvm_path() else "scalar_rgb"
    mi.set_variant(variant)
    camera_path = os.path.join(SURVEY, "heldout", "camera.json")
    lighting_path = os.path.join(SURVEY, "heldout", "lighting.toml")
    with open(camera_path) as f:
        camera = json.load(f)
    exported = mi.load_file(os.path.join(out, "export", "scene.xml"))
    with tempfile.TemporaryDirectory() as work:
        scene = {"type": "scene",
                 "integrator": {"type": "path", "max_depth": sr.MAX_DEPTH, "hide_emitters": False},
                 "sensor": sr.sensor_from_camera(camera)}
        scene.update(sr.emitters(lighting_path, work))
        for i, shape in enumerate(exported.shapes()):
            scene[f"shape{i}"] = shape
        scene = mi.load_dict(scene)
        t0 = time.time()
        pass_spp = 256 if variant == "llvm_ad_rgb" else a.spp
        mean, se = sr.render_mean(scene, a.spp, range(a.renders), min(pass_spp, a.spp))
        secs = time.time() - t0
    ref.write_exr(os.path.join(out, "reference.exr"), mean)
    ref.write_exr(os.path.join(out, "reference_stderr.exr"), se)
    meta = {"generator": "datasets/mitsuba/export_reference.py", "mitsuba": mi.__version__, "variant": variant,
            "renders": a.renders, "spp_per_render": a.spp, "max_depth": sr.MAX_DEPTH, "rfilter": "box",
            "camera": "datasets/fixtures/survey/heldout/camera.json",
            "lighting": "datasets/fixtures/survey/heldout/lighting.toml",
            "solve": SOLVE, "seconds": round(secs, 1),
            "mean": float(mean.mean()), "mean_stderr_rel": float(np.sqrt((se ** 2).mean()) / mean.mean())}
    ref.write_text(os.path.join(out, "reference_meta.json"), json.dumps(meta, indent=2) + "\n")
    print(json.dumps(meta, indent=2))


if __name__ == "__main__":
    main()
