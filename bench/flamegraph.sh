#!/usr/bin/env bash
# A flame graph (perf + inferno, SVG) of one thread, either rendering the
# Whitted benchmark scene with a 64-sample sphere light at 400×300, 1 spp,
# or (--bunny) answering the bunny's mesh queries of bench/meshes.py
# (primary, incoherent and shadow rays, examples/meshbench on one thread;
# only the stacks under Prism's mesh queries are drawn).
#
#   bench/flamegraph.sh OUT.svg [PRISM_BINARY]
#   bench/flamegraph.sh --bunny OUT.svg [MESHBENCH_BINARY]
#
# The binary defaults to this checkout's release build; give an older build
# to draw the "before" graph. Installs perf (Debian's linux-perf) and
# inferno (crates.io) when missing. --bunny needs bench/data/bunny.ply,
# which python3 bench/meshes.py writes on its first run.
set -euo pipefail
mode=whitted
if [ "${1:-}" = --bunny ]; then
    mode=bunny
    shift
fi
out=$(realpath -m "$1")
root=$(cd "$(dirname "$0")/.." && pwd)
if ! command -v perf >/dev/null 2>&1; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq linux-perf >/dev/null
fi
command -v inferno-flamegraph >/dev/null 2>&1 || cargo install inferno --locked
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
if [ "$mode" = bunny ]; then
    if [ $# -ge 2 ]; then
        exe=$(realpath "$2")
    else
        (cd "$root" && cargo build --release --quiet --example meshbench)
        exe="$root/target/release/examples/meshbench"
    fi
    bunny="$root/bench/data/bunny.ply"
    [ -f "$bunny" ] || { echo "no $bunny: run python3 bench/meshes.py once to write it" >&2; exit 1; }
    RAYON_NUM_THREADS=1 perf record -q --call-graph dwarf -F 2000 -o "$work/perf.data" -- \
        "$exe" "$bunny" "$work" 262144 >/dev/null 2>&1
    perf script -i "$work/perf.data" 2>/dev/null | inferno-collapse-perf |
        grep -E 'Mesh::(intersect|any_hit)' >"$work/folded"
    title="Prism: the bunny's mesh queries (primary, incoherent, shadow), 1 thread"
else
    if [ $# -ge 2 ]; then
        prism=$(realpath "$2")
    else
        (cd "$root" && cargo build --release --quiet)
        prism="$root/target/release/prism"
    fi
    sed -e 's/samples = 16/samples = 64/' "$root/bench/whitted.toml" >"$work/scene.toml"
    perf record -q --call-graph dwarf -F 2000 -o "$work/perf.data" -- \
        "$prism" render "$work/scene.toml" -o "$work/out.png" --quiet --threads 1 --spp 1 \
        --width 400 --height 300 >/dev/null 2>&1
    perf script -i "$work/perf.data" 2>/dev/null | inferno-collapse-perf >"$work/folded"
    title="Prism: Whitted scene, 64 feelers, 1 thread"
fi
inferno-flamegraph --minwidth 0.5 --title "$title" <"$work/folded" >"$out"
echo "$out"
