"""Writes a small COLMAP binary model with pycolmap (PyPI), the cross-check of igi's COLMAP
binary reader (crates/import/src/tests_pycolmap.rs, issue 33).

    python3 -m venv /tmp/pcv && /tmp/pcv/bin/pip install pycolmap
    /tmp/pcv/bin/python datasets/pycolmap_model.py

writes datasets/fixtures/import/pycolmap/sparse/ (cameras.bin, images.bin, points3D.bin and,
with pycolmap 3.12 and later, rigs.bin and frames.bin) and expected.json: the model as pycolmap
reads the files back (camera parameters, quaternions (w, x, y, z), translations, 2D points, 3D
points and tracks, every float as written), which the Rust reader must reproduce exactly.
"""

import json
import math
import os
import shutil

import numpy as np
import pycolmap

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "fixtures", "import", "pycolmap")


def quat_xyzw(axis, angle):
    a = np.asarray(axis, dtype=float)
    a = a / np.linalg.norm(a)
    s = math.sin(angle / 2.0)
    return np.array([a[0] * s, a[1] * s, a[2] * s, math.cos(angle / 2.0)])


def build():
    rec = pycolmap.Reconstruction()
    cams = [
        (1, "SIMPLE_RADIAL", 1200, 800, [1000.5, 600.25, 399.75, -0.051]),
        (2, "OPENCV", 1600, 1200, [1402.0, 1398.5, 801.0, 598.25, -0.07, 0.021, 4e-4, -3e-4]),
        (3, "PINHOLE", 640, 480, [500.0, 501.0, 320.5, 240.5]),
    ]
    for cid, model, w, h, params in cams:
        cam = pycolmap.Camera(model=model, width=w, height=h, params=params, camera_id=cid)
        rec.add_camera_with_trivial_rig(cam)
    points = [
        [0.1, -0.2, 5.0],
        [1.0, 0.5, 6.0],
        [-0.8, 0.3, 4.5],
        [0.4, 1.1, 5.5],
        [-1.2, -0.9, 7.0],
    ]
    poses = [
        (1, 1, "a/IMG_0001.JPG", quat_xyzw([0.1, 1.0, 0.2], 0.05), [0.1, -0.2, 0.3]),
        (2, 2, "IMG_0002.JPG", quat_xyzw([1.0, 0.0, 0.3], -0.12), [-0.5, 0.1, 0.2]),
        (3, 3, "IMG_0003.JPG", quat_xyzw([0.0, 0.2, 1.0], 0.3), [0.3, 0.4, -0.1]),
        (4, 1, "IMG_0004.JPG", quat_xyzw([0.5, -1.0, 0.1], 0.08), [-0.2, 0.0, 0.5]),
    ]
    for iid, cid, name, q, t in poses:
        cam = rec.cameras[cid]
        pose = pycolmap.Rigid3d(pycolmap.Rotation3d(q), np.asarray(t))
        xy = []
        for p in points:
            pc = pose * np.asarray(p)
            uv = cam.img_from_cam(pc)
            xy.append(np.asarray(uv, dtype=float).reshape(2))
        # one 2D point without a 3D point
        xy.append(np.array([12.25, 34.5]))
        img = pycolmap.Image(
            name=name,
            keypoints=np.asarray(xy),
            camera_id=cid,
            image_id=iid,
        )
        rec.add_image_with_trivial_frame(img, pose)
    for k, p in enumerate(points):
        track = pycolmap.Track()
        for iid, *_ in poses:
            track.add_element(iid, k)
        pid = rec.add_point3D(np.asarray(p), track, np.array([10 * k, 200 - k, 7], dtype=np.uint8))
        rec.point3D(pid).error = 0.25 + k / 8.0
    return rec


def describe(rec):
    cams = []
    for cid in sorted(rec.cameras):
        c = rec.cameras[cid]
        cams.append({
            "id": cid,
            "model": c.model.name,
            "width": c.width,
            "height": c.height,
            "params": [float(x) for x in c.params],
        })
    imgs = []
    for iid in sorted(rec.images):
        im = rec.images[iid]
        pose = im.cam_from_world()
        x, y, z, w = (float(v) for v in pose.rotation.quat)
        pts = []
        for p in im.points2D:
            pid = int(p.point3D_id) if p.has_point3D() else -1
            pts.append([float(p.xy[0]), float(p.xy[1]), pid])
        imgs.append({
            "id": iid,
            "name": im.name,
            "camera_id": im.camera_id,
            "q": [w, x, y, z],
            "t": [float(v) for v in pose.translation],
            "points2d": pts,
        })
    pts = []
    for pid in sorted(rec.points3D):
        p = rec.points3D[pid]
        pts.append({
            "id": pid,
            "xyz": [float(v) for v in p.xyz],
            "rgb": [int(v) for v in p.color],
            "error": float(p.error),
            "track": [[int(e.image_id), int(e.point2D_idx)] for e in p.track.elements],
        })
    return {"pycolmap": pycolmap.__version__, "cameras": cams, "images": imgs, "points": pts}


def main():
    sparse = os.path.join(OUT, "sparse")
    shutil.rmtree(sparse, ignore_errors=True)
    os.makedirs(sparse)
    build().write_binary(sparse)
    back = pycolmap.Reconstruction()
    back.read_binary(sparse)
    with open(os.path.join(OUT, "expected.json"), "w") as f:
        json.dump(describe(back), f, indent=1)
        f.write("\n")
    print("wrote", sparse, sorted(os.listdir(sparse)))


if __name__ == "__main__":
    main()
