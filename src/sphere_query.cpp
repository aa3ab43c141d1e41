// Many spheres against one model (sphere_query.h).

#include "cfl/sphere_query.h"

#include "cfl/error.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <string>
#include <vector>

namespace cfl {

void computeSphereDistances(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d* centers_W,
                            const double* radii, std::size_t count, SphereDistance* results,
                            const PointQueryOptions& options) {
  double largest = 0;
  for (std::size_t i = 0; i < count; ++i) {
    if (!(radii[i] >= 0) || !std::isfinite(radii[i]))
      throw Error("computeSphereDistances: radii[" + std::to_string(i) + "] is " + std::to_string(radii[i]) +
                  " (must be finite and >= 0)");
    largest = std::max(largest, radii[i]);
  }
  // The centers may be that much farther than the spheres' bound (the points' own bound check validates it).
  PointQueryOptions point_options = options;
  if (!options.signed_distance && options.upper_bound >= 0) point_options.upper_bound = options.upper_bound + largest;
  if (options.signed_distance) point_options.upper_bound = std::numeric_limits<double>::infinity();
  std::vector<PointDistance> points(count);
  computePointDistances(model, X_WM, centers_W, count, points.data(), point_options);
  for (std::size_t i = 0; i < count; ++i) {
    const PointDistance& p = points[i];
    SphereDistance& s = results[i];
    s = SphereDistance{};
    if (p.triangle < 0) continue;
    const double distance = p.distance - radii[i];
    if (!options.signed_distance && !(distance < options.upper_bound)) continue;
    s.distance = distance;
    s.mesh_point = p.closest_point;
    s.sphere_point = centers_W[i] - radii[i] * p.gradient;
    s.triangle = p.triangle;
  }
}

SphereDistance computeLeastSphereDistance(const CflModel& model, const Eigen::Isometry3d& X_WM,
                                          const Eigen::Vector3d* centers_W, const double* radii, std::size_t count,
                                          const PointQueryOptions& options, int* index) {
  if (!(options.upper_bound >= 0))
    throw Error("computeLeastSphereDistance: upper_bound must be >= 0 (got " + std::to_string(options.upper_bound) +
                ")");
  if (options.signed_distance)
    throw Error("computeLeastSphereDistance: unsigned only (use computeSphereDistances for signed distances)");
  for (std::size_t i = 0; i < count; ++i)
    if (!(radii[i] >= 0) || !std::isfinite(radii[i]))
      throw Error("computeLeastSphereDistance: radii[" + std::to_string(i) + "] is " + std::to_string(radii[i]) +
                  " (must be finite and >= 0)");
  SphereDistance best;
  best.distance = options.upper_bound;
  if (index) *index = -1;
  PointQueryOptions point_options = options;
  for (std::size_t i = 0; i < count; ++i) {
    // A penetrating best (negative) leaves nothing to find for a sphere that is not larger.
    point_options.upper_bound = std::max(0.0, best.distance + radii[i]);
    const PointDistance p = computePointDistance(model, X_WM, centers_W[i], point_options);
    if (p.triangle < 0 || !(p.distance - radii[i] < best.distance)) continue;
    best.distance = p.distance - radii[i];
    best.mesh_point = p.closest_point;
    best.sphere_point = centers_W[i] - radii[i] * p.gradient;
    best.triangle = p.triangle;
    if (index) *index = int(i);
  }
  if (best.triangle < 0) best.distance = std::numeric_limits<double>::infinity();
  return best;
}

}  // namespace cfl
