"""Exact ray queries on triangle meshes: :class:`RayScene`.

Prism's watertight double-precision triangle test and its mesh BVHs, for
callers that want hits rather than pictures (lidar and sensor simulation,
visibility, inside/outside tests for meshing and voxelization)::

    >>> import numpy as np, prism
    >>> scene = prism.RayScene(vertices, faces)       # (V, 3) floats, (F, 3) ints
    >>> hits = scene.intersect(origins, directions)   # (N, 3) each
    >>> hits["t"], hits["triangle_id"]                # inf and -1 where a ray misses

No ray slips between two triangles that share an edge or a vertex, and the
hits equal, bit for bit, the ones Prism's renderer finds. Every query takes
``threads=`` (default: one per core) and gives the same answer for any
count; it runs without the GIL, and Ctrl-C stops a long one
(``KeyboardInterrupt``). Arrays go in without a copy where they are
C-contiguous float64 or float32 (float32 is widened, exactly, where it is
read: rays a chunk at a time as they are traced) and come out as NumPy
arrays without a copy. Bad shapes, dtypes, NaN or infinite values, indices out of
range and empty arrays raise ``ValueError`` naming the argument.

``closest_point`` (the nearest point of the surface to a point) is not
offered.
"""

from __future__ import annotations

import os
from typing import Dict, List, Optional, Sequence, Union

import numpy as np
import numpy.typing as npt

from . import _prism

PathLike = Union[str, "os.PathLike[str]"]
ArrayLike = npt.ArrayLike

__all__ = ["RayScene"]


def _coords(name: str, value: ArrayLike) -> np.ndarray:
    """An (N, 3) float64 or float32 array, C-contiguous (copied only when
    it is not already)."""
    a = np.asarray(value)
    if a.dtype.kind not in "fiu" or a.dtype.itemsize > 8:
        raise ValueError(f"{name}: must hold real numbers, got dtype {a.dtype}")
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"{name}: must have shape (N, 3), got {a.shape}")
    if a.shape[0] == 0:
        raise ValueError(f"{name}: is empty")
    if a.dtype != np.float32:
        a = np.ascontiguousarray(a, dtype=np.float64)
    else:
        a = np.ascontiguousarray(a)
    return a


def _faces(value: ArrayLike) -> np.ndarray:
    a = np.asarray(value)
    if a.dtype.kind not in "iu":
        raise ValueError(f"faces: must hold integers, got dtype {a.dtype}")
    if a.ndim != 2 or a.shape[1] != 3:
        raise ValueError(f"faces: must have shape (F, 3), got {a.shape}")
    if a.shape[0] == 0:
        raise ValueError("faces: is empty")
    if a.dtype.kind == "u" and a.size and int(a.max()) > np.iinfo(np.int64).max:
        raise ValueError(f"faces: index {int(a.max())} is out of range")
    return np.ascontiguousarray(a, dtype=np.int64)


def _transform(value: Optional[ArrayLike]) -> Optional[np.ndarray]:
    if value is None:
        return None
    a = np.asarray(value)
    if a.dtype.kind not in "fiu" or a.shape != (4, 4):
        raise ValueError(f"transform: must be a (4, 4) matrix of numbers, got shape {a.shape}")
    return np.ascontiguousarray(a, dtype=np.float64)


def _limit(name: str, value: float) -> float:
    try:
        return float(value)
    except (TypeError, ValueError):
        raise ValueError(f"{name}: must be a number, got {value!r}") from None


def _threads(value: Optional[int]) -> Optional[int]:
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, (int, np.integer)):
        raise ValueError(f"threads: must be an integer, got {value!r}")
    return int(value)


class RayScene:
    """Triangle meshes for exact ray queries, built once, queried many times.

    ``RayScene(vertices, faces)`` makes a scene of one mesh (id 0);
    ``RayScene()`` an empty one to :meth:`add_mesh` to. ``vertices`` is a
    (V, 3) array of float64 or float32 (or integers), ``faces`` an (F, 3)
    array of vertex indices, counter-clockwise seen from the outside.

    Rays are (N, 3) arrays of ``origins`` and ``directions`` (any length,
    not zero; t is measured in the direction's length, so a hit lies at
    ``origin + t * direction``), searched for hits with t in
    (``tmin``, ``tmax``), 0 <= tmin < tmax.
    """

    def __init__(self, vertices: Optional[ArrayLike] = None, faces: Optional[ArrayLike] = None,
                 transform: Optional[ArrayLike] = None) -> None:
        self._scene = _prism.RayScene()
        if vertices is not None or faces is not None:
            if vertices is None:
                raise ValueError("vertices: is missing (faces were given)")
            if faces is None:
                raise ValueError("faces: is missing (vertices were given)")
            self.add_mesh(vertices, faces, transform)

    @classmethod
    def from_file(cls, path: PathLike, allow_read: Sequence[PathLike] = ()) -> "RayScene":
        """A scene of every mesh in a model file (``.obj``, ``.ply``,
        ``.gltf``, ``.glb``), read as a Prism scene reads it: through the
        same loaders, within the same limits and read policy (the file's
        own folder, ``allow_read`` and ``PRISM_ALLOW_READ``). Each placement
        of a glTF mesh is a mesh of its own, with its node's transform. OBJ
        positions are read in single precision, as the renderer reads them."""
        scene = cls()
        scene.add_file(path, allow_read)
        return scene

    def add_file(self, path: PathLike, allow_read: Sequence[PathLike] = ()) -> List[int]:
        """Adds every mesh of a model file (see :meth:`from_file`); returns
        their ids."""
        return list(self._scene.add_file(os.fspath(path), [os.fspath(p) for p in allow_read]))

    def add_mesh(self, vertices: ArrayLike, faces: ArrayLike,
                 transform: Optional[ArrayLike] = None) -> int:
        """Adds a mesh and builds its BVH; returns its id (0, 1, ... in the
        order meshes are added). ``transform``: an affine (4, 4) matrix,
        object to world (the last row 0, 0, 0, 1), applied as the renderer
        applies it (rays mapped into the mesh's space, so t is unchanged)."""
        return self._scene.add_mesh(_coords("vertices", vertices), _faces(faces),
                                    _transform(transform))

    @property
    def mesh_count(self) -> int:
        """Number of meshes."""
        return self._scene.mesh_count

    @property
    def triangle_count(self) -> int:
        """Number of triangles (a mesh of a file placed twice counted twice)."""
        return self._scene.triangle_count

    @property
    def memory_bytes(self) -> int:
        """Heap memory of the meshes and their BVHs, in bytes."""
        return self._scene.memory_bytes

    @property
    def memory_per_triangle(self) -> float:
        """``memory_bytes / triangle_count``."""
        return self.memory_bytes / max(1, self.triangle_count)

    def is_closed(self, mesh_id: int) -> bool:
        """Whether mesh ``mesh_id`` is closed (every edge shared by two
        triangles that run it in opposite directions): what
        :meth:`contains` needs."""
        return self._scene.is_closed(mesh_id)

    def _rays(self, origins: ArrayLike, directions: ArrayLike, tmin: float, tmax: float,
              threads: Optional[int]):
        o = _coords("origins", origins)
        d = _coords("directions", directions)
        if o.shape[0] != d.shape[0]:
            raise ValueError(f"directions: {d.shape[0]} rays, but origins has {o.shape[0]}")
        return o, d, _limit("tmin", tmin), _limit("tmax", tmax), _threads(threads)

    def intersect(self, origins: ArrayLike, directions: ArrayLike, tmin: float = 0.0,
                  tmax: float = float("inf"), threads: Optional[int] = None
                  ) -> Dict[str, np.ndarray]:
        """The nearest hit of each ray, as a dict of arrays: ``t`` (float64,
        inf for a miss), ``mesh_id`` and ``triangle_id`` (int64, -1 for a
        miss; the triangle's row in its mesh's ``faces``), ``u`` and ``v``
        (barycentric: the hit is ``(1-u-v)*a + u*b + v*c``) and ``normal``
        ((N, 3), the unit geometric normal by the right-hand rule of the
        face, zero for a miss). Of triangles hit at the same t, the first in
        its mesh's faces wins, and of meshes, the lowest id.

        The arrays are the caller's to keep and change. Once nothing refers
        to them any more (no name, view or memoryview), a later query (of
        any scene) may write its answers into them rather than into new
        memory; the last 24 answer arrays, up to 256 MiB, are kept for
        that."""
        return self._scene.intersect(*self._rays(origins, directions, tmin, tmax, threads))

    def occluded(self, origins: ArrayLike, directions: ArrayLike, tmin: float = 0.0,
                 tmax: float = float("inf"), threads: Optional[int] = None) -> np.ndarray:
        """Whether each ray hits anything with t in (tmin, tmax): bool (N,)."""
        return self._scene.occluded(*self._rays(origins, directions, tmin, tmax, threads))

    def count_intersections(self, origins: ArrayLike, directions: ArrayLike,
                            tmin: float = 0.0, tmax: float = float("inf"),
                            threads: Optional[int] = None) -> np.ndarray:
        """How many triangles each ray hits with t in (tmin, tmax): uint32
        (N,). A ray through an edge or a vertex counts every triangle that
        holds it (use :meth:`contains` for inside/outside)."""
        return self._scene.count_intersections(
            *self._rays(origins, directions, tmin, tmax, threads))

    def all_intersections(self, origins: ArrayLike, directions: ArrayLike,
                          tmin: float = 0.0, tmax: float = float("inf"),
                          threads: Optional[int] = None) -> Dict[str, np.ndarray]:
        """Every hit of each ray, sorted by t (ties by mesh id, then
        triangle), as flat arrays: ray k's hits are entries
        ``offsets[k]:offsets[k + 1]`` of ``t``, ``mesh_id``,
        ``triangle_id``, ``u`` and ``v``; ``offsets`` has N + 1 entries."""
        return self._scene.all_intersections(
            *self._rays(origins, directions, tmin, tmax, threads))

    def contains(self, points: ArrayLike, threads: Optional[int] = None) -> np.ndarray:
        """Whether each point lies inside one of the meshes, all of which
        must be closed (``ValueError`` otherwise): bool (N,).

        By crossing parity (the Jordan curve theorem) along a ray, with
        every sign the answer rests on certified by an error bound, so it is
        exact for any point farther from the surface than rounding (about
        1e-15 of the mesh's size). A ray that passes within rounding of an
        edge or a vertex is set aside for the next of eight fixed
        directions, never guessed; a point within rounding of the surface
        (every ray uncertain) is inside, as a closed solid holds its
        boundary. The answer depends on the point alone."""
        return self._scene.contains(_coords("points", points), _threads(threads))

    def closest_point(self, points: ArrayLike, threads: Optional[int] = None
                      ) -> Dict[str, np.ndarray]:
        """The point of the meshes nearest each point, in world space, as a
        dict of arrays: ``point`` ((N, 3) float64), ``distance`` (float64),
        ``mesh_id`` and ``triangle_id`` (int64; the triangle's row in its
        mesh's ``faces``), ``u`` and ``v`` (barycentric: the point is
        ``(1-u-v)*a + u*b + v*c``) and ``normal`` ((N, 3), the triangle's
        unit geometric normal as ``intersect`` gives it; zero for a
        degenerate triangle). Of points equally near, the one on the
        lowest mesh id, then on the first triangle in its ``faces``, so the
        answer depends on the point alone. Computed in double precision
        (each triangle's nearest point by the region of its plane the point
        projects into); meshes need not be closed."""
        return self._scene.closest_point(_coords("points", points), _threads(threads))

    def __repr__(self) -> str:
        return (f"RayScene({self.mesh_count} meshes, {self.triangle_count} triangles, "
                f"{self.memory_bytes / 2**20:.1f} MiB)")
