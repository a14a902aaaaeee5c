#!/usr/bin/env python3
"""Closest-hit ray casting: Prism's aggregate against Embree (embreex), on
the same camera rays of the same scene, single-threaded, in the same run.

Prism's side is `examples/raycast.rs`; it also writes the rays and the
scene's triangles, which this script hands to Embree. Both take the best of
5 passes. The ratio (Embree rays/s over Prism rays/s) is what to compare
across runs; absolute times drift on a shared machine.

Set-up: none; the script makes bench/.venv (embreex, numpy) on first run.
Usage:  python3 bench/raycast.py [--size N] [SCENE ...]
"""

import argparse
import json
import os
import subprocess
import sys
import tempfile
import time

sys.path.insert(0, os.path.dirname(os.path.abspath(__file__)))
import benchenv  # noqa: E402

benchenv.ensure()
import numpy as np  # noqa: E402
from embreex import rtcore_scene as rtcs  # noqa: E402
from embreex.mesh_construction import TriangleMesh  # noqa: E402

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=512, help="image side in pixels (rays = size²)")
    parser.add_argument("scenes", nargs="*", default=["scenes/cornell.toml"])
    args = parser.parse_args()
    subprocess.run(["cargo", "build", "--release", "--quiet", "--example", "raycast"], cwd=ROOT, check=True)
    exe = os.path.join(ROOT, "target", "release", "examples", "raycast")
    print(f"{'scene':<22} {'rays':>8} {'prims':>6} {'prism Mrays/s':>14} {'embree Mrays/s':>15} {'embree/prism':>13} {'hits agree':>11}")
    for scene in args.scenes:
        with tempfile.TemporaryDirectory() as out:
            line = subprocess.run([exe, os.path.join(ROOT, scene), str(args.size), str(args.size), out],
                                  check=True, capture_output=True, text=True).stdout
            prism = json.loads(line)
            rays = np.fromfile(os.path.join(out, "rays.f32"), dtype="<f4").reshape(-1, 6)
            triangles = np.fromfile(os.path.join(out, "triangles.f32"), dtype="<f4").reshape(-1, 3, 3)
        origins = np.ascontiguousarray(rays[:, :3])
        directions = np.ascontiguousarray(rays[:, 3:])
        embree = rtcs.EmbreeScene()
        TriangleMesh(embree, triangles)
        best = float("inf")
        for _ in range(5):
            start = time.perf_counter()
            prim = embree.run(origins, directions)
            best = min(best, time.perf_counter() - start)
        embree_hits = int((prim >= 0).sum())
        n = len(rays)
        p_rate = n / prism["seconds"] / 1e6
        e_rate = n / best / 1e6
        agree = abs(embree_hits - prism["hits"]) <= n * 1e-4
        print(f"{os.path.basename(scene):<22} {n:>8} {prism['primitives']:>6} {p_rate:>14.2f} {e_rate:>15.2f} {e_rate / p_rate:>12.2f}x {str(agree):>11}")


if __name__ == "__main__":
    main()
