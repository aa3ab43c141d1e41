#include "conversions.h"

#include <climits>
#include <cstdint>
#include <cstring>
#include <sstream>
#include <type_traits>

#include "cfl/cfl_query.h"

namespace cfl_python {

void throwValueError(const std::string& message) { throw py::value_error(message); }
void throwTypeError(const std::string& message) { throw py::type_error(message); }

namespace {

// numpy.asarray, looked up once. The reference is deliberately never released: a static py::object would be
// destroyed after the interpreter is gone.
py::handle asarrayFunction() {
  static py::handle function = py::object(py::module_::import("numpy").attr("asarray")).release();
  return function;
}

std::string shapeText(const py::array& array) {
  std::ostringstream text;
  text << "(";
  for (py::ssize_t d = 0; d < array.ndim(); ++d) text << (d ? ", " : "") << array.shape(d);
  text << (array.ndim() == 1 ? ",)" : ")");
  return text.str();
}

std::string typeName(py::handle object) { return py::str(py::type::handle_of(object).attr("__name__")); }

// `object` as an ndarray whose elements are numbers of one of the NumPy kinds in `kinds` ('f' float, 'i'
// signed, 'u' unsigned integer). Whatever NumPy cannot turn into an array raises its own exception (a ragged
// list gives NumPy's ValueError); bool, complex, string and object arrays raise TypeError here, since casting
// them to double would silently change their meaning.
py::array numericArray(py::handle object, const char* name, const char* kinds, const char* expected) {
  py::array array = asarrayFunction()(object);
  const char kind = array.dtype().kind();
  if (std::strchr(kinds, kind) == nullptr) {
    throwTypeError(std::string(name) + " must be an array of " + expected + ", got " +
                   (py::isinstance<py::array>(object)
                        ? "an array of dtype " + std::string(py::str(array.dtype()))
                        : "a " + typeName(object) + " holding dtype " + std::string(py::str(array.dtype()))));
  }
  return array;
}

template <typename Index>
void copyFaces(const py::array& faces, std::int64_t vertex_count, cfl::TriangleMesh& mesh) {
  const auto converted = py::array_t<Index, py::array::c_style | py::array::forcecast>(faces);
  const Index* data = converted.data();
  const std::size_t count = static_cast<std::size_t>(converted.shape(0));
  mesh.triangles.resize(count);
  for (std::size_t f = 0; f < count; ++f) {
    for (int k = 0; k < 3; ++k) {
      const Index index = data[3 * f + k];
      // Checked here rather than by cfl::validateMesh: an index beyond int's range would change on the way
      // into the C++ mesh and the message would name the wrong value.
      bool negative = false;
      if constexpr (std::is_signed_v<Index>) negative = index < 0;
      if (negative || static_cast<std::uint64_t>(index) >= static_cast<std::uint64_t>(vertex_count)) {
        std::ostringstream message;
        message << "faces[" << f << "]: vertex index " << +index << " is out of range [0, " << vertex_count << ")";
        throwValueError(message.str());
      }
      mesh.triangles[f][k] = static_cast<int>(index);
    }
  }
}

Eigen::Isometry3d checkedPose(const Eigen::Matrix4d& m, const std::string& name) {
  if (!(m(3, 0) == 0 && m(3, 1) == 0 && m(3, 2) == 0 && m(3, 3) == 1)) {
    std::ostringstream message;
    message << name << " must be a rigid transform, whose last row is [0, 0, 0, 1]; got [" << m(3, 0) << ", " << m(3, 1)
            << ", " << m(3, 2) << ", " << m(3, 3) << "]";
    throwValueError(message.str());
  }
  Eigen::Isometry3d X;
  X.matrix() = m;
  cfl::validatePose(X, name.c_str());  // cfl::Error, translated to ValueError, for a non-rigid rotation
  return X;
}

}  // namespace

cfl::TriangleMesh meshFromPython(py::handle vertices, py::handle faces) {
  py::object vertex_source = py::reinterpret_borrow<py::object>(vertices);
  py::object face_source = py::reinterpret_borrow<py::object>(faces);
  if (faces.is_none()) {
    if (!py::hasattr(vertices, "vertices") || !py::hasattr(vertices, "faces")) {
      throwTypeError(
          "faces is missing: pass a (n, 3) vertex array and a (m, 3) face array, or one object with "
          ".vertices and .faces (such as a trimesh.Trimesh); got a " +
          typeName(vertices));
    }
    vertex_source = vertices.attr("vertices");
    face_source = vertices.attr("faces");
  }

  cfl::TriangleMesh mesh;
  const py::array vertex_array = numericArray(vertex_source, "vertices", "fiu", "numbers");
  if (vertex_array.ndim() != 2 || vertex_array.shape(1) != 3) {
    throwValueError("vertices must have shape (n, 3), got " + shapeText(vertex_array));
  }
  if (vertex_array.shape(0) > INT_MAX) throwValueError("vertices: more than 2^31 - 1 vertices");
  const auto vertex_data = py::array_t<double, py::array::c_style | py::array::forcecast>(vertex_array);
  mesh.vertices.resize(static_cast<std::size_t>(vertex_data.shape(0)));
  if (!mesh.vertices.empty())
    std::memcpy(mesh.vertices[0].data(), vertex_data.data(), 3 * sizeof(double) * mesh.vertices.size());

  const py::array face_array = numericArray(face_source, "faces", "iu", "integers (vertex indices)");
  if (face_array.ndim() != 2 || face_array.shape(1) != 3) {
    throwValueError("faces must have shape (m, 3), got " + shapeText(face_array));
  }
  const auto vertex_count = static_cast<std::int64_t>(mesh.vertices.size());
  if (face_array.dtype().kind() == 'u') {
    copyFaces<std::uint64_t>(face_array, vertex_count, mesh);
  } else {
    copyFaces<std::int64_t>(face_array, vertex_count, mesh);
  }
  return mesh;
}

Eigen::Isometry3d poseFromPython(py::handle pose, const char* name) {
  if (pose.is_none()) return Eigen::Isometry3d::Identity();
  // The common case, a float64 ndarray, is read through its strides without building another array.
  py::array array = py::isinstance<py::array_t<double>>(pose)
                        ? py::reinterpret_borrow<py::array>(pose)
                        : py::array(py::array_t<double, py::array::forcecast>(
                              numericArray(pose, name, "fiu", "numbers (a 4x4 rigid transform)")));
  if (array.ndim() != 2 || array.shape(0) != 4 || array.shape(1) != 4) {
    throwValueError(std::string(name) + " must have shape (4, 4) (a rigid transform), got " + shapeText(array));
  }
  const char* base = static_cast<const char*>(array.data());
  const py::ssize_t row_stride = array.strides(0), column_stride = array.strides(1);
  Eigen::Matrix4d m;
  for (int i = 0; i < 4; ++i) {
    for (int j = 0; j < 4; ++j) {
      std::memcpy(&m(i, j), base + i * row_stride + j * column_stride, sizeof(double));  // may be unaligned
    }
  }
  return checkedPose(m, name);
}

std::vector<Eigen::Isometry3d> posesFromPython(py::handle poses, const char* name) {
  const py::array array = numericArray(poses, name, "fiu", "numbers (a stack of 4x4 rigid transforms)");
  if (array.ndim() != 3 || array.shape(1) != 4 || array.shape(2) != 4) {
    throwValueError(std::string(name) + " must have shape (N, 4, 4) (N rigid transforms), got " + shapeText(array));
  }
  const auto data = py::array_t<double, py::array::c_style | py::array::forcecast>(array);
  const std::size_t count = static_cast<std::size_t>(data.shape(0));
  std::vector<Eigen::Isometry3d> result(count);
  for (std::size_t i = 0; i < count; ++i) {
    const Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>> m(data.data() + 16 * i);
    result[i] = checkedPose(m, std::string(name) + "[" + std::to_string(i) + "]");
  }
  return result;
}

py::array readOnlyView(py::dtype dtype, std::vector<py::ssize_t> shape, std::vector<py::ssize_t> strides,
                       const void* data, py::handle owner) {
  py::array view(std::move(dtype), std::move(shape), std::move(strides), data, owner);
  view.attr("setflags")(py::arg("write") = false);
  return view;
}

py::array_t<double> vectorToArray(const Eigen::Vector3d& p) {
  py::array_t<double> array(3);
  std::memcpy(array.mutable_data(), p.data(), 3 * sizeof(double));
  return array;
}

std::string pathFromPython(py::handle path) {
  static py::handle fsdecode = py::object(py::module_::import("os").attr("fsdecode")).release();
  return py::str(fsdecode(path));
}

}  // namespace cfl_python
