#!/usr/bin/env python3
"""The texel MAE no solve can go below on a large survey, from its true albedo texture alone.

`igi solve --truth` compares each texel with the true albedo *at its centre* (a point), while a
photograph's pixel reports the albedo averaged over its footprint on the surface. Where the
albedo has detail finer than that footprint (large_survey.py's 5-10 cm gravel, tiles, bricks
against 5 cm pixels), an estimate that recovers every pixel exactly still differs from the
point truth by the detail inside the footprint. This script measures that difference on the
survey's own texture (datasets/mitsuba/large_survey.py writes it, at 1.72 cm per texel): per
chart of the atlas (inside its margin), in blocks of k x k texels, the mean absolute difference
between the block's centre texel and the block's mean, for k = 2, 3, 5, 8 (3.4, 5.2, 8.6 and
13.8 cm: the resolving pixel footprint of the survey's photographs is 5.2 cm, `igi solve`'s
auto atlas chooses 4.4 cm texels, `--atlas 512` gives 13.2 cm), weighted by the charts' texels.
A box is the footprint of a pixel of the box-filtered renders at one footprint; the photographs'
footprints range over 3-6 cm with distance and the solver reads them bilinearly, so the numbers
estimate the floor rather than bound it.

Usage: python3 datasets/mitsuba/albedo_floor.py SURVEY_DIR   (mitsuba 3.9.1 reads the EXR)
"""

import json
import os
import sys

import mitsuba as mi
import numpy as np

mi.set_variant("scalar_rgb")


def floor(texture, cells, margin, k):
    """Texel-weighted MAE (R, G, B) between block centres and block means of k x k texels."""
    height = texture.shape[0]
    total, count = np.zeros(3), 0
    for c in cells:
        w, h = c["texels"]
        x0, y0b = c["X0"], c["Y0_from_bottom"]
        # the image's rows run top-down; the cell's origin is its bottom-left corner
        top = height - (y0b + h)
        a = texture[top + margin : top + h - margin, x0 + margin : x0 + w - margin]
        ny, nx = a.shape[0] // k, a.shape[1] // k
        if nx == 0 or ny == 0:
            continue
        a = a[: ny * k, : nx * k]
        means = a.reshape(ny, k, nx, k, 3).mean(axis=(1, 3))
        centres = a[k // 2 :: k, k // 2 :: k][:ny, :nx]
        total += np.abs(centres - means).sum(axis=(0, 1))
        count += ny * nx
    return total / max(count, 1)


def main():
    if len(sys.argv) != 2:
        sys.exit(__doc__)
    survey = sys.argv[1]
    meta = json.load(open(os.path.join(survey, "survey_meta.json")))
    tex = meta["site"]["texture"]
    texture = np.array(mi.Bitmap(os.path.join(survey, "truth", "site_albedo.exr")))[:, :, :3]
    texture = texture.astype(np.float64)
    print(f"{meta['generator']}: texture {tex['size']} at {100 * tex['texel_m']:.2f} cm")
    for k in (2, 3, 5, 8):
        m = floor(texture, tex["cells"], tex["margin_texels"], k)
        print(f"footprint {k} texels ({100 * k * tex['texel_m']:.1f} cm): point vs footprint "
              f"MAE {m[0]:.4f} {m[1]:.4f} {m[2]:.4f}")


if __name__ == "__main__":
    main()
