"""Installs the add-on zip the way a user does (into BLENDER_USER_SCRIPTS),
enables it, points it at the prism binary and keeps the exported files in
EXPORT_DIR; the render output is a 32-bit float EXR. Blender's arguments
after this script then render with it, e.g.
  blender -b FILE --python use_addon.py -E PRISM -o OUT_# -f 1 -- ZIP PRISM EXPORT_DIR SPP [- LIGHTS]
with LIGHTS the add-on's Lights setting, GLTF (default) or SCENE.
"""

import sys

import addon_utils
import bpy

args = sys.argv[sys.argv.index("--") + 1:]
zip_path, prism, export_dir, spp = args[:4]
lights = args[5] if len(args) > 5 else "GLTF"  # args[4]: other scripts' use
bpy.ops.preferences.addon_install(filepath=zip_path, overwrite=True)
addon_utils.enable("prism_render", default_set=True, handle_error=None)
bpy.context.preferences.addons["prism_render"].preferences.prism_path = prism
for scene in bpy.data.scenes:
    scene.prism.export_dir = export_dir
    scene.prism.spp = int(spp)
    scene.prism.lights = lights
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
