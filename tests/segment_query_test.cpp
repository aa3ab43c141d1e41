// computeSegmentDistance, findTrianglesNearSegment, segmentTriangleSquaredDistance (segment_query.h) and
// computeSphereDistances (sphere_query.h) against independent references: brute force over every triangle
// with the triangle-triangle kernel (a segment is the degenerate triangle (a, b, b)), and for signed values a
// brute-force distance signed by the brute-force winding number, sampled densely along the segment.

#include "cfl/error.h"
#include "cfl/segment_query.h"
#include "cfl/sphere_query.h"
#include "cfl/triangle_distance.h"
#include "support/sign_references.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <random>
#include <string>
#include <vector>

namespace cfl {
namespace {

double bruteSegment(const TriangleMesh& mesh, const Eigen::Isometry3d& X, const Eigen::Vector3d& p0,
                    const Eigen::Vector3d& p1) {
  const Eigen::Vector3d s[3] = {p0, p1, p1};
  double best = INFINITY;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d q[3] = {X * mesh.vertices[t[0]], X * mesh.vertices[t[1]], X * mesh.vertices[t[2]]};
    best = std::min(best, triangleTriangleSquaredDistance(s, q));
  }
  return std::sqrt(best);
}

double bruteSigned(const TriangleMesh& mesh, const Eigen::Isometry3d& X, const Eigen::Vector3d& p) {
  const double d = test::referencePointMeshDistance(mesh, p, X);
  return std::abs(test::referenceWindingNumber(mesh, X.inverse() * p)) >= 0.5 ? -d : d;
}

struct Case {
  std::string name;
  CflModel model;
};

const std::vector<Case>& cases() {
  static const std::vector<Case> all = [] {
    std::vector<Case> c;
    c.push_back({"knot", buildCflModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 96, 8))});
    c.push_back({"sheet", buildCflModel(test::makeWavySheet(1.5, 0.4, 20))});
    c.push_back({"soup", buildCflModel(test::makeTriangleSoup(600, 3))});
    return c;
  }();
  return all;
}

// Segments of every kind: points (length 0), short and long, near the surface, crossing it, far away.
std::pair<Eigen::Vector3d, Eigen::Vector3d> randomSegment(const CflModel& model, std::mt19937_64& rng, int i) {
  const TriangleMesh& mesh = model.geometry.mesh;
  const double size = model.geometry.bounds.diagonal();
  std::normal_distribution<double> gauss;
  std::uniform_int_distribution<int> pick(0, int(mesh.triangles.size()) - 1);
  const Eigen::Vector3d on = test::randomPointOnTriangle(mesh, pick(rng), rng);
  const Eigen::Vector3d off = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)) * (i % 4 == 3 ? 0.5 : 0.02) * size;
  const Eigen::Vector3d axis = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)) * (i % 5 == 0 ? 0.0 : 0.05) * size;
  return {on + off - axis, on + off + axis};
}

TEST(SegmentTriangle, EqualsTheTriangleKernelOnTheDegenerateTriangleAndItsPointsAttainIt) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> gauss;
  auto v = [&] { return Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)); };
  for (int i = 0; i < 20000; ++i) {
    Eigen::Vector3d a = v(), b = v(), c = v(), p0 = v(), p1 = v();
    if (i % 7 == 0) c = a + 0.5 * (b - a);  // degenerate triangle
    if (i % 11 == 0) p1 = p0;                // point
    if (i % 13 == 0) p1 = p0 + 1e-3 * (c - p0);  // short, near-crossing
    const Eigen::Vector3d s[3] = {p0, p1, p1}, t[3] = {a, b, c};
    Eigen::Vector3d on_s, on_t;
    const double got = segmentTriangleSquaredDistance(p0, p1, a, b, c, &on_s, &on_t);
    const double expected = triangleTriangleSquaredDistance(s, t);
    ASSERT_NEAR(std::sqrt(got), std::sqrt(expected), 1e-12) << i;
    ASSERT_NEAR((on_s - on_t).squaredNorm(), got, 1e-12) << i;
  }
}

TEST(SegmentQuery, UnsignedEqualsBruteForceWithPointsOnTheSegmentAndTheTriangle) {
  std::mt19937_64 rng(2);
  for (const Case& c : cases()) {
    const double tolerance = 1e-9 * c.model.geometry.bounds.diagonal();
    for (int i = 0; i < 120; ++i) {
      const Eigen::Isometry3d X = test::randomPose(rng, 1.0);
      auto [p0, p1] = randomSegment(c.model, rng, i);
      p0 = X * p0;
      p1 = X * p1;
      const std::string at = c.name + " segment " + std::to_string(i);
      const SegmentDistance got = computeSegmentDistance(c.model, X, p0, p1);
      ASSERT_GE(got.triangle, 0) << at;
      EXPECT_NEAR(got.distance, bruteSegment(c.model.geometry.mesh, X, p0, p1), tolerance) << at;
      EXPECT_NEAR((got.segment_point - got.mesh_point).norm(), got.distance, tolerance) << at;
      const auto& t = c.model.geometry.corners[got.triangle];
      EXPECT_LE(std::sqrt(pointTriangleSquaredDistance(X.inverse() * got.mesh_point, t[0], t[1], t[2])), tolerance) << at;
      const Eigen::Vector3d s[3] = {p0, p1, p1};
      const Eigen::Vector3d point[3] = {got.segment_point, got.segment_point, got.segment_point};
      EXPECT_LE(std::sqrt(triangleTriangleSquaredDistance(s, point)), tolerance) << at;
      // An upper bound at or below the answer finds nothing; above it, the same answer.
      EXPECT_EQ(computeSegmentDistance(c.model, X, p0, p1, {false, got.distance * (1 - 1e-9)}).triangle, -1) << at;
      EXPECT_EQ(computeSegmentDistance(c.model, X, p0, p1, {false, got.distance * 1.01 + tolerance}).distance,
                got.distance)
          << at;
      // Every triangle within a radius, against brute force.
      const double radius = got.distance + 0.01 * c.model.geometry.bounds.diagonal();
      std::vector<SegmentDistance> near;
      findTrianglesNearSegment(c.model, X, p0, p1, radius, 1u << 30, &near);
      std::size_t expected = 0;
      for (const auto& tri : c.model.geometry.corners.in_leaf_order) {
        const Eigen::Vector3d q[3] = {X * tri[0], X * tri[1], X * tri[2]};
        expected += std::sqrt(triangleTriangleSquaredDistance(s, q)) <= radius;
      }
      EXPECT_NEAR(double(near.size()), double(expected), 0.0) << at;
      for (const auto& n : near) EXPECT_LE(n.distance, radius) << at;
    }
  }
}

// Where only some of a triangle's features can be closest to a segment (the search tries an end only if the
// triangle reaches behind it, an edge only if the segment reaches past it): segments parallel to faces and
// edges of an axis-aligned mesh, lying in their planes, crossing them, on grid points; a mesh with zero-area
// and duplicated triangles; an open mesh.
TEST(SegmentQuery, UnsignedEqualsBruteForceOnParallelSegmentsAndDegenerateTriangles) {
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> uniform(-1, 1);
  for (const auto& [name, mesh] : test::makeFeaturePruningMeshes()) {
    const CflModel model = buildCflModel(mesh);
    const double size = model.geometry.bounds.diagonal();
    const Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    for (int i = 0; i < 300; ++i) {
      // Ends on a grid of quarter units (so on the blocks' faces and edges, or level with them), along an
      // axis, or anywhere.
      auto gridPoint = [&]() {
        return Eigen::Vector3d(std::round(6 * uniform(rng)) / 4, std::round(6 * uniform(rng)) / 4,
                               std::round(6 * uniform(rng)) / 4);
      };
      Eigen::Vector3d p0 = gridPoint(), p1 = p0;
      if (i % 3 == 0) p1[i % 9 / 3] += std::round(4 * uniform(rng)) / 4;
      if (i % 3 == 1) p1 = gridPoint();
      if (i % 3 == 2) p1 = p0 + 0.3 * Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
      const std::string at = name + " segment " + std::to_string(i);
      const SegmentDistance got = computeSegmentDistance(model, X, p0, p1);
      ASSERT_GE(got.triangle, 0) << at;
      EXPECT_NEAR(got.distance, bruteSegment(mesh, X, p0, p1), 1e-9 * size) << at;
      EXPECT_NEAR((got.segment_point - got.mesh_point).norm(), got.distance, 1e-9 * size) << at;
    }
  }
}

TEST(SegmentQuery, SignedIsTheLeastBruteForceSignedDistanceWithinTheCertifiedTolerance) {
  const Case& c = cases()[0];
  ASSERT_TRUE(c.model.sign.closure.closed) << c.model.sign.closure.reason;
  std::mt19937_64 rng(3);
  const double diagonal = c.model.geometry.bounds.diagonal();
  int inside = 0;
  for (int i = 0; i < 40; ++i) {
    const Eigen::Isometry3d X = test::randomPose(rng, 1.0);
    auto [p0, p1] = randomSegment(c.model, rng, i);
    p0 = X * p0;
    p1 = X * p1;
    SegmentQueryOptions options;
    options.signed_distance = true;
    const SegmentDistance got = computeSegmentDistance(c.model, X, p0, p1, options);
    const int samples = 300;
    double sampled = INFINITY;
    for (int k = 0; k <= samples; ++k)
      sampled = std::min(sampled, bruteSigned(c.model.geometry.mesh, X, p0 + (p1 - p0) * (double(k) / samples)));
    const double slack = 0.5 * (p1 - p0).norm() / samples, certified = 1e-6 * diagonal + 1e-9 * diagonal;
    const std::string at = "segment " + std::to_string(i);
    if (sampled >= 0) {
      EXPECT_NEAR(got.distance, bruteSegment(c.model.geometry.mesh, X, p0, p1), 1e-9 * diagonal) << at;
      continue;
    }
    ++inside;
    EXPECT_LE(got.distance, sampled + certified) << at;
    EXPECT_GE(got.distance, sampled - slack - certified) << at;
    EXPECT_NEAR((got.segment_point - got.mesh_point).norm(), -got.distance, 1e-9 * diagonal) << at;
    EXPECT_NEAR(bruteSigned(c.model.geometry.mesh, X, got.segment_point), got.distance, 1e-9 * diagonal) << at;
  }
  EXPECT_GT(inside, 5);
}

TEST(SegmentQuery, SignedOnAnOpenMeshAndBadInputThrowCflErrors) {
  const Case& sheet = cases()[1];
  SegmentQueryOptions options;
  options.signed_distance = true;
  EXPECT_THROW(computeSegmentDistance(sheet.model, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(),
                                      Eigen::Vector3d::Ones(), options),
               Error);
  EXPECT_THROW(computeSegmentDistance(sheet.model, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Constant(NAN),
                                      Eigen::Vector3d::Ones()),
               Error);
  EXPECT_THROW(computeSegmentDistance(sheet.model, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(),
                                      Eigen::Vector3d::Ones(), {false, -1.0}),
               Error);
}

TEST(SphereQuery, BatchIsThePointDistanceMinusTheRadiusSignedOrNot) {
  const Case& c = cases()[0];
  std::mt19937_64 rng(4);
  const Eigen::Isometry3d X = test::randomPose(rng, 1.0);
  std::vector<Eigen::Vector3d> centers;
  std::vector<double> radii;
  for (int i = 0; i < 200; ++i) {
    centers.push_back(X * randomSegment(c.model, rng, i).first);
    radii.push_back(0.01 * (i % 5) * c.model.geometry.bounds.diagonal());
  }
  for (const bool signed_distance : {false, true}) {
    PointQueryOptions options;
    options.signed_distance = signed_distance;
    std::vector<SphereDistance> got(centers.size());
    computeSphereDistances(c.model, X, centers.data(), radii.data(), centers.size(), got.data(), options);
    for (std::size_t i = 0; i < centers.size(); ++i) {
      const PointDistance p = computePointDistance(c.model, X, centers[i], options);
      EXPECT_EQ(got[i].distance, p.distance - radii[i]) << i;
      EXPECT_EQ(got[i].triangle, p.triangle) << i;
      if (p.distance != 0)
        EXPECT_NEAR((got[i].sphere_point - got[i].mesh_point).norm(), std::abs(got[i].distance), 1e-9) << i;
    }
  }
  // The least sphere, with its running bound, is the least of the batch.
  {
    std::vector<SphereDistance> all(centers.size());
    computeSphereDistances(c.model, X, centers.data(), radii.data(), centers.size(), all.data());
    int index = -1;
    const SphereDistance least = computeLeastSphereDistance(c.model, X, centers.data(), radii.data(), centers.size(), {}, &index);
    const auto best = std::min_element(all.begin(), all.end(), [](const SphereDistance& x, const SphereDistance& y) {
      return x.distance < y.distance;
    });
    EXPECT_EQ(least.distance, best->distance);
    ASSERT_GE(index, 0);
    EXPECT_EQ(all[index].distance, least.distance);
  }
  radii[7] = -1;
  std::vector<SphereDistance> untouched(centers.size());
  EXPECT_THROW(computeSphereDistances(c.model, X, centers.data(), radii.data(), centers.size(), untouched.data()), Error);
  EXPECT_EQ(untouched[0].triangle, -1);
}

}  // namespace
}  // namespace cfl
