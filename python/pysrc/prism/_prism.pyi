"""Type stubs of the extension module; the package `prism` wraps it."""

from os import PathLike
from typing import Any, Callable, Dict, List, Mapping, Optional, Sequence, Tuple, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, PathLike[str]]

AOVS: List[str]
LIMITS: Dict[str, int]

class SceneError(Exception):
    file: str
    line: Optional[int]
    column: Optional[int]
    message: str
    problems: List[Tuple[Optional[int], Optional[int], str]]
    key_path: Optional[str]

class Scene:
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
        progress: Optional[Callable[[int, int], object]] = None,
    ) -> npt.NDArray[np.float32]: ...
    def explain_json(
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
    ) -> str: ...
    @property
    def settings_dict(self) -> dict: ...
    @property
    def warnings(self) -> List[str]: ...
    @property
    def frames(self) -> int: ...

def load(path: _Path, allow_read: Sequence[_Path] = ..., frame: int = 0) -> Scene: ...
def loads(
    text: str,
    base_dir: Optional[_Path] = None,
    origin: str = "<string>",
    allow_read: Sequence[_Path] = ...,
    frame: int = 0,
) -> Scene: ...
def from_dict(
    scene: Mapping[str, Any],
    base_dir: Optional[_Path] = None,
    allow_read: Sequence[_Path] = ...,
    frame: int = 0,
) -> Scene: ...
def escape_controls(text: str) -> str: ...
def write(path: _Path, array: npt.NDArray[np.float32]) -> None: ...
def to_srgb8(array: npt.NDArray[np.float32]) -> npt.NDArray[np.uint8]: ...
def read_exr(path: _Path) -> Tuple[npt.NDArray[np.float32], Tuple[int, int, int, int]]: ...

class RayScene:
    """The extension's ray scene; ``prism.RayScene`` wraps it."""
    def __init__(self) -> None: ...
    def add_mesh(
        self,
        vertices: npt.NDArray[Any],
        faces: npt.NDArray[np.int64],
        transform: Optional[npt.NDArray[np.float64]] = None,
    ) -> int: ...
    def add_file(self, path: _Path, allow_read: Sequence[_Path] = ...) -> List[int]: ...
    @property
    def mesh_count(self) -> int: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...
    def is_closed(self, mesh_id: int) -> bool: ...
    def intersect(
        self,
        origins: npt.NDArray[Any],
        directions: npt.NDArray[Any],
        tmin: float = 0.0,
        tmax: float = ...,
        threads: Optional[int] = None,
    ) -> Dict[str, npt.NDArray[Any]]: ...
    def occluded(
        self,
        origins: npt.NDArray[Any],
        directions: npt.NDArray[Any],
        tmin: float = 0.0,
        tmax: float = ...,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.bool_]: ...
    def count_intersections(
        self,
        origins: npt.NDArray[Any],
        directions: npt.NDArray[Any],
        tmin: float = 0.0,
        tmax: float = ...,
        threads: Optional[int] = None,
    ) -> npt.NDArray[np.uint32]: ...
    def all_intersections(
        self,
        origins: npt.NDArray[Any],
        directions: npt.NDArray[Any],
        tmin: float = 0.0,
        tmax: float = ...,
        threads: Optional[int] = None,
    ) -> Dict[str, npt.NDArray[Any]]: ...
    def contains(
        self, points: npt.NDArray[Any], threads: Optional[int] = None
    ) -> npt.NDArray[np.bool_]: ...
    def closest_point(
        self, points: npt.NDArray[Any], threads: Optional[int] = None
    ) -> Dict[str, npt.NDArray[Any]]: ...
