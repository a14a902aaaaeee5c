"""F12 as in Blender's interface (run under a display, e.g. xvfb-run):
the render job's thread runs the add-on, as it does for a user. Starts
render.render('INVOKE_DEFAULT') from a timer, saves the Render Result to
OUT when the job completes, then quits.
Run: blender SCENE --python use_addon.py --python ui_render.py -- ZIP PRISM DIR SPP OUT"""

import sys

import bpy

out = sys.argv[sys.argv.index("--") + 1:][4]
state = {"done": None}


def finished(kind):
    def handler(*_):
        state["done"] = kind
    return handler


bpy.app.handlers.render_complete.append(finished("complete"))
bpy.app.handlers.render_cancel.append(finished("cancel"))


def start():
    window = bpy.context.window_manager.windows[0]
    bpy.context.scene.render.engine = "PRISM"
    with bpy.context.temp_override(window=window):
        print("ui_render: F12:", bpy.ops.render.render("INVOKE_DEFAULT"))
    bpy.app.timers.register(wait, first_interval=0.5)


def wait():
    if state["done"] is None:
        return 0.5
    image = bpy.data.images.get("Render Result")
    if state["done"] == "complete" and image is not None:
        image.save_render(out)
        print(f"ui_render: {state['done']}; saved {out}")
    else:
        print(f"ui_render: FAIL: {state['done']}")
    bpy.ops.wm.quit_blender()
    return None


bpy.app.timers.register(start, first_interval=1.0)
