"""Objects' motion blur: the rigid motion of the objects that move while
the shutter is open, written into the exported .glb as a glTF animation
(one LINEAR channel per moving node and property, keyed at the shutter's
instants; rotations slerp between keys), which Prism plays at frame /
fps seconds.

Each node gets its LOCAL translation, rotation and scale in glTF's +Y-up
space at each instant: local = world(parent node)^-1 . world(node), with
world(node) = C . M . C^-1 . K for the node of a moving object (M its
Blender world matrix then, C the exporter's basis change (x, y, z) ->
(x, z, -y), K what the exporter adds under it: the identity for meshes
and empties, a fixed turn for cameras and lights, worked out at the
exported frame), and world(parent) . local as exported for other nodes.
At the exported frame this is the node's exported transform by
construction; a node whose K is not what the exporter is known to write,
or whose local matrix is not translation . rotation . scale (shear, a
mirrored scale that the decomposition cannot keep), is left sharp and
named.
"""

from mathutils import Matrix, Quaternion, Vector

from . import glb

# Relative tolerance for "the same matrix".
TOLERANCE = 1e-5


def _basis():
    return Matrix(((1, 0, 0, 0), (0, 0, 1, 0), (0, -1, 0, 0), (0, 0, 0, 1)))


def _close(a, b, tol=TOLERANCE):
    scale = max(1.0, max(abs(a[i][j]) for i in range(4) for j in range(4)))
    return all(abs(a[i][j] - b[i][j]) <= tol * scale for i in range(4) for j in range(4))


def _trs(node):
    """The node's exported local matrix."""
    if "matrix" in node:
        m = node["matrix"]
        return Matrix([[m[c * 4 + r] for c in range(4)] for r in range(4)])
    t = node.get("translation", (0.0, 0.0, 0.0))
    x, y, z, w = node.get("rotation", (0.0, 0.0, 0.0, 1.0))
    s = node.get("scale", (1.0, 1.0, 1.0))
    return Matrix.LocRotScale(Vector(t), Quaternion((w, x, y, z)), Vector(s))


def carry(glb_path, motion, fps):
    """Adds the animation to the .glb at `glb_path` for the objects
    `motion` (shutter_poses) names as moving; times are seconds after the
    shutter's opening at `fps`. Returns (names carried, notes)."""
    moving = {name: poses for name, poses in motion["objects"].items()
              if name in motion["moving"]}
    if not moving:
        return [], []
    doc, binary = glb.read(glb_path)
    nodes = doc.get("nodes", [])
    parent = {}
    for i, node in enumerate(nodes):
        for c in node.get("children", []):
            parent[c] = i
    by_name = {}
    for i, node in enumerate(nodes):
        by_name.setdefault(node.get("name"), i)
    local = [_trs(n) for n in nodes]
    cache = {}

    def exported_world(i):
        if ("now", i) not in cache:
            w = local[i]
            if i in parent:
                w = exported_world(parent[i]) @ w
            cache[("now", i)] = w
        return cache[("now", i)]

    C = _basis()
    Ci = C.inverted()
    # The nodes that follow an object's matrices, and their K.
    driven, unmatched = {}, []
    for name, poses in moving.items():
        i = by_name.get(name)
        if poses["kind"] == "LIGHT" and (
                i is None or "KHR_lights_punctual" not in nodes[i].get("extensions", {})):
            # Area lights, Cycles spots and every light under Lights: Scene
            # File are the scene file's, which keys no light.
            unmatched.append((name, "a light the scene file carries, unkeyed"))
            continue
        if i is None:
            unmatched.append((name, "no node of that name in the export"))
            continue
        world_now = C @ poses["now"] @ Ci
        try:
            K = world_now.inverted() @ exported_world(i)
        except ValueError:
            unmatched.append((name, "its matrix is singular"))
            continue
        turn_only = _close(K.to_3x3().to_4x4() @ K.to_3x3().transposed().to_4x4(), Matrix.Identity(4)) \
            and K.to_translation().length <= TOLERANCE
        if not (_close(K, Matrix.Identity(4)) or (poses["kind"] in ("LIGHT", "CAMERA") and turn_only)):
            unmatched.append((name, "the export places it otherwise than its Blender matrix"))
            continue
        driven[i] = (poses["at"], K)

    instants = len(motion["instants"])

    def world(i, k):
        key = (k, i)
        if key not in cache:
            if i in driven:
                mats, K = driven[i]
                w = C @ mats[k] @ Ci @ K
            else:
                w = local[i]
                if i in parent:
                    w = world(parent[i], k) @ w
            cache[key] = w
        return cache[key]

    channels = []  # (node, path, values per instant)
    carried = []
    names = {i: nodes[i].get("name") for i in driven}
    for i in sorted(driven):
        keys = []
        ok = True
        for k in range(instants):
            m = world(i, k)
            if i in parent:
                m = world(parent[i], k).inverted() @ m
            t, q, s = m.decompose()
            if not _close(Matrix.LocRotScale(t, q, s), m, 1e-4):
                ok = False
                break
            keys.append((t, q, s))
        if not ok:
            unmatched.append((names[i], "its motion is not translation, rotation and scale (shear "
                                        "or a mirroring scale)"))
            continue
        # Quaternions on one side (slerp takes the shorter arc anyway).
        for k in range(1, len(keys)):
            if keys[k][1].dot(keys[k - 1][1]) < 0.0:
                keys[k] = (keys[k][0], -keys[k][1], keys[k][2])
        now = local[i]
        t0, q0, s0 = now.decompose()
        for path, index, rest in (("translation", 0, t0), ("rotation", 1, q0), ("scale", 2, s0)):
            values = [key[index] for key in keys]
            if path == "rotation":
                flat = [(v.x, v.y, v.z, v.w) for v in values]
                still = all(abs(v.rotation_difference(q0).angle) <= 1e-6 for v in values)
            else:
                flat = [tuple(v) for v in values]
                still = all((v - rest).length <= TOLERANCE * max(1.0, rest.length) for v in values)
            if not still:
                channels.append((i, path, flat))
        carried.append(names[i])
    notes = []
    if unmatched:
        listed = ", ".join(f"'{n}' ({why})" for n, why in unmatched[:8])
        more = f" and {len(unmatched) - 8} more" if len(unmatched) > 8 else ""
        notes.append(f"motion blur: rendered sharp: {listed}{more}")
    if not channels:
        return carried, notes
    times = [(t - motion["times"][0]) / fps for t in motion["instants"]]
    binary, time_accessor = glb.append_floats(doc, binary, [(t,) for t in times], "SCALAR",
                                               min_max=True)
    samplers, out_channels = [], []
    for i, path, values in channels:
        binary, output = glb.append_floats(doc, binary, values,
                                           "VEC4" if path == "rotation" else "VEC3")
        samplers.append({"input": time_accessor, "output": output, "interpolation": "LINEAR"})
        out_channels.append({"sampler": len(samplers) - 1, "target": {"node": i, "path": path}})
    doc.setdefault("animations", []).append(
        {"name": "Prism shutter", "channels": out_channels, "samplers": samplers})
    glb.write(glb_path, doc, binary)
    return carried, notes
