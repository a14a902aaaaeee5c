"""Object motion blur against Cycles and the analytic streak on
motion_object (a glowing ball of radius 0.25 moving 1.5 units along x
while the shutter is open, 32 px a unit, seen from above): along the two
rows through its centre, a point x is covered for
|[x - c, x + c] ∩ [-0.75, 0.75]| / 1.5 of the exposure (c the half chord
on that row): a box of the travel smeared by the ball's chord, ramps 16 px
long up to a plateau of 1/3 (radiance 1 a third of the time).
Measured on each image and on that analytic row: the streak's length,
the run of pixels above 5 % of the plateau (travel + diameter = 64 px,
less the ramps' first 5 %: 62.4 px), and its width at half the plateau
(the travel, 48 px); and the mean |image - analytic| over the streak.
Prism's length and width must be within 20 % of Cycles' and of the
analytic ones.
Run: blender -b --factory-startup --python object_motion_probe.py -- CYCLES.exr PRISM.exr
"""

import os
import sys

import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

cycles_path, prism_path = sys.argv[sys.argv.index("--") + 1:][:2]
SCALE, RADIUS, TRAVEL = 32.0, 0.25, 1.5  # px a unit, ball, units moved
PLATEAU = 2 * RADIUS / TRAVEL


def row(a):
    """The mean of the two rows through the ball's centre."""
    h = a.shape[0]
    return a[h // 2 - 1:h // 2 + 1].mean(axis=2).mean(axis=0)


def analytic(width):
    x = (np.arange(width) + 0.5) / SCALE - width / (2 * SCALE)
    c = np.sqrt(RADIUS ** 2 - (0.5 / SCALE) ** 2)  # the rows lie half a pixel off centre
    overlap = np.minimum(x + c, TRAVEL / 2) - np.maximum(x - c, -TRAVEL / 2)
    return np.maximum(overlap, 0.0) / TRAVEL


def measure(r):
    """(length above 5 % of the plateau, width above half of it), in px."""
    return (r > 0.05 * PLATEAU).sum(), (r > 0.5 * PLATEAU).sum()


cycles, prism = row(exr.rgb(cycles_path)), row(exr.rgb(prism_path))
exact = analytic(len(prism))
(lc, wc), (lp, wp), (la, wa) = measure(cycles), measure(prism), measure(exact)
streak = exact > 0
print(f"object_motion_probe: streak length Prism {lp} px, Cycles {lc} px, analytic {la} px "
      f"(travel + diameter {(TRAVEL + 2 * RADIUS) * SCALE:.0f} px); width at half the plateau "
      f"Prism {wp} px, Cycles {wc} px, analytic {wa} px (the travel, {TRAVEL * SCALE:.0f} px); "
      f"mean |image - analytic| over the streak: Prism {np.abs(prism - exact)[streak].mean():.3f}, "
      f"Cycles {np.abs(cycles - exact)[streak].mean():.3f} (plateau {PLATEAU:.3f})")
bad = [f"{what} {got} against {name} {want}" for what, got, want, name in (
    ("length", lp, lc, "Cycles"), ("length", lp, la, "analytic"),
    ("width", wp, wc, "Cycles"), ("width", wp, wa, "analytic")) if abs(got / want - 1.0) > 0.2]
if bad:
    print(f"object_motion_probe: FAIL: the ball's streak is not Cycles' (within 20 %): {'; '.join(bad)}")
    sys.exit(1)
