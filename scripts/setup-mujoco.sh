#!/usr/bin/env bash
# Puts MuJoCo's shared library (3.17.0, the version mujoco-rs 7.0.0 binds) into
# third_party/mujoco/lib/, taken from the official `mujoco` wheel on PyPI.
# Idempotent: a no-op when the library is already there. Called by the Makefile.
set -euo pipefail
VERSION=3.17.0
cd "$(dirname "$0")/.."
LIB_DIR=third_party/mujoco/lib
LIB="$LIB_DIR/libmujoco.so.$VERSION"

if [ -n "${MUJOCO_DYNAMIC_LINK_DIR:-}" ] && [ -f "$MUJOCO_DYNAMIC_LINK_DIR/libmujoco.so" ]; then
  exit 0  # the user points at their own MuJoCo
fi

if [ -f "$LIB" ] && [ -L "$LIB_DIR/libmujoco.so" ]; then
  exit 0
fi

if ! command -v python3 >/dev/null 2>&1 || ! python3 -m pip --version >/dev/null 2>&1; then
  cat >&2 <<MSG
error: MuJoCo $VERSION is needed and cannot be fetched: python3 with pip is missing.
  Either install python3 and pip (Debian: apt-get install python3-pip) and run 'make' again,
  or set MUJOCO_DYNAMIC_LINK_DIR to the absolute path of a folder holding libmujoco.so
  from MuJoCo $VERSION (e.g. export MUJOCO_DYNAMIC_LINK_DIR=\$HOME/mujoco-$VERSION/lib).
MSG
  exit 1
fi

tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
echo "setup: downloading the mujoco==$VERSION wheel from PyPI (for libmujoco.so only)"
python3 -m pip download --quiet --no-deps --only-binary=:all: --dest "$tmp" "mujoco==$VERSION"
wheel=$(ls "$tmp"/mujoco-"$VERSION"-*.whl | head -n 1)
mkdir -p "$LIB_DIR"
python3 - "$wheel" "$LIB" <<'PY'
import shutil, sys, zipfile
wheel, dest = sys.argv[1], sys.argv[2]
name = "mujoco/libmujoco.so.3.17.0"
with zipfile.ZipFile(wheel) as z, z.open(name) as src, open(dest + ".part", "wb") as out:
    shutil.copyfileobj(src, out)
PY
mv "$LIB.part" "$LIB"
ln -sf "libmujoco.so.$VERSION" "$LIB_DIR/libmujoco.so"
echo "setup: MuJoCo $VERSION library in $LIB_DIR"
