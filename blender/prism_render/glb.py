"""Reading and rewriting the exported binary glTF (.glb): its JSON and its
one binary chunk, so the add-on can carry what the exporter drops (a
Checker Texture node as a texture, spot lights through the scene file).

Plain Python (no bpy), after the glTF 2.0 specification's GLB layout: a
12-byte header (magic, version 2, length), a JSON chunk padded with
spaces, then an optional BIN chunk padded with zeros, each chunk 4-byte
aligned.
"""

import json
import struct
import zlib

MAGIC, JSON_CHUNK, BIN_CHUNK = 0x46546C67, 0x4E4F534A, 0x004E4942


def read(path):
    """(the JSON as a dict, the BIN chunk's bytes or b"")."""
    with open(path, "rb") as f:
        data = f.read()
    magic, version, length = struct.unpack_from("<III", data, 0)
    if magic != MAGIC or version != 2 or length > len(data):
        raise ValueError(f"{path} is not a binary glTF 2.0 file")
    offset, doc, binary = 12, None, b""
    while offset + 8 <= length:
        size, kind = struct.unpack_from("<II", data, offset)
        chunk = data[offset + 8:offset + 8 + size]
        if kind == JSON_CHUNK and doc is None:
            doc = json.loads(chunk.decode("utf-8"))
        elif kind == BIN_CHUNK and not binary:
            binary = bytes(chunk)
        offset += 8 + size
    if doc is None:
        raise ValueError(f"{path} has no JSON chunk")
    return doc, binary


def write(path, doc, binary):
    """Writes the file back; the buffer's byteLength follows the chunk."""
    if binary:
        doc.setdefault("buffers", [{}])
        doc["buffers"][0]["byteLength"] = len(binary)
    text = json.dumps(doc, ensure_ascii=False, separators=(",", ":")).encode("utf-8")
    text += b" " * (-len(text) % 4)
    chunks = struct.pack("<II", len(text), JSON_CHUNK) + text
    if binary:
        padded = binary + b"\0" * (-len(binary) % 4)
        chunks += struct.pack("<II", len(padded), BIN_CHUNK) + padded
    with open(path, "wb") as f:
        f.write(struct.pack("<III", MAGIC, 2, 12 + len(chunks)) + chunks)


def append_image(doc, binary, png, name):
    """Adds a PNG to the BIN chunk as an image (through a buffer view);
    returns (the image's index, the new BIN bytes)."""
    start = len(binary) + (-len(binary) % 4)
    binary = binary + b"\0" * (start - len(binary)) + png
    if not doc.get("buffers"):
        doc["buffers"] = [{"byteLength": 0}]
    views = doc.setdefault("bufferViews", [])
    views.append({"buffer": 0, "byteOffset": start, "byteLength": len(png)})
    images = doc.setdefault("images", [])
    images.append({"bufferView": len(views) - 1, "mimeType": "image/png", "name": name})
    return len(images) - 1, binary


def append_floats(doc, binary, values, kind, min_max=False):
    """Adds float elements (tuples of 1, 3 or 4 numbers: kind SCALAR, VEC3
    or VEC4) to the BIN chunk as an accessor through a buffer view, with
    their min and max where `min_max` (an animation's times need them);
    returns (the new BIN bytes, the accessor's index)."""
    start = len(binary) + (-len(binary) % 4)
    flat = [float(c) for v in values for c in v]
    data = struct.pack(f"<{len(flat)}f", *flat)
    binary = binary + b"\0" * (start - len(binary)) + data
    if not doc.get("buffers"):
        doc["buffers"] = [{"byteLength": 0}]
    views = doc.setdefault("bufferViews", [])
    views.append({"buffer": 0, "byteOffset": start, "byteLength": len(data)})
    accessor = {"bufferView": len(views) - 1, "componentType": 5126, "count": len(values),
                "type": kind}
    if min_max:
        # The values as float32 rounds them, so the bounds hold what is stored.
        stored = struct.unpack(f"<{len(flat)}f", data)
        width = len(values[0])
        accessor["min"] = [min(stored[c::width]) for c in range(width)]
        accessor["max"] = [max(stored[c::width]) for c in range(width)]
    accessors = doc.setdefault("accessors", [])
    accessors.append(accessor)
    return binary, len(accessors) - 1


def png_rgb8(width, height, rows):
    """A PNG of 8-bit RGB rows (each a list of (r, g, b) bytes), top row first."""
    raw = b"".join(b"\0" + bytes(c for px in row for c in px) for row in rows)

    def chunk(tag, body):
        return (struct.pack(">I", len(body)) + tag + body
                + struct.pack(">I", zlib.crc32(tag + body) & 0xFFFFFFFF))

    return (b"\x89PNG\r\n\x1a\n"
            + chunk(b"IHDR", struct.pack(">IIBBBBB", width, height, 8, 2, 0, 0, 0))
            + chunk(b"IDAT", zlib.compress(raw))
            + chunk(b"IEND", b""))


def remove_lights(doc, keep):
    """Drops the KHR_lights_punctual lights for which keep(light) is false,
    and their nodes' references, renumbering the rest. Returns how many
    were dropped."""
    ext = doc.get("extensions", {}).get("KHR_lights_punctual")
    if not ext or "lights" not in ext:
        return 0
    new_index, kept = {}, []
    for i, light in enumerate(ext["lights"]):
        if keep(light):
            new_index[i] = len(kept)
            kept.append(light)
    dropped = len(ext["lights"]) - len(kept)
    if not dropped:
        return 0
    ext["lights"] = kept
    for node in doc.get("nodes", []):
        node_ext = node.get("extensions", {})
        ref = node_ext.get("KHR_lights_punctual")
        if ref is None:
            continue
        if ref.get("light") in new_index:
            ref["light"] = new_index[ref["light"]]
        else:
            del node_ext["KHR_lights_punctual"]
            if not node_ext:
                del node["extensions"]
    return dropped
