#!/usr/bin/env python3
"""Rays for equal error: Whitted's adaptive anti-aliasing against uniform stratified sampling.

Runs examples/adaptive_rmse.rs on bench/whitted.toml (320x240) and the
edge-heavy bench/edges.toml (320x200): a 1,024-spp reference, uniform renders
at 1..64 spp and adaptive renders at depths 1..3 and thresholds 0.4..0.0125,
each with its RMSE against the reference and its rays; then edges.toml again
with its checker box-filtered (`filter = "box"`: each camera ray sees the
checker's mean over its footprint, so the floor near the horizon no longer
aliases, for either sampler), and with no checker at all (a plain floor:
the star polygon and the bars alone, the edge scene as the issue names
it). For each adaptive
render it prints the rays uniform sampling needs for the same RMSE
(interpolated in log-log between the two uniform renders around it) and the
ratio adaptive / uniform (below 1/3 meets the issue's goal).

Usage: python3 bench/adaptive.py
"""

import json
import math
import os
import re
import subprocess
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def uniform_rays_for(rmse, uniform):
    """Rays uniform sampling needs for `rmse`, log-log between its renders."""
    pts = sorted((u["rmse"], u["rays"]) for u in uniform)
    for (e0, r0), (e1, r1) in zip(pts, pts[1:]):
        if e0 <= rmse <= e1:
            s = (math.log(rmse) - math.log(e1)) / (math.log(e0) - math.log(e1))
            return math.exp(math.log(r1) + s * (math.log(r0) - math.log(r1)))
    return None


def main():
    subprocess.run(["cargo", "build", "--release", "--quiet", "--example", "adaptive_rmse"],
                   cwd=ROOT, check=True)
    exe = os.path.join(ROOT, "target", "release", "examples", "adaptive_rmse")
    tmp = tempfile.mkdtemp(prefix="prism-adaptive-")
    with open(os.path.join(ROOT, "bench", "edges.toml")) as f:
        text, n = re.subn(r"(checker = \{[^}]*?)\s*\}", r'\1, filter = "box" }', f.read())
    assert n == 1, "edges.toml has one checker"
    filtered = os.path.join(tmp, "edges-filtered.toml")
    with open(filtered, "w") as f:
        f.write(text)
    text, n = re.subn(r"\n\s*checker = \{[^}]*\}", "", text)
    assert n == 1, "edges.toml has one checker"
    plain = os.path.join(tmp, "edges-plain.toml")
    with open(plain, "w") as f:
        f.write(text)
    for scene, w, h in (("bench/whitted.toml", 320, 240), ("bench/edges.toml", 320, 200),
                        (filtered, 320, 200), (plain, 320, 200)):
        out = subprocess.run([exe, os.path.join(ROOT, scene), str(w), str(h)],
                             check=True, capture_output=True, text=True).stdout
        rows = [json.loads(line) for line in out.splitlines() if line.strip()]
        uniform = [r for r in rows if r["kind"] == "uniform"]
        print(f"\n{scene} at {w}x{h}, RMSE against 1,024 spp")
        for r in uniform:
            print(f"  uniform  {r['setting']:>26}  rmse {r['rmse']:.2e}  rays {r['rays']:>11,}")
        for r in rows:
            if r["kind"] != "adaptive":
                continue
            need = uniform_rays_for(r["rmse"], uniform)
            ratio = f"{r['rays'] / need:.2f}" if need else "  - "
            print(f"  adaptive {r['setting']:>26}  rmse {r['rmse']:.2e}  rays {r['rays']:>11,}"
                  f"  uniform needs {need or 0:>12,.0f}  ratio {ratio}")


if __name__ == "__main__":
    main()
