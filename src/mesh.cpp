#include "cfl/mesh.h"

#include "cfl/error.h"

#include <cmath>
#include <sstream>

namespace cfl {

void validateMesh(const TriangleMesh& mesh) {
  if (mesh.triangles.empty()) {
    throw Error("mesh has no triangles (" + std::to_string(mesh.vertices.size()) + " vertices)");
  }
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    const Eigen::Vector3d& p = mesh.vertices[v];
    if (!p.allFinite()) {
      std::ostringstream message;
      message << "vertex " << v << " has a non-finite coordinate (" << p.x() << ", " << p.y() << ", " << p.z() << ")";
      throw Error(message.str());
    }
    if (!(p.cwiseAbs().maxCoeff() <= kMaxCoordinate)) {
      std::ostringstream message;
      message << "vertex " << v << " has a coordinate beyond " << kMaxCoordinate << " in magnitude (" << p.x() << ", "
              << p.y() << ", " << p.z() << "): the squared distances and products the queries take would overflow";
      throw Error(message.str());
    }
  }
  const long long vertex_count = static_cast<long long>(mesh.vertices.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    for (int corner = 0; corner < 3; ++corner) {
      const int index = mesh.triangles[t][corner];
      if (index < 0 || index >= vertex_count) {
        std::ostringstream message;
        message << "triangle " << t << ": vertex index " << index << " (corner " << corner << ") is out of range [0, "
                << vertex_count << ")";
        throw Error(message.str());
      }
    }
  }
  const double diagonal = boundingBox(mesh).size().stableNorm();  // norm() would underflow to 0 here
  if (diagonal > 0 && !(diagonal >= kMinDiagonal)) {
    std::ostringstream message;
    message << "the mesh is " << diagonal << " units across (its bounding box's diagonal), below " << kMinDiagonal
            << ": the squared lengths the distance kernels take would underflow; express it in larger units";
    throw Error(message.str());
  }
}

Aabb boundingBox(const TriangleMesh& mesh) {
  Aabb box;
  for (const auto& triangle : mesh.triangles) {
    for (int index : triangle) box.extend(mesh.vertices[index]);
  }
  return box;
}

}  // namespace cfl
