"""Measures a spot light's pool on the diffuse plane of probe_spot_profile
in Cycles' image and Prism's: across the image centre (the mean of the two
middle rows, and of the two middle columns), the width where the
brightness is at least 90 % of the centre's (the fully lit core), 50 %
(the half-brightness width) and 10 %, each crossing found by linear
interpolation between pixels. The core and the half-brightness width
must be within TOLERANCE (3 %) of Cycles'.
Run: blender -b --factory-startup --python spot_profile.py -- CYCLES.exr PRISM.exr NAME [TOLERANCE]
"""

import os
import sys

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
cycles_path, prism_path, name = args[:3]
tolerance = float(args[3]) if len(args) > 3 else 0.03


def width(profile, level):
    """Pixels between the two crossings of `level` × the centre's value
    (outward from the middle), or None when the pool is not inside."""
    n = len(profile)
    centre = profile[n // 2 - 1:n // 2 + 1].mean()
    target = level * centre
    mid = n // 2

    def crossing(step):
        i = mid if step > 0 else mid - 1
        while 0 <= i + step < n and profile[i + step] >= target:
            i += step
        j = i + step
        if not 0 <= j < n:
            return None
        # Between pixel centres i (above) and j (below), linearly.
        return i + step * (profile[i] - target) / (profile[i] - profile[j])

    right, left = crossing(1), crossing(-1)
    return None if right is None or left is None else right - left


def profiles(path):
    a = exr.rgb(path).mean(axis=2)
    h, w = a.shape
    return a[h // 2 - 1:h // 2 + 1, :].mean(axis=0), a[:, w // 2 - 1:w // 2 + 1].mean(axis=1)


failed = False
for axis, c, p in zip(("row", "column"), profiles(cycles_path), profiles(prism_path)):
    for level, label, asserted in ((0.9, "core (90 %)", True), (0.5, "half brightness", True),
                                   (0.1, "10 %", False)):
        wc, wp = width(c, level), width(p, level)
        if wc is None or wp is None:
            print(f"spot_profile: FAIL: {name}: {axis}: the {label} width runs off the image")
            failed = True
            continue
        ratio = wp / wc
        print(f"spot_profile: {name}: {axis} {label}: Prism {wp:.2f} px, Cycles {wc:.2f} px, "
              f"Prism/Cycles = {ratio:.4f}")
        if asserted and not abs(ratio - 1.0) <= tolerance:
            print(f"spot_profile: FAIL: {name}: {axis} {label} width not within {tolerance:.0%} of Cycles'")
            failed = True
sys.exit(1 if failed else 0)
