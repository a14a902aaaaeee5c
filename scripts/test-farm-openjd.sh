#!/bin/bash
# The farm through Open Job Description: `prism farm openjd` writes a job
# template for 2 frames x 3 tiles of the example animation, `openjd run`
# (openjd-cli from PyPI, in a virtual environment this script makes under
# target/) runs its Render and Merge steps here, and the merged frames must
# equal single-process renders byte for byte. Then once more with the
# scene and the output in folders named with quotes, `$()`, backticks,
# `;`, `%`, spaces and non-ASCII: the same frames, and no command run.
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

# Renders scene $1 into folder $2 through `openjd run` and compares.
render_and_compare() {
    local scene=$1 out=$2
    "$PRISM" farm openjd "$scene" -o "$out" --tiles 3 --frames 0-1 --format png
    (cd "$WORK" && "$VENV/bin/openjd" run "$out/job.template.json" --step Merge --run-dependencies \
        -p Prism="$PRISM" -p Scene="$scene" -p OutputDir="$out") > "$WORK/openjd.log" 2>&1 \
        || { cat "$WORK/openjd.log" >&2; fail "openjd run failed"; }
    for f in 0 1; do
        "$PRISM" render "$scene" --frame "$f" -q -o "$WORK/ref_$f.png"
        cmp "$WORK/ref_$f.png" "$out/frame_000$f.png" || fail "frame $f differs from the single-process render"
    done
    status=$("$PRISM" farm status "$out")
    echo "$status" | grep -q "merged: 2 of 2 frames" || fail "status: $status"
}

sed -e 's/^width = .*/width = 160/' -e 's/^height = .*/height = 120/' scenes/rolling.toml > "$WORK/scene.toml"
render_and_compare "$WORK/scene.toml" "$WORK/out"
echo "ok: openjd run rendered and merged 2 frames x 3 tiles, identical to single-process renders"

H=$'it\'s $(touch PWNED) `touch PWNED` ; %j "q" {{x}} é✓'
mkdir -p "$WORK/scene $H"
cp "$WORK/scene.toml" "$WORK/scene $H/scene.toml"
render_and_compare "$WORK/scene $H/scene.toml" "$WORK/out $H"
[ -z "$(find "$WORK" -name PWNED)" ] || fail "a folder name ran a command"
echo "ok: hostile folder names give the same frames through openjd run, and run nothing"
