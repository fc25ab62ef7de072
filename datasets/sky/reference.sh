#!/usr/bin/env bash
# Regenerate datasets/sky/sky.csv and sun.csv with the Hosek-Wilkie reference code.
# Usage: bash datasets/sky/reference.sh REF_DIR
# REF_DIR: ArHosekSkyModel.c, ArHosekSkyModel.h and its three data headers (v1.4a, e.g. pbrt-v3's
# src/ext/ at commit 13d871faae88233b327d04cda24022b8bb0093ee) and pbrt-v3's src/core/spectrum.cpp
# (for the CIE 1931 tables). Needs gcc and python3; takes a few seconds.
set -euo pipefail
ref=$(cd "$1" && pwd)
here=$(cd "$(dirname "$0")" && pwd)
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
python3 - "$ref/spectrum.cpp" > "$tmp/cie.h" <<'PY'
import re, sys
t = open(sys.argv[1]).read()
for n in ("CIE_X", "CIE_Y", "CIE_Z"):
    body = re.search(r"const Float " + n + r"\[nCIESamples\] = \{(.*?)\};", t, re.S).group(1)
    body = re.sub(r"//[^\n]*", "", body).replace("f", "")
    vals = [v.strip() for v in body.split(",") if v.strip()]
    assert len(vals) == 471
    print(f"static const double {n}[471] = {{{', '.join(vals)}}};")
PY
gcc -O2 -std=c99 -I"$ref" -I"$tmp" -o "$tmp/reference" "$here/reference.c" "$ref/ArHosekSkyModel.c" -lm
(cd "$tmp" && ./reference)
cp "$tmp/sky.csv" "$tmp/sun.csv" "$here/"
wc -l "$here/sky.csv" "$here/sun.csv"
