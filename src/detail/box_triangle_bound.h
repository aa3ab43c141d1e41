#pragma once
// Internal: a cheap lower bound on the distance between an axis-aligned cube and a triangle.

#include <Eigen/Core>
#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>

namespace cfl::detail {

/// The two cheap terms of cubeTriangleLowerBound (bounding-box gap and center-direction gap).
inline double cubeTriangleQuickBound(const Eigen::Vector3d& center, double half, const Eigen::Vector3d& a,
                                     const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                     const Eigen::Vector3d& closest) {
  const Eigen::Vector3d v0 = a - center, v1 = b - center, v2 = c - center;
  const Eigen::Vector3d lo = v0.cwiseMin(v1).cwiseMin(v2), hi = v0.cwiseMax(v1).cwiseMax(v2);
  const Eigen::Vector3d axis_gap = (lo.array() - half).max(-hi.array() - half).max(0.0).matrix();
  double bound = axis_gap.norm();
  const Eigen::Vector3d to_closest = closest - center;
  const double distance = to_closest.norm();
  if (distance > 0) bound = std::max(bound, distance - half * (to_closest / distance).cwiseAbs().sum());
  return std::max(bound, 0.0);
}

/// The separating-axis terms of cubeTriangleLowerBound: the gaps along the triangle normal and the nine
/// edge-cross-axis directions (the box axes are in cubeTriangleQuickBound), or `at_least` if that is larger.
/// An axis is normalized (a square root and a division) only when its unnormalized gap can beat the bound
/// so far, compared squared; rounding there only decides between two valid lower bounds.
inline double cubeTriangleSeparatingAxisBound(const Eigen::Vector3d& center, double half, const Eigen::Vector3d& a,
                                              const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                              double at_least = 0.0) {
  // Scalar code: the builder calls this for every listed entry, and Eigen's 3-vectors lose to plain scalars.
  const double v[3][3] = {{a.x() - center.x(), a.y() - center.y(), a.z() - center.z()},
                          {b.x() - center.x(), b.y() - center.y(), b.z() - center.z()},
                          {c.x() - center.x(), c.y() - center.y(), c.z() - center.z()}};
  double bound = std::max(at_least, 0.0);
  auto axisGap = [&](double x, double y, double z) {
    const double p0 = x * v[0][0] + y * v[0][1] + z * v[0][2];
    const double p1 = x * v[1][0] + y * v[1][1] + z * v[1][2];
    const double p2 = x * v[2][0] + y * v[2][1] + z * v[2][2];
    const double radius = half * (std::abs(x) + std::abs(y) + std::abs(z));
    const double gap = std::max(std::min({p0, p1, p2}) - radius, -std::max({p0, p1, p2}) - radius);
    if (!(gap > 0)) return;
    const double length_squared = x * x + y * y + z * z;
    if (!(gap * gap > bound * bound * length_squared)) return;
    const double length = std::sqrt(length_squared);
    if (!(length > 1e-300)) return;
    bound = std::max(bound, gap / length);
  };
  double e[3][3];
  for (int n = 0; n < 3; ++n) {
    for (int d = 0; d < 3; ++d) e[n][d] = v[(n + 1) % 3][d] - v[n][d];
  }
  axisGap(e[0][1] * e[1][2] - e[0][2] * e[1][1], e[0][2] * e[1][0] - e[0][0] * e[1][2],
          e[0][0] * e[1][1] - e[0][1] * e[1][0]);
  for (const auto& edge : e) {
    axisGap(0, -edge[2], edge[1]);
    axisGap(edge[2], 0, -edge[0]);
    axisGap(-edge[1], edge[0], 0);
  }
  return bound;
}

/// A lower bound on the distance between the cube of center `center` and half edge `half` and the triangle
/// (a, b, c). It is the largest of: the gap between the cube and the triangle's bounding box, the separating
/// gaps along the triangle normal and the nine edge-cross-axis directions of the separating axis theorem,
/// and the gap along the direction from the center to `closest`, the triangle's closest point to the center.
/// Exactly 0 when the cube and triangle intersect (the 13 axes decide intersection exactly); never above the
/// true distance.
inline double cubeTriangleLowerBound(const Eigen::Vector3d& center, double half, const Eigen::Vector3d& a,
                                     const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                     const Eigen::Vector3d& closest) {
  return cubeTriangleSeparatingAxisBound(center, half, a, b, c, cubeTriangleQuickBound(center, half, a, b, c, closest));
}

}  // namespace cfl::detail
