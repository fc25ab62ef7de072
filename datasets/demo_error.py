"""Where the albedo error of an `igi demo` run sits (docs/SOLVER.md, "Error against run time").

    python3 datasets/demo_error.py OUT [OUT ...]

OUT is the output folder of `igi demo -o OUT` (or of the `demo_photos` example). For each part,
over the texels seen by two or more photographs: the rho_d MAE, and the error regressed on the
truth's high-frequency part (the true atlas minus its 3 x 3 texel mean): `k` is the share of
that detail the solve lost (error ~ -k * detail), `corr` the correlation, and the MAE left once
that share is given back. A last line sums over all parts; then the R error by how many
photographs see a texel, each count's share of the texels and of the summed error. Reads EXR through Mitsuba's Bitmap
(`bash scripts/deps.sh mitsuba`) and numpy.
"""
import sys

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")

PARTS = ["terrain", "stylobate", "wall", "architrave"] + [f"column_0{i}" for i in range(6)]


def read(path):
    a = np.array(mi.Bitmap(path), dtype=np.float64)
    return a if a.ndim == 3 else a[..., None]


def detail(t):
    """The truth minus its 3 x 3 mean (edges replicated)."""
    p = np.pad(t, ((1, 1), (1, 1), (0, 0)), mode="edge")
    h, w = t.shape[:2]
    mean = sum(p[1 + dy:1 + dy + h, 1 + dx:1 + dx + w] for dy in (-1, 0, 1) for dx in (-1, 0, 1)) / 9
    return t - mean


def row(name, e, hf):
    k = (e * hf).sum() / (hf * hf).sum()
    corr = np.corrcoef(e.ravel(), hf.ravel())[0, 1]
    left = np.abs(e - k * hf).mean()
    print(f"  {name:11s} texels {e.shape[0]:6d}  MAE {np.abs(e).mean():.4f}  "
          f"(R/G/B {' / '.join(f'{x:.4f}' for x in np.abs(e).mean(0))})  "
          f"detail lost k {-k:.2f}  corr {corr:+.2f}  MAE without it {left:.4f}  "
          f"MAE if all detail were lost {np.abs(hf).mean():.4f}")


def by_views(e, views):
    """The R error by the number of photographs that see a texel."""
    total = np.abs(e[:, 0]).sum()
    for k in np.unique(views):
        m = views == k
        print(f"  seen by {int(k)}: {m.mean():5.1%} of the texels, MAE R {np.abs(e[m, 0]).mean():.4f}, "
              f"{np.abs(e[m, 0]).sum() / total:5.1%} of the summed error")


def main(out):
    print(out)
    errs, details, views = [], [], []
    for name in PARTS:
        t = read(f"{out}/survey/truth/{name}_albedo.exr")[..., :3]
        r = read(f"{out}/result/parts/{name}_rho_d.exr")[..., :3]
        count = read(f"{out}/result/parts/{name}_observations.exr")[..., 0]
        seen = count >= 2
        e, hf = (r - t)[seen], detail(t)[seen]
        row(name, e, hf)
        errs.append(e)
        details.append(hf)
        views.append(count[seen])
    row("all", np.concatenate(errs), np.concatenate(details))
    by_views(np.concatenate(errs), np.concatenate(views))


if __name__ == "__main__":
    if len(sys.argv) < 2:
        sys.exit(__doc__)
    for folder in sys.argv[1:]:
        main(folder)
