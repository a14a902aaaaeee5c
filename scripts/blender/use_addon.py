"""Checks that the add-on is installed and enabled the headless way
docs/blender.md gives (scripts/test-blender.sh runs that command once,
saving the preferences under its own XDG_CONFIG_HOME), with its preference
prism_path set to PRISM, and keeps the exported files in EXPORT_DIR; the
render output is a 32-bit float EXR. Blender's arguments after this
script then render with it, e.g.
  blender -b FILE --python use_addon.py -E PRISM -o OUT_# -f 1 -- ZIP PRISM EXPORT_DIR SPP [- LIGHTS]
with LIGHTS the add-on's Lights setting, GLTF (default) or SCENE.
"""

import sys

import bpy

args = sys.argv[sys.argv.index("--") + 1:]
zip_path, prism, export_dir, spp = args[:4]
lights = args[5] if len(args) > 5 else "GLTF"  # args[4]: other scripts' use
addon = bpy.context.preferences.addons.get("prism_render")
if addon is None or addon.preferences.prism_path != prism:
    print(f"use_addon: FAIL: the saved preferences do not enable prism_render with prism_path {prism!r}")
    sys.exit(1)
for scene in bpy.data.scenes:
    scene.prism.export_dir = export_dir
    scene.prism.spp = int(spp)
    scene.prism.lights = lights
    scene.render.image_settings.file_format = "OPEN_EXR"
    scene.render.image_settings.color_depth = "32"
    scene.render.image_settings.exr_codec = "ZIP"
