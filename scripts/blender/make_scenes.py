"""Builds the test scenes as .blend files in OUT:
  probe_area, probe_area_disk, probe_area45: the same plane under a 100 W
    area light (a 1 x 1 square, a disk 1 across) 4 above its centre, or
    the square 1.5 above it probed 45 degrees off its axis;
  probe_point, probe_spot, probe_sun: a 4x4 diffuse plane (albedo 0.8,
    roughness 1) at z = 0 under one light 4 units above its centre, a camera
    looking straight down, black world, Standard view transform. Nothing
    else is in the scene, so Cycles has no indirect light to add.
  default: Blender's factory startup scene (cube, light, camera);
  default_anim: the same with the cube moving over frames 1 to 3;
  default_ortho: the same through an orthographic camera;
  default_portrait: the same at 36x64;
  showcase: an 8x8 floor (a packed 16x16 checker image tiled 4 times by a
    Mapping node, so the exporter writes KHR_texture_transform), a mirror
    ball, a glass ball, a small emissive cube and a spot light, dark world;
    its scene property prism_probe is a floor point the spot lights
    directly, away from the balls and the cube (cycles_probe.py compares
    Cycles there).
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

# Area lights (issue 29): a 1 x 1 square 4 above the centre (probe_area),
# a disk of diameter 1 4 above it (probe_area_disk), and the square 1.5
# above the plane probed 1.5 off its foot, 45 degrees off its axis
# (probe_area45); 100 W each, emitting down.
for name, shape, height, probe in (("area", "SQUARE", 4.0, None),
                                   ("area_disk", "DISK", 4.0, None),
                                   ("area45", "SQUARE", 1.5, (1.5, 0.0, 0.0))):
    light_data = bpy.data.lights.new(f"{name} light", "AREA")
    light_data.shape = shape
    light_data.size = 1.0
    light_data.energy = 100.0
    light = bpy.data.objects.new(f"{name} light", light_data)
    light.location = (0.0, 0.0, height)
    scene.collection.objects.link(light)
    if probe is not None:
        scene["prism_probe"] = probe
    bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, f"probe_{name}.blend"), copy=True)
    if probe is not None:
        del scene["prism_probe"]
    bpy.data.objects.remove(light, do_unlink=True)

# The showcase (issue 15): texture transform, mirror, glass, emission, spot.
for obj in list(bpy.data.objects):
    if obj.type != "CAMERA":
        bpy.data.objects.remove(obj, do_unlink=True)
scene.cycles.max_bounces = 8  # the mirror and the glass need bounces in Cycles
scene.cycles.samples = 32
checker = bpy.data.images.new("checker", 16, 16, alpha=False)
dark, light_ = 0.2, 0.8  # sRGB-encoded, as a PNG holds them
checker.pixels.foreach_set([v for y in range(16) for x in range(16)
                            for v in ((light_,) * 3 if (x // 8 + y // 8) % 2 == 0 else (dark,) * 3) + (1.0,)])
checker.pack()
floor_material = bpy.data.materials.new("checker floor")
floor_material.use_nodes = True
nodes, links = floor_material.node_tree.nodes, floor_material.node_tree.links
bsdf = nodes["Principled BSDF"]
bsdf.inputs["Roughness"].default_value = 1.0
bsdf.inputs["Specular"].default_value = 0.0
texture = nodes.new("ShaderNodeTexImage")
texture.image = checker
texture.interpolation = "Closest"
mapping = nodes.new("ShaderNodeMapping")
mapping.inputs["Scale"].default_value = (4.0, 4.0, 1.0)
coordinates = nodes.new("ShaderNodeTexCoord")
links.new(coordinates.outputs["UV"], mapping.inputs["Vector"])
links.new(mapping.outputs["Vector"], texture.inputs["Vector"])
links.new(texture.outputs["Color"], bsdf.inputs["Base Color"])
bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
bpy.context.active_object.name = "floor"
bpy.context.active_object.data.materials.append(floor_material)


def ball(name, location, **inputs):
    bpy.ops.mesh.primitive_uv_sphere_add(radius=0.6, location=location, segments=32, ring_count=16)
    obj = bpy.context.active_object
    obj.name = name
    bpy.ops.object.shade_smooth()
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    for key, value in inputs.items():
        m.node_tree.nodes["Principled BSDF"].inputs[key].default_value = value
    obj.data.materials.append(m)
    return obj


ball("mirror", (-1.0, 0.8, 0.6), **{"Base Color": (0.9, 0.9, 0.9, 1.0), "Metallic": 1.0, "Roughness": 0.0})
ball("glass", (1.0, 0.8, 0.6), **{"Base Color": (1.0, 1.0, 1.0, 1.0), "Transmission": 1.0,
                                  "IOR": 1.5, "Roughness": 0.0})
bpy.ops.mesh.primitive_cube_add(size=0.3, location=(2.8, 2.8, 0.15))
emitter = bpy.context.active_object
emitter.name = "emitter"
m = bpy.data.materials.new("emitter")
m.use_nodes = True
m.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
m.node_tree.nodes["Principled BSDF"].inputs["Emission"].default_value = (1.0, 0.5, 0.1, 1.0)
m.node_tree.nodes["Principled BSDF"].inputs["Emission Strength"].default_value = 4.0
emitter.data.materials.append(m)
light_data = bpy.data.lights.new("spot light", "SPOT")
light_data.energy = 300.0  # W
light_data.shadow_soft_size = 0.0
light_data.spot_size = math.radians(70.0)
light_data.spot_blend = 0.15
light = bpy.data.objects.new("spot light", light_data)
# Straight above the probe point (below): Cycles 3.x scales a spot's
# intensity by the cosine of the angle off its axis (Prism, like glTF,
# does not), so only on the axis do the two agree (off it by 1/cos).
light.location = (0.5, -1.5, 4.0)  # points down -Z
scene.collection.objects.link(light)
camera.location = (0.0, -7.0, 4.0)
camera.rotation_euler = (math.radians(62.0), 0.0, 0.0)
# A floor point in a light cell (cells are 1 unit; the light cells' centres
# at half-odd coordinates of the same parity), under the spot, 2.5 from the
# mirror ball's centre and 4.8 from the cube.
scene["prism_probe"] = (0.5, -1.5, 0.0)
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "showcase.blend"), copy=True)
print(f"make_scenes: wrote {sorted(os.listdir(out))}")
