"""Checks that two EXR images agree: the add-on's render (as Blender saved
it) against `prism render` of the same export. Each channel within 1/255,
relative to the value above 1 (Prism's radiance is not clamped).
Run: blender -b --factory-startup --python compare.py -- [--differ] A.exr B.exr [X0,X1,Y0,Y1]"""

import os
import sys

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
differ = args[0] == "--differ"  # the two must not be equal (frames of an animation)
args = args[1:] if differ else args
a_path, b_path = args[:2]
a, b = exr.rgb(a_path), exr.rgb(b_path)
if len(args) > 2:
    # A render border: B's pixels x0 <= x < x1, y0 <= y < y1 (rows from the bottom).
    x0, x1, y0, y1 = (int(v) for v in args[2].split(","))
    b = b[y0:y1, x0:x1]
if a.shape != b.shape:
    print(f"compare: FAIL: {a_path} is {a.shape[1]}x{a.shape[0]}, {b_path} {b.shape[1]}x{b.shape[0]}")
    sys.exit(1)
diff = np.abs(a - b) / np.maximum(1.0, np.abs(b))
worst = float(diff.max())
print(f"compare: {a.shape[1]}x{a.shape[0]}, largest difference {worst:.3g} "
      f"({'byte-equal' if worst == 0 else 'within 1/255' if worst <= 1 / 255 else 'different, as expected' if differ else 'DIFFERENT'}), "
      f"mean {float(a.mean()):.6g} vs {float(b.mean()):.6g}")
if differ:
    if worst <= 1 / 255:
        print("compare: FAIL (equal, expected different)")
        sys.exit(1)
elif not (worst <= 1 / 255) or float(a.max()) <= 0.0:
    print("compare: FAIL (differ, or the image is black)")
    sys.exit(1)
