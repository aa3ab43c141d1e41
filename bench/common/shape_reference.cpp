#include "shape_reference.h"

#include "cfl/segment_query.h"
#include "cfl/triangle_distance.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>

namespace cfl::bench {

double bruteForceShapeDistance(const FclShape& shape, const Eigen::Isometry3d& X_MS, const TriangleMesh& mesh) {
  double best_squared = std::numeric_limits<double>::infinity();
  const auto& v = mesh.vertices;
  switch (shape.kind) {
    case FclShape::Kind::kSphere: {
      const Eigen::Vector3d c = X_MS.translation();
      for (const auto& t : mesh.triangles)
        best_squared = std::min(best_squared, pointTriangleSquaredDistance(c, v[t[0]], v[t[1]], v[t[2]]));
      return std::max(0.0, std::sqrt(best_squared) - shape.radius);
    }
    case FclShape::Kind::kCapsule: {
      const Eigen::Vector3d p0 = X_MS * Eigen::Vector3d(0, 0, -0.5 * shape.length);
      const Eigen::Vector3d p1 = X_MS * Eigen::Vector3d(0, 0, 0.5 * shape.length);
      for (const auto& t : mesh.triangles)
        best_squared = std::min(best_squared, segmentTriangleSquaredDistance(p0, p1, v[t[0]], v[t[1]], v[t[2]]));
      return std::max(0.0, std::sqrt(best_squared) - shape.radius);
    }
    case FclShape::Kind::kBox:
      break;
  }
  const Eigen::Vector3d half = 0.5 * shape.sides;
  std::array<Eigen::Vector3d, 8> corner;
  for (int k = 0; k < 8; ++k)
    corner[k] = X_MS * Eigen::Vector3d((k & 1) ? half.x() : -half.x(), (k & 2) ? half.y() : -half.y(),
                                       (k & 4) ? half.z() : -half.z());
  // Two triangles per face, corners numbered by bit k = +half along axis k.
  static constexpr int kFaces[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                                        {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  const Eigen::Isometry3d X_SM = X_MS.inverse();
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d q[3] = {v[t[0]], v[t[1]], v[t[2]]};
    for (const Eigen::Vector3d& p : q)
      if (((X_SM * p).cwiseAbs() - half).maxCoeff() <= 0) return 0;
    for (const auto& f : kFaces) {
      const Eigen::Vector3d p[3] = {corner[f[0]], corner[f[1]], corner[f[2]]};
      best_squared = std::min(best_squared, triangleTriangleSquaredDistance(p, q));
    }
  }
  return std::sqrt(best_squared);
}

}  // namespace cfl::bench
