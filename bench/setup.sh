#!/usr/bin/env bash
# Installs the peers the benchmarks compare against: POV-Ray from Debian.
set -euo pipefail
if ! command -v povray >/dev/null 2>&1; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq povray >/dev/null
fi
povray --version 2>&1 | head -1 || true
