#!/bin/bash
# Same bits on every CPU: renders the example scenes with the normal build
# (glam's SSE2 code for the 4-wide box tests and vector math) and with the
# portable build (feature scalar-math: plain scalar code), and compares the
# image bytes, EXR and PNG. Also checks that no build asks for
# target-cpu=native or CPU features beyond the baseline.
set -euo pipefail
cd "$(dirname "$0")/.."
fail() { echo "FAIL: $*" >&2; exit 1; }
if grep -rn -E "target-cpu|target-feature" .cargo Cargo.toml cli/Cargo.toml 2>/dev/null; then
    fail "a build setting asks for CPU-specific code"
fi
case "${RUSTFLAGS:-}" in *target-cpu*|*target-feature*) fail "RUSTFLAGS asks for CPU-specific code";; esac
cargo build --release --locked --quiet
cargo build --release --locked --quiet --features scalar-math --target-dir target/portable
WORK=$(mktemp -d /tmp/prism-bits.XXXXXX)
trap 'rm -rf "$WORK"' EXIT
for scene in whitted soft-shadows star nested-glass cornell models gltf rolling; do
    for ext in exr png; do
        args=(render "scenes/$scene.toml" --width 160 --height 120 --spp 2 -q)
        [ "$scene" = rolling ] && args+=(--frame 30)
        target/release/prism "${args[@]}" -o "$WORK/simd.$ext"
        target/portable/release/prism "${args[@]}" -o "$WORK/portable.$ext"
        cmp "$WORK/simd.$ext" "$WORK/portable.$ext" || fail "$scene.$ext: the SIMD and portable builds differ"
    done
done
echo "ok: SIMD and portable builds give the same bytes on 8 scenes (EXR and PNG)"
