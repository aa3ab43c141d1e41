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
/// edge-cross-axis directions (the box axes are in cubeTriangleQuickBound).
inline double cubeTriangleSeparatingAxisBound(const Eigen::Vector3d& center, double half, const Eigen::Vector3d& a,
                                              const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  const Eigen::Vector3d v0 = a - center, v1 = b - center, v2 = c - center;
  auto axisGap = [&](const Eigen::Vector3d& axis) {
    const double length = axis.norm();
    if (!(length > 1e-300)) return 0.0;
    const double p0 = axis.dot(v0), p1 = axis.dot(v1), p2 = axis.dot(v2);
    const double radius = half * axis.cwiseAbs().sum();
    const double gap = std::max(std::min({p0, p1, p2}) - radius, -std::max({p0, p1, p2}) - radius);
    return gap / length;
  };
  const Eigen::Vector3d e0 = v1 - v0, e1 = v2 - v1, e2 = v0 - v2;
  double bound = axisGap(e0.cross(e1));
  const Eigen::Vector3d edges[3] = {e0, e1, e2};
  for (const Eigen::Vector3d& edge : edges) {
    bound = std::max(bound, axisGap(Eigen::Vector3d(0, -edge.z(), edge.y())));
    bound = std::max(bound, axisGap(Eigen::Vector3d(edge.z(), 0, -edge.x())));
    bound = std::max(bound, axisGap(Eigen::Vector3d(-edge.y(), edge.x(), 0)));
  }
  return std::max(bound, 0.0);
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
  return std::max(cubeTriangleQuickBound(center, half, a, b, c, closest),
                  cubeTriangleSeparatingAxisBound(center, half, a, b, c));
}

}  // namespace cfl::detail
