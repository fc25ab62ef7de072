#!/usr/bin/env python3
"""An opacity-hull turntable capture with thin parts that leave the frame, rendered by Mitsuba 3
(issue 32, item 1), in the multi-view capture format `igi hull build` reads (FORMATS.md).

The object: the Stanford bunny (../shared/data, bun_zipper_res2, Z up, 7 cm tall, diffuse beige),
a glossy blue ball beside it (rough plastic, GGX alpha 0.05) and ten straws 0.6 mm thick
(Mitsuba cylinders, radius 0.3 mm: under half a pixel) rising from the bunny out of the top of
every frame, up to z = 1 m. A turntable capture: two cameras (12 and 38 degrees up) x 12
positions 30 degrees apart, 320 x 240, 40 degrees horizontal field of view, 0.3 m from the
object; the object turns, so the room's light (a soft sky with a warm lamp) turns with the
cameras. Per view:
  photos/VIEW.exr            the object with the monitors off (black behind it: premultiplied)
  obj/VIEW-lL-{p,m}.exr      the object in front of the Eq. 1 backdrop (lambda L, n = +1 / -1)
The backdrop is a monitor 0.6 m behind the object, square to the camera and filling its frame,
showing the Eq. 1 pattern one display pixel per camera pixel (a textured area emitter: it
lights the object from behind and the ball reflects it, as a monitor does). The backdrop alone
is the same for every view (the monitor moves with the camera): bg/lL-{p,m}.exr.

Truth at 4 new views between the turntable positions (12/15, 38/105, 25/200, 12/285 degrees),
of the object inside the rig's box (the straws cut at its top, z = 0.15: what a hull can hold):
  heldout/hK.json, heldout/hK.exr (premultiplied colour), heldout/hK_alpha.exr (coverage, in
  all three channels), at TRUTH_SPP.

Mitsuba is only a generator of test data, never a dependency of igi.
Usage: python3 datasets/mitsuba/hull_straws.py [--out DIR] [--spp 64] [--truth-spp 256]
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
import outdoor_reference as ref  # noqa: E402  (EXR writers, lat-long directions, envmap frame)
import slf_gloss as sg  # noqa: E402  (the bunny reader and PLY writer)
import mitsuba as mi  # noqa: E402
import numpy as np  # noqa: E402

BUNNY = os.path.join(sr.ROOT, "..", "shared", "data", "meshes", "stanford_bunny", "reconstruction",
                     "bun_zipper_res2.ply")
W, H, HFOV_DEG, DISTANCE = 320, 240, 40.0, 0.3
TARGET = np.array([0.0, 0.0, 0.01])
BUNNY_HEIGHT = 0.07
BUNNY_COLOUR = [0.55, 0.45, 0.33]
BALL_CENTRE, BALL_RADIUS = [0.03, -0.035, -0.02], 0.015
BALL = {"alpha": 0.05, "diffuse": [0.03, 0.08, 0.40]}
STRAW_RADIUS, STRAW_TOP = 0.0003, 1.0
STRAW_COLOUR = [0.8, 0.75, 0.6]
BOX_MIN, BOX_MAX = [-0.06, -0.06, -0.05], [0.06, 0.06, 0.15]
CAPTURE = [(e, 30.0 * p) for e in (12.0, 38.0) for p in range(12)]
NEW_VIEWS = [(12.0, 15.0), (38.0, 105.0), (25.0, 200.0), (12.0, 285.0)]
LAMBDAS = (27, 40, 53)
MONITOR = 0.6                          # the backdrop's distance behind the camera's target, m
MARGIN = 4                             # display pixels beyond the frame on each side
SKY_W, SKY_H = 256, 128
MAX_DEPTH = 3                          # direct light and one indirect bounce


def straws():
    """The analytic test's straws (crates/opacity-hull/tests/integration/thin_parts.rs)."""
    return [(0.012 + 0.002 * i) * np.array([math.cos(0.6283 * i), math.sin(0.6283 * i)]) for i in range(10)]


def camera(elevation, azimuth):
    """igi's Camera::look_at(eye, TARGET, W, H, HFOV_DEG) at DISTANCE."""
    e, a = math.radians(elevation), math.radians(azimuth)
    eye = DISTANCE * np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    z = (TARGET - eye) / np.linalg.norm(TARGET - eye)
    x = np.cross(z, [0, 0, 1.0])
    x /= np.linalg.norm(x)
    y = np.cross(z, x)
    R = np.stack([x, y, z])
    f = 0.5 * W / math.tan(math.radians(HFOV_DEG) / 2)
    return {"width": W, "height": H, "K": [[f, 0, W / 2 - 0.5], [0, f, H / 2 - 0.5], [0, 0, 1]],
            "dist": [0.0] * 5, "R": R.tolist(), "t": (-R @ eye).tolist()}


def pattern(lam, n):
    """Eq. 1 (igi_opacity_hull::backdrop::pattern_value / 255) at display pixels -MARGIN ..
    W + MARGIN - 1 (rows top to bottom), linear radiance."""
    ys, xs = np.mgrid[-MARGIN:H + MARGIN, -MARGIN:W + MARGIN].astype(np.float64)
    ph = 2 * math.pi * (xs + ys) / lam
    return np.stack([(1 + n * np.sin(ph + i * math.pi / 3)) * 127 / 255 for i in range(3)], -1)


def monitor(cam, texture_path):
    """The backdrop: a rectangle MONITOR m past the target along the camera's axis, square to it,
    covering the frame and MARGIN pixels more; local +z (its emitting side) toward the camera,
    local +y up in the image; the bitmap's top row at the frame's top."""
    R, t, f = np.array(cam["R"]), np.array(cam["t"]), cam["K"][0][0]
    eye = -R.T @ t
    depth = np.linalg.norm(TARGET - eye) + MONITOR
    sx, sy = depth * (W / 2 + MARGIN) / f, depth * (H / 2 + MARGIN) / f
    c2w = np.eye(4)
    c2w[:3, :3], c2w[:3, 3] = R.T, eye          # OpenCV camera axes -> world
    local = np.diag([sx, -sy, -1.0, 1.0])       # x right, y up (camera -y), normal -> camera -z
    local[2, 3] = depth
    tex = {"type": "bitmap", "filename": texture_path, "raw": True, "filter_type": "bilinear",
           "wrap_mode": "clamp"}
    return {"type": "rectangle", "to_world": mi.ScalarTransform4f((c2w @ local).tolist()),
            "emitter": {"type": "area", "radiance": tex},
            "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": [0.0, 0.0, 0.0]}}}


def make_sky():
    """FORMATS.md lat-long map of the room's light: a soft sky (paler at the horizon), a dim
    floor, and a warm lamp 15 degrees wide, 40 degrees up, 60 degrees left of the first camera."""
    d = ref.latlong_pixel_dirs(SKY_W, SKY_H)
    cz = d[..., 2:3]
    sky = np.array([0.45, 0.5, 0.6]) + np.array([0.25, 0.2, 0.1]) * (1 - np.clip(cz, 0, 1)) ** 2
    img = np.where(cz >= 0, sky, np.array([0.12, 0.11, 0.1]) * np.ones_like(sky))
    e, a = math.radians(40), math.radians(60)
    lamp = np.array([math.cos(e) * math.cos(a), math.cos(e) * math.sin(a), math.sin(e)])
    img[np.degrees(np.arccos(np.clip(d @ lamp, -1, 1))) <= 7.5] = [12.0, 10.0, 7.0]
    return img.astype(np.float32)


def scene(cam, azimuth, spp, paths, backdrop=None, object_=True, straw_top=STRAW_TOP, rgba=False):
    """The object (or, with `object_` False, nothing) lit by the room's light turned with the
    turntable by `azimuth`; with `backdrop`, the monitor showing that texture."""
    sensor = sr.sensor_from_camera(cam, spp)
    if rgba:
        sensor["film"]["pixel_format"] = "rgba"
    turn = mi.ScalarTransform4f().rotate([0, 0, 1], azimuth) @ mi.ScalarTransform4f(ref.ENVMAP_TO_WORLD)
    s = {"type": "scene", "sensor": sensor,
         "integrator": {"type": "path", "max_depth": MAX_DEPTH, "hide_emitters": backdrop is None},
         "room": {"type": "envmap", "filename": paths["sky"], "scale": 1.0, "to_world": turn}}
    if object_:
        s["bunny"] = {"type": "ply", "filename": paths["mesh"],
                      "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": BUNNY_COLOUR}}}
        s["ball"] = {"type": "sphere", "center": BALL_CENTRE, "radius": BALL_RADIUS,
                     "bsdf": {"type": "roughplastic", "distribution": "ggx", "alpha": BALL["alpha"],
                              "int_ior": 1.49, "diffuse_reflectance": {"type": "rgb", "value": BALL["diffuse"]}}}
        for i, (x, y) in enumerate(straws()):
            s[f"straw{i}"] = {"type": "cylinder", "p0": [x, y, -0.02], "p1": [x, y, straw_top],
                              "radius": STRAW_RADIUS,
                              "bsdf": {"type": "diffuse", "reflectance": {"type": "rgb", "value": STRAW_COLOUR}}}
    if backdrop is not None:
        s["monitor"] = monitor(cam, backdrop)
    return s


def write_json(path, obj):
    ref.write_text(path, json.dumps(obj, indent=1) + "\n")


def bunny_mesh(path):
    pos, nrm, tris = sg.bunny(BUNNY)
    sg.write_ply(path, pos * BUNNY_HEIGHT, nrm, tris)


def tag(lam, n):
    return f"l{lam}-{'p' if n > 0 else 'm'}"


def main():
    ap = argparse.ArgumentParser()
    ap.add_argument("--out", default="/tmp/hull_straws")
    ap.add_argument("--spp", type=int, default=64)
    ap.add_argument("--truth-spp", type=int, default=256)
    a = ap.parse_args()
    variant = "llvm_ad_rgb" if sr.llvm_path() else "scalar_rgb"
    mi.set_variant(variant)
    out = os.path.abspath(a.out)
    for sub in ("cameras", "photos", "obj", "bg", "heldout", "mitsuba"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)
    paths = {"mesh": os.path.join(out, "mitsuba", "bunny.ply"), "sky": os.path.join(out, "mitsuba", "room.exr")}
    bunny_mesh(paths["mesh"])
    ref.write_exr(paths["sky"], ref.mitsuba_sky(make_sky()))
    patterns = {}
    for lam in LAMBDAS:
        for n in (1, -1):
            p = os.path.join(out, "mitsuba", f"pattern-{tag(lam, n)}.exr")
            # Mitsuba's bitmap has its top row at v = 0, the rectangle's bottom edge (local y = -1)
            ref.write_exr(p, pattern(lam, n)[::-1])
            patterns[(lam, n)] = p
    t0 = time.time()
    # The backdrop alone: the same for every view; checked against Eq. 1 at the pixel centres.
    cam0 = camera(*CAPTURE[0])
    for (lam, n), p in patterns.items():
        img = ref.render(mi.load_dict(scene(cam0, 0.0, a.spp, paths, p, object_=False)), a.spp, 7)
        want = pattern(lam, n)[MARGIN:H + MARGIN, MARGIN:W + MARGIN]
        # a pixel averages the pattern over its area from SPP points: about 0.008 of noise
        err = np.abs(img - want)
        assert err.mean() < 0.015 and err.max() < 0.05, \
            f"the monitor does not show Eq. 1 pixel for pixel (error mean {err.mean()}, max {err.max()})"
        ref.write_exr(os.path.join(out, "bg", f"{tag(lam, n)}.exr"), img)
    rig = ["# Mitsuba 3 capture: datasets/mitsuba/hull_straws.py", "[object]",
           f"bbox_min = {BOX_MIN}", f"bbox_max = {BOX_MAX}", ""]
    for i, (e, az) in enumerate(CAPTURE):
        cam, vid = camera(e, az), f"e{int(e)}-a{int(az):03}"
        write_json(os.path.join(out, "cameras", f"{vid}.json"), cam)
        seed = 1000 + 16 * i
        img = ref.render(mi.load_dict(scene(cam, az, a.spp, paths)), a.spp, seed)
        ref.write_exr(os.path.join(out, "photos", f"{vid}.exr"), img)
        pairs = []
        for k, ((lam, n), p) in enumerate(patterns.items()):
            img = ref.render(mi.load_dict(scene(cam, az, a.spp, paths, p)), a.spp, seed + 1 + k)
            ref.write_exr(os.path.join(out, "obj", f"{vid}-{tag(lam, n)}.exr"), img)
            pairs.append(f'{{ lambda = {lam}, n = {n}, backdrop = "bg/{tag(lam, n)}.exr", '
                         f'object = "obj/{vid}-{tag(lam, n)}.exr" }}')
        rig += ["[[view]]", f'id = "{vid}"', f'camera = "cameras/{vid}.json"', f'photo = "photos/{vid}.exr"',
                "backdrops = [" + ", ".join(pairs) + "]", ""]
        print(f"view {i + 1}/{len(CAPTURE)} {time.time() - t0:.0f} s", flush=True)
    t1 = time.time()
    for k, (e, az) in enumerate(NEW_VIEWS):
        cam = camera(e, az)
        write_json(os.path.join(out, "heldout", f"h{k}.json"), cam)
        sc = scene(cam, az, a.truth_spp, paths, straw_top=BOX_MAX[2], rgba=True)
        img = ref.render(mi.load_dict(sc), a.truth_spp, 9000 + k)
        ref.write_exr(os.path.join(out, "heldout", f"h{k}.exr"), img[..., :3])
        ref.write_exr(os.path.join(out, "heldout", f"h{k}_alpha.exr"), np.repeat(img[..., 3:4], 3, -1))
        print(f"new view {k + 1}/{len(NEW_VIEWS)} {time.time() - t1:.0f} s", flush=True)
    # the rig last: a folder with rig.toml is complete
    write_json(os.path.join(out, "meta.json"), {
        "renderer": f"Mitsuba {mi.__version__} {variant}", "integrator": {"type": "path", "max_depth": MAX_DEPTH},
        "bunny": f"bun_zipper_res2, Z up, {BUNNY_HEIGHT} m tall, diffuse {BUNNY_COLOUR}",
        "ball": {"centre": BALL_CENTRE, "radius": BALL_RADIUS, **BALL},
        "straws": {"radius": STRAW_RADIUS, "top": STRAW_TOP, "positions": [s.tolist() for s in straws()]},
        "capture": CAPTURE, "new_views": NEW_VIEWS, "size": [W, H], "hfov_deg": HFOV_DEG, "spp": a.spp,
        "truth_spp": a.truth_spp, "capture_seconds": round(t1 - t0, 1), "truth_seconds": round(time.time() - t1, 1)})
    ref.write_text(os.path.join(out, "rig.toml"), "\n".join(rig))


if __name__ == "__main__":
    main()
