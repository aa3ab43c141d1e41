"""cfl: exact minimum distance between non-convex triangle meshes from discrete Voronoi regions.

Build a Model of a mesh once (or load a saved one), then ask for distances at any poses:

    >>> import numpy as np, cfl
    >>> a = cfl.Model.from_file("bunny.obj")             # or cfl.Model(vertices, faces)
    >>> b = cfl.Mesh.from_file("bunny.obj")              # b needs no regions
    >>> X_WB = np.eye(4); X_WB[0, 3] = 0.2               # b moved 0.2 units along world x
    >>> r = cfl.distance(a, np.eye(4), b, X_WB)
    >>> r.distance, r.point_a, r.point_b, r.triangle_a, r.triangle_b

Poses are 4x4 rigid transforms "world from model" (X_WA maps the model's vertex coordinates to world
coordinates); lengths are in the meshes' own unit; returned points are in the world frame. In full,
from the extension module cfl._cfl:
"""

from ._cfl import (
    Contact,
    CollisionResult,
    DistanceBatch,
    DistanceResult,
    Mesh,
    Model,
    PenetrationResult,
    PointDistances,
    __doc__ as _conventions,
    __version__,
    collide,
    distance,
    distances,
    penetration,
    point_distances,
    signed_distance,
)

__doc__ = __doc__ + "\n" + _conventions.split("\n", 1)[1]

__all__ = [
    "Contact",
    "CollisionResult",
    "DistanceBatch",
    "DistanceResult",
    "Mesh",
    "Model",
    "PenetrationResult",
    "PointDistances",
    "collide",
    "distance",
    "distances",
    "penetration",
    "point_distances",
    "signed_distance",
]
