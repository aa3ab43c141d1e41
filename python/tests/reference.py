"""Independent references for the tests: exact triangle-triangle distance by brute force in NumPy, rigid
poses and small meshes. Nothing here calls cfl.

The distance between two triangles is 0 when they intersect; otherwise the closest pair of points has one
point at a vertex of one triangle facing the interior of the other, or lies on an edge of each. So the
distance is the minimum over
  * 9 edge pairs: segment-segment distance, itself the minimum over the 4 endpoint-to-segment distances and
    the interior stationary point when both its parameters are in [0, 1] (the minimum of a convex quadratic
    over a square is at that point or on the square's boundary, where one parameter is 0 or 1);
  * 6 vertex-triangle pairs whose projection onto the other triangle's plane falls inside the triangle
    (otherwise the vertex's closest point is on an edge, covered above);
and is 0 when an edge of one triangle crosses the other triangle (two intersecting triangles that are not
coplanar have such an edge; coplanar overlaps show up as crossing edges or a vertex inside).
"""

import numpy as np


def _dot(u, v):
    return np.einsum("...k,...k->...", u, v)


def point_segment_distance(p, a, b):
    """Distance from points p to segments [a, b]; arrays broadcast over leading axes, last axis 3."""
    d = b - a
    dd = _dot(d, d)
    t = np.where(dd > 0, _dot(p - a, d) / np.where(dd > 0, dd, 1), 0.0)
    t = np.clip(t, 0.0, 1.0)
    return np.linalg.norm(p - (a + t[..., None] * d), axis=-1)


def segment_segment_distance(p1, q1, p2, q2):
    """Distance between segments [p1, q1] and [p2, q2] (broadcasting)."""
    best = np.minimum(
        np.minimum(point_segment_distance(p1, p2, q2), point_segment_distance(q1, p2, q2)),
        np.minimum(point_segment_distance(p2, p1, q1), point_segment_distance(q2, p1, q1)),
    )
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, b = _dot(d1, d1), _dot(d2, d2), _dot(d1, d2)
    c, f = _dot(d1, r), _dot(d2, r)
    denominator = a * e - b * b
    # Only a clearly non-parallel pair has an interior stationary point worth taking; near-parallel pairs
    # reach their minimum at an endpoint as well.
    valid = denominator > 1e-12 * a * e
    safe = np.where(valid, denominator, 1.0)
    s = (b * f - c * e) / safe
    t = (a * f - b * c) / safe
    inside = valid & (s >= 0) & (s <= 1) & (t >= 0) & (t <= 1)
    interior = np.linalg.norm((p1 + s[..., None] * d1) - (p2 + t[..., None] * d2), axis=-1)
    return np.where(inside, np.minimum(best, interior), best)


def _barycentric_inside(x, a, b, c):
    """Whether points x, assumed in the plane of (a, b, c), lie in the triangle (boundary included)."""
    v0, v1, v2 = b - a, c - a, x - a
    d00, d01, d11 = _dot(v0, v0), _dot(v0, v1), _dot(v1, v1)
    d20, d21 = _dot(v2, v0), _dot(v2, v1)
    denominator = d00 * d11 - d01 * d01
    # A triangle whose corners are collinear up to rounding (sine of its angle below 1e-10) counts as
    # degenerate: its rounded normal points anywhere, and its edges, which the callers also measure, are
    # within 1e-10 of its size from every point of it. The test takes the cross product itself: the
    # denominator above equals its squared length but cancels to a rounding error 1e16 times larger.
    normal = np.cross(v0, v1)
    ok = _dot(normal, normal) > 1e-20 * d00 * d11
    safe = np.where(ok, denominator, 1.0)
    v = (d11 * d20 - d01 * d21) / safe
    w = (d00 * d21 - d01 * d20) / safe
    slack = 1e-12
    return ok & (v >= -slack) & (w >= -slack) & (v + w <= 1 + slack)


def point_plane_projection_distance(p, a, b, c):
    """|distance| from p to the plane of (a, b, c) where p projects inside the triangle, else inf."""
    n = np.cross(b - a, c - a)
    nn = np.linalg.norm(n, axis=-1)
    ok = nn > 0
    unit = n / np.where(ok, nn, 1.0)[..., None]
    height = _dot(p - a, unit)
    foot = p - height[..., None] * unit
    return np.where(ok & _barycentric_inside(foot, a, b, c), np.abs(height), np.inf)


def point_triangle_distance(p, a, b, c):
    """Distance from points p to triangles (a, b, c), degenerate triangles included."""
    edges = np.minimum(np.minimum(point_segment_distance(p, a, b), point_segment_distance(p, b, c)),
                       point_segment_distance(p, c, a))
    return np.minimum(edges, point_plane_projection_distance(p, a, b, c))


def segment_crosses_triangle(p, q, a, b, c):
    """Whether segment [p, q] meets triangle (a, b, c) at a point where it crosses the plane."""
    n = np.cross(b - a, c - a)
    dp, dq = _dot(p - a, n), _dot(q - a, n)
    crosses = (dp * dq <= 0) & (dp != dq)
    t = np.where(crosses, dp / np.where(crosses, dp - dq, 1.0), 0.0)
    x = p + t[..., None] * (q - p)
    return crosses & _barycentric_inside(x, a, b, c)


def triangle_distance(A, B):
    """Distances between triangles A[i] and B[i]; A, B of shape (..., 3, 3) (triangle, corner, xyz)."""
    best = np.full(A.shape[:-2], np.inf)
    for i in range(3):
        for j in range(3):
            best = np.minimum(best, segment_segment_distance(A[..., i, :], A[..., (i + 1) % 3, :],
                                                             B[..., j, :], B[..., (j + 1) % 3, :]))
    for k in range(3):
        best = np.minimum(best, point_plane_projection_distance(A[..., k, :], B[..., 0, :], B[..., 1, :], B[..., 2, :]))
        best = np.minimum(best, point_plane_projection_distance(B[..., k, :], A[..., 0, :], A[..., 1, :], A[..., 2, :]))
    touching = np.zeros(best.shape, dtype=bool)
    for k in range(3):
        touching |= segment_crosses_triangle(A[..., k, :], A[..., (k + 1) % 3, :], B[..., 0, :], B[..., 1, :], B[..., 2, :])
        touching |= segment_crosses_triangle(B[..., k, :], B[..., (k + 1) % 3, :], A[..., 0, :], A[..., 1, :], A[..., 2, :])
    return np.where(touching, 0.0, best)


def transform(X, points):
    """Points (..., 3) mapped by the 4x4 rigid transform X."""
    return points @ X[:3, :3].T + X[:3, 3]


def world_triangles(vertices, faces, X):
    return transform(X, np.asarray(vertices, dtype=float))[np.asarray(faces)]


def brute_force_distance(vertices_a, faces_a, X_WA, vertices_b, faces_b, X_WB, chunk=20000):
    """(distance, i, j): the minimum over all triangle pairs of A at X_WA and B at X_WB, and a pair there."""
    TA = world_triangles(vertices_a, faces_a, X_WA)
    TB = world_triangles(vertices_b, faces_b, X_WB)
    ia, ib = np.meshgrid(np.arange(len(TA)), np.arange(len(TB)), indexing="ij")
    ia, ib = ia.ravel(), ib.ravel()
    best, pair = np.inf, (-1, -1)
    for start in range(0, len(ia), chunk):
        sa, sb = ia[start:start + chunk], ib[start:start + chunk]
        d = triangle_distance(TA[sa], TB[sb])
        k = int(np.argmin(d))
        if d[k] < best:
            best, pair = float(d[k]), (int(sa[k]), int(sb[k]))
    return best, pair[0], pair[1]


# --- poses ---------------------------------------------------------------------------------------------------

def random_rotation(rng):
    """A uniformly distributed rotation matrix (from a unit quaternion)."""
    w, x, y, z = rng.normal(size=4) / 1.0
    norm = np.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    return np.array([
        [1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)],
        [2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)],
        [2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)],
    ])


def rigid(R=None, t=None):
    X = np.eye(4)
    if R is not None:
        X[:3, :3] = R
    if t is not None:
        X[:3, 3] = t
    return X


def random_pose(rng, scale):
    """A random rotation and a translation of up to `scale` along a random direction."""
    direction = rng.normal(size=3)
    direction /= np.linalg.norm(direction)
    return rigid(random_rotation(rng), direction * scale * rng.random())


# --- meshes --------------------------------------------------------------------------------------------------

def torus(major=1.0, minor=0.35, rings=12, sides=8):
    """A closed, non-convex torus around the z axis."""
    u = np.linspace(0, 2 * np.pi, rings, endpoint=False)
    v = np.linspace(0, 2 * np.pi, sides, endpoint=False)
    U, V = np.meshgrid(u, v, indexing="ij")
    vertices = np.stack([(major + minor * np.cos(V)) * np.cos(U), (major + minor * np.cos(V)) * np.sin(U),
                         minor * np.sin(V)], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(rings):
        for j in range(sides):
            a, b = i * sides + j, ((i + 1) % rings) * sides + j
            c, d = ((i + 1) % rings) * sides + (j + 1) % sides, i * sides + (j + 1) % sides
            faces += [(a, b, c), (a, c, d)]
    return vertices, np.array(faces)


def wavy_patch(n=9, size=2.0, amplitude=0.3):
    """An open, non-convex height field: a sheet with a boundary."""
    x = np.linspace(-size / 2, size / 2, n)
    X, Y = np.meshgrid(x, x, indexing="ij")
    Z = amplitude * np.sin(3 * X) * np.cos(2 * Y)
    vertices = np.stack([X, Y, Z], axis=-1).reshape(-1, 3)
    faces = []
    for i in range(n - 1):
        for j in range(n - 1):
            a, b, c, d = i * n + j, (i + 1) * n + j, (i + 1) * n + j + 1, i * n + j + 1
            faces += [(a, b, c), (a, c, d)]
    return vertices, np.array(faces)


def triangle_soup(rng, count=60, size=1.5):
    """Random triangles: non-manifold, self-intersecting, with a duplicate, a sliver, a segment and a point."""
    vertices = rng.uniform(-size / 2, size / 2, size=(3 * count, 3))
    vertices[3:6] += rng.normal(scale=0.3, size=(3, 3))
    faces = np.arange(3 * count).reshape(count, 3)
    extra_vertices = np.array([[0.0, 0.0, 0.0], [0.5, 0.5, 0.5], [1.0, 1.0, 1.0], [0.2, -0.3, 0.1]])
    base = len(vertices)
    vertices = np.vstack([vertices, extra_vertices])
    extra_faces = np.array([
        faces[0],                              # duplicate triangle
        (base, base + 1, base + 2),            # collinear: a segment
        (base + 3, base + 3, base + 3),        # a point
        (base, base + 2, base + 3),            # a sliver-ish triangle sharing vertices with the segment
    ])
    return vertices, np.vstack([faces, extra_faces])


def write_obj(path, vertices, faces):
    """Writes an OBJ file whose coordinates parse back to the same doubles (repr is round-trip exact)."""
    with open(path, "w") as out:
        for v in vertices:
            out.write("v " + " ".join(repr(float(x)) for x in v) + "\n")
        for f in faces:
            out.write("f " + " ".join(str(int(i) + 1) for i in f) + "\n")
