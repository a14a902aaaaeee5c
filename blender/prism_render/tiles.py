"""Finished tiles while Prism renders: `prism render --checkpoint DIR`
saves each tile as DIR/X-Y.tile (written to a .part file, then renamed).
The layout is Prism's own (src/render/checkpoint.rs): b"PRISMTL1", the
region x0, x1, y0, y1 as little-endian u32 (rows counted from the top),
its pixels as little-endian f64 RGB row by row, then a 32-byte digest.
A file that does not parse is skipped: the final EXR is what counts."""

import os
import struct
import sys
from array import array

MAGIC = b"PRISMTL1"


def read_tile(path):
    """(x0, x1, y0, y1, rows) with rows top-down lists of RGB floats, or None."""
    try:
        with open(path, "rb") as f:
            data = f.read()
    except OSError:
        return None
    if len(data) < 24 + 32 or not data.startswith(MAGIC):
        return None
    x0, x1, y0, y1 = struct.unpack_from("<4I", data, 8)
    if x0 >= x1 or y0 >= y1:
        return None
    body = data[24:-32]
    if len(body) != (x1 - x0) * (y1 - y0) * 24:
        return None
    values = array("d")
    values.frombytes(body)
    if sys.byteorder != "little":
        values.byteswap()
    return x0, x1, y0, y1, values


class TileWatcher:
    """Hands each tile that appears in `folder` to the engine once."""

    def __init__(self, folder, origin, layer=""):
        """origin: the frame's (x, y) of the result's bottom-left corner,
        y counted from the top (the bottom edge of a border)."""
        self.folder = folder
        self.origin = origin
        self.layer = layer
        self.seen = set()

    def poll(self, engine):
        try:
            names = [n for n in os.listdir(self.folder) if n.endswith(".tile")]
        except OSError:
            return
        for name in names:
            if name in self.seen:
                continue
            tile = read_tile(os.path.join(self.folder, name))
            if tile is None:
                continue
            self.seen.add(name)
            x0, x1, y0, y1, v = tile
            w, h = x1 - x0, y1 - y0
            # Blender's rows run bottom-up.
            rect = []
            for row in range(h - 1, -1, -1):
                base = row * w * 3
                for i in range(w):
                    j = base + 3 * i
                    rect.append((v[j], v[j + 1], v[j + 2], 1.0))
            ox, oy = self.origin
            result = engine.begin_result(x0 - ox, oy - y1, w, h, layer=self.layer)
            result.layers[0].passes["Combined"].rect = rect
            engine.end_result(result)
