"""Renders the opened scene in Cycles (its own low sample count, CPU) and
prints the ratio of Prism's image to Cycles' at the image centre (on the
diffuse plane in the probe scenes), or, where the scene has the property
prism_probe (a world point) or prism_probes (a list of them), at the 2x2
pixels around each one's image, each asserted; writes OUT/cycles.exr and a
side-by-side OUT/side_by_side_PRISM.png (Cycles left, Prism right).
Run: blender -b SCENE.blend --python cycles_probe.py -- PRISM.exr OUT NAME [TOLERANCE]
"""

import os
import sys

import bpy
import numpy as np

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

# ---------------------------------------------------------------------------
# The probes' tolerance against Cycles: Prism reads glTF lights in their
# units (candela, lux at 683 lm/W, over base colour / π), so a diffuse
# surface is within 5 % of Cycles. PRISM_ASSERT_CYCLES overrides it.
# ---------------------------------------------------------------------------
ASSERT_WITHIN = 0.05
if os.environ.get("PRISM_ASSERT_CYCLES"):
    ASSERT_WITHIN = float(os.environ["PRISM_ASSERT_CYCLES"])

args = sys.argv[sys.argv.index("--") + 1:]
prism_path, out, name = args[:3]
if len(args) > 3:  # this run's own tolerance (the add-on's own light units)
    ASSERT_WITHIN = float(args[3])
scene = bpy.context.scene
scene.render.engine = "CYCLES"
scene.cycles.device = "CPU"
scene.cycles.use_denoising = False  # Debian builds Cycles without OpenImageDenoise
scene.render.image_settings.file_format = "OPEN_EXR"
scene.render.image_settings.color_depth = "32"
scene.render.filepath = os.path.join(out, "cycles.exr")
if not os.path.exists(scene.render.filepath):  # one Cycles render per scene
    bpy.ops.render.render(write_still=True)
cycles, prism = exr.rgb(os.path.join(out, "cycles.exr")), exr.rgb(prism_path)
def at_world_point(point):
    """Mean of the 2x2 pixels around a world point's image, both images."""
    from bpy_extras.object_utils import world_to_camera_view
    from mathutils import Vector
    v = world_to_camera_view(scene, scene.camera, Vector(point))
    h, w = cycles.shape[:2]
    x, y = int(round(v.x * w)), int(round(v.y * h))  # rows from the bottom, as exr.rgb
    c, p = (a[y - 1:y + 1, x - 1:x + 1].reshape(-1, 3).mean(axis=0) for a in (cycles, prism))
    return c, p, f"pixels {x - 1}..{x}, {h - y - 1}..{h - y} from the top (the floor at {tuple(point)})"


if "prism_probes" in scene:  # several points, each asserted
    probes = [at_world_point(tuple(q)) for q in scene["prism_probes"]]
elif "prism_probe" in scene:
    probes = [at_world_point(tuple(scene["prism_probe"]))]
else:
    probes = [(exr.centre(cycles), exr.centre(prism), "centre")]
ratios = []
for c, p, where in probes:
    ratio = float(p.mean() / c.mean()) if c.mean() > 0 else float("inf")
    ratios.append(ratio)
    print(f"cycles_probe: {name}: {where}: Prism {p.mean():.6g}, Cycles {c.mean():.6g}, "
          f"Prism/Cycles = {ratio:.4g}")

# Framing, whatever the units: the pixels that are not background (the
# world colour, seen directly) must be the same in both, as intersection
# over union. Only for the default scenes: in the probes the lit area
# differs (a spot cone is still a point light in Prism).
background = np.array(scene.world.node_tree.nodes["Background"].inputs["Color"].default_value[:3]) \
    * scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value
seen_c = np.abs(cycles - background).max(axis=2) > 0.003
seen_p = np.abs(prism - background).max(axis=2) > 0.003
iou = float((seen_c & seen_p).sum() / max(1, (seen_c | seen_p).sum()))
print(f"cycles_probe: {name}: silhouette IoU Prism/Cycles = {iou:.3f}")
framing_failed = name.startswith("default") and iou < 0.9

# Side by side, both through the Standard view (sRGB), for docs/blender.md.
both = np.concatenate([cycles, prism], axis=1)
srgb = np.where(both <= 0.0031308, 12.92 * both, 1.055 * np.power(np.maximum(both, 0), 1 / 2.4) - 0.055)
srgb = np.repeat(np.repeat(srgb, 4, axis=0), 4, axis=1)  # 4x, nearest: visible in the docs
h, w = srgb.shape[:2]
rgba = np.concatenate([np.clip(srgb, 0, 1), np.ones((h, w, 1), np.float32)], axis=2)
image = bpy.data.images.new("side by side", w, h, alpha=False)
image.pixels.foreach_set(rgba.astype(np.float32).ravel())
image.filepath_raw = os.path.join(out, f"side_by_side_{os.path.splitext(os.path.basename(prism_path))[0]}.png")
image.file_format = "PNG"
image.save()

if framing_failed:
    print(f"cycles_probe: FAIL: {name}: the framing differs from Cycles (IoU {iou:.3f} < 0.9)")
    sys.exit(1)
for ratio in ratios:
    if ASSERT_WITHIN is not None and not abs(ratio - 1.0) <= ASSERT_WITHIN:
        print(f"cycles_probe: FAIL: {name}: Prism/Cycles = {ratio:.4g}, not within {ASSERT_WITHIN:.0%}")
        sys.exit(1)
