"""Depth of field against Cycles: the newcomer's checker scene rendered
through a pinhole and with the lens (f/0.1 focused on the mirror ball), by
both renderers, all four at the same samples per pixel and pixel filter
(make_scenes.py gives Cycles a 1-pixel box, as Prism's, and no adaptive
sampling; test-blender.sh renders both scenes at 16 spp). An edge's
steepness, the largest step between neighbouring pixels of a row averaged
over the rows of a region, falls where the lens blurs; noise raises it, so
pinhole and lens are compared at equal noise. The fraction the lens keeps
(lens / pinhole):
  near floor: the bottom quarter of the image, out of focus, crossed by the
    checker's edges: at most 0.7, Prism's within 0.1 of Cycles';
  floor at the focus distance: the checker's cell edge x = 0 (between the
    balls) on the rows where the floor lies at the focus object's depth
    (a diffuse edge in the plane in focus; the row is also where the focus
    plane lies, so a misplaced plane blurs it): at least 0.9, Prism's within
    0.1 of Cycles';
  mirror ball: the rows through the middle half of its image, its
    silhouettes inside the window (what it reflects lies behind its
    surface, near the plane in focus at f/0.1): at least 0.9, Prism's
    within 0.1 of Cycles'.
With SCENE_TOML (the add-on's export of the lens scene), its lens is
checked against Cycles' reading of the camera (intern/cycles/blender/
camera.cpp): aperture radius = lens [mm] * 1e-3 / (2 * f-stop), focus
distance = the focus object's depth along the view (Blender's own
world_to_camera_view depth here), both within 1e-5 relative.
Run: blender -b SCENE.blend --python dof_probe.py -- PIN_CYCLES PIN_PRISM DOF_CYCLES DOF_PRISM [SCENE_TOML]
"""

import os
import re
import sys

import bpy
import numpy as np
from bpy_extras.object_utils import world_to_camera_view
from mathutils import Vector

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

args = sys.argv[sys.argv.index("--") + 1:]
pin_c, pin_p, dof_c, dof_p = (exr.rgb(p).mean(axis=2) for p in args[:4])
scene = bpy.context.scene
camera = scene.camera
h, w = pin_c.shape


def image(point):
    """(column, row from the bottom, depth along the view) of a world point."""
    v = world_to_camera_view(scene, camera, Vector(point))
    return v.x * w, v.y * h, v.z


# The mirror ball: its centre's image and its image radius (the camera's
# right axis carries the ball's radius sideways).
ball = camera.data.dof.focus_object
bx, by, _ = image(ball.location)
right = camera.matrix_world.to_3x3() @ Vector((1.0, 0.0, 0.0))
rx, _, _ = image(ball.location + right.normalized() * (ball.dimensions.x / 2.0))
r = abs(rx - bx)
# The floor line x = 0 (a checker cell edge) where its depth is the focus
# object's: the depth along the view is linear along the line.
_, _, ball_depth = image(ball.location)
(ex, _, z0), (_, _, z1) = image((0.0, 0.0, 0.0)), image((0.0, 1.0, 0.0))
_, focus_row, _ = image((0.0, (ball_depth - z0) / (z1 - z0), 0.0))
focus_row, ex = int(focus_row), int(round(ex))
regions = {
    "near floor (out of focus)": (slice(0, h // 4), slice(0, w)),
    "floor at the focus distance": (slice(focus_row - 1, focus_row + 2), slice(ex - 6, ex + 6)),
    "mirror ball (in focus)": (slice(int(by - r / 2), int(by + r / 2) + 1),
                               slice(max(0, int(bx - r) - 3), min(w, int(bx + r) + 4))),
}


def steepness(a, region):
    rows = a[region]
    return float(np.abs(np.diff(rows, axis=1)).max(axis=1).mean())


failed = False
if len(args) > 4:
    with open(args[4], encoding="utf-8") as f:
        text = f.read()
    written = {key: float(m.group(1)) if (m := re.search(rf"^{key} = (\S+)$", text, re.M)) else None
               for key in ("aperture", "focus_distance")}
    lens = camera.data
    expected = {"aperture": lens.lens * 1e-3 / (2.0 * lens.dof.aperture_fstop), "focus_distance": ball_depth}
    for key, want in expected.items():
        got = written[key]
        ok = got is not None and abs(got - want) <= 1e-5 * want
        print(f"dof_probe: the export's {key} {got}, Cycles' {want:.7g}" + ("" if ok else ": FAIL"))
        failed |= not ok
for label, region in regions.items():
    kept = {}
    for who, pin, dof in (("Cycles", pin_c, dof_c), ("Prism", pin_p, dof_p)):
        kept[who] = steepness(dof, region) / max(steepness(pin, region), 1e-9)
    rows, cols = region
    print(f"dof_probe: {label} (rows {h - rows.stop}..{h - rows.start - 1} from the top, columns "
          f"{cols.start}..{cols.stop - 1}): edge steepness with the lens / pinhole: "
          f"Prism {kept['Prism']:.3f}, Cycles {kept['Cycles']:.3f}")
    close = abs(kept["Prism"] - kept["Cycles"]) <= 0.1
    if label.startswith("near"):
        if not (kept["Prism"] <= 0.7 and kept["Cycles"] <= 0.7 and close):
            print("dof_probe: FAIL: the out-of-focus floor is not blurred as Cycles blurs it")
            failed = True
    elif not (kept["Prism"] >= 0.9 and close):
        print(f"dof_probe: FAIL: the {label.split(' (')[0]} is not as sharp as in Cycles")
        failed = True
sys.exit(1 if failed else 0)
