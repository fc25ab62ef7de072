"""LibRaw's reading of a real camera RAW file, the cross-check of igi's RAW decoder
(crates/imaging/src/raw.rs, `a_real_sony_arw_decodes_as_libraw_does`; issue 33).

The file is `_DSC2164.ARW`, a Sony ILCE-7RM3 photograph (APS-C crop, 5168 x 3448, ISO 3200)
that the MIT-licensed PyPI package libraw-cffi 0.19.0 ships in its source distribution as a
test file; `bash scripts/deps.sh test` puts it in /opt/igi-data/raw/ (checked by SHA-256).

    python3 -m pip install rawpy==0.28.0 exifread==3.5.1 numpy
    python3 datasets/raw_reference.py [/opt/igi-data/raw/_DSC2164.ARW]

writes datasets/fixtures/raw/dsc2164_libraw.json:
- `exif`: the fields igi reads, as exifread (an independent EXIF reader) reads them;
- `black`, `white` (the file's own per-channel white level), `wb` (the camera's white balance,
  green 1) and `xyz_to_cam` (LibRaw's colour matrix for this camera, rows camera R, G, B);
- `blocks`: LibRaw's linear Rec. 709 image (rawpy `postprocess`: camera white balance, no
  brightening, gamma 1, 16 bits, bilinear demosaicing) cropped to the file's default crop, as
  the mean of each 64 x 64 block, with the block's largest channel value (`block_max`).

LibRaw scales by 16383 - black (the 14-bit maximum) where the file says its sensor saturates at
15360; rawler (igi's decoder) takes the file's white level. So LibRaw is asked for the file's
level here (`user_sat`, which LibRaw 0.22 takes with the black level already subtracted), and
both then put 1 at the white level. Nothing else is adjusted.
"""

import hashlib
import json
import os
import sys

import exifread
import numpy as np
import rawpy

HERE = os.path.dirname(os.path.abspath(__file__))
OUT = os.path.join(HERE, "fixtures", "raw", "dsc2164_libraw.json")
BLOCK = 64


def ratio(tag):
    v = tag.values[0]
    return float(v.num) / float(v.den)


def exif_fields(path):
    with open(path, "rb") as f:
        t = exifread.process_file(f, details=False)
    return {
        "make": str(t["Image Make"]).strip(),
        "model": str(t["Image Model"]).strip(),
        "date_time_original": str(t["EXIF DateTimeOriginal"]),
        "offset_time_original": str(t["EXIF OffsetTimeOriginal"]),
        "exposure_time_s": ratio(t["EXIF ExposureTime"]),
        "f_number": ratio(t["EXIF FNumber"]),
        "iso": float(t["EXIF ISOSpeedRatings"].values[0]),
    }


def main():
    path = sys.argv[1] if len(sys.argv) > 1 else "/opt/igi-data/raw/_DSC2164.ARW"
    data = open(path, "rb").read()
    raw = rawpy.imread(path)
    s = raw.sizes
    black = raw.black_level_per_channel
    white = raw.camera_white_level_per_channel
    assert len(set(black)) == 1 and len(set(white)) == 1, (black, white)
    black, white = black[0], white[0]
    wb = list(raw.camera_whitebalance[:3])
    wb = [w / wb[1] for w in wb]
    xyz_to_cam = raw.rgb_xyz_matrix[:3].tolist()
    rgb = raw.postprocess(
        gamma=(1, 1),
        no_auto_bright=True,
        use_camera_wb=True,
        output_color=rawpy.ColorSpace.sRGB,
        output_bps=16,
        adjust_maximum_thr=0.0,
        user_sat=white - black,
        user_flip=0,
        demosaic_algorithm=rawpy.DemosaicAlgorithm.LINEAR,
        highlight_mode=rawpy.HighlightMode.Clip,
    )
    img = rgb.astype(np.float64) / 65535.0
    top, left = s.crop_top_margin, s.crop_left_margin
    img = img[top : top + s.crop_height, left : left + s.crop_width]
    by, bx = img.shape[0] // BLOCK, img.shape[1] // BLOCK
    tiles = img[: by * BLOCK, : bx * BLOCK].reshape(by, BLOCK, bx, BLOCK, 3)
    means = tiles.mean(axis=(1, 3))
    maxes = tiles.max(axis=(1, 3, 4))
    out = {
        "file": os.path.basename(path),
        "bytes": len(data),
        "sha256": hashlib.sha256(data).hexdigest(),
        "decoder": f"rawpy {rawpy.__version__}, LibRaw {'.'.join(map(str, rawpy.libraw_version))}",
        "exif": exif_fields(path),
        "width": int(s.crop_width),
        "height": int(s.crop_height),
        "black": int(black),
        "white": int(white),
        "wb": wb,
        "xyz_to_cam": xyz_to_cam,
        "block": BLOCK,
        "blocks": [[[round(float(v), 7) for v in px] for px in row] for row in means],
        "block_max": [[round(float(v), 5) for v in row] for row in maxes],
    }
    os.makedirs(os.path.dirname(OUT), exist_ok=True)
    with open(OUT, "w") as f:
        json.dump(out, f, separators=(",", ":"))
        f.write("\n")
    print(f"wrote {OUT}: {by} x {bx} blocks of {BLOCK} px, {out['decoder']}")


if __name__ == "__main__":
    main()
