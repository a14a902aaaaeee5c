"""Counts the triangles and distinct vertex positions of one mesh in a
binary glTF export (the node of that name), and checks them: the add-on
must export the render's geometry (a Subdivision modifier at its render
levels). Plain Python 3, no Blender.
Run: python3 glb_mesh.py FILE.glb NODE_NAME TRIANGLES VERTICES
"""

import os
import struct
import sys

sys.dont_write_bytecode = True  # no __pycache__ in the source tree
sys.path.insert(0, os.path.join(os.path.dirname(__file__), "..", "..", "blender", "prism_render"))
import glb  # noqa: E402

path, node_name, want_triangles, want_vertices = sys.argv[1], sys.argv[2], int(sys.argv[3]), int(sys.argv[4])
doc, binary = glb.read(path)
node = next((n for n in doc.get("nodes", []) if n.get("name") == node_name), None)
if node is None or "mesh" not in node:
    print(f"glb_mesh: FAIL: no mesh node '{node_name}' in {path}")
    sys.exit(1)
triangles, positions = 0, set()
for prim in doc["meshes"][node["mesh"]]["primitives"]:
    accessor = doc["accessors"][prim["attributes"]["POSITION"]]
    view = doc["bufferViews"][accessor["bufferView"]]
    start = view.get("byteOffset", 0) + accessor.get("byteOffset", 0)
    stride = view.get("byteStride", 12)
    for i in range(accessor["count"]):
        xyz = struct.unpack_from("<3f", binary, start + i * stride)
        positions.add(tuple(round(c, 5) for c in xyz))
    count = doc["accessors"][prim["indices"]]["count"] if "indices" in prim else accessor["count"]
    triangles += count // 3
print(f"glb_mesh: '{node_name}': {triangles} triangles, {len(positions)} distinct vertices "
      f"(want {want_triangles}, {want_vertices})")
if (triangles, len(positions)) != (want_triangles, want_vertices):
    print("glb_mesh: FAIL: the export is not the render's mesh")
    sys.exit(1)
