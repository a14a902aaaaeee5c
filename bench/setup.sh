#!/usr/bin/env bash
# Installs the peers the benchmarks compare against: POV-Ray from Debian,
# and Embree through the embreex package in bench/.venv.
set -euo pipefail
cd "$(dirname "$0")"
if ! command -v povray >/dev/null 2>&1 || [ ! -x /usr/bin/time ]; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq povray time >/dev/null
fi
if [ ! -x .venv/bin/python ]; then
    python3 -m venv .venv
fi
.venv/bin/pip install -q --disable-pip-version-check embreex numpy
povray --version 2>&1 | grep -m1 "POV-Ray" || true
.venv/bin/python -c "import embreex; print('embreex', embreex.__version__ if hasattr(embreex, '__version__') else 'ok')"
