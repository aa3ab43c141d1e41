// The builder's cube-triangle separating-axis bound against independent references: the per-axis code it
// replaced (bit for bit) and the distance of sampled triangle points (it must never exceed it).

#include "cfl/triangle_distance.h"
#include "support/test_meshes.h"

#include "../src/detail/box_triangle_bound.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <vector>

namespace cfl {
namespace {

using test::Rng;

bool sameBits(double x, double y) { return std::memcmp(&x, &y, sizeof x) == 0; }

// The separating-axis bound as computed before the axes were batched: one axis at a time, each tested as it
// is formed. Kept here as the reference the batched code must match bit for bit.
double referenceSeparatingAxisBound(const Eigen::Vector3d& center, double half, const Eigen::Vector3d& a,
                                    const Eigen::Vector3d& b, const Eigen::Vector3d& c, double at_least) {
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

// Squared distance from p to the cube of center `center` and half edge `half`.
double pointCubeSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& center, double half) {
  return ((p - center).cwiseAbs().array() - half).max(0.0).matrix().squaredNorm();
}

TEST(SeparatingAxisBound, MatchesPerAxisCodeAndStaysBelowTheDistance) {
  Rng rng(20261126);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> scale_exponent(-6.0, 3.0);
  std::uniform_int_distribution<int> shape(0, 5);
  int positive = 0;
  for (int trial = 0; trial < 200000; ++trial) {
    const double scale = std::pow(10.0, scale_exponent(rng));
    const Eigen::Vector3d offset = 1000.0 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) * (trial % 3 == 0);
    const Eigen::Vector3d center = offset + scale * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    const double half = scale * (0.05 + std::abs(unit(rng)));
    Eigen::Vector3d corner[3];
    for (auto& p : corner) p = offset + 2 * scale * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    // Ugly shapes too: slivers, repeated corners, axis-aligned edges, a point.
    switch (shape(rng)) {
      case 1: corner[2] = corner[0] + 1e-9 * (corner[1] - corner[0]); break;
      case 2: corner[1] = corner[0]; break;
      case 3: corner[1].y() = corner[0].y(), corner[1].z() = corner[0].z(); break;
      case 4: corner[1] = corner[2] = corner[0]; break;
      default: break;
    }
    const double at_least = trial % 4 == 0 ? scale * 0.3 * std::abs(unit(rng)) : 0.0;
    const double bound =
        detail::cubeTriangleSeparatingAxisBound(center, half, corner[0], corner[1], corner[2], at_least);
    const double reference = referenceSeparatingAxisBound(center, half, corner[0], corner[1], corner[2], at_least);
    ASSERT_TRUE(sameBits(bound, reference)) << trial << ": " << bound << " vs " << reference;
    // Never above the distance of any point of the triangle from the cube (when at_least is below it).
    double nearest_sample = std::numeric_limits<double>::infinity();
    for (int s = 0; s < 40; ++s) {
      double u = std::abs(unit(rng)), w = std::abs(unit(rng));
      if (u + w > 1) u = 1 - u, w = 1 - w;
      const Eigen::Vector3d p = corner[0] + u * (corner[1] - corner[0]) + w * (corner[2] - corner[0]);
      nearest_sample = std::min(nearest_sample, std::sqrt(pointCubeSquaredDistance(p, center, half)));
    }
    for (const auto& p : corner) {
      nearest_sample = std::min(nearest_sample, std::sqrt(pointCubeSquaredDistance(p, center, half)));
    }
    if (at_least <= nearest_sample) {
      ASSERT_LE(bound, nearest_sample * (1 + 1e-9) + 1e-12 * (offset.norm() + scale)) << trial;
    }
    positive += bound > at_least;
  }
  EXPECT_GT(positive, 10000);  // the axes did raise the bound often
}

}  // namespace
}  // namespace cfl
