#!/usr/bin/env bash
# Idempotent set-up for a fresh machine: Debian packages, then .venv with `pip install -e .[dev]`.
# A second run with nothing changed only checks (well under 10 s).
set -euo pipefail
cd "$(dirname "$0")/.."

DEB_PACKAGES=(
  libusb-1.0-0          # open3d imports it
  libegl1 libegl-mesa0 libgl1-mesa-dri libgles2   # headless OpenGL (EGL + llvmpipe) for moderngl
  graphviz              # `probeless graph --out g.png`
  chromium              # tests/viz: the Rerun web viewer in a real browser (driven by playwright)
)

missing=()
for pkg in "${DEB_PACKAGES[@]}"; do
  dpkg-query -W -f='${Status}' "$pkg" 2>/dev/null | grep -q "install ok installed" || missing+=("$pkg")
done
if ((${#missing[@]})); then
  echo "setup: installing Debian packages: ${missing[*]}"
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq
  DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

PY=${PYTHON:-python3}
STAMP=.venv/.probeless-installed
if [ ! -x .venv/bin/python ]; then
  echo "setup: creating .venv"
  "$PY" -m venv .venv
fi
if [ ! -f "$STAMP" ] || [ pyproject.toml -nt "$STAMP" ]; then
  echo "setup: pip install -e .[dev]"
  .venv/bin/python -m pip install -q --upgrade pip
  .venv/bin/python -m pip install -q -e ".[dev]"
  touch "$STAMP"
fi
