"""Builds the test scenes as .blend files in OUT:
  probe_point, probe_spot, probe_sun: a 4x4 diffuse plane (albedo 0.8,
    roughness 1) at z = 0 under one light 4 units above its centre, a camera
    looking straight down, black world, Standard view transform. Nothing
    else is in the scene, so Cycles has no indirect light to add.
  default: Blender's factory startup scene (cube, light, camera);
  default_anim: the same with the cube moving over frames 1 to 3;
  default_ortho: the same through an orthographic camera;
  default_portrait: the same at 36x64.
All at 64x48 (the default scene 64x36, its 16:9).
Run: blender --background --factory-startup --python make_scenes.py -- OUT
"""

import math
import os
import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1]
os.makedirs(out, exist_ok=True)

# The default scene first, as the factory startup has it.
scene = bpy.context.scene
scene.render.resolution_x, scene.render.resolution_y = 64, 36
scene.render.resolution_percentage = 100
scene.cycles.samples = 16
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "default.blend"))
# The cube keyed to move (frames 1 to 3): an animation renders each frame's pose.
cube = bpy.data.objects["Cube"]
cube.keyframe_insert("location", frame=1)
cube.location = (0.0, 2.0, 0.0)
cube.keyframe_insert("location", frame=3)
scene.frame_start, scene.frame_end = 1, 3
scene.frame_set(1)
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "default_anim.blend"), copy=True)
cube.animation_data_clear()
cube.location = (0.0, 0.0, 0.0)
# The same through an orthographic camera, and a portrait frame (the
# sensor then fits the height): the framing tests of the camera mapping.
camera = scene.camera
camera.data.type = "ORTHO"
camera.data.ortho_scale = 6.0
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "default_ortho.blend"), copy=True)
camera.data.type = "PERSP"
scene.render.resolution_x, scene.render.resolution_y = 36, 64
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "default_portrait.blend"), copy=True)

# The probes: start empty.
for obj in list(bpy.data.objects):
    bpy.data.objects.remove(obj, do_unlink=True)
scene.world.use_nodes = True
background = scene.world.node_tree.nodes["Background"]
background.inputs["Color"].default_value = (0, 0, 0, 1)
background.inputs["Strength"].default_value = 0.0
scene.render.resolution_x, scene.render.resolution_y = 64, 48
scene.view_settings.view_transform = "Standard"
scene.view_settings.look = "None"
scene.cycles.samples = 16
scene.cycles.use_denoising = False
# Direct light only: Cycles and Whitted then agree on a lone plane.
scene.cycles.max_bounces = 0

material = bpy.data.materials.new("albedo 0.8")
material.use_nodes = True
bsdf = material.node_tree.nodes["Principled BSDF"]
bsdf.inputs["Base Color"].default_value = (0.8, 0.8, 0.8, 1.0)
bsdf.inputs["Roughness"].default_value = 1.0
bsdf.inputs["Specular"].default_value = 0.0
bsdf.inputs["Metallic"].default_value = 0.0

bpy.ops.mesh.primitive_plane_add(size=4.0, location=(0, 0, 0))
plane = bpy.context.active_object
plane.name = "plane"
plane.data.materials.append(material)

camera_data = bpy.data.cameras.new("camera")
camera_data.lens = 50.0
camera = bpy.data.objects.new("camera", camera_data)
camera.location = (0.0, 0.0, 6.0)  # looking down -Z at the plane's centre
scene.collection.objects.link(camera)
scene.camera = camera

for kind in ("POINT", "SPOT", "SUN"):
    light_data = bpy.data.lights.new(f"{kind.lower()} light", kind)
    light_data.color = (1.0, 1.0, 1.0)
    if kind == "SUN":
        light_data.energy = 1.0  # W/m²
        light_data.angle = 0.0
    else:
        light_data.energy = 100.0  # W
        light_data.shadow_soft_size = 0.0
    if kind == "SPOT":
        light_data.spot_size = math.radians(60.0)
        light_data.spot_blend = 0.15
    light = bpy.data.objects.new(f"{kind.lower()} light", light_data)
    light.location = (0.0, 0.0, 4.0)  # points down -Z
    scene.collection.objects.link(light)
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, f"probe_{kind.lower()}.blend"), copy=True)
    bpy.data.objects.remove(light, do_unlink=True)
print(f"make_scenes: wrote {sorted(os.listdir(out))}")
