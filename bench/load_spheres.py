#!/usr/bin/env python3
"""Loading a scene of a million spheres: Prism against POV-Ray 3.7, same run.

Writes the same N spheres (default 1,000,000, seeded) as a Prism scene
(`[[objects]]` tables, ~91 bytes of text per sphere) and as a POV-Ray scene
(`sphere { ... }`), then measures for each, with GNU time: peak resident memory, wall time and
CPU time of loading and building the scene. Prism runs `prism check`
(parse, validate, build the BVH; nothing rendered); POV-Ray renders a 1×1
image (parse, bounding, one pixel). Both read the same spheres; bytes per
sphere are peak RSS / N. The issue-6 goal: at most 400 bytes per sphere and
10 s for a million.

Set-up: none; POV-Ray and GNU time (Debian's povray, time) are installed by
bench/setup.sh on first run.
Usage:  python3 bench/load_spheres.py [--spheres N] [--repeat R]
"""

import argparse
import os
import random
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def write_scenes(n, folder):
    rng = random.Random(1)
    toml = os.path.join(folder, "spheres.toml")
    pov = os.path.join(folder, "spheres.pov")
    with open(toml, "w") as t, open(pov, "w") as p:
        t.write('[render]\nwidth = 64\nheight = 48\nspp = 1\n'
                '[camera]\nposition = [0, 0, 300]\nlook_at = [0, 0, 0]\n'
                '[materials.m]\ncolor = [0.8, 0.8, 0.8]\n'
                '[lights.l]\ntype = "point"\nposition = [100, 200, 300]\n')
        p.write('camera { location <0, 0, 300> look_at <0, 0, 0> }\n'
                'light_source { <100, 200, 300> color rgb 1 }\n')
        for _ in range(n):
            x, y, z = (rng.uniform(-100, 100) for _ in range(3))
            t.write(f'[[objects]]\ntype = "sphere"\nmaterial = "m"\n'
                    f'center = [{x:.3f}, {y:.3f}, {z:.3f}]\nradius = 0.1\n')
            p.write(f'sphere {{ <{x:.3f}, {y:.3f}, {-z:.3f}>, 0.1 pigment {{ rgb 0.8 }} }}\n')
    return toml, pov


def measure(cmd, cwd):
    """(peak RSS in bytes, wall s, CPU s) of one run of `cmd`, by GNU time."""
    out = subprocess.run(["/usr/bin/time", "-f", "%M %e %U %S"] + cmd, cwd=cwd, check=True,
                         stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True)
    rss_kib, wall, user, system = out.stderr.strip().splitlines()[-1].split()
    return int(rss_kib) * 1024, float(wall), float(user) + float(system)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    if shutil.which("povray") is None or not os.path.exists("/usr/bin/time"):
        subprocess.run([os.path.join(ROOT, "bench", "setup.sh")], check=True)
    subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
    prism = os.path.join(ROOT, "target", "release", "prism")
    n = args.spheres
    with tempfile.TemporaryDirectory() as folder:
        toml, pov = write_scenes(n, folder)
        runs = {
            "prism": [prism, "check", toml],
            "povray": ["povray", "+I" + pov, "+O" + os.path.join(folder, "o.png"),
                       "+W1", "+H1", "-D", "-GA", "+WT1"],
        }
        print(f"{n:,} spheres; Prism text {os.path.getsize(toml) / n:.0f} B/sphere, "
              f"POV-Ray text {os.path.getsize(pov) / n:.0f} B/sphere")
        results = {name: [] for name in runs}
        for _ in range(args.repeat):
            for name, cmd in runs.items():
                results[name].append(measure(cmd, folder))
        print(f"{'':8} {'peak B/sphere':>16} {'wall s':>14} {'CPU s':>14}")
        for name, rows in results.items():
            rss = [r[0] / n for r in rows]
            wall = [r[1] for r in rows]
            cpu = [r[2] for r in rows]
            span = lambda xs, f: f"{f(min(xs))}–{f(max(xs))}" if xs else "n/a"
            print(f"{name:8} {span(rss, lambda x: f'{x:.0f}'):>16} {span(wall, lambda x: f'{x:.2f}'):>14} "
                  f"{span(cpu, lambda x: f'{x:.2f}'):>14}")
        med = lambda name, i: statistics.median(r[i] for r in results[name])
        print(f"ratio POV-Ray / Prism (median): memory {med('povray', 0) / med('prism', 0):.2f}×, "
              f"wall {med('povray', 1) / med('prism', 1):.2f}×, CPU {med('povray', 2) / med('prism', 2):.2f}×")


if __name__ == "__main__":
    sys.exit(main())
