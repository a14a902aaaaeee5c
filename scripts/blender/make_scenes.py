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
  default_shift, default_ortho_shift: the same with lens shift (0.15, -0.1),
    perspective and orthographic (the framing test of the off-centre frustum);
  probe_furnace: a rough metal ball (roughness 0.5) alone under a grey
    world, no lights: glossy reflection against Cycles' at its centre;
  motion_camera: a checker plane seen from above by a camera moving
    along x, motion blur on (motion_probe.py);
  motion_object: a glowing ball moving sideways while the shutter is open,
    seen from above at 128x48 (object_motion_probe.py);
  probe_spot_profile: the plane under a spot (size 45, blend 0.5) at 128x96,
    its whole pool in view (spot_profile.py);
  newcomer_checker, newcomer_dof, newcomer_spot, newcomer_area(_side): a
    newcomer's three scenes (issue 29): glass and mirror balls on a Checker
    Texture floor under a point light (and the same through a lens focused
    on the mirror ball); a spot, an emissive ball and a vertex-coloured cube
    under Subdivision at viewport 0 / render 2 (with a Noise Texture the
    export drops, and motion blur on while the emitter rises); two cameras, an area light and a sun
    with an angle. Each has prism_probes, floor points lit directly;
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
camera.data.shift_x, camera.data.shift_y = 0.15, -0.1  # lens shift (issue 29)
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "default_ortho_shift.blend"), copy=True)
camera.data.type = "PERSP"
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "default_shift.blend"), copy=True)
camera.data.shift_x, camera.data.shift_y = 0.0, 0.0
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

# The spot's profile (issue 29): a spot of size 45 degrees and blend 0.5
# 4 above the plane, its whole pool in view at 128x96, so that
# spot_profile.py can measure the pool's widths across the centre.
light_data = bpy.data.lights.new("spot light", "SPOT")
light_data.energy = 100.0
light_data.shadow_soft_size = 0.0
light_data.spot_size = math.radians(45.0)
light_data.spot_blend = 0.5
light = bpy.data.objects.new("spot light", light_data)
light.location = (0.0, 0.0, 4.0)
scene.collection.objects.link(light)
scene.render.resolution_x, scene.render.resolution_y = 128, 96
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "probe_spot_profile.blend"), copy=True)
scene.render.resolution_x, scene.render.resolution_y = 64, 48
bpy.data.objects.remove(light, do_unlink=True)

# A furnace (issue 29): a rough metal ball (metallic 1, base colour 0.8,
# roughness 0.5) alone under a uniform grey world, no lights; its centre
# reflects the world through the GGX lobe, 0.8 x the world in both.
plane.hide_render = True
bpy.ops.mesh.primitive_uv_sphere_add(radius=1.5, location=(0, 0, 0), segments=64, ring_count=32)
furnace_ball = bpy.context.active_object
bpy.ops.object.shade_smooth()
m = bpy.data.materials.new("rough metal")
m.use_nodes = True
for key, value in {"Base Color": (0.8, 0.8, 0.8, 1.0), "Metallic": 1.0, "Roughness": 0.5}.items():
    m.node_tree.nodes["Principled BSDF"].inputs[key].default_value = value
# Multiscatter GGX: energy-conserving, as Prism's lobe is (each ray an
# equal share of kr). Blender's default GGX scatters once and loses about
# a tenth at roughness 0.5 (measured: Prism 1.107 of it, 1.017 of this).
m.node_tree.nodes["Principled BSDF"].distribution = "MULTI_GGX"
furnace_ball.data.materials.append(m)
background.inputs["Color"].default_value = (0.5, 0.5, 0.5, 1.0)
background.inputs["Strength"].default_value = 1.0
scene.cycles.max_bounces = 8
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "probe_furnace.blend"), copy=True)
scene.cycles.max_bounces = 0
background.inputs["Color"].default_value = (0, 0, 0, 1)
background.inputs["Strength"].default_value = 0.0
bpy.data.objects.remove(furnace_ball, do_unlink=True)
plane.hide_render = False

# Camera motion blur (issue 29): the plane with a Checker Texture (1-unit
# cells) under a 1 W/m2 sun, seen from straight above at 128x96 by a camera
# moving along x at 1 unit a frame (keyed linearly, frames 0 to 2), motion
# blur on with Blender's default shutter (0.5 frames centred on frame 1):
# the cells' vertical edges smear over 0.5 units, about 15 pixels.
motion_floor = bpy.data.materials.new("moving checker")
motion_floor.use_nodes = True
motion_checker = motion_floor.node_tree.nodes.new("ShaderNodeTexChecker")
motion_checker.inputs["Scale"].default_value = 4.0
motion_bsdf = motion_floor.node_tree.nodes["Principled BSDF"]
motion_bsdf.inputs["Roughness"].default_value = 1.0
motion_bsdf.inputs["Specular"].default_value = 0.0
motion_floor.node_tree.links.new(motion_checker.outputs["Color"], motion_bsdf.inputs["Base Color"])
plane.data.materials[0] = motion_floor
sun_data = bpy.data.lights.new("sun", "SUN")
sun_data.energy, sun_data.angle = 1.0, 0.0
sun = bpy.data.objects.new("sun", sun_data)
scene.collection.objects.link(sun)
camera.location = (-1.0, 0.0, 6.0)
camera.keyframe_insert("location", frame=0)
camera.location = (1.0, 0.0, 6.0)
camera.keyframe_insert("location", frame=2)
for curve in camera.animation_data.action.fcurves:
    for key in curve.keyframe_points:
        key.interpolation = "LINEAR"
scene.frame_set(1)
scene.render.use_motion_blur = True
scene.render.resolution_x, scene.render.resolution_y = 128, 96
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "motion_camera.blend"), copy=True)
scene.render.resolution_x, scene.render.resolution_y = 64, 48
scene.render.use_motion_blur = False
camera.animation_data_clear()
camera.location = (0.0, 0.0, 6.0)
bpy.data.objects.remove(sun, do_unlink=True)
plane.data.materials[0] = material

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

# A newcomer's three scenes (issue 29), each at 64x48 with a dark world.
# Cycles without diffuse bounces (mirror and glass bounces kept): Whitted's
# light transport, so that the floor probes compare what Prism can show.
scene.cycles.diffuse_bounces = 0


def clear_scene():
    for obj in list(bpy.data.objects):
        bpy.data.objects.remove(obj, do_unlink=True)
    for key in ("prism_probe", "prism_probes"):
        if key in scene:
            del scene[key]


def diffuse(name, colour=(0.8, 0.8, 0.8, 1.0)):
    m = bpy.data.materials.new(name)
    m.use_nodes = True
    b = m.node_tree.nodes["Principled BSDF"]
    b.inputs["Base Color"].default_value = colour
    b.inputs["Roughness"].default_value = 1.0
    b.inputs["Specular"].default_value = 0.0
    return m


def add_camera(name, location, rotation):
    data = bpy.data.cameras.new(name)
    obj = bpy.data.objects.new(name, data)
    obj.location, obj.rotation_euler = location, rotation
    scene.collection.objects.link(obj)
    return obj


# 1: a glass and a mirror ball on a Checker Texture floor (the node's
# defaults but scale 4: colours 0.8 and 0.2, Generated coordinates, which
# on Blender's plane are its UV map) under a point light. The probes are
# a light and a dark cell of the floor, lit directly.
clear_scene()
floor_material = diffuse("checker texture floor")
nodes = floor_material.node_tree.nodes
checker_node = nodes.new("ShaderNodeTexChecker")
checker_node.inputs["Scale"].default_value = 4.0
floor_material.node_tree.links.new(checker_node.outputs["Color"],
                                   nodes["Principled BSDF"].inputs["Base Color"])
bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
bpy.context.active_object.name = "floor"
bpy.context.active_object.data.materials.append(floor_material)
ball("mirror", (-1.0, 0.8, 0.6), **{"Base Color": (0.9, 0.9, 0.9, 1.0), "Metallic": 1.0, "Roughness": 0.0})
ball("glass", (1.0, 0.8, 0.6), **{"Base Color": (1.0, 1.0, 1.0, 1.0), "Transmission": 1.0,
                                  "IOR": 1.5, "Roughness": 0.0})
light_data = bpy.data.lights.new("point light", "POINT")
light_data.energy = 500.0
light_data.shadow_soft_size = 0.0
light = bpy.data.objects.new("point light", light_data)
light.location = (0.0, -1.0, 4.0)
scene.collection.objects.link(light)
scene.camera = add_camera("camera", (0.0, -7.0, 4.0), (math.radians(62.0), 0.0, 0.0))
# Cells are 2 units (8 / 4): the probes are a light and a dark cell
# either side of x = 0.
scene["prism_probes"] = [(-1.0, -1.0, 0.0), (1.0, -1.0, 0.0)]
scene.render.resolution_x, scene.render.resolution_y = 128, 96  # edges for dof_probe.py
# dof_probe.py compares edges' steepness, which noise and the pixel filter
# change: Cycles here at Prism's 16 samples (test-blender.sh) and filter (a
# 1-pixel box), no adaptive sampling; both scenes, pinhole and lens alike.
scene.cycles.samples, scene.cycles.use_adaptive_sampling = 16, False
scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BOX", 1.0
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "newcomer_checker.blend"), copy=True)
# The same with depth of field: f/0.1 (a lens of radius 0.25) focused on the
# mirror ball; the near floor spreads over about 4 pixels, the floor at the
# ball's depth (its cell edge x = 0, between the balls) stays sharp.
dof = scene.camera.data.dof
dof.use_dof, dof.aperture_fstop = True, 0.1
dof.focus_object = bpy.data.objects["mirror"]
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "newcomer_dof.blend"), copy=True)
scene.render.resolution_x, scene.render.resolution_y = 64, 48
scene.cycles.samples, scene.cycles.use_adaptive_sampling = 32, True
scene.cycles.pixel_filter_type, scene.cycles.filter_width = "BLACKMAN_HARRIS", 1.5

# 2: a spot light, an emissive object and a vertex-coloured cube under a
# Subdivision modifier at viewport 0 / render 2, shaded smooth. The probe
# is the floor straight under the spot.
clear_scene()
bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
bpy.context.active_object.name = "floor"
bpy.context.active_object.data.materials.append(diffuse("floor"))
bpy.ops.mesh.primitive_cube_add(size=1.2, location=(-0.6, 0.0, 0.6))  # in the spot's pool
cube = bpy.context.active_object
cube.name = "subdivided cube"
subsurf = cube.modifiers.new("Subdivision", "SUBSURF")
subsurf.levels, subsurf.render_levels = 0, 2
bpy.ops.object.shade_smooth()
colours = cube.data.color_attributes.new("Col", "FLOAT_COLOR", "POINT")
for i, v in enumerate(cube.data.vertices):
    colours.data[i].color = (0.9 if v.co.x > 0 else 0.2, 0.9 if v.co.y > 0 else 0.2, 0.5, 1.0)
cube_material = diffuse("vertex colours")
attribute = cube_material.node_tree.nodes.new("ShaderNodeVertexColor")
attribute.layer_name = "Col"
cube_material.node_tree.links.new(attribute.outputs["Color"],
                                  cube_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
# A node the glTF export drops (named in the add-on's warning).
noise = cube_material.node_tree.nodes.new("ShaderNodeTexNoise")
cube_material.node_tree.links.new(noise.outputs["Fac"],
                                  cube_material.node_tree.nodes["Principled BSDF"].inputs["Roughness"])
cube.data.materials.append(cube_material)
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.4, location=(1.5, 1.5, 0.4))
bpy.context.active_object.name = "emitter"
# Disabled in viewports, not in renders: F12 renders it, so must the export.
bpy.context.active_object.hide_viewport = True
# Rising over frames 0 to 2: with motion blur on, Prism names it as sharp.
emitter = bpy.context.active_object
emitter.keyframe_insert("location", frame=0)
emitter.location.z = 0.8
emitter.keyframe_insert("location", frame=2)
scene.frame_set(1)
m = bpy.data.materials.new("glow")
m.use_nodes = True
m.node_tree.nodes["Principled BSDF"].inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
m.node_tree.nodes["Principled BSDF"].inputs["Emission"].default_value = (0.2, 0.5, 1.0, 1.0)
m.node_tree.nodes["Principled BSDF"].inputs["Emission Strength"].default_value = 3.0
bpy.context.active_object.data.materials.append(m)
light_data = bpy.data.lights.new("spot light", "SPOT")
light_data.energy = 300.0
light_data.shadow_soft_size = 0.1  # not carried (Prism's spot is a point), noted
light_data.spot_size = math.radians(60.0)
light_data.spot_blend = 0.3
light = bpy.data.objects.new("spot light", light_data)
light.location = (0.5, -1.5, 4.0)
scene.collection.objects.link(light)
scene.camera = add_camera("camera", (0.0, -7.0, 4.0), (math.radians(62.0), 0.0, 0.0))
scene["prism_probes"] = [(0.5, -1.5, 0.0), (1.3, -1.5, 0.0)]
scene.render.use_motion_blur = True  # the emitter moves: Prism names it as sharp
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "newcomer_spot.blend"), copy=True)
scene.render.use_motion_blur = False

# 3: two cameras, an area light and a sun (with an angle, which Prism
# warns about). The probes: the floor under the area light, and the floor
# the sun alone lights.
clear_scene()
bpy.ops.mesh.primitive_plane_add(size=8.0, location=(0, 0, 0))
bpy.context.active_object.name = "floor"
bpy.context.active_object.data.materials.append(diffuse("floor"))
bpy.ops.mesh.primitive_cube_add(size=1.0, location=(1.5, 1.0, 0.5))
box_material = diffuse("box", (0.6, 0.3, 0.2, 1.0))
# A Checker Texture on Generated coordinates, which on a cube are not its
# UV map: not carried, and named among the dropped nodes.
box_checker = box_material.node_tree.nodes.new("ShaderNodeTexChecker")
box_material.node_tree.links.new(box_checker.outputs["Color"],
                                 box_material.node_tree.nodes["Principled BSDF"].inputs["Base Color"])
bpy.context.active_object.data.materials.append(box_material)
light_data = bpy.data.lights.new("area light", "AREA")
light_data.shape, light_data.size, light_data.size_y = "RECTANGLE", 1.0, 0.5
light_data.energy = 200.0
light = bpy.data.objects.new("area light", light_data)
light.location = (-1.0, -1.0, 2.5)
scene.collection.objects.link(light)
light_data = bpy.data.lights.new("sun", "SUN")
light_data.energy, light_data.angle = 0.5, math.radians(5.0)
light = bpy.data.objects.new("sun", light_data)
light.rotation_euler = (math.radians(30.0), 0.0, math.radians(40.0))
scene.collection.objects.link(light)
add_camera("side camera", (6.0, 0.0, 5.0), (math.radians(50.0), 0.0, math.radians(90.0)))
scene.camera = add_camera("camera", (0.0, -7.0, 4.0), (math.radians(62.0), 0.0, 0.0))
# Not where the view grazes the floor: there Cycles' Principled diffuse
# (Disney's, retro-reflective at roughness 1) is brighter than Lambert's
# (measured 0.85-0.90 at 68 degrees from the normal).
scene["prism_probes"] = [(-1.0, -1.0, 0.0), (2.0, -2.5, 0.0)]
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "newcomer_area.blend"), copy=True)
scene.camera = bpy.data.objects["side camera"]
scene["prism_probes"] = [(-1.0, -1.0, 0.0), (2.0, -1.0, 0.0)]
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "newcomer_area_side.blend"), copy=True)

# Object motion blur (issue 29): a ball of radius 0.25 glowing white
# (black base, emission 1: radiance 1 in Cycles and in Prism) moving along
# x at 3 units a frame (keyed linearly, frames 0 to 2), seen from straight
# above by an orthographic camera 4 units wide at 128x48 (32 px a unit),
# motion blur on with Blender's default shutter (0.5 frames centred on
# frame 1): it travels 1.5 units (48 px) while the shutter is open, and
# its streak is travel + diameter = 2 units, 64 px (object_motion_probe.py).
clear_scene()
scene.world.use_nodes = True
scene.world.node_tree.nodes["Background"].inputs["Strength"].default_value = 0.0
bpy.ops.mesh.primitive_uv_sphere_add(radius=0.25, location=(-3.0, 0.0, 0.0), segments=32, ring_count=16)
moving = bpy.context.active_object
moving.name = "moving ball"
bpy.ops.object.shade_smooth()
m = bpy.data.materials.new("glowing white")
m.use_nodes = True
b = m.node_tree.nodes["Principled BSDF"]
b.inputs["Base Color"].default_value = (0.0, 0.0, 0.0, 1.0)
b.inputs["Specular"].default_value = 0.0
b.inputs["Roughness"].default_value = 1.0
b.inputs["Emission"].default_value = (1.0, 1.0, 1.0, 1.0)
b.inputs["Emission Strength"].default_value = 1.0
moving.data.materials.append(m)
moving.keyframe_insert("location", frame=0)
moving.location.x = 3.0
moving.keyframe_insert("location", frame=2)
for curve in moving.animation_data.action.fcurves:
    for key in curve.keyframe_points:
        key.interpolation = "LINEAR"
scene.camera = add_camera("camera", (0.0, 0.0, 5.0), (0.0, 0.0, 0.0))
scene.camera.data.type = "ORTHO"
scene.camera.data.ortho_scale = 4.0
scene.frame_set(1)
scene.render.use_motion_blur = True
scene.render.motion_blur_shutter = 0.5
scene.render.resolution_x, scene.render.resolution_y = 128, 48
scene.cycles.samples = 64
bpy.ops.wm.save_as_mainfile(filepath=os.path.join(out, "motion_object.blend"), copy=True)
print(f"make_scenes: wrote {sorted(os.listdir(out))}")
