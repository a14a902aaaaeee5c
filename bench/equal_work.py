#!/usr/bin/env python3
"""Prism against POV-Ray 3.7 at equal work: 1 sample per pixel, both sides' ray counts.

Renders the same scenes in both (bench/whitted.toml and .pov with a
16-sample sphere light, the same with 64 samples (8×8 area light), that
again with shadows through the glass ball (Prism's transparent_shadows),
the soft-shadow study: a point light and two sphere lights, the Whitted
scene under a 16-feeler rectangle light (POV-Ray: a 4×4 area light), the solids:
bench/solids.toml and .pov, boxes, cylinders, cones, discs and tori under a
16-sample sphere light, shadows through glass on both sides, the CSG
scene: bench/csg.toml and .pov, dice, lenses, drilled balls, a glass merge,
a glass block less a bubble, half-spaces, under the same light, and depth of
field: bench/focal.toml and .pov, a thin lens against POV-Ray's focal_blur at
16 samples per pixel on both sides), without antialiasing, and prints each
side's rays as it counts them (camera, reflected, refracted, shadow
feelers), CPU and wall
time from GNU time, on one thread and on all. Ray counts differ a little
(POV-Ray also traces feelers from surfaces facing away from the light and
counts rays its light buffer saves), so besides the plain time ratio the
script prints the ratio per ray: (POV-Ray CPU / POV-Ray rays) / (Prism CPU /
Prism rays). A ratio above 1 means Prism is faster.

Set-up: none; POV-Ray and GNU time are installed by bench/setup.sh on first run.
Usage:  python3 bench/equal_work.py [--repeat N] [--only NAME] [--prism BINARY]
"""

import argparse
import os
import re
import shutil
import statistics
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))

# (name, Prism scene, POV-Ray scene, width, height, text edits applied to both)
CASES = [
    ("whitted-16", "bench/whitted.toml", "bench/whitted.pov", 640, 480, []),
    ("whitted-64", "bench/whitted.toml", "bench/whitted.pov", 640, 480,
     [("samples = 16", "samples = 64"), ("4, 4 circular", "8, 8 circular")]),
    # POV-Ray's shadows always pass through transmitting surfaces (the glass
    # ball is rgbt 0.9); Prism's do with transparent_shadows.
    ("whitted-64-transparent", "bench/whitted.toml", "bench/whitted.pov", 640, 480,
     [("samples = 16", "samples = 64"), ("4, 4 circular", "8, 8 circular"),
      ("[render]\n", "[render]\ntransparent_shadows = true\n")]),
    ("soft-shadows", "scenes/soft-shadows.toml", "bench/soft-shadows.pov", 720, 300, []),
    # The Whitted scene under a 1 × 1 rectangle light of 16 feelers where
    # the sphere light was; POV-Ray: a 4×4 (rectangular) area light of the
    # same size. POV-Ray's area light is 16 point lights with no cos θ′/d²
    # weighting, so the two pictures differ in brightness, not in work.
    ("area-16", "bench/whitted.toml", "bench/whitted.pov", 640, 480,
     [('type = "sphere"\nposition = [4.0, 9.0, 7.0]\nradius = 0.5\n',
       'type = "rectangle"\nposition = [4.0, 9.0, 7.0]\nedge_u = [1.0, 0.0, 0.0]\nedge_v = [0.0, 0.0, 1.0]\n'),
      ("intensity = 1.0\n\n# The floor", "intensity = 150.0\n\n# The floor"),
      ("4, 4 circular orient", "4, 4")]),
    # Every object a solid (box, cylinder, cone, disc, torus); the .toml sets
    # transparent_shadows, as POV-Ray's shadows pass through its glass.
    ("solids", "bench/solids.toml", "bench/solids.pov", 640, 480, []),
    # Every object but the floor a CSG (dice, lenses, drilled balls, a glass
    # merge, a glass block less a bubble, planes as half-spaces, an inverse
    # sphere); transparent_shadows as in the solids.
    ("csg", "bench/csg.toml", "bench/csg.pov", 640, 480, []),
    # Depth of field: Prism's thin lens against POV-Ray's focal_blur, five
    # balls receding over the floor, a point light (bench/focal.pov says how
    # the two apertures map).
    ("focal", "bench/focal.toml", "bench/focal.pov", 640, 480, []),
]

# Samples per pixel where a case needs more than one: a lens is sampled by
# the camera rays, so Prism's spp equals POV-Ray's blur_samples (which it
# traces whatever its antialiasing, with variance 0 all of them).
SAMPLES = {"focal": 16}


def timed(cmd, cwd):
    """(stderr+stdout text, CPU s, wall s) of one run under GNU time."""
    out = subprocess.run(["/usr/bin/time", "-f", "TIME %e %U %S"] + cmd, cwd=cwd,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, check=True)
    wall, user, system = re.findall(r"TIME ([\d.]+) ([\d.]+) ([\d.]+)", out.stdout)[-1]
    return out.stdout, float(user) + float(system), float(wall)


def prism_rays(text):
    m = re.search(r"rays: (\d+) camera, (\d+) reflection, (\d+) refraction, (\d+) shadow", text)
    return tuple(int(x) for x in m.groups())


def povray_rays(text):
    def count(label):
        # POV-Ray leaves out the lines of kinds it traced none of.
        m = re.search(label + r":\s+(\d+)", text)
        return int(m.group(1)) if m else 0
    rays, reflected, refracted = count("Rays"), count("Reflected Rays"), count("Refracted Rays")
    return rays - reflected - refracted, reflected, refracted, count("Shadow Ray Tests")


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    # Five: on a shared machine a median of three was once thrown by two
    # slow runs (docs/performance.md, third round of issue 16).
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--only", help="run only the case of this name")
    parser.add_argument("--prism", help="render with this Prism binary instead of building this checkout's "
                        "(a copy stays the same while others rebuild target/ during the run)")
    args = parser.parse_args()
    if shutil.which("povray") is None or not os.path.exists("/usr/bin/time"):
        subprocess.run([os.path.join(ROOT, "bench", "setup.sh")], check=True)
    if args.prism:
        prism = os.path.abspath(args.prism)
    else:
        subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
        prism = os.path.join(ROOT, "target", "release", "prism")
    threads_all = os.cpu_count() or 1
    with tempfile.TemporaryDirectory() as tmp:
        for name, toml, pov, w, h, edits in CASES:
            if args.only and name != args.only:
                continue
            texts = []
            for src, ext in ((toml, "toml"), (pov, "pov")):
                text = open(os.path.join(ROOT, src)).read()
                for a, b in edits:
                    text = text.replace(a, b)
                path = os.path.join(tmp, f"{name}.{ext}")
                open(path, "w").write(text)
                texts.append(path)
            spp = SAMPLES.get(name, 1)
            for threads in sorted({1, threads_all}):
                p_cmd = [prism, "render", texts[0], "-o", os.path.join(tmp, "p.png"), "--spp", str(spp),
                         "--width", str(w), "--height", str(h), "--threads", str(threads)]
                v_cmd = ["povray", "+I" + texts[1], "+O" + os.path.join(tmp, "v.png"), f"+W{w}", f"+H{h}",
                         "-A", "-D", "-GR", "-GD", f"+WT{threads}"]
                runs = {"prism": [], "povray": []}
                rays = {}
                for _ in range(args.repeat):
                    text, cpu, wall = timed(p_cmd, tmp)
                    rays["prism"] = prism_rays(text)
                    runs["prism"].append((cpu, wall))
                    text, cpu, wall = timed(v_cmd, tmp)
                    rays["povray"] = povray_rays(text)
                    runs["povray"].append((cpu, wall))
                print(f"\n{name}, {w}x{h}, {spp} spp, {threads} thread(s)")
                print(f"  {'':7} {'camera':>9} {'reflected':>10} {'refracted':>10} {'feelers':>11} "
                      f"{'CPU s':>12} {'wall s':>12}")
                for side in ("prism", "povray"):
                    cpu = [r[0] for r in runs[side]]
                    wall = [r[1] for r in runs[side]]
                    c, rl, rf, sh = rays[side]
                    print(f"  {side:7} {c:>9,} {rl:>10,} {rf:>10,} {sh:>11,} "
                          f"{min(cpu):>5.2f}–{max(cpu):<5.2f} {min(wall):>5.2f}–{max(wall):<5.2f}")
                med = {s: (statistics.median(r[0] for r in runs[s]), statistics.median(r[1] for r in runs[s]))
                       for s in runs}
                total = {s: sum(rays[s]) for s in rays}
                per_ray = (med["povray"][0] / total["povray"]) / (med["prism"][0] / total["prism"])
                print(f"  POV-Ray / Prism (medians): CPU {med['povray'][0] / med['prism'][0]:.2f}x, "
                      f"wall {med['povray'][1] / med['prism'][1]:.2f}x, CPU per ray {per_ray:.2f}x")


if __name__ == "__main__":
    sys.exit(main())
