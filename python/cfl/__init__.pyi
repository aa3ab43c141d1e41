# Typing stub of the cfl package (the extension module cfl._cfl, re-exported by cfl/__init__.py).
# Frames and units: poses are 4x4 rigid transforms "world from model" (X_WA); lengths are in the meshes'
# own unit; returned points are in the world frame. See help(cfl) for the conventions.

import os
from typing import Any, Callable, Iterator, Optional, Protocol, Tuple, Union

import numpy as np
import numpy.typing as npt

__version__: str

_Path = Union[str, bytes, os.PathLike[str], os.PathLike[bytes]]
# A 4x4 rigid transform (anything numpy.asarray turns into a (4, 4) array of numbers), or None for the identity.
_Pose = Optional[npt.ArrayLike]
_Progress = Union[None, bool, Callable[[float], Any]]

class _MeshLike(Protocol):
    @property
    def vertices(self) -> npt.ArrayLike: ...
    @property
    def faces(self) -> npt.ArrayLike: ...

class Mesh:
    """A triangle mesh with its bounding volume hierarchy (no Voronoi regions): the second model of a query."""

    def __init__(self, vertices: Union[npt.ArrayLike, _MeshLike], faces: Optional[npt.ArrayLike] = None) -> None:
        """vertices (n, 3) numbers and faces (m, 3) vertex indices, or one object with .vertices and .faces."""
    @staticmethod
    def from_file(path: _Path) -> Mesh:
        """Reads OBJ / STL (native, double precision) or any format assimp reads. Raises OSError."""
    @property
    def vertices(self) -> npt.NDArray[np.float64]:
        """(n, 3) read-only view, mesh frame."""
    @property
    def faces(self) -> npt.NDArray[np.int32]:
        """(m, 3) read-only view of vertex indices."""
    @property
    def bounds(self) -> npt.NDArray[np.float64]:
        """(2, 3): min and max corner, mesh frame."""
    @property
    def triangle_count(self) -> int: ...
    @property
    def vertex_count(self) -> int: ...

class Model:
    """A triangle mesh with its discrete Voronoi regions (adaptive cells listing the closest triangles): the first
    model of a query."""

    def __init__(
        self,
        vertices: Union[npt.ArrayLike, _MeshLike],
        faces: Optional[npt.ArrayLike] = None,
        *,
        resolution: int = 0,
        padding: float = 3.0,
        topology_culling: bool = True,
        threads: int = 0,
        memory_limit: int = 0,
        progress: _Progress = None,
    ) -> None:
        """Builds the regions. resolution 0 = adaptive cells, sized automatically; N > 0 = the paper's uniform grid
        of N cells along the longest axis. padding: the box grows by (padding - 1) / 2 of its longest extent on
        every side. memory_limit: bytes for the regions, 0 = min(half of RAM, 32 MiB + 2 KiB per triangle);
        past it an adaptive build coarsens (sets coarsened). threads 0 = all; progress True = a bar on stderr.
        Raises ValueError for resolution < 0, padding < 1, memory_limit < 0."""
    @staticmethod
    def from_file(
        path: _Path,
        *,
        resolution: int = 0,
        padding: float = 3.0,
        topology_culling: bool = True,
        threads: int = 0,
        memory_limit: int = 0,
        progress: _Progress = None,
    ) -> Model:
        """Reads a mesh file (see Mesh.from_file) and builds its model. Raises OSError for file problems."""
    @staticmethod
    def load(path: _Path) -> Model:
        """Loads a .cfl file written by save(). Raises OSError (FileNotFoundError when missing)."""
    def save(self, path: _Path) -> None:
        """Writes a .cfl file atomically. Raises OSError."""
    @property
    def vertices(self) -> npt.NDArray[np.float64]: ...
    @property
    def faces(self) -> npt.NDArray[np.int32]: ...
    @property
    def bounds(self) -> npt.NDArray[np.float64]: ...
    @property
    def triangle_count(self) -> int: ...
    @property
    def vertex_count(self) -> int: ...
    # Build statistics.
    @property
    def resolution(self) -> int:
        """Cells of the finest level along the longest axis of the regions."""
    @property
    def voxel_count(self) -> int:
        """Leaves (cells not split further), with or without a list: sum(leaves_per_depth)."""
    @property
    def leaves_per_depth(self) -> list[int]:
        """Leaves at each depth, the root cells' level first (one entry for a uniform grid)."""
    @property
    def leaves_without_list(self) -> int:
        """Leaves that store no list; queries use the mesh's hierarchy there."""
    @property
    def average_list_length(self) -> float:
        """Mean list length over the leaves that store one."""
    @property
    def longest_list(self) -> int: ...
    @property
    def distinct_lists(self) -> int: ...
    @property
    def memory_bytes(self) -> int: ...
    @property
    def coarsened(self) -> bool:
        """Whether the build stopped refining at memory_limit (answers stay exact)."""
    @property
    def build_seconds(self) -> float: ...
    @property
    def statistics(self) -> dict[str, Union[int, float, bool, list[int]]]: ...
    @property
    def closed(self) -> bool:
        """Whether the mesh bounds a solid; signed queries and penetration need it."""
    @property
    def closure(self) -> dict[str, Union[int, bool, str]]:
        """Why the mesh does or does not bound a solid: closed, reason, edge and triangle counts, orientation."""

class DistanceResult:
    """distance, point_a, point_b (world frame), triangle_a, triangle_b; unpacks in that order."""

    @property
    def distance(self) -> float: ...
    @property
    def point_a(self) -> npt.NDArray[np.float64]: ...
    @property
    def point_b(self) -> npt.NDArray[np.float64]: ...
    @property
    def triangle_a(self) -> int: ...
    @property
    def triangle_b(self) -> int: ...
    @property
    def triangle_pairs(self) -> int: ...
    @property
    def voxel_tests(self) -> int: ...
    def __iter__(self) -> Iterator[Any]: ...

class DistanceBatch:
    """Arrays over N poses: distance (N,), point_a / point_b (N, 3), triangle_a / triangle_b (N,) int32."""

    @property
    def distance(self) -> npt.NDArray[np.float64]: ...
    @property
    def point_a(self) -> npt.NDArray[np.float64]: ...
    @property
    def point_b(self) -> npt.NDArray[np.float64]: ...
    @property
    def triangle_a(self) -> npt.NDArray[np.int32]: ...
    @property
    def triangle_b(self) -> npt.NDArray[np.int32]: ...
    @property
    def triangle_pairs(self) -> npt.NDArray[np.int64]: ...
    @property
    def voxel_tests(self) -> npt.NDArray[np.int64]: ...
    def __len__(self) -> int: ...
    def __iter__(self) -> Iterator[npt.NDArray[Any]]: ...

class PointDistances:
    """Arrays over N points: distance (N,), closest_point / gradient (N, 3), triangle (N,) int32."""

    @property
    def distance(self) -> npt.NDArray[np.float64]: ...
    @property
    def closest_point(self) -> npt.NDArray[np.float64]: ...
    @property
    def gradient(self) -> npt.NDArray[np.float64]: ...
    @property
    def triangle(self) -> npt.NDArray[np.int32]: ...
    def __len__(self) -> int: ...
    def __iter__(self) -> Iterator[npt.NDArray[Any]]: ...

class PenetrationResult:
    """The certified depth interval of two overlapping closed meshes, with the deepest point (world frame)."""

    @property
    def overlapping(self) -> bool: ...
    @property
    def contained(self) -> int: ...
    @property
    def depth(self) -> float: ...
    @property
    def depth_upper(self) -> float: ...
    @property
    def deepest_point(self) -> npt.NDArray[np.float64]: ...
    @property
    def surface_point(self) -> npt.NDArray[np.float64]: ...
    @property
    def normal(self) -> npt.NDArray[np.float64]: ...
    @property
    def deepest_body(self) -> int: ...
    @property
    def triangle_a(self) -> int: ...
    @property
    def triangle_b(self) -> int: ...

class Contact:
    @property
    def triangle_a(self) -> int: ...
    @property
    def triangle_b(self) -> int: ...
    @property
    def position(self) -> npt.NDArray[np.float64]:
        """A world-frame point of both triangles."""

class CollisionResult:
    @property
    def colliding(self) -> bool: ...
    @property
    def contacts(self) -> list[Contact]: ...
    def __bool__(self) -> bool: ...

def distance(
    a: Model,
    pose_a: _Pose,
    b: Union[Model, Mesh],
    pose_b: _Pose,
    *,
    rel_err: float = 0.0,
    abs_err: float = 0.0,
    upper_bound: float = ...,
    mode: str = "hierarchical",
    hint: Optional[Tuple[int, int]] = None,
) -> DistanceResult:
    """Exact minimum distance between a at X_WA = pose_a and b at X_WB = pose_b (world-frame points)."""

def distances(
    a: Model,
    pose_a: _Pose,
    b: Union[Model, Mesh],
    poses_b: npt.ArrayLike,
    *,
    rel_err: float = 0.0,
    abs_err: float = 0.0,
    upper_bound: float = ...,
    mode: str = "hierarchical",
    hint: Optional[Tuple[int, int]] = None,
    threads: int = 0,
    chunk_size: int = 0,
) -> DistanceBatch:
    """distance() for each of the (N, 4, 4) poses_b, on all cores with the GIL released."""

def collide(
    a: Union[Model, Mesh],
    pose_a: _Pose,
    b: Union[Model, Mesh],
    pose_b: _Pose,
    *,
    max_contacts: int = 1,
) -> CollisionResult:
    """Whether a and b share a point, with up to max_contacts intersecting triangle pairs."""

def point_distances(
    model: Model,
    pose: _Pose,
    points: npt.ArrayLike,
    *,
    signed: bool = False,
    sign_method: str = "auto",
    upper_bound: float = ...,
    threads: int = 0,
) -> PointDistances:
    """Exact (signed) distance from each of the (N, 3) world-frame points to the mesh, on all cores."""

def signed_distance(a: Model, pose_a: _Pose, b: Model, pose_b: _Pose) -> DistanceResult:
    """Distance between two closed meshes, minus the penetration depth when they overlap."""

def penetration(a: Model, pose_a: _Pose, b: Model, pose_b: _Pose, *, tolerance: float = 0.0) -> PenetrationResult:
    """Certified depth of two overlapping closed meshes: the deepest point of either surface inside the other."""
