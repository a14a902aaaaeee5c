"""The shadow terminator through the add-on (issue 29, item 3): a
smooth-shaded 32-segment UV sphere under a sun from the side and above,
seen by an orthographic camera, must shade as the sphere its normals
describe: along the meridian facing the camera the brightness rises
monotonically from the terminator to the brightest point, and wherever
the true sphere's N·L is at least 0.01 (inside 0.9 of the outline, where
the polygon's silhouette and the circle's agree) it is within 2 % of
E·N·L, E fitted on the well-lit part. Without Prism's shadow-terminator
offset the facets along the terminator shadow their own smoothed normals
(0.11 of E off, tests/shadow_terminator.rs).

Run: blender -b --factory-startup --python terminator_probe.py -- make OUT.blend
     blender -b --factory-startup --python terminator_probe.py -- measure PRISM.exr [CYCLES.exr]
"""

import os
import sys

import bpy
import numpy as np
from mathutils import Vector

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.dirname(__file__))
import exr  # noqa: E402

SIZE = 121
ORTHO_SCALE = 2.2
# Towards the sun, in Blender's axes (z up; the camera looks along +y).
TOWARDS_SUN = np.array([1.0, -0.35, 0.7])
TOWARDS_SUN /= np.linalg.norm(TOWARDS_SUN)


def make(path):
    bpy.ops.wm.read_factory_settings(use_empty=True)
    scene = bpy.context.scene
    bpy.ops.mesh.primitive_uv_sphere_add(segments=32, ring_count=16, radius=1.0)
    sphere = bpy.context.active_object
    bpy.ops.object.shade_smooth()
    material = bpy.data.materials.new("white")
    material.use_nodes = True
    principled = material.node_tree.nodes["Principled BSDF"]
    principled.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
    principled.inputs["Roughness"].default_value = 1.0
    principled.inputs["Specular"].default_value = 0.0
    sphere.data.materials.append(material)
    sun_data = bpy.data.lights.new("sun", "SUN")
    sun_data.energy = 3.0
    sun_data.angle = 0.0
    sun = bpy.data.objects.new("sun", sun_data)
    # A sun shines along its −Z: its +Z towards the sun.
    sun.rotation_euler = Vector(TOWARDS_SUN.tolist()).to_track_quat("Z", "Y").to_euler()
    scene.collection.objects.link(sun)
    camera_data = bpy.data.cameras.new("camera")
    camera_data.type = "ORTHO"
    camera_data.ortho_scale = ORTHO_SCALE
    camera = bpy.data.objects.new("camera", camera_data)
    camera.location = (0.0, -10.0, 0.0)
    camera.rotation_euler = (np.pi / 2, 0.0, 0.0)
    scene.collection.objects.link(camera)
    scene.camera = camera
    world = bpy.data.worlds.new("black")
    world.color = (0.0, 0.0, 0.0)
    scene.world = world
    scene.render.resolution_x = scene.render.resolution_y = SIZE
    scene.render.resolution_percentage = 100
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.cycles.samples = 16
    scene.cycles.use_denoising = False
    scene.cycles.max_bounces = 0
    bpy.ops.wm.save_as_mainfile(filepath=path)


def sphere_normals():
    """Per pixel (rows bottom-up): the unit sphere's normal facing the
    camera, and where the pixel is inside 0.9 of the outline."""
    centres = ((np.arange(SIZE) + 0.5) / SIZE * 2.0 - 1.0) * ORTHO_SCALE / 2.0
    u, v = np.meshgrid(centres, centres)  # u right (+x), v up (+z)
    r2 = u * u + v * v
    inside = r2 < 0.9 * 0.9
    normal = np.stack([u, -np.sqrt(np.clip(1.0 - r2, 0.0, None)), v], axis=-1)
    return normal, inside


def measure(prism_path, cycles_path=None):
    value = exr.rgb(prism_path).mean(axis=2)
    normal, inside = sphere_normals()
    n_dot_l = normal @ TOWARDS_SUN
    well_lit = inside & (n_dot_l > 0.3)
    e = float((value[well_lit] * n_dot_l[well_lit]).sum() / (n_dot_l[well_lit] ** 2).sum())
    lit = inside & (n_dot_l >= 0.01)
    worst = float(np.abs(value[lit] - e * n_dot_l[lit]).max() / e)
    # The middle column, bottom to top: from the terminator (below, the
    # sun being above) up to the brightest point.
    column = value[:, SIZE // 2]
    lit_column = np.nonzero((n_dot_l[:, SIZE // 2] > -0.2) & inside[:, SIZE // 2])[0]
    segment = column[lit_column]
    peak = int(np.argmax(segment))
    drops = np.diff(segment[: peak + 1])
    falls = max(0.0, float(-drops.min()) / e if len(drops) else 0.0)
    print(f"terminator_probe: |Prism - E N.L| <= {worst:.4f} E where N.L >= 0.01; "
          f"largest fall along the meridian {falls:.4f} E")
    if cycles_path:
        cycles = exr.rgb(cycles_path).mean(axis=2)
        ratio = float(value[well_lit].sum() / cycles[well_lit].sum())
        print(f"terminator_probe: Prism/Cycles on the well-lit part {ratio:.4f}")
    ok = worst < 0.02 and falls <= 1e-3
    if not ok:
        print("terminator_probe: FAIL: the smooth sphere shows its facets at the terminator")
        sys.exit(1)


args = sys.argv[sys.argv.index("--") + 1:]
if args[0] == "make":
    make(args[1])
else:
    measure(*args[1:3])
