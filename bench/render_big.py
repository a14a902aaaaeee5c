#!/usr/bin/env python3
"""Renders bench/big.toml (the 1M-triangle terrain placed four times, the
bunny, and OBJ/PLY/glTF models) and reports the render summary and peak
resident memory. Makes the meshes with bench/meshes.py's generators first.

Usage: python3 bench/render_big.py  → bench/out/big.png
"""

import os
import subprocess
import sys

HERE = os.path.dirname(os.path.abspath(__file__))
ROOT = os.path.dirname(HERE)
sys.path.insert(0, HERE)
import meshes  # noqa: E402

os.makedirs(meshes.DATA, exist_ok=True)
meshes.bunny()
meshes.terrain()
os.makedirs(os.path.join(HERE, "out"), exist_ok=True)
subprocess.run(["cargo", "build", "--release", "--quiet"], cwd=ROOT, check=True)
out = os.path.join(HERE, "out", "big.png")
child = subprocess.Popen([os.path.join(ROOT, "target", "release", "prism"), "render", os.path.join(HERE, "big.toml"),
                          "--allow-read", os.path.join(ROOT, "scenes"), "-o", out])
_, status, usage = os.wait4(child.pid, 0)
if status != 0:
    sys.exit("the render failed")
peak_mb = usage.ru_maxrss / 1024
print(f"peak RSS of the render: {peak_mb:.0f} MB; picture: {out}")
