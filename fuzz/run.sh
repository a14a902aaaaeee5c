#!/usr/bin/env bash
# Coverage-guided fuzzing of Prism's scene parser and loaders with AFL++
# through cargo-afl, on stable Rust. See fuzz/README.md.
#
#   fuzz/run.sh [SECONDS]        every target for SECONDS each (default 60)
#   fuzz/run.sh --planted [S]    checks the set-up: the scene target built
#                                with a planted bug must crash within S s
#   fuzz/run.sh --save ...       also merges what the fuzzers found (the
#                                queue, minimised by afl-cmin) into corpus/
#
# Each run is under a 2000 MB address-space limit (afl-fuzz -m), so an
# oversized allocation is a finding like a panic. Findings are copied to
# fuzz/findings/TARGET/; each becomes a regression test by adding it to
# fuzz/corpus/TARGET/, which tests/fuzz_corpus.rs replays in `cargo test`.
set -euo pipefail
cd "$(dirname "$0")"

planted=0
save=0
seconds=60
for arg in "$@"; do
    case "$arg" in
        --planted) planted=1 ;;
        --save) save=1 ;;
        *) seconds="$arg" ;;
    esac
done

if ! command -v cargo-afl >/dev/null 2>&1; then
    cargo install cargo-afl --locked
fi
# Builds AFL++ itself once per rustc (it says so and fails when done already).
cargo afl config --build >/dev/null 2>&1 || true

export AFL_SKIP_CPUFREQ=1 AFL_I_DONT_CARE_ABOUT_MISSING_CRASHES=1 AFL_NO_UI=1
export AFL_SKIP_CRASHES=1

stat() { awk -F' *: *' -v k="$2" '$1 == k { print $2 }' "$1/default/fuzzer_stats"; }

if [ "$planted" = 1 ]; then
    cargo afl build --release --features planted --target-dir target/planted --bin scene
    mkdir -p out/planted-seed
    rm -rf out/planted
    # A short seed: the planted bug sits at the text's first bytes.
    printf '#\n' >out/planted-seed/seed
    start=$(date +%s)
    AFL_BENCH_UNTIL_CRASH=1 cargo afl fuzz -i out/planted-seed -o out/planted -m 2000 -t 5000 \
        -V "$seconds" target/planted/release/scene >out/planted.log 2>&1 || true
    crashes=$(stat out/planted saved_crashes)
    echo "planted bug: ${crashes:-0} crash(es) after $(($(date +%s) - start)) s, $(stat out/planted execs_done) executions"
    [ "${crashes:-0}" -gt 0 ]
    exit
fi

cargo afl build --release
mkdir -p out findings
printf '%-6s %8s %12s %8s %8s %6s\n' target seconds executions exec/s crashes hangs
for target in scene obj ply gltf glb image; do
    rm -rf "out/$target"
    cargo afl fuzz -i "corpus/$target" -o "out/$target" -m 2000 -t 5000 -V "$seconds" \
        "target/release/$target" >"out/$target.log" 2>&1 || true
    printf '%-6s %8s %12s %8s %8s %6s\n' "$target" "$(stat "out/$target" run_time)" \
        "$(stat "out/$target" execs_done)" "$(stat "out/$target" execs_per_sec)" \
        "$(stat "out/$target" saved_crashes)" "$(stat "out/$target" saved_hangs)"
    if compgen -G "out/$target/default/crashes/id*" >/dev/null; then
        mkdir -p "findings/$target"
        cp "out/$target"/default/crashes/id* "findings/$target/"
    fi
    if [ "$save" = 1 ]; then
        rm -rf "out/$target.min"
        cargo afl cmin -i "out/$target/default/queue" -o "out/$target.min" -m 2000 -t 5000 \
            -- "target/release/$target" >/dev/null 2>&1 || true
        for f in out/"$target".min/*; do
            [ -f "$f" ] && cp "$f" "corpus/$target/$(sha1sum "$f" | cut -c1-16)"
        done
    fi
done
