#!/usr/bin/env python3
"""Prism against POV-Ray on equivalent scenes, measured in the same run.

Absolute times on a shared machine drift, so what this prints that matters
is the ratio: POV-Ray's wall time over Prism's for the same picture (same
resolution, one sample per pixel, same thread count, same trace depth).
Each command runs `--repeat` times, alternating, and the median is kept.
POV-Ray spends a fixed time starting up (reading its include files); that
is measured on a 1x1 render of the same scene and shown, and the second
ratio compares Prism's whole run against POV-Ray's time past start-up.

Set-up: bench/setup.sh (installs POV-Ray from Debian).
Usage:  python3 bench/run.py [--repeat N] [--threads T]
"""

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (name, Prism scene, POV-Ray twin, width, height)
CASES = [
    ("whitted", "scenes/whitted.toml", "bench/povray/whitted.pov", 640, 480),
    ("soft-shadows", "scenes/soft-shadows.toml", "bench/povray/soft-shadows.pov", 720, 300),
]


def wall_time(cmd):
    start = time.perf_counter()
    subprocess.run(cmd, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - start


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--threads", type=int, default=os.cpu_count() or 1)
    args = parser.parse_args()
    if shutil.which("povray") is None:
        sys.exit("povray not found: run bench/setup.sh first")
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    prism = os.path.join(ROOT, "target", "release", "prism")
    out = tempfile.mkdtemp(prefix="prism-bench-")
    print(f"{'scene':<14} {'size':>9} {'prism s':>9} {'povray s':>9} {'pov start':>9} {'povray/prism':>13} {'(past start)':>13}")
    for name, scene, pov, w, h in CASES:
        prism_cmd = [prism, "render", os.path.join(ROOT, scene), "-o", os.path.join(out, name + ".png"),
                     "--width", str(w), "--height", str(h), "--spp", "1", "--max-depth", "8",
                     "--threads", str(args.threads), "--quiet"]
        pov_cmd = ["povray", "+I" + os.path.join(ROOT, pov), "+O" + os.path.join(out, name + "-pov.png"),
                   f"+W{w}", f"+H{h}", "-A", f"+WT{args.threads}", "-D", "-V", "-GA", "+FN"]
        pov_start_cmd = [c for c in pov_cmd if not c.startswith(("+W", "+H"))] + ["+W1", "+H1"]
        prism_times, pov_times, start_times = [], [], []
        for _ in range(args.repeat):
            prism_times.append(wall_time(prism_cmd))
            pov_times.append(wall_time(pov_cmd))
            start_times.append(wall_time(pov_start_cmd))
        p, q, s = (statistics.median(t) for t in (prism_times, pov_times, start_times))
        print(f"{name:<14} {w:>4}x{h:<4} {p:>9.3f} {q:>9.3f} {s:>9.3f} {q / p:>12.2f}x {(q - s) / p:>12.2f}x")
    shutil.rmtree(out)


if __name__ == "__main__":
    main()
