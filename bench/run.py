#!/usr/bin/env python3
"""Prism against POV-Ray 3.7 on the same scenes, measured in the same run.

Scenes (both versions kept in bench/): the Whitted picture with a 16-sample
area light (bench/whitted.toml, bench/whitted.pov) and the soft-shadow study
(scenes/soft-shadows.toml, bench/soft-shadows.pov). Same resolution, trace
depth, thread count and light samples; antialiasing: Prism 4 stratified
samples per pixel, POV-Ray +A0.0 +AM1 +R2 (every pixel supersampled on a
2×2 grid). What counts is the ratio, POV-Ray's wall time over Prism's;
absolute times on a shared machine drift. POV-Ray spends a fixed time
starting up, measured on a 1×1 render of the same scene; the last column
compares Prism's whole run with POV-Ray's time past start-up.

Set-up: none; POV-Ray (Debian's povray) is installed by bench/setup.sh on first run.
Usage:  python3 bench/run.py [--repeat N] [--threads T]
Pictures: bench/out/NAME-prism.png and bench/out/NAME-povray.png.
"""

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import time

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))
OUT = os.path.join(ROOT, "bench", "out")

# (name, Prism scene, POV-Ray twin, width, height)
CASES = [
    ("whitted", "bench/whitted.toml", "bench/whitted.pov", 640, 480),
    ("soft-shadows", "scenes/soft-shadows.toml", "bench/soft-shadows.pov", 720, 300),
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
        # Installs Debian's povray (and the Embree venv) for the benchmarks.
        subprocess.run([os.path.join(ROOT, "bench", "setup.sh")], check=True)
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    prism = os.path.join(ROOT, "target", "release", "prism")
    os.makedirs(OUT, exist_ok=True)
    print(f"{'scene':<14} {'size':>9} {'prism s':>9} {'povray s':>9} {'pov start':>9} {'povray/prism':>13} {'(past start)':>13}")
    pictures = []
    for name, scene, pov, w, h in CASES:
        prism_png = os.path.join(OUT, f"{name}-prism.png")
        pov_png = os.path.join(OUT, f"{name}-povray.png")
        prism_cmd = [prism, "render", os.path.join(ROOT, scene), "-o", prism_png,
                     "--width", str(w), "--height", str(h), "--spp", "4", "--max-depth", "8",
                     "--threads", str(args.threads), "--quiet"]
        pov_common = ["povray", "+I" + os.path.join(ROOT, pov), "+A0.0", "+AM1", "+R2",
                      f"+WT{args.threads}", "-D", "-V", "-GA", "+FN"]
        pov_cmd = pov_common + ["+O" + pov_png, f"+W{w}", f"+H{h}"]
        pov_start_cmd = pov_common + ["+O" + os.path.join(OUT, "start.png"), "+W1", "+H1"]
        prism_times, pov_times, start_times = [], [], []
        for _ in range(args.repeat):
            prism_times.append(wall_time(prism_cmd))
            pov_times.append(wall_time(pov_cmd))
            start_times.append(wall_time(pov_start_cmd))
        p, q, s = (statistics.median(t) for t in (prism_times, pov_times, start_times))
        print(f"{name:<14} {w:>4}x{h:<4} {p:>9.3f} {q:>9.3f} {s:>9.3f} {q / p:>12.2f}x {(q - s) / p:>12.2f}x")
        pictures += [prism_png, pov_png]
    os.remove(os.path.join(OUT, "start.png"))
    print("pictures:", *pictures, sep="\n  ")


if __name__ == "__main__":
    main()
