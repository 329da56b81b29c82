#!/usr/bin/env bash
# Installs PIMM into .venv on a machine that has only python3 (Debian/Ubuntu): the system library
# open3d needs, then the package with CPU-only torch pinned by constraints.txt.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! ldconfig -p 2>/dev/null | grep -q libusb-1.0.so.0; then
  SUDO=""; [ "$(id -u)" -ne 0 ] && SUDO="sudo"
  $SUDO apt-get update -qq && $SUDO apt-get install -y -qq libusb-1.0-0 >/dev/null
fi
python3 -m venv .venv
.venv/bin/pip install -q --upgrade pip
.venv/bin/pip install -q -c constraints.txt -e ".[dev]"
.venv/bin/python -c "import torch, open3d, faiss, pybullet, gymnasium; print('installed: torch', torch.__version__)"
