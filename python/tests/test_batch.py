"""cfl.distances: the same answers as cfl.distance, bit for bit, as NumPy arrays."""

import gc

import numpy as np
import pytest

import cfl
import reference
from conftest import MESHES, diagonal


def random_poses(count, seed, scale):
    rng = np.random.default_rng(seed)
    return np.stack([reference.random_pose(rng, scale) for _ in range(count)])


@pytest.mark.parametrize("b_kind", ["model", "mesh"])
def test_batch_equals_single_calls_bit_for_bit(models, b_kind):
    a = models["torus"]
    b = models["soup"] if b_kind == "model" else cfl.Mesh(*MESHES["soup"])
    X_WA = reference.rigid(reference.random_rotation(np.random.default_rng(1)), [0.2, 0.1, -0.3])
    poses = random_poses(60, seed=2, scale=2 * diagonal(MESHES["torus"][0], MESHES["soup"][0]))
    batch = cfl.distances(a, X_WA, b, poses)
    assert len(batch) == 60
    for i, X_WB in enumerate(poses):
        single = cfl.distance(a, X_WA, b, X_WB)
        assert batch.distance[i] == single.distance
        np.testing.assert_array_equal(batch.point_a[i], single.point_a)
        np.testing.assert_array_equal(batch.point_b[i], single.point_b)
        assert batch.triangle_a[i] == single.triangle_a
        assert batch.triangle_b[i] == single.triangle_b
        assert batch.triangle_pairs[i] == single.triangle_pairs
        assert batch.voxel_tests[i] == single.voxel_tests


def test_options_reach_every_query_of_the_batch(models):
    a, b = models["torus"], models["patch"]
    poses = random_poses(20, seed=3, scale=4.0)
    for options in ({"mode": "paper"}, {"rel_err": 0.3, "abs_err": 1e9}, {"upper_bound": 0.2}):
        batch = cfl.distances(a, None, b, poses, **options)
        single = [cfl.distance(a, None, b, X, **options).distance for X in poses]
        np.testing.assert_array_equal(batch.distance, single)


def test_thread_count_and_chunk_size_do_not_change_the_answers(models):
    a, b = models["torus"], models["soup"]
    poses = random_poses(50, seed=4, scale=3.0)
    reference_batch = cfl.distances(a, None, b, poses, threads=1)
    for threads, chunk_size in ((0, 0), (2, 1), (3, 7)):
        other = cfl.distances(a, None, b, poses, threads=threads, chunk_size=chunk_size)
        for left, right in zip(reference_batch, other):
            np.testing.assert_array_equal(left, right)


def test_result_arrays_have_documented_shapes_and_outlive_the_batch_object(models):
    poses = random_poses(5, seed=5, scale=2.0)
    batch = cfl.distances(models["torus"], None, models["patch"], poses)
    distance, point_a, point_b, triangle_a, triangle_b = batch
    assert distance.shape == (5,) and distance.dtype == np.float64
    assert point_a.shape == (5, 3) and point_b.shape == (5, 3) and point_a.dtype == np.float64
    assert triangle_a.shape == (5,) and triangle_a.dtype == np.int32 and triangle_b.dtype == np.int32
    assert batch.triangle_pairs.dtype == np.int64 and batch.voxel_tests.shape == (5,)
    # Views of the C++ results, not copies.
    assert not distance.flags.owndata and not point_a.flags.owndata
    expected = distance.copy(), point_b.copy()
    del batch, distance, point_a, triangle_a, triangle_b
    gc.collect()
    np.testing.assert_array_equal(point_b, expected[1])
    np.testing.assert_array_equal(np.linalg.norm(point_b, axis=1) >= 0, True)


def test_empty_batch_gives_empty_arrays(models):
    batch = cfl.distances(models["torus"], None, models["patch"], np.zeros((0, 4, 4)))
    assert len(batch) == 0
    assert batch.distance.shape == (0,) and batch.point_a.shape == (0, 3) and batch.triangle_b.shape == (0,)


def test_any_array_like_stack_of_poses_gives_the_same_answers(models):
    a, b = models["patch"], models["soup"]
    poses = random_poses(16, seed=6, scale=2.0)
    expected = cfl.distances(a, None, b, poses).distance
    strided = np.repeat(poses, 2, axis=0)[::2]
    for form in (poses.tolist(), np.asfortranarray(poses), strided, poses.astype(">f8")):
        np.testing.assert_array_equal(cfl.distances(a, None, b, form).distance, expected)
