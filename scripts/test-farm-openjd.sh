#!/bin/bash
# The farm through Open Job Description: `prism farm openjd` writes a job
# template for 2 frames x 3 tiles of the example animation, `openjd run`
# (openjd-cli from PyPI, in a virtual environment this script makes under
# target/) runs its Render and Merge steps here, and the merged frames must
# equal single-process renders byte for byte.
set -euo pipefail
cd "$(dirname "$0")/.."
cargo build --release --locked --quiet
PRISM=$PWD/target/release/prism
VENV=$PWD/target/openjd-venv
if [ ! -x "$VENV/bin/openjd" ]; then
    python3 -m venv "$VENV"
    "$VENV/bin/pip" install --quiet --disable-pip-version-check "openjd-cli==0.8.0"
fi
WORK=$(mktemp -d /tmp/prism-openjd-test.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
fail() { echo "FAIL: $*" >&2; exit 1; }

sed -e 's/^width = .*/width = 160/' -e 's/^height = .*/height = 120/' scenes/rolling.toml > "$WORK/scene.toml"
"$PRISM" farm openjd "$WORK/scene.toml" -o "$WORK/out" --tiles 3 --frames 0-1 --format png
"$VENV/bin/openjd" run "$WORK/out/job.template.json" --step Merge --run-dependencies \
    -p Prism="$PRISM" -p Scene="$WORK/scene.toml" > "$WORK/openjd.log" 2>&1 \
    || { cat "$WORK/openjd.log" >&2; fail "openjd run failed"; }
for f in 0 1; do
    "$PRISM" render "$WORK/scene.toml" --frame "$f" -q -o "$WORK/ref_$f.png"
    cmp "$WORK/ref_$f.png" "$WORK/out/frame_000$f.png" || fail "frame $f differs from the single-process render"
done
status=$("$PRISM" farm status "$WORK/out")
echo "$status" | grep -q "merged: 2 of 2 frames" || fail "status: $status"
echo "ok: openjd run rendered and merged 2 frames x 3 tiles, identical to single-process renders"
