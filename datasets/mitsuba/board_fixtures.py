#!/usr/bin/env python3
"""Lighting-capture board fixtures for `igi probe`, rendered by Mitsuba 3 (independent renderer).

One camera (OpenCV convention, 256x256, camera at the world origin looking along world +X,
world Z up) sees three spheres 0.6 m away (radius 0.07 m, about 47 px):

    mirror  : conductor, complex index 2.40+2.98i (R), 2.40+3.02i (G, B)  (about 52 % at normal)
    black   : `plastic` (smooth dielectric coating, ior 1.5) over a dark base (0.01)
    diffuse : Lambertian (0.30, 0.31, 0.32)

lit by a smooth lat-long sky (128x64, FORMATS.md lat-long) and, for the sunny case, a sun disk
0.53 degrees across modelled as a far `disk` area emitter (distance 1e4 m, radius
1e4 * tan(0.265 deg)), radiance about 8e4 times the sky's. Each sphere is rendered alone (so the
spheres do not shadow or reflect each other, which igi's probe model ignores) and the three
renders are composited; the crops do not overlap. Gaussian reconstruction filter (Mitsuba's
default), like a real lens's blur, so the sun's sub-pixel spot has a sub-pixel centroid.

Writes into datasets/fixtures/board/<case>/ (case = sunny, cloudy):
    board.exr            HDR board image (linear radiance, float32)
    bracket_0..2.png     16-bit linear PNGs clip(L * t), t = times.txt (0.25, 1/32, 1/256 s)
    times.txt            exposure times, one per line, in bracket order
    camera.json board.json   FORMATS.md camera and board files
    sky_truth.exr        the 128x64 FORMATS.md lat-long sky given to Mitsuba (ground truth)
    truth.json           sun direction / radiance / diameter (sunny) and render settings

Self-checks against Mitsuba itself before rendering: (a) camera rays of the Mitsuba sensor vs.
the OpenCV camera.json rays; (b) Mitsuba's envmap emitter vs. the FORMATS.md lat-long lookup;
(c) the conductor's reflectance at normal incidence, measured in a Mitsuba render, vs. Fresnel.
Mitsuba is only a generator of committed fixtures, never a dependency of igi.

Usage: python3 datasets/mitsuba/board_fixtures.py [--out DIR] [--scale-spp F]

Large boards (issue 16: sun accuracy at the size of a real board photograph):

    python3 datasets/mitsuba/board_fixtures.py --cases sunny --size 1024x768 --fx 766 \
        --sun-el 14 --out /tmp/board1024/el14 --scale-spp 0.25

renders the sunny case at 1024x768 (spheres about 90 px in radius) with the sun at the given
elevation (and --sun-az); only the spheres' crops are rendered (the background is black) and no brackets are written.
"""

import argparse
import json
import math
import os
import sys

import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)
# Shared, self-checked conventions of the outdoor reference script (envmap frame and row layout,
# FORMATS.md lat-long lookup, atomic writers).
from outdoor_reference import (ENVMAP_TO_WORLD, atomic_write, latlong_lookup,  # noqa: E402
                               latlong_pixel_dirs, mitsuba_sky, write_exr, write_text)

DEFAULT_OUT = os.path.normpath(os.path.join(HERE, "..", "fixtures", "board"))

W = H = 256
FX = FY = 400.0
CX, CY = W / 2 - 0.5, H / 2 - 0.5
# world -> camera: camera x right = world -Y, y down = world -Z, z forward = world +X
R = np.array([[0.0, -1.0, 0.0], [0.0, 0.0, -1.0], [1.0, 0.0, 0.0]])
T = np.zeros(3)
SPHERES = [  # kind, centre (camera frame, m), radius (m)
    ("mirror", [-0.10, -0.08, 0.60], 0.07),
    ("black", [0.10, -0.08, 0.60], 0.07),
    ("diffuse", [0.00, 0.10, 0.60], 0.07),
]
MIRROR_ETA = [2.40, 2.40, 2.40]
MIRROR_K = [2.98, 3.02, 3.02]
BLACK_IOR = 1.5
BLACK_BASE = 0.01
DIFFUSE_RHO = [0.30, 0.31, 0.32]
SUN_DIAM_DEG = 0.53
SUN_DIST = 1.0e4
SUN_EL_DEG, SUN_AZ_DEG = 35.0, 200.0
SUN_RADIANCE = [8.0e4, 7.6e4, 6.8e4]
TIMES = [0.25, 1.0 / 32.0, 1.0 / 256.0]
SKY_W, SKY_H = 128, 64


def sun_dir():
    el, az = math.radians(SUN_EL_DEG), math.radians(SUN_AZ_DEG)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


def sky_sunny(d):
    s = sun_dir()
    cz = d[..., 2:3]
    zen = np.array([0.25, 0.40, 0.80])
    hor = np.array([0.90, 0.95, 1.05])
    up = zen + (hor - zen) * (1.0 - np.clip(cz, 0, 1)) ** 2
    g = np.arccos(np.clip(d @ s, -1, 1))[..., None]
    up = up + np.array([0.8, 0.7, 0.5]) * np.exp(-g / 0.35)
    below = np.array([0.20, 0.18, 0.14]) * (1.0 + 0.6 * np.exp(np.minimum(cz, 0) * 6.0))
    # smooth blend across the horizon (+-6 degrees) keeps the map band-limited
    a = np.clip(0.5 + cz / (2 * math.sin(math.radians(6))), 0, 1)
    return a * up + (1 - a) * below


def sky_cloudy(d):
    cz = d[..., 2:3]
    el = np.clip(cz, 0, 1)
    base = np.array([0.9, 0.92, 0.95]) * (1 + 2 * el) / 3 * 2.0
    ph = np.arctan2(d[..., 1], d[..., 0])[..., None]
    clouds = 1 + 0.25 * np.sin(2 * ph + 1.0) * np.sqrt(1 - el ** 2) + 0.15 * np.cos(3 * ph) * el
    up = base * clouds
    below = np.array([0.22, 0.21, 0.19]) * (1.0 + 0.5 * np.exp(np.minimum(cz, 0) * 6.0))
    a = np.clip(0.5 + cz / (2 * math.sin(math.radians(6))), 0, 1)
    return a * up + (1 - a) * below


# ----------------------------------------------------------------------------- Mitsuba pieces
def cam_to_world_mi():
    """Mitsuba camera frame is x left, y up, z forward = OpenCV's with x and y negated."""
    m = np.eye(4)
    m[:3, :3] = R.T @ np.diag([-1.0, -1.0, 1.0])
    m[:3, 3] = -R.T @ T
    return m


def sensor_dict(spp, crop=None):
    film = {"type": "hdrfilm", "width": W, "height": H, "pixel_format": "rgb"}  # gaussian filter
    if crop is not None:
        x0, y0, cw, ch = crop
        film.update({"crop_offset_x": x0, "crop_offset_y": y0, "crop_width": cw, "crop_height": ch})
    return {"type": "perspective", "fov": math.degrees(2 * math.atan(W / 2 / FX)), "fov_axis": "x",
            "near_clip": 0.01, "far_clip": 1e6, "to_world": mi.ScalarTransform4f(cam_to_world_mi().tolist()),
            "sampler": {"type": "independent", "sample_count": spp}, "film": film}


def envmap_dict(bitmap_path):
    return {"type": "envmap", "filename": bitmap_path, "to_world": mi.ScalarTransform4f(ENVMAP_TO_WORLD)}


def sun_disk_dict():
    s = sun_dir()
    r = SUN_DIST * math.tan(math.radians(SUN_DIAM_DEG / 2))
    tw = mi.ScalarTransform4f().look_at(origin=(SUN_DIST * s).tolist(), target=[0, 0, 0], up=[0, 0, 1]) \
        @ mi.ScalarTransform4f().scale([r, r, 1.0])
    return {"type": "disk", "to_world": tw,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": SUN_RADIANCE}}}


def bsdf(kind):
    if kind == "mirror":
        return {"type": "conductor", "eta": {"type": "rgb", "value": MIRROR_ETA},
                "k": {"type": "rgb", "value": MIRROR_K}}
    if kind == "black":
        return {"type": "plastic", "int_ior": BLACK_IOR, "ext_ior": 1.0,
                "diffuse_reflectance": {"type": "rgb", "value": [BLACK_BASE] * 3}, "nonlinear": False}
    return {"type": "diffuse", "reflectance": {"type": "rgb", "value": DIFFUSE_RHO}}


def world_center(c_cam):
    return R.T @ (np.array(c_cam) - T)


def render_sphere(env_path, sunny, kind, center_cam, radius, spp, crop, seed):
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 3, "hide_emitters": False},
             "sensor": sensor_dict(spp, crop), "sky": envmap_dict(env_path),
             "ball": {"type": "sphere", "center": world_center(center_cam).tolist(), "radius": radius,
                      "bsdf": bsdf(kind)}}
    if sunny:
        scene["sun"] = sun_disk_dict()
    return np.array(mi.render(mi.load_dict(scene), seed=seed), dtype=np.float64)


def project(p_cam):
    return np.array([FX * p_cam[0] / p_cam[2] + CX, FY * p_cam[1] / p_cam[2] + CY])


def sphere_crop(c, r, margin=4):
    c = np.array(c)
    d = np.linalg.norm(c)
    rad = FX * r / math.sqrt(d * d - r * r) * 1.1  # generous for the off-axis ellipse
    uv = project(c)
    x0 = int(max(0, math.floor(uv[0] - rad - margin)))
    y0 = int(max(0, math.floor(uv[1] - rad - margin)))
    x1 = int(min(W, math.ceil(uv[0] + rad + margin)))
    y1 = int(min(H, math.ceil(uv[1] + rad + margin)))
    return x0, y0, x1 - x0, y1 - y0


# ----------------------------------------------------------------------------- self-checks
def check_camera():
    sensor = mi.load_dict(sensor_dict(1))
    worst = 0.0
    for (u, v) in [(0, 0), (W - 1, 0), (0, H - 1), (CX, CY), (40.25, H - 55.25), (W - 6, 13)]:
        ray = sensor.sample_ray(0.0, 0.5, mi.Point2f((u + 0.5) / W, (v + 0.5) / H), mi.Point2f(0.5, 0.5))[0]
        dc = R @ np.array(ray.d, dtype=float)
        err = math.hypot(FX * dc[0] / dc[2] + CX - u, FY * dc[1] / dc[2] + CY - v)
        worst = max(worst, err)
    print(f"(a) camera: Mitsuba sensor rays vs OpenCV projection, max error {worst:.2e} px")
    assert worst < 1e-3, worst
    return worst


def check_envmap(env_path, sky):
    em = mi.load_dict({"type": "scene", "sky": envmap_dict(env_path)}).emitters()[0]
    rng = np.random.default_rng(3)
    worst = 0.0
    for d in rng.normal(size=(100, 3)):
        d = d / np.linalg.norm(d)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-d))
        v_mi = np.array(em.eval(si), dtype=float)
        v_ref = latlong_lookup(sky, d)
        worst = max(worst, float(np.max(np.abs(v_mi - v_ref) / np.abs(v_ref))))
    print(f"(b) envmap: Mitsuba envmap.eval vs FORMATS lat-long lookup, max relative diff {worst:.2e}")
    assert worst < 1e-4, worst
    return worst


def conductor_fresnel(cos_i, eta, k):
    """Unpolarised Fresnel reflectance of a conductor (exact complex formula)."""
    n = complex(eta, k)
    s2 = 1 - cos_i ** 2
    ct = np.sqrt(1 - s2 / n ** 2)
    rs = (cos_i - n * ct) / (cos_i + n * ct)
    rp = (n * cos_i - ct) / (n * cos_i + ct)
    return 0.5 * (abs(rs) ** 2 + abs(rp) ** 2)


def check_conductor(tmpdir):
    """Uniform white sky: the mirror sphere's centre pixel shows F(0) per channel."""
    path = os.path.join(tmpdir, ".white_env.exr")
    write_exr(path, np.ones((9, 16, 3), np.float32))
    kind, c, r = SPHERES[0]
    uv = project(np.array(c) - r * np.array(c) / np.linalg.norm(c))
    crop = (int(uv[0]) - 2, int(uv[1]) - 2, 5, 5)
    img = render_sphere(path, False, "mirror", c, r, 64, crop, 1)
    os.remove(path)
    got = img[2, 2]
    want = np.array([conductor_fresnel(1.0, e, k) for e, k in zip(MIRROR_ETA, MIRROR_K)])
    print(f"(c) conductor: centre pixel {got.round(4)} vs Fresnel(0) {want.round(4)}")
    assert np.max(np.abs(got - want)) < 0.01, (got, want)
    return got.tolist()


# ----------------------------------------------------------------------------- writers
def write_png16(path, img):
    q = np.clip(np.round(img * 65535.0), 0, 65535).astype(np.uint16)
    atomic_write(path, lambda tmp: mi.Bitmap(q, mi.Bitmap.PixelFormat.RGB).write(tmp), ".png")


def make_case(out, case, spp_scale):
    sunny = case == "sunny"
    os.makedirs(out, exist_ok=True)
    sky_fn = sky_sunny if sunny else sky_cloudy
    sky = sky_fn(latlong_pixel_dirs(SKY_W, SKY_H)).astype(np.float32)
    write_exr(os.path.join(out, "sky_truth.exr"), sky)
    env_path = os.path.join(out, ".mitsuba_sky.exr")
    write_exr(env_path, mitsuba_sky(sky))
    checks = {"camera_max_px": check_camera(), "envmap_max_rel": check_envmap(env_path, sky)}

    spp = {"mirror": int(256 * spp_scale), "black": int(512 * spp_scale), "diffuse": int(4096 * spp_scale)}
    board = np.zeros((H, W, 3))
    first = True
    large = W * H > 256 * 256
    if large:  # large boards: the spheres' crops only (black background, small committed files)
        first = False
    for i, (kind, c, r) in enumerate(SPHERES):
        crop = (0, 0, W, H) if first else sphere_crop(c, r)
        print(f"  rendering {case}/{kind} crop {crop} spp {spp[kind]}", flush=True)
        img = render_sphere(env_path, sunny, kind, c, r, spp[kind], crop, 17 + i)
        x0, y0, cw, ch = crop
        board[y0:y0 + ch, x0:x0 + cw] = img
        first = False
    os.remove(env_path)
    assert np.all(np.isfinite(board))
    write_exr(os.path.join(out, "board.exr"), board.astype(np.float32))
    for i, t in enumerate([] if large else TIMES):
        write_png16(os.path.join(out, f"bracket_{i}.png"), board * t)
    write_text(os.path.join(out, "times.txt"), "".join(f"{t!r}\n" for t in TIMES))
    cam = {"width": W, "height": H, "K": [[FX, 0, CX], [0, FY, CY], [0, 0, 1]], "dist": [0, 0, 0, 0, 0],
           "R": R.tolist(), "t": T.tolist()}
    write_text(os.path.join(out, "camera.json"), json.dumps(cam, indent=2) + "\n")
    bj = {"spheres": [{"kind": k, "center": c, "radius": r} for k, c, r in SPHERES]}
    write_text(os.path.join(out, "board.json"), json.dumps(bj, indent=2) + "\n")
    truth = {"case": case, "sky": "sky_truth.exr", "spp": spp, "times": TIMES,
             "mirror_ior": [[e, k] for e, k in zip(MIRROR_ETA, MIRROR_K)], "black_ior": BLACK_IOR,
             "diffuse_reflectance": DIFFUSE_RHO, "checks": checks}
    if sunny:
        truth["sun"] = {"direction": sun_dir().tolist(), "radiance": SUN_RADIANCE,
                        "angular_diameter_deg": SUN_DIAM_DEG, "distance_m": SUN_DIST}
    write_text(os.path.join(out, "truth.json"), json.dumps(truth, indent=2) + "\n")


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--scale-spp", type=float, default=1.0)
    ap.add_argument("--cases", default="sunny,cloudy")
    ap.add_argument("--size", default="256x256", help="image WIDTHxHEIGHT")
    ap.add_argument("--fx", type=float, default=400.0, help="focal length in pixels (fx = fy)")
    ap.add_argument("--sun-el", type=float, default=35.0)
    ap.add_argument("--sun-az", type=float, default=200.0)
    a = ap.parse_args()
    global W, H, FX, FY, CX, CY, SUN_EL_DEG, SUN_AZ_DEG
    W, H = (int(x) for x in a.size.split("x"))
    FX = FY = a.fx
    CX, CY = W / 2 - 0.5, H / 2 - 0.5
    SUN_EL_DEG, SUN_AZ_DEG = a.sun_el, a.sun_az
    os.makedirs(a.out, exist_ok=True)
    check_conductor(a.out)
    for case in a.cases.split(","):
        make_case(os.path.join(a.out, case), case, a.scale_spp)


if __name__ == "__main__":
    main()
