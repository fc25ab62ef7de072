#!/usr/bin/env python3
"""Outdoor reference scene for igi, rendered by Mitsuba 3 (independent reference renderer).

Builds a small outdoor scene directly in igi's world frame (Z up, metres): a ground plane, a
colonnade (five square columns under an architrave), a wall with a UV-mapped procedural albedo
texture, a smooth lat-long sky (brighter toward the horizon and around the sun) and a sun disk
0.53 degrees across. All materials are diffuse. Writes, in igi's conventions (FORMATS.md):

    ground.ply colonnade.ply wall.ply   meshes (binary PLY: x y z nx ny nz u v, vertex_indices)
    wall_albedo.exr                     64x64 linear RGB albedo texture of the wall
    sky.exr                             128x64 lat-long linear RGB sky radiance
    lighting.toml scene.toml            FORMATS.md lighting and scene files (relative paths)
    camera.json                         OpenCV K/R/t, 128x128, no distortion
    reference.exr                       mean of M independent Mitsuba renders (path, max_depth 4,
                                        box filter, scalar_rgb)
    reference_stderr.exr                per-pixel standard error of that mean
    reference_meta.json                 render settings, self-check numbers

Before rendering, the script asserts its conventions against Mitsuba itself:
  (a) camera.json projections (OpenCV math in numpy) vs. centroids of tiny emissive spheres
      rendered by Mitsuba, within 0.3 px;
  (b) Mitsuba's envmap emitter (with the to_world used here) vs. the FORMATS.md lat-long lookup
      of sky.exr, in many directions;
  (c) the sun disk's irradiance on a horizontal white plane vs. L_sun * solid angle * cos(zenith),
      within 1 %;
  (d) the wall texture as Mitsuba's BSDF sees it at ray hits vs. the FORMATS.md texel lookup of
      wall_albedo.exr at the PLY's (u, v).

Mitsuba is only a generator of committed fixtures, never a dependency of igi.
Usage: python3 datasets/mitsuba/outdoor_reference.py [--out DIR] [--renders M] [--spp N]
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np
import mitsuba as mi

HERE = os.path.dirname(os.path.abspath(__file__))
DEFAULT_OUT = os.path.normpath(os.path.join(HERE, "..", "fixtures", "outdoor"))

# ----------------------------------------------------------------------------- scene constants
WIDTH = HEIGHT = 128
FOV_X_DEG = 55.0
CAM_ORIGIN = np.array([3.0, -12.0, 2.5])
CAM_TARGET = np.array([0.0, 1.0, 2.0])
CAM_UP = np.array([0.0, 0.0, 1.0])

SUN_ELEVATION_DEG = 40.0
SUN_AZIMUTH_DEG = -110.0          # measured from +X toward +Y (FORMATS.md phi)
SUN_ANGULAR_DIAMETER_DEG = 0.53
# 1e4 m instead of 1e3 m: at 1 km the 12 m scene sees the sun direction vary by 0.7 degrees,
# more than the disk's own diameter, while igi's sun is infinitely far away. At 10 km the
# parallax is 0.07 degrees; float precision at 1e4 m (~1 mm) is still ample.
SUN_DISTANCE = 1.0e4
SUN_RADIANCE = np.array([6.0e4, 5.7e4, 5.2e4])

SKY_W, SKY_H = 128, 64
TEX_W = TEX_H = 64
GROUND_ALBEDO = [0.30, 0.28, 0.25]
COLONNADE_ALBEDO = [0.70, 0.66, 0.58]
MAX_DEPTH = 4                     # = igi --indirect 2 (direct + 2 indirect bounces)


def sun_direction():
    el, az = math.radians(SUN_ELEVATION_DEG), math.radians(SUN_AZIMUTH_DEG)
    return np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])


# ----------------------------------------------------------------------------- file helpers
def atomic_write(path, write_fn, suffix=""):
    """write_fn(tmp_path) then rename to path (same folder)."""
    folder = os.path.dirname(os.path.abspath(path))
    fd, tmp = tempfile.mkstemp(dir=folder, prefix=".tmp-", suffix=suffix or os.path.splitext(path)[1])
    os.close(fd)
    try:
        write_fn(tmp)
        os.replace(tmp, path)
    except BaseException:
        if os.path.exists(tmp):
            os.remove(tmp)
        raise


def write_text(path, text):
    def w(tmp):
        with open(tmp, "w") as f:
            f.write(text)
    atomic_write(path, w)


def write_exr(path, img):
    img = np.ascontiguousarray(img, dtype=np.float32)
    assert img.ndim == 3 and img.shape[2] == 3 and np.all(np.isfinite(img)), path
    atomic_write(path, lambda tmp: mi.Bitmap(img, mi.Bitmap.PixelFormat.RGB).write(tmp), ".exr")


def read_exr(path):
    return np.array(mi.Bitmap(path), dtype=np.float32)


def write_ply(path, pos, nrm, uv, tris):
    n, m = len(pos), len(tris)
    header = ("ply\nformat binary_little_endian 1.0\ncomment igi outdoor fixture, world Z up, metres\n"
              f"element vertex {n}\nproperty float x\nproperty float y\nproperty float z\n"
              "property float nx\nproperty float ny\nproperty float nz\n"
              "property float u\nproperty float v\n"
              f"element face {m}\nproperty list uchar int vertex_indices\nend_header\n")
    vdt = np.dtype([(k, "<f4") for k in ("x", "y", "z", "nx", "ny", "nz", "u", "v")])
    v = np.empty(n, vdt)
    for i, k in enumerate(("x", "y", "z")):
        v[k] = pos[:, i]
        v["n" + k] = nrm[:, i]
    v["u"], v["v"] = uv[:, 0], uv[:, 1]
    fdt = np.dtype([("n", "u1"), ("i", "<i4", (3,))])
    f = np.empty(m, fdt)
    f["n"] = 3
    f["i"] = tris

    def w(tmp):
        with open(tmp, "wb") as fh:
            fh.write(header.encode("ascii"))
            fh.write(v.tobytes())
            fh.write(f.tobytes())
    atomic_write(path, w)


# ----------------------------------------------------------------------------- geometry
def box(lo, hi, uv_faces=None):
    """Closed axis-aligned box, 24 vertices (flat normals), outward CCW triangles.
    Each face gets UVs spanning [0,1]^2 with u along the face's first tangent and v up (or +y
    for horizontal faces)."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    pos, nrm, uv, tris = [], [], [], []
    # (normal, tangent u, tangent v): u x v = normal, so the quad below is CCW seen from outside
    faces = [((0, -1, 0), (1, 0, 0), (0, 0, 1)), ((0, 1, 0), (-1, 0, 0), (0, 0, 1)),
             ((1, 0, 0), (0, 1, 0), (0, 0, 1)), ((-1, 0, 0), (0, -1, 0), (0, 0, 1)),
             ((0, 0, 1), (1, 0, 0), (0, 1, 0)), ((0, 0, -1), (-1, 0, 0), (0, 1, 0))]
    c, h = (lo + hi) / 2, (hi - lo) / 2
    for n, tu, tv in faces:
        n, tu, tv = map(np.array, (n, tu, tv))
        assert np.allclose(np.cross(tu, tv), n)
        base = len(pos)
        for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
            pos.append(c + n * h + a * tu * h + b * tv * h)
            nrm.append(n)
            uv.append(((a + 1) / 2, (b + 1) / 2))
        tris += [(base, base + 1, base + 2), (base, base + 2, base + 3)]
    return np.array(pos), np.array(nrm, float), np.array(uv, float), np.array(tris)


def merge(parts):
    pos, nrm, uv, tris, off = [], [], [], [], 0
    for p, n, u, t in parts:
        pos.append(p); nrm.append(n); uv.append(u); tris.append(t + off); off += len(p)
    return np.concatenate(pos), np.concatenate(nrm), np.concatenate(uv), np.concatenate(tris)


def ground_mesh():
    s = 20.0
    pos = np.array([[-s, -s, 0], [s, -s, 0], [s, s, 0], [-s, s, 0]], float)
    nrm = np.tile([0.0, 0.0, 1.0], (4, 1))
    uv = (pos[:, :2] + s) / (2 * s)
    return pos, nrm, uv, np.array([[0, 1, 2], [0, 2, 3]])


WALL_LO, WALL_HI = (-6.0, 3.0, 0.0), (6.0, 3.4, 4.5)


def wall_mesh():
    return box(WALL_LO, WALL_HI)


def colonnade_mesh():
    parts = [box((x - 0.25, -0.25, 0.0), (x + 0.25, 0.25, 3.5)) for x in (-4.0, -2.0, 0.0, 2.0, 4.0)]
    parts.append(box((-4.5, -0.35, 3.5), (4.5, 0.35, 4.1)))
    return merge(parts)


# ----------------------------------------------------------------------------- textures and sky
def wall_texture():
    """64x64 linear RGB brick pattern, row 0 = top of the image (v = 1). Deliberately
    asymmetric (darker toward the bottom rows, warmer to the right) so a flipped lookup shows."""
    rng = np.random.default_rng(1234)
    img = np.zeros((TEX_H, TEX_W, 3), np.float32)
    brick_colors = rng.uniform([0.35, 0.15, 0.08], [0.65, 0.35, 0.22], size=(8, 5, 3))
    for i in range(TEX_H):
        for j in range(TEX_W):
            row = i // 8
            jj = j + (8 if row % 2 else 0)
            col = (jj // 16) % 5
            mortar = (i % 8 == 7) or (jj % 16 == 15)
            c = np.array([0.62, 0.60, 0.55]) if mortar else brick_colors[row, col]
            shade = 0.75 + 0.25 * (1.0 - i / (TEX_H - 1))      # top rows brighter
            warm = np.array([1.0 + 0.2 * j / (TEX_W - 1), 1.0, 1.0 - 0.2 * j / (TEX_W - 1)])
            img[i, j] = np.clip(c * shade * warm, 0.02, 0.95)
    return img


def latlong_pixel_dirs(w, h):
    """FORMATS.md: row i, column j -> theta = pi (i+.5)/h from +Z, phi = 2 pi (j+.5)/w from +X to +Y."""
    th = math.pi * (np.arange(h) + 0.5) / h
    ph = 2 * math.pi * (np.arange(w) + 0.5) / w
    th, ph = np.meshgrid(th, ph, indexing="ij")
    return np.stack([np.sin(th) * np.cos(ph), np.sin(th) * np.sin(ph), np.cos(th)], -1)


def sky_radiance(d, sun):
    """Smooth clear-ish sky: blue zenith, brighter horizon, circumsolar glow; dim ground below."""
    cz = d[..., 2:3]
    zen = np.array([0.22, 0.36, 0.70])
    hor = np.array([0.95, 1.00, 1.05])
    up = zen + (hor - zen) * (1.0 - np.clip(cz, 0, 1)) ** 2
    g = np.arccos(np.clip(d @ sun, -1, 1))[..., None]
    up = up + np.array([1.6, 1.4, 1.1]) * np.exp(-g / 0.18) + np.array([0.25, 0.22, 0.18]) * np.exp(-g / 0.8)
    below = np.array([0.16, 0.14, 0.11]) * (1.0 + 0.5 * np.exp(cz * 8.0))
    return np.where(cz >= 0, up, below)


def make_sky():
    return sky_radiance(latlong_pixel_dirs(SKY_W, SKY_H), sun_direction()).astype(np.float32)


def latlong_lookup(img, d):
    """FORMATS.md bilinear lookup: x = u W - 0.5, y = v H - 0.5; wrap in x, clamp in y."""
    h, w, _ = img.shape
    d = d / np.linalg.norm(d)
    th = math.acos(max(-1.0, min(1.0, d[2])))
    ph = math.atan2(d[1], d[0]) % (2 * math.pi)
    x, y = ph / (2 * math.pi) * w - 0.5, th / math.pi * h - 0.5
    x0, y0 = math.floor(x), math.floor(y)
    fx, fy = x - x0, y - y0
    out = 0
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            yy = min(max(y0 + dy, 0), h - 1)
            out = out + wy * wx * img[yy, (x0 + dx) % w].astype(float)
    return out


def texture_lookup(img, u, v):
    """FORMATS.md texel (i, j) centre at ((j+.5)/W, 1-(i+.5)/H); bilinear, repeat wrap."""
    h, w, _ = img.shape
    x, y = u * w - 0.5, (1.0 - v) * h - 0.5
    x0, y0 = math.floor(x), math.floor(y)
    fx, fy = x - x0, y - y0
    out = 0
    for dy, wy in ((0, 1 - fy), (1, fy)):
        for dx, wx in ((0, 1 - fx), (1, fx)):
            out = out + wy * wx * img[(y0 + dy) % h, (x0 + dx) % w].astype(float)
    return out


# ----------------------------------------------------------------------------- Mitsuba pieces
# Mitsuba's envmap looks up a local direction v as u = atan2(v.x, -v.z)/(2 pi), v = acos(v.y)/pi.
# This to_world maps that local frame onto FORMATS.md's (local +x -> world +Y, local +y -> world
# +Z, local -z -> world +X); check (b) verifies it against Mitsuba's own emitter.
ENVMAP_TO_WORLD = [[0, 0, -1, 0], [1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 0, 1]]


def sensor_dict(spp=16, far_clip=1e7):
    return {
        "type": "perspective", "fov": FOV_X_DEG, "fov_axis": "x",
        "near_clip": 0.01, "far_clip": far_clip,
        "to_world": mi.ScalarTransform4f().look_at(origin=CAM_ORIGIN.tolist(), target=CAM_TARGET.tolist(),
                                                   up=CAM_UP.tolist()),
        "sampler": {"type": "independent", "sample_count": spp},
        "film": {"type": "hdrfilm", "width": WIDTH, "height": HEIGHT, "pixel_format": "rgb",
                 "rfilter": {"type": "box"}},
    }


def sun_disk_emitter(direction, radiance, angular_diameter_deg, distance=SUN_DISTANCE):
    """Mitsuba's stand-in for an infinitely far sun: an emitting disk of the sun's angular
    diameter at `distance` along the unit `direction` (shared with survey_reference.py)."""
    r = distance * math.tan(math.radians(angular_diameter_deg / 2))
    # look_at points the disk's local +z (its emitting side) toward the scene origin.
    up = [0, 0, 1] if abs(direction[2]) < 0.99 else [1, 0, 0]
    tw = mi.ScalarTransform4f().look_at(origin=(distance * direction).tolist(), target=[0, 0, 0], up=up) \
        @ mi.ScalarTransform4f().scale([r, r, 1.0])
    return {"type": "disk", "to_world": tw,
            "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [float(x) for x in radiance]}}}


def sun_disk_dict(radiance=SUN_RADIANCE):
    return sun_disk_emitter(sun_direction(), radiance, SUN_ANGULAR_DIAMETER_DEG)


def mitsuba_sky(sky):
    """Resample a FORMATS.md lat-long map for Mitsuba's envmap. Mitsuba places its columns at
    u = (j + .5) / W like FORMATS.md, but its rows at v = r / (H' - 1) (first row at the zenith,
    last at the nadir) where FORMATS.md has v = (i + .5) / H. A map of H' = 2H + 1 rows holding
    FORMATS.md's row i at r = 2i + 1, the mean of rows i - 1 and i at r = 2i, and rows 0 and H - 1
    repeated at the poles has exactly FORMATS.md's bilinear lookup (both are linear in theta
    between these knots). Check (b) verifies the result against Mitsuba's emitter."""
    h = sky.shape[0]
    out = np.empty((2 * h + 1,) + sky.shape[1:], np.float32)
    out[1::2] = sky
    out[2:-1:2] = 0.5 * (sky[:-1].astype(np.float64) + sky[1:])
    out[0], out[-1] = sky[0], sky[-1]
    return out


def envmap_dict(sky_path):
    """sky_path: the Mitsuba-side map written by mitsuba_sky()."""
    return {"type": "envmap", "filename": sky_path, "scale": 1.0,
            "to_world": mi.ScalarTransform4f(ENVMAP_TO_WORLD)}


def diffuse(value_or_path):
    if isinstance(value_or_path, str):
        # Mitsuba's bitmap lookup has v = 0 at the top row; FORMATS.md (like OBJ) has v = 0 at
        # the bottom row, so flip v. Check (d) verifies this against Mitsuba's BSDF.
        refl = {"type": "bitmap", "filename": value_or_path, "raw": True, "filter_type": "bilinear",
                "wrap_mode": "repeat",
                "to_uv": mi.ScalarTransform4f().translate([0, 1, 0]) @ mi.ScalarTransform4f().scale([1, -1, 1])}
    else:
        refl = {"type": "rgb", "value": list(value_or_path)}
    return {"type": "diffuse", "reflectance": refl}


def scene_dict(out, spp=16, max_depth=MAX_DEPTH):
    return {
        "type": "scene",
        "integrator": {"type": "path", "max_depth": max_depth, "hide_emitters": False},
        "sensor": sensor_dict(spp),
        "sky": envmap_dict(os.path.join(out, "mitsuba_sky.exr")),
        "sun": sun_disk_dict(),
        "ground": {"type": "ply", "filename": os.path.join(out, "ground.ply"), "bsdf": diffuse(GROUND_ALBEDO)},
        "colonnade": {"type": "ply", "filename": os.path.join(out, "colonnade.ply"),
                      "bsdf": diffuse(COLONNADE_ALBEDO)},
        "wall": {"type": "ply", "filename": os.path.join(out, "wall.ply"),
                 "bsdf": diffuse(os.path.join(out, "wall_albedo.exr"))},
    }


def render(scene, spp, seed):
    return np.array(mi.render(scene, spp=spp, seed=seed), dtype=np.float64)


# ----------------------------------------------------------------------------- camera (OpenCV)
def opencv_camera():
    """World->camera R, t and K for the Mitsuba sensor above. Mitsuba's camera frame is x left,
    y up, z forward; OpenCV's is x right, y down, z forward."""
    m = np.array(mi.ScalarTransform4f().look_at(origin=CAM_ORIGIN.tolist(), target=CAM_TARGET.tolist(),
                                                up=CAM_UP.tolist()).matrix, dtype=float)
    cam_to_world_mi = m[:3, :3]
    cv_axes_world = np.stack([-cam_to_world_mi[:, 0], -cam_to_world_mi[:, 1], cam_to_world_mi[:, 2]])
    R = cv_axes_world                      # rows: camera axes in world coordinates
    t = -R @ CAM_ORIGIN
    fx = (WIDTH / 2.0) / math.tan(math.radians(FOV_X_DEG) / 2.0)
    fy = fx                                # square pixels, fov given along x
    cx, cy = WIDTH / 2.0 - 0.5, HEIGHT / 2.0 - 0.5   # centre of the top-left pixel is (0, 0)
    K = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    return K, R, t


def project(K, R, t, p):
    x = R @ p + t
    return np.array([K[0, 0] * x[0] / x[2] + K[0, 2], K[1, 1] * x[1] / x[2] + K[1, 2]])


# ----------------------------------------------------------------------------- self-checks
def check_camera(K, R, t):
    pts = [np.array(p) for p in ([0.0, 1.0, 2.0], [-4.0, 0.0, 3.8], [4.0, -0.3, 1.0],
                                 [-2.5, 3.0, 0.6], [5.0, 2.9, 4.2], [-1.0, -6.0, 0.3])]
    dist = [np.linalg.norm(p - CAM_ORIGIN) for p in pts]
    ang_px = math.radians(FOV_X_DEG) / WIDTH
    scene = {"type": "scene", "integrator": {"type": "path", "max_depth": 1}, "sensor": sensor_dict(64)}
    for k, (p, d) in enumerate(zip(pts, dist)):
        scene[f"m{k}"] = {"type": "sphere", "center": p.tolist(), "radius": float(1.6 * ang_px * d),
                          "emitter": {"type": "area", "radiance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}}
    img = render(mi.load_dict(scene), 1024, 7).mean(axis=2)
    errs = []
    ys, xs = np.mgrid[0:HEIGHT, 0:WIDTH]
    for p in pts:
        uv = project(K, R, t, p)
        win = (np.abs(xs - uv[0]) <= 6) & (np.abs(ys - uv[1]) <= 6)
        w = img * win
        assert w.sum() > 1.0, f"marker at {p} not found near {uv}"
        c = np.array([(w * xs).sum(), (w * ys).sum()]) / w.sum()
        errs.append(float(np.linalg.norm(c - uv)))
    print(f"(a) camera: marker centroid vs OpenCV projection, max error {max(errs):.4f} px "
          f"(all: {', '.join(f'{e:.3f}' for e in errs)})")
    assert max(errs) < 0.3, errs
    return max(errs)


def check_envmap(out, sky):
    scene = mi.load_dict({"type": "scene", "sky": envmap_dict(os.path.join(out, "mitsuba_sky.exr"))})
    em = scene.emitters()[0]
    rng = np.random.default_rng(5)
    dirs = [np.array(d) for d in ([0, 0, 1], [1, 0, 0], [0, 1, 0], [-1, 0, 0], [0, -1, 0.2], [0.3, 0.2, -0.9])]
    dirs += list(latlong_pixel_dirs(SKY_W, SKY_H).reshape(-1, 3)[rng.choice(SKY_W * SKY_H, 40)])
    dirs += list(rng.normal(size=(60, 3)))
    dirs.append(sun_direction())
    worst = 0.0
    for d in dirs:
        d = d / np.linalg.norm(d)
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-d))          # Mitsuba's envmap eval looks up -si.wi
        v_mi = np.array(em.eval(si), dtype=float)
        v_ref = latlong_lookup(sky, d)
        rel = float(np.max(np.abs(v_mi - v_ref) / np.maximum(np.abs(v_ref), 1e-3)))
        worst = max(worst, rel)
    print(f"(b) envmap: Mitsuba envmap.eval vs FORMATS lat-long lookup, {len(dirs)} directions, "
          f"max relative difference {worst:.2e}")
    assert worst < 1e-4, worst
    return worst


def plane_irradiance(emitter):
    """Mitsuba's irradiance (RGB) on a horizontal white Lambertian plane lit by `emitter` alone,
    seen from above by an orthographic camera (shared with survey_reference.py)."""
    cam = {"type": "orthographic", "near_clip": 0.01, "far_clip": 100.0,
           "to_world": mi.ScalarTransform4f().look_at(origin=[0, 0, 10], target=[0, 0, 0], up=[0, 1, 0])
           @ mi.ScalarTransform4f().scale([0.5, 0.5, 1]),
           "sampler": {"type": "independent", "sample_count": 64},
           "film": {"type": "hdrfilm", "width": 8, "height": 8, "pixel_format": "rgb", "rfilter": {"type": "box"}}}
    scene = mi.load_dict({
        "type": "scene", "integrator": {"type": "direct", "emitter_samples": 4, "bsdf_samples": 1},
        "sensor": cam, "sun": emitter,
        "plane": {"type": "rectangle", "to_world": mi.ScalarTransform4f().scale([5, 5, 1]),
                  "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [1.0, 1.0, 1.0]}}},
    })
    img = render(scene, 64, 3)
    return img.reshape(-1, 3).mean(axis=0) * math.pi          # white Lambertian: L = E / pi


def check_sun_irradiance():
    sun = sun_direction()
    e_mi = plane_irradiance(sun_disk_dict())
    alpha = math.radians(SUN_ANGULAR_DIAMETER_DEG / 2)
    omega = 2 * math.pi * (1 - math.cos(alpha))
    e_ref = SUN_RADIANCE * omega * sun[2]
    rel = float(np.max(np.abs(e_mi / e_ref - 1)))
    print(f"(c) sun: irradiance on a horizontal plane, Mitsuba {e_mi.round(5).tolist()} vs "
          f"L*omega*cos(zenith) {e_ref.round(5).tolist()} (omega = {omega:.4e} sr), max relative error {rel:.2e}")
    assert rel < 0.01, rel
    return rel, e_ref.tolist()


def check_texture(out, tex):
    scene = mi.load_dict(scene_dict(out, spp=1))
    wall = [s for s in scene.shapes() if s.id() == "wall"][0]
    bsdf = wall.bsdf()
    rng = np.random.default_rng(11)
    worst_uv, worst = 0.0, 0.0
    for _ in range(50):
        x, z = rng.uniform(-5.9, 5.9), rng.uniform(0.05, 4.45)
        ray = mi.Ray3f(mi.Point3f(x, 1.0, z), mi.Vector3f(0, 1, 0))
        si = scene.ray_intersect(ray)
        assert si.is_valid() and si.shape == wall and abs(si.p[1] - WALL_LO[1]) < 1e-4
        u_ply, v_ply = (x - WALL_LO[0]) / (WALL_HI[0] - WALL_LO[0]), z / WALL_HI[2]
        worst_uv = max(worst_uv, abs(si.uv[0] - u_ply), abs(si.uv[1] - v_ply))
        v_mi = np.array(bsdf.eval_diffuse_reflectance(si), dtype=float)
        v_ref = texture_lookup(tex, u_ply, v_ply)
        worst = max(worst, float(np.max(np.abs(v_mi - v_ref))))
    print(f"(d) texture: Mitsuba wall reflectance at ray hits vs FORMATS texel lookup at the PLY uv, "
          f"max abs difference {worst:.2e} (uv read back within {worst_uv:.1e})")
    assert worst_uv < 1e-4 and worst < 2e-3, (worst_uv, worst)
    return worst


# ----------------------------------------------------------------------------- main
def write_inputs(out):
    os.makedirs(out, exist_ok=True)
    write_ply(os.path.join(out, "ground.ply"), *ground_mesh())
    write_ply(os.path.join(out, "colonnade.ply"), *colonnade_mesh())
    write_ply(os.path.join(out, "wall.ply"), *wall_mesh())
    tex, sky = wall_texture(), make_sky()
    write_exr(os.path.join(out, "wall_albedo.exr"), tex)
    write_exr(os.path.join(out, "sky.exr"), sky)
    write_exr(os.path.join(out, "mitsuba_sky.exr"), mitsuba_sky(sky))
    sun = sun_direction()
    fmt = lambda v: "[" + ", ".join(repr(float(x)) for x in v) + "]"
    write_text(os.path.join(out, "lighting.toml"),
               "# Generated by datasets/mitsuba/outdoor_reference.py (Mitsuba 3 reference scene).\n"
               "[environment]\nmap = \"sky.exr\"\nscale = 1.0\n\n"
               f"[sun]\ndirection = {fmt(sun)}\nradiance = {fmt(SUN_RADIANCE)}\n"
               f"angular_diameter_deg = {SUN_ANGULAR_DIAMETER_DEG}\n")
    write_text(os.path.join(out, "scene.toml"),
               "# Generated by datasets/mitsuba/outdoor_reference.py (Mitsuba 3 reference scene).\n"
               "# All materials diffuse. Render with: igi render scene.toml --camera camera.json --indirect 2\n"
               "lighting = \"lighting.toml\"\n\n"
               f"[[object]]\nmesh = \"ground.ply\"\nalbedo = {fmt(GROUND_ALBEDO)}\n\n"
               f"[[object]]\nmesh = \"colonnade.ply\"\nalbedo = {fmt(COLONNADE_ALBEDO)}\n\n"
               "[[object]]\nmesh = \"wall.ply\"\nalbedo = \"wall_albedo.exr\"\n")
    K, R, t = opencv_camera()
    cam = {"width": WIDTH, "height": HEIGHT, "K": K.tolist(), "dist": [0.0, 0.0, 0.0, 0.0, 0.0],
           "R": R.tolist(), "t": t.tolist()}
    write_text(os.path.join(out, "camera.json"), json.dumps(cam, indent=2) + "\n")
    return tex, sky, (K, R, t)


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=DEFAULT_OUT)
    ap.add_argument("--renders", type=int, default=16, help="M independent renders (seeds 1..M)")
    ap.add_argument("--spp", type=int, default=256, help="samples per pixel of each render")
    ap.add_argument("--checks-only", action="store_true")
    args = ap.parse_args()
    mi.set_variant("scalar_rgb")
    out = os.path.abspath(args.out)

    tex, sky, (K, R, t) = write_inputs(out)
    checks = {
        "camera_max_px_error": check_camera(K, R, t),
        "envmap_max_rel_diff": check_envmap(out, sky),
    }
    rel, e_sun = check_sun_irradiance()
    checks["sun_irradiance_rel_error"] = rel
    checks["sun_irradiance_horizontal"] = e_sun
    checks["texture_max_abs_diff"] = check_texture(out, tex)
    if args.checks_only:
        return 0

    scene = mi.load_dict(scene_dict(out, spp=args.spp))
    acc = np.zeros((HEIGHT, WIDTH, 3))
    acc2 = np.zeros((HEIGHT, WIDTH, 3))
    t0 = time.time()
    for s in range(1, args.renders + 1):
        img = render(scene, args.spp, s)
        assert np.all(np.isfinite(img))
        acc += img
        acc2 += img * img
        print(f"render {s}/{args.renders}: {time.time() - t0:.1f} s", flush=True)
    m = args.renders
    mean = acc / m
    var = np.maximum(acc2 / m - mean * mean, 0.0) * m / (m - 1)       # sample variance of one render
    stderr = np.sqrt(var / m)
    write_exr(os.path.join(out, "reference.exr"), mean)
    write_exr(os.path.join(out, "reference_stderr.exr"), stderr)
    meta = {"generator": "datasets/mitsuba/outdoor_reference.py", "mitsuba": mi.__version__,
            "variant": "scalar_rgb", "integrator": {"type": "path", "max_depth": MAX_DEPTH},
            "rfilter": "box", "renders": m, "spp_per_render": args.spp, "seeds": list(range(1, m + 1)),
            "total_spp": m * args.spp, "render_seconds": round(time.time() - t0, 1),
            "sun_distance_m": SUN_DISTANCE, "sun_disk_radius_m": SUN_DISTANCE * math.tan(math.radians(0.265)),
            "mean_radiance": mean.reshape(-1, 3).mean(axis=0).tolist(),
            "mean_relative_stderr": float((stderr / np.maximum(mean, 1e-6)).mean()),
            "self_checks": checks}
    write_text(os.path.join(out, "reference_meta.json"), json.dumps(meta, indent=2) + "\n")
    print(json.dumps(meta, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
