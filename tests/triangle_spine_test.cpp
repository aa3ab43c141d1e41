// The spine bound between two triangles (src/detail/triangle_spine.h) against the exact triangle distance
// (cfl::triangleTriangleSquaredDistance, itself checked against independent references in
// triangle_distance_test): it must never exceed the distance, on triangles of every shape, slivers and
// degenerate ones included, and it must stay close where two flat slivers face each other, which is what
// it is for.

#include "../src/detail/triangle_spine.h"

#include "cfl/triangle_distance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <array>
#include <cmath>
#include <random>

namespace {

using Vec = Eigen::Vector3d;
using Triangle = std::array<Vec, 3>;

double exactDistance(const Triangle& a, const Triangle& b) {
  return std::sqrt(cfl::triangleTriangleSquaredDistance(a.data(), b.data()));
}

double spineBound(const Triangle& a, const Triangle& b) {
  using cfl::detail::longestEdge;
  using cfl::detail::triangleSpine;
  return cfl::detail::spineLowerBound(a.data(), triangleSpine(a.data(), longestEdge(a.data())), b.data(),
                                      triangleSpine(b.data(), longestEdge(b.data())));
}

// A random triangle of one of several shapes around `center`: ordinary, a sliver (up to 1e4 times longer
// than wide), a needle (two corners nearly together), collinear corners, or one point three times.
Triangle randomTriangle(std::mt19937_64& rng, const Vec& center, double size) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  auto random_vector = [&] { return Vec(unit(rng), unit(rng), unit(rng)); };
  const Vec a = center + size * random_vector();
  const Vec along = size * random_vector();
  switch (std::uniform_int_distribution<int>(0, 4)(rng)) {
    case 0:
      return {a, center + size * random_vector(), center + size * random_vector()};
    case 1: {
      const double width = std::pow(10.0, -4 * std::abs(unit(rng)));
      const Vec across = along.cross(random_vector()).normalized() * along.norm() * width;
      return {a, a + along, a + (0.5 + 0.5 * unit(rng)) * along + across};
    }
    case 2:
      return {a, a + along, a + along + 1e-6 * size * random_vector()};
    case 3:
      return {a, a + along, a + (2 * unit(rng)) * along};
    default:
      return {a, a, a};
  }
}

TEST(TriangleSpine, NeverExceedsTheDistanceBetweenTriangles) {
  std::mt19937_64 rng(20261127);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int checked = 0, positive = 0;
  for (int n = 0; n < 200000; ++n) {
    const double scale = std::pow(10.0, 3 * unit(rng));
    const Vec offset = 1e3 * scale * Vec(unit(rng), unit(rng), unit(rng)) * (n % 3 == 0 ? 1.0 : 0.0);
    const Triangle a = randomTriangle(rng, offset, scale);
    const Triangle b = randomTriangle(rng, offset + 2 * scale * Vec(unit(rng), unit(rng), unit(rng)), scale);
    const double exact = exactDistance(a, b);
    const double bound = spineBound(a, b);
    // The exact kernel rounds too: a few eps of the configuration's coordinates.
    const double rounding = 1e-13 * (offset.norm() + 4 * scale);
    ASSERT_LE(bound, exact + rounding) << "pair " << n << ": bound " << bound << ", distance " << exact;
    ++checked;
    positive += bound > 0;
  }
  EXPECT_EQ(checked, 200000);
  EXPECT_GT(positive, 20000);  // the bound is not vacuous on separated pairs
}

// Two slivers in parallel planes h apart, crossing at a random angle with their spines over each other: the
// distance is h, and the bound must find nearly all of it however wide they are (a bound from the widths
// alone loses both widths). The same slivers shifted sideways keep the bound within their widths' share
// along the line between the spines.
TEST(TriangleSpine, FacingSliversAreBoundedNearlyExactly) {
  std::mt19937_64 rng(7);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int n = 0; n < 2000; ++n) {
    const double h = 0.01 + unit(rng), width = 0.05 * unit(rng), length = 10;
    const double angle = 3.14159 * unit(rng);
    const Vec dir_b(std::cos(angle), std::sin(angle), 0);
    const Vec across_b(-dir_b.y(), dir_b.x(), 0);
    const Triangle a = {Vec(-length / 2, 0, 0), Vec(length / 2, 0, 0), Vec(0.3, width, 0)};
    const Triangle b = {Vec(0, 0, h) - dir_b * length / 2, Vec(0, 0, h) + dir_b * length / 2,
                        Vec(0, 0, h) + 0.2 * dir_b - width * across_b};
    const double exact = exactDistance(a, b);
    ASSERT_NEAR(exact, h, 1e-12);
    EXPECT_GE(spineBound(a, b), h - 1e-9) << "pair " << n;
  }
}

}  // namespace
