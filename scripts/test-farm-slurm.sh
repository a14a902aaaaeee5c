#!/bin/bash
# The farm on a real Slurm: brings up a one-node cluster
# (scripts/slurm-cluster.sh), renders 2 frames x 4 tiles through
# `prism farm slurm --submit`, and compares the merged frames with
# single-process renders byte for byte. Then the fault test: one task is
# cancelled (scancel), `prism farm slurm` is run again, and it must submit
# that part only; the result must still be identical. Then: a rerun while
# the array still runs is refused and cancels nothing (the merge still
# merges); an output folder and scene folder named with quotes, `$()`,
# backticks, `;`, `%j`, spaces and non-ASCII render the same frames on the
# real cluster and run nothing. Tears the cluster down afterwards (only the
# daemons it started). Needs root (CI runs as root).
set -euo pipefail
cd "$(dirname "$0")/.."
ROOT=$PWD
cargo build --release --locked --quiet
PRISM=$ROOT/target/release/prism
WORK=$(mktemp -d /tmp/prism-farm-test.XXXXXX)
scripts/slurm-cluster.sh up >/dev/null
trap 'scripts/slurm-cluster.sh down; rm -rf "$WORK"' EXIT

fail() { echo "FAIL: $*" >&2; exit 1; }

# A small copy of the example animation (the glass ball rolls: frames differ).
sed -e 's/^width = .*/width = 200/' -e 's/^height = .*/height = 150/' scenes/rolling.toml > "$WORK/scene.toml"

# Waits until none of the jobs recorded in $1/jobs.txt (of kind $2, or all)
# is queued or running. All jobs are listed (by their array's job ID) and
# searched, so that a job already purged is not an error, and a failed
# squeue (slurmctld busy) is asked again rather than read as "none left".
wait_jobs() {
    local ids now left
    ids=$(awk -v k="${2:-}" 'k == "" || $1 == k {print $2}' "$1/jobs.txt")
    for _ in $(seq 1 300); do
        if now=$(squeue --noheader --format '%F' 2>/dev/null); then
            left=$(for id in $ids; do if echo "$now" | grep -qx "$id"; then echo "$id"; fi; done)
            if [ -z "$left" ]; then return 0; fi
        fi
        sleep 1
    done
    squeue >&2
    fail "jobs $ids did not finish in 300 s"
}

compare() {
    local scene=${2:-$WORK/scene.toml}
    for f in 0 1; do
        "$PRISM" render "$scene" --frame "$f" -q -o "$WORK/ref_$f.exr"
        cmp "$WORK/ref_$f.exr" "$1/frame_000$f.exr" || fail "$1: frame $f differs from the single-process render"
    done
}

echo "== 2 frames x 4 tiles through prism farm slurm --submit"
start=$(date +%s.%N)
"$PRISM" farm slurm "$WORK/scene.toml" -o "$WORK/a" --tiles 4 --frames 0-1 --max-running 2 --submit
wait_jobs "$WORK/a"
echo "all jobs done in $(echo "$(date +%s.%N) - $start" | bc) s"
compare "$WORK/a"
grep -q "percent=100" "$WORK"/a/logs/render_*_0.log || fail "task logs carry no progress lines"
echo "ok: merged frames identical to single-process renders"

echo "== fault: one task cancelled, the farm run again"
# One task at a time, so the last one is still waiting when cancelled.
out=$("$PRISM" farm slurm "$WORK/scene.toml" -o "$WORK/b" --tiles 4 --frames 0-1 --max-running 1 --submit)
echo "$out"
job=$(echo "$out" | sed -n 's/^submitted render job \([0-9]*\).*/\1/p')
scancel "${job}_6"
# All of them: the merge job starts once the renders end, and a rerun
# refuses to submit while a merge of the folder runs.
wait_jobs "$WORK/b"
[ ! -e "$WORK/b/parts/frame_0001_tile_0002.exr" ] || fail "the cancelled task's part exists"
[ ! -e "$WORK/b/frame_0001.exr" ] || fail "frame 1 was merged without its part"
"$PRISM" farm status "$WORK/b"
out=$("$PRISM" farm slurm "$WORK/scene.toml" -o "$WORK/b" --tiles 4 --frames 0-1 --max-running 1 --submit)
echo "$out"
echo "$out" | grep -q "^submitted render job [0-9]*: 1 tasks (6%1)$" || fail "the rerun did not submit exactly the missing part"
wait_jobs "$WORK/b"
compare "$WORK/b"
status=$("$PRISM" farm status "$WORK/b")
echo "$status" | grep -q "merged: 2 of 2 frames" || fail "status does not report both frames merged"
out=$("$PRISM" farm slurm "$WORK/scene.toml" -o "$WORK/b" --tiles 4 --frames 0-1 --submit)
echo "$out" | grep -q "nothing to submit" || fail "a finished farm render resubmitted work: $out"
echo "ok: only the missing part was resubmitted; frames identical"

echo "== a rerun while the array runs: refused, nothing cancelled"
out=$("$PRISM" farm slurm "$WORK/scene.toml" -o "$WORK/c" --tiles 4 --frames 0-1 --max-running 1 --submit)
echo "$out"
set +e
again=$("$PRISM" farm slurm "$WORK/scene.toml" -o "$WORK/c" --tiles 4 --frames 0-1 --submit 2>&1)
code=$?
set -e
echo "$again"
[ "$code" = 2 ] || fail "a rerun during the render array exited $code, not 2"
echo "$again" | grep -q "still queued or running" || fail "the refusal does not say why"
wait_jobs "$WORK/c"
compare "$WORK/c"
echo "ok: the refused rerun left the merge in place; frames identical"

echo "== hostile folder names on the real cluster"
H=$'it\'s $(touch PWNED) `touch PWNED` ; %j %A "q" é✓'
mkdir -p "$WORK/scene $H"
cp "$WORK/scene.toml" "$WORK/scene $H/scene.toml"
"$PRISM" farm slurm "$WORK/scene $H/scene.toml" -o "$WORK/out $H" --tiles 3 --frames 0-1 --partition main --submit
wait_jobs "$WORK/out $H"
compare "$WORK/out $H" "$WORK/scene $H/scene.toml"
ls "$WORK/out $H/logs/" | grep -q "^render_[0-9]*_0.log$" || fail "the task logs are not where they belong"
[ ! -e /PWNED ] && [ -z "$(find "$WORK" -name PWNED)" ] || fail "a folder name ran a command"
echo "ok: hostile folder names render the same frames and run nothing"
