"""Where the noise of the demo's survey photographs comes from (docs/SOLVER.md, "Adaptive
photographs, and what is left").

    python3 datasets/photo_noise.py OUT [SPP]

OUT is the output folder of `igi demo -o OUT`. For each survey photograph, `igi render` (the
release binary, `target/release/igi`) renders the truth scene under the lighting the survey
records for the photograph (the probe's recovery of its sky: as noisy as the true one) at its
camera, stratified, SPP samples a pixel (default 32), with two seeds, once with
the demo's two indirect bounces and once with direct light only (`--indirect 0`). The relative
variance of a render is half the squared difference of its two seeds over the squared mean of
the full render, averaged over the pixels that see the site (mean above 1e-4); per sample, its
square root times sqrt(SPP). Prints, per photograph, that relative standard deviation per sample and the
share of the variance direct light alone has. Reads EXR through Mitsuba's Bitmap
(`bash scripts/deps.sh mitsuba`) and numpy.
"""
import os
import subprocess
import sys
import tempfile

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")

IGI = os.path.join(os.path.dirname(__file__), "..", "target", "release", "igi")


def read(path):
    return np.array(mi.Bitmap(path), dtype=np.float64)[..., :3].mean(-1)


def render(scene, camera, spp, seed, indirect, out):
    subprocess.run([IGI, "render", scene, "--camera", camera, "--spp", str(spp), "--stratified",
                    "--seed", str(seed), "--indirect", str(indirect), "-o", out, "-q"],
                   check=True, stdout=subprocess.DEVNULL)
    return read(out)


def variance(a, b, mean):
    """Half the squared seed-to-seed difference of `a` and `b` over `mean` squared, averaged over
    the pixels where `mean` exceeds 1e-4."""
    seen = mean > 1e-4
    return (0.5 * (a - b)[seen] ** 2 / mean[seen] ** 2).mean()


def main(out, spp):
    survey = os.path.join(out, "survey")
    with open(os.path.join(survey, "truth", "scene.toml")) as f:
        objects = "".join(line for line in f if not line.startswith("#"))
    with tempfile.TemporaryDirectory() as tmp:
        for cam in sorted(os.listdir(os.path.join(survey, "cameras"))):
            shot = cam[:-len(".json")]
            if shot == "held-out":
                continue
            lighting = shot.split("-", 1)[1]
            # the truth scene under the survey's lighting, beside the truth's textures
            scene = os.path.join(survey, "truth", f".noise-{lighting}.toml")
            with open(scene, "w") as f:
                f.write(f'lighting = "../lighting/{lighting}.toml"\n' + objects)
            camera = os.path.join(survey, "cameras", cam)
            try:
                (f1, f2), (d1, d2) = ([render(scene, camera, spp, seed, k,
                                              os.path.join(tmp, f"{k}-{seed}.exr"))
                                       for seed in (1, 2)] for k in (2, 0))
            finally:
                os.remove(scene)
            mean = 0.5 * (f1 + f2)
            full, direct = variance(f1, f2, mean), variance(d1, d2, mean)
            print(f"{shot:16s} relative sd per sample {np.sqrt(full * spp):.3f}  "
                  f"direct light's share of the variance {direct / full:.2f}")


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    main(sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 32)
