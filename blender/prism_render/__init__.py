"""Prism as a Blender render engine: F12 exports the scene with Blender's
own glTF exporter, writes a scene file beside it for what glTF cannot
carry, runs the `prism` command and loads its EXR into the render result.
See docs/blender.md in the Prism repository."""

bl_info = {
    "name": "Prism Render Engine",
    "author": "The Prism authors",
    "version": (0, 1, 0),
    "blender": (3, 4, 0),
    "location": "Properties > Render > Render Engine > Prism",
    "description": "Render with Prism, a Whitted-style ray tracer, through a glTF export",
    "category": "Render",
}

import math
import os
import shutil
import tempfile
import threading

import bpy

from . import materials, motion as object_motion, runner, scene_file, tiles
from .render_levels import render_levels
from .text import escape_controls, report_lines

ENGINE = "PRISM"


def _prefs(context):
    addon = context.preferences.addons.get(__package__)
    return addon.preferences if addon else None


class PrismPreferences(bpy.types.AddonPreferences):
    bl_idname = __package__

    prism_path: bpy.props.StringProperty(
        name="Prism command",
        description="The prism program: a path, or a name looked up on PATH",
        default="prism",
        subtype="FILE_PATH",
    )

    def draw(self, context):
        self.layout.prop(self, "prism_path")


class PrismSettings(bpy.types.PropertyGroup):
    spp: bpy.props.IntProperty(
        name="Samples", description="Samples per pixel (anti-aliasing and soft shadows)",
        default=4, min=1, max=65536)
    max_depth: bpy.props.IntProperty(
        name="Max Depth", description="Longest ray path counting the camera ray",
        default=8, min=1, max=256)
    ambient_from_world: bpy.props.FloatProperty(
        name="Ambient from World",
        description="Whitted's ambient light Ia as this multiple of the world colour "
                    "(glTF materials have ka = 0.1)",
        default=1.0, min=0.0, soft_max=20.0)
    lights: bpy.props.EnumProperty(
        name="Lights",
        description="Where Prism takes Blender's lights from",
        items=[
            ("GLTF", "glTF File",
             "KHR_lights_punctual in the exported .glb, in the specification's units (as "
             "`prism render` of any export reads them); hard shadows"),
            ("SCENE", "Scene File",
             "Written to scene.toml by the add-on, matched to Cycles on diffuse surfaces; "
             "a light's radius makes a sphere light (soft shadows); the .glb has no lights"),
        ],
        default="GLTF")
    export_dir: bpy.props.StringProperty(
        name="Keep Files In",
        description="Folder for scene.glb, scene.toml and render.exr, kept after the render "
                    "(render them again with `prism render scene.toml`); empty: a temporary folder. "
                    "A relative folder needs a saved .blend",
        default="", subtype="DIR_PATH")


class PrismRenderEngine(bpy.types.RenderEngine):
    bl_idname = ENGINE
    bl_label = "Prism"
    bl_use_preview = False
    # Blender's own material, light and world settings are what the glTF
    # exporter reads.
    bl_use_shading_nodes_custom = False

    def render(self, depsgraph):
        scene = depsgraph.scene
        settings = scene.prism
        prefs = _prefs(bpy.context)
        prism = (prefs.prism_path if prefs else "") or "prism"
        if os.sep in prism or (os.altsep and os.altsep in prism):
            prism = bpy.path.abspath(prism)
        width, height = scene_file.image_size(scene.render)
        keep = bool(settings.export_dir.strip())
        if keep:
            folder = bpy.path.abspath(settings.export_dir)
            # A relative folder is relative to the .blend; an unsaved file
            # has none, and the working directory is nobody's choice.
            if not bpy.data.filepath and (settings.export_dir.startswith("//")
                                          or not os.path.isabs(folder)):
                return self._fail(
                    f"Keep Files In ({settings.export_dir}) is relative to the .blend file, "
                    "which is not saved yet: save it, or give an absolute folder")
            try:
                os.makedirs(folder, exist_ok=True)
            except OSError as e:
                return self._fail(f"cannot make {folder}: {e}")
        else:
            folder = tempfile.mkdtemp(prefix="prism-blender-")
        try:
            self._render_in(depsgraph, folder, prism, width, height)
        finally:
            if not keep:
                shutil.rmtree(folder, ignore_errors=True)

    def _render_in(self, depsgraph, folder, prism, width, height):
        scene = depsgraph.scene
        glb = os.path.join(folder, "scene.glb")
        toml = os.path.join(folder, "scene.toml")
        exr = os.path.join(folder, "render.exr")
        self.update_stats("", "Prism: exporting glTF")
        try:
            motion = export_on_main_thread(self, scene, glb, depsgraph.view_layer,
                                           lights=scene.prism.lights == "GLTF")
        except Cancelled:
            return
        except Exception as e:  # the exporter's own failure, whatever it is
            return self._fail(f"the glTF export failed: {e}")
        try:
            if scene.prism.lights == "GLTF":
                # The scene file carries spots with Cycles' cone.
                scene_file.drop_gltf_spots(glb)
            # Checker textures the exporter drops, and what else it drops.
            material_notes = materials.carry(glb, depsgraph)
            # Objects moving during the shutter: a glTF animation in the .glb.
            motion_notes = []
            if motion is not None and motion["times"][1] > motion["times"][0]:
                motion["carried"], motion_notes = object_motion.carry(
                    glb, motion, scene_file.fps(scene.render))
            text, notes = scene_file.scene_toml(depsgraph, "scene.glb", scene.prism, motion)
            notes += motion_notes + material_notes
        except (OSError, ValueError) as e:
            return self._fail(str(e))
        for note in notes:
            self.report({"WARNING"}, f"Prism: {escape_controls(note)}")
        try:
            with open(toml, "w", encoding="utf-8") as f:
                f.write(text)
            if os.path.exists(exr):
                os.remove(exr)  # a stale image is never loaded
        except OSError as e:
            return self._fail(f"cannot write in {folder}: {e}")
        # Prism saves each finished tile here; they are shown as they come.
        tile_dir = os.path.join(folder, "tiles")
        shutil.rmtree(tile_dir, ignore_errors=True)
        command = [prism, "render", toml, "-o", exr, "--checkpoint", tile_dir]
        # A render border: Blender's result is the border alone, and Prism
        # renders it alone (its EXR's data window is the border).
        crop = scene_file.border(scene.render, width, height)
        if crop is not None:
            command += ["--crop", ",".join(str(c) for c in crop)]
        x0, x1, y0, y1 = crop or (0, width, 0, height)
        if scene.render.threads_mode == "FIXED":
            command += ["--threads", str(scene.render.threads)]
        self.update_stats("", "Prism: rendering")
        watcher = tiles.TileWatcher(tile_dir, (x0, y1), depsgraph.view_layer.name)
        outcome = runner.render(command, self.update_progress, self.test_break,
                                on_poll=lambda: watcher.poll(self))
        shutil.rmtree(tile_dir, ignore_errors=True)
        for w in outcome.warnings:
            self.report({"WARNING"}, f"Prism: {escape_controls(w)}")
        if outcome.cancelled:
            return
        if outcome.errors:
            return self._fail(outcome.errors)
        # Blender calls render() once per view layer; the image is that layer's.
        result = self.begin_result(0, 0, x1 - x0, y1 - y0, layer=depsgraph.view_layer.name)
        try:
            result.layers[0].load_from_file(exr)
        except RuntimeError as e:
            self.end_result(result, cancel=True)
            return self._fail(f"cannot load {exr}: {e}")
        self.end_result(result)
        self.update_progress(1.0)

    def _fail(self, message):
        """Reports `message` (one line, or Prism's error lines as a list).

        Names from the scene and paths reach these lines: each is escaped
        whole, so a name's newline cannot make a report line of its own."""
        lines = report_lines(message)
        for line in lines:
            self.report({"ERROR"}, f"Prism: {line}")
        self.error_set(f"Prism: {lines[0] if lines and lines[0] else 'failed'}")


class Cancelled(Exception):
    pass


def export_on_main_thread(engine, scene, path, view_layer, lights=True):
    """The exporter is an operator and needs Blender's main thread; F12 in
    the interface renders on a job thread. There the export is handed to
    a timer (timers run on the main thread, whose event loop goes on during
    a render) and this thread waits for it, or for Esc. Returns the
    shutter's poses (see shutter_poses), found there too."""
    if threading.current_thread() is threading.main_thread():
        return export_gltf(scene, path, view_layer, lights)
    done = threading.Event()
    outcome = {}
    frame = scene.frame_current

    def run():
        try:
            if scene.frame_current != frame:
                scene.frame_set(frame)
            outcome["motion"] = export_gltf(scene, path, view_layer, lights)
        except Exception as e:  # handed to the render thread
            outcome["error"] = e
        done.set()
        return None

    bpy.app.timers.register(run, first_interval=0.0)
    while not done.wait(0.1):
        if engine.test_break():
            bpy.app.timers.is_registered(run) and bpy.app.timers.unregister(run)
            raise Cancelled()
    if "error" in outcome:
        raise outcome["error"]
    return outcome.get("motion")


# Instants the shutter's motion is keyed at (open, between, close): enough
# for rotations and curved paths to follow; Prism interpolates between them.
SHUTTER_KEYS = 5


def shutter_poses(scene):
    """With motion blur on, the scene at SHUTTER_KEYS instants across the
    shutter (Blender's motion_blur_position: the frame starts, centres or
    ends the exposure of motion_blur_shutter frames), as frame offsets from
    this frame: the active camera's world matrix at each, the other
    objects' at each and at this frame (what the export holds), the names
    of those whose world matrix differs across the shutter ("moving"), and
    of the meshes whose evaluated geometry changes ("deforming": armatures,
    shape keys, modifiers; their deformation is not carried). None without
    motion blur. The scene is put back at its frame. Main thread only
    (frame_set evaluates the scene)."""
    render = scene.render
    if not render.use_motion_blur or scene.camera is None:
        return None
    length = max(0.0, render.motion_blur_shutter)
    # Blender 3.x keeps the position in Cycles' settings, later versions in render's.
    position = getattr(render, "motion_blur_position", None) \
        or getattr(getattr(scene, "cycles", None), "motion_blur_position", "CENTER")
    start = {"START": 0.0, "END": -length}.get(position, -0.5 * length)
    instants = [start + length * k / (SHUTTER_KEYS - 1) for k in range(SHUTTER_KEYS)]
    frame, subframe = scene.frame_current, scene.frame_subframe
    # Evaluated first: an object render_levels has just shown (hidden in
    # viewports) has no world matrix of this frame until then.
    scene.frame_set(frame, subframe=subframe)
    # What the export holds (objects F12 does not render are not there).
    others = [o for o in scene.objects if o != scene.camera and not o.hide_render
              and o.type not in ("SPEAKER", "LIGHT_PROBE")]
    objects = {o.name: {"kind": o.type, "now": o.matrix_world.copy(), "at": []} for o in others}
    # Meshes that could deform: a modifier or shape keys (geometry is
    # compared at the shutter's ends for these only).
    may_deform = [o for o in others if o.type == "MESH"
                  and (len(o.modifiers) or getattr(o.data, "shape_keys", None))]
    shapes = {}
    cameras = []
    try:
        for k, t in enumerate(instants):
            whole = math.floor(frame + t)
            scene.frame_set(int(whole), subframe=frame + t - whole)
            cameras.append(scene.camera.matrix_world.copy())
            for o in others:
                objects[o.name]["at"].append(o.matrix_world.copy())
            if k in (0, len(instants) - 1) and may_deform:
                depsgraph = bpy.context.evaluated_depsgraph_get()
                for o in may_deform:
                    shapes.setdefault(o.name, []).append(_geometry(o, depsgraph))
    finally:
        scene.frame_set(frame, subframe=subframe)
    moving = sorted(name for name, o in objects.items()
                    if not all(_same_matrix(o["at"][0], m) for m in o["at"][1:]))
    deforming = sorted(name for name, (a, b) in shapes.items() if a != b)
    return {"times": (start, start + length), "instants": instants, "camera": cameras,
            "objects": objects, "moving": moving, "deforming": deforming}


def _geometry(obj, depsgraph):
    """The evaluated mesh's vertex coordinates in its own space, rounded
    (a deformation, not rounding, should tell two apart)."""
    evaluated = obj.evaluated_get(depsgraph)
    mesh = evaluated.to_mesh()
    try:
        coords = [0.0] * (3 * len(mesh.vertices))
        mesh.vertices.foreach_get("co", coords)
        return tuple(round(c, 5) for c in coords)
    finally:
        evaluated.to_mesh_clear()


def _same_matrix(a, b):
    return all(abs(a[i][j] - b[i][j]) <= 1e-9 * (1.0 + abs(a[i][j])) for i in range(4) for j in range(4))


def export_gltf(scene, path, view_layer=None, lights=True):
    """Blender's bundled glTF exporter with the options a render needs;
    options this Blender's exporter lacks are left out. Returns the
    shutter's poses (shutter_poses), taken as the render sees the scene."""
    wanted = {
        "filepath": path,
        "check_existing": False,
        "export_format": "GLB",
        "export_yup": True,            # Prism's world is +Y up, as glTF's
        "export_apply": True,          # modifiers applied
        "export_cameras": True,        # the .glb alone renders too
        "export_lights": lights,       # KHR_lights_punctual
        # Blender 3.6+: the specification's units (W to cd at 683 lm/W), as
        # 3.4 always writes them.
        "export_import_convert_lighting_mode": "SPEC",
        "use_selection": False,
        "use_visible": False,
        "use_renderable": True,        # what F12 renders: not hide_render
        "use_active_scene": True,
        "export_animations": False,
        "export_current_frame": True,  # the frame rendered, not frame 0
        "export_extras": False,
        "export_texcoords": True,
        "export_normals": True,
        "export_materials": "EXPORT",
        "export_image_format": "AUTO",
    }
    known = bpy.ops.export_scene.gltf.get_rna_type().properties.keys()
    options = {k: v for k, v in wanted.items() if k in known}
    # A render has no screen, hence no active object in its context; the
    # exporter reads it, so the context is given the view layer's.
    view_layer = view_layer or scene.view_layers[0]
    active = view_layer.objects.active
    # The exporter also sets its window's scene; a render's context has no
    # window, so the first one is lent (a background render has one too).
    windows = bpy.context.window_manager.windows
    window = bpy.context.window or (windows[0] if len(windows) else None)
    if window is None:
        raise RuntimeError("Blender has no window for the glTF exporter to use")
    # The exporter reads the viewport's depsgraph; a render wants the
    # render's modifier levels and visibility (render_levels.py).
    with render_levels(scene, view_layer):
        # Objects hidden only in viewports move too: poses with them shown.
        motion = shutter_poses(scene)
        with bpy.context.temp_override(
            window=window, scene=scene, view_layer=view_layer, active_object=active, object=active,
            selected_objects=[o for o in view_layer.objects if o.select_get(view_layer=view_layer)],
        ):
            result = bpy.ops.export_scene.gltf(**options)
    if "FINISHED" not in result:
        raise RuntimeError(f"the exporter returned {result}")
    return motion


class RENDER_PT_prism(bpy.types.Panel):
    bl_label = "Prism"
    bl_space_type = "PROPERTIES"
    bl_region_type = "WINDOW"
    bl_context = "render"
    COMPAT_ENGINES = {ENGINE}

    @classmethod
    def poll(cls, context):
        return context.engine in cls.COMPAT_ENGINES

    def draw(self, context):
        layout = self.layout
        layout.use_property_split = True
        settings = context.scene.prism
        layout.prop(settings, "spp")
        layout.prop(settings, "max_depth")
        layout.prop(settings, "ambient_from_world")
        layout.prop(settings, "lights")
        layout.prop(settings, "export_dir")


# Blender's own panels that show what the export reads (lights, materials,
# world, camera); each gains Prism's engine while the add-on is enabled.
PANELS = [
    "RENDER_PT_color_management", "RENDER_PT_color_management_curves",
    "DATA_PT_context_light", "DATA_PT_EEVEE_light", "DATA_PT_EEVEE_light_distance",
    "DATA_PT_light", "DATA_PT_lens", "DATA_PT_camera", "DATA_PT_camera_display",
    "EEVEE_MATERIAL_PT_context_material", "EEVEE_MATERIAL_PT_surface",
    "EEVEE_WORLD_PT_surface", "WORLD_PT_context_world",
]


def _panels():
    return [p for p in (getattr(bpy.types, n, None) for n in PANELS)
            if p is not None and hasattr(p, "COMPAT_ENGINES")]


CLASSES = (PrismPreferences, PrismSettings, PrismRenderEngine, RENDER_PT_prism)


def register():
    for c in CLASSES:
        bpy.utils.register_class(c)
    bpy.types.Scene.prism = bpy.props.PointerProperty(type=PrismSettings)
    for p in _panels():
        p.COMPAT_ENGINES.add(ENGINE)


def unregister():
    for p in _panels():
        p.COMPAT_ENGINES.discard(ENGINE)
    del bpy.types.Scene.prism
    for c in reversed(CLASSES):
        bpy.utils.unregister_class(c)
