#!/usr/bin/env python3
"""A surface-light-field capture rendered by Mitsuba 3 (issue 32, item 2): a glossy object under a
small bright light, in the multi-view capture format `igi slf build` reads (FORMATS.md).

The Stanford bunny (../shared/data, bun_zipper_res3, turned Z up, centred, 1 unit tall) as rough
plastic (Mitsuba `roughplastic`: GGX alpha 0.12, IOR 1.49, over a diffuse 0.45 / 0.30 / 0.18)
under a dim sky (blue zenith, paler horizon, dim ground) with a 4-degree spot whose radiance is 30
times the sky's mean radiance over the upper hemisphere. VIEWS cameras on a Fibonacci sphere at
distance 3 looking at the origin (igi's look_at convention, square pixels, f = 1.6 x size), SPP
samples per pixel; HELD_OUT new views (directions no capture view has) at TRUTH_SPP (1024: two truths of
different seeds differ by a relative RMSE of 0.024 on the object, at 256 spp by 0.048).

Writes OUT/ (default /tmp/slf_gloss):
  rig.toml, cameras/vNN.json, photos/vNN.exr   the capture (linear EXR, no masks)
  mesh.ply                                     the true mesh (positions, the vertex normals
                                               Mitsuba shaded with: area-weighted, as igi computes)
  heldout/hK.json, heldout/hK.exr              the new views and their truth
  meta.json                                    the settings, the spot direction, render times

Mitsuba is only a generator of test data, never a dependency of igi.
Usage: python3 datasets/mitsuba/slf_gloss.py [--out DIR] [--size 256] [--views 96] [--spp 64]
           [--truth-spp 1024] [--held-out 6]
"""

import argparse
import json
import math
import os
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
import survey_reference as sr  # noqa: E402  (sets DRJIT_LIBLLVM_PATH; the camera -> sensor converter)
import outdoor_reference as ref  # noqa: E402  (EXR/PLY writers, lat-long directions, envmap frame)
import mitsuba as mi  # noqa: E402
import numpy as np  # noqa: E402

BUNNY = os.path.join(sr.ROOT, "..", "shared", "data", "meshes", "stanford_bunny", "reconstruction",
                     "bun_zipper_res3.ply")
DIFFUSE = [0.45, 0.30, 0.18]
ALPHA = 0.12
SPOT_DIAMETER_DEG = 4.0
SPOT_RATIO = 30.0
SPOT_ELEVATION_DEG = 35.0
SPOT_AZIMUTH_DEG = 30.0
SKY_W, SKY_H = 1024, 512
DISTANCE = 3.0
MAX_DEPTH = 3                       # direct light and one indirect bounce


def read_ply_ascii(path):
    with open(path) as f:
        lines = f.read().split("\n")
    nv = nf = 0
    i = 0
    while lines[i].strip() != "end_header":
        t = lines[i].split()
        if t[:2] == ["element", "vertex"]:
            nv = int(t[2])
        if t[:2] == ["element", "face"]:
            nf = int(t[2])
        i += 1
    i += 1
    pos = np.array([[float(x) for x in lines[i + k].split()[:3]] for k in range(nv)])
    faces = [[int(x) for x in lines[i + nv + k].split()[1:4]] for k in range(nf)]
    return pos, np.array(faces, dtype=np.int64)


def bunny(path=BUNNY):
    """bun_zipper_res3 (or the mesh at `path`) as crates/lightfield/tests/integration/common does it: centred, 1 unit
    tall (its Y extent), Y up -> Z up, (x, y, z) -> (x, -z, y); area-weighted vertex normals."""
    pos, tris = read_ply_ascii(path)
    lo, hi = pos.min(0), pos.max(0)
    c, s = (lo + hi) / 2, 1.0 / (hi[1] - lo[1])
    p = (pos - c) * s
    pos = np.stack([p[:, 0], -p[:, 2], p[:, 1]], 1)
    # drop vertices no face uses (they would get no normal)
    used = np.unique(tris)
    remap = -np.ones(len(pos), np.int64)
    remap[used] = np.arange(len(used))
    pos, tris = pos[used], remap[tris]
    fn = np.cross(pos[tris[:, 1]] - pos[tris[:, 0]], pos[tris[:, 2]] - pos[tris[:, 0]])
    nrm = np.zeros_like(pos)
    for k in range(3):
        np.add.at(nrm, tris[:, k], fn)
    ln = np.linalg.norm(nrm, axis=1, keepdims=True)
    # a vertex whose faces cancel gets +Z, as igi's compute_vertex_normals gives it
    nrm = np.where(ln > 0, nrm / np.maximum(ln, 1e-30), np.array([0.0, 0.0, 1.0]))
    return pos, nrm, tris


def write_ply(path, pos, nrm, tris):
    n, m = len(pos), len(tris)
    header = ("ply\nformat binary_little_endian 1.0\ncomment igi slf_gloss fixture, world Z up\n"
              f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              f"element face {m}\nproperty list uchar int vertex_indices\nend_header\n")
    v = np.concatenate([pos, nrm], 1).astype("<f4")
    f = np.empty(m, np.dtype([("n", "u1"), ("i", "<i4", (3,))]))
    f["n"], f["i"] = 3, tris

    def w(tmp):
        with open(tmp, "wb") as fh:
            fh.write(header.encode())
            fh.write(v.tobytes())
            fh.write(f.tobytes())
    ref.atomic_write(path, w)


def fibonacci(n, offset=0.0):
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    phi = (i - 0.5) * 2.399963 + offset
    r = np.sqrt(1 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], 1)


def camera(direction, size):
    """FORMATS.md camera at DISTANCE along `direction` looking at the origin (igi's
    WorldToCamera::look_at: z forward, x = z x up, y = z x x; up Z, or X near the poles)."""
    d = direction / np.linalg.norm(direction)
    eye = d * DISTANCE
    up = np.array([1.0, 0, 0]) if abs(d[2]) > 0.95 else np.array([0, 0, 1.0])
    z = -d
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    t = -R @ eye
    f = 1.6 * size
    c = (size - 1) / 2.0
    return {"width": size, "height": size, "K": [[f, 0, c], [0, f, c], [0, 0, 1]],
            "dist": [0.0] * 5, "R": R.tolist(), "t": t.tolist()}


def spot_direction():
    e, a = math.radians(SPOT_ELEVATION_DEG), math.radians(SPOT_AZIMUTH_DEG)
    return np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])


def make_sky():
    """FORMATS.md lat-long map: dim sky (upper mean about 0.3), dim ground, and the spot."""
    d = ref.latlong_pixel_dirs(SKY_W, SKY_H)
    cz = d[..., 2:3]
    zen = np.array([0.14, 0.22, 0.40])
    hor = np.array([0.40, 0.42, 0.45])
    sky = zen + (hor - zen) * (1.0 - np.clip(cz, 0, 1)) ** 2
    ground = np.array([0.10, 0.09, 0.07]) * np.ones_like(sky)
    img = np.where(cz >= 0, sky, ground)
    th = math.pi * (np.arange(SKY_H) + 0.5) / SKY_H
    upper = (np.arange(SKY_H) < SKY_H // 2)
    w = np.sin(th) * upper
    sky_mean = (img * w[:, None, None]).sum((0, 1)) / (w.sum() * SKY_W)
    spot = SPOT_RATIO * sky_mean
    inside = np.degrees(np.arccos(np.clip(d @ spot_direction(), -1, 1))) <= SPOT_DIAMETER_DEG / 2
    img[inside] = spot
    return img.astype(np.float32), sky_mean, spot


def scene(cam, spp, sky_path, mesh_path):
    return {"type": "scene",
            "integrator": {"type": "path", "max_depth": MAX_DEPTH, "hide_emitters": True},
            "sensor": sr.sensor_from_camera(cam, spp),
            "sky": ref.envmap_dict(sky_path),
            "bunny": {"type": "ply", "filename": mesh_path,
                      "bsdf": {"type": "roughplastic", "distribution": "ggx", "alpha": ALPHA,
                               "int_ior": 1.49, "ext_ior": 1.0, "nonlinear": False,
                               "diffuse_reflectance": {"type": "rgb", "value": DIFFUSE}}}}


def write_json(path, obj):
    ref.write_text(path, json.dumps(obj, indent=1) + "\n")


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="/tmp/slf_gloss")
    ap.add_argument("--size", type=int, default=256)
    ap.add_argument("--views", type=int, default=96)
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--truth-spp", type=int, default=1024)
    ap.add_argument("--held-out", type=int, default=6)
    a = ap.parse_args()
    variant = "llvm_ad_rgb" if sr.llvm_path() else "scalar_rgb"
    mi.set_variant(variant)
    out = os.path.abspath(a.out)
    for sub in ("cameras", "photos", "heldout"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)
    pos, nrm, tris = bunny()
    mesh_path = os.path.join(out, "mesh.ply")
    write_ply(mesh_path, pos, nrm, tris)
    sky, sky_mean, spot = make_sky()
    sky_path = os.path.join(out, "sky_mitsuba.exr")
    ref.write_exr(sky_path, ref.mitsuba_sky(sky))
    lo, hi = pos.min(0) - 0.05, pos.max(0) + 0.05
    rig = ["# Mitsuba 3 capture: datasets/mitsuba/slf_gloss.py", "[object]",
           f"bbox_min = [{lo[0]:.4f}, {lo[1]:.4f}, {lo[2]:.4f}]",
           f"bbox_max = [{hi[0]:.4f}, {hi[1]:.4f}, {hi[2]:.4f}]", ""]
    t0 = time.time()
    for i, d in enumerate(fibonacci(a.views)):
        cam = camera(d, a.size)
        write_json(os.path.join(out, "cameras", f"v{i:02}.json"), cam)
        img = ref.render(mi.load_dict(scene(cam, a.spp, sky_path, mesh_path)), a.spp, 1000 + i)
        ref.write_exr(os.path.join(out, "photos", f"v{i:02}.exr"), img)
        rig += ["[[view]]", f'id = "v{i:02}"', f'camera = "cameras/v{i:02}.json"',
                f'photo = "photos/v{i:02}.exr"', ""]
        print(f"view {i + 1}/{a.views} {time.time() - t0:.0f} s", flush=True)
    ref.write_text(os.path.join(out, "rig.toml"), "\n".join(rig))
    t1 = time.time()
    # new views: a Fibonacci set of another size, turned half a golden step, so no direction is a
    # capture view's
    held = fibonacci(a.held_out + 2, 1.2)[1:-1]
    for k, d in enumerate(held):
        cam = camera(d, a.size)
        write_json(os.path.join(out, "heldout", f"h{k}.json"), cam)
        img = ref.render(mi.load_dict(scene(cam, a.truth_spp, sky_path, mesh_path)), a.truth_spp, 9000 + k)
        ref.write_exr(os.path.join(out, "heldout", f"h{k}.exr"), img)
        print(f"held-out view {k + 1}/{len(held)} {time.time() - t1:.0f} s", flush=True)
    write_json(os.path.join(out, "meta.json"), {
        "renderer": f"Mitsuba {mi.__version__} {variant}", "integrator": {"type": "path", "max_depth": MAX_DEPTH},
        "mesh": "bun_zipper_res3, Z up, 1 unit tall", "triangles": int(len(tris)),
        "bsdf": {"type": "roughplastic", "distribution": "ggx", "alpha": ALPHA, "int_ior": 1.49, "diffuse": DIFFUSE},
        "sky_mean_upper": sky_mean.tolist(), "spot_radiance": spot.tolist(),
        "spot_direction": spot_direction().tolist(), "spot_diameter_deg": SPOT_DIAMETER_DEG,
        "views": a.views, "size": a.size, "spp": a.spp, "held_out": len(held), "truth_spp": a.truth_spp,
        "view_seconds": round(t1 - t0, 1), "held_out_seconds": round(time.time() - t1, 1)})


if __name__ == "__main__":
    main()
