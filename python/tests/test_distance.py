"""cfl.distance against the NumPy brute force over all triangle pairs, and the properties of its answer."""

import concurrent.futures
import zlib

import numpy as np
import pytest

import cfl
import reference
from conftest import MESHES, diagonal

PAIRS = [("torus", "torus"), ("torus", "patch"), ("patch", "soup"), ("soup", "torus"), ("soup", "soup")]


def poses_for(name_a, name_b, count, seed):
    """Random poses of B from overlapping A to two diagonals away (beyond A's regions, padding 3)."""
    rng = np.random.default_rng(seed)
    scale = diagonal(MESHES[name_a][0], MESHES[name_b][0])
    X_WA = reference.random_pose(rng, 0.5 * scale)
    result = []
    for k in range(count):
        reach = [0.3, 0.7, 1.2, 2.0][k % 4] * scale
        X_WB = X_WA @ reference.random_pose(rng, reach)
        result.append(X_WB)
    return X_WA, result


@pytest.mark.parametrize("kind", ["uniform", "adaptive"])
@pytest.mark.parametrize("name_a,name_b", PAIRS)
def test_distance_equals_brute_force_at_random_poses(models, adaptive_models, name_a, name_b, kind):
    # Uniform grids (resolution=12) and the default adaptive regions, whose leaves without a list send
    # queries to the Bvh.
    built = models if kind == "uniform" else adaptive_models
    va, fa = MESHES[name_a]
    vb, fb = MESHES[name_b]
    tolerance = 1e-9 * diagonal(va, vb)
    X_WA, poses = poses_for(name_a, name_b, 12, seed=zlib.crc32(f"{name_a}-{name_b}".encode()))
    mesh_b = cfl.Mesh(vb, fb)
    for X_WB in poses:
        expected, _, _ = reference.brute_force_distance(va, fa, X_WA, vb, fb, X_WB)
        # b with regions (a Model) and without (a Mesh) take different C++ overloads.
        for b in (built[name_b], mesh_b):
            assert cfl.distance(built[name_a], X_WA, b, X_WB).distance == pytest.approx(expected, abs=tolerance)


@pytest.mark.parametrize("name_a,name_b", PAIRS)
def test_closest_points_lie_on_the_reported_triangles_in_the_world_frame(models, name_a, name_b):
    va, fa = MESHES[name_a]
    vb, fb = MESHES[name_b]
    tolerance = 1e-9 * diagonal(va, vb)
    X_WA, poses = poses_for(name_a, name_b, 8, seed=7)
    for X_WB in poses:
        r = cfl.distance(models[name_a], X_WA, models[name_b], X_WB)
        TA = reference.world_triangles(va, fa, X_WA)[r.triangle_a]
        TB = reference.world_triangles(vb, fb, X_WB)[r.triangle_b]
        assert reference.point_triangle_distance(r.point_a, *TA) <= tolerance
        assert reference.point_triangle_distance(r.point_b, *TB) <= tolerance
        assert np.linalg.norm(r.point_a - r.point_b) == pytest.approx(r.distance, abs=tolerance)
        # The reported pair is itself at that distance (not only its points).
        assert float(reference.triangle_distance(TA[None], TB[None])[0]) == pytest.approx(r.distance, abs=tolerance)


def test_intersecting_meshes_give_zero_and_one_shared_point(models):
    v, f = MESHES["torus"]
    X = reference.rigid(reference.random_rotation(np.random.default_rng(2)), [0.1, 0.2, 0.3])
    r = cfl.distance(models["torus"], X, models["torus"], X @ reference.rigid(t=[0.05, 0, 0]))
    assert r.distance == 0.0
    np.testing.assert_array_equal(r.point_a, r.point_b)


def test_moving_both_meshes_by_one_transform_moves_the_points_with_it(models):
    # The answer lives in the world frame: composing both poses with T changes only the frame.
    rng = np.random.default_rng(3)
    a, b = models["torus"], models["patch"]
    X_WA, X_WB = reference.random_pose(rng, 1.0), reference.random_pose(rng, 3.0)
    T = reference.random_pose(rng, 10.0)
    r1 = cfl.distance(a, X_WA, b, X_WB)
    r2 = cfl.distance(a, T @ X_WA, b, T @ X_WB)
    tolerance = 1e-9 * 12
    assert r2.distance == pytest.approx(r1.distance, abs=tolerance)
    np.testing.assert_allclose(r2.point_a, reference.transform(T, r1.point_a), atol=tolerance)
    np.testing.assert_allclose(r2.point_b, reference.transform(T, r1.point_b), atol=tolerance)


def test_none_is_the_identity_and_any_array_like_pose_is_accepted(models):
    a, b = models["torus"], models["soup"]
    X = reference.rigid(t=[0.3, -2.0, 0.4])
    expected = cfl.distance(a, np.eye(4), b, X)
    forms = [X.tolist(), np.asfortranarray(X),
             np.kron(X, np.ones((2, 2)))[::2, ::2], X.astype(">f8")]
    assert cfl.distance(a, None, b, X).distance == expected.distance
    for form in forms:
        assert cfl.distance(a, None, b, form).distance == expected.distance
    # float32 changes the pose itself (rounding), still a rigid one within 1e-6.
    assert cfl.distance(a, None, b, X.astype(np.float32)).distance == pytest.approx(expected.distance, abs=1e-5)


def test_result_unpacks_in_documented_order(models):
    r = cfl.distance(models["torus"], None, models["patch"], reference.rigid(t=[0, 0, 1.5]))
    d, pa, pb, ta, tb = r
    assert (d, ta, tb) == (r.distance, r.triangle_a, r.triangle_b)
    np.testing.assert_array_equal(pa, r.point_a)
    np.testing.assert_array_equal(pb, r.point_b)
    assert pa.shape == (3,) and pa.dtype == np.float64
    assert r.triangle_pairs >= 1 and r.voxel_tests >= 0
    assert "DistanceResult(distance=" in repr(r)


def test_paper_mode_hint_and_tolerances_keep_their_guarantees(models, meshes):
    va, fa = meshes["torus"]
    vb, fb = meshes["soup"]
    a, b = models["torus"], models["soup"]
    tolerance = 1e-9 * diagonal(va, vb)
    X_WA, poses = poses_for("torus", "soup", 8, seed=11)
    for X_WB in poses:
        exact = cfl.distance(a, X_WA, b, X_WB)
        expected, ia, ib = reference.brute_force_distance(va, fa, X_WA, vb, fb, X_WB)
        assert cfl.distance(a, X_WA, b, X_WB, mode="paper").distance == pytest.approx(expected, abs=tolerance)
        assert cfl.distance(a, X_WA, b, X_WB, hint=(ia, ib)).distance == pytest.approx(expected, abs=tolerance)
        # FCL's guarantee: d <= true * (1 + rel_err) with abs_err large enough to let rel_err act alone.
        loose = cfl.distance(a, X_WA, b, X_WB, rel_err=0.5, abs_err=1e9)
        assert expected - tolerance <= loose.distance <= expected * 1.5 + tolerance
        # ... and the reported points are still that far apart.
        assert np.linalg.norm(loose.point_a - loose.point_b) == pytest.approx(loose.distance, abs=tolerance)
        absolute = cfl.distance(a, X_WA, b, X_WB, abs_err=0.1, rel_err=1e9)
        assert expected - tolerance <= absolute.distance <= expected + 0.1 + tolerance
        assert exact.distance == pytest.approx(expected, abs=tolerance)


def test_upper_bound_dismisses_farther_pairs_and_keeps_closer_answers_exact(models):
    a, b = models["torus"], models["patch"]
    X_WB = reference.rigid(t=[0.0, 0.0, 2.0])
    exact = cfl.distance(a, None, b, X_WB)
    assert exact.distance > 0
    below = cfl.distance(a, None, b, X_WB, upper_bound=0.5 * exact.distance)
    assert below.distance == np.inf and below.triangle_a == -1 and below.triangle_b == -1
    above = cfl.distance(a, None, b, X_WB, upper_bound=2 * exact.distance)
    assert above.distance == exact.distance


def test_concurrent_python_threads_get_the_serial_answers(models):
    a, b = models["torus"], models["soup"]
    _, poses = poses_for("torus", "soup", 32, seed=4)
    serial = [cfl.distance(a, None, b, X).distance for X in poses]
    with concurrent.futures.ThreadPoolExecutor(4) as pool:
        parallel = list(pool.map(lambda X: cfl.distance(a, None, b, X).distance, poses))
    assert parallel == serial
