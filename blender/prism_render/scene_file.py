"""The TOML scene that goes beside the exported .glb: what glTF cannot
carry (image size, samples, background, the active camera's framing).

Plain Python apart from the `bpy` objects passed in, so the mapping can be
read (and tested) on its own.
"""

import json
import math

# ---------------------------------------------------------------------------
# Switches for what the library gained in issue 15 (items 1-2); both on.
# Off, the key is not written (an older prism refuses unknown keys).
# ---------------------------------------------------------------------------

# `[render] exposure` (EV), from Blender's Color Management exposure. Only
# the 8-bit output of a standalone `prism render scene.toml -o x.png` uses
# it: the EXR the add-on reads stays linear, and Blender applies its own
# exposure when it shows the render (so it is never applied twice).
HAS_EXPOSURE = True

# `[camera] shift` (issue 29): Blender's lens shift as an off-centre frustum.
HAS_SHIFT = True

# The glTF loader's diffuse term is base colour / π (issue 15, item 1).
# Only the lights this file writes ("Lights: Scene File") depend on it:
# their intensities are matched to Cycles on a glTF material.
GLTF_DIFFUSE_OVER_PI = True


def toml_string(s):
    """A TOML basic string: JSON's escaping without \\u surrogate pairs,
    and DEL, which TOML also wants escaped."""
    return json.dumps(str(s), ensure_ascii=False).replace("\x7f", "\\u007f")


def toml_number(x):
    x = float(x)
    if not math.isfinite(x):
        raise ValueError(f"{x} is not a finite number")
    return f"{x + 0.0:.9g}"  # + 0.0: no "-0"


def toml_vector(v):
    return "[" + ", ".join(toml_number(c) for c in v) + "]"


def to_y_up(v):
    """Blender's +Z-up world to glTF's (and Prism's) +Y-up, as the glTF
    exporter converts it with export_yup: (x, y, z) -> (x, z, -y)."""
    return (v[0], v[2], -v[1])


def image_size(render):
    """Pixels Blender renders: the resolution at its percentage."""
    scale = render.resolution_percentage / 100.0
    return (
        max(1, int(render.resolution_x * scale)),
        max(1, int(render.resolution_y * scale)),
    )


def border(render, width, height):
    """The render border as Prism's crop (x0, x1, y0, y1, rows from the
    top), or None. Blender truncates border × size to whole pixels (its
    render_init_from_main); its rows count from the bottom."""
    if not render.use_border:
        return None
    x0, x1 = int(render.border_min_x * width), int(render.border_max_x * width)
    y0, y1 = int(render.border_min_y * height), int(render.border_max_y * height)
    x0, x1 = max(0, min(x0, width)), max(0, min(x1, width))
    y0, y1 = max(0, min(y0, height)), max(0, min(y1, height))
    if x0 >= x1 or y0 >= y1:
        return None
    return x0, x1, height - y1, height - y0


def world_colour(world):
    """The world's background colour: the Background node feeding the
    World Output (colour × strength) when it uses nodes, else its colour.
    A texture or anything else linked into it is not followed."""
    if world is None:
        return (0.0, 0.0, 0.0), None
    if world.use_nodes and world.node_tree is not None:
        output = next(
            (n for n in world.node_tree.nodes
             if n.type == "OUTPUT_WORLD" and n.is_active_output),
            None,
        )
        links = output.inputs["Surface"].links if output else ()
        if links:
            node = links[0].from_node
            if node.type == "BACKGROUND":
                colour, strength = node.inputs["Color"], node.inputs["Strength"]
                note = None
                if colour.is_linked or strength.is_linked:
                    note = "the world's Background node has linked inputs; Prism uses their unlinked values"
                s = strength.default_value
                return tuple(max(0.0, c * s) for c in colour.default_value[:3]), note
            return (0.0, 0.0, 0.0), (
                f"the world shader ({node.bl_label}) is not a plain Background; Prism's background is black")
        return (0.0, 0.0, 0.0), None
    return tuple(max(0.0, c) for c in world.color[:3]), None


def _view(m):
    """(position, look_at, up) of a camera's world matrix, +Y up."""
    position = m.translation
    forward = (m.to_3x3() @ _vec(0.0, 0.0, -1.0)).normalized()
    up = (m.to_3x3() @ _vec(0.0, 1.0, 0.0)).normalized()
    return to_y_up(position), to_y_up(position + forward), to_y_up(up)


def camera_table(cam_obj, width, height, pixel_aspect, motion=None):
    """`[camera]` for Blender's active camera: position, look_at, up and the
    field of view along the axis Blender fits the sensor to; with
    `motion` (the shutter's camera poses, times in frames from this
    frame) each keyed at the shutter's instants, the opening as Prism's
    frame 0. Returns the lines and a list of notes for what Prism cannot show."""
    notes = []
    cam = cam_obj.data
    # The sensor fits the wider side of the (pixel-aspect-corrected) frame
    # under AUTO; HORIZONTAL and VERTICAL say which side.
    wide = width * pixel_aspect[0] >= height * pixel_aspect[1]
    if cam.sensor_fit == "VERTICAL":
        axis, sensor = "vertical", cam.sensor_height
    elif cam.sensor_fit == "HORIZONTAL":
        axis, sensor = "horizontal", cam.sensor_width
    else:
        axis, sensor = ("horizontal" if wide else "vertical"), cam.sensor_width
    lines = ["[camera]"]
    view_height = None
    if cam.type == "PERSP":
        fov = math.degrees(2.0 * math.atan(sensor / (2.0 * cam.lens)))
        lines.append('type = "perspective"')
        lines.append(f"fov = {toml_number(fov)}")
        lines.append(f'fov_axis = "{axis}"')
    elif cam.type == "ORTHO":
        # ortho_scale spans the fitted axis; Prism takes the height.
        view_height = cam.ortho_scale if axis == "vertical" else cam.ortho_scale * height / width
        lines.append('type = "orthographic"')
        lines.append(f"view_height = {toml_number(view_height)}")
    else:
        raise ValueError(
            f"camera '{cam_obj.name}' is panoramic; Prism has perspective and orthographic cameras only")
    if motion is None:
        views = [(0.0, _view(cam_obj.matrix_world))]
    else:
        t0 = motion["times"][0]
        views = [(t - t0, _view(m)) for t, m in zip(motion["instants"], motion["camera"])]
    for i, key in enumerate(("position", "look_at", "up")):
        if len(views) == 1:
            lines.append(f"{key} = {toml_vector(views[0][1][i])}")
        else:
            keys = ", ".join(f"{{ frame = {toml_number(t)}, value = {toml_vector(v[i])} }}"
                             for t, v in views)
            lines.append(f"{key} = [{keys}]")
    lines += lens_lines(cam_obj, notes)
    if HAS_SHIFT and (cam.shift_x != 0.0 or cam.shift_y != 0.0):
        # Blender shifts by its fitted side (the fov axis above); Prism's
        # orthographic shift is in view heights.
        scale = 1.0 if cam.type == "PERSP" else cam.ortho_scale / view_height
        lines.append(f"shift = {toml_vector((cam.shift_x * scale, cam.shift_y * scale))}")
    elif cam.shift_x != 0.0 or cam.shift_y != 0.0:
        notes.append(f"camera '{cam_obj.name}': lens shift is ignored (this prism has none)")
    if tuple(pixel_aspect) != (1.0, 1.0):
        notes.append("a pixel aspect other than 1:1 is ignored")
    return lines, notes


def lens_lines(cam_obj, notes):
    """Depth of field as Prism's thin lens: Cycles' aperture radius,
    focal length / (2 · f-stop) with the focal length in metres (Blender's
    unit is the metre), and for an orthographic camera 1 / (2 · f-stop),
    as Cycles takes it; the focus distance along the view axis, to the
    focus object's origin when there is one (as Cycles measures it).
    Polygonal bokeh (blades) and an aperture ratio are noted, not carried."""
    cam = cam_obj.data
    dof = cam.dof
    if not dof.use_dof:
        return []
    fstop = max(dof.aperture_fstop, 1e-5)
    radius = 1.0 / (2.0 * fstop) if cam.type == "ORTHO" else cam.lens * 1e-3 / (2.0 * fstop)
    if dof.focus_object is not None:
        m = cam_obj.matrix_world
        forward = (m.to_3x3() @ _vec(0.0, 0.0, -1.0)).normalized()
        target = dof.focus_object.matrix_world.translation
        distance = abs(forward.dot(target - m.translation))
    else:
        distance = dof.focus_distance
    if distance <= 0.0:
        notes.append(f"camera '{cam_obj.name}': a focus distance of 0 is a pinhole (everything sharp)")
        return []
    if dof.aperture_blades >= 3:
        notes.append(f"camera '{cam_obj.name}': the aperture's {dof.aperture_blades} blades are not "
                     "carried; Prism's lens is round")
    if abs(dof.aperture_ratio - 1.0) > 1e-6:
        notes.append(f"camera '{cam_obj.name}': an aperture ratio other than 1 is not carried")
    return [f"aperture = {toml_number(radius)}",
            f"focus_distance = {toml_number(distance)}"]


def _same(a, b):
    return all(abs(x - y) <= 1e-9 * (1.0 + abs(x)) for x, y in zip(a, b))


def _vec(*c):
    from mathutils import Vector
    return Vector(c)


def light_tables(depsgraph, everything=True):
    """Blender's lights as scene-file lights. With `everything` ("Lights:
    Scene File", the .glb then has none) every light, a light with a
    radius (`shadow_soft_size`) as a sphere light for soft shadows;
    otherwise ("Lights: glTF File") only what glTF cannot carry as Cycles
    means it: area lights, and spot lights with Cycles' cone (the .glb's
    spots are dropped, see drop_gltf_spots). Intensities in the scene
    file's Whitted units, matched to Cycles on a glTF material's diffuse
    surface: a point light of P watts gives radiance albedo/π · P/(4π d²),
    a sun of E W/m² albedo/π · E. Returns (lines, notes); the lights
    Prism cannot render are named in one note."""
    lines, notes, names, skipped = [], [], {}, []
    over_pi = 1.0 if GLTF_DIFFUSE_OVER_PI else 1.0 / math.pi
    for inst in depsgraph.object_instances:
        obj = inst.object
        if obj.type != "LIGHT":
            continue
        light = obj.data
        if not everything and light.type not in {"AREA", "SPOT"}:
            if light.type == "SUN" and light.angle > 0:
                notes.append(f"light '{obj.name}': a sun's angle is not carried (Prism has no "
                             "soft directional light); hard shadows")
            continue
        # Instanced lights share a name; a scene-file table may not.
        count = names[obj.name] = names.get(obj.name, 0) + 1
        name = toml_string(obj.name if count == 1 else f"{obj.name} {count}")
        m = inst.matrix_world
        colour = toml_vector(light.color)
        if light.type in {"POINT", "SPOT"}:
            # Prism's spot is a point: a spot keeps its cone (the pool's
            # shape) and loses its radius (soft shadows), noted.
            spot = light.type == "SPOT"
            r = light.shadow_soft_size if everything and not spot else 0.0
            if spot and light.shadow_soft_size > 0:
                notes.append(f"light '{obj.name}': a spot's radius is not carried (Prism's spot "
                             "is a point); hard shadows")
            kind = "spot" if spot else ("sphere" if r > 0 else "point")
            lines += [f"[lights.{name}]",
                      f'type = "{kind}"',
                      f"position = {toml_vector(to_y_up(m.translation))}"]
            if r > 0:
                lines.append(f"radius = {toml_number(r)}")
            if spot:
                inner, outer = cycles_spot_cone(light.spot_size, light.spot_blend)
                axis = (m.to_3x3() @ _vec(0.0, 0.0, -1.0)).normalized()
                lines += [f"direction = {toml_vector(to_y_up(axis))}",
                          f"inner_angle = {toml_number(math.degrees(inner))}",
                          f"outer_angle = {toml_number(math.degrees(outer))}",
                          'cone_falloff = "cycles"']
            lines += [f"color = {colour}",
                      f"intensity = {toml_number(light.energy / (4.0 * math.pi) * over_pi)}",
                      'falloff = "inverse_square"', ""]
        elif light.type == "SUN":
            d = (m.to_3x3() @ _vec(0.0, 0.0, -1.0)).normalized()
            lines += [f"[lights.{name}]", 'type = "directional"',
                      f"direction = {toml_vector(to_y_up(d))}",
                      f"color = {colour}",
                      f"intensity = {toml_number(light.energy * over_pi)}", ""]
            if light.angle > 0:
                notes.append(f"light '{obj.name}': a sun's angle is not carried (Prism has no "
                             "soft directional light); hard shadows")
        elif light.type == "AREA":
            area_lines, area_notes = area_light_table(obj.name, name, light, m)
            if not area_lines:
                skipped.append(f"'{obj.name}' (an area light of size 0)")
            lines += area_lines
            notes += area_notes
        else:
            skipped.append(f"'{obj.name}' ({light.type.lower()})")
    if skipped:
        notes.append("lights Prism cannot render, skipped: " + ", ".join(skipped))
    return lines, notes


def cycles_spot_cone(size, blend):
    """Blender's spot of `size` (the cone's full angle) and `blend` as the
    scene file's cone with `cone_falloff = "cycles"`: (inner, outer)
    half-angles in radians. Cycles lights cos θ · smoothstep((cos θ −
    cos(size/2)) / spot_smooth), spot_smooth = (1 − cos(size/2))·blend,
    so the band ends (the inner cone) where cos θ = cos(size/2) + spot_smooth."""
    outer = 0.5 * size
    cos_outer = math.cos(outer)
    cos_inner = min(1.0, cos_outer + (1.0 - cos_outer) * max(0.0, blend))
    return math.acos(cos_inner), outer


def drop_gltf_spots(glb_path):
    """Removes the spot lights from the exported .glb ("Lights: glTF
    File"): the scene file carries them with Cycles' cone instead of
    glTF's. Returns how many were dropped."""
    from . import glb
    doc, binary = glb.read(glb_path)
    dropped = glb.remove_lights(doc, lambda light: light.get("type") != "spot")
    if dropped:
        glb.write(glb_path, doc, binary)
    return dropped


def area_light_table(label, name, light, m):
    """An area light as the scene file's rectangle or disk light (an
    ellipse as the disk of the same area, noted). Cycles renders an area
    light of P watts as a one-sided Lambertian emitter of radiance
    P / (4·A) (A its area) towards its local −Z: measured by the probes
    (P / (π·A), a flux of P, comes out 4/π too bright). Over glTF's
    materials (diffuse base colour / π) that is the scene file's
    `intensity` as it stands."""
    notes = []
    rot = m.to_3x3()
    sx, sy, _ = m.to_scale()
    x_axis = (rot @ _vec(1.0, 0.0, 0.0)).normalized()
    y_axis = (rot @ _vec(0.0, 1.0, 0.0)).normalized()
    down = (rot @ _vec(0.0, 0.0, -1.0)).normalized()
    size_x = light.size * sx
    size_y = (light.size_y if light.shape in {"RECTANGLE", "ELLIPSE"} else light.size) * sy
    lines = [f"[lights.{name}]"]
    if light.shape in {"SQUARE", "RECTANGLE"}:
        area = size_x * size_y
        # edge_u × edge_v must point the way it emits: x × (−y) = −z.
        lines += ['type = "rectangle"',
                  f"edge_u = {toml_vector(to_y_up(x_axis * size_x))}",
                  f"edge_v = {toml_vector(to_y_up(-y_axis * size_y))}"]
    else:
        if light.shape == "ELLIPSE" and abs(size_x - size_y) > 1e-9 * max(size_x, size_y):
            notes.append(f"light '{label}': an ellipse is rendered as the disk of the same area")
        radius = 0.5 * math.sqrt(size_x * size_y)
        area = math.pi * radius * radius
        lines += ['type = "disk"',
                  f"normal = {toml_vector(to_y_up(down))}",
                  f"radius = {toml_number(radius)}"]
    spread = getattr(light, "spread", math.pi)
    if spread < math.pi - 1e-6:
        notes.append(f"light '{label}': a spread below 180° is not carried; it emits as a Lambertian area")
    if area <= 0.0:
        return [], []
    over_pi = 1.0 if GLTF_DIFFUSE_OVER_PI else 1.0 / math.pi
    lines += [f"position = {toml_vector(to_y_up(m.translation))}",
              f"color = {toml_vector(light.color)}",
              f"intensity = {toml_number(light.energy / (4.0 * area) * over_pi)}",
              "samples = 16", ""]
    return lines, notes


def fps(render):
    """Blender's frames per second (render.fps / render.fps_base)."""
    return render.fps / render.fps_base


def scene_toml(depsgraph, glb_name, settings, motion=None):
    """The whole scene file; `settings` is the scene's PrismSettings;
    `motion` the shutter's poses with motion blur on (the add-on's
    shutter_poses), else None. Returns (text, notes)."""
    scene = depsgraph.scene
    render = scene.render
    width, height = image_size(render)
    notes = []
    if scene.camera is None:
        raise ValueError("the scene has no active camera")
    background, note = world_colour(scene.world)
    if note:
        notes.append(note)
    ambient = tuple(c * settings.ambient_from_world for c in background)
    lines = [
        # Escaped: a comment may not hold control characters either.
        f"# Written by the Prism add-on for Blender {_blender_version()} from {toml_string(scene.name)}.",
        f"# Render it again: prism render {_name_hint()} -o image.png",
        "",
        "[render]",
        f"width = {width}",
        f"height = {height}",
        f"spp = {int(settings.spp)}",
        f"max_depth = {int(settings.max_depth)}",
        f"background = {toml_vector(background)}",
        f"ambient = {toml_vector(ambient)}",
    ]
    if HAS_EXPOSURE:
        lines.append(f"exposure = {toml_number(scene.view_settings.exposure)}")
    elif scene.view_settings.exposure != 0.0:
        notes.append("Prism's scene file has no exposure yet; Blender applies its exposure to the render it shows")
    camera_motion = None
    animation = []
    if render.use_motion_blur and motion is not None:
        # The camera's motion is Prism's shutter over keyed camera values,
        # the objects' a glTF animation in the .glb (motion.py), both with
        # the shutter's opening as Prism's frame 0 and Blender's fps.
        t0, t1 = motion["times"]
        views = [_view(m) for m in motion["camera"]]
        if t1 > t0 and not all(_same(a, b) for v in views[1:] for a, b in zip(views[0], v)):
            camera_motion = motion
        if t1 > t0 and (camera_motion or motion.get("carried")):
            lines.append(f"shutter = [0, {toml_number(t1 - t0)}]")
            animation = ["[animation]", "frames = 1", f"fps = {toml_number(fps(render))}", ""]
        if motion.get("deforming"):
            names = ", ".join(f"'{n}'" for n in motion["deforming"][:8])
            more = f" and {len(motion['deforming']) - 8} more" if len(motion["deforming"]) > 8 else ""
            notes.append("motion blur: objects whose shape changes while the shutter is open "
                         "(armatures, shape keys, animated modifiers) keep one shape in Prism; "
                         f"only their movement as a whole is blurred: {names}{more}")
    elif render.use_motion_blur:
        notes.append("motion blur is not carried: the scene file holds the glTF export of one "
                     f"instant (frame {scene.frame_current}); rendered sharp")
    lines.append("")
    lines += animation
    cam_lines, cam_notes = camera_table(
        scene.camera, width, height, (render.pixel_aspect_x, render.pixel_aspect_y), camera_motion)
    lines += cam_lines + [""]
    notes += cam_notes
    # glTF has no area light and another spot cone: with "Lights: glTF
    # File" those come through the scene file too.
    light_lines, light_notes = light_tables(depsgraph, everything=settings.lights == "SCENE")
    lines += light_lines
    notes += light_notes
    if settings.lights != "SCENE" and any(
            o.type == "LIGHT" and o.data.type == "POINT" and o.data.shadow_soft_size > 0
            for o in scene.objects):
        notes.append("point lights' radii (soft shadows) are carried with Lights: Scene File; "
                     "hard shadows")
    lines += [
        "[[objects]]",
        'type = "mesh"',
        f"name = {toml_string(scene.name)}",
        f"file = {toml_string(glb_name)}",
    ]
    return "\n".join(lines) + "\n", notes


def _blender_version():
    import bpy
    return bpy.app.version_string


def _name_hint():
    return "scene.toml"
