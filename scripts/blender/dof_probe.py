"""Depth of field against Cycles: the newcomer's checker scene rendered
through a pinhole and with the lens (f/0.1 on the mirror ball), by both
renderers. An edge's steepness, the largest step between neighbouring
pixels of a row averaged over the rows of a region, falls where the lens
blurs: in the floor's near band (the bottom quarter of the image, out of
focus, crossed by the checker's edges) it must fall to at most 0.7 of the
pinhole's, as Cycles' does, Prism's fraction within 0.2 of Cycles'; on the
mirror ball in focus (rows through its image) it must stay at least 0.8
of the pinhole's.
Run: blender -b SCENE.blend --python dof_probe.py -- PIN_CYCLES PIN_PRISM DOF_CYCLES DOF_PRISM
"""

import os
import sys

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

pin_c, pin_p, dof_c, dof_p = (exr.rgb(p).mean(axis=2) for p in sys.argv[sys.argv.index("--") + 1:][:4])
scene = bpy.context.scene
h, w = pin_c.shape
ball = bpy.data.objects["mirror"]
v = world_to_camera_view(scene, scene.camera, ball.location)
bx, by = int(round(v.x * w)), int(round(v.y * h))
radius = max(3, int(0.06 * w))
regions = {
    "near floor (out of focus)": (slice(0, h // 4), slice(0, w)),
    "mirror ball (in focus)": (slice(by - 2, by + 2), slice(max(0, bx - 2 * radius), min(w, bx + 2 * radius))),
}


def steepness(a, region):
    rows = a[region]
    return float(np.abs(np.diff(rows, axis=1)).max(axis=1).mean())


failed = False
for label, region in regions.items():
    kept = {}
    for who, pin, dof in (("Cycles", pin_c, dof_c), ("Prism", pin_p, dof_p)):
        kept[who] = steepness(dof, region) / max(steepness(pin, region), 1e-9)
    print(f"dof_probe: {label}: edge steepness with the lens / pinhole: Prism {kept['Prism']:.3f}, "
          f"Cycles {kept['Cycles']:.3f}")
    if label.startswith("near"):
        if not (kept["Prism"] <= 0.7 and kept["Cycles"] <= 0.7 and abs(kept["Prism"] - kept["Cycles"]) <= 0.2):
            print("dof_probe: FAIL: the out-of-focus floor is not blurred as Cycles blurs it")
            failed = True
    elif not kept["Prism"] >= 0.8:
        print("dof_probe: FAIL: the mirror ball in focus is not sharp")
        failed = True
sys.exit(1 if failed else 0)
