"""Shared by the test scripts: an image file's RGB as a numpy array
(rows bottom-up, as Blender stores them)."""

import bpy
import numpy as np


def rgb(path):
    image = bpy.data.images.load(path, check_existing=False)
    width, height = image.size
    pixels = np.empty(width * height * 4, dtype=np.float32)
    image.pixels.foreach_get(pixels)
    bpy.data.images.remove(image)
    return pixels.reshape(height, width, 4)[:, :, :3]


def centre(a, half=2):
    """Mean of the (2·half)² pixels around the image centre."""
    h, w = a.shape[:2]
    return a[h // 2 - half:h // 2 + half, w // 2 - half:w // 2 + half].reshape(-1, 3).mean(axis=0)
