"""The render's geometry for the glTF exporter.

Blender's glTF exporter evaluates the scene through the viewport's
depsgraph (`context.evaluated_depsgraph_get()`), so it sees modifiers at
their viewport levels and objects hidden in the viewport not at all. F12
renders the render depsgraph: modifiers enabled for renders, subdivision
at render levels, what is hidden from renders left out. While the export
runs, `render_levels` gives the viewport the render's settings, and puts
every one back afterwards, whatever happens.

What is covered: each modifier's viewport switch (`show_viewport` from
`show_render`), Subdivision Surface and Multiresolution levels
(`levels` from `render_levels`), curve and text resolution
(`resolution_u` from `render_resolution_u` where that is set), metaball
resolution, objects and collections hidden in the viewport but not in
renders, and the scene's Simplify (`simplify_subdivision` from
`simplify_subdivision_render`). Geometry nodes that ask "Is Viewport"
still see the viewport.
"""

import contextlib


@contextlib.contextmanager
def render_levels(scene, view_layer):
    saved = []  # (owner, attribute, old value), put back in reverse order

    def set_(owner, attribute, value):
        old = getattr(owner, attribute)
        if old != value:
            try:
                setattr(owner, attribute, value)
            except (AttributeError, RuntimeError, TypeError):
                return  # linked from a library (read-only): left as the viewport has it
            saved.append((owner, attribute, old))

    try:
        if scene.render.use_simplify:
            set_(scene.render, "simplify_subdivision", scene.render.simplify_subdivision_render)
        for collection in _collections(scene.collection):
            set_(collection, "hide_viewport", collection.hide_render)
        for obj in scene.objects:
            if obj.hide_viewport and not obj.hide_render:
                set_(obj, "hide_viewport", False)
            for modifier in getattr(obj, "modifiers", ()):
                set_(modifier, "show_viewport", modifier.show_render)
                if modifier.type in {"SUBSURF", "MULTIRES"}:
                    set_(modifier, "levels", modifier.render_levels)
            data = obj.data
            if obj.type in {"CURVE", "FONT", "SURFACE"} and data.render_resolution_u > 0:
                set_(data, "resolution_u", data.render_resolution_u)
            if obj.type == "SURFACE" and data.render_resolution_v > 0:
                set_(data, "resolution_v", data.render_resolution_v)
            if obj.type == "META" and data.render_resolution > 0:
                set_(data, "resolution", data.render_resolution)
        view_layer.update()
        yield
    finally:
        for owner, attribute, old in reversed(saved):
            try:
                setattr(owner, attribute, old)
            except (AttributeError, ReferenceError, TypeError):
                pass  # the owner is gone (the export removed it); nothing to restore
        if saved:
            view_layer.update()


def _collections(root):
    """Every collection under `root` (the scene's master collection has
    no visibility switches of its own)."""
    seen, stack = set(), list(root.children)
    while stack:
        c = stack.pop()
        if c.name_full in seen:
            continue
        seen.add(c.name_full)
        yield c
        stack.extend(c.children)
