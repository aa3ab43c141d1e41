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
  double e[3][3];
  for (int n = 0; n < 3; ++n) {
    for (int d = 0; d < 3; ++d) e[n][d] = v[(n + 1) % 3][d] - v[n][d];
  }
  // The ten axes: the normal, then per edge its cross products with the x, y and z axes.
  double x[10], y[10], z[10];
  x[0] = e[0][1] * e[1][2] - e[0][2] * e[1][1];
  y[0] = e[0][2] * e[1][0] - e[0][0] * e[1][2];
  z[0] = e[0][0] * e[1][1] - e[0][1] * e[1][0];
  for (int n = 0; n < 3; ++n) {
    const double* edge = e[n];
    x[1 + 3 * n] = 0, y[1 + 3 * n] = -edge[2], z[1 + 3 * n] = edge[1];
    x[2 + 3 * n] = edge[2], y[2 + 3 * n] = 0, z[2 + 3 * n] = -edge[0];
    x[3 + 3 * n] = -edge[1], y[3 + 3 * n] = edge[0], z[3 + 3 * n] = 0;
  }
  // Every axis's gap first, with no branch between them, so that the compiler can compute several at once;
  // then the axes in order, each normalized only when it can raise the bound. Each value is the same
  // expression as computed one axis at a time, so the bound is the same.
  double gap[10], length_squared[10];
  for (int k = 0; k < 10; ++k) {
    const double p0 = x[k] * v[0][0] + y[k] * v[0][1] + z[k] * v[0][2];
    const double p1 = x[k] * v[1][0] + y[k] * v[1][1] + z[k] * v[1][2];
    const double p2 = x[k] * v[2][0] + y[k] * v[2][1] + z[k] * v[2][2];
    const double radius = half * (std::abs(x[k]) + std::abs(y[k]) + std::abs(z[k]));
    gap[k] = std::max(std::min(std::min(p0, p1), p2) - radius, -std::max(std::max(p0, p1), p2) - radius);
    length_squared[k] = x[k] * x[k] + y[k] * y[k] + z[k] * z[k];
  }
  double bound = std::max(at_least, 0.0);
  for (int k = 0; k < 10; ++k) {
    if (!(gap[k] > 0)) continue;
    if (!(gap[k] * gap[k] > bound * bound * length_squared[k])) continue;
    const double length = std::sqrt(length_squared[k]);
    if (!(length > 1e-300)) continue;
    bound = std::max(bound, gap[k] / length);
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
