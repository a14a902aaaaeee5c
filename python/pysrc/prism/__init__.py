"""Prism, an exact Whitted-style ray tracer, from Python.

    >>> import prism
    >>> scene = prism.load("scenes/whitted.toml")
    >>> img = scene.render(spp=4)          # (480, 640, 3) float32, linear radiance
    >>> prism.write("whitted.png", img)     # 8-bit sRGB, as `prism render` writes it
    >>> tree = prism.explain(scene, 320, 240)   # the pixel's ray tree, as dicts

Renders equal, bit for bit, the EXR that ``prism render`` writes with the
same settings. Scenes are the TOML files of docs/scene-format.md, TOML
text (:func:`loads`), or dicts with the same keys (:meth:`Scene.from_dict`).
Problems in a scene raise :class:`SceneError` with its file, line and
column (a dict's: its key path); bad arguments, integers out of range
included, raise ``ValueError`` naming the argument.
"""

from __future__ import annotations

import json
import os
import zlib
import struct
from typing import Any, Callable, Iterable, Mapping, Optional, Sequence, Tuple, Union

import numpy as np

from . import _prism
from ._prism import SceneError
from .lecture import Explanation
from .rays import RayScene

__all__ = [
    "Image",
    "Scene",
    "SceneError",
    "explain",
    "load",
    "loads",
    "read_exr",
    "to_srgb8",
    "write",
    "interact",
    "AOVS",
    "LIMITS",
    "escape_controls",
    "RayScene",
    "Explanation",
]

#: The debug views ``Scene.render(aov=...)`` takes.
AOVS: Tuple[str, ...] = tuple(_prism.AOVS)

#: The bounds the command puts on its arguments (prism::limits), which
#: ``render`` and ``explain`` apply too: ``MAX_THREADS``, ``MAX_SPP``,
#: ``MAX_IMAGE_SIDE``, ``MAX_PIXELS``, ``MAX_DEPTH``, ``MAX_FRAMES``.
LIMITS: Mapping[str, int] = dict(_prism.LIMITS)

#: ``escape_controls(text)``: ``text`` with control characters written as
#: escapes (``\n``, ``\u{1b}``), as Prism's messages show names from files.
escape_controls: Callable[[str], str] = _prism.escape_controls

PathLike = Union[str, "os.PathLike[str]"]


class Image(np.ndarray):
    """Linear radiance, float32, shape (H, W, 3): a NumPy array (no copy of
    the render) that shows itself in Jupyter. ``exposure`` (in stops) is
    applied to what is shown, never to the values."""

    exposure: float = 0.0

    def __array_finalize__(self, obj: Any) -> None:
        self.exposure = getattr(obj, "exposure", 0.0)

    def with_exposure(self, ev: float) -> "Image":
        """The same pixels (a view), shown ``ev`` stops brighter."""
        view = self.view(Image)
        view.exposure = float(ev)
        return view

    def _repr_png_(self) -> Optional[bytes]:
        if self.ndim != 3 or self.shape[2] != 3 or self.dtype != np.float32:
            return None
        scaled = np.asarray(self, dtype=np.float32) * np.float32(2.0 ** self.exposure)
        return _png_bytes(to_srgb8(scaled))


def _png_bytes(rgb8: np.ndarray) -> bytes:
    """A PNG of an (H, W, 3) uint8 array, with the standard library only."""
    h, w, _ = rgb8.shape
    raw = b"".join(b"\x00" + rgb8[y].tobytes() for y in range(h))

    def chunk(kind: bytes, data: bytes) -> bytes:
        body = kind + data
        return struct.pack(">I", len(data)) + body + struct.pack(">I", zlib.crc32(body) & 0xFFFFFFFF)

    header = struct.pack(">IIBBBBB", w, h, 8, 2, 0, 0, 0)
    return (
        b"\x89PNG\r\n\x1a\n"
        + chunk(b"IHDR", header)
        + chunk(b"IDAT", zlib.compress(raw, 6))
        + chunk(b"IEND", b"")
    )


def _tqdm_progress(total_hint: str) -> Optional[Callable[[int, int], None]]:
    try:
        from tqdm.auto import tqdm  # type: ignore
    except ImportError:
        return None
    bar = None

    def update(done: int, total: int) -> None:
        nonlocal bar
        if bar is None:
            bar = tqdm(total=total, unit="px", unit_scale=True, desc=total_hint, leave=False)
        bar.n = done
        bar.refresh()
        if done >= total:
            bar.close()

    return update


class Scene:
    """A loaded scene. Make one with :func:`load`, :func:`loads` or
    :meth:`Scene.from_dict`."""

    def __init__(self, inner: "_prism.Scene") -> None:
        self._inner = inner

    @classmethod
    def from_dict(
        cls,
        scene: Mapping[str, Any],
        base_dir: Optional[PathLike] = None,
        allow_read: Union[PathLike, Iterable[PathLike]] = (),
        frame: int = 0,
    ) -> "Scene":
        """A scene from a dict with the keys of the scene file
        (``{"camera": {...}, "objects": [{...}], ...}``), built from the
        values directly (no TOML text). A problem raises
        :class:`SceneError` whose ``key_path`` names the key
        (``objects[1].radius``). Relative paths are read below
        ``base_dir`` (the working folder by default). An animated scene
        reads the dict again for each other frame it renders."""
        return cls(
            _prism.from_dict(
                scene,
                _folder_arg(base_dir),
                _folders(allow_read),
                frame,
            )
        )

    def render(
        self,
        width: Optional[int] = None,
        height: Optional[int] = None,
        spp: Optional[int] = None,
        max_depth: Optional[int] = None,
        seed: Optional[int] = None,
        frame: int = 0,
        threads: Optional[int] = None,
        crop: Optional[Tuple[int, int, int, int]] = None,
        aov: Optional[str] = None,
        progress: Union[None, bool, Callable[[int, int], Any]] = None,
    ) -> Image:
        """Render the scene; settings left out are the scene's own.

        Returns linear radiance as an :class:`Image` (a float32 NumPy array
        of shape (height, width, 3); with ``crop=(x0, x1, y0, y1)`` the
        crop's shape), equal bit for bit to the EXR of ``prism render``.
        ``aov`` renders a debug view instead (one of :data:`AOVS`).
        ``progress``: a callable ``f(pixels_done, pixels_total)``, ``False``
        for none; by default a tqdm bar when tqdm is installed.

        The GIL is released while rendering; Ctrl-C (KeyboardInterrupt)
        stops the render within a row of pixels.
        """
        if progress is None:
            progress = _tqdm_progress("prism")
        elif progress is False:
            progress = None
        elif progress is True:
            progress = _tqdm_progress("prism")
        if crop is not None and not isinstance(crop, (str, bytes)):
            crop = tuple(crop)
        pixels = self._inner.render(
            width=width,
            height=height,
            spp=spp,
            max_depth=max_depth,
            seed=seed,
            frame=frame,
            threads=threads,
            crop=crop,
            aov=aov,
            progress=progress,
        )
        return pixels.view(Image)

    def explain(
        self,
        x: int,
        y: int,
        sample: int = 0,
        width: Optional[int] = None,
        height: Optional[int] = None,
        spp: Optional[int] = None,
        max_depth: Optional[int] = None,
        seed: Optional[int] = None,
        frame: int = 0,
    ) -> Explanation:
        """The ray tree of one sample of pixel (x, y): the same tree as
        ``prism explain --json``, as dicts and lists (an :class:`Explanation`,
        which Jupyter draws: the lecture's steps). Settings left out are
        the scene's own; its ``radiance`` is the rendered pixel when the
        render has one sample per pixel (``spp=1``)."""
        return Explanation(
            json.loads(
                self._inner.explain_json(
                    x,
                    y,
                    sample=sample,
                    width=width,
                    height=height,
                    spp=spp,
                    max_depth=max_depth,
                    seed=seed,
                    frame=frame,
                )
            )
        )

    @property
    def settings(self) -> dict:
        """The scene's ``[render]`` settings."""
        return {k: (v if k == "min_weight" else int(v)) for k, v in self._inner.settings_dict.items()}

    @property
    def warnings(self) -> list:
        """Warnings from loading, in file order."""
        return list(self._inner.warnings)

    @property
    def frames(self) -> int:
        """Number of animation frames (1 for a still)."""
        return self._inner.frames

    def __repr__(self) -> str:
        s = self.settings
        return f"<prism.Scene {s['width']}x{s['height']} spp={s['spp']} frames={self.frames}>"


def _folders(allow_read: Union[PathLike, Iterable[PathLike], None]) -> list:
    """``allow_read`` as a list of paths: one path (a str or PathLike) is
    one folder, not a sequence of one-letter folders."""
    if allow_read is None:
        return []
    if isinstance(allow_read, (str, bytes, os.PathLike)):
        allow_read = [allow_read]
    return [os.fsdecode(p) for p in allow_read]


def _folder_arg(base_dir: Optional[PathLike]) -> Optional[str]:
    return os.fsdecode(base_dir) if base_dir is not None else None


def load(
    path: PathLike,
    allow_read: Union[PathLike, Iterable[PathLike]] = (),
    frame: int = 0,
) -> Scene:
    """Load a scene file (TOML). It may read files below its own folder,
    below each of ``allow_read`` (a folder or a list of folders) and below
    PRISM_ALLOW_READ's folders: the read policy of ``prism render``. A
    folder of ``allow_read`` that does not exist is a ValueError."""
    return Scene(_prism.load(os.fsdecode(path), _folders(allow_read), frame))


def loads(
    text: str,
    base_dir: Optional[PathLike] = None,
    origin: str = "<string>",
    allow_read: Union[PathLike, Iterable[PathLike]] = (),
    frame: int = 0,
) -> Scene:
    """Load a scene from TOML text. Relative paths in it (models,
    textures) are read below ``base_dir`` (the working folder by default;
    a path that is not a folder is a ValueError); ``origin`` names the
    text in error messages."""
    return Scene(_prism.loads(text, _folder_arg(base_dir), origin, _folders(allow_read), frame))


def explain(scene: Scene, x: int, y: int, sample: int = 0, **settings: Any) -> Explanation:
    """The ray tree of one sample of pixel (x, y), as ``prism explain
    --json`` gives it: ``radiance`` (the sample's RGB; with ``spp=1`` the
    rendered pixel), ``tree`` (the camera ray, its hit, the Whitted terms
    and the reflected and refracted subtrees). ``settings``: ``width``,
    ``height``, ``spp``, ``max_depth``, ``seed``, ``frame``."""
    return scene.explain(x, y, sample=sample, **settings)


def _as_rgb32(array: Any) -> np.ndarray:
    a = np.ascontiguousarray(array, dtype=np.float32)
    if a.ndim != 3 or a.shape[2] != 3:
        raise ValueError(f"expected an array of shape (H, W, 3), got {a.shape}")
    return a


def write(path: PathLike, array: Any) -> None:
    """Write linear radiance (H, W, 3) to ``path``: .png and .ppm as 8-bit
    sRGB (clamped), .exr and .hdr as linear float; atomically, with the
    encodings of ``prism render``."""
    _prism.write(os.fsdecode(path), _as_rgb32(array))


def to_srgb8(array: Any) -> np.ndarray:
    """Linear radiance to 8-bit sRGB (clamped), as PNG output encodes it."""
    return _prism.to_srgb8(_as_rgb32(array))


def read_exr(path: PathLike) -> Tuple[Image, Tuple[int, int, int, int]]:
    """Read an EXR written by ``prism render`` (a frame or a part) or by
    :func:`write`: its pixels (float32) and its region (x0, x1, y0, y1) in
    the frame."""
    pixels, region = _prism.read_exr(os.fsdecode(path))
    return pixels.view(Image), region


def interact(scene_dict: Mapping[str, Any], render: Optional[Mapping[str, Any]] = None, **sliders: Any):
    """Re-render a dict scene as sliders change (needs ipywidgets).

    ``sliders`` maps a key path (``"materials.glass.ior"`` written as
    ``materials__glass__ior``) to an ipywidgets slider or a (min, max, step)
    tuple; ``render`` holds ``Scene.render`` arguments."""
    import copy

    import ipywidgets  # type: ignore
    from IPython.display import display  # type: ignore

    render = dict(render or {})
    render.setdefault("progress", False)

    def show(**values: Any) -> None:
        d = copy.deepcopy(dict(scene_dict))
        for key, value in values.items():
            _set_path(d, key.split("__"), value)
        display(Scene.from_dict(d).render(**render))

    ipywidgets.interact(show, **sliders)


def _set_path(d: Any, path: Sequence[str], value: Any) -> None:
    for key in path[:-1]:
        d = d[int(key)] if isinstance(d, list) else d[key]
    last = path[-1]
    if isinstance(d, list):
        d[int(last)] = value
    else:
        d[last] = value
