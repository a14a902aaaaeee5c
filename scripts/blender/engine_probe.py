"""The add-on's engine beyond a plain render, in the opened scene after
use_addon.py: (1) cancel: a slow render is stopped once tiles have been
shown, and it returns at once with nothing written; (2) errors: Prism's
refusal (a width over its limit) reaches Blender's reports with the scene
file's line and column.
Run: blender -b SCENE --python use_addon.py --python engine_probe.py -- ZIP PRISM DIR SPP"""

import os
import sys
import time

import bpy
import prism_render

export_dir = sys.argv[sys.argv.index("--") + 1:][2]
engine = prism_render.PrismRenderEngine
shown, reports = [], []
stop = [False]

# Blender's own engine methods cannot be wrapped from Python; the add-on's
# are: tiles shown, the stop signal, and the errors it reports.
real_poll = prism_render.tiles.TileWatcher.poll


def poll(self, engine_):
    real_poll(self, engine_)
    shown[:] = sorted(self.seen)


prism_render.tiles.TileWatcher.poll = poll
real_render = prism_render.runner.render
prism_render.runner.render = lambda command, progress, should_stop, **kw: real_render(
    command, progress, lambda: should_stop() or (stop[0] and len(shown) >= 1), **kw)
real_fail = engine._fail


def fail(self, message):
    # One line, or Prism's error lines as a list.
    reports.extend([message] if isinstance(message, str) else message)
    real_fail(self, message)


engine._fail = fail
stop[0] = True
scene = bpy.context.scene
scene.render.engine = "PRISM"
scene.render.resolution_x, scene.render.resolution_y = 320, 240
scene.prism.spp = 1024
# Names are text in the scene file: quotes, backslashes, control
# characters, DEL and non-ASCII must come through (Prism parses it before
# the first tile); the light goes there with Lights: Scene File.
scene.name = 'a "scene"\\ with\tall\x7f kinds ☃ \U0001F600\nof name'
bpy.data.objects["point light"].name = 'a "light" \x01 ☃'
scene.prism.lights = "SCENE"
start = time.monotonic()
bpy.ops.render.render()
took = time.monotonic() - start
failures = []
if not shown or len(shown) >= (320 // 16) * (240 // 16):
    failures.append(f"cancel: expected some of the tiles shown, got {len(shown)}")
if os.path.exists(os.path.join(export_dir, "render.exr")):
    failures.append("cancel: prism wrote an image")
print(f"engine_probe: cancel after {len(shown)} tile(s) in {took:.1f} s")

shown.clear()
stop[0] = False
scene.render.resolution_x = 40000  # over Prism's limit of 32768
scene.prism.spp = 1
try:
    bpy.ops.render.render()
    failures.append("error: the render operator did not fail")
except RuntimeError as e:  # the engine's error_set, as the operator raises it
    print(f"engine_probe: the operator failed with: {e}")
errors = reports
print("engine_probe: reported " + " | ".join(errors))
if not any("scene.toml:" in m and "width" in m for m in errors):
    failures.append(f"error: no report naming scene.toml's width: {reports}")
if shown:
    failures.append(f"error: a result was shown: {shown}")
for f in failures:
    print(f"engine_probe: FAIL: {f}")
sys.exit(1 if failures else 0)
