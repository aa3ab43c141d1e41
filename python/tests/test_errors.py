"""Every bad input raises the documented exception with a message naming the culprit, never a crash.

TypeError: an argument of the wrong kind. ValueError: the right kind with a bad shape or value.
OSError: anything wrong while reading or writing a file (FileNotFoundError when it does not exist).
"""

import os
import pickle

import numpy as np
import pytest

import cfl
import reference
from conftest import MESHES, needs_mesh_files

V, F = MESHES["torus"]


@pytest.fixture(scope="module")
def a():
    return cfl.Model(V, F, resolution=8)


# --- meshes --------------------------------------------------------------------------------------------------

@pytest.mark.parametrize("build", [cfl.Mesh, lambda v, f: cfl.Model(v, f, resolution=8)])
@pytest.mark.parametrize("vertices,faces,error,message", [
    (V[:, :2], F, ValueError, r"vertices must have shape \(n, 3\), got \(96, 2\)"),
    (V.ravel(), F, ValueError, r"vertices must have shape \(n, 3\), got \(288,\)"),
    (V, F[:, :2], ValueError, r"faces must have shape \(m, 3\), got \(192, 2\)"),
    (V, F.ravel(), ValueError, r"faces must have shape"),
    (V.astype(complex), F, TypeError, "vertices must be an array of numbers, got an array of dtype complex128"),
    (V > 0, F, TypeError, "vertices must be an array of numbers.*bool"),
    ([["a", "b", "c"]], F, TypeError, "vertices must be an array of numbers, got a list"),
    (V, F.astype(float), TypeError, r"faces must be an array of integers \(vertex indices\).*float64"),
    (V, np.vstack([F, [[0, 1, 96]]]), ValueError, r"faces\[192\]: vertex index 96 is out of range \[0, 96\)"),
    (V, np.vstack([F[:5], [[0, -1, 2]]]), ValueError, r"faces\[5\]: vertex index -1 is out of range"),
    (V, np.vstack([F[:3], [[2**40, 1, 2]]]), ValueError, r"faces\[3\]: vertex index 1099511627776 is out of range"),
    (V, np.array([[0, 1, 2**64 - 1]], dtype=np.uint64), ValueError, r"faces\[0\]: vertex index 18446744073709551615"),
    (np.vstack([V[:4], [[0.0, np.nan, 1.0]]]), F[:2] * 0 + [0, 1, 4], ValueError, "vertex 4 .*non-finite"),
    (np.vstack([V[:4], [[0.0, np.inf, 1.0]]]), [[0, 1, 4]], ValueError, "vertex 4"),
    (np.vstack([V[:4], [[1e300, 0.0, 1.0]]]), [[0, 1, 4]], ValueError, "vertex 4"),
    (V, np.zeros((0, 3), dtype=int), ValueError, "triangle"),
    ([[0, 0, 0], [1, 1]], F, ValueError, ""),  # ragged: NumPy's own ValueError
])
def test_bad_meshes(build, vertices, faces, error, message):
    with pytest.raises(error, match=message):
        build(vertices, faces)


def test_object_without_faces_is_a_type_error():
    with pytest.raises(TypeError, match="faces is missing.*got a int"):
        cfl.Mesh(5)
    with pytest.raises(TypeError, match="faces is missing"):
        cfl.Model(V)


@pytest.mark.parametrize("options,error,message", [
    ({"resolution": -1}, ValueError, "resolution"),
    ({"padding": 0.5}, ValueError, "padding"),
    ({"padding": float("nan")}, ValueError, "padding"),
    ({"threads": -1}, ValueError, "threads must be >= 0"),
    ({"progress": 5}, TypeError, "progress must be None, True .* or a callable"),
    ({"resolution": "8"}, TypeError, ""),
    ({"memory_limit": -1}, ValueError, "memory_limit must be >= 0"),
    ({"memory_limit": 1.5e6}, TypeError, ""),
    # A uniform grid whose cells alone exceed the limit is refused, saying what it would need.
    ({"resolution": 64, "memory_limit": 100000}, ValueError, "resolution 64 needs .* cells .* memory limit of 100000"),
])
def test_bad_build_options(options, error, message, tmp_path):
    with pytest.raises(error, match=message):
        cfl.Model(V, F, **options)
    if cfl._cfl._have_mesh_files:
        path = tmp_path / "torus.obj"
        reference.write_obj(path, V, F)
        with pytest.raises(error, match=message):
            cfl.Model.from_file(path, **options)


# --- poses and query options ---------------------------------------------------------------------------------

@pytest.mark.parametrize("pose,error,message", [
    (np.eye(3), ValueError, r"pose_b must have shape \(4, 4\) \(a rigid transform\), got \(3, 3\)"),
    (np.eye(4)[None], ValueError, r"got \(1, 4, 4\)"),
    (reference.rigid(t=[1, 2, 3]) + np.diag([0, 0, 0, 1.0]), ValueError, r"last row is \[0, 0, 0, 1\]; got \[0, 0, 0, 2\]"),
    (np.vstack([np.eye(4)[:3], [[0.5, 0, 0, 1]]]), ValueError, "last row"),
    (np.diag([2.0, 2.0, 2.0, 1.0]), ValueError, "pose_b is not a rigid transform"),
    (np.diag([1.0, 1.0, -1.0, 1.0]), ValueError, "pose_b is not a rigid transform"),  # a reflection
    (reference.rigid(t=[np.nan, 0, 0]), ValueError, "pose_b is not finite"),
    (np.full((4, 4), "x"), TypeError, "pose_b must be an array of numbers"),
    ("identity", TypeError, "pose_b must be an array of numbers"),
    (np.eye(4).astype(complex), TypeError, "pose_b must be an array of numbers"),
])
def test_bad_poses(a, pose, error, message):
    with pytest.raises(error, match=message):
        cfl.distance(a, None, a, pose)
    with pytest.raises(error, match=message.replace("pose_b", "pose_a")):
        cfl.distance(a, pose, a, None)
    with pytest.raises(error, match=message.replace("pose_b", "pose_a")):
        cfl.collide(a, pose, a, None)


@pytest.mark.parametrize("options,error,message", [
    ({"rel_err": -0.1}, ValueError, "rel_err must be finite and >= 0"),
    ({"abs_err": float("nan")}, ValueError, "abs_err must be finite and >= 0"),
    ({"abs_err": float("inf")}, ValueError, "abs_err"),
    ({"upper_bound": -1.0}, ValueError, "upper_bound must be >= 0"),
    ({"upper_bound": float("nan")}, ValueError, "upper_bound"),
    ({"mode": "fast"}, ValueError, "mode must be 'hierarchical' or 'paper', got 'fast'"),
    ({"hint": (1, 2, 3)}, ValueError, "hint must be a pair"),
    ({"hint": 7}, TypeError, "hint must be None or a pair"),
    ({"hint": ("a", 1)}, TypeError, r"hint must be a pair of triangle ids \(ints\)"),
])
def test_bad_query_options(a, options, error, message):
    with pytest.raises(error, match=message):
        cfl.distance(a, None, a, None, **options)
    with pytest.raises(error, match=message):
        cfl.distances(a, None, a, np.eye(4)[None], **options)


def test_wrong_model_types(a):
    mesh = cfl.Mesh(V, F)
    with pytest.raises(TypeError, match=r"a must be a cfl.Model \(the side whose Voronoi regions answer the query\), got a Mesh"):
        cfl.distance(mesh, None, a, None)
    with pytest.raises(TypeError, match="b must be a cfl.Model or a cfl.Mesh, got a ndarray"):
        cfl.distance(a, None, V, None)
    with pytest.raises(TypeError, match="a must be a cfl.Model"):
        cfl.distances(None, None, a, np.eye(4)[None])
    with pytest.raises(TypeError, match="a must be a cfl.Model or a cfl.Mesh, got a str"):
        cfl.collide("torus", None, a, None)
    with pytest.raises(ValueError, match="max_contacts must be >= 0"):
        cfl.collide(a, None, a, None, max_contacts=-1)


def test_bad_pose_stacks_name_the_pose(a):
    poses = np.tile(np.eye(4), (10, 1, 1))
    poses[7, 0, 0] = 3.0
    with pytest.raises(ValueError, match=r"poses_b\[7\] is not a rigid transform"):
        cfl.distances(a, None, a, poses)
    poses[7] = np.eye(4)
    poses[4, 3, 0] = 1.0
    with pytest.raises(ValueError, match=r"poses_b\[4\] must be a rigid transform, whose last row"):
        cfl.distances(a, None, a, poses)
    with pytest.raises(ValueError, match=r"poses_b must have shape \(N, 4, 4\) \(N rigid transforms\), got \(4, 4\)"):
        cfl.distances(a, None, a, np.eye(4))
    with pytest.raises(ValueError, match=r"got \(2, 3, 4\)"):
        cfl.distances(a, None, a, np.zeros((2, 3, 4)))
    with pytest.raises(TypeError, match="poses_b must be an array of numbers"):
        cfl.distances(a, None, a, [["x"]])
    with pytest.raises(ValueError, match="threads must be >= 0"):
        cfl.distances(a, None, a, np.eye(4)[None], threads=-2)
    with pytest.raises(ValueError, match="chunk_size must be >= 0"):
        cfl.distances(a, None, a, np.eye(4)[None], chunk_size=-1)


# --- files ---------------------------------------------------------------------------------------------------

def test_missing_files_raise_file_not_found(tmp_path):
    missing = tmp_path / "nothing.obj"
    loaders = [cfl.Model.load] + ([cfl.Model.from_file, cfl.Mesh.from_file] if cfl._cfl._have_mesh_files else [])
    for load in loaders:
        with pytest.raises(FileNotFoundError, match="nothing.obj") as raised:
            load(missing)
        assert raised.value.errno == 2


@needs_mesh_files
def test_malformed_mesh_files_raise_os_error_naming_the_line(tmp_path):
    path = tmp_path / "bad.obj"
    path.write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\nv 1 1 zero\nf 1 2 3\n")
    with pytest.raises(OSError, match=r"bad.obj.*line 4") as raised:
        cfl.Model.from_file(path)
    assert not isinstance(raised.value, FileNotFoundError)
    path.write_text("v 0 0 0\nv 1 0 0\nf 1 2 9\n")
    with pytest.raises(OSError, match="bad.obj"):
        cfl.Mesh.from_file(path)
    empty = tmp_path / "empty.obj"
    empty.write_text("")
    with pytest.raises(OSError, match="empty.obj"):
        cfl.Mesh.from_file(empty)
    with pytest.raises(OSError):
        cfl.Mesh.from_file(tmp_path)  # a directory


def test_corrupt_model_files_raise_os_error(a, tmp_path):
    good = tmp_path / "good.cfl"
    a.save(good)
    data = good.read_bytes()
    cases = {
        "truncated.cfl": data[: len(data) // 2],
        "flipped.cfl": data[:100] + bytes([data[100] ^ 0xFF]) + data[101:],
        "text.cfl": b"not a cfl file at all",
        "empty.cfl": b"",
    }
    for name, content in cases.items():
        (tmp_path / name).write_bytes(content)
        with pytest.raises(OSError, match=name) as raised:
            cfl.Model.load(tmp_path / name)
        assert not isinstance(raised.value, FileNotFoundError)


def test_unwritable_paths_raise_os_error(a, tmp_path):
    with pytest.raises(OSError, match="no_such_dir"):
        a.save(tmp_path / "no_such_dir" / "model.cfl")
    with pytest.raises(OSError):
        a.save(tmp_path)  # a directory


def test_paths_of_the_wrong_type_are_type_errors(a):
    for call in (lambda: a.save(3), lambda: cfl.Model.load(None), lambda: cfl.Mesh.from_file(["x.obj"])):
        with pytest.raises(TypeError):
            call()


def test_bad_pickle_states_are_value_errors():
    with pytest.raises(ValueError, match="pickled cfl.Model"):
        cfl.Model.__new__(cfl.Model).__setstate__((b"garbage",))
    with pytest.raises(ValueError, match="bad pickle state"):
        cfl.Model.__new__(cfl.Model).__setstate__(("text", 1))
    with pytest.raises(ValueError, match="bad pickle state"):
        cfl.Mesh.__new__(cfl.Mesh).__setstate__((V,))
