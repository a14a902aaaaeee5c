"""Camera motion blur against Cycles on motion_camera (a checker plane seen
from above by a camera moving along x while the shutter is open): across
the image's middle rows each vertical cell edge becomes a ramp. Its width
in pixels: in the mean row, each run of pixels lying between 10 % and
90 % of the way from the dark cells' level to the light cells' (and not
cut by the image's border) over 0.8, averaged: a linear ramp of w pixels
has 0.8·w such pixels, a sharp edge none or one. Prism's must be at least
4 px (blur is there) and within 20 % of Cycles'.
Run: blender -b --factory-startup --python motion_probe.py -- CYCLES.exr PRISM.exr
"""

import os
import sys

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

cycles_path, prism_path = sys.argv[sys.argv.index("--") + 1:][:2]


def ramp(path):
    a = exr.rgb(path).mean(axis=2)
    h = a.shape[0]
    # Rows through the middle of a row of cells (cells are 1 unit, about
    # 30 px; the rows an eighth of the image above the centre).
    # The middle half of the columns: the plane's own edge (x = 2, near
    # the image's right border) is not a cell edge.
    w = a.shape[1]
    row = a[h // 2 + h // 8 - 2:h // 2 + h // 8 + 2, w // 4:3 * w // 4].mean(axis=0)
    lo, hi = row.min(), row.max()
    level = (row - lo) / max(hi - lo, 1e-9)
    inside = (level > 0.1) & (level < 0.9)
    # Runs of in-between pixels with a cell's level on both sides (a ramp
    # cut by the image's border is not a whole one).
    runs, start = [], None
    for i, b in enumerate(inside):
        if b and start is None:
            start = i
        elif not b and start is not None:
            if start > 0:
                runs.append(i - start)
            start = None
    return sum(runs) / (0.8 * len(runs)) if runs else 0.0


wc, wp = ramp(cycles_path), ramp(prism_path)
print(f"motion_probe: an edge's smear: Prism {wp:.2f} px, Cycles {wc:.2f} px, Prism/Cycles = {wp / wc:.3f}")
if not (wp >= 4.0 and abs(wp / wc - 1.0) <= 0.2):
    print("motion_probe: FAIL: the camera's motion is not blurred as Cycles blurs it")
    sys.exit(1)
