#!/bin/bash
# Same bits on every CPU: renders the example scenes with the normal build
# on each box-test path it can choose at run time (PRISM_SIMD=avx2, sse2,
# scalar: see src/accel/simd/) and with the portable build (feature
# scalar-math: plain scalar vector math), and compares the image bytes, EXR
# and PNG. Also checks that no build asks for target-cpu=native or CPU
# features beyond the baseline (AVX2 is chosen at run time only).
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
# The paths this CPU runs: the stats line names the one a render used.
paths=()
for path in avx2 sse2 scalar; do
    used=$(PRISM_SIMD=$path target/release/prism render --width 8 --height 6 -o "$WORK/probe.png" 2>&1 | sed -n 's/.* threads, \([a-z0-9]*\) boxes;.*/\1/p')
    if [ "$used" = "$path" ]; then
        paths+=("$path")
    elif [ "$path" = avx2 ]; then
        echo "note: this CPU has no AVX2 ($used ran instead); comparing the other paths" >&2
    else
        fail "PRISM_SIMD=$path ran '$used'"
    fi
done
for scene in whitted soft-shadows star nested-glass cornell models gltf rolling solids csg distributed; do
    for ext in exr png; do
        args=(render "scenes/$scene.toml" --width 160 --height 120 --spp 2 -q)
        [ "$scene" = rolling ] && args+=(--frame 30)
        target/release/prism "${args[@]}" -o "$WORK/simd.$ext"
        target/portable/release/prism "${args[@]}" -o "$WORK/portable.$ext"
        cmp "$WORK/simd.$ext" "$WORK/portable.$ext" || fail "$scene.$ext: the SIMD and portable builds differ"
        for path in "${paths[@]}"; do
            PRISM_SIMD=$path target/release/prism "${args[@]}" -o "$WORK/$path.$ext"
            cmp "$WORK/simd.$ext" "$WORK/$path.$ext" || fail "$scene.$ext: PRISM_SIMD=$path differs"
        done
    done
done
echo "ok: the SIMD and portable builds, and the ${paths[*]} box tests, give the same bytes on 11 scenes (EXR and PNG)"
