#!/usr/bin/env bash
# A flame graph (perf + inferno, SVG) of one thread rendering the Whitted
# benchmark scene with a 64-sample sphere light at 400×300, 1 spp.
#
#   bench/flamegraph.sh OUT.svg [PRISM_BINARY]
#
# PRISM_BINARY defaults to this checkout's release build; give an older
# build to draw the "before" graph. Installs perf (Debian's linux-perf) and
# inferno (crates.io) when missing.
set -euo pipefail
out=$(realpath -m "$1")
root=$(cd "$(dirname "$0")/.." && pwd)
if ! command -v perf >/dev/null 2>&1; then
    SUDO=""
    [ "$(id -u)" -eq 0 ] || SUDO="sudo"
    $SUDO apt-get update -qq
    DEBIAN_FRONTEND=noninteractive $SUDO apt-get install -y -qq linux-perf >/dev/null
fi
command -v inferno-flamegraph >/dev/null 2>&1 || cargo install inferno --locked
if [ $# -ge 2 ]; then
    prism=$(realpath "$2")
else
    (cd "$root" && cargo build --release --quiet)
    prism="$root/target/release/prism"
fi
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
sed -e 's/samples = 16/samples = 64/' "$root/bench/whitted.toml" >"$work/scene.toml"
perf record -q --call-graph dwarf -F 2000 -o "$work/perf.data" -- \
    "$prism" render "$work/scene.toml" -o "$work/out.png" --quiet --threads 1 --spp 1 \
    --width 400 --height 300 >/dev/null 2>&1
perf script -i "$work/perf.data" 2>/dev/null | inferno-collapse-perf >"$work/folded"
inferno-flamegraph --minwidth 0.5 --title "Prism: Whitted scene, 64 feelers, 1 thread" <"$work/folded" >"$out"
echo "$out"
