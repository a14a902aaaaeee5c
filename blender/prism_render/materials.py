"""What Blender's glTF exporter drops from a material's nodes, carried or
named.

A Checker Texture node feeding the Principled BSDF's Base Color (the
exporter drops it: the floor comes out white) is carried into the .glb
as what it is on the surface: a 2 × 2 texel checker image, sampled
nearest and repeated, tiled by KHR_texture_transform so that each texel
is one of Blender's cells. Its Vector must be a UV map (a Texture
Coordinate node's UV output or a UV Map node), or unlinked (Blender's
Generated coordinates) on meshes whose UV map is those coordinates (a
plane as Blender adds it); otherwise it is named with the other nodes.

Every other node the exporter does not read, between the material's
output and its shader, is named per material in one warning.
"""

import math

from . import glb

# The node types Blender 3.4's glTF exporter reads (io_scene_gltf2/blender/exp).
EXPORTED = {
    "OUTPUT_MATERIAL", "BSDF_PRINCIPLED", "EMISSION", "BACKGROUND", "BSDF_TRANSPARENT",
    "MIX_SHADER", "ADD_SHADER", "TEX_IMAGE", "MAPPING", "TEX_COORD", "UVMAP", "NORMAL_MAP",
    "SEPRGB", "SEPARATE_COLOR", "SEPXYZ", "MIX_RGB", "MIX", "MATH", "VALUE", "RGB", "REROUTE",
    "GROUP", "VERTEX_COLOR", "BSDF_VELVET", "VOLUME_ABSORPTION", "LIGHT_FALLOFF",
}


def srgb_byte(linear):
    """A linear colour channel as the 8-bit sRGB a glTF base colour texture holds."""
    c = min(max(float(linear), 0.0), 1.0)
    c = 12.92 * c if c <= 0.0031308 else 1.055 * c ** (1.0 / 2.4) - 0.055
    return int(round(c * 255.0))


def checker_fac(p, scale):
    """Cycles' svm_checker at point p (3 coordinates) and `scale`: True
    for the first colour."""
    xi, yi, zi = (abs(math.floor((c * scale + 0.000001) * 0.999999)) for c in p)
    return (xi % 2 == yi % 2) == bool(zi % 2)


def checker_texels(scale, z, colour1, colour2):
    """The 2 × 2 image (rows from the top) and the KHR_texture_transform
    (offset, scale) that give Blender's checker of `scale` over UV
    (u, v) at depth z: glTF's texture coordinates are (u, 1 − v), and the
    transform u' = u·scale/2, t' = t·scale/2 − frac(scale)/2 puts the
    texel edges on the cells' edges (v·scale whole), each texel's colour
    Blender's at its centre."""
    offset_t = -0.5 * (scale - math.floor(scale))
    rows = []
    for b in range(2):
        row = []
        for a in range(2):
            u = (a + 0.5) / scale
            t = (b + 0.5 - 2.0 * offset_t) / scale
            first = checker_fac((u, 1.0 - t, z), scale)
            row.append(tuple(srgb_byte(c) for c in (colour1 if first else colour2)[:3]))
        rows.append(row)
    return rows, (0.0, offset_t), (0.5 * scale, 0.5 * scale)


def _output(material):
    tree = material.node_tree if material.use_nodes else None
    if tree is None:
        return None
    outputs = [n for n in tree.nodes if n.type == "OUTPUT_MATERIAL"]
    active = [n for n in outputs if n.is_active_output]
    return (active or outputs or [None])[0]


def _reachable(output):
    """The nodes linked (directly or not) into the output, output first."""
    seen, order, stack = set(), [], [output]
    while stack:
        node = stack.pop()
        if node.name in seen:
            continue
        seen.add(node.name)
        order.append(node)
        for socket in node.inputs:
            for link in socket.links:
                if link.is_valid and not link.is_muted:
                    stack.append(link.from_node)
    return order


def checker_of(material):
    """The Checker Texture node feeding a Principled BSDF's Base Color
    straight into the output, with how its Vector is fed: (node, "uv" or
    "generated"), or None."""
    output = _output(material)
    if output is None or not output.inputs["Surface"].links:
        return None
    bsdf = output.inputs["Surface"].links[0].from_node
    if bsdf.type != "BSDF_PRINCIPLED" or not bsdf.inputs["Base Color"].links:
        return None
    link = bsdf.inputs["Base Color"].links[0]
    node = link.from_node
    if node.type != "TEX_CHECKER" or link.from_socket.name != "Color":
        return None
    if node.inputs["Scale"].is_linked or node.inputs["Color1"].is_linked \
            or node.inputs["Color2"].is_linked:
        return None
    vector = node.inputs["Vector"]
    if not vector.links:
        return node, "generated"
    src = vector.links[0]
    if (src.from_node.type == "TEX_COORD" and src.from_socket.name == "UV") \
            or src.from_node.type == "UVMAP":
        return node, "uv"
    return None


def generated_is_uv(obj):
    """Whether the mesh's Generated texture coordinates are its first UV
    map in x and y and constant in z (a flat mesh in its texture space);
    returns (True, z) or (False, None)."""
    import numpy as np
    mesh = obj.data
    if mesh is None or not len(mesh.uv_layers) or not len(mesh.loops):
        return False, None
    n = len(mesh.loops)
    vertex = np.empty(n, dtype=np.int64)
    mesh.loops.foreach_get("vertex_index", vertex)
    co = np.empty(3 * len(mesh.vertices), dtype=np.float64)
    mesh.vertices.foreach_get("co", co)
    uv = np.empty(2 * n, dtype=np.float64)
    mesh.uv_layers[0].data.foreach_get("uv", uv)
    co, uv = co.reshape(-1, 3)[vertex], uv.reshape(-1, 2)
    loc, size = np.array(mesh.texspace_location), np.array(mesh.texspace_size)
    # Blender's texture space spans loc ± size; a flat axis reads 0.5.
    safe = np.where(size != 0.0, size, 1.0)
    generated = np.where(size != 0.0, ((co - loc) / safe + 1.0) * 0.5, 0.5)
    if np.abs(generated[:, :2] - uv).max() > 1e-4 or np.ptp(generated[:, 2]) > 1e-4:
        return False, None
    return True, float(generated[0, 2])


def used_materials(depsgraph):
    """{material: [mesh objects using it]} over the objects rendered."""
    found = {}
    for inst in depsgraph.object_instances:
        obj = inst.object.original
        if obj.type != "MESH":
            continue
        for slot in obj.material_slots:
            if slot.material is not None:
                users = found.setdefault(slot.material.original, [])
                if obj not in users:
                    users.append(obj)
    return found


def carry(glb_path, depsgraph):
    """Carries checkers into the .glb and names what else is dropped;
    returns the notes (one per material at most)."""
    notes, checkers = [], {}
    for material, users in used_materials(depsgraph).items():
        output = _output(material)
        if output is None:
            continue
        dropped = []
        found = checker_of(material)
        z = 0.0
        if found is not None and found[1] == "generated":
            # Generated coordinates are the UV map's on every user, at one depth.
            depths = [generated_is_uv(obj) for obj in users]
            if all(same for same, _ in depths) and max(d for _, d in depths) - min(d for _, d in depths) <= 1e-4:
                z = depths[0][1]
            else:
                found = None
        for node in _reachable(output):
            if node.type in EXPORTED:
                continue
            if found is not None and node == found[0]:
                continue
            dropped.append(node.bl_label if node.label == "" else f"{node.label} ({node.bl_label})")
        if found is not None:
            node = found[0]
            checkers[material.name] = checker_texels(
                node.inputs["Scale"].default_value, z if found[1] == "generated" else 0.0,
                node.inputs["Color1"].default_value, node.inputs["Color2"].default_value)
        if dropped:
            names = ", ".join(sorted(set(dropped)))
            notes.append(f"material '{material.name}': the glTF export drops {names}; "
                         "Prism renders it without them")
    if checkers:
        doc, binary = glb.read(glb_path)
        if add_checkers(doc, binary, checkers, glb_path) < len(checkers):
            notes.append("a checker's material is missing from the glTF export; not carried")
    return notes


def add_checkers(doc, binary, checkers, path):
    """Gives each glTF material named in `checkers` its checker image as
    base colour texture; writes the file; returns how many were given."""
    given = 0
    for material in doc.get("materials", []):
        found = checkers.get(material.get("name"))
        if found is None:
            continue
        rows, offset, scale = found
        image, binary = glb.append_image(doc, binary, glb.png_rgb8(2, 2, rows),
                                         f"checker {material.get('name')}")
        samplers = doc.setdefault("samplers", [])
        # NEAREST both ways, REPEAT (the default wrap).
        samplers.append({"magFilter": 9728, "minFilter": 9728})
        textures = doc.setdefault("textures", [])
        textures.append({"sampler": len(samplers) - 1, "source": image})
        pbr = material.setdefault("pbrMetallicRoughness", {})
        factor = pbr.get("baseColorFactor", [1.0, 1.0, 1.0, 1.0])
        pbr["baseColorFactor"] = [1.0, 1.0, 1.0, factor[3] if len(factor) > 3 else 1.0]
        pbr["baseColorTexture"] = {
            "index": len(textures) - 1, "texCoord": 0,
            "extensions": {"KHR_texture_transform": {"offset": list(offset), "scale": list(scale)}},
        }
        used = doc.setdefault("extensionsUsed", [])
        if "KHR_texture_transform" not in used:
            used.append("KHR_texture_transform")
        given += 1
    glb.write(path, doc, binary)
    return given
