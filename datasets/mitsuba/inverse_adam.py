#!/usr/bin/env python3
"""igi's inverse global illumination against Mitsuba 3's gradient-based inverse rendering, on the
same survey, on the same machine, in one run.

Mitsuba side: `llvm_ad_rgb`, the `prb` integrator (max_depth 4, the photographs' own light paths),
`mi.ad.Adam` (learning rate 0.03, exponential decay to 5 % of it after 15 steps) on the three albedo textures (ground, block, wall; the truth textures' resolution,
starting from 0.5 grey like igi), L2 loss against every survey photograph under its own lighting
(one backward pass per photograph, one Adam step per sweep over the photographs), albedo clamped
to [0, 1] after every step. The scenes are built from the survey's FORMATS.md files
(survey_reference.mitsuba_scene).

igi side: `igi solve` with the same photographs, run one iteration at a time (each run resumes the
previous one; `report.json`'s cumulative_s is the solve time) plus the first run's set-up (atlas
building, photo loading), followed by `igi sample` after every iteration.

Timing: wall seconds and CPU seconds (user + system of all threads: Mitsuba's process, igi's
child processes), since the machine is shared; "the same albedo RMSE" is igi's final one, or
Mitsuba's best if Mitsuba never reaches it.

Fair error measure: both methods are evaluated at the SAME surface points: N points drawn
uniformly by area on the faces of the site (2 cm away from face edges) that at least two survey
cameras see (in the image, unoccluded, view more frontal than 84 degrees). Mitsuba's albedo there
is its bilinear texture lookup at the point's (u, v); igi's is `igi sample`; the truth is the
truth texture's lookup. The error is the RMS over points and channels (and the per-channel MAE).

Usage:
    cargo build --release --bin igi
    python3 datasets/mitsuba/inverse_adam.py [--survey datasets/fixtures/survey] [--iterations 80]
        [--spp 8] [--lr 0.03] [--igi target/release/igi] [--atlas 128] [--out DIR]
Writes DIR/inverse_comparison.json (default /tmp/igi-inverse-compare) and prints a Markdown table.
"""

import argparse
import csv
import json
import os
import resource
import subprocess
import sys
import time
import tomllib

import numpy as np

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.normpath(os.path.join(HERE, "..", ".."))
sys.path.insert(0, HERE)

import survey_reference as sr  # noqa: E402  (sets DRJIT_LIBLLVM_PATH, imports mitsuba)

mi = sr.mi
ref = sr.ref


def bilinear_repeat(tex, uv):
    """FORMATS.md texel centres, bilinear, repeat wrap (= Mitsuba's bitmap with the v flip), vectorised."""
    h, w, _ = tex.shape
    x, y = uv[:, 0] * w - 0.5, (1.0 - uv[:, 1]) * h - 0.5
    x0, y0 = np.floor(x).astype(int), np.floor(y).astype(int)
    fx, fy = (x - x0)[:, None], (y - y0)[:, None]
    t = lambda yy, xx: tex[yy % h, xx % w].astype(np.float64)
    return ((1 - fy) * ((1 - fx) * t(y0, x0) + fx * t(y0, x0 + 1)) + fy * ((1 - fx) * t(y0 + 1, x0) + fx * t(y0 + 1, x0 + 1)))


def read_survey(folder):
    with open(os.path.join(folder, "survey.toml"), "rb") as f:
        sv = tomllib.load(f)
    photos = []
    for p in sv["photo"]:
        with open(os.path.join(folder, p["camera"])) as f:
            cam = json.load(f)
        photos.append({"id": p["id"], "image": ref.read_exr(os.path.join(folder, p["image"])), "camera": cam,
                       "lighting": os.path.abspath(os.path.join(folder, p["lighting"]))})
    return photos


def quads(name):
    """(v0, edge_u, edge_v, uv0, duv_u, duv_v, area) per face of a part's mesh (4 vertices per face)."""
    pos, nrm, uv, tris = sr.PARTS[name]["mesh"]()
    out = []
    for b in range(0, len(pos), 4):
        if nrm[b][2] < -0.5:                  # box bottoms lie on the ground: never seen
            continue
        eu, ev = pos[b + 1] - pos[b], pos[b + 3] - pos[b]
        out.append((pos[b], eu, ev, uv[b], uv[b + 1] - uv[b], uv[b + 3] - uv[b], np.linalg.norm(np.cross(eu, ev)),
                    nrm[b]))
    return out


def evaluation_points(photos, n, seed=3):
    """Points seen by >= 2 survey cameras, uniform by area over the site's faces."""
    rng = np.random.default_rng(seed)
    faces = [(name, q) for name in sr.PARTS for q in quads(name)]
    areas = np.array([q[6] for _, q in faces])
    m = 4 * n
    k = rng.choice(len(faces), size=m, p=areas / areas.sum())
    pts, nrms, uvs, names = [], [], [], []
    for i in k:
        name, (v0, eu, ev, uv0, du, dv, _, nn) = faces[i]
        a, b = 0.02 / np.linalg.norm(eu), 0.02 / np.linalg.norm(ev)
        s, t = rng.uniform(a, 1 - a), rng.uniform(b, 1 - b)
        pts.append(v0 + s * eu + t * ev)
        uvs.append(uv0 + s * du + t * dv)
        nrms.append(nn)
        names.append(name)
    pts, nrms, uvs, names = np.array(pts), np.array(nrms), np.array(uvs), np.array(names)
    scene = mi.load_dict({"type": "scene", **{nm: {"type": "ply", "filename": os.path.join(SURVEY, "geometry", f"{nm}.ply")}
                                             for nm in sr.PARTS}})
    seen = np.zeros(m, int)
    for ph in photos:
        cam = ph["camera"]
        R, t = np.array(cam["R"]), np.array(cam["t"])
        eye = -R.T @ t
        xc = pts @ R.T + t
        K = np.array(cam["K"])
        u = K[0, 0] * xc[:, 0] / xc[:, 2] + K[0, 2]
        v = K[1, 1] * xc[:, 1] / xc[:, 2] + K[1, 2]
        inside = (xc[:, 2] > 0) & (u > 0) & (v > 0) & (u < cam["width"] - 1) & (v < cam["height"] - 1)
        d = eye - pts
        dist = np.linalg.norm(d, axis=1)
        d /= dist[:, None]
        front = (d * nrms).sum(1) > 0.1
        o = pts + nrms * 1e-3
        ray = mi.Ray3f(mi.Point3f(*[mi.Float(o[:, i]) for i in range(3)]), mi.Vector3f(*[mi.Float(d[:, i]) for i in range(3)]))
        si = scene.ray_intersect(ray)
        free = ~np.array(si.is_valid()) | (np.array(si.t) >= dist * (1 - 1e-4))
        seen += inside & front & free
    keep = np.nonzero(seen >= 2)[0][:n]
    return pts[keep], nrms[keep], uvs[keep], names[keep]


def truth_at(points_uv, names):
    out = np.zeros((len(names), 3))
    for nm in sr.PARTS:
        sel = names == nm
        out[sel] = bilinear_repeat(ref.read_exr(os.path.join(SURVEY, "truth", f"{nm}_albedo.exr")), points_uv[sel])
    return out


def errors(values, truth):
    d = values - truth
    return float(np.sqrt((d * d).mean())), np.abs(d).mean(0).tolist()


# ----------------------------------------------------------------------------- Mitsuba Adam
def run_adam(photos, uvs, names, truth, args, work):
    import drjit as dr
    mi.set_variant("llvm_ad_rgb")
    objects = sr.read_scene_file(os.path.join(SURVEY, "truth", "scene.toml"))
    res = {nm: ref.read_exr(tex).shape[:2] for nm, _, tex in objects}
    grey = {}
    for nm, (h, w) in res.items():
        grey[nm] = os.path.join(work, f"init_{nm}.exr")
        ref.write_exr(grey[nm], np.full((h, w, 3), args.initial, np.float32))
    t_setup = time.perf_counter()
    scenes = []
    for ph in photos:
        d = sr.mitsuba_scene([(nm, ply, grey[nm]) for nm, ply, _ in objects], ph["camera"], ph["lighting"], work,
                             spp=args.spp, integrator="prb")
        sc = mi.load_dict(d)
        scenes.append((sc, mi.traverse(sc), mi.TensorXf(ph["image"])))
    keys = {nm: f"{nm}.bsdf.reflectance.data" for nm in res}
    opt = mi.ad.Adam(lr=args.lr)
    for nm, k in keys.items():
        opt[nm] = scenes[0][1][k]
    setup_s = time.perf_counter() - t_setup
    rows = []
    elapsed, cpu = 0.0, 0.0

    def record(it):
        vals = np.zeros((len(names), 3))
        for nm in res:
            sel = names == nm
            vals[sel] = bilinear_repeat(np.array(opt[nm]), uvs[sel])
        rms, mae = errors(vals, truth)
        rows.append({"iteration": it, "seconds": elapsed, "cpu_seconds": cpu, "rmse": rms, "mae": mae})
        return rms

    record(0)
    print(f"mitsuba adam: set-up {setup_s:.1f} s; start RMSE {rows[0]['rmse']:.4f}", flush=True)
    for it in range(1, args.iterations + 1):
        t0, c0 = time.perf_counter(), time.process_time()
        for k, (sc, params, target) in enumerate(scenes):
            for nm, key in keys.items():
                params[key] = opt[nm]
            params.update()
            img = mi.render(sc, params, spp=args.spp, seed=it * 1000 + k, seed_grad=it * 1000 + k + 500)
            loss = dr.mean(dr.square(img - target)) / len(scenes)
            dr.backward(loss)
        # learning-rate schedule: constant for the first `decay_start` steps, then exponential
        # decay to lr * decay_to at the last step (without it Adam's steps on 8-spp gradients
        # keep the albedo wandering at RMSE ~0.04)
        if it > args.decay_start:
            frac = (it - args.decay_start) / max(1, args.iterations - args.decay_start)
            opt.set_learning_rate(args.lr * args.decay_to ** frac)
        opt.step()
        for nm in res:
            opt[nm] = dr.clip(opt[nm], 0.0, 1.0)
        dr.eval(*[opt[nm] for nm in res])
        elapsed += time.perf_counter() - t0
        cpu += time.process_time() - c0
        rms = record(it)
        if it % 10 == 0 or it <= 5:
            print(f"mitsuba adam iteration {it}: {elapsed:.1f} s, CPU {cpu:.1f} s, RMSE {rms:.4f}", flush=True)
    return {"setup_seconds": setup_s, "rows": rows}


# ----------------------------------------------------------------------------- igi
def children_cpu():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def run_igi(points, nrms, truth, args, work):
    pts_csv = os.path.join(work, "points.csv")
    with open(pts_csv, "w", newline="") as f:
        wr = csv.writer(f)
        wr.writerow(["x", "y", "z", "nx", "ny", "nz"])
        for p, n in zip(points, nrms):
            wr.writerow([repr(float(x)) for x in (*p, *n)])
    res = os.path.join(work, "igi_result")
    rows, first_overhead, cpu = [], None, 0.0
    spp = args.igi_spp.split(",")
    for it in range(1, args.igi_iterations + 1):
        cmd = [args.igi, "solve", SURVEY, "-o", res, "--atlas", str(args.atlas), "--spp", args.igi_spp,
               "--iterations", str(it), "--tolerance", "0", "--quiet", "--json"]
        if it == 1:
            cmd.append("--restart")
        t0, c0 = time.perf_counter(), children_cpu()
        out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
        wall = time.perf_counter() - t0
        cpu += children_cpu() - c0
        rep = json.loads(out)
        cum = rep["iterations"][-1]["cumulative_s"]
        if it == 1:
            first_overhead = wall - cum                 # atlas building, photo loading, writing
        vals_csv = os.path.join(work, "values.csv")
        subprocess.run([args.igi, "sample", res, "--points", pts_csv, "-o", vals_csv], check=True, capture_output=True)
        vals = np.loadtxt(vals_csv, delimiter=",", skiprows=1)[:, 6:9]
        rms, mae = errors(vals, truth)
        rows.append({"iteration": it, "spp": int(spp[min(it - 1, len(spp) - 1)]), "solve_seconds": cum,
                     "seconds": cum + first_overhead, "cpu_seconds": cpu, "rmse": rms, "mae": mae,
                     "report_truth_rms": rep["iterations"][-1]["truth_rms"]})
        print(f"igi iteration {it}: {cum + first_overhead:.1f} s (solve {cum:.1f} s), CPU {cpu:.1f} s, RMSE {rms:.4f}", flush=True)
    return {"setup_seconds": first_overhead, "rows": rows}


def time_to(rows, target, key="seconds"):
    """Time of the first row at or below target (linear interpolation in time between rows)."""
    prev = None
    for r in rows:
        if r["rmse"] <= target:
            if prev is None or prev["rmse"] == r["rmse"]:
                return r[key]
            f = (prev["rmse"] - target) / (prev["rmse"] - r["rmse"])
            return prev[key] + f * (r[key] - prev[key])
        prev = r
    return None


SURVEY = None
LOAD_START = None


def main():
    global SURVEY, LOAD_START
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--survey", default=os.path.join(ROOT, "datasets", "fixtures", "survey"))
    ap.add_argument("--out", default="/tmp/igi-inverse-compare")
    ap.add_argument("--iterations", type=int, default=80, help="Adam steps (each a sweep over all photos)")
    ap.add_argument("--spp", type=int, default=8, help="prb samples per pixel per photo and step")
    ap.add_argument("--lr", type=float, default=0.03)
    ap.add_argument("--decay-start", type=int, default=15, help="Adam steps at the full learning rate")
    ap.add_argument("--decay-to", type=float, default=0.05, help="final learning rate / initial")
    ap.add_argument("--initial", type=float, default=0.5)
    ap.add_argument("--points", type=int, default=4000)
    ap.add_argument("--igi", default=os.path.join(ROOT, "target", "release", "igi"))
    ap.add_argument("--atlas", type=int, default=128, help="igi atlas resolution")
    ap.add_argument("--igi-spp", default="32,128,512")
    ap.add_argument("--igi-iterations", type=int, default=3)
    args = ap.parse_args()
    SURVEY = os.path.abspath(args.survey)
    LOAD_START = os.getloadavg()
    os.makedirs(args.out, exist_ok=True)
    work = os.path.abspath(args.out)
    mi.set_variant("llvm_ad_rgb")
    photos = read_survey(SURVEY)
    pts, nrms, uvs, names = evaluation_points(photos, args.points)
    truth = truth_at(uvs, names)
    print(f"{len(pts)} evaluation points seen by >= 2 cameras "
          f"({', '.join(f'{nm} {int((names == nm).sum())}' for nm in sr.PARTS)})", flush=True)
    igi = run_igi(pts, nrms, truth, args, work)
    igi_load = os.getloadavg()
    ref.write_text(os.path.join(work, "igi_curve.json"), json.dumps(igi, indent=1) + "\n")
    adam = run_adam(photos, uvs, names, truth, args, work)
    # the same albedo RMSE for both: igi's final one, or Adam's best if Adam never gets there
    igi_final = igi["rows"][-1]["rmse"]
    adam_best = min(r["rmse"] for r in adam["rows"])
    target = max(igi_final, adam_best)
    t_igi, t_adam = time_to(igi["rows"], target), time_to(adam["rows"], target)
    c_igi, c_adam = time_to(igi["rows"], target, "cpu_seconds"), time_to(adam["rows"], target, "cpu_seconds")
    summary = {"target_rmse": target, "igi_seconds": t_igi, "adam_seconds": t_adam,
               "speedup": (t_adam / t_igi) if (t_igi and t_adam) else None,
               "igi_cpu_seconds": c_igi, "adam_cpu_seconds": c_adam,
               "cpu_speedup": (c_adam / c_igi) if (c_igi and c_adam) else None,
               "igi_final_rmse": igi_final, "adam_best_rmse": adam_best,
               "adam_final_rmse": adam["rows"][-1]["rmse"], "adam_total_seconds": adam["rows"][-1]["seconds"]}
    result = {"generator": "datasets/mitsuba/inverse_adam.py", "mitsuba": mi.__version__, "cores": os.cpu_count(),
              "load_average": {"start": LOAD_START, "after_igi": igi_load, "end": os.getloadavg()},
              "survey": SURVEY, "points": len(pts), "args": vars(args), "summary": summary,
              "igi": igi, "mitsuba_adam": adam}
    ref.write_text(os.path.join(work, "inverse_comparison.json"), json.dumps(result, indent=1) + "\n")
    print(json.dumps(summary, indent=2))
    print("\n| method | iteration | wall s | CPU s | albedo RMSE |\n|---|---:|---:|---:|---:|")
    for r in igi["rows"]:
        print(f"| igi | {r['iteration']} ({r['spp']} spp) | {r['seconds']:.1f} | {r['cpu_seconds']:.1f} | {r['rmse']:.4f} |")
    for r in adam["rows"]:
        if r["iteration"] in (0, 1, 2, 5, 10, 20, 50, 100, 150, 200, 300, 400, 500) or r is adam["rows"][-1]:
            print(f"| Mitsuba Adam | {r['iteration']} | {r['seconds']:.1f} | {r['cpu_seconds']:.1f} | {r['rmse']:.4f} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
