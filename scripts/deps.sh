#!/usr/bin/env bash
# Installs the system packages igi builds against, only when they are missing (idempotent).
# Usage: bash scripts/deps.sh [demo|test|mitsuba]
#   demo: what the default build needs (Embree 3 for ray tracing, a font for plot labels)
#   test: also OpenCV with contrib and clang/libclang (the `opencv` feature generates its
#         bindings with libclang), Slurm and munge (tests/cli/cli_cluster.rs runs a one-node
#         loopback cluster, scripts/slurm-loopback.sh), Debian's chromium (tests/cli/cli_view.rs
#         opens `igi view` headless, WebGL through SwiftShader), Mitsuba 3.9.1 (the gloss test
#         of crates/lightfield renders its 20 MB capture with datasets/mitsuba/slf_gloss.py,
#         the straws test of crates/opacity-hull its 141 MB one with hull_straws.py, rather
#         than committing them), a real camera RAW file (crates/imaging's test against
#         LibRaw; fetched from PyPI into $IGI_DATA_DIR, default /opt/igi-data), everything the
#         test command builds and runs
#   mitsuba: what regenerating the reference data of datasets/mitsuba/ needs (never igi
#         itself): Mitsuba 3.9.1 for python3 and Debian's libllvm19 for its llvm_ad_rgb
#         variant (the scripts find libLLVM-19.so with `dpkg -L libllvm19`)
set -euo pipefail
profile="${1:-test}"
# Runs a command as root: directly when this is root, else through sudo.
as_root() { if [ "$(id -u)" -eq 0 ]; then "$@"; else sudo "$@"; fi; }
# Runs a command that writes under folder $1: as this user when it may write there, else as root.
writing_under() { local dir="$1"; shift; if [ -w "$dir" ]; then "$@"; else as_root "$@"; fi; }
pkgs=(libembree-dev pkg-config fonts-dejavu-core)
case "$profile" in
  demo) ;;
  test) pkgs+=(libopencv-dev clang libclang-dev slurm-wlm slurmctld slurmd slurm-client munge chromium
               libllvm19 python3 python3-pip) ;;
  mitsuba) pkgs=(libllvm19 python3) ;;
  *) echo "igi: deps.sh: unknown profile '$profile' (demo, test or mitsuba)" >&2; exit 2 ;;
esac
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "igi: installing system packages: ${missing[*]}" >&2
  as_root apt-get update -qq
  as_root env DEBIAN_FRONTEND=noninteractive \
    apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi
if [ "$profile" = test ]; then
  # the Khronos glTF-Validator of tests/cli/cli_gltf.rs (found there, or via IGI_GLTF_VALIDATOR)
  GLTF_VALIDATOR_VERSION=2.0.0-dev.3.10
  IGI_NODE=/opt/igi-node
  if ! grep -q "\"version\": \"$GLTF_VALIDATOR_VERSION\"" "$IGI_NODE/node_modules/gltf-validator/package.json" 2>/dev/null; then
    echo "igi: installing gltf-validator@$GLTF_VALIDATOR_VERSION (npm) under $IGI_NODE" >&2
    as_root mkdir -p "$IGI_NODE"
    as_root npm install --prefix "$IGI_NODE" --no-audit --no-fund --silent "gltf-validator@$GLTF_VALIDATOR_VERSION" >&2
  fi
fi
if [ "$profile" = mitsuba ] || [ "$profile" = test ]; then
  # the reference scripts (datasets/mitsuba, datasets/demo_error.py) need numpy beside Mitsuba
  if ! python3 -c 'import numpy, mitsuba, sys; sys.exit(mitsuba.__version__ != "3.9.1")' 2>/dev/null; then
    if ! python3 -m pip --version >/dev/null 2>&1; then
      echo "igi: python3 has no pip; install python3-pip (Debian) or use a virtual environment" >&2
      exit 1
    fi
    echo "igi: installing mitsuba==3.9.1 and numpy for python3 (pip)" >&2
    python3 -m pip install -q "mitsuba==3.9.1" numpy \
      || python3 -m pip install -q --break-system-packages "mitsuba==3.9.1" numpy
  fi
  if [ "$profile" = mitsuba ]; then exit 0; fi
fi
if [ "$profile" = test ]; then
  # a real camera RAW file for crates/imaging's test against LibRaw (datasets/raw_reference.py):
  # a Sony ILCE-7RM3 ARW that the MIT-licensed PyPI package libraw-cffi 0.19.0 ships as a test
  # file in its source distribution; kept under $IGI_DATA_DIR (default /opt/igi-data)
  IGI_DATA="${IGI_DATA_DIR:-/opt/igi-data}"
  ARW="$IGI_DATA/raw/_DSC2164.ARW"
  ARW_SHA256=42ec55eef6047c1bfbd1fd05fdcae78993f3513814138eff4cbcf9498c57d4e6
  if ! echo "$ARW_SHA256  $ARW" | sha256sum --check --status 2>/dev/null; then
    echo "igi: fetching a camera RAW test file (libraw-cffi==0.19.0's source, PyPI) into $IGI_DATA/raw" >&2
    fetch_dir="$(mktemp -d)"
    python3 -m pip download -q --no-deps --no-binary :all: -d "$fetch_dir" "libraw-cffi==0.19.0" >&2
    tar -xzf "$fetch_dir/libraw_cffi-0.19.0.tar.gz" -C "$fetch_dir" \
      libraw_cffi-0.19.0/libraw_cffi/tests/_DSC2164.ARW libraw_cffi-0.19.0/COPYING
    data_parent="$(dirname "$IGI_DATA")"
    writing_under "$data_parent" mkdir -p "$IGI_DATA/raw"
    writing_under "$data_parent" cp "$fetch_dir/libraw_cffi-0.19.0/libraw_cffi/tests/_DSC2164.ARW" "$ARW"
    writing_under "$data_parent" cp "$fetch_dir/libraw_cffi-0.19.0/COPYING" "$IGI_DATA/raw/COPYING.libraw-cffi"
    rm -rf "$fetch_dir"
    if ! echo "$ARW_SHA256  $ARW" | sha256sum --check --status; then
      echo "igi: $ARW is not the expected file (SHA-256 differs)" >&2
      exit 1
    fi
  fi
fi
if ! command -v cargo >/dev/null 2>&1; then
  echo "igi: cargo not found; install the Rust toolchain (rustup) first" >&2
  exit 1
fi
