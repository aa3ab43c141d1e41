"""Building, inspecting, saving, loading and pickling models."""

import os
import pathlib
import pickle
import types

import numpy as np
import pytest

import cfl
import reference
from conftest import DATA_DIR, MESHES, needs_mesh_files


def answers(model, other, seed=12, count=10):
    rng = np.random.default_rng(seed)
    poses = [reference.random_pose(rng, 3.0) for _ in range(count)]
    results = [cfl.distance(model, None, other, X) for X in poses]
    return [(r.distance, r.triangle_a, r.triangle_b, tuple(r.point_a), tuple(r.point_b)) for r in results]


def test_every_mesh_form_builds_the_same_model(models):
    v, f = MESHES["torus"]
    forms = [
        (v, f),
        (v.tolist(), f.tolist()),
        (v.astype(np.float32).astype(np.float64), f.astype(np.int32)),
        (np.asfortranarray(v), f.astype(np.uint32)),
        (np.repeat(v, 2, axis=1)[:, ::2], np.repeat(f, 2, axis=0)[::2]),
        (types.SimpleNamespace(vertices=v, faces=f), None),
        (cfl.Mesh(v, f), None),
    ]
    expected = answers(models["torus"], models["patch"])
    for vertices, faces in forms:
        model = cfl.Model(vertices, faces, resolution=12, threads=1)
        np.testing.assert_array_equal(model.faces, f)
        assert model.vertices.dtype == np.float64 and model.faces.dtype == np.int32
    # Forms that keep the coordinates exactly give identical answers.
    for vertices, faces in (forms[0], forms[1], forms[4], forms[5]):
        assert answers(cfl.Model(vertices, faces, resolution=12, threads=1), models["patch"]) == expected
    assert cfl.Model(v.astype(np.int64), f, resolution=8).vertices.dtype == np.float64


def test_vertices_and_faces_are_read_only_views_of_the_input(models):
    v, f = MESHES["soup"]
    model = models["soup"]
    np.testing.assert_array_equal(model.vertices, v)
    np.testing.assert_array_equal(model.faces, f)
    assert model.triangle_count == len(f) and model.vertex_count == len(v)
    with pytest.raises(ValueError):
        model.vertices[0, 0] = 1.0
    with pytest.raises(ValueError):
        model.faces[0, 0] = 1
    used = v[np.unique(f)]
    np.testing.assert_array_equal(model.bounds, [used.min(axis=0), used.max(axis=0)])


def test_build_statistics_are_consistent(models):
    for name, model in models.items():
        s = model.statistics
        assert s == {key: getattr(model, key) for key in ("resolution", "voxel_count", "average_list_length",
                                                          "longest_list", "distinct_lists", "memory_bytes",
                                                          "build_seconds")}
        assert model.resolution == 12
        # The longest axis has `resolution` voxels, the others at most as many.
        assert 12 <= model.voxel_count <= 12 ** 3
        assert 1 <= model.longest_list <= model.triangle_count
        assert 0 < model.average_list_length <= model.longest_list
        assert 1 <= model.distinct_lists <= model.voxel_count
        assert model.memory_bytes > 8 * model.voxel_count
        assert model.build_seconds >= 0
        assert f"resolution 12, {model.voxel_count} voxels" in repr(model)
    automatic = cfl.Model(*MESHES["torus"])
    assert automatic.resolution > 0


def test_save_and_load_round_trip_answers_bit_for_bit(models, tmp_path):
    model = models["torus"]
    path = tmp_path / "torus.cfl"
    model.save(path)  # os.PathLike
    for loaded in (cfl.Model.load(path), cfl.Model.load(str(path)), cfl.Model.load(os.fsencode(path))):
        assert loaded.statistics == model.statistics
        np.testing.assert_array_equal(loaded.vertices, model.vertices)
        np.testing.assert_array_equal(loaded.faces, model.faces)
        assert answers(loaded, models["soup"]) == answers(model, models["soup"])
        assert answers(models["patch"], loaded) == answers(models["patch"], model)


def test_pickle_round_trips_models_and_meshes(models):
    model = models["patch"]
    clone = pickle.loads(pickle.dumps(model))
    assert clone.statistics == model.statistics
    assert answers(clone, models["torus"]) == answers(model, models["torus"])
    mesh = cfl.Mesh(*MESHES["soup"])
    mesh_clone = pickle.loads(pickle.dumps(mesh))
    np.testing.assert_array_equal(mesh_clone.vertices, mesh.vertices)
    assert answers(model, mesh_clone) == answers(model, mesh)


@needs_mesh_files
def test_from_file_reads_the_written_obj_exactly(tmp_path):
    v, f = MESHES["patch"]
    path = tmp_path / "patch.obj"
    reference.write_obj(path, v, f)
    model = cfl.Model.from_file(path, resolution=10)
    mesh = cfl.Mesh.from_file(str(path))
    # The loader numbers vertices by first use, so compare the triangles' corners, which must be exact.
    for loaded in (model, mesh):
        np.testing.assert_array_equal(loaded.vertices[loaded.faces], v[f])
    assert model.resolution == 10


@needs_mesh_files
def test_bundled_bunny_loads():
    mesh = cfl.Mesh.from_file(os.path.join(DATA_DIR, "bunny.obj"))
    assert mesh.triangle_count == 3674 and mesh.faces.max() < mesh.vertex_count
    assert "3674 triangles" in repr(mesh)


def test_progress_callback_sees_increasing_fractions_ending_at_one():
    fractions = []
    cfl.Model(*MESHES["torus"], resolution=16, progress=fractions.append)
    assert fractions and fractions[-1] == 1.0
    assert all(0.0 <= x <= 1.0 for x in fractions)
    assert fractions == sorted(fractions)


def test_progress_true_draws_a_bar_on_stderr(capsys):
    cfl.Model(*MESHES["torus"], resolution=8, progress=True)
    err = capsys.readouterr().err
    assert "building cfl.Model" in err and "100.0%" in err


def test_an_exception_in_the_progress_callback_is_raised_after_the_build():
    calls = []

    def failing(fraction):
        calls.append(fraction)
        raise KeyError("stop")

    with pytest.raises(KeyError, match="stop"):
        cfl.Model(*MESHES["torus"], resolution=16, progress=failing)
    assert len(calls) == 1  # reports after the first failure are dropped


def test_thread_count_does_not_change_the_model(models):
    v, f = MESHES["soup"]
    two = cfl.Model(v, f, resolution=12, threads=2)
    assert answers(two, models["torus"]) == answers(models["soup"], models["torus"])
    assert two.distinct_lists == models["soup"].distinct_lists
