"""Point queries, signed distance and penetration from Python, against references in NumPy."""

import numpy as np
import pytest

import cfl
import reference


def point_mesh_distance(p, vertices, faces):
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    return float(np.min(reference.point_triangle_distance(np.broadcast_to(p, a.shape), a, b, c)))


def box(lo, hi):
    """A closed axis-aligned box, 12 triangles, counterclockwise from outside."""
    lo, hi = np.asarray(lo, float), np.asarray(hi, float)
    v = np.array([[hi[0] if k & 1 else lo[0], hi[1] if k & 2 else lo[1], hi[2] if k & 4 else lo[2]] for k in range(8)])
    quads = [(0, 2, 3, 1), (4, 5, 7, 6), (0, 1, 5, 4), (2, 6, 7, 3), (0, 4, 6, 2), (1, 3, 7, 5)]
    f = [t for a, b, c, d in quads for t in ((a, b, c), (a, c, d))]
    return v, np.array(f, dtype=np.int32)


def translation(x, y, z):
    pose = np.eye(4)
    pose[:3, 3] = [x, y, z]
    return pose


def test_unit_cube_point_distances_have_the_closed_form():
    v, f = box([0, 0, 0], [1, 1, 1])
    model = cfl.Model(v, f)
    assert model.closed and model.closure["reason"] == ""
    rng = np.random.default_rng(3)
    points = rng.uniform(-0.5, 1.5, size=(500, 3))
    pose = translation(2, 0, 0)
    r = cfl.point_distances(model, pose, points + [2, 0, 0], signed=True)
    inside = np.all((points > 0) & (points < 1), axis=1)
    outside_gap = np.linalg.norm(np.maximum(np.maximum(-points, points - 1), 0), axis=1)
    inside_depth = np.min(np.concatenate([points, 1 - points], axis=1), axis=1)
    expected = np.where(inside, -inside_depth, outside_gap)
    np.testing.assert_allclose(r.distance, expected, atol=1e-12)
    np.testing.assert_allclose(np.linalg.norm(r.closest_point - (points + [2, 0, 0]), axis=1), np.abs(expected),
                               atol=1e-12)
    assert np.allclose(np.linalg.norm(r.gradient, axis=1), 1)
    distance, closest, gradient, triangle = r
    assert len(r) == 500 and triangle.dtype == np.int32 and np.all(triangle >= 0)


def test_unsigned_matches_brute_force_and_open_meshes_refuse_signs_by_name(meshes):
    torus = meshes["torus"]
    model = cfl.Model(*torus, threads=1)
    assert model.closed, model.closure["reason"]
    rng = np.random.default_rng(5)
    points = rng.uniform(-2, 2, size=(100, 3))
    r = cfl.point_distances(model, None, points)
    expected = np.array([point_mesh_distance(p, *torus) for p in points])
    np.testing.assert_allclose(r.distance, expected, rtol=0, atol=1e-12)
    v, f = box([0, 0, 0], [1, 1, 1])
    open_box = cfl.Model(v, f[:-1])  # one triangle missing
    assert not open_box.closed and open_box.closure["boundary_edges"] == 3
    with pytest.raises(ValueError, match="boundary"):
        cfl.point_distances(open_box, None, [[0.5, 0.5, 0.5]], signed=True)
    w = cfl.point_distances(open_box, None, [[0.5, 0.5, 0.5], [3, 3, 3]], signed=True, sign_method="winding")
    assert w.distance[0] < 0 < w.distance[1]
    with pytest.raises(ValueError, match="shape"):
        cfl.point_distances(model, None, np.zeros((4, 2)))
    with pytest.raises(ValueError, match="sign_method"):
        cfl.point_distances(model, None, np.zeros((1, 3)), signed=True, sign_method="parity")


def test_penetration_and_signed_distance_of_boxes():
    v, f = box([0, 0, 0], [1, 1, 1])
    a = cfl.Model(v, f)
    vb, fb = box([0, 0.2, 0.2], [1.1, 0.8, 0.8])
    b = cfl.Model(vb, fb)
    # b moved 0.9 along x enters a's face x = 1 by 0.1.
    p = cfl.penetration(a, None, b, translation(0.9, 0, 0))
    assert p.overlapping and p.contained == 0
    assert p.depth == pytest.approx(0.1, abs=1e-9)
    assert p.depth <= p.depth_upper <= p.depth + 1e-4 * np.sqrt(3) + 1e-12
    assert np.linalg.norm(p.surface_point - p.deepest_point) == pytest.approx(p.depth, abs=1e-12)
    s = cfl.signed_distance(a, None, b, translation(0.9, 0, 0))
    assert s.distance == pytest.approx(-0.1, abs=1e-9)
    assert cfl.signed_distance(a, None, b, translation(1.3, 0, 0)).distance == pytest.approx(0.3, abs=1e-12)
    # A small box wholly inside: contained, negative.
    vi, fi = box([0.4, 0.4, 0.2], [0.6, 0.6, 0.4])
    inner = cfl.Model(vi, fi)
    q = cfl.penetration(a, None, inner, None)
    assert q.contained == 1 and q.depth == pytest.approx(0.4, abs=1e-9)
    assert cfl.signed_distance(a, None, inner, None).distance == pytest.approx(-0.4, abs=1e-9)
    open_box = cfl.Model(v, f[:-1])
    with pytest.raises(ValueError, match="mesh B"):
        cfl.penetration(a, None, open_box, None)
