#!/usr/bin/env bash
# Installs the system packages igi builds against, only when they are missing (idempotent).
# Debian/Ubuntu: Embree 3 (ray tracing), OpenCV with contrib (calibration, PnP, ArUco) and
# clang/libclang (the opencv crate generates its bindings with libclang).
set -euo pipefail
pkgs=(libembree-dev libopencv-dev clang libclang-dev pkg-config fonts-dejavu-core)
missing=()
for p in "${pkgs[@]}"; do
  dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q "install ok installed" || missing+=("$p")
done
if ((${#missing[@]})); then
  echo "igi: installing system packages: ${missing[*]}" >&2
  SUDO=""
  if [ "$(id -u)" -ne 0 ]; then SUDO="sudo"; fi
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >&2
fi
if ! command -v cargo >/dev/null 2>&1; then
  echo "igi: cargo not found; install the Rust toolchain (rustup) first" >&2
  exit 1
fi
