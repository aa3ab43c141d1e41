"""Building, inspecting, saving, loading and pickling models."""

import os
import pathlib
import pickle
import types

import numpy as np
import pytest

import cfl
import reference
from conftest import DATA_DIR, MESHES, coarsened_model, needs_mesh_files


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


STATISTICS = ("resolution", "voxel_count", "leaves_per_depth", "leaves_without_list", "average_list_length",
              "longest_list", "distinct_lists", "memory_bytes", "coarsened", "build_seconds")


def check_statistics(model):
    """What holds for every model, uniform or adaptive."""
    s = model.statistics
    assert s == {key: getattr(model, key) for key in STATISTICS}
    assert isinstance(model.leaves_per_depth, list) and all(type(n) is int for n in model.leaves_per_depth)
    assert isinstance(model.coarsened, bool)
    # voxel_count counts the leaves, those without a list included, at every depth.
    assert sum(model.leaves_per_depth) == model.voxel_count
    assert model.leaves_per_depth[-1] > 0 and min(model.leaves_per_depth) >= 0
    # The finest level has 2^depth times the root cells along the longest axis.
    assert model.resolution % 2 ** (len(model.leaves_per_depth) - 1) == 0
    assert 0 <= model.leaves_without_list < model.voxel_count
    assert 1 <= model.longest_list <= model.triangle_count
    assert 0 < model.average_list_length <= model.longest_list
    assert 1 <= model.distinct_lists <= model.voxel_count - model.leaves_without_list
    assert model.memory_bytes > 8 * model.voxel_count
    assert model.build_seconds >= 0
    assert f"resolution {model.resolution}, {model.voxel_count} leaves" in repr(model)
    assert ("coarsened" in repr(model)) == model.coarsened


def test_build_statistics_of_uniform_grids_are_consistent(models):
    for name, model in models.items():
        check_statistics(model)
        # resolution=12 asks for the paper's uniform grid: 12 cells along the longest axis, all at depth 0,
        # the other axes at most as many; every cell keeps its list.
        assert model.resolution == 12
        assert model.leaves_per_depth == [model.voxel_count]
        assert 12 <= model.voxel_count <= 12 ** 3
        assert model.leaves_without_list == 0
        assert not model.coarsened


def test_build_statistics_of_adaptive_regions_are_consistent(adaptive_models):
    for name, model in adaptive_models.items():
        check_statistics(model)
        assert model.resolution > 0 and not model.coarsened
    # Cells are refined where lists are long: a finely tessellated sheet gets leaves below the root level
    # (the small test meshes' triangles are as large as the root cells, which then need no split).
    fine = cfl.Model(*reference.wavy_patch(n=33), threads=1)
    check_statistics(fine)
    assert len(fine.leaves_per_depth) > 1


def test_padding_grows_the_box_by_the_longest_extent_on_every_side():
    # A flat 2 x 2 square: padding p adds (p - 1) / 2 * 2 on every side, the flat axis too. A uniform grid of
    # 10 cells along the longest axis then has cells of (2 + 2 (p - 1)) / 10 and covers the flat axis's
    # 2 (p - 1) with as many more cells as it takes.
    v = np.array([[-1.0, -1.0, 0.0], [1.0, -1.0, 0.0], [1.0, 1.0, 0.0], [-1.0, 1.0, 0.0]])
    f = np.array([[0, 1, 2], [0, 2, 3]])
    for padding, flat_cells in ((1.0, 1), (2.0, 5), (3.0, 7)):  # 0 / 0.2 -> 1 layer, 2 / 0.4, 4 / 0.6 -> 7
        model = cfl.Model(v, f, resolution=10, padding=padding, threads=1)
        assert model.voxel_count == 10 * 10 * flat_cells, padding


def test_memory_limit_coarsens_adaptive_builds_and_keeps_them_exact(adaptive_models):
    v, f = reference.wavy_patch(n=33)
    full = cfl.Model(v, f, threads=1)
    assert len(full.leaves_per_depth) > 1  # the fine sheet refines, so a limit has something to stop
    model, limit = coarsened_model(v, f)
    assert model is not None, "no memory_limit coarsened the wavy sheet's build"
    check_statistics(model)
    assert model.coarsened and model.statistics["coarsened"] is True
    assert model.voxel_count < full.voxel_count
    # An explicit limit large enough changes nothing.
    roomy = cfl.Model(v, f, threads=1, memory_limit=100 * full.memory_bytes)
    assert not roomy.coarsened and roomy.leaves_per_depth == full.leaves_per_depth
    assert answers(roomy, adaptive_models["torus"]) == answers(full, adaptive_models["torus"])
    # Coarser lists are longer, never wrong: the answers still equal the brute force.
    rng = np.random.default_rng(41)
    vt, ft = MESHES["torus"]
    tolerance = 1e-9 * 12
    for k in range(12):
        X_WB = reference.random_pose(rng, [0.2, 0.8, 1.5, 4.0][k % 4])
        expected, _, _ = reference.brute_force_distance(v, f, np.eye(4), vt, ft, X_WB)
        for b in (adaptive_models["torus"], cfl.Mesh(vt, ft)):
            r = cfl.distance(model, None, b, X_WB)
            assert r.distance == pytest.approx(expected, abs=tolerance)
            assert np.linalg.norm(r.point_a - r.point_b) == pytest.approx(r.distance, abs=tolerance)
    # The flag and the per-depth counts survive save/load and pickling.
    clone = pickle.loads(pickle.dumps(model))
    assert clone.statistics == model.statistics and clone.coarsened
    assert answers(clone, adaptive_models["soup"]) == answers(model, adaptive_models["soup"])


@pytest.mark.parametrize("kind", ["uniform", "adaptive"])
def test_save_and_load_round_trip_answers_bit_for_bit(models, adaptive_models, kind, tmp_path):
    built = models if kind == "uniform" else adaptive_models
    for name in ("torus", "patch"):
        model = built[name]
        path = tmp_path / f"{name}.cfl"
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
    # from_file takes every build option of Model(), memory_limit included (on a sheet fine enough to refine).
    v, f = reference.wavy_patch(n=33)
    path = tmp_path / "fine_patch.obj"
    reference.write_obj(path, v, f)
    _, limit = coarsened_model(v, f)
    assert limit is not None, "no memory_limit coarsened the fine sheet's build"
    limited = cfl.Model.from_file(path, memory_limit=limit, threads=1)
    assert limited.coarsened
    assert limited.statistics["leaves_per_depth"] == cfl.Model(v, f, memory_limit=limit, threads=1).leaves_per_depth


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
