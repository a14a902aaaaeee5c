#!/usr/bin/env python3
"""Loading N spheres through the Python package: `prism.Scene.from_dict`
(the dict walked in Rust into the format's structs, no TOML text) against
`prism.loads` of the same scene as TOML text, same process, alternated.

Times each call's wall clock (build of the BVH included, nothing rendered)
and prints the range over the runs and the ratio of medians; issue 26's
goal is from_dict within 1.5x of loads.

Set-up: the package installed (`pip install ./python`, or
scripts/test-python.sh's virtual environment).
Usage:  python3 bench/load_spheres_python.py [--spheres N] [--repeat R]
"""

import argparse
import gc
import random
import statistics
import sys
import time

import prism


def scene(n):
    rng = random.Random(1)
    head = {
        "render": {"width": 64, "height": 48, "spp": 1},
        "camera": {"position": [0, 0, 300], "look_at": [0, 0, 0]},
        "materials": {"m": {"color": [0.8, 0.8, 0.8]}},
        "lights": {"l": {"type": "point", "position": [100, 200, 300]}},
    }
    spheres = [[round(rng.uniform(-100, 100), 3) for _ in range(3)] for _ in range(n)]
    d = dict(head, objects=[{"type": "sphere", "material": "m", "center": c, "radius": 0.1}
                            for c in spheres])
    text = ('[render]\nwidth = 64\nheight = 48\nspp = 1\n'
            '[camera]\nposition = [0, 0, 300]\nlook_at = [0, 0, 0]\n'
            '[materials.m]\ncolor = [0.8, 0.8, 0.8]\n'
            '[lights.l]\ntype = "point"\nposition = [100, 200, 300]\n'
            + "".join(f'[[objects]]\ntype = "sphere"\nmaterial = "m"\n'
                      f'center = [{x!r}, {y!r}, {z!r}]\nradius = 0.1\n' for x, y, z in spheres))
    return d, text


def timed(f):
    gc.collect()
    start = time.perf_counter()
    result = f()
    elapsed = time.perf_counter() - start
    del result
    return elapsed


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--spheres", type=int, default=1_000_000)
    parser.add_argument("--repeat", type=int, default=3)
    args = parser.parse_args()
    d, text = scene(args.spheres)
    a = prism.Scene.from_dict(d).render(progress=False, width=16, height=12)
    b = prism.loads(text).render(progress=False, width=16, height=12)
    assert a.tobytes() == b.tobytes(), "from_dict and loads built different scenes"
    runs = {"from_dict": [], "loads": []}
    for _ in range(args.repeat):
        runs["from_dict"].append(timed(lambda: prism.Scene.from_dict(d)))
        runs["loads"].append(timed(lambda: prism.loads(text)))
    print(f"{args.spheres:,} spheres, {args.repeat} runs each (alternated)")
    for name, times in runs.items():
        print(f"  {name:10} {min(times):.2f}-{max(times):.2f} s (median {statistics.median(times):.2f})")
    ratio = statistics.median(runs["from_dict"]) / statistics.median(runs["loads"])
    print(f"  from_dict / loads (medians): {ratio:.2f}x")


if __name__ == "__main__":
    sys.exit(main())
