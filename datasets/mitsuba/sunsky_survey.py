#!/usr/bin/env python3
"""A survey without light probes, rendered by Mitsuba 3 under its `sunsky` emitter (issue 34).

The site, albedo textures, cameras and Mitsuba scene helpers of
datasets/mitsuba/survey_reference.py (ground square, block, wall; diffuse textures known per
texel), with a grey card painted on the ground (a disc of albedo 0.5 at CARD_CENTER, radius
CARD_RADIUS) and six photographs around the site, each at its own time of 21 June 2026 in
Paris (UTC+2): five under Mitsuba's Hosek-Wilkie `sunsky` (turbidity 3, ground albedo 0.2,
with per-photo `sun_scale` and `sky_scale` as haze or thin cloud would give), one under a CIE
overcast sky (an `envmap` of the sky igi-sky's `CieOvercast` describes, no sun). The survey
gives each photo its `time` and no lighting, the site its latitude and longitude, and names the
card as a `[[reference]]` target; `survey_nocard.toml` is the same without the target.

Frames: Mitsuba's sunsky puts the sun at (-north, -east, up) of its local frame, a mirror image
of east-north-up (docs/SKY.md). With igi's world east = +X, north = +Y, up = +Z, the emitter's
`to_world` is the reflection (a, b, u) -> (-b, -a, u), so that the rendered sun stands where SPA
puts it; the script checks that `emitter.eval` toward the SPA-like direction it reads back is
the sun's disk.

Units: a Mitsuba sunsky radiance times 106.75 is igi-sky's (docs/SKY.md, "Against Mitsuba 3"),
so `sun_scale` and `sky_scale` are 106.75 times the scales igi's estimation should find.

Writes (default datasets/fixtures/sunsky_survey):
    survey.toml, survey_nocard.toml   photos with `time`, no lighting; [site] location
    geometry/*.ply, cameras/*.json, photos/*.exr, truth/scene.toml + *_albedo.exr
    truth.json                        per photo: time, Mitsuba's sun direction (igi frame),
                                      the scales, the overcast zenith radiance

Run: python3 datasets/mitsuba/sunsky_survey.py [--out DIR] [--spp N]   (mitsuba 3.9.1, numpy)
"""

import argparse
import json
import math
import os
import sys
import tempfile
import time

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)

import survey_reference as S  # noqa: E402  (site, textures, cameras, Mitsuba scenes)
import outdoor_reference as ref  # noqa: E402
import mitsuba as mi  # noqa: E402

LAT, LON, TZ = 48.85, 2.35, 2.0
DATE = (2026, 6, 21)
TURBIDITY, GROUND_ALBEDO = 3.0, 0.2
MITSUBA_TO_IGI = 106.75            # docs/SKY.md: Mitsuba sunsky radiance x this = igi-sky's
CARD_CENTER = np.array([2.6, -2.6, 0.0])
CARD_RADIUS = 0.6
CARD_ALBEDO = 0.5
OVERCAST_ZENITH = 2.5              # igi units (CIE overcast zenith radiance)
# (id, local time, sun scale, sky scale) in igi's units (Mitsuba's = x MITSUBA_TO_IGI);
# sun scale None: the CIE overcast sky instead
SHOTS = [("t0830", (8, 30), 0.85, 1.10), ("t1030", (10, 30), 1.00, 1.00),
         ("t1230", (12, 30), 0.95, 0.90), ("t1430-overcast", (14, 30), None, None),
         ("t1630", (16, 30), 0.90, 1.20), ("t1830", (18, 30), 0.80, 1.30)]
SIZE = (200, 150)
FOV = 60.0


def ground_with_card(f):
    def g(p):
        v = f(p)
        d = np.linalg.norm(np.asarray(p, float)[..., :2] - CARD_CENTER[:2], axis=-1)
        return np.where((d <= CARD_RADIUS)[..., None], CARD_ALBEDO, v)
    return g


_albedo = S.albedo_function
S.albedo_function = lambda name: ground_with_card(_albedo(name)) if name == "ground" else _albedo(name)

REFLECT = [[0.0, -1.0, 0.0, 0.0], [-1.0, 0.0, 0.0, 0.0], [0.0, 0.0, 1.0, 0.0], [0.0, 0.0, 0.0, 1.0]]


def sunsky(hm, sun_scale, sky_scale):
    return {"type": "sunsky", "latitude": LAT, "longitude": LON, "timezone": TZ,
            "year": DATE[0], "month": DATE[1], "day": DATE[2],
            "hour": float(hm[0]), "minute": float(hm[1]), "second": 0.0,
            "turbidity": TURBIDITY, "albedo": GROUND_ALBEDO,
            "sun_scale": sun_scale * MITSUBA_TO_IGI, "sky_scale": sky_scale * MITSUBA_TO_IGI,
            "to_world": mi.ScalarTransform4f(REFLECT)}


def mitsuba_sun_igi(hm):
    """Mitsuba's own sun direction (local frame, identity to_world) mapped to igi's frame."""
    e = mi.load_dict({**sunsky(hm, 1.0, 1.0), "to_world": mi.ScalarTransform4f()})
    a, b, u = (float(x) for x in mi.traverse(e)["sun_direction"])
    return np.array([-b, -a, u])


def check_rendered_sun(hm, sun_igi):
    """emitter.eval (with the reflecting to_world) toward sun_igi is the disk; 1 degree off it,
    and toward the unreflected direction, it is sky."""
    e = mi.load_dict(sunsky(hm, 1.0, 1.0))

    def ev(d):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-np.asarray(d, float)))
        return float(np.mean(np.array(e.eval(si))))
    on = ev(sun_igi)
    off_dir = sun_igi + np.array([0.0, 0.0, math.radians(1.0)])
    off = ev(off_dir / np.linalg.norm(off_dir))
    mirror = ev(np.array([sun_igi[1], sun_igi[0], sun_igi[2]]))
    assert on > 1000 * off and on > 1000 * mirror, (hm, on, off, mirror)
    return on / off


def sun_irradiance(hm, sun_igi, n=161, half_deg=0.4):
    """The irradiance of Mitsuba's sun disk at normal incidence (igi units, sun_scale 1): its
    radiance less the sky's just outside it, summed over an n x n grid of directions within
    half_deg of the sun (tangent-plane steps, solid angle per cell dx dy / (1 + r^2)^1.5)."""
    e = mi.load_dict(sunsky(hm, 1.0, 1.0))
    s = np.asarray(sun_igi, float)
    t1 = np.cross(s, [0.0, 0.0, 1.0])
    t1 /= np.linalg.norm(t1)
    t2 = np.cross(s, t1)

    def ev(d):
        si = mi.SurfaceInteraction3f()
        si.wi = mi.Vector3f(*(-np.asarray(d, float)))
        return np.array(e.eval(si), float)
    h = math.tan(math.radians(half_deg))
    xs = np.linspace(-h, h, n)
    step = xs[1] - xs[0]
    ring = [ev((s + h * 1.2 * (math.cos(a) * t1 + math.sin(a) * t2))) for a in np.linspace(0, 2 * math.pi, 12, endpoint=False)]
    sky = np.mean(ring, axis=0)
    total = np.zeros(3)
    for x in xs:
        for y in xs:
            d = s + x * t1 + y * t2
            r2 = x * x + y * y
            total += (ev(d / math.sqrt(1 + r2)) - sky) * step * step / (1 + r2) ** 1.5
    return total               # the emitter already carries MITSUBA_TO_IGI (sunsky())


def cie_overcast_latlong(w, h, zenith):
    d = ref.latlong_pixel_dirs(w, h)
    cz = d[..., 2:3]
    return np.where(cz >= 0, zenith * (1 + 2 * np.clip(cz, 0, 1)) / 3, 0.0) * np.ones(3)


def cameras():
    out = []
    centre = S.SITE_CENTRE
    for k in range(len(SHOTS)):
        az = math.radians(-90 + 360 * k / len(SHOTS) + 15)
        eye = centre + np.array([12.0 * math.cos(az), 12.0 * math.sin(az), 0.0])
        eye[2] = 6.0 + 1.5 * (k % 2)
        out.append(S.opencv_camera(eye, centre + np.array([0.0, 0.0, -0.5]), SIZE[0], SIZE[1], FOV))
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--out", default=os.path.join(ROOT, "datasets", "fixtures", "sunsky_survey"))
    ap.add_argument("--spp", type=int, default=1024)
    args = ap.parse_args()
    out = os.path.abspath(args.out)
    for sub in ("geometry", "photos", "cameras", "truth", "lighting"):
        os.makedirs(os.path.join(out, sub), exist_ok=True)
    work = tempfile.mkdtemp(prefix="igi-sunsky-survey-")
    mi.set_variant("scalar_rgb")
    t0 = time.time()
    for name, part in S.PARTS.items():
        ref.write_ply(os.path.join(out, "geometry", f"{name}.ply"), *part["mesh"]())
        ref.write_exr(os.path.join(out, "truth", f"{name}_albedo.exr"), S.make_texture(name))
    truth_toml = "# Generated by datasets/mitsuba/sunsky_survey.py: the true albedo textures.\n"
    for name in S.PARTS:
        truth_toml += f"\n[[object]]\nmesh = \"../geometry/{name}.ply\"\nalbedo = \"{name}_albedo.exr\"\n"
    ref.write_text(os.path.join(out, "truth", "scene.toml"), truth_toml)
    # the overcast photo's sky: CIE overcast as a contract lighting file (Mitsuba envmap)
    ref.write_exr(os.path.join(out, "lighting", "overcast.exr"),
                  cie_overcast_latlong(256, 128, OVERCAST_ZENITH).astype(np.float32))
    ref.write_text(os.path.join(out, "lighting", "overcast.toml"),
                   "# CIE overcast (igi units), the truth of the overcast photo\n"
                   "[environment]\nmap = \"overcast.exr\"\nscale = 1.0\n")
    cams = cameras()
    head = ("# Generated by datasets/mitsuba/sunsky_survey.py (Mitsuba 3 sunsky): photos with a time and\n"
            "# no lighting; their light is estimated with the albedo.\n"
            "[site]\nmeshes = [" + ", ".join(f"\"geometry/{n}.ply\"" for n in S.PARTS) + "]\n"
            f"latitude_deg = {LAT}\nlongitude_deg = {LON}\n")
    photos = ""
    truth = {"latitude_deg": LAT, "longitude_deg": LON, "mitsuba": mi.__version__,
             "mitsuba_to_igi": MITSUBA_TO_IGI, "turbidity": TURBIDITY, "ground_albedo": GROUND_ALBEDO,
             "card": {"center": CARD_CENTER.tolist(), "radius": CARD_RADIUS, "albedo": CARD_ALBEDO},
             "photos": []}
    for k, (pid, hm, sun_s, sky_s) in enumerate(SHOTS):
        ref.write_text(os.path.join(out, "cameras", f"{pid}.json"), json.dumps(cams[k], indent=2) + "\n")
        stamp = f"{DATE[0]:04d}-{DATE[1]:02d}-{DATE[2]:02d}T{hm[0]:02d}:{hm[1]:02d}:00+02:00"
        photos += (f"\n[[photo]]\nid = \"{pid}\"\nimage = \"photos/{pid}.exr\"\ncamera = \"cameras/{pid}.json\"\n"
                   f"time = \"{stamp}\"\n")
        sun = mitsuba_sun_igi(hm)
        entry = {"id": pid, "time": stamp, "mitsuba_sun_direction": sun.tolist(),
                 "overcast": sun_s is None}
        if sun_s is None:
            entry.update(sun_scale=0.0, sky_scale=0.0, overcast_zenith=OVERCAST_ZENITH)
        else:
            entry.update(sun_scale=sun_s, sky_scale=sky_s, overcast_zenith=0.0,
                         sun_over_sky_at_1deg=check_rendered_sun(hm, sun),
                         sun_irradiance_at_scale_1=sun_irradiance(hm, sun).tolist())
        truth["photos"].append(entry)
    reference = ("\n[[reference]]\n"
                 f"center = [{CARD_CENTER[0]}, {CARD_CENTER[1]}, {CARD_CENTER[2]}]\nnormal = [0.0, 0.0, 1.0]\n"
                 f"radius = {CARD_RADIUS}\nalbedo = [{CARD_ALBEDO}, {CARD_ALBEDO}, {CARD_ALBEDO}]\n")
    print(f"inputs and checks: {time.time() - t0:.1f} s", flush=True)

    variant = "llvm_ad_rgb" if S.llvm_path() else "scalar_rgb"
    mi.set_variant(variant)
    objects = S.read_scene_file(os.path.join(out, "truth", "scene.toml"))
    t1 = time.time()
    for k, (pid, hm, sun_s, sky_s) in enumerate(SHOTS):
        d = S.mitsuba_scene(objects, cams[k], os.path.join(out, "lighting", "overcast.toml"), work)
        if sun_s is not None:
            del d["sky"]
            d["sky"] = sunsky(hm, sun_s, sky_s)
        scene = mi.load_dict(d)
        mean, _ = S.render_mean(scene, args.spp // 2, [k * 16 + 1, k * 16 + 2], min(256, args.spp // 2))
        ref.write_exr(os.path.join(out, "photos", f"{pid}.exr"), mean)
        print(f"photo {pid}: {time.time() - t1:.1f} s, mean {mean.reshape(-1, 3).mean(0)}", flush=True)
    truth["render"] = {"variant": variant, "spp": args.spp, "max_depth": S.MAX_DEPTH, "size": list(SIZE),
                       "seconds": round(time.time() - t1, 1)}
    ref.write_text(os.path.join(out, "survey.toml"), head + photos + reference)
    ref.write_text(os.path.join(out, "survey_nocard.toml"), head + photos)
    ref.write_text(os.path.join(out, "truth.json"), json.dumps(truth, indent=2) + "\n")
    return 0


if __name__ == "__main__":
    sys.exit(main())
