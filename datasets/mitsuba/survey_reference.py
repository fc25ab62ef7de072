#!/usr/bin/env python3
"""Survey with known albedo textures for `igi solve`, rendered by Mitsuba 3 (independent ground truth).

A small site in igi's world frame (Z up, metres): a 14 m ground square, a block (3 x 2 x 2.5 m)
and a wall (10 x 0.3 x 2 m) behind it, every surface diffuse with a UV-mapped albedo texture
(smooth colour patches and gradients, about 1 m across, values in 0.1-0.8). Each texture is
generated as a function of *world position* sampled at its texel centres (through the inverse of
the mesh's UV map, extended past the face edges into a margin), so bilinear lookups at face
borders never bleed between faces and Mitsuba's and igi's lookups agree everywhere.

Writes a FORMATS.md survey folder:

    survey.toml                     the survey (site meshes, photos, cameras, lighting files)
    geometry/{ground,block,wall}.ply  binary PLY: x y z nx ny nz u v, vertex_indices
    photos/*.exr                    Mitsuba renders (path, max_depth 4 = igi --indirect 2, box
                                    filter, llvm_ad_rgb), linear RGB radiance
    cameras/*.json                  OpenCV K/R/t, no distortion
    lighting/*.toml, *_sky.exr      sunny (hard shadows), low sun, overcast: lat-long skies plus
                                    0.53 degree sun disks (sun radiance 3e4-1e5 x the sky)
    truth/scene.toml, *_albedo.exr  FORMATS.md scene file with the true albedo textures
                                    (`igi solve --truth truth/scene.toml`; lit by the held-out
                                    lighting, so `igi render truth/scene.toml` renders the
                                    held-out view with the true albedo)
    heldout/photo.exr               a photograph from a held-out viewpoint under a held-out
                                    lighting: the mean of M renders with independent seeds,
    heldout/photo_stderr.exr        its per-pixel standard error,
    heldout/camera.json, lighting.toml, sky.exr
    survey_meta.json                settings, render times, noise, self-check numbers

Before rendering, the script asserts its conventions against Mitsuba itself (`scalar_rgb`), as
datasets/mitsuba/outdoor_reference.py does: (a) camera.json projections vs centroids of tiny
emissive markers, (b) Mitsuba's envmap vs the FORMATS.md lat-long lookup of every sky, (c) each
sun disk's irradiance vs L_sun * solid angle * cos(zenith), (d) every part's texture as Mitsuba's
BSDF sees it at ray hits vs the FORMATS.md texel lookup at the PLY's (u, v) and vs the albedo
function at the hit point, (e) every UV lies inside its texture by at least one texel.

Mitsuba scenes are built back from the written FORMATS.md files (`mitsuba_scene`), which
datasets/mitsuba/inverse_adam.py reuses.

Usage:
    python3 datasets/mitsuba/survey_reference.py --small          # CI fixture: datasets/fixtures/survey
    python3 datasets/mitsuba/survey_reference.py --out /tmp/survey_full   # full size (outside the repo)
    python3 datasets/mitsuba/survey_reference.py --small --detail 2 --out /tmp/survey2x
                                    # twice the texture detail (issue 16 item 7, docs/SOLVER.md)
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)


def llvm_path():
    """DRJIT_LIBLLVM_PATH, or Debian's libllvm19."""
    if os.environ.get("DRJIT_LIBLLVM_PATH"):
        return os.environ["DRJIT_LIBLLVM_PATH"]
    for p in ("/usr/lib/x86_64-linux-gnu/libLLVM-19.so", "/usr/lib/llvm-19/lib/libLLVM-19.so"):
        if os.path.exists(p):
            return p
    return None


if llvm_path():
    os.environ["DRJIT_LIBLLVM_PATH"] = llvm_path()

import mitsuba as mi  # noqa: E402
import outdoor_reference as ref  # noqa: E402  (file helpers, lat-long and texture lookups, envmap frame)

MAX_DEPTH = 4                      # = igi --indirect 2
SUN_DIAMETER_DEG = 0.53
SUN_DISTANCE = 1.0e4               # see outdoor_reference.py: parallax 0.07 degrees over the site
SKY_W, SKY_H = 128, 64

# ----------------------------------------------------------------------------- site
GROUND_HALF = 7.0
BLOCK_LO, BLOCK_HI = (-1.5, 0.0, 0.0), (1.5, 2.0, 2.5)
WALL_LO, WALL_HI = (-5.0, 3.5, 0.0), (5.0, 3.8, 2.0)
TEX = {"ground": 128, "block": 192, "wall": 192}
MARGIN_TEXELS = 2.0                # UVs stay this many texels inside each face's cell


def ground_mesh(tex):
    s = GROUND_HALF
    pos = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], float)
    nrm = np.tile([0.0, 0.0, 1.0], (4, 1))
    m = MARGIN_TEXELS / tex
    uv = m + (1 - 2 * m) * (pos[:, :2] + s) / (2 * s)
    return pos, nrm, uv, np.array([[0, 1, 2], [0, 2, 3]])


# (normal, tangent u, tangent v) as in outdoor_reference.box: u x v = normal
BOX_FACES = [((0, -1, 0), (1, 0, 0), (0, 0, 1)), ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
             ((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, -1, 0), (0, 0, 1)),
             ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]


def box_face_cells(tex):
    """Face k of a box gets cell (k % 3, k // 3) of a 3 x 2 grid in UV space, shrunk by the margin:
    returns [(u0, u1, v0, v1)] per face."""
    m = MARGIN_TEXELS / tex
    return [((k % 3) / 3 + m, (k % 3 + 1) / 3 - m, (k // 3) / 2 + m, (k // 3 + 1) / 2 - m) for k in range(6)]


def box_mesh(lo, hi, tex):
    pos, nrm, uv, tris = ref.box(lo, hi)
    cells = box_face_cells(tex)
    for k in range(6):                       # ref.box: 4 vertices per face, uv in {0,1}^2
        u0, u1, v0, v1 = cells[k]
        sl = slice(4 * k, 4 * k + 4)
        uv[sl, 0] = u0 + (u1 - u0) * uv[sl, 0]
        uv[sl, 1] = v0 + (v1 - v0) * uv[sl, 1]
    return pos, nrm, uv, tris


def box_uv_to_world(lo, hi, tex, u, v):
    """World position of texture coordinate (u, v) on a box_mesh, extended past the face edges
    (the face is chosen by the cell that holds (u, v))."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    c, h = (lo + hi) / 2, (hi - lo) / 2
    cells = box_face_cells(tex)
    col = np.clip(np.floor(u * 3), 0, 2).astype(int)
    row = np.clip(np.floor(v * 2), 0, 1).astype(int)
    k = row * 3 + col
    out = np.zeros(u.shape + (3,))
    for f in range(6):
        sel = k == f
        n, tu, tv = (np.array(x, float) for x in BOX_FACES[f])
        u0, u1, v0, v1 = cells[f]
        a = 2 * (u[sel] - u0) / (u1 - u0) - 1            # -1..1 across the face
        b = 2 * (v[sel] - v0) / (v1 - v0) - 1
        out[sel] = c + n * h + a[:, None] * tu * h + b[:, None] * tv * h
    return out


def ground_uv_to_world(tex, u, v):
    m = MARGIN_TEXELS / tex
    s = GROUND_HALF
    x = (u - m) / (1 - 2 * m) * 2 * s - s
    y = (v - m) / (1 - 2 * m) * 2 * s - s
    return np.stack([x, y, np.zeros_like(x)], -1)


PARTS = {
    "ground": dict(mesh=lambda: ground_mesh(TEX["ground"]), uv_to_world=lambda u, v: ground_uv_to_world(TEX["ground"], u, v)),
    "block": dict(mesh=lambda: box_mesh(BLOCK_LO, BLOCK_HI, TEX["block"]),
                  uv_to_world=lambda u, v: box_uv_to_world(BLOCK_LO, BLOCK_HI, TEX["block"], u, v)),
    "wall": dict(mesh=lambda: box_mesh(WALL_LO, WALL_HI, TEX["wall"]),
                 uv_to_world=lambda u, v: box_uv_to_world(WALL_LO, WALL_HI, TEX["wall"], u, v)),
}


DETAIL = 1.0                       # --detail: patches DETAIL x smaller, DETAIL^2 x as many


def albedo_function(name):
    """Smooth albedo of a part as a function of world position: a base colour, a linear gradient
    and Gaussian colour patches (sigma 0.7-1.2 m, divided by DETAIL), squashed into (0.1, 0.8)
    with tanh."""
    rng = np.random.default_rng({"ground": 11, "block": 12, "wall": 13}[name])
    if name == "ground":
        lo, hi = np.array([-GROUND_HALF, -GROUND_HALF, 0]), np.array([GROUND_HALF, GROUND_HALF, 0])
        n = 26
    elif name == "block":
        lo, hi = np.array(BLOCK_LO) - 0.5, np.array(BLOCK_HI) + 0.5
        n = 10
    else:
        lo, hi = np.array(WALL_LO) - 0.5, np.array(WALL_HI) + 0.5
        n = 12
    n = int(round(n * DETAIL * DETAIL))
    centres = rng.uniform(lo, hi, size=(n, 3))
    sigmas = rng.uniform(0.7, 1.2, size=n) / DETAIL
    amps = rng.uniform(-1.1, 1.1, size=(n, 3))
    base = rng.uniform(-0.5, 0.5, size=3)
    grad = rng.uniform(-0.06, 0.06, size=(3, 3))           # per metre, per channel

    def f(p):
        p = np.asarray(p, float)
        g = base + p @ grad
        d2 = ((p[..., None, :] - centres) ** 2).sum(-1)     # (..., n)
        g = g + np.exp(-d2 / (2 * sigmas ** 2)) @ amps
        return 0.45 + 0.35 * np.tanh(g)
    return f


def make_texture(name):
    """FORMATS.md texture (row 0 = top, v up) of the part's albedo function at texel centres."""
    w = h = TEX[name]
    j, i = np.meshgrid(np.arange(w), np.arange(h))
    u, v = (j + 0.5) / w, 1.0 - (i + 0.5) / h
    return albedo_function(name)(PARTS[name]["uv_to_world"](u, v)).astype(np.float32)


# ----------------------------------------------------------------------------- lighting
def direction(el_deg, az_deg):
    el, az = math.radians(el_deg), math.radians(az_deg)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


def overcast_radiance(d, zenith=1.6):
    """CIE overcast sky L = Lz (1 + 2 cos theta) / 3, slightly cool; dim ground below."""
    cz = d[..., 2:3]
    up = zenith * (1 + 2 * np.clip(cz, 0, 1)) / 3 * np.array([0.95, 1.0, 1.08])
    below = np.array([0.12, 0.11, 0.10]) * (1.0 + 0.5 * np.exp(cz * 8.0))
    return np.where(cz >= 0, up, below)


# name -> (sky function of directions, sun (direction, radiance) or None)
LIGHTINGS = {
    "sunny": dict(sun=(direction(52, -70), np.array([6.0e4, 5.7e4, 5.2e4])), sky_scale=0.8),
    "lowsun": dict(sun=(direction(14, -140), np.array([3.2e4, 2.5e4, 1.6e4])), sky_scale=0.5),
    "overcast": dict(sun=None),
    "heldout": dict(sun=(direction(30, 155), np.array([4.5e4, 4.2e4, 3.6e4])), sky_scale=0.7),
}


def make_sky(name):
    d = ref.latlong_pixel_dirs(SKY_W, SKY_H)
    spec = LIGHTINGS[name]
    if spec["sun"] is None:
        return overcast_radiance(d).astype(np.float32)
    return (spec["sky_scale"] * ref.sky_radiance(d, spec["sun"][0])).astype(np.float32)


def lighting_toml(name, sky_file):
    spec = LIGHTINGS[name]
    fmt = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"
    t = ("# Generated by datasets/mitsuba/survey_reference.py.\n"
         f"[environment]\nmap = \"{sky_file}\"\nscale = 1.0\n")
    if spec["sun"] is not None:
        d, l = spec["sun"]
        t += f"\n[sun]\ndirection = {fmt(d)}\nradiance = {fmt(l)}\nangular_diameter_deg = {SUN_DIAMETER_DEG}\n"
    return t


# ----------------------------------------------------------------------------- cameras
SITE_CENTRE = np.array([0.0, 1.5, 0.8])


def shots(small):
    """(id, eye, target, lighting) of the survey photographs and of the held-out one."""
    order = ["sunny", "lowsun", "overcast"]
    out = []
    n = 8 if small else 12
    for k in range(n):
        az = math.radians(-90 + 360 * k / n)
        r, hgt = (12.0, 5.0 + 2.0 * (k % 2)) if small else (11.0 + 2.0 * (k % 3), 4.5 + 1.5 * (k % 3))
        eye = SITE_CENTRE + np.array([r * math.cos(az), r * math.sin(az), 0.0])
        eye[2] = hgt
        light = order[k % 3]
        out.append((f"v{k:02d}-{light}", eye, SITE_CENTRE + np.array([0.0, 0.0, -0.3]), light))
    az = math.radians(-118)
    heldout = ("heldout", SITE_CENTRE + np.array([10.0 * math.cos(az), 10.0 * math.sin(az), 0.0]) + np.array([0, 0, 2.7]),
               SITE_CENTRE + np.array([0.3, 0.2, 0.0]), "heldout")
    return out, heldout


def opencv_camera(eye, target, width, height, fov_x_deg):
    """camera.json dict for a Mitsuba look_at sensor (Mitsuba camera: x left, y up, z forward)."""
    m = np.array(mi.ScalarTransform4f().look_at(origin=eye.tolist(), target=target.tolist(), up=[0, 0, 1]).matrix,
                 dtype=float)
    cam_to_world_mi = m[:3, :3]
    R = np.stack([-cam_to_world_mi[:, 0], -cam_to_world_mi[:, 1], cam_to_world_mi[:, 2]])
    t = -R @ eye
    fx = (width / 2.0) / math.tan(math.radians(fov_x_deg) / 2.0)
    K = np.array([[fx, 0, width / 2.0 - 0.5], [0, fx, height / 2.0 - 0.5], [0, 0, 1.0]])
    return {"width": width, "height": height, "K": K.tolist(), "dist": [0.0] * 5, "R": R.tolist(), "t": t.tolist()}


def sensor_from_camera(cam, spp=16):
    """Mitsuba sensor for a FORMATS.md camera.json (centred principal point, no distortion)."""
    K, R, t = np.array(cam["K"]), np.array(cam["R"]), np.array(cam["t"])
    w, h = cam["width"], cam["height"]
    assert abs(K[0, 2] - (w / 2 - 0.5)) < 1e-6 and abs(K[1, 2] - (h / 2 - 0.5)) < 1e-6, "principal point not centred"
    assert abs(K[0, 0] - K[1, 1]) < 1e-6 * K[0, 0] and not np.any(cam.get("dist", [0] * 5)), "non-square or distorted"
    eye = -R.T @ t
    c2w = np.eye(4)
    c2w[:3, 0], c2w[:3, 1], c2w[:3, 2], c2w[:3, 3] = -R[0], -R[1], R[2], eye
    fov = math.degrees(2 * math.atan((w / 2.0) / K[0, 0]))
    return {"type": "perspective", "fov": fov, "fov_axis": "x", "near_clip": 0.01, "far_clip": 1e7,
            "to_world": mi.ScalarTransform4f(c2w.tolist()),
            "sampler": {"type": "independent", "sample_count": spp},
            "film": {"type": "hdrfilm", "width": w, "height": h, "pixel_format": "rgb", "rfilter": {"type": "box"}}}


def project(cam, p):
    K, R, t = np.array(cam["K"]), np.array(cam["R"]), np.array(cam["t"])
    x = R @ p + t
    return np.array([K[0, 0] * x[0] / x[2] + K[0, 2], K[1, 1] * x[1] / x[2] + K[1, 2]])


# ----------------------------------------------------------------------------- Mitsuba scenes from FORMATS files
def read_lighting(path):
    with open(path, "rb") as f:
        lt = tomllib.load(f)
    folder = os.path.dirname(os.path.abspath(path))
    env = lt.get("environment")
    sky = None
    if env is not None:
        sky = ref.read_exr(os.path.join(folder, env["map"])) * float(env.get("scale", 1.0))
    sun = lt.get("sun")
    if sun is not None:
        sun = (np.array(sun["direction"], float) / np.linalg.norm(sun["direction"]), np.array(sun["radiance"], float),
               float(sun.get("angular_diameter_deg", 0.53)))
    return sky, sun


def sun_disk(sun):
    d, radiance, diam = sun
    return ref.sun_disk_emitter(d, radiance, diam, SUN_DISTANCE)


def emitters(lighting_path, workdir):
    """Mitsuba emitters of a FORMATS.md lighting file (sky resampled for Mitsuba's envmap rows)."""
    sky, sun = read_lighting(lighting_path)
    out = {}
    if sky is not None:
        key = os.path.abspath(lighting_path).replace("/", "_").replace(".", "_")
        p = os.path.join(workdir, f"mitsuba_sky{key}.exr")
        if not os.path.exists(p):
            ref.write_exr(p, ref.mitsuba_sky(sky))
        out["sky"] = ref.envmap_dict(p)
    if sun is not None:
        out["sun"] = sun_disk(sun)
    return out


def read_scene_file(path):
    """[(name, mesh path, albedo texture path)] of a FORMATS.md scene file with texture albedos."""
    with open(path, "rb") as f:
        sc = tomllib.load(f)
    folder = os.path.dirname(os.path.abspath(path))
    objs = []
    for o in sc["object"]:
        mesh = os.path.join(folder, o["mesh"])
        objs.append((os.path.splitext(os.path.basename(mesh))[0], mesh, os.path.join(folder, o["albedo"])))
    return objs


def mitsuba_scene(objects, camera, lighting_path, workdir, spp=16, integrator="path", albedo_override=None):
    """Mitsuba scene dict: diffuse textured objects [(name, ply, texture)], a camera.json dict and a
    FORMATS.md lighting file. albedo_override maps a name to a bitmap dict (inverse rendering)."""
    d = {"type": "scene", "integrator": {"type": integrator, "max_depth": MAX_DEPTH, "hide_emitters": False},
         "sensor": sensor_from_camera(camera, spp)}
    d.update(emitters(lighting_path, workdir))
    for name, ply, tex in objects:
        bsdf = ref.diffuse(tex)
        if albedo_override and name in albedo_override:
            bsdf = {"type": "diffuse", "reflectance": albedo_override[name]}
        d[name] = {"type": "ply", "filename": ply, "bsdf": bsdf}
    return d


# ----------------------------------------------------------------------------- self-checks (scalar_rgb)
def check_camera(cam, markers):
    ang_px = math.radians(60.0) / cam["width"]
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 1}, "sensor": sensor_from_camera(cam, 64)}
    eye = -np.array(cam["R"]).T @ np.array(cam["t"])
    R, t = np.array(cam["R"]), np.array(cam["t"])
    markers = [p for p in markers if (R @ p + t)[2] > 0.5 and np.all(project(cam, p) > 8)
               and project(cam, p)[0] < cam["width"] - 8 and project(cam, p)[1] < cam["height"] - 8]
    assert len(markers) >= 3, "too few markers in view"
    for k, p in enumerate(markers):
        scene[f"m{k}"] = {"type": "sphere", "center": p.tolist(), "radius": float(1.6 * ang_px * np.linalg.norm(p - eye)),
                          "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}}
    img = ref.render(mi.load_dict(scene), 1024, 7).mean(axis=2)
    ys, xs = np.mgrid[0:cam["height"], 0:cam["width"]]
    errs = []
    for p in markers:
        uv = project(cam, p)
        win = (np.abs(xs - uv[0]) <= 6) & (np.abs(ys - uv[1]) <= 6)
        w = img * win
        assert w.sum() > 1.0, f"marker at {p} not found near {uv}"
        c = np.array([(w * xs).sum(), (w * ys).sum()]) / w.sum()
        errs.append(float(np.linalg.norm(c - uv)))
    assert max(errs) < 0.3, errs
    return max(errs)


def check_envmap(sky, sky_path, sun_dir):
    scene = mi.load_dict({"type": "scene", "sky": ref.envmap_dict(sky_path)})
    em = scene.emitters()[0]
    rng = np.random.default_rng(5)
    dirs = [np.array(d, float) for d in ([0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.2], [0.3, 0.2, -0.9])]
    dirs += list(ref.latlong_pixel_dirs(SKY_W, SKY_H).reshape(-1, 3)[rng.choice(SKY_W * SKY_H, 40)])
    dirs += list(rng.normal(size=(60, 3)))
    if sun_dir is not None:
        dirs.append(sun_dir)
    worst = 0.0
    for d in dirs:
        d = d / np.linalg.norm(d)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-d))
        v_mi = np.array(em.eval(si), dtype=float)
        v_ref = ref.latlong_lookup(sky, d)
        worst = max(worst, float(np.max(np.abs(v_mi - v_ref) / np.maximum(np.abs(v_ref), 1e-3))))
    assert worst < 1e-4, worst
    return worst


def check_sun(sun):
    d, radiance, diam = sun
    e_mi = ref.plane_irradiance(sun_disk(sun))
    alpha = math.radians(diam / 2)
    e_ref = radiance * 2 * math.pi * (1 - math.cos(alpha)) * d[2]
    rel = float(np.max(np.abs(e_mi / e_ref - 1)))
    assert rel < 0.01, rel
    return rel


def check_texture(name, ply, tex_path, tex):
    scene = mi.load_dict({"type": "scene", name: {"type": "ply", "filename": ply, "bsdf": ref.diffuse(tex_path)}})
    shape = scene.shapes()[0]
    bsdf = shape.bsdf()
    f = albedo_function(name)
    rng = np.random.default_rng(17)
    pos, nrm, uv, tris = PARTS[name]["mesh"]()
    worst_tex, worst_fn, n = 0.0, 0.0, 0
    for _ in range(300):
        k = rng.integers(len(tris))
        if nrm[tris[k][0]][2] < -0.5:          # skip faces nobody sees (box bottoms)
            continue
        b = rng.dirichlet([1, 1, 1])
        p = b @ pos[tris[k]]
        uv_ref = b @ uv[tris[k]]
        nn = nrm[tris[k][0]]
        si = scene.ray_intersect(mi.Ray3f(mi.Point3f(*(p + 0.01 * nn)), mi.Vector3f(*(-nn))))
        assert si.is_valid() and abs(si.uv[0] - uv_ref[0]) < 1e-4 and abs(si.uv[1] - uv_ref[1]) < 1e-4
        v_mi = np.array(bsdf.eval_diffuse_reflectance(si), dtype=float)
        worst_tex = max(worst_tex, float(np.max(np.abs(v_mi - ref.texture_lookup(tex, uv_ref[0], uv_ref[1])))))
        worst_fn = max(worst_fn, float(np.max(np.abs(v_mi - f(p)))))
        n += 1
    assert worst_tex < 2e-3, worst_tex
    # bilinear reconstruction of the smooth albedo function between texel centres
    assert worst_fn < 5e-3, worst_fn
    m = 1.0 / tex.shape[0]
    assert uv.min() >= m - 1e-9 and uv.max() <= 1 - m + 1e-9, "UVs closer than a texel to the texture border"
    return worst_tex, worst_fn, n


# ----------------------------------------------------------------------------- rendering
def render_mean(scene, spp, seeds, pass_spp):
    """Mean over seeds of renders of spp samples each (made of passes of pass_spp), and the
    per-pixel standard error of that mean (from the spread across seeds)."""
    acc, acc2 = None, None
    for s in seeds:
        img = 0
        for p in range(spp // pass_spp):
            img = img + np.array(mi.render(scene, spp=pass_spp, seed=1000 * s + p), dtype=np.float64)
        img = img / (spp // pass_spp)
        assert np.all(np.isfinite(img))
        acc = img if acc is None else acc + img
        acc2 = img * img if acc2 is None else acc2 + img * img
    m = len(seeds)
    mean = acc / m
    var = np.maximum(acc2 / m - mean * mean, 0.0) * m / (m - 1)
    return mean, np.sqrt(var / m)


def fmt_vec(v):
    return "[" + ", ".join(repr(float(x)) for x in v) + "]"


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--small", action="store_true", help="CI fixture size (160x120, 8 photos)")
    ap.add_argument("--out", default=None, help="survey folder (default: datasets/fixtures/survey with --small)")
    ap.add_argument("--spp", type=int, default=None, help="samples per pixel of each survey photo")
    ap.add_argument("--heldout-renders", type=int, default=8, help="M independent renders of the held-out photo")
    ap.add_argument("--heldout-spp", type=int, default=None, help="samples per pixel of each held-out render")
    ap.add_argument("--detail", type=float, default=1.0,
                    help="texture detail: colour patches this many times smaller (and its square as many), "
                         "textures this many times finer (default 1: the committed fixture)")
    ap.add_argument("--checks-only", action="store_true")
    args = ap.parse_args()
    if not (1.0 <= args.detail <= 8.0):
        ap.error("--detail must lie in 1..8")
    global DETAIL
    DETAIL = args.detail
    for k in TEX:
        TEX[k] = int(round(TEX[k] * DETAIL))
    if args.out is None:
        if not args.small:
            ap.error("the full survey is large: give --out DIR outside the repository")
        args.out = os.path.join(ROOT, "datasets", "fixtures", "survey")
    width, height = (160, 120) if args.small else (320, 240)
    spp = args.spp or (2048 if args.small else 4096)
    heldout_spp = args.heldout_spp or 1024
    fov = 60.0
    out = os.path.abspath(args.out)
    for sub in ("geometry", "photos", "cameras", "lighting", "truth", "heldout"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)
    work = tempfile.mkdtemp(prefix="igi-survey-mitsuba-")
    mi.set_variant("scalar_rgb")

    # ---- inputs in FORMATS.md
    textures = {}
    for name, part in PARTS.items():
        ref.write_ply(os.path.join(out, "geometry", f"{name}.ply"), *part["mesh"]())
        textures[name] = make_texture(name)
        ref.write_exr(os.path.join(out, "truth", f"{name}_albedo.exr"), textures[name])
    skies = {}
    for name in LIGHTINGS:
        skies[name] = make_sky(name)
        if name == "heldout":
            ref.write_exr(os.path.join(out, "heldout", "sky.exr"), skies[name])
            ref.write_text(os.path.join(out, "heldout", "lighting.toml"), lighting_toml(name, "sky.exr"))
        else:
            ref.write_exr(os.path.join(out, "lighting", f"{name}_sky.exr"), skies[name])
            ref.write_text(os.path.join(out, "lighting", f"{name}.toml"), lighting_toml(name, f"{name}_sky.exr"))
    truth_toml = ("# Generated by datasets/mitsuba/survey_reference.py: the true albedo textures.\n"
                  "# igi solve SURVEY --truth truth/scene.toml; lit by the held-out lighting.\n"
                  "lighting = \"../heldout/lighting.toml\"\n")
    for name in PARTS:
        truth_toml += f"\n[[object]]\nmesh = \"../geometry/{name}.ply\"\nalbedo = \"{name}_albedo.exr\"\n"
    ref.write_text(os.path.join(out, "truth", "scene.toml"), truth_toml)
    photos, heldout = shots(args.small)
    cams = {}
    survey = ("# Generated by datasets/mitsuba/survey_reference.py (Mitsuba 3 ground truth).\n"
              "[site]\nmeshes = [" + ", ".join(f"\"geometry/{n}.ply\"" for n in PARTS) + "]\n")
    for pid, eye, target, light in photos:
        cams[pid] = opencv_camera(eye, target, width, height, fov)
        ref.write_text(os.path.join(out, "cameras", f"{pid}.json"), json.dumps(cams[pid], indent=2) + "\n")
        survey += (f"\n[[photo]]\nid = \"{pid}\"\nimage = \"photos/{pid}.exr\"\ncamera = \"cameras/{pid}.json\"\n"
                   f"lighting = \"lighting/{light}.toml\"\n")
    hid, heye, htarget, _ = heldout
    cams[hid] = opencv_camera(heye, htarget, width, height, fov)
    ref.write_text(os.path.join(out, "heldout", "camera.json"), json.dumps(cams[hid], indent=2) + "\n")

    # ---- self-checks against Mitsuba itself
    t0 = time.time()
    markers = [np.array(p) for p in ([0.0, 1.0, 1.2], [-4.0, 3.4, 1.8], [4.5, -3.0, 0.1], [-5.0, -5.0, 0.0],
                                     [1.4, 0.1, 2.4], [3.0, 3.0, 0.5])]
    checks = {"camera_max_px_error": {}}
    for pid in (photos[0][0], photos[3][0], hid):
        checks["camera_max_px_error"][pid] = check_camera(cams[pid], markers)
    print(f"(a) camera: marker centroids vs OpenCV projection, max {max(checks['camera_max_px_error'].values()):.4f} px")
    checks["envmap_max_rel_diff"] = {}
    checks["sun_irradiance_rel_error"] = {}
    for name in LIGHTINGS:
        p = os.path.join(work, f"check_sky_{name}.exr")
        ref.write_exr(p, ref.mitsuba_sky(skies[name]))
        sun = LIGHTINGS[name]["sun"]
        checks["envmap_max_rel_diff"][name] = check_envmap(skies[name], p, None if sun is None else sun[0])
        if sun is not None:
            checks["sun_irradiance_rel_error"][name] = check_sun((sun[0], sun[1], SUN_DIAMETER_DEG))
    print(f"(b) envmap vs FORMATS lat-long lookup, max rel {max(checks['envmap_max_rel_diff'].values()):.2e}")
    print(f"(c) sun irradiance vs L omega cos, max rel {max(checks['sun_irradiance_rel_error'].values()):.2e}")
    checks["texture"] = {}
    for name in PARTS:
        wt, wf, n = check_texture(name, os.path.join(out, "geometry", f"{name}.ply"),
                                  os.path.join(out, "truth", f"{name}_albedo.exr"), textures[name])
        checks["texture"][name] = {"vs_texel_lookup_max_abs": wt, "vs_albedo_function_max_abs": wf, "hits": n}
    print("(d) texture: Mitsuba BSDF vs FORMATS texel lookup / albedo function, max abs "
          + ", ".join(f"{k} {v['vs_texel_lookup_max_abs']:.1e} / {v['vs_albedo_function_max_abs']:.1e}"
                      for k, v in checks["texture"].items()))
    print(f"self-checks: {time.time() - t0:.1f} s", flush=True)
    if args.checks_only:
        return 0

    # ---- renders (llvm_ad_rgb: same plugins, several times faster than scalar_rgb here)
    variant = "llvm_ad_rgb" if llvm_path() else "scalar_rgb"
    mi.set_variant(variant)
    pass_spp = 256 if variant == "llvm_ad_rgb" else spp
    objects = read_scene_file(os.path.join(out, "truth", "scene.toml"))
    meta_photos = []
    t0 = time.time()
    for k, (pid, _, _, light) in enumerate(photos):
        scene = mi.load_dict(mitsuba_scene(objects, cams[pid], os.path.join(out, "lighting", f"{light}.toml"), work))
        seeds = [k * 16 + 1, k * 16 + 2]           # two halves: their spread gives the photo's noise
        mean, se = render_mean(scene, spp // 2, seeds, min(pass_spp, spp // 2))
        ref.write_exr(os.path.join(out, "photos", f"{pid}.exr"), mean)
        rel = float(np.median(se / np.maximum(mean, 1e-6)))
        meta_photos.append({"id": pid, "lighting": light, "spp": spp, "mean_radiance": mean.reshape(-1, 3).mean(0).tolist(),
                            "median_relative_stderr": rel})
        print(f"photo {pid}: {time.time() - t0:.1f} s, median relative standard error {100 * rel:.2f} %", flush=True)
    ref.write_text(os.path.join(out, "survey.toml"), survey)
    t1 = time.time()
    scene = mi.load_dict(mitsuba_scene(objects, cams[hid], os.path.join(out, "heldout", "lighting.toml"), work))
    m = args.heldout_renders
    mean, se = render_mean(scene, heldout_spp, list(range(901, 901 + m)), min(pass_spp, heldout_spp))
    ref.write_exr(os.path.join(out, "heldout", "photo.exr"), mean)
    ref.write_exr(os.path.join(out, "heldout", "photo_stderr.exr"), se)
    print(f"held-out: {m} x {heldout_spp} spp, {time.time() - t1:.1f} s", flush=True)
    meta = {"generator": "datasets/mitsuba/survey_reference.py" + (" --small" if args.small else "")
            + (f" --detail {args.detail:g}" if args.detail != 1.0 else ""),
            "mitsuba": mi.__version__, "variant": variant,
            "integrator": {"type": "path", "max_depth": MAX_DEPTH, "hide_emitters": False}, "rfilter": "box",
            "image_size": [width, height], "fov_x_deg": fov, "photos": meta_photos,
            "photo_seconds": round(t1 - t0, 1),
            "heldout": {"renders": m, "spp_per_render": heldout_spp, "total_spp": m * heldout_spp,
                        "seconds": round(time.time() - t1, 1), "mean_radiance": mean.reshape(-1, 3).mean(0).tolist(),
                        "mean_relative_stderr": float((se / np.maximum(mean, 1e-6)).mean())},
            "textures": {n: list(t.shape[:2]) for n, t in textures.items()},
            "albedo_range": [float(min(t.min() for t in textures.values())), float(max(t.max() for t in textures.values()))],
            "self_checks": checks}
    ref.write_text(os.path.join(out, "survey_meta.json"), json.dumps(meta, indent=2) + "\n")
    print(json.dumps({k: meta[k] for k in ("photo_seconds", "heldout", "albedo_range")}, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
