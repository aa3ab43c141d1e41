#pragma once
// Conversions between Python objects (NumPy arrays, sequences, trimesh-like meshes) and the library's types,
// with the checks that keep a bad argument from reaching C++ as anything but a Python exception.
//
// Conventions of every function here: a Python object of the wrong kind (not an array of numbers, a model
// of the wrong class) raises TypeError; the right kind with a wrong shape or value raises ValueError; the
// message names the argument, and the element (face, pose index) when it is one of many.

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>

#include <Eigen/Geometry>
#include <string>
#include <vector>

#include "cfl/mesh.h"

namespace cfl_python {

namespace py = pybind11;

/// Raises ValueError / TypeError with `message` (thrown as pybind11's C++ exceptions, which it translates).
[[noreturn]] void throwValueError(const std::string& message);
[[noreturn]] void throwTypeError(const std::string& message);

/// The mesh held by `vertices` ((n, 3) numbers) and `faces` ((m, 3) integers, each in [0, n)), copied into a
/// TriangleMesh. When `faces` is None, `vertices` may be any object with `.vertices` and `.faces`
/// attributes (trimesh.Trimesh, cfl.Mesh, a SimpleNamespace). Checks shapes, element kinds and index
/// ranges here (naming the face); finiteness and emptiness are left to cfl::validateMesh.
cfl::TriangleMesh meshFromPython(py::handle vertices, py::handle faces);

/// A 4x4 rigid transform from `pose` (anything NumPy turns into a (4, 4) array of numbers; None is the
/// identity). The last row must be exactly [0, 0, 0, 1]; the rotation is checked by cfl::validatePose.
/// `name` is the argument's name in messages. A float64 ndarray, the common case, is read in place.
Eigen::Isometry3d poseFromPython(py::handle pose, const char* name);

/// The (N, 4, 4) stack of poses in `poses`, each checked as by poseFromPython and named "name[i]".
std::vector<Eigen::Isometry3d> posesFromPython(py::handle poses, const char* name);

/// A read-only NumPy array over `data`, which `owner` keeps alive (no copy).
py::array readOnlyView(py::dtype dtype, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides,
                       const void* data, py::handle owner);

/// A new float64 array of shape (3,) holding `p`.
py::array_t<double> vectorToArray(const Eigen::Vector3d& p);

/// Accepts str, bytes and os.PathLike, as open() does.
std::string pathFromPython(py::handle path);

}  // namespace cfl_python
