// The extension module cfl._cfl: the public C++ API (mesh models, CFL models, their files, distance,
// collision and batch queries) in Python's conventions. python/cfl/__init__.py re-exports it as `cfl`;
// python/cfl/__init__.pyi describes it for type checkers.
//
// Ownership: a Model or Mesh is a std::shared_ptr to the immutable C++ model, so queries may run with the
// GIL released while other Python threads use the same objects; the arguments of a call keep them alive.

#include "cfl/batch_query.h"
#include "cfl/cfl_file.h"
#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/penetration.h"
#include "cfl/point_query.h"
#include "cfl/error.h"
#include "cfl/mesh.h"
#include "cfl/mesh_model.h"
#include "conversions.h"
#ifdef CFL_PYTHON_HAVE_IO
#include "cfl/mesh_io.h"
#endif

#include <pybind11/numpy.h>
#include <pybind11/pybind11.h>
#include <pybind11/stl.h>

#include <cerrno>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <memory>
#include <optional>
#include <sstream>
#include <string>
#include <vector>

namespace py = pybind11;
using namespace pybind11::literals;

namespace cfl_python {
namespace {

// ---------------------------------------------------------------------------------------------------------
// Errors

// Runs `body`, turning a cfl::Error into OSError (FileNotFoundError when a file to read does not exist), with
// the library's message, which starts with the path. Every problem met while reading or writing a file,
// including a file whose contents are invalid, is an OSError: that is what Python code around file I/O
// catches.
template <typename Body>
auto withFileErrors(const std::string& path, bool reading, Body body) -> decltype(body()) {
  try {
    return body();
  } catch (const cfl::Error& error) {
    std::error_code ignored;
    const bool missing = reading && !std::filesystem::exists(path, ignored);
    // OSError(ENOENT, message) is constructed as a FileNotFoundError by Python itself.
    py::object exception = missing ? py::reinterpret_borrow<py::object>(PyExc_OSError)(ENOENT, error.what())
                                   : py::reinterpret_borrow<py::object>(PyExc_OSError)(error.what());
    PyErr_SetObject(reinterpret_cast<PyObject*>(Py_TYPE(exception.ptr())), exception.ptr());
    throw py::error_already_set();
  }
}

// ---------------------------------------------------------------------------------------------------------
// Building

// Relays BuildOptions::progress to a Python callable. The builder calls it from the calling thread (the one
// that released the GIL), so it takes the GIL back for the call. An exception from the callable cannot be
// thrown through the builder (its worker threads would be left running), so the first one is kept, later
// reports are dropped, and it is raised once the build has returned.
struct ProgressRelay {
  py::object callback;
  std::optional<py::error_already_set> error;

  void operator()(double fraction) {
    py::gil_scoped_acquire gil;
    if (error) return;
    try {
      callback(fraction);
    } catch (py::error_already_set& raised) {
      error.emplace(std::move(raised));
    }
  }
};

py::object progressCallback(py::handle progress) {
  if (progress.is_none() || (PyBool_Check(progress.ptr()) && !progress.cast<bool>())) return py::none();
  if (PyBool_Check(progress.ptr())) return py::module_::import("cfl._progress").attr("ProgressBar")();
  if (!PyCallable_Check(progress.ptr())) {
    throwTypeError("progress must be None, True (a bar on stderr) or a callable taking the fraction done, got a " +
                   std::string(py::str(py::type::handle_of(progress).attr("__name__"))));
  }
  return py::reinterpret_borrow<py::object>(progress);
}

std::shared_ptr<cfl::CflModel> buildModel(cfl::TriangleMesh mesh, int resolution, double padding, bool topology_culling,
                                          int threads, std::int64_t memory_limit, py::handle progress) {
  // The builder checks resolution, padding and memory_limit itself (its cfl::Error becomes ValueError);
  // threads only here, since it reads a negative count as "all".
  if (threads < 0) throwValueError("threads must be >= 0 (0 = every hardware thread), got " + std::to_string(threads));
  cfl::BuildOptions options;
  options.resolution = resolution;
  options.padding = padding;
  options.topology_culling = topology_culling;
  options.threads = threads;
  options.memory_limit = memory_limit;
  ProgressRelay relay{progressCallback(progress), std::nullopt};
  if (!relay.callback.is_none()) options.progress = [&relay](double fraction) { relay(fraction); };
  std::shared_ptr<cfl::CflModel> model;
  {
    py::gil_scoped_release release;
    model = std::make_shared<cfl::CflModel>(cfl::buildCflModel(std::move(mesh), options));
  }
  if (relay.error) throw *relay.error;
  return model;
}

// ---------------------------------------------------------------------------------------------------------
// Queries

cfl::DistanceOptions distanceOptions(double rel_err, double abs_err, double upper_bound, const std::string& mode,
                                     py::handle hint) {
  cfl::DistanceOptions options;
  if (!(rel_err >= 0 && std::isfinite(rel_err)))
    throwValueError("rel_err must be finite and >= 0, got " + py::repr(py::float_(rel_err)).cast<std::string>());
  if (!(abs_err >= 0 && std::isfinite(abs_err)))
    throwValueError("abs_err must be finite and >= 0, got " + py::repr(py::float_(abs_err)).cast<std::string>());
  if (!(upper_bound >= 0))
    throwValueError("upper_bound must be >= 0 (inf for none), got " +
                    py::repr(py::float_(upper_bound)).cast<std::string>());
  options.rel_err = rel_err;
  options.abs_err = abs_err;
  options.upper_bound = upper_bound;
  if (mode == "hierarchical") {
    options.mode = cfl::QueryMode::kHierarchical;
  } else if (mode == "paper") {
    options.mode = cfl::QueryMode::kPaper;
  } else {
    throwValueError("mode must be 'hierarchical' or 'paper', got '" + mode + "'");
  }
  if (!hint.is_none()) {
    // Out-of-range ids are ignored by the query (a stale hint from another model is harmless), so only the
    // form is checked.
    py::tuple pair;
    try {
      pair = py::tuple(py::reinterpret_borrow<py::object>(hint));
    } catch (py::error_already_set&) {
      throwTypeError("hint must be None or a pair (triangle of a, triangle of b)");
    }
    if (pair.size() != 2)
      throwValueError("hint must be a pair (triangle of a, triangle of b), got " + std::to_string(pair.size()) +
                      " items");
    try {
      options.hint_triangle_a = pair[0].cast<int>();
      options.hint_triangle_b = pair[1].cast<int>();
    } catch (const py::cast_error&) {
      throwTypeError("hint must be a pair of triangle ids (ints)");
    }
  }
  return options;
}

const cfl::CflModel& modelArgument(py::handle object, const char* name) {
  if (!py::isinstance<cfl::CflModel>(object)) {
    throwTypeError(std::string(name) + " must be a cfl.Model (the side whose Voronoi regions answer the query), got a " +
                   std::string(py::str(py::type::handle_of(object).attr("__name__"))));
  }
  return object.cast<const cfl::CflModel&>();
}

// The mesh of a Model or a Mesh, for the queries that need no Voronoi regions.
const cfl::MeshModel& meshArgument(py::handle object, const char* name) {
  if (py::isinstance<cfl::CflModel>(object)) return object.cast<const cfl::CflModel&>().geometry;
  if (py::isinstance<cfl::MeshModel>(object)) return object.cast<const cfl::MeshModel&>();
  throwTypeError(std::string(name) + " must be a cfl.Model or a cfl.Mesh, got a " +
                 std::string(py::str(py::type::handle_of(object).attr("__name__"))));
}

// The query's two models as the C++ overloads take them: B with its regions (a Model) or without (a Mesh).
struct QueryModels {
  const cfl::CflModel* a = nullptr;
  const cfl::CflModel* b_model = nullptr;  // set when b is a Model
  const cfl::MeshModel* b_mesh = nullptr;  // set when b is a Mesh
};

QueryModels queryModels(py::handle a, py::handle b) {
  QueryModels models;
  models.a = &modelArgument(a, "a");
  if (py::isinstance<cfl::CflModel>(b)) {
    models.b_model = &b.cast<const cfl::CflModel&>();
  } else {
    models.b_mesh = &meshArgument(b, "b");
  }
  return models;
}

cfl::DistanceResult distance(py::handle a, py::handle pose_a, py::handle b, py::handle pose_b, double rel_err,
                             double abs_err, double upper_bound, const std::string& mode, py::handle hint) {
  const QueryModels models = queryModels(a, b);
  const Eigen::Isometry3d X_WA = poseFromPython(pose_a, "pose_a");
  const Eigen::Isometry3d X_WB = poseFromPython(pose_b, "pose_b");
  const cfl::DistanceOptions options = distanceOptions(rel_err, abs_err, upper_bound, mode, hint);
  // Released even for one query: it takes microseconds to milliseconds, long enough for other Python threads
  // (possibly querying the same models) to use the time.
  py::gil_scoped_release release;
  return models.b_model ? cfl::computeDistance(*models.a, X_WA, *models.b_model, X_WB, options)
                        : cfl::computeDistance(*models.a, X_WA, *models.b_mesh, X_WB, options);
}

// The results of a batch as NumPy arrays. They are strided views into the std::vector<DistanceResult> that
// cfl::computeDistances filled (kept alive by a capsule they share), so nothing is copied after the queries.
struct DistanceBatch {
  py::array distance, point_a, point_b, triangle_a, triangle_b, triangle_pairs, voxel_tests;
};

DistanceBatch batchArrays(std::unique_ptr<std::vector<cfl::DistanceResult>> results) {
  const auto count = static_cast<py::ssize_t>(results->size());
  if (count == 0) {
    const std::vector<py::ssize_t> no_points{0, 3};
    return {py::array_t<double>(0), py::array_t<double>(no_points), py::array_t<double>(no_points), py::array_t<int>(0),
            py::array_t<int>(0),    py::array_t<std::int64_t>(0),   py::array_t<std::int64_t>(0)};
  }
  const cfl::DistanceResult& first = results->front();
  py::capsule owner(results.get(), [](void* vector) { delete static_cast<std::vector<cfl::DistanceResult>*>(vector); });
  results.release();
  // Field offsets are taken from an element rather than offsetof, which Eigen members make non-portable.
  const py::ssize_t row = sizeof(cfl::DistanceResult);
  const auto column = static_cast<py::ssize_t>(sizeof(double));
  auto view = [&](py::dtype dtype, const void* field) {
    return py::array(std::move(dtype), {count}, {row}, field, owner);
  };
  auto points = [&](const Eigen::Vector3d& field) {
    return py::array(py::dtype::of<double>(), {count, py::ssize_t{3}}, {row, column}, field.data(), owner);
  };
  return {view(py::dtype::of<double>(), &first.distance),
          points(first.point_a),
          points(first.point_b),
          view(py::dtype::of<int>(), &first.triangle_a),
          view(py::dtype::of<int>(), &first.triangle_b),
          view(py::dtype::of<std::int64_t>(), &first.counters.triangle_pairs),
          view(py::dtype::of<std::int64_t>(), &first.counters.voxel_tests)};
}

DistanceBatch distances(py::handle a, py::handle pose_a, py::handle b, py::handle poses_b, double rel_err,
                        double abs_err, double upper_bound, const std::string& mode, py::handle hint, int threads,
                        int chunk_size) {
  const QueryModels models = queryModels(a, b);
  const Eigen::Isometry3d X_WA = poseFromPython(pose_a, "pose_a");
  const std::vector<Eigen::Isometry3d> X_WB = posesFromPython(poses_b, "poses_b");
  cfl::BatchOptions options;
  options.distance = distanceOptions(rel_err, abs_err, upper_bound, mode, hint);
  if (threads < 0) throwValueError("threads must be >= 0 (0 = every hardware thread), got " + std::to_string(threads));
  if (chunk_size < 0) throwValueError("chunk_size must be >= 0 (0 = automatic), got " + std::to_string(chunk_size));
  options.threads = threads;
  options.chunk_size = chunk_size;
  auto results = std::make_unique<std::vector<cfl::DistanceResult>>(X_WB.size());
  {
    py::gil_scoped_release release;
    if (models.b_model) {
      cfl::computeDistances(*models.a, X_WA, *models.b_model, X_WB.data(), X_WB.size(), results->data(), options);
    } else {
      cfl::computeDistances(*models.a, X_WA, *models.b_mesh, X_WB.data(), X_WB.size(), results->data(), options);
    }
  }
  return batchArrays(std::move(results));
}

// The answers of point_distances(), views of the C++ results like DistanceBatch.
struct PointBatch {
  py::array distance, closest_point, gradient, triangle;
};

std::vector<Eigen::Vector3d> pointsFromPython(py::handle points, const char* name) {
  const py::array array = py::array::ensure(points);
  if (!array) throwTypeError(std::string(name) + " must be an (N, 3) array of numbers");
  if (array.dtype().kind() != 'f' && array.dtype().kind() != 'i' && array.dtype().kind() != 'u')
    throwTypeError(std::string(name) + " must hold numbers, got dtype " + std::string(py::str(array.dtype())));
  if (array.ndim() != 2 || array.shape(1) != 3) {
    std::string shape = "(";
    for (py::ssize_t k = 0; k < array.ndim(); ++k) shape += (k ? ", " : "") + std::to_string(array.shape(k));
    throwValueError(std::string(name) + " must have shape (N, 3), got " + shape + (array.ndim() == 1 ? ",)" : ")"));
  }
  const auto values = py::array_t<double, py::array::c_style | py::array::forcecast>::ensure(array);
  std::vector<Eigen::Vector3d> result(static_cast<std::size_t>(values.shape(0)));
  const double* data = values.data();
  for (std::size_t i = 0; i < result.size(); ++i) result[i] = Eigen::Vector3d(data[3 * i], data[3 * i + 1], data[3 * i + 2]);
  return result;
}

PointBatch pointDistances(py::handle model, py::handle pose, py::handle points, bool signed_distance,
                          const std::string& sign_method, double upper_bound, int threads) {
  const cfl::CflModel& m = modelArgument(model, "model");
  const Eigen::Isometry3d X_WM = poseFromPython(pose, "pose");
  const std::vector<Eigen::Vector3d> p_W = pointsFromPython(points, "points");
  cfl::PointQueryOptions options;
  options.signed_distance = signed_distance;
  if (sign_method == "auto") options.sign_method = cfl::SignMethod::kAuto;
  else if (sign_method == "winding") options.sign_method = cfl::SignMethod::kWindingNumber;
  else throwValueError("sign_method must be 'auto' or 'winding', got '" + sign_method + "'");
  options.upper_bound = upper_bound;
  if (threads < 0) throwValueError("threads must be >= 0 (0 = every hardware thread), got " + std::to_string(threads));
  options.threads = threads;
  auto results = std::make_unique<std::vector<cfl::PointDistance>>(p_W.size());
  {
    py::gil_scoped_release release;
    cfl::computePointDistances(m, X_WM, p_W.data(), p_W.size(), results->data(), options);
  }
  const auto count = static_cast<py::ssize_t>(results->size());
  if (count == 0) {
    const std::vector<py::ssize_t> none{0, 3};
    return {py::array_t<double>(0), py::array_t<double>(none), py::array_t<double>(none), py::array_t<int>(0)};
  }
  const cfl::PointDistance& first = results->front();
  py::capsule owner(results.get(), [](void* vector) { delete static_cast<std::vector<cfl::PointDistance>*>(vector); });
  results.release();
  const py::ssize_t row = sizeof(cfl::PointDistance);
  const auto column = static_cast<py::ssize_t>(sizeof(double));
  auto vectors = [&](const Eigen::Vector3d& field) {
    return py::array(py::dtype::of<double>(), {count, py::ssize_t{3}}, {row, column}, field.data(), owner);
  };
  return {py::array(py::dtype::of<double>(), {count}, {row}, &first.distance, owner), vectors(first.closest_point),
          vectors(first.gradient), py::array(py::dtype::of<int>(), {count}, {row}, &first.triangle, owner)};
}

cfl::DistanceResult signedDistance(py::handle a, py::handle pose_a, py::handle b, py::handle pose_b) {
  const cfl::CflModel& model_a = modelArgument(a, "a");
  const cfl::CflModel& model_b = modelArgument(b, "b");
  const Eigen::Isometry3d X_WA = poseFromPython(pose_a, "pose_a");
  const Eigen::Isometry3d X_WB = poseFromPython(pose_b, "pose_b");
  py::gil_scoped_release release;
  return cfl::computeSignedDistance(model_a, X_WA, model_b, X_WB);
}

cfl::PenetrationResult penetration(py::handle a, py::handle pose_a, py::handle b, py::handle pose_b, double tolerance) {
  const cfl::CflModel& model_a = modelArgument(a, "a");
  const cfl::CflModel& model_b = modelArgument(b, "b");
  const Eigen::Isometry3d X_WA = poseFromPython(pose_a, "pose_a");
  const Eigen::Isometry3d X_WB = poseFromPython(pose_b, "pose_b");
  cfl::PenetrationOptions options;
  options.tolerance = tolerance;
  py::gil_scoped_release release;
  return cfl::computePenetration(model_a, X_WA, model_b, X_WB, options);
}

struct CollisionResult {
  bool colliding = false;
  std::vector<cfl::Contact> contacts;
};

CollisionResult collide(py::handle a, py::handle pose_a, py::handle b, py::handle pose_b, long long max_contacts) {
  const cfl::MeshModel& mesh_a = meshArgument(a, "a");
  const cfl::MeshModel& mesh_b = meshArgument(b, "b");
  const Eigen::Isometry3d X_WA = poseFromPython(pose_a, "pose_a");
  const Eigen::Isometry3d X_WB = poseFromPython(pose_b, "pose_b");
  if (max_contacts < 0) throwValueError("max_contacts must be >= 0, got " + std::to_string(max_contacts));
  CollisionResult result;
  py::gil_scoped_release release;
  // With no contact list the C++ query stops at the first intersecting pair, which max_contacts = 0 asks for.
  result.colliding = cfl::computeCollision(mesh_a, X_WA, mesh_b, X_WB, static_cast<std::size_t>(max_contacts),
                                           max_contacts > 0 ? &result.contacts : nullptr);
  return result;
}

// ---------------------------------------------------------------------------------------------------------
// Files

cfl::TriangleMesh readMesh(py::handle path_object) {
  const std::string path = pathFromPython(path_object);
#ifdef CFL_PYTHON_HAVE_IO
  return withFileErrors(path, true, [&] {
    py::gil_scoped_release release;
    return cfl::loadMesh(path);
  });
#else
  PyErr_SetString(PyExc_NotImplementedError,
                  (path + ": this cfl module was built without mesh files (CFL_BUILD_IO=OFF)").c_str());
  throw py::error_already_set();
#endif
}

// ---------------------------------------------------------------------------------------------------------
// Shared pieces of the Model and Mesh classes

py::array verticesView(py::handle self, const cfl::TriangleMesh& mesh) {
  return readOnlyView(py::dtype::of<double>(), {static_cast<py::ssize_t>(mesh.vertices.size()), 3},
                      {static_cast<py::ssize_t>(sizeof(Eigen::Vector3d)), static_cast<py::ssize_t>(sizeof(double))},
                      mesh.vertices.data(), self);
}

py::array facesView(py::handle self, const cfl::TriangleMesh& mesh) {
  static_assert(sizeof(std::array<int, 3>) == 3 * sizeof(int), "faces are read as an (m, 3) int array");
  return readOnlyView(py::dtype::of<int>(), {static_cast<py::ssize_t>(mesh.triangles.size()), 3},
                      {static_cast<py::ssize_t>(sizeof(std::array<int, 3>)), static_cast<py::ssize_t>(sizeof(int))},
                      mesh.triangles.data(), self);
}

py::array boundsArray(const cfl::Aabb& box) {
  py::array_t<double> bounds({py::ssize_t{2}, py::ssize_t{3}});
  auto view = bounds.mutable_unchecked<2>();
  for (int k = 0; k < 3; ++k) {
    view(0, k) = box.min[k];
    view(1, k) = box.max[k];
  }
  return bounds;
}

std::string megabytes(std::int64_t bytes) {
  std::ostringstream text;
  text.precision(1);
  text << std::fixed << bytes / 1e6 << " MB";
  return text.str();
}

// BuildStatistics::leaves_per_depth as a Python list of int (a fresh one each time: the model is immutable).
py::list leavesPerDepth(const cfl::BuildStatistics& statistics) {
  py::list counts;
  for (std::int64_t count : statistics.leaves_per_depth) counts.append(count);
  return counts;
}

const char* const kModuleDoc = R"doc(Exact minimum distance between non-convex triangle meshes (cfl).

A Model is a triangle mesh with its precomputed discrete Voronoi regions (cubic cells around the mesh,
refined where needed, each listing the triangles that can be closest to a point in it); a Mesh is a
triangle mesh with only its bounding volume hierarchy. distance(a, pose_a, b, pose_b) returns the exact
minimum distance between a Model a and a Model or Mesh b, with the two closest points and their triangle
ids; distances() does the same for many poses of b at once on all cores; collide() reports intersecting
triangle pairs.

Conventions
-----------
* Units: lengths are in the meshes' own unit (whatever the vertex coordinates are in); nothing is scaled.
* Frames: each mesh's vertices are in its own frame (A for a, B for b). A pose is a 4x4 rigid transform
  X_WA, "world from A": a point p_A of the mesh is at X_WA @ [p_A, 1] in the world frame W. Its upper-left
  3x3 block must be a rotation (orthonormal, det +1, to 1e-6) and its last row exactly [0, 0, 0, 1]; no
  scale or shear. None stands for the identity.
* Results are in the world frame: point_a and point_b are world coordinates; triangle ids are row indices
  into the models' faces arrays (model.faces: the faces it was built from, or read from its file).
* Triangles are two-sided and may form open, non-manifold or self-intersecting meshes; distances are
  unsigned (>= 0) and 0 when the meshes touch or intersect, in which case point_a == point_b is a point
  of the intersection.
* Errors: a wrong kind of argument raises TypeError, a bad value (shape, index, non-finite coordinate,
  non-rigid pose, bad option) ValueError, and any problem reading or writing a file OSError
  (FileNotFoundError when the file does not exist); messages name the culprit.
* Threads: models are immutable; every query releases the GIL, so Python threads may query shared models
  concurrently.
)doc";

}  // namespace
}  // namespace cfl_python

PYBIND11_MODULE(_cfl, m) {
  using namespace cfl_python;
  m.doc() = kModuleDoc;
  // pybind11's generated signatures would show every flexible argument as "handle"; each docstring starts
  // with the signature in the stub's (cfl/__init__.pyi) terms instead.
  py::options options;
  options.disable_function_signatures();
  m.attr("__version__") = CFL_VERSION;
  // Whether Model.from_file and Mesh.from_file can read meshes (cfl::cfl_io was built); the tests skip them
  // when not.
#ifdef CFL_PYTHON_HAVE_IO
  m.attr("_have_mesh_files") = true;
#else
  m.attr("_have_mesh_files") = false;
#endif

  py::register_exception_translator([](std::exception_ptr pointer) {
    try {
      if (pointer) std::rethrow_exception(pointer);
    } catch (const cfl::Error& error) {
      PyErr_SetString(PyExc_ValueError, error.what());
    }
  });

  const cfl::BuildOptions build_defaults;

  // --- Mesh ------------------------------------------------------------------------------------------------
  py::class_<cfl::MeshModel, std::shared_ptr<cfl::MeshModel>> mesh(m, "Mesh", R"doc(
A triangle mesh with its bounding volume hierarchy: what a query needs of its second model b. Cheap to
build (O(n log n), no Voronoi regions); use a Model instead where the mesh is the first argument of distance().
Immutable. Pickles.
)doc");
  mesh.def(py::init([](py::handle vertices, py::handle faces) {
             cfl::TriangleMesh triangles = meshFromPython(vertices, faces);
             py::gil_scoped_release release;
             return std::make_shared<cfl::MeshModel>(cfl::makeMeshModel(std::move(triangles)));
           }),
           "vertices"_a, "faces"_a = py::none(),
           R"doc(Mesh(vertices: ArrayLike | MeshLike, faces: ArrayLike | None = None)

Mesh(vertices, faces) or Mesh(obj)

vertices: (n, 3) array of numbers, the vertex coordinates in the mesh's own frame and unit.
faces: (m, 3) array of integers, each row three indices into vertices (a triangle).
obj: instead of the two arrays, any object with .vertices and .faces (trimesh.Trimesh, cfl.Mesh, ...).

Raises TypeError for arrays that do not hold numbers (faces: integers), ValueError for a wrong shape, an
index out of range (naming the face), a non-finite coordinate or no face at all.
)doc");
  mesh.def_static(
      "from_file",
      [](py::handle path) {
        cfl::TriangleMesh triangles = readMesh(path);
        py::gil_scoped_release release;
        return std::make_shared<cfl::MeshModel>(cfl::makeMeshModel(std::move(triangles)));
      },
      "path"_a, R"doc(from_file(path: str | bytes | os.PathLike) -> Mesh

Reads a mesh file: OBJ and ASCII STL natively in double precision, binary STL, PLY, OFF, glTF, Collada and
the other formats assimp reads (as 32-bit floats). All meshes of the file become one triangle soup in the
file's frame and unit; polygons are triangulated; triangle i is the i-th triangle of the file.
Raises OSError (FileNotFoundError when missing) with a message naming the file and, for OBJ/STL, the line.
)doc");
  mesh.def_property_readonly(
      "vertices", [](py::object self) { return verticesView(self, self.cast<const cfl::MeshModel&>().mesh); },
      "(n, 3) float64 read-only view of the vertices (mesh frame).");
  mesh.def_property_readonly(
      "faces", [](py::object self) { return facesView(self, self.cast<const cfl::MeshModel&>().mesh); },
      "(m, 3) int32 read-only view of the triangles' vertex indices.");
  mesh.def_property_readonly(
      "bounds", [](const cfl::MeshModel& self) { return boundsArray(self.bounds); },
      "(2, 3) array: min and max corner of the bounding box of the used vertices (mesh frame).");
  mesh.def_property_readonly("triangle_count", [](const cfl::MeshModel& self) { return self.mesh.triangles.size(); });
  mesh.def_property_readonly("vertex_count", [](const cfl::MeshModel& self) { return self.mesh.vertices.size(); });
  mesh.def("__repr__", [](const cfl::MeshModel& self) {
    return "cfl.Mesh(" + std::to_string(self.mesh.triangles.size()) + " triangles, " +
           std::to_string(self.mesh.vertices.size()) + " vertices)";
  });
  mesh.def(py::pickle([](py::object self) { return py::make_tuple(self.attr("vertices"), self.attr("faces")); },
                      [](py::tuple state) {
                        if (state.size() != 2) throwValueError("cfl.Mesh: bad pickle state");
                        return std::make_shared<cfl::MeshModel>(cfl::makeMeshModel(meshFromPython(state[0], state[1])));
                      }));

  // --- Model -----------------------------------------------------------------------------------------------
  py::class_<cfl::CflModel, std::shared_ptr<cfl::CflModel>> model(m, "Model", R"doc(
A triangle mesh with its discrete Voronoi regions: cubic cells around the mesh, each leaf cell listing the
triangles that can be closest to a point in it. By default the regions are adaptive: cells are refined
where their lists are long (near the surface) and kept coarse where lists are short (far from the mesh,
over large flat triangles), so memory grows with the surface, not with the bounding box. Building costs
seconds for meshes of thousands of triangles (save() it to build once); queries then take microseconds.
Immutable and thread-safe. Pickles (as the bytes of a .cfl file).

The build statistics are attributes: resolution, voxel_count (leaves), leaves_per_depth,
leaves_without_list, average_list_length, longest_list, distinct_lists, memory_bytes, coarsened,
build_seconds (also together as the dict `statistics`).
)doc");
  model.def(
      py::init([](py::handle vertices, py::handle faces, int resolution, double padding, bool topology_culling,
                  int threads, std::int64_t memory_limit, py::handle progress) {
        return buildModel(meshFromPython(vertices, faces), resolution, padding, topology_culling, threads,
                          memory_limit, progress);
      }),
      "vertices"_a, "faces"_a = py::none(), py::kw_only(), "resolution"_a = build_defaults.resolution,
      "padding"_a = build_defaults.padding, "topology_culling"_a = build_defaults.topology_culling,
      "threads"_a = build_defaults.threads, "memory_limit"_a = build_defaults.memory_limit, "progress"_a = py::none(),
      R"doc(Model(vertices: ArrayLike | MeshLike, faces: ArrayLike | None = None, *, resolution: int = 0, padding: float = 3.0, topology_culling: bool = True, threads: int = 0, memory_limit: int = 0, progress: None | bool | Callable[[float], Any] = None)

Model(vertices, faces, *, ...) or Model(obj, *, ...)

Builds the discrete Voronoi regions of a mesh: cubic cells around it, each leaf listing the triangles that
can be closest to a point in it.

vertices: (n, 3) array of numbers, vertex coordinates in the mesh's own frame and unit.
faces: (m, 3) array of integers, each row three indices into vertices. Triangles need no topology: open,
    non-manifold, duplicated or degenerate triangles are fine.
obj: instead of the two arrays, any object with .vertices and .faces (trimesh.Trimesh, cfl.Mesh, ...).
resolution: 0 (the default) builds adaptive regions: a coarse root grid whose cells split in eight where
    their lists are long and stay whole where lists are short, sized automatically; a leaf whose list
    would still be too long to pay off stores none, and queries use the mesh's hierarchy there.
    N > 0 builds the paper's uniform grid instead, N cells along the longest axis of the padded box and
    no refinement; its build time and memory grow with N cubed.
padding: the regions cover the mesh's bounding box grown on every side by (padding - 1) / 2 times its
    longest extent, the same margin on every axis (>= 1; the default 3 leaves one longest extent on each
    side). Queries stay exact outside the regions, only slower; outside cells are coarse, so a large
    padding costs little memory.
topology_culling: drop list entries provably covered by a neighbouring triangle (conservative on any mesh).
threads: build threads, 0 = every hardware thread. The model does not depend on it.
memory_limit: upper bound in bytes on the regions' memory (the mesh and its hierarchy come on top); 0 =
    the smaller of half of the machine's physical memory and 32 MiB + 2 KiB per triangle. An adaptive
    build that would exceed it stops refining (lists get longer, answers stay exact) and sets
    `coarsened`; a limit that the starting grid's cells alone exceed (for resolution > 0, the whole grid)
    is refused.
progress: None, True for a progress bar on stderr, or a callable called with the fraction done in [0, 1]
    a few times per second from this thread. An exception it raises is re-raised when the build ends.

Raises TypeError / ValueError as Mesh() does, and ValueError for resolution < 0, padding < 1 or not
finite, memory_limit < 0, or a grid whose cells alone exceed memory_limit (the message says how many
cells and bytes it would need).
)doc");
  model.def_static(
      "from_file",
      [](py::handle path, int resolution, double padding, bool topology_culling, int threads,
         std::int64_t memory_limit, py::handle progress) {
        return buildModel(readMesh(path), resolution, padding, topology_culling, threads, memory_limit, progress);
      },
      "path"_a, py::kw_only(), "resolution"_a = build_defaults.resolution, "padding"_a = build_defaults.padding,
      "topology_culling"_a = build_defaults.topology_culling, "threads"_a = build_defaults.threads,
      "memory_limit"_a = build_defaults.memory_limit, "progress"_a = py::none(),
      R"doc(from_file(path: str | bytes | os.PathLike, *, resolution: int = 0, padding: float = 3.0, topology_culling: bool = True, threads: int = 0, memory_limit: int = 0, progress: None | bool | Callable[[float], Any] = None) -> Model

Reads a mesh file (see Mesh.from_file for the formats) and builds its Model (see Model() for the options).
Raises OSError for a file that cannot be read or parsed (FileNotFoundError when missing).
)doc");
  model.def_static(
      "load",
      [](py::handle path_object) {
        const std::string path = pathFromPython(path_object);
        return withFileErrors(path, true, [&] {
          py::gil_scoped_release release;
          return std::make_shared<cfl::CflModel>(cfl::loadCflModel(path));
        });
      },
      "path"_a, R"doc(load(path: str | bytes | os.PathLike) -> Model

Loads a model written by save(). The file is checked (checksums, every count and index) before use; a
loaded model answers every query bit-identically to the saved one.
Raises OSError (FileNotFoundError when missing) naming the file and what is wrong with it.
)doc");
  model.def(
      "save",
      [](const cfl::CflModel& self, py::handle path_object) {
        const std::string path = pathFromPython(path_object);
        withFileErrors(path, false, [&] {
          py::gil_scoped_release release;
          cfl::saveCflModel(self, path);
        });
      },
      "path"_a, R"doc(save(self, path: str | bytes | os.PathLike) -> None

Writes the model to path (a versioned, checksummed little-endian .cfl file, replacing any file there
atomically). Raises OSError when it cannot be written.
)doc");
  model.def_property_readonly(
      "vertices", [](py::object self) { return verticesView(self, self.cast<const cfl::CflModel&>().geometry.mesh); },
      "(n, 3) float64 read-only view of the vertices (model frame).");
  model.def_property_readonly(
      "faces", [](py::object self) { return facesView(self, self.cast<const cfl::CflModel&>().geometry.mesh); },
      "(m, 3) int32 read-only view of the triangles' vertex indices.");
  model.def_property_readonly(
      "bounds", [](const cfl::CflModel& self) { return boundsArray(self.geometry.bounds); },
      "(2, 3) array: min and max corner of the bounding box of the used vertices (model frame).");
  model.def_property_readonly("triangle_count",
                              [](const cfl::CflModel& self) { return self.geometry.mesh.triangles.size(); });
  model.def_property_readonly("vertex_count",
                              [](const cfl::CflModel& self) { return self.geometry.mesh.vertices.size(); });
  model.def_property_readonly(
      "resolution", [](const cfl::CflModel& self) { return self.statistics.resolution; },
      "Cells of the finest level along the longest axis of the regions (N for a uniform grid of resolution N).");
  model.def_property_readonly(
      "voxel_count", [](const cfl::CflModel& self) { return self.statistics.voxel_count; },
      "Leaves of the regions (cells not split further), with or without a list; sum(leaves_per_depth).");
  model.def_property_readonly(
      "leaves_per_depth",
      [](const cfl::CflModel& self) { return leavesPerDepth(self.statistics); },
      "List of int: leaves at each depth, the root cells' level first (one entry for a uniform grid).");
  model.def_property_readonly(
      "leaves_without_list", [](const cfl::CflModel& self) { return self.statistics.leaves_without_list; },
      "Leaves that store no list (it would be too long to pay off): queries use the mesh's hierarchy there.");
  model.def_property_readonly(
      "average_list_length", [](const cfl::CflModel& self) { return self.statistics.average_list_length; },
      "Mean number of triangles per list, over the leaves that store one.");
  model.def_property_readonly("longest_list", [](const cfl::CflModel& self) { return self.statistics.longest_list; });
  model.def_property_readonly(
      "distinct_lists", [](const cfl::CflModel& self) { return self.statistics.distinct_lists; },
      "Lists stored (identical lists are stored once).");
  model.def_property_readonly(
      "memory_bytes", [](const cfl::CflModel& self) { return self.statistics.memory_bytes; },
      "Bytes of the model, mesh and hierarchy included.");
  model.def_property_readonly(
      "coarsened", [](const cfl::CflModel& self) { return self.statistics.coarsened; },
      "True when the build stopped refining at memory_limit (longer lists, answers still exact).");
  model.def_property_readonly(
      "build_seconds", [](const cfl::CflModel& self) { return self.statistics.build_seconds; },
      "Wall time of the build (kept through save/load).");
  model.def_property_readonly(
      "statistics",
      [](const cfl::CflModel& self) {
        const cfl::BuildStatistics& s = self.statistics;
        return py::dict("resolution"_a = s.resolution, "voxel_count"_a = s.voxel_count,
                        "leaves_per_depth"_a = leavesPerDepth(s), "leaves_without_list"_a = s.leaves_without_list,
                        "average_list_length"_a = s.average_list_length, "longest_list"_a = s.longest_list,
                        "distinct_lists"_a = s.distinct_lists, "memory_bytes"_a = s.memory_bytes,
                        "coarsened"_a = s.coarsened, "build_seconds"_a = s.build_seconds);
      },
      "The build statistics as a dict.");
  model.def_property_readonly(
      "closed", [](const cfl::CflModel& self) { return self.sign.closure.closed; },
      "True when the mesh bounds a solid (every edge shared by two oppositely oriented triangles, no degenerate "
      "or crossing triangles): signed queries and penetration need it.");
  model.def_property_readonly(
      "closure",
      [](const cfl::CflModel& self) {
        const cfl::MeshClosure& c = self.sign.closure;
        return py::dict("closed"_a = c.closed, "reason"_a = c.reason, "boundary_edges"_a = c.boundary_edges,
                        "nonmanifold_edges"_a = c.nonmanifold_edges, "inconsistent_edges"_a = c.inconsistent_edges,
                        "degenerate_triangles"_a = c.degenerate_triangles,
                        "intersecting_pairs"_a = c.intersecting_pairs, "orientation"_a = c.orientation);
      },
      "Why the mesh does or does not bound a solid, as a dict: closed, reason (empty when closed), the counts of "
      "boundary, non-manifold and inconsistently oriented edges, degenerate triangles, crossing pairs (up to "
      "1000), and orientation (+1 outward, -1 inside out).");
  model.def("__repr__", [](const cfl::CflModel& self) {
    return "cfl.Model(" + std::to_string(self.geometry.mesh.triangles.size()) + " triangles, resolution " +
           std::to_string(self.statistics.resolution) + ", " + std::to_string(self.statistics.voxel_count) +
           " leaves, " + megabytes(self.statistics.memory_bytes) + (self.statistics.coarsened ? ", coarsened" : "") +
           ")";
  });
  model.def(py::pickle(
      [](const cfl::CflModel& self) {
        const std::vector<unsigned char> bytes = cfl::serializeCflModel(self);
        return py::make_tuple(py::bytes(reinterpret_cast<const char*>(bytes.data()), bytes.size()));
      },
      [](py::tuple state) {
        if (state.size() != 1 || !py::isinstance<py::bytes>(state[0])) throwValueError("cfl.Model: bad pickle state");
        char* data = nullptr;
        py::ssize_t size = 0;
        PyBytes_AsStringAndSize(state[0].ptr(), &data, &size);
        return std::make_shared<cfl::CflModel>(cfl::deserializeCflModel(
            reinterpret_cast<const unsigned char*>(data), static_cast<std::size_t>(size), "pickled cfl.Model"));
      }));

  // --- Results ---------------------------------------------------------------------------------------------
  py::class_<cfl::DistanceResult>(m, "DistanceResult", R"doc(
The answer of distance(): distance, point_a, point_b, triangle_a, triangle_b (unpacks in that order).
distance: the minimum distance (>= 0, 0 when touching or intersecting; inf with triangle ids -1 when an
    upper_bound was given and no pair is closer).
point_a, point_b: (3,) world-frame closest points, on triangle_a of a and triangle_b of b; equal when the
    meshes intersect.
triangle_pairs, voxel_tests: work done by the query (exact triangle distances; tests of region cells and
    bounding volumes).
)doc")
      .def_readonly("distance", &cfl::DistanceResult::distance)
      .def_property_readonly("point_a", [](const cfl::DistanceResult& r) { return vectorToArray(r.point_a); })
      .def_property_readonly("point_b", [](const cfl::DistanceResult& r) { return vectorToArray(r.point_b); })
      .def_readonly("triangle_a", &cfl::DistanceResult::triangle_a)
      .def_readonly("triangle_b", &cfl::DistanceResult::triangle_b)
      .def_property_readonly("triangle_pairs", [](const cfl::DistanceResult& r) { return r.counters.triangle_pairs; })
      .def_property_readonly("voxel_tests", [](const cfl::DistanceResult& r) { return r.counters.voxel_tests; })
      .def("__iter__",
           [](const cfl::DistanceResult& r) {
             return py::iter(py::make_tuple(r.distance, vectorToArray(r.point_a), vectorToArray(r.point_b),
                                            r.triangle_a, r.triangle_b));
           })
      .def("__repr__", [](const cfl::DistanceResult& r) {
        std::ostringstream text;
        text.precision(17);
        text << "DistanceResult(distance=" << r.distance << ", point_a=[" << r.point_a.x() << ", " << r.point_a.y()
             << ", " << r.point_a.z() << "], point_b=[" << r.point_b.x() << ", " << r.point_b.y() << ", "
             << r.point_b.z() << "], triangle_a=" << r.triangle_a << ", triangle_b=" << r.triangle_b << ")";
        return text.str();
      });

  py::class_<DistanceBatch>(m, "DistanceBatch", R"doc(
The answers of distances() for N poses, as NumPy arrays indexed like the poses (unpacks as distance,
point_a, point_b, triangle_a, triangle_b):
distance (N,) float64; point_a, point_b (N, 3) float64, world frame; triangle_a, triangle_b (N,) int32;
triangle_pairs, voxel_tests (N,) int64. The arrays are views of the C++ results (no copy); they stay valid
as long as any of them is referenced.
)doc")
      .def_readonly("distance", &DistanceBatch::distance)
      .def_readonly("point_a", &DistanceBatch::point_a)
      .def_readonly("point_b", &DistanceBatch::point_b)
      .def_readonly("triangle_a", &DistanceBatch::triangle_a)
      .def_readonly("triangle_b", &DistanceBatch::triangle_b)
      .def_readonly("triangle_pairs", &DistanceBatch::triangle_pairs)
      .def_readonly("voxel_tests", &DistanceBatch::voxel_tests)
      .def("__len__", [](const DistanceBatch& batch) { return batch.distance.shape(0); })
      .def("__iter__",
           [](const DistanceBatch& batch) {
             return py::iter(
                 py::make_tuple(batch.distance, batch.point_a, batch.point_b, batch.triangle_a, batch.triangle_b));
           })
      .def("__repr__", [](const DistanceBatch& batch) {
        return "DistanceBatch(" + std::to_string(batch.distance.shape(0)) + " poses)";
      });

  py::class_<PointBatch>(m, "PointDistances", R"doc(
The answers of point_distances() for N points, as NumPy arrays indexed like the points (unpacks as
distance, closest_point, gradient, triangle): distance (N,) float64 (negative inside when signed);
closest_point (N, 3) float64, world frame, on the mesh; gradient (N, 3) float64, world frame, the unit
gradient of the (signed) distance (on the surface the outward normal); triangle (N,) int32, the triangle
holding closest_point. Views of the C++ results (no copy).
)doc")
      .def_readonly("distance", &PointBatch::distance)
      .def_readonly("closest_point", &PointBatch::closest_point)
      .def_readonly("gradient", &PointBatch::gradient)
      .def_readonly("triangle", &PointBatch::triangle)
      .def("__len__", [](const PointBatch& batch) { return batch.distance.shape(0); })
      .def("__iter__",
           [](const PointBatch& batch) {
             return py::iter(py::make_tuple(batch.distance, batch.closest_point, batch.gradient, batch.triangle));
           })
      .def("__repr__", [](const PointBatch& batch) {
        return "PointDistances(" + std::to_string(batch.distance.shape(0)) + " points)";
      });

  py::class_<cfl::PenetrationResult>(m, "PenetrationResult", R"doc(
The answer of penetration(), world frame throughout.
overlapping: the bodies share a point. contained: 0, or 1 when a holds b wholly inside (no surfaces
    meeting), 2 when b holds a.
depth, depth_upper: the certified interval of the depth (the largest distance from a point of one surface
    inside the other body to that body's surface); depth is attained by deepest_point.
deepest_point: on the surface of body deepest_body (0: a, 1: b), inside the other body; surface_point: its
    closest point on the other surface; normal: unit, from deepest_point towards surface_point.
triangle_a, triangle_b: the triangles of a and b holding those two points.
)doc")
      .def_readonly("overlapping", &cfl::PenetrationResult::overlapping)
      .def_readonly("contained", &cfl::PenetrationResult::contained)
      .def_readonly("depth", &cfl::PenetrationResult::depth)
      .def_readonly("depth_upper", &cfl::PenetrationResult::depth_upper)
      .def_property_readonly("deepest_point",
                             [](const cfl::PenetrationResult& r) { return vectorToArray(r.deepest_point); })
      .def_property_readonly("surface_point",
                             [](const cfl::PenetrationResult& r) { return vectorToArray(r.surface_point); })
      .def_property_readonly("normal", [](const cfl::PenetrationResult& r) { return vectorToArray(r.normal); })
      .def_readonly("deepest_body", &cfl::PenetrationResult::deepest_body)
      .def_readonly("triangle_a", &cfl::PenetrationResult::triangle_a)
      .def_readonly("triangle_b", &cfl::PenetrationResult::triangle_b)
      .def("__repr__", [](const cfl::PenetrationResult& r) {
        std::ostringstream text;
        text.precision(17);
        text << "PenetrationResult(overlapping=" << (r.overlapping ? "True" : "False") << ", contained=" << r.contained
             << ", depth=" << r.depth << ", depth_upper=" << r.depth_upper << ")";
        return text.str();
      });

  py::class_<cfl::Contact>(
      m, "Contact",
      "One intersecting triangle pair of collide(): triangle_a, triangle_b and position, a world-frame point of both.")
      .def_readonly("triangle_a", &cfl::Contact::triangle_a)
      .def_readonly("triangle_b", &cfl::Contact::triangle_b)
      .def_property_readonly("position", [](const cfl::Contact& c) { return vectorToArray(c.position); })
      .def("__repr__", [](const cfl::Contact& c) {
        std::ostringstream text;
        text.precision(17);
        text << "Contact(triangle_a=" << c.triangle_a << ", triangle_b=" << c.triangle_b << ", position=["
             << c.position.x() << ", " << c.position.y() << ", " << c.position.z() << "])";
        return text.str();
      });

  py::class_<CollisionResult>(m, "CollisionResult", R"doc(
The answer of collide(): colliding (bool; the object itself is truthy when colliding) and contacts, a
list of up to max_contacts Contact objects (intersecting triangle pairs).
)doc")
      .def_readonly("colliding", &CollisionResult::colliding)
      .def_readonly("contacts", &CollisionResult::contacts)
      .def("__bool__", [](const CollisionResult& r) { return r.colliding; })
      .def("__repr__", [](const CollisionResult& r) {
        return "CollisionResult(colliding=" + std::string(r.colliding ? "True" : "False") + ", " +
               std::to_string(r.contacts.size()) + " contacts)";
      });

  // --- Queries ---------------------------------------------------------------------------------------------
  const double no_bound = std::numeric_limits<double>::infinity();
  m.def(
      "distance", &distance, "a"_a, "pose_a"_a, "b"_a, "pose_b"_a, py::kw_only(), "rel_err"_a = 0.0, "abs_err"_a = 0.0,
      "upper_bound"_a = no_bound, "mode"_a = "hierarchical", "hint"_a = py::none(),
      R"doc(distance(a: Model, pose_a: ArrayLike | None, b: Model | Mesh, pose_b: ArrayLike | None, *, rel_err: float = 0.0, abs_err: float = 0.0, upper_bound: float = inf, mode: str = 'hierarchical', hint: tuple[int, int] | None = None) -> DistanceResult

The exact minimum distance between Model a placed at pose_a and Model or Mesh b placed at pose_b.

a: cfl.Model (its Voronoi regions answer the query).
pose_a: 4x4 rigid transform X_WA, world from a's frame (None = identity).
b: cfl.Model or cfl.Mesh.
pose_b: 4x4 rigid transform X_WB, world from b's frame (None = identity).
rel_err, abs_err: FCL's tolerances. The answer d then satisfies d <= true + abs_err and
    d <= true * (1 + rel_err) (both: rel_err alone keeps it exact); d is still the distance of the two
    returned points.
upper_bound: only pairs closer than this are looked for; when none is, the result has distance inf and
    triangle ids -1. Lets a broadphase that already holds a distance skip far pairs quickly.
mode: 'hierarchical' (default) or 'paper' (the paper's four-step search; same answer, slower).
hint: (triangle of a, triangle of b) from a previous query of a moving pair: speeds up, never changes, the
    answer.

Returns a DistanceResult: distance, point_a, point_b (world frame, in the meshes' unit), triangle_a,
triangle_b (row indices into a.faces and b.faces). Exact: equals the minimum over all triangle pairs up to
rounding. The GIL is released during the query.
Raises TypeError for arguments of the wrong type and ValueError for a pose that is not a 4x4 rigid
transform or a bad option.
)doc");

  m.def(
      "distances", &distances, "a"_a, "pose_a"_a, "b"_a, "poses_b"_a, py::kw_only(), "rel_err"_a = 0.0,
      "abs_err"_a = 0.0, "upper_bound"_a = no_bound, "mode"_a = "hierarchical", "hint"_a = py::none(), "threads"_a = 0,
      "chunk_size"_a = 0,
      R"doc(distances(a: Model, pose_a: ArrayLike | None, b: Model | Mesh, poses_b: ArrayLike, *, rel_err: float = 0.0, abs_err: float = 0.0, upper_bound: float = inf, mode: str = 'hierarchical', hint: tuple[int, int] | None = None, threads: int = 0, chunk_size: int = 0) -> DistanceBatch

distance() for N poses of b at once (a sampling planner's shape of work: one obstacle a, many placements
of b), spread over `threads` threads (0 = every hardware thread) with the GIL released.

poses_b: (N, 4, 4) array of rigid transforms X_WB[i], world from b's frame.
chunk_size: poses handed to a thread at a time (0 = automatic).
The other arguments are those of distance().

Returns a DistanceBatch of NumPy arrays: distance (N,), point_a (N, 3), point_b (N, 3), triangle_a (N,),
triangle_b (N,), plus the counters triangle_pairs and voxel_tests (N,). Each row equals distance() for
that pose bit for bit, whatever the thread count. Every pose is checked before any query runs; a bad one
raises ValueError naming it (poses_b[17]).
)doc");

  m.def(
      "collide", &collide, "a"_a, "pose_a"_a, "b"_a, "pose_b"_a, py::kw_only(), "max_contacts"_a = 1,
      R"doc(collide(a: Model | Mesh, pose_a: ArrayLike | None, b: Model | Mesh, pose_b: ArrayLike | None, *, max_contacts: int = 1) -> CollisionResult

Whether a at pose_a and b at pose_b share a point (touching counts), through both meshes' hierarchies.
a, b: cfl.Model or cfl.Mesh; poses as for distance().
max_contacts: how many intersecting triangle pairs to report (0 = none, only the answer; the search then
    stops at the first pair).

Returns a CollisionResult (truthy when colliding) with .colliding and .contacts, a list of Contact
(triangle_a, triangle_b, position: a world-frame point of both triangles).
)doc");

  m.def(
      "point_distances", &pointDistances, "model"_a, "pose"_a, "points"_a, py::kw_only(), "signed"_a = false,
      "sign_method"_a = "auto", "upper_bound"_a = no_bound, "threads"_a = 0,
      R"doc(point_distances(model: Model, pose: ArrayLike | None, points: ArrayLike, *, signed: bool = False, sign_method: str = 'auto', upper_bound: float = inf, threads: int = 0) -> PointDistances

The exact distance from each of N points to the mesh of `model` placed at `pose` (an exact distance field,
not a sampled one), on `threads` threads (0 = every hardware thread) with the GIL released.

points: (N, 3) array, world frame.
signed: negative inside. sign_method 'auto' (angle-weighted pseudonormals, exact) needs a closed mesh
    (model.closed; otherwise ValueError naming why not); 'winding' signs by the generalized winding number
    on any mesh (robust on nearly closed meshes).
upper_bound: only triangles closer than this are looked for; farther points get inf (or -inf inside) and
    triangle -1.

Returns PointDistances: distance (N,), closest_point (N, 3), gradient (N, 3), triangle (N,).
)doc");

  m.def("signed_distance", &signedDistance, "a"_a, "pose_a"_a, "b"_a, "pose_b"_a,
        R"doc(signed_distance(a: Model, pose_a: ArrayLike | None, b: Model, pose_b: ArrayLike | None) -> DistanceResult

Signed distance between two closed meshes: their distance when apart, minus the penetration depth (see
penetration(); its certified lower end) when the bodies overlap, one inside the other included. On overlap
point_a and point_b are the deepest point and its closest point on the other surface, each on its own mesh.
Raises ValueError naming the mesh and the reason when either is not closed.
)doc");

  m.def("penetration", &penetration, "a"_a, "pose_a"_a, "b"_a, "pose_b"_a, py::kw_only(), "tolerance"_a = 0.0,
        R"doc(penetration(a: Model, pose_a: ArrayLike | None, b: Model, pose_b: ArrayLike | None, *, tolerance: float = 0.0) -> PenetrationResult

How deep two closed meshes overlap: the largest distance from a point of one surface lying inside the other
body to that body's surface (a lower bound on the translational penetration depth), to a certified interval
[depth, depth_upper] no wider than `tolerance` (0: 1e-4 of the larger bounding-box diagonal).
Raises ValueError naming the mesh and the reason when either is not closed.
)doc");
}
