#!/usr/bin/env python3
"""Mitsuba 3's `sunsky` emitter as an independent reference for igi-sky (docs/SKY.md,
"Against Mitsuba 3").

For one site (Paris, 48.85 N 2.35 E, UTC+2) on 21 June 2026 at several local times, turbidity 3
and ground albedo 0.2, this loads Mitsuba's sunsky from the time and place (its own solar
position), reads its sun direction, and evaluates the emitter's RGB radiance (`scalar_rgb`,
`emitter.eval` on a surface interaction whose `wi` points away from the sky) in a fixed set of
world directions away from the sun's disk. Writes datasets/fixtures/sky/mitsuba_sunsky.csv.

Frames: igi's world here is east-north-up (x east, y north, z up: `[site] north` +Y).
Mitsuba's sunsky, loaded with an identity `to_world`, puts the sun at (-north, -east, up) of its
local frame (checked against SPA: the printed directions below), a mirror of east-north-up. So
the igi direction (e, n, u) is Mitsuba's local (-n, -e, u); this script maps each direction
through that reflection rather than handing Mitsuba a `to_world` of determinant -1.

Run: python3 datasets/mitsuba/sunsky_reference.py   (mitsuba==3.9.1, numpy)
"""
import csv
import math
import os

import mitsuba as mi

mi.set_variant("scalar_rgb")

LAT, LON, TZ = 48.85, 2.35, 2.0
TIMES = [(7, 30), (10, 0), (12, 0), (14, 30), (17, 30), (19, 30)]
TURBIDITY, ALBEDO = 3.0, 0.2
OUT = os.path.join(os.path.dirname(os.path.abspath(__file__)), "..", "fixtures", "sky",
                   "mitsuba_sunsky.csv")


def igi_to_mitsuba(d):
    e, n, u = d
    return (-n, -e, u)


def mitsuba_to_igi(m):
    a, b, u = m
    return (-b, -a, u)


def directions():
    """Zenith angles 5..85 deg by 10, azimuths 0..330 by 30 (east-north-up), and the zenith."""
    out = [(0.0, 0.0, 1.0)]
    for zen in range(5, 90, 10):
        for az in range(0, 360, 30):
            t, p = math.radians(zen), math.radians(az)
            # azimuth clockwise from north: (sin az, cos az) in (east, north)
            out.append((math.sin(t) * math.sin(p), math.sin(t) * math.cos(p), math.cos(t)))
    return out


def main():
    rows = []
    for hour, minute in TIMES:
        emitter = mi.load_dict({
            "type": "sunsky",
            "latitude": LAT, "longitude": LON, "timezone": TZ,
            "year": 2026, "month": 6, "day": 21,
            "hour": float(hour), "minute": float(minute), "second": 0.0,
            "turbidity": TURBIDITY, "albedo": ALBEDO,
        })
        sun_m = mi.traverse(emitter)["sun_direction"]
        sun = mitsuba_to_igi([sun_m[0], sun_m[1], sun_m[2]])
        for d in directions():
            cos_sun = sum(a * b for a, b in zip(d, sun))
            if cos_sun > math.cos(math.radians(3.0)):
                continue  # away from the sun's disk (Mitsuba's eval includes it)
            m = igi_to_mitsuba(d)
            si = mi.SurfaceInteraction3f()
            si.wi = mi.Vector3f(-m[0], -m[1], -m[2])
            v = emitter.eval(si)
            rows.append([f"{hour:02d}:{minute:02d}", *sun, *d, v[0], v[1], v[2]])
        print(f"{hour:02d}:{minute:02d} sun (igi east-north-up) {sun}")
    with open(OUT, "w", newline="") as f:
        f.write("# Mitsuba 3.9.1 sunsky, scalar_rgb: Paris 48.85 N 2.35 E, UTC+2, 2026-06-21, "
                "turbidity 3, albedo 0.2; directions east-north-up (datasets/mitsuba/sunsky_reference.py)\n")
        w = csv.writer(f)
        w.writerow(["local_time", "sun_x", "sun_y", "sun_z", "dir_x", "dir_y", "dir_z", "r", "g", "b"])
        for r in rows:
            w.writerow([r[0]] + [f"{x:.9g}" for x in r[1:]])
    print(f"wrote {len(rows)} rows to {OUT}")


if __name__ == "__main__":
    main()
