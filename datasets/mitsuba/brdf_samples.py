#!/usr/bin/env python3
"""BRDF sample fixtures from Mitsuba 3's own BSDF evaluation (scalar_rgb).
Writes FORMATS.md BRDF CSVs: r, g, b = pi * f, where f = eval / cos(theta_light) (Mitsuba 3's
BSDF.eval includes the cosine foreshortening of the incident direction, divided out here).
  datasets/fixtures/brdf/samples.csv  light at 0/30/50/75 deg in the x-z plane, 20 views each,
                                      1 % multiplicative noise (numpy seed 2024)
  datasets/fixtures/brdf/heldout.csv  500 random light/view pairs per material, noise-free
  datasets/fixtures/brdf/lights8.csv  (--lights8) 8 light positions x 20 views per material, 1 %
                                      noise (numpy seed 2025): the first four are the lights of
                                      samples.csv, then (elevation, azimuth) (20, 90), (40, 225),
                                      (60, 135), (65, 300); each light's 20 views are those of
                                      samples.csv rotated by the light's azimuth (the hand-held
                                      frame: the camera moves with the light around the sample)
  datasets/fixtures/brdf/validation_lights8.csv, validation_heldout.csv  (--validation) the same
                                      two files (8 lights x 20 views, seed 2026; 500 noise-free
                                      random pairs, seed 2027) for four other materials (VALIDATION),
                                      never used to choose the fit's options: a check that the
                                      default fit's gain on the fixtures is no fit to the fixtures
Usage: python3 datasets/mitsuba/brdf_samples.py [--lights8 | --validation]"""
import math, os, sys
import numpy as np
import mitsuba as mi

mi.set_variant("scalar_rgb")
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fixtures", "brdf")
MATERIALS = {
    "plastic_a010": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.1,
                     "diffuse_reflectance": {"type": "rgb", "value": [0.6, 0.25, 0.1]}},
    "plastic_a030": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.3,
                     "diffuse_reflectance": {"type": "rgb", "value": [0.15, 0.45, 0.2]}},
    "dark_grazing": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.2, "int_ior": 1.9,
                     "diffuse_reflectance": {"type": "rgb", "value": [0.03, 0.03, 0.035]}},
}


def pi_f(bsdf, wl, wv):
    si = mi.SurfaceInteraction3f()
    si.sh_frame = mi.Frame3f(mi.Vector3f(0, 0, 1))
    si.wi = mi.Vector3f(*wv)          # Mitsuba: wi = toward the viewer, wo = toward the light
    v = np.array(bsdf.eval(mi.BSDFContext(), si, mi.Vector3f(*wl)), dtype=float)
    return math.pi * v / wl[2]


def hemi(rng):
    while True:
        d = rng.normal(size=3)
        d /= np.linalg.norm(d)
        if d[2] > 0.02:
            return d


VALIDATION = {
    "val_a005_blue": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.05,
                      "diffuse_reflectance": {"type": "rgb", "value": [0.15, 0.25, 0.55]}},
    "val_a015_grey": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.15, "int_ior": 1.6,
                      "diffuse_reflectance": {"type": "rgb", "value": [0.45, 0.45, 0.4]}},
    "val_beckmann_a020": {"type": "roughplastic", "distribution": "beckmann", "alpha": 0.2,
                          "diffuse_reflectance": {"type": "rgb", "value": [0.35, 0.2, 0.3]}},
    "val_a040_yellow": {"type": "roughplastic", "distribution": "ggx", "alpha": 0.4,
                        "diffuse_reflectance": {"type": "rgb", "value": [0.7, 0.6, 0.2]}},
}

LIGHTS8 = [(0, 0), (30, 0), (50, 0), (75, 0), (20, 90), (40, 225), (60, 135), (65, 300)]


def lights8(bsdfs, head, file="lights8.csv", seed=2025):
    """8 light positions x 20 views, 1 % noise: the fixture of the error-against-lights plot."""
    rng = np.random.default_rng(seed)
    rows = []
    for name, b in bsdfs.items():
        for lt, la in LIGHTS8:
            t, a = math.radians(lt), math.radians(la)
            wl = np.array([math.sin(t) * math.cos(a), math.sin(t) * math.sin(a), math.cos(t)])
            for k in range(20):
                vt = math.radians(-80 + 160 * k / 19)
                vp = math.radians(10.0 * (k % 3)) + a
                wv = np.array([math.sin(vt) * math.cos(vp), math.sin(vt) * math.sin(vp), math.cos(vt)])
                val = pi_f(b, wl, wv) * (1 + 0.01 * rng.standard_normal(3))
                rows.append([name, *wl, *wv, *val])
    with open(os.path.join(OUT, file), "w") as f:
        f.write(head + "".join(",".join([r[0]] + [f"{x:.7g}" for x in r[1:]]) + "\n" for r in rows))


def heldout(bsdfs, head, file, rng):
    """500 noise-free pairs per material, both directions uniform on the hemisphere."""
    rows = []
    for name, b in bsdfs.items():
        for _ in range(500):
            wl, wv = hemi(rng), hemi(rng)
            rows.append([name, *wl, *wv, *pi_f(b, wl, wv)])
    with open(os.path.join(OUT, file), "w") as f:
        f.write(head + "".join(",".join([r[0]] + [f"{x:.7g}" for x in r[1:]]) + "\n" for r in rows))


def main():
    os.makedirs(OUT, exist_ok=True)
    if "--validation" in sys.argv:
        bsdfs = {k: mi.load_dict(v) for k, v in VALIDATION.items()}
        head = "material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n"
        lights8(bsdfs, head, "validation_lights8.csv", 2026)
        heldout(bsdfs, head, "validation_heldout.csv", np.random.default_rng(2027))
        return
    if "--lights8" in sys.argv:
        bsdfs = {k: mi.load_dict(v) for k, v in MATERIALS.items()}
        lights8(bsdfs, "material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n")
        return
    rng = np.random.default_rng(2024)
    bsdfs = {k: mi.load_dict(v) for k, v in MATERIALS.items()}
    # sanity: a white diffuse reads 1 (checks the cosine convention)
    white = mi.load_dict({"type": "diffuse", "reflectance": {"type": "rgb", "value": [1, 1, 1]}})
    assert np.allclose(pi_f(white, np.array([0.5, 0, math.sqrt(0.75)]), np.array([0, 0.6, 0.8])), 1, atol=1e-5)
    head = "material,light_x,light_y,light_z,view_x,view_y,view_z,r,g,b\n"
    rows = []
    for name, b in bsdfs.items():
        for lt in (0, 30, 50, 75):
            t = math.radians(lt)
            wl = np.array([math.sin(t), 0.0, math.cos(t)])
            for k in range(20):
                vt = math.radians(-80 + 160 * k / 19)
                vp = math.radians(10.0 * (k % 3))
                wv = np.array([math.sin(vt) * math.cos(vp), math.sin(vt) * math.sin(vp), math.cos(vt)])
                if wv[2] < 0:
                    wv = -wv; wv[2] = -wv[2]
                val = pi_f(b, wl, wv) * (1 + 0.01 * rng.standard_normal(3))
                rows.append([name, *wl, *wv, *val])
    with open(os.path.join(OUT, "samples.csv"), "w") as f:
        f.write(head + "".join(",".join([r[0]] + [f"{x:.7g}" for x in r[1:]]) + "\n" for r in rows))
    rows = []
    for name, b in bsdfs.items():
        for _ in range(500):
            wl, wv = hemi(rng), hemi(rng)
            rows.append([name, *wl, *wv, *pi_f(b, wl, wv)])
    with open(os.path.join(OUT, "heldout.csv"), "w") as f:
        f.write(head + "".join(",".join([r[0]] + [f"{x:.7g}" for x in r[1:]]) + "\n" for r in rows))


if __name__ == "__main__":
    main()
