#!/usr/bin/env python3
"""Large survey for the performance issue, rendered by Mitsuba 3 (independent ground truth).

A site about 44 m across, as one scan-like mesh of about 36,000 triangles with one albedo
texture, photographed 32 times: what the issue measured `igi solve` on (default atlas against
`--atlas 512`, albedo error against run time). In igi's world frame (Z up, metres):

- a terrain heightfield over 44 x 44 m with 1.6 m of smooth relief, triangulated on a jittered
  grid that is 2.5 x finer at the centre than at the edges (random diagonals), with the triangles
  under the buildings removed;
- five buildings and walls merged into the same mesh: a flat-roofed hall, a house with a gable
  roof (turned 20 degrees), a tower, a long wall and a low wall, their faces subdivided at
  0.4-1.2 m (they sink 0.4 m into the terrain; no bottoms);
- one UV atlas of 4096 x 4096 texels: the terrain as a planar (x, y) chart in the bottom-left
  2560 x 2560 texels, each building face its own chart, shelf-packed into the rest, every chart
  at the same texel size (1.72 cm) with a 3-texel margin inside its cell;
- albedo as a function of world position per chart, values in (0.05, 0.85): colour patches of
  1 and 3.5 m (smooth lattice noise) times 5-10 cm structure: gravel cells (6 cm), paving tiles
  (10 cm), grass cells, bricks, ashlar blocks, plaster speckle with a striped band, formwork
  boards, roof tiles. The texture holds the function at its texel centres (through the inverse
  of the chart map, extended into the margins), so bilinear lookups never bleed between charts
  and Mitsuba's and igi's lookups agree.

Writes a FORMATS.md survey folder (as datasets/mitsuba/survey_reference.py, whose cameras, skies,
lighting files, sun disks, Mitsuba scenes, checks and render_mean it reuses):

    survey.toml                 the survey: [site] meshes = ["geometry/site.ply"], 32 photos
    geometry/site.ply           binary PLY: x y z nx ny nz u v, vertex_indices
    photos/vK-LIGHT.exr         512 x 384, 8 viewpoints just outside the terrain (eye 2-15 m
                                high, 25-35 m from the site centre, 14-28 m from what it looks at;
                                84 % of the surface in view of two or more) x 4 lightings (high sun,
                                low sun from another azimuth, hazy sun, overcast); Mitsuba path
                                tracer, max_depth 4 (= igi --indirect 2), box filter, llvm_ad_rgb
    cameras/vK-LIGHT.json       OpenCV K/R/t, 60 degrees across, no distortion
    lighting/*.toml, *_sky.exr  lat-long skies and 0.53 degree sun disks (sun 3e4-1e5 x the sky)
    truth/scene.toml, site_albedo.exr   the true albedo texture (`igi solve --truth
                                truth/scene.toml`), lit by the held-out lighting
    heldout/photo.exr, photo_stderr.exr, camera.json, lighting.toml, sky.exr
                                a ninth viewpoint under a fifth lighting: the mean of M renders
                                and its per-pixel standard error
    survey_meta.json            settings, triangle counts, texture and chart layout, coverage,
                                self-checks, render times

Before rendering it asserts its conventions against Mitsuba (scalar_rgb), as
survey_reference.py does: (a) camera projections vs emissive markers, (b) envmaps vs the
FORMATS.md lat-long lookup, (c) sun irradiance vs L omega cos, (d) the texture at ray hits vs
the FORMATS.md texel lookup and vs the albedo function, (e) every UV inside its chart cell by
the margin; then (f, llvm_ad_rgb) how much of the surface the viewpoints see.

Usage:
    python3 datasets/mitsuba/large_survey.py --out /tmp/survey_large [--spp 64] [--seed 1]
    igi solve /tmp/survey_large -o R --atlas 512 --truth /tmp/survey_large/truth/scene.toml
Deterministic for a given seed (byte-identical files). Write it outside the repository: about
170 MB, the texture 100 MB. Here (2 cores shared with a Rust build, llvm_ad_rgb): inputs
11-14 s, checks 21-43 s, 64 spp photos 2.5-4.6 s each (80-150 s for the 32; median relative
standard error of a pixel 2-5 %), held-out 4 x 64 spp 9-19 s. At `--spp 256` (noise about a
camera's at base ISO: median relative standard error 0.9-2.5 %) 30 s a photo, about 16 min for
the 32 (docs/BENCHMARKS.md, "Photographs as noisy as a camera's").
"""

import argparse
import json
import math
import os
import shutil
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)
import survey_reference as sr  # noqa: E402  (sets DRJIT_LIBLLVM_PATH, imports mitsuba)

mi, ref = sr.mi, sr.ref

# ----------------------------------------------------------------------------- site layout
SITE_HALF = 22.0                   # the terrain spans [-22, 22]^2 m
RELIEF = 1.6                       # metres from the lowest to the highest terrain point
TARGET_TRIANGLES = 36000
GRID_WARP = 0.5                    # terrain grid spacing, edge / centre = 1 + 3 GRID_WARP
TEX = 4096                         # one square atlas
TERRAIN_CELL = 2560                # the terrain chart's cell: bottom-left TERRAIN_CELL^2 texels
MARGIN = 3                         # texels between a chart and its cell's border
TEXEL = 2 * SITE_HALF / (TERRAIN_CELL - 2 * MARGIN)      # metres per texel, every chart
SINK = 0.4                         # buildings reach this far below the lowest terrain under them

# footprint centre, size (along its own x, y), yaw, wall height above the highest terrain under
# it, optional gable ridge height above the eaves (ridge along the footprint's x), materials,
# face subdivision step
BUILDINGS = [
    dict(name="hall", centre=(-8.0, 6.0), size=(12.0, 8.0), yaw=0.0, height=6.0, walls="plaster",
         roof="gravel", step=1.2),
    dict(name="house", centre=(9.0, 8.0), size=(9.0, 6.5), yaw=20.0, height=3.8, ridge=2.4,
         walls="brick", roof="tiles", step=0.5),
    dict(name="tower", centre=(6.0, -9.0), size=(4.0, 4.0), yaw=0.0, height=9.0, walls="stone",
         roof="gravel", step=0.8),
    dict(name="wall", centre=(-6.0, -8.0), size=(16.0, 0.4), yaw=0.0, height=2.2, walls="concrete",
         roof="concrete", step=0.4),
    dict(name="lowwall", centre=(-14.5, -1.0), size=(9.0, 0.35), yaw=75.0, height=1.4, walls="stone",
         roof="stone", step=0.4),
]

WIDTH, HEIGHT, FOV = 512, 384, 60.0
# viewpoints, from just outside the terrain: azimuth of the eye around the site centre (deg), its
# horizontal distance from the centre, its height above the terrain (extended past the site), and
# how far toward the centre it looks (the target is that far from the eye horizontally, 0.5 m
# above the terrain). Low eyes on the axes, high ones at the corners.
VIEWS = [(-90, 25.0, 2.0, 14.0), (-45, 35.0, 15.0, 24.0), (0, 26.0, 5.0, 17.0), (45, 34.0, 11.0, 22.0),
         (90, 25.0, 3.0, 14.0), (135, 35.0, 13.0, 24.0), (180, 26.0, 7.0, 18.0), (225, 34.0, 9.0, 22.0)]
HELDOUT_VIEW = (160, 27.0, 6.0, 16.0)

LIGHTINGS = {
    "highsun": dict(sun=(sr.direction(62, -60), np.array([7.0e4, 6.7e4, 6.2e4])), sky_scale=0.8),
    "lowsun": dict(sun=(sr.direction(13, 150), np.array([3.2e4, 2.5e4, 1.6e4])), sky_scale=0.5),
    "hazy": dict(sun=(sr.direction(38, -150), np.array([3.6e4, 3.5e4, 3.3e4])), sky_scale=1.2, haze=0.6),
    "overcast": dict(sun=None),
    "heldout": dict(sun=(sr.direction(30, 95), np.array([4.5e4, 4.2e4, 3.6e4])), sky_scale=0.7),
}
SURVEY_LIGHTINGS = ["highsun", "lowsun", "hazy", "overcast"]


# ----------------------------------------------------------------------------- terrain
def terrain_function(rng):
    """Smooth heightfield h(x, y): a tilt and seven Gaussian bumps (sigma 4-11 m), scaled to
    RELIEF metres from the lowest to the highest point of the site."""
    c = rng.uniform(-SITE_HALF, SITE_HALF, (7, 2))
    s = rng.uniform(4.0, 11.0, 7)
    a = rng.uniform(-1.0, 1.0, 7)
    tilt = rng.uniform(-0.3, 0.3, 2)

    def raw(x, y):
        g = (tilt[0] * x + tilt[1] * y) / SITE_HALF
        for k in range(7):
            g = g + a[k] * np.exp(-((x - c[k, 0]) ** 2 + (y - c[k, 1]) ** 2) / (2 * s[k] ** 2))
        return g
    gx, gy = np.meshgrid(*(np.linspace(-SITE_HALF, SITE_HALF, 201),) * 2)
    g = raw(gx, gy)
    lo, hi = g.min(), g.max()
    return lambda x, y: RELIEF * (raw(x, y) - lo) / (hi - lo)


def footprint_axes(b):
    t = math.radians(b["yaw"])
    return np.array([math.cos(t), math.sin(t), 0.0]), np.array([-math.sin(t), math.cos(t), 0.0])


def inside_footprint(b, x, y):
    ex, ey = footprint_axes(b)
    dx, dy = x - b["centre"][0], y - b["centre"][1]
    return (np.abs(dx * ex[0] + dy * ex[1]) < b["size"][0] / 2) & (np.abs(dx * ey[0] + dy * ey[1]) < b["size"][1] / 2)


def terrain_grid(n, seed):
    """Vertex (x, y) of an (n+1)^2 grid over the site, warped finer toward the centre and jittered
    (interior vertices by up to 0.2 of the smaller neighbouring spacing per axis: no triangle flips)."""
    s = np.linspace(-1.0, 1.0, n + 1)
    g = SITE_HALF * (s + GRID_WARP * s ** 3) / (1 + GRID_WARP)
    d = np.minimum(np.diff(g)[:-1], np.diff(g)[1:])              # interior vertices
    rng = np.random.default_rng([seed, 2, n])
    x, y = np.meshgrid(g, g, indexing="ij")                        # [i, j]: i along x
    x[1:-1, 1:-1] += rng.uniform(-0.2, 0.2, (n - 1, n - 1)) * d[:, None]
    y[1:-1, 1:-1] += rng.uniform(-0.2, 0.2, (n - 1, n - 1)) * d[None, :]
    return x.ravel(), y.ravel(), rng.random((n, n)) < 0.5


def terrain_mesh(h, n, seed):
    """Terrain triangles (CCW from above, random diagonals), those under a building removed."""
    x, y, flip = terrain_grid(n, seed)
    i, j = np.meshgrid(np.arange(n), np.arange(n), indexing="ij")
    v00, v10, v01, v11 = i * (n + 1) + j, (i + 1) * (n + 1) + j, i * (n + 1) + j + 1, (i + 1) * (n + 1) + j + 1
    a = np.stack([np.stack([v00, v10, v11], -1), np.stack([v00, v11, v01], -1)], 2)
    b = np.stack([np.stack([v00, v10, v01], -1), np.stack([v10, v11, v01], -1)], 2)
    tris = np.where(flip[..., None, None], b, a).reshape(-1, 3)
    hidden = np.zeros(len(tris), bool)
    for bd in BUILDINGS:
        inside = inside_footprint(bd, x, y)
        hidden |= inside[tris].all(axis=1)
    tris = tris[~hidden]
    used, tris = np.unique(tris, return_inverse=True)
    pos = np.stack([x[used], y[used], h(x[used], y[used])], -1)
    tris = tris.reshape(-1, 3)
    e = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    assert np.all(e[:, 2] > 0), "terrain triangle flipped"
    nrm = np.zeros_like(pos)
    for k in range(3):
        np.add.at(nrm, tris[:, k], e)                              # area-weighted vertex normals
    return pos, nrm / np.linalg.norm(nrm, axis=1, keepdims=True), tris


# ----------------------------------------------------------------------------- building faces
def face(name, o, tu, tv, w, hgt, material, step, shape="rect"):
    """A planar face: p = o + a tu + b tv for (a, b) in [0, w] x [0, hgt] (a triangle (0, 0),
    (w, 0), (w/2, hgt) for a gable); tu x tv is its outward normal."""
    return dict(name=name, o=np.asarray(o, float), tu=np.asarray(tu, float), tv=np.asarray(tv, float),
                w=float(w), hgt=float(hgt), material=material, step=step, shape=shape)


def building_faces(b, h):
    """Walls (and gables) down to SINK below the lowest terrain under the footprint, and a flat
    roof or two roof slopes; no bottom."""
    ex, ey = footprint_axes(b)
    (lx, ly), up = b["size"], np.array([0.0, 0.0, 1.0])
    c = np.array([b["centre"][0], b["centre"][1], 0.0])
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 21), np.linspace(-0.5, 0.5, 21))
    ground = h(c[0] + u * lx * ex[0] + v * ly * ey[0], c[1] + u * lx * ex[1] + v * ly * ey[1])
    z0, z1 = ground.min() - SINK, ground.max() + b["height"]
    ridge = b.get("ridge", 0.0)
    out = []
    for k, (n, half, width) in enumerate(((ex, lx / 2, ly), (-ex, lx / 2, ly), (ey, ly / 2, lx), (-ey, ly / 2, lx))):
        tu = np.cross(up, n)
        o = c + n * half - tu * width / 2
        out.append(face(f"{b['name']}-wall{k}", o + up * z0, tu, up, width, z1 - z0, b["walls"], b["step"]))
        if ridge and k < 2:
            out.append(face(f"{b['name']}-gable{k}", o + up * z1, tu, up, width, ridge, b["walls"], b["step"], "tri"))
    if not ridge:
        corner = c - ex * lx / 2 - ey * ly / 2 + up * z1
        out.append(face(f"{b['name']}-roof", corner, ex, ey, lx, ly, b["roof"], b["step"]))
        return out
    for k, s in enumerate((1.0, -1.0)):
        eave = c + s * ey * ly / 2 + up * z1
        tv = (c + up * (z1 + ridge)) - eave
        slope = float(np.linalg.norm(tv))
        tu = ex if np.cross(ex, tv)[2] > 0 else -ex
        out.append(face(f"{b['name']}-roof{k}", eave - tu * lx / 2, tu, tv / slope, lx, slope, b["roof"], b["step"]))
    return out


def face_grid(f):
    """(a, b) plane coordinates and CCW triangles of a face, subdivided at about f['step']."""
    if f["shape"] == "rect":
        na, nb = (max(1, math.ceil(L / f["step"])) for L in (f["w"], f["hgt"]))
        a, b = np.meshgrid(np.linspace(0, f["w"], na + 1), np.linspace(0, f["hgt"], nb + 1), indexing="ij")
        i, j = np.meshgrid(np.arange(na), np.arange(nb), indexing="ij")
        v00, v10, v01, v11 = i * (nb + 1) + j, (i + 1) * (nb + 1) + j, i * (nb + 1) + j + 1, (i + 1) * (nb + 1) + j + 1
        tris = np.concatenate([np.stack([v00, v10, v11], -1).reshape(-1, 3),
                               np.stack([v00, v11, v01], -1).reshape(-1, 3)])
        return np.stack([a.ravel(), b.ravel()], -1), tris
    n = max(1, math.ceil(max(f["w"], f["hgt"]) / f["step"]))          # gable: barycentric lattice
    idx = {(i, j): k for k, (i, j) in enumerate((i, j) for i in range(n + 1) for j in range(n + 1 - i))}
    corner = np.array([[0.0, 0.0], [f["w"], 0.0], [f["w"] / 2, f["hgt"]]])
    ab = np.array([corner[0] + (corner[1] - corner[0]) * i / n + (corner[2] - corner[0]) * j / n for i, j in idx])
    tris = [(idx[i, j], idx[i + 1, j], idx[i, j + 1]) for i, j in idx if i + j < n]
    tris += [(idx[i + 1, j], idx[i + 1, j + 1], idx[i, j + 1]) for i, j in idx if i + j < n - 1]
    return ab, np.array(tris)


# ----------------------------------------------------------------------------- atlas charts
def terrain_chart(h):
    return dict(face("terrain", (-SITE_HALF, -SITE_HALF, 0.0), (1, 0, 0), (0, 1, 0), 2 * SITE_HALF, 2 * SITE_HALF,
                     "ground", None), h=h, X0=0, Y0=0, cw=TERRAIN_CELL, ch=TERRAIN_CELL)


def pack_charts(faces):
    """Give each face a cell (X0, Y0, cw, ch) in texels from the bottom-left corner: shelf
    packing, tallest first, into the texture right of the terrain cell, then above it."""
    regions = [(TERRAIN_CELL, 0, TEX - TERRAIN_CELL, TEX), (0, TERRAIN_CELL, TERRAIN_CELL, TEX - TERRAIN_CELL)]
    for f in faces:
        f["cw"], f["ch"] = (math.ceil(L / TEXEL) + 2 * MARGIN for L in (f["w"], f["hgt"]))
    r = 0
    x, y, shelf = regions[0][0], regions[0][1], 0
    for f in sorted(faces, key=lambda f: -f["ch"]):
        while True:
            rx, ry, rw, rh = regions[r]
            assert f["cw"] <= rw, f"chart {f['name']} wider than the atlas region"
            if x + f["cw"] > rx + rw:
                x, y, shelf = rx, y + shelf, 0
            if y + f["ch"] <= ry + rh:
                break
            r += 1
            assert r < len(regions), "the charts do not fit in the atlas"
            x, y, shelf = regions[r][0], regions[r][1], 0
        f["X0"], f["Y0"] = x, y
        x, shelf = x + f["cw"], max(shelf, f["ch"])
    return faces


def chart_uv(c, a, b):
    return np.stack([(c["X0"] + MARGIN + a / TEXEL) / TEX, (c["Y0"] + MARGIN + b / TEXEL) / TEX], -1)


def chart_world(c, a, b):
    """World position of plane coordinates (a, b), past the chart's edges too; the terrain chart
    lies on the heightfield."""
    p = c["o"] + a[..., None] * c["tu"] + b[..., None] * c["tv"]
    if c.get("h") is not None:
        p[..., 2] = c["h"](p[..., 0], p[..., 1])
    return p


def chart_ab(c, p):
    d = np.asarray(p, float) - c["o"]
    return d @ c["tu"], d @ c["tv"]


# ----------------------------------------------------------------------------- albedo patterns
HASH = 1024                        # lattice tables repeat every HASH cells (> 44 m / 5 cm)
PAT = {}


def seed_patterns(seed):
    rng = np.random.default_rng([seed, 3])
    PAT["val"] = rng.uniform(-1.0, 1.0, (HASH, HASH, 3))
    PAT["jit"] = rng.uniform(0.0, 1.0, (HASH, HASH, 2))


def lattice(i, j, off):
    """Random RGB in [-1, 1] of lattice cell (i, j); `off` decorrelates patterns."""
    return PAT["val"][(i + off) % HASH, (j + 3 * off) % HASH]


def noise2(a, b, cell, off):
    """Smooth (C1) value noise, RGB in [-1, 1], features about `cell` metres across."""
    fa, fb = a / cell, b / cell
    i, j = np.floor(fa).astype(np.int64), np.floor(fb).astype(np.int64)
    s, t = fa - i, fb - j
    s, t = (s * s * (3 - 2 * s))[..., None], (t * t * (3 - 2 * t))[..., None]
    return ((1 - s) * (1 - t) * lattice(i, j, off) + s * (1 - t) * lattice(i + 1, j, off)
            + (1 - s) * t * lattice(i, j + 1, off) + s * t * lattice(i + 1, j + 1, off))


def voronoi(a, b, cell, off):
    """Cells around jittered lattice points `cell` metres apart (gravel, speckle): the RGB of the
    nearest point's cell and the gap to the second nearest (in cells, 0 on a cell border)."""
    fa, fb = a / cell, b / cell
    i, j = np.floor(fa).astype(np.int64), np.floor(fb).astype(np.int64)
    best, second = np.full(fa.shape, np.inf), np.full(fa.shape, np.inf)
    bi, bj = i.copy(), j.copy()
    for di in (-1, 0, 1):
        for dj in (-1, 0, 1):
            ii, jj = i + di, j + dj
            jit = PAT["jit"][(ii + off) % HASH, (jj + 5 * off) % HASH]
            d = (ii + jit[..., 0] - fa) ** 2 + (jj + jit[..., 1] - fb) ** 2
            closer = d < best
            second = np.where(closer, best, np.minimum(second, d))
            bi, bj, best = np.where(closer, ii, bi), np.where(closer, jj, bj), np.where(closer, d, best)
    return lattice(bi, bj, off + 11), np.sqrt(second) - np.sqrt(best)


def bond(a, b, length, height, joint, off, shift=0.5):
    """Running bond of length x height units (bricks, blocks, tiles): each unit's RGB and a
    joint mask `joint` metres wide."""
    row = np.floor(b / height).astype(np.int64)
    s = a / length + shift * (row % 2)
    col = np.floor(s).astype(np.int64)
    mortar = ((s - col) * length < joint) | (b - row * height < joint)
    return lattice(col, row, off), mortar[..., None]


def tint(v, lum, chroma):
    """Random RGB v in [-1, 1] as mostly a brightness change (lum) with some colour (chroma)."""
    return lum * v[..., :1] + chroma * v


def material(kind, off, contrast):
    """Logit-space albedo of plane coordinates (a, b) in metres: 1 and 3.5 m patches plus 5-10 cm
    structure at `contrast` (1: full); squashed into (0.05, 0.85) by `albedo`."""
    def f(a, b):
        patches = tint(noise2(a, b, 1.0, off), 0.5, 0.25) + tint(noise2(a, b, 3.5, off + 1), 0.3, 0.15)
        if kind == "ground":
            region = noise2(a, b, 8.0, off + 2)[..., :1]
            stones, gap = voronoi(a, b, 0.06, off + 3)
            gravel = np.array([0.15, 0.05, -0.2]) + tint(stones, 0.45, 0.15) - 0.7 * (gap < 0.12)[..., None]
            tiles, joint = bond(a, b, 0.10, 0.10, 0.015, off + 4, shift=0.0)
            paving = np.where(joint, -0.6, np.array([0.4, 0.3, 0.2]) + tint(tiles, 0.3, 0.12))
            blades, _ = voronoi(a, b, 0.05, off + 5)
            grass = np.array([-0.7, 0.05, -0.9]) + tint(blades, 0.3, 0.15)
            fine = np.where(region > 0.25, paving, np.where(region < -0.3, grass, gravel))
        elif kind == "brick":
            units, joint = bond(a, b, 0.24, 0.08, 0.02, off + 3)
            fine = np.where(joint, np.array([0.4, 0.35, 0.2]), np.array([0.35, -0.3, -0.6]) + tint(units, 0.35, 0.15))
        elif kind == "stone":
            units, joint = bond(a, b, 0.40, 0.20, 0.02, off + 3)
            speck, _ = voronoi(a, b, 0.05, off + 4)
            fine = np.where(joint, -0.5, np.array([0.2, 0.15, 0.0]) + tint(units, 0.3, 0.1) + tint(speck, 0.2, 0.05))
        elif kind == "plaster":
            speck, _ = voronoi(a, b, 0.05, off + 3)
            stripes = (b > 2.0) & (b < 2.64) & (np.floor(a / 0.08) % 2 == 0)
            fine = np.where(stripes[..., None], np.array([-0.5, -0.2, 0.5]),
                            np.array([0.7, 0.55, 0.3]) + tint(speck, 0.2, 0.05))
        elif kind == "concrete":
            boards = lattice(np.floor(b / 0.10).astype(np.int64), np.zeros_like(b, np.int64), off + 3)[..., :1]
            speck, _ = voronoi(a, b, 0.04, off + 4)
            fine = np.array([0.05, 0.05, 0.0]) + 0.25 * boards + tint(speck, 0.15, 0.03)
        elif kind == "tiles":
            units, joint = bond(a, b, 0.20, 0.08, 0.012, off + 3)
            fine = np.where(joint, -0.6, np.array([0.45, -0.35, -0.7]) + tint(units, 0.35, 0.1))
        else:                                                           # gravel roof
            stones, gap = voronoi(a, b, 0.05, off + 3)
            fine = np.array([-0.1, -0.1, -0.1]) + tint(stones, 0.5, 0.15) - 0.5 * (gap < 0.12)[..., None]
        return contrast * fine + patches
    return f


def albedo(c, p):
    """The albedo function of world position on chart c, values in (0.05, 0.85)."""
    return 0.45 + 0.4 * np.tanh(c["logits"](*chart_ab(c, p)))


def make_texture(charts):
    """FORMATS.md texture (row 0 = top, v up): each chart's albedo at the world positions of its
    cell's texel centres; texels outside every cell 0.45."""
    img = np.full((TEX, TEX, 3), 0.45, np.float32)
    for c in charts:
        cols = np.arange(c["X0"], c["X0"] + c["cw"])
        for r0 in range(c["Y0"], c["Y0"] + c["ch"], 128):
            rows = np.arange(r0, min(r0 + 128, c["Y0"] + c["ch"]))           # from the bottom
            a, b = np.meshgrid((cols + 0.5 - c["X0"] - MARGIN) * TEXEL, (rows + 0.5 - c["Y0"] - MARGIN) * TEXEL)
            img[TEX - 1 - rows, c["X0"]:c["X0"] + c["cw"]] = albedo(c, chart_world(c, a, b))
    return img


# ----------------------------------------------------------------------------- the site
def build_site(seed, contrast):
    """One mesh: terrain and building faces, one atlas. Returns the mesh (pos, nrm, uv, tris),
    each triangle's chart index and the charts."""
    rng = np.random.default_rng([seed, 1])
    h = terrain_function(rng)
    faces = pack_charts([f for b in BUILDINGS for f in building_faces(b, h)])
    charts = [terrain_chart(h)] + faces
    for k, c in enumerate(charts):
        c["logits"] = material(c["material"], 97 * k + 13, contrast)
    parts = []
    for k, f in enumerate(faces, start=1):
        ab, tris = face_grid(f)
        n = np.tile(np.cross(f["tu"], f["tv"]), (len(ab), 1))
        parts.append((chart_world(f, ab[:, 0], ab[:, 1]), n, chart_uv(f, ab[:, 0], ab[:, 1]), tris, k))
    n_buildings = sum(len(p[3]) for p in parts)
    n = next(n for n in range(60, 400) if len(terrain_mesh(h, n, seed)[2]) >= TARGET_TRIANGLES - n_buildings)
    pos, nrm, tris = terrain_mesh(h, n, seed)
    uv = chart_uv(charts[0], pos[:, 0] + SITE_HALF, pos[:, 1] + SITE_HALF)
    parts.insert(0, (pos, nrm, uv, tris, 0))
    mesh = ref.merge([p[:4] for p in parts])
    tri_chart = np.concatenate([np.full(len(p[3]), p[4]) for p in parts])
    return mesh, tri_chart, charts, dict(terrain_grid=n, terrain_triangles=len(tris), building_triangles=n_buildings)


# ----------------------------------------------------------------------------- lighting and cameras
def use_lightings():
    """survey_reference's make_sky and lighting_toml look lightings up by name in its table."""
    sr.LIGHTINGS.clear()
    sr.LIGHTINGS.update(LIGHTINGS)


def make_sky(name):
    """survey_reference's clear or overcast sky; a hazy one mixes in a scaled overcast sky."""
    sky = sr.make_sky(name)
    haze = LIGHTINGS[name].get("haze", 0.0)
    if haze:
        d = ref.latlong_pixel_dirs(sr.SKY_W, sr.SKY_H)
        sky = (1 - haze) * sky + haze * LIGHTINGS[name]["sky_scale"] * sr.overcast_radiance(d, zenith=2.0)
    return sky.astype(np.float32)


def lighting_toml(name, sky_file):
    return sr.lighting_toml(name, sky_file).replace("survey_reference.py", "large_survey.py")


def viewpoint(h, az_deg, r, height, reach):
    """(eye, target): the eye `r` m from the site centre at azimuth az_deg, `height` m above the
    terrain, looking `reach` m toward the centre at a point 0.5 m above the terrain."""
    d = np.array([math.cos(math.radians(az_deg)), math.sin(math.radians(az_deg))])
    e, t = r * d, (r - reach) * d
    eye = np.array([e[0], e[1], float(h(e[0], e[1])) + height])
    target = np.array([t[0], t[1], float(h(t[0], t[1])) + 0.5])
    assert 10.0 <= np.linalg.norm(eye - target) <= 30.0
    return eye, target


def shots(h):
    """(id, eye, target, lighting) of the 32 survey photographs, and of the held-out one."""
    out = []
    for k, v in enumerate(VIEWS):
        eye, target = viewpoint(h, *v)
        out += [(f"v{k}-{light}", eye, target, light) for light in SURVEY_LIGHTINGS]
    return out, ("heldout",) + viewpoint(h, *HELDOUT_VIEW) + ("heldout",)


# ----------------------------------------------------------------------------- self-checks
def function_lookup(c, u, v):
    """The FORMATS.md bilinear texel lookup at (u, v), the four texels computed from the albedo
    function at their centres' world positions on chart c (what the texture should hold)."""
    x, y = u * TEX - 0.5, (1.0 - v) * TEX - 0.5
    j, i = math.floor(x), math.floor(y)
    fx, fy = x - j, y - i
    jj, ii = np.array([j, j + 1, j, j + 1]), np.array([i, i, i + 1, i + 1])
    a = (jj + 0.5 - c["X0"] - MARGIN) * TEXEL
    b = (TEX - 1 - ii + 0.5 - c["Y0"] - MARGIN) * TEXEL
    w = np.array([(1 - fx) * (1 - fy), fx * (1 - fy), (1 - fx) * fy, fx * fy])
    return w @ albedo(c, chart_world(c, a, b))


def check_texture(ply, tex_path, tex, mesh, tri_chart, charts, seed):
    """(d) Mitsuba's BSDF at ray hits on random triangles vs the FORMATS.md texel lookup at the
    PLY's (u, v), and vs the same lookup of the albedo function at the texel centres' world
    positions (the hit's chart map taken back from the hit point); the difference from the
    function at the hit itself (bilinear reconstruction of 5 cm detail) is reported."""
    scene = mi.load_dict({"type": "scene", "site": {"type": "ply", "filename": ply, "bsdf": ref.diffuse(tex_path)}})
    bsdf = scene.shapes()[0].bsdf()
    pos, _, uv, tris = mesh
    rng = np.random.default_rng([seed, 17])
    worst_tex, worst_fn, worst_uv, dev = 0.0, 0.0, 0.0, []
    for k in rng.choice(len(tris), 400, replace=False):
        b = rng.dirichlet([1, 1, 1])
        p, uv_ref, c = b @ pos[tris[k]], b @ uv[tris[k]], charts[tri_chart[k]]
        n = np.cross(pos[tris[k][1]] - pos[tris[k][0]], pos[tris[k][2]] - pos[tris[k][0]])
        n /= np.linalg.norm(n)
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*(p + 0.01 * n)), mi.Vector3f(*(-n))))
        if not si.is_valid() or si.prim_index != k:
            continue
        assert abs(si.uv[0] - uv_ref[0]) < 1e-5 and abs(si.uv[1] - uv_ref[1]) < 1e-5
        worst_uv = max(worst_uv, float(np.max(np.abs(chart_uv(c, *chart_ab(c, p)) - uv_ref))) * TEX)
        v_mi = np.array(bsdf.eval_diffuse_reflectance(si), dtype=float)
        worst_tex = max(worst_tex, float(np.max(np.abs(v_mi - ref.texture_lookup(tex, uv_ref[0], uv_ref[1])))))
        worst_fn = max(worst_fn, float(np.max(np.abs(v_mi - function_lookup(c, uv_ref[0], uv_ref[1])))))
        dev.append(float(np.max(np.abs(v_mi - albedo(c, p)))))
    assert len(dev) > 300 and worst_tex < 2e-3 and worst_fn < 2e-3 and worst_uv < 0.01, \
        (len(dev), worst_tex, worst_fn, worst_uv)
    dev = np.array(dev)
    assert np.median(dev) < 0.05, np.median(dev)
    return dict(hits=len(dev), vs_texel_lookup_max_abs=worst_tex, vs_function_at_texel_centres_max_abs=worst_fn,
                chart_map_max_texels=worst_uv, vs_albedo_function_median_abs=float(np.median(dev)),
                vs_albedo_function_p90_abs=float(np.percentile(dev, 90)), vs_albedo_function_max_abs=float(dev.max()))


def check_uv_cells(mesh, tri_chart, charts):
    """(e) every vertex's UV lies inside its chart's cell by MARGIN texels (bilinear lookups stay
    in the cell), and the cells do not overlap."""
    _, _, uv, tris = mesh
    worst = np.inf
    for k, c in enumerate(charts):
        t = uv[tris[tri_chart == k]].reshape(-1, 2) * TEX
        inset = np.concatenate([t[:, 0] - c["X0"], c["X0"] + c["cw"] - t[:, 0],
                                t[:, 1] - c["Y0"], c["Y0"] + c["ch"] - t[:, 1]])
        worst = min(worst, float(inset.min()))
    assert worst >= MARGIN - 1e-3, worst
    cover = np.zeros((TEX, TEX), np.int8)
    for c in charts:
        cover[c["Y0"]:c["Y0"] + c["ch"], c["X0"]:c["X0"] + c["cw"]] += 1
    assert cover.max() == 1, "chart cells overlap"
    return worst


def coverage(ply, cams, mesh, tri_chart, h, seed, n=20000):
    """(f) Fraction of the surface (above the terrain) that the viewpoints see: points spread by
    area, each counted in a viewpoint when in front of its camera, inside its frame, facing it and
    unoccluded (Mitsuba ray tests, vectorised: run under llvm_ad_rgb)."""
    scene = mi.load_dict({"type": "scene", "site": {"type": "ply", "filename": ply}})
    pos, _, _, tris = mesh
    e = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    area = np.linalg.norm(e, axis=1)
    rng = np.random.default_rng([seed, 19])
    k = rng.choice(len(tris), n, p=area / area.sum())
    b = rng.dirichlet([1, 1, 1], n)
    p = np.einsum("nk,nkd->nd", b, pos[tris[k]])
    nrm = e[k] / area[k, None]
    keep = (tri_chart[k] == 0) | (p[:, 2] > h(p[:, 0], p[:, 1]) + 0.02)
    p, nrm, k = p[keep], nrm[keep], k[keep]
    seen = np.zeros((len(cams), len(p)), bool)
    for c, cam in enumerate(cams):
        R, t, K = np.array(cam["R"]), np.array(cam["t"]), np.array(cam["K"])
        x = p @ R.T + t
        u, v = K[0, 0] * x[:, 0] / x[:, 2] + K[0, 2], K[1, 1] * x[:, 1] / x[:, 2] + K[1, 2]
        eye = -R.T @ t
        d = eye - p
        dist = np.linalg.norm(d, axis=1)
        o = p + 2e-3 * nrm
        ray = mi.Ray3f(mi.Point3f(*o.T), mi.Vector3f(*(d / dist[:, None]).T))
        ray.maxt = mi.Float(dist * (1 - 1e-4))
        hidden = np.array(scene.ray_test(ray), dtype=bool)
        seen[c] = (x[:, 2] > 0.1) & (u > -0.5) & (u < cam["width"] - 0.5) & (v > -0.5) & (v < cam["height"] - 0.5) \
            & (np.sum(nrm * d, axis=1) > 0) & ~hidden
    views = seen.sum(0)
    terrain = tri_chart[k] == 0
    frac = lambda m, sel: float(np.mean(m[sel]))
    return {"points": int(len(p)), "seen_by_1": frac(views >= 1, slice(None)), "seen_by_2": frac(views >= 2, slice(None)),
            "terrain_seen_by_2": frac(views >= 2, terrain), "buildings_seen_by_2": frac(views >= 2, ~terrain),
            "per_viewpoint": [float(s.mean()) for s in seen]}


# ----------------------------------------------------------------------------- the survey folder
def write_inputs(out, seed, contrast):
    """Mesh, truth texture and scene file, skies and lighting files, cameras; returns the site."""
    mesh, tri_chart, charts, counts = build_site(seed, contrast)
    S = dict(mesh=mesh, tri_chart=tri_chart, charts=charts, counts=counts, h=charts[0]["h"],
             ply=os.path.join(out, "geometry", "site.ply"), tex_path=os.path.join(out, "truth", "site_albedo.exr"))
    ref.write_ply(S["ply"], *mesh)
    S["tex"] = make_texture(charts)
    ref.write_exr(S["tex_path"], S["tex"])
    ref.write_text(os.path.join(out, "truth", "scene.toml"),
                   "# Generated by datasets/mitsuba/large_survey.py: the true albedo texture.\n"
                   "# igi solve SURVEY --truth truth/scene.toml; lit by the held-out lighting.\n"
                   "lighting = \"../heldout/lighting.toml\"\n\n[[object]]\nmesh = \"../geometry/site.ply\"\n"
                   "albedo = \"site_albedo.exr\"\n")
    S["skies"] = {name: make_sky(name) for name in LIGHTINGS}
    for name, sky in S["skies"].items():
        folder, stem = ("heldout", "") if name == "heldout" else ("lighting", f"{name}_")
        ref.write_exr(os.path.join(out, folder, f"{stem}sky.exr"), sky)
        ref.write_text(os.path.join(out, folder, "lighting.toml" if name == "heldout" else f"{name}.toml"),
                       lighting_toml(name, f"{stem}sky.exr"))
    S["photos"], S["heldout"] = shots(S["h"])
    S["cams"] = {pid: sr.opencv_camera(eye, target, WIDTH, HEIGHT, FOV)
                 for pid, eye, target, _ in S["photos"] + [S["heldout"]]}
    for pid, cam in S["cams"].items():
        path = os.path.join(out, "heldout", "camera.json") if pid == "heldout" else os.path.join(out, "cameras", f"{pid}.json")
        ref.write_text(path, json.dumps(cam, indent=2) + "\n")
    return S


def survey_toml(S):
    t = ("# Generated by datasets/mitsuba/large_survey.py (Mitsuba 3 ground truth).\n"
         "[site]\nmeshes = [\"geometry/site.ply\"]\n")
    for pid, _, _, light in S["photos"]:
        t += (f"\n[[photo]]\nid = \"{pid}\"\nimage = \"photos/{pid}.exr\"\ncamera = \"cameras/{pid}.json\"\n"
              f"lighting = \"lighting/{light}.toml\"\n")
    return t


def check_camera(cam, markers):
    """survey_reference's check (a) on the markers in front of the camera whose images lie 16 px
    or more apart (its 13 px centroid windows would otherwise hold two)."""
    R, t = np.array(cam["R"]), np.array(cam["t"])
    kept = []
    for p in markers:
        uv = sr.project(cam, p)
        if (R @ p + t)[2] > 0.5 and all(np.linalg.norm(uv - sr.project(cam, q)) >= 16 for q in kept):
            kept.append(p)
    return sr.check_camera(cam, kept)


def run_checks(S, work):
    """(a)-(e) under scalar_rgb, as survey_reference.py does."""
    h = S["h"]
    markers = [np.array([x, y, float(h(x, y)) + 0.3]) for x in np.linspace(-18, 18, 5) for y in np.linspace(-18, 18, 5)]
    checks = {"camera_max_px_error": {}}
    for pid in (S["photos"][0][0], S["photos"][4][0], "heldout"):
        checks["camera_max_px_error"][pid] = check_camera(S["cams"][pid], markers)
    print(f"(a) camera: marker centroids vs OpenCV projection, max {max(checks['camera_max_px_error'].values()):.4f} px")
    checks["envmap_max_rel_diff"], checks["sun_irradiance_rel_error"] = {}, {}
    for name, sky in S["skies"].items():
        p = os.path.join(work, f"check_sky_{name}.exr")
        ref.write_exr(p, ref.mitsuba_sky(sky))
        sun = LIGHTINGS[name]["sun"]
        checks["envmap_max_rel_diff"][name] = sr.check_envmap(sky, p, None if sun is None else sun[0])
        if sun is not None:
            checks["sun_irradiance_rel_error"][name] = sr.check_sun((sun[0], sun[1], sr.SUN_DIAMETER_DEG))
    print(f"(b) envmap vs FORMATS lat-long lookup, max rel {max(checks['envmap_max_rel_diff'].values()):.2e}")
    print(f"(c) sun irradiance vs L omega cos, max rel {max(checks['sun_irradiance_rel_error'].values()):.2e}")
    t = checks["texture"] = check_texture(S["ply"], S["tex_path"], S["tex"], S["mesh"], S["tri_chart"], S["charts"], 0)
    print(f"(d) texture at {t['hits']} hits: vs texel lookup max {t['vs_texel_lookup_max_abs']:.1e}, vs albedo function "
          f"at texel centres max {t['vs_function_at_texel_centres_max_abs']:.1e}, chart map max "
          f"{t['chart_map_max_texels']:.1e} texels; vs albedo function at the hit median "
          f"{t['vs_albedo_function_median_abs']:.3f}, p90 {t['vs_albedo_function_p90_abs']:.3f}, "
          f"max {t['vs_albedo_function_max_abs']:.3f} (bilinear reconstruction)")
    checks["uv_min_inset_texels"] = check_uv_cells(S["mesh"], S["tri_chart"], S["charts"])
    print(f"(e) UVs inside their chart cells by >= {checks['uv_min_inset_texels']:.3f} texels; cells disjoint")
    return checks


def render_photos(out, S, spp, seed, work):
    """The 32 photographs: each the mean of two halves of spp/2 (their spread gives the noise)."""
    objects = sr.read_scene_file(os.path.join(out, "truth", "scene.toml"))
    pass_spp = math.gcd(spp // 2, 32)
    meta, t0 = [], time.time()
    for k, (pid, eye, target, light) in enumerate(S["photos"]):
        t1 = time.time()
        scene = mi.load_dict(sr.mitsuba_scene(objects, S["cams"][pid], os.path.join(out, "lighting", f"{light}.toml"), work))
        mean, se = sr.render_mean(scene, spp // 2, [1000 * seed + 2 * k + 1, 1000 * seed + 2 * k + 2], pass_spp)
        ref.write_exr(os.path.join(out, "photos", f"{pid}.exr"), mean)
        rel = float(np.median(se / np.maximum(mean, 1e-6)))
        lum = mean.mean(axis=2)
        meta.append({"id": pid, "lighting": light, "eye": eye.tolist(), "target": target.tolist(), "spp": spp,
                     "seconds": round(time.time() - t1, 1), "mean_radiance": mean.reshape(-1, 3).mean(0).tolist(),
                     "radiance_percentiles_1_50_99": np.percentile(lum, [1, 50, 99]).tolist(),
                     "median_relative_stderr": rel})
        eta = (time.time() - t0) / (k + 1) * (len(S["photos"]) - k - 1)
        print(f"photo {pid}: {time.time() - t1:.1f} s, median relative standard error {100 * rel:.2f} %, "
              f"{eta / 60:.1f} min to go", flush=True)
    return meta, time.time() - t0


def render_heldout(out, S, renders, spp, seed, work):
    objects = sr.read_scene_file(os.path.join(out, "truth", "scene.toml"))
    t0 = time.time()
    scene = mi.load_dict(sr.mitsuba_scene(objects, S["cams"]["heldout"], os.path.join(out, "heldout", "lighting.toml"), work))
    mean, se = sr.render_mean(scene, spp, [1000 * seed + 901 + k for k in range(renders)], math.gcd(spp, 32))
    ref.write_exr(os.path.join(out, "heldout", "photo.exr"), mean)
    ref.write_exr(os.path.join(out, "heldout", "photo_stderr.exr"), se)
    print(f"held-out: {renders} x {spp} spp, {time.time() - t0:.1f} s", flush=True)
    return {"renders": renders, "spp_per_render": spp, "total_spp": renders * spp, "eye": S["heldout"][1].tolist(),
            "target": S["heldout"][2].tolist(), "seconds": round(time.time() - t0, 1),
            "mean_radiance": mean.reshape(-1, 3).mean(0).tolist(),
            "mean_relative_stderr": float((se / np.maximum(mean, 1e-6)).mean())}


def site_meta(S):
    pos, _, _, tris = S["mesh"]
    e = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    area = np.linalg.norm(e, axis=1) / 2
    used = sum(c["cw"] * c["ch"] for c in S["charts"]) / TEX ** 2
    return {"extent_m": [2 * SITE_HALF, 2 * SITE_HALF], "relief_m": RELIEF, "triangles": int(len(tris)),
            "vertices": int(len(pos)), **S["counts"], "surface_m2": float(area.sum()),
            "triangle_area_m2_percentiles_1_50_99": np.percentile(area, [1, 50, 99]).tolist(),
            "buildings": [dict(b) for b in BUILDINGS],
            "texture": {"size": [TEX, TEX], "texel_m": TEXEL, "margin_texels": MARGIN, "charts": len(S["charts"]),
                        "cells_fill_fraction": used, "terrain_cell_texels": [0, 0, TERRAIN_CELL, TERRAIN_CELL],
                        "range": [float(S["tex"].min()), float(S["tex"].max())],
                        "cells": [{"name": c["name"], "material": c["material"], "X0": c["X0"], "Y0_from_bottom": c["Y0"],
                                   "texels": [c["cw"], c["ch"]], "metres": [c["w"], c["hgt"]]} for c in S["charts"]]}}


def lighting_meta():
    return {n: {"sun_direction": None if l["sun"] is None else l["sun"][0].tolist(),
                "sun_radiance": None if l["sun"] is None else l["sun"][1].tolist(),
                "sky_scale": l.get("sky_scale"), "haze": l.get("haze", 0.0)} for n, l in LIGHTINGS.items()}


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", required=True, help="survey folder, outside the repository")
    ap.add_argument("--fine-contrast", type=float, default=0.25,
                    help="contrast of the 5-10 cm structure in logit space (1: full; the default keeps "
                         "it within what 3-6 cm pixels resolve, as on the survey the issue measured)")
    ap.add_argument("--spp", type=int, default=64, help="samples per pixel of each survey photo (even)")
    ap.add_argument("--seed", type=int, default=1, help="terrain, albedo patterns and Mitsuba seeds (0-3999)")
    ap.add_argument("--heldout-renders", type=int, default=4, help="M independent renders of the held-out photo")
    ap.add_argument("--heldout-spp", type=int, default=None, help="samples per pixel of each (default --spp)")
    ap.add_argument("--checks-only", action="store_true", help="write the inputs, run the checks, render nothing")
    args = ap.parse_args()
    out = os.path.abspath(args.out)
    if out == ROOT or out.startswith(ROOT + os.sep):
        ap.error("write the survey outside the repository (it is about 170 MB)")
    if args.spp < 2 or args.spp % 2 or not 0 <= args.seed < 4000 or args.heldout_renders < 2:
        ap.error("--spp must be even, --seed in 0..3999, --heldout-renders at least 2")
    for sub in ("geometry", "photos", "cameras", "lighting", "truth", "heldout"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)
    work = tempfile.mkdtemp(prefix="igi-large-survey-")
    mi.set_variant("scalar_rgb")
    use_lightings()
    seed_patterns(args.seed)

    t0 = time.time()
    S = write_inputs(out, args.seed, args.fine_contrast)
    print(f"inputs: {len(S['mesh'][3])} triangles, texture {TEX} x {TEX} at {100 * TEXEL:.2f} cm, "
          f"{time.time() - t0:.1f} s", flush=True)
    t0 = time.time()
    checks = run_checks(S, work)
    mi.set_variant("llvm_ad_rgb" if sr.llvm_path() else "scalar_rgb")
    per_view = [S["cams"][pid] for pid, *_ in S["photos"][::len(SURVEY_LIGHTINGS)]]
    checks["coverage"] = cov = coverage(S["ply"], per_view, S["mesh"], S["tri_chart"], S["h"], args.seed)
    print(f"(f) surface seen by >= 1 viewpoint {100 * cov['seen_by_1']:.1f} %, by >= 2 {100 * cov['seen_by_2']:.1f} % "
          f"(terrain {100 * cov['terrain_seen_by_2']:.1f} %, buildings {100 * cov['buildings_seen_by_2']:.1f} %)")
    assert cov["seen_by_2"] > 0.5, cov
    print(f"self-checks: {time.time() - t0:.1f} s", flush=True)
    if args.checks_only:
        shutil.rmtree(work)
        return 0

    photos, seconds = render_photos(out, S, args.spp, args.seed, work)
    ref.write_text(os.path.join(out, "survey.toml"), survey_toml(S))
    heldout = render_heldout(out, S, args.heldout_renders, args.heldout_spp or args.spp, args.seed, work)
    meta = {"generator": f"datasets/mitsuba/large_survey.py --spp {args.spp} --seed {args.seed} --fine-contrast {args.fine_contrast}",
            "mitsuba": mi.__version__, "variant": mi.variant(),
            "integrator": {"type": "path", "max_depth": sr.MAX_DEPTH, "hide_emitters": False}, "rfilter": "box",
            "image_size": [WIDTH, HEIGHT], "fov_x_deg": FOV, "site": site_meta(S), "lightings": lighting_meta(),
            "photos": photos, "photo_seconds": round(seconds, 1), "seconds_per_photo": round(seconds / len(photos), 1),
            "photo_median_relative_stderr_range": [min(p["median_relative_stderr"] for p in photos),
                                                   max(p["median_relative_stderr"] for p in photos)],
            "heldout": heldout, "self_checks": checks}
    ref.write_text(os.path.join(out, "survey_meta.json"), json.dumps(meta, indent=2) + "\n")
    print(json.dumps({k: meta[k] for k in ("photo_seconds", "seconds_per_photo", "photo_median_relative_stderr_range")}))
    shutil.rmtree(work)
    return 0


if __name__ == "__main__":
    sys.exit(main())
