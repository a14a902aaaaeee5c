#!/bin/bash
# The live preview in a real browser: installs Chromium and its WebDriver
# from Debian when absent and Selenium into target/browser-venv, then runs
# scripts/preview_browser_test.py against `prism serve` on a copy of
# scenes/whitted.toml. Screenshots go to target/preview-screens/.
# With --readme-shot, the inspector's screenshot also replaces
# docs/images/preview.png, and the lecture's (lecture-*.png) go beside it.
# CARGO_TARGET_DIR, if set, is where the binary is built and found.
set -euo pipefail
cd "$(dirname "$0")/.."
if ! command -v chromium >/dev/null || [ ! -x /usr/bin/chromedriver ]; then
    echo "installing chromium and chromium-driver from Debian ..." >&2
    apt-get update -qq
    DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium chromium-driver >/dev/null
fi
VENV=$PWD/target/browser-venv
if [ ! -x "$VENV/bin/python" ] || ! "$VENV/bin/python" -c "import selenium" 2>/dev/null; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet --disable-pip-version-check "selenium==4.51.0"
fi
cargo build --release --locked --quiet
WORK=$(mktemp -d /tmp/prism-browser.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
cp scenes/whitted.toml scenes/star.toml scenes/nested-glass.toml "$WORK/"
shot=()
[ "${1:-}" = "--readme-shot" ] && shot=("$PWD/docs/images/preview.png")
"$VENV/bin/python" scripts/preview_browser_test.py "${CARGO_TARGET_DIR:-$PWD/target}/release/prism" "$WORK" \
    "$PWD/target/preview-screens" "${shot[@]}"
