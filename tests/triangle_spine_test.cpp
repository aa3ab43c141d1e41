// The spine bound between two triangles (src/detail/triangle_spine.h) against the exact triangle distance
// (cfl::triangleTriangleSquaredDistance, itself checked against independent references in
// triangle_distance_test): it must never exceed the distance, on triangles of every shape, slivers and
// degenerate ones included, and it must stay close where two flat slivers face each other, which is what
// it is for. The same for oriented boxes (boxSpineLowerBound, and the search's separating-axes bound
// orientedBoxPairBound with its vector kernel), against the exact distance between two boxes taken as the
// least distance between their faces' triangles.

#include "../src/detail/query_kernels.h"
#include "../src/detail/triangle_spine.h"

#include "cfl/mesh_model.h"
#include "cfl/query_kernels.h"
#include "cfl/triangle_distance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <utility>
#include <vector>

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

// A size from 1e-3 to 1e3 and, for every third pair n, an offset a thousand sizes from the origin (where
// the coordinates' rounding is what the bounds' slack must cover); otherwise the origin.
std::pair<double, Vec> randomScaleAndOffset(std::mt19937_64& rng, int n) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const double scale = std::pow(10.0, 3 * unit(rng));
  const Vec offset = 1e3 * scale * Vec(unit(rng), unit(rng), unit(rng));
  return {scale, n % 3 == 0 ? offset : Vec::Zero()};
}

TEST(TriangleSpine, NeverExceedsTheDistanceBetweenTriangles) {
  std::mt19937_64 rng(20261127);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int checked = 0, positive = 0;
  for (int n = 0; n < 200000; ++n) {
    const auto [scale, offset] = randomScaleAndOffset(rng, n);
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

// An oriented box: points center + axes * s with |s_i| <= half_i.
struct Box {
  Eigen::Matrix3d axes;
  Vec center;
  Vec half;
  Vec corner(int k) const {
    return center + axes * Vec((k & 1) ? half[0] : -half[0], (k & 2) ? half[1] : -half[1],
                               (k & 4) ? half[2] : -half[2]);
  }
  bool holds(const Vec& p) const {
    return ((axes.transpose() * (p - center)).cwiseAbs() - half).maxCoeff() <= 0;
  }
};

// The exact distance between two boxes: 0 where a corner of one lies in the other (the only way two boxes
// can meet without their faces crossing), otherwise the least distance between the 12 triangles of each
// box's faces (exact kernel, degenerate triangles of flat boxes included).
double boxDistance(const Box& a, const Box& b) {
  for (int k = 0; k < 8; ++k) {
    if (a.holds(b.corner(k)) || b.holds(a.corner(k))) return 0;
  }
  // Each face: the four corners where bit `axis` is fixed at `side`, as two triangles.
  auto faces = [](const Box& box) {
    std::vector<Triangle> triangles;
    for (int axis = 0; axis < 3; ++axis) {
      const int u = 1 << ((axis + 1) % 3), v = 1 << ((axis + 2) % 3);
      for (int side = 0; side < 2; ++side) {
        const int base = side << axis;
        const Vec c0 = box.corner(base), c1 = box.corner(base | u), c2 = box.corner(base | u | v),
                  c3 = box.corner(base | v);
        triangles.push_back({c0, c1, c2});
        triangles.push_back({c0, c2, c3});
      }
    }
    return triangles;
  };
  double best = std::numeric_limits<double>::infinity();
  for (const Triangle& p : faces(a)) {
    for (const Triangle& q : faces(b)) best = std::min(best, exactDistance(p, q));
  }
  return best;
}

double boxSpineBound(const Box& a, const Box& b) {
  return cfl::detail::boxSpineLowerBound(a.axes, a.center, a.half, b.axes, b.center, b.half);
}

// A random box around `center`: a cube, a slab, a needle, a flat rectangle of zero thickness, a segment or
// a point, with random orthonormal axes.
Box randomBox(std::mt19937_64& rng, const Vec& center, double size) {
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Quaterniond rotation =
      Eigen::Quaterniond(Eigen::Vector4d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5)).normalized();
  Vec half = size * Vec(unit(rng), unit(rng), unit(rng));
  switch (std::uniform_int_distribution<int>(0, 5)(rng)) {
    case 0:
      break;
    case 1:
      half[0] *= 1e-3;
      break;
    case 2:
      half[0] *= 1e-2, half[1] *= 1e-2;
      break;
    case 3:
      half[1] = 0;
      break;
    case 4:
      half[0] = half[1] = 0;
      break;
    default:
      half.setZero();
  }
  // Any axis may be the longest: the bound picks it.
  std::shuffle(half.data(), half.data() + 3, rng);
  return {rotation.toRotationMatrix(), center, half};
}

TEST(BoxSpine, NeverExceedsTheDistanceBetweenBoxes) {
  std::mt19937_64 rng(20261128);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int positive = 0, close = 0;
  const int count = 20000;
  for (int n = 0; n < count; ++n) {
    const auto [scale, offset] = randomScaleAndOffset(rng, n);
    const Vec apart = 3 * scale * Vec(unit(rng), unit(rng), unit(rng));
    const Box boxes[2] = {randomBox(rng, offset, scale), randomBox(rng, offset + apart, scale)};
    const double exact = boxDistance(boxes[0], boxes[1]), bound = boxSpineBound(boxes[0], boxes[1]);
    // The face triangles' exact distance rounds too, over eight corners' coordinates.
    ASSERT_LE(bound, exact + 1e-13 * (offset.norm() + 8 * scale)) << "pair " << n << ": " << bound << " > " << exact;
    positive += bound > 0;
    close += bound > 0.99 * exact && exact > 0;
  }
  EXPECT_GT(positive, count / 10);  // not vacuous on separated pairs
  EXPECT_GT(close, count / 50);     // and tight on some (needles and slabs facing each other)
}

// The oriented boxes' separating axes (the line between the centers and each box's axes; what the search
// bounds a node pair with, detail/box_pair_bound.h) in the generic build and through every kernel table this
// CPU runs: never above the distance between the boxes, the same bits in every table, at every threshold
// (where it may return early), and tight where the boxes lie apart along an axis.
TEST(BoxPairBound, NeverExceedsTheDistanceBetweenBoxesInEveryTable) {
  using Bound = double (*)(const Eigen::Matrix3d&, const Vec&, const Vec&, const Eigen::Matrix3d&, const Vec&,
                           const Vec&, double, double);
  std::vector<Bound> kernels;
#if CFL_X86_64_V3_KERNELS
  if (cfl::queryKernelsAvailable(cfl::QueryKernels::kX86_64_V3)) {
    kernels.push_back(cfl::detail::kX86_64_V3QueryKernels.box_pair_bound);
  }
#endif
  ASSERT_EQ(cfl::detail::kGenericQueryKernels.box_pair_bound, nullptr);  // the search runs the scalar bound
  std::mt19937_64 rng(20261129);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  int positive = 0, close = 0;
  const int count = 20000;
  for (int n = 0; n < count; ++n) {
    const auto [scale, offset] = randomScaleAndOffset(rng, n);
    const Vec apart = 3 * scale * Vec(unit(rng), unit(rng), unit(rng));
    const Box a = randomBox(rng, offset, scale), b = randomBox(rng, offset + apart, scale);
    const double exact = boxDistance(a, b);
    const double bound = cfl::detail::orientedBoxPairBound(a.axes, a.center, a.half, b.axes, b.center, b.half,
                                                           -kInfinity, kInfinity);
    ASSERT_LE(bound, exact + 1e-13 * (offset.norm() + 8 * scale)) << "pair " << n << ": " << bound << " > " << exact;
    positive += bound > 0;
    close += bound > 0.99 * exact && exact > 0;
    for (const Bound kernel : kernels) {
      const double start = n % 2 == 0 ? -kInfinity : exact * (0.5 + 0.5 * unit(rng));
      for (const double threshold : {kInfinity, exact, 0.5 * exact, 0.0}) {
        const double reference =
            cfl::detail::orientedBoxPairBound(a.axes, a.center, a.half, b.axes, b.center, b.half, start, threshold);
        const double fast = kernel(a.axes, a.center, a.half, b.axes, b.center, b.half, start, threshold);
        ASSERT_EQ(std::memcmp(&fast, &reference, sizeof fast), 0)
            << "pair " << n << " at threshold " << threshold << ": kernel " << fast << ", scalar " << reference;
      }
    }
  }
  EXPECT_GT(positive, count / 10);  // not vacuous on separated pairs
  EXPECT_GT(close, count / 100);    // and tight on some (boxes apart along an axis)
}

// Two needles (boxes 10 long, up to 0.05 across) in parallel planes h apart, crossing at a random angle over
// each other: the distance is h less their reach across, and the bound finds it. The separating axes of
// the boxes' faces find h only where the needles cross squarely; the line between their centers finds it
// only where the needles are parallel.
TEST(BoxSpine, FacingNeedlesAreBoundedNearlyExactly) {
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  for (int n = 0; n < 2000; ++n) {
    const double h = 0.2 + unit(rng), width = 0.05 * unit(rng), thickness = 0.01 * unit(rng);
    const double angle = 3.14159 * unit(rng);
    const Eigen::Matrix3d axes_b = Eigen::AngleAxisd(angle, Vec::UnitZ()).toRotationMatrix();
    const Box a{Eigen::Matrix3d::Identity(), Vec(1.0, 0, 0), Vec(5, width, thickness)};
    const Box b{axes_b, Vec(0, 0, h) + 2 * axes_b.col(0), Vec(5, width, thickness)};
    const double exact = boxDistance(a, b);
    ASSERT_NEAR(exact, h - 2 * thickness, 1e-12);
    EXPECT_GE(boxSpineBound(a, b), exact - 1e-9) << "pair " << n;
  }
}

// A piece of a tube (or a rod's skin) along z: `sides` around (3: a triangular prism), `rings` along, its
// vertices pushed off the circle by up to `roughness` of the radius, then turned and moved at random.
cfl::TriangleMesh randomTube(std::mt19937_64& rng, double radius, double length, int sides, int rings,
                             double roughness) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  const Eigen::Quaterniond rotation =
      Eigen::Quaterniond(Eigen::Vector4d(unit(rng), unit(rng), unit(rng), unit(rng))).normalized();
  const Vec shift = 3 * length * Vec(unit(rng), unit(rng), unit(rng));
  cfl::TriangleMesh mesh;
  for (int ring = 0; ring <= rings; ++ring) {
    for (int side = 0; side < sides; ++side) {
      const double angle = 2 * 3.14159265358979 * side / sides;
      const double r = radius * (1 + roughness * unit(rng));
      const Vec p(r * std::cos(angle), r * std::sin(angle), length * ring / rings);
      mesh.vertices.push_back(rotation * p + shift);
    }
  }
  for (int ring = 0; ring < rings; ++ring) {
    for (int side = 0; side < sides; ++side) {
      const int a = ring * sides + side, b = ring * sides + (side + 1) % sides;
      mesh.triangles.push_back({a, b, b + sides});
      mesh.triangles.push_back({a, b + sides, a + sides});
    }
  }
  return mesh;
}

// The bound of two Bvh roots with their spine radii (MeshModel::node_spine_radii), against the least distance
// between the two meshes' triangles: tubes of every width for their length (rods to rings), coarse or fine
// around, rough or round, at random distances and angles. Round tubes far apart for their width are bounded
// nearly as the cylinders they are, which the box alone (square across) is not; that is what the radii are
// for, and the test checks that they are used.
TEST(BoxSpine, SpineRadiiNeverExceedTheDistanceBetweenTubes) {
  std::mt19937_64 rng(20261127);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  int positive = 0, tighter = 0, close = 0;
  const int count = 400;
  for (int n = 0; n < count; ++n) {
    cfl::MeshModel models[2];
    for (cfl::MeshModel& model : models) {
      const double length = 0.5 + 4 * unit(rng);
      const double radius = length * std::pow(10.0, -2 * unit(rng));
      const int sides = 3 + int(10 * unit(rng));
      model = cfl::makeMeshModel(randomTube(rng, radius, length, sides, 1 + int(5 * unit(rng)), 0.3 * unit(rng)));
    }
    const cfl::BvhNode& a = models[0].bvh.nodes[0];
    const cfl::BvhNode& b = models[1].bvh.nodes[0];
    const double radius_a = models[0].node_spine_radii[0], radius_b = models[1].node_spine_radii[0];
    const double bound = cfl::detail::boxSpineLowerBound(a.obb_axes, a.obb_center, a.obb_half, b.obb_axes, b.obb_center,
                                                         b.obb_half, cfl::segmentSegmentSquaredDistance, radius_a,
                                                         radius_b);
    const double box_only =
        cfl::detail::boxSpineLowerBound(a.obb_axes, a.obb_center, a.obb_half, b.obb_axes, b.obb_center, b.obb_half);
    double exact = std::numeric_limits<double>::infinity();
    for (std::size_t i = 0; i < models[0].corners.size(); ++i) {
      for (std::size_t j = 0; j < models[1].corners.size(); ++j) {
        exact = std::min(exact, std::sqrt(cfl::triangleTriangleSquaredDistance(models[0].corners[i].data(),
                                                                                 models[1].corners[j].data())));
      }
    }
    const double scale = a.obb_center.norm() + b.obb_center.norm() + a.obb_half.sum() + b.obb_half.sum();
    ASSERT_LE(bound, exact + 1e-12 * scale) << "pair " << n << ": " << bound << " > " << exact;
    EXPECT_GE(bound, box_only) << "pair " << n;
    positive += bound > 0;
    tighter += bound > box_only + 1e-6 * exact;
    close += bound > 0.99 * exact && exact > 0;
  }
  EXPECT_GT(positive, count / 2);
  EXPECT_GT(tighter, count / 4);
  EXPECT_GT(close, count / 20);
}

}  // namespace
