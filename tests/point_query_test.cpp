// computePointDistance(s) against independent references: brute force over every triangle for the distance,
// the brute-force winding number and closed forms for the sign.

#include "cfl/error.h"
#include "cfl/point_query.h"
#include "cfl/query_kernels.h"
#include "cfl/triangle_distance.h"
#include "support/sign_references.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <array>
#include <limits>
#include <random>
#include <string>
#include <thread>
#include <vector>

namespace cfl {
namespace {

using test::NamedMesh;

TriangleMesh unitCube() { return test::makeBox(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()); }

// Points in frame M of every kind a query meets: just off the surface (down to 1e-6 of the size), in the
// mesh's box, elsewhere in the regions, and outside the regions.
std::vector<Eigen::Vector3d> samplePoints(const CflModel& model, int count, test::Rng& rng) {
  const TriangleMesh& mesh = model.geometry.mesh;
  const Aabb box = model.geometry.bounds;
  const Aabb regions = model.regions.bounds();
  const double size = box.diagonal();
  std::uniform_real_distribution<double> unit(0, 1);
  std::normal_distribution<double> gauss;
  std::uniform_int_distribution<int> pick(0, int(mesh.triangles.size()) - 1);
  auto inBox = [&](const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    return Eigen::Vector3d(lo.x() + unit(rng) * (hi.x() - lo.x()), lo.y() + unit(rng) * (hi.y() - lo.y()),
                           lo.z() + unit(rng) * (hi.z() - lo.z()));
  };
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < count; ++i) {
    const Eigen::Vector3d direction = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
    switch (i % 4) {
      case 0:
        points.push_back(test::randomPointOnTriangle(mesh, pick(rng), rng) +
                         size * std::pow(10.0, -6 + 5 * unit(rng)) * direction);
        break;
      case 1:
        points.push_back(inBox(box.min - 0.1 * box.size(), box.max + 0.1 * box.size()));
        break;
      case 2:
        points.push_back(inBox(regions.min, regions.max));
        break;
      default:
        points.push_back(regions.center() + regions.diagonal() * (0.6 + 2 * unit(rng)) * direction);
    }
  }
  return points;
}

double bruteForceSquared(const MeshModel& geometry, const Eigen::Vector3d& p_M) {
  double best = std::numeric_limits<double>::infinity();
  for (const auto& c : geometry.corners.in_leaf_order) best = std::min(best, pointTriangleSquaredDistance(p_M, c[0], c[1], c[2]));
  return best;
}

// A long, narrow, slightly twisted strip of fans of slivers, as a turbine blade's tessellation: each
// triangle spans the strip's length from one short edge, down to a height of 1e-13 of its length (those get
// no plane, MeshModel::planes), and below it a second strip, so that points see slivers on both sides.
TriangleMesh makeSliverStrip() {
  TriangleMesh mesh;
  const int n = 24;
  const double length = 40, width = 1;
  for (int sheet = 0; sheet < 2; ++sheet) {
    const double z = sheet == 0 ? 0.0 : -0.3;
    const int base = int(mesh.vertices.size());
    for (int i = 0; i <= n; ++i) {
      const double x = width * i / n;
      const double twist = 0.02 * x * x;
      mesh.vertices.push_back(Eigen::Vector3d(x, 0, z + twist));
      mesh.vertices.push_back(Eigen::Vector3d(x, length, z - twist));
    }
    for (int i = 0; i < n; ++i) {
      const int a = base + 2 * i, b = a + 2, c = a + 1, d = a + 3;
      mesh.triangles.push_back({a, b, c});
      mesh.triangles.push_back({b, d, c});
    }
    // Slivers thinner than any plane: a corner 1e-13 of the length off the long edge.
    const int e = int(mesh.vertices.size());
    mesh.vertices.push_back(Eigen::Vector3d(width + 0.5, 0, z));
    mesh.vertices.push_back(Eigen::Vector3d(width + 0.5, length, z));
    mesh.vertices.push_back(Eigen::Vector3d(width + 0.5 + 1e-13 * length, 0.5 * length, z));
    mesh.triangles.push_back({e, e + 1, e + 2});
  }
  return mesh;
}

std::vector<NamedMesh> unsignedMeshes() {
  return {
      {"sliver strip", makeSliverStrip()},
      {"sphere", test::makeSphere()},
      {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6)},
      {"cube soup", test::toSoup(unitCube())},
      {"hemisphere", test::makeHemisphere(1.0, 6, 16)},
      {"messy", test::makeMessyMesh()},
      {"self_intersecting", test::makeSelfIntersectingMesh()},
      {"bunny", test::loadBunny()},
  };
}

TEST(PointQuery, UnsignedDistanceMatchesBruteForce) {
  test::Rng rng(11);
  for (const NamedMesh& named : unsignedMeshes()) {
    SCOPED_TRACE(named.name);
    const CflModel model = buildCflModel(named.mesh);
    const Eigen::Isometry3d X_WM = test::randomPose(rng, 5.0);
    const double size = model.geometry.bounds.diagonal();
    int listed = 0;  // points whose leaf has a list: the path this test is mostly about
    const std::vector<Eigen::Vector3d> points = samplePoints(model, 2000, rng);
    for (const Eigen::Vector3d& p_M : points) {
      const Aabb regions = model.regions.bounds();
      if ((p_M.array() >= regions.min.array()).all() && (p_M.array() <= regions.max.array()).all()) {
        listed += model.regions.hasList(model.regions.locate(p_M).leaf);
      }
    }
    EXPECT_GT(listed, 1000);
    for (const Eigen::Vector3d& p_M : points) {
      const Eigen::Vector3d p_W = X_WM * p_M;
      const PointDistance got = computePointDistance(model, X_WM, p_W);
      const double expected = std::sqrt(bruteForceSquared(model.geometry, X_WM.inverse(Eigen::Isometry) * p_W));
      ASSERT_NEAR(got.distance, expected, 1e-12 * (size + expected)) << "p_M " << p_M.transpose();
      // And against the test suite's own kernel.
      ASSERT_NEAR(got.distance, test::referencePointMeshDistance(named.mesh, p_W, X_WM), 1e-9 * (size + expected));
      ASSERT_GE(got.triangle, 0);
      EXPECT_NEAR((got.closest_point - p_W).norm(), got.distance, 1e-9 * (size + expected));
      const auto& c = model.geometry.corners[got.triangle];
      const Eigen::Vector3d closest_M = X_WM.inverse(Eigen::Isometry) * got.closest_point;
      EXPECT_NEAR(std::sqrt(pointTriangleSquaredDistance(closest_M, c[0], c[1], c[2])), 0, 1e-9 * size);
      if (got.distance > 1e-9 * size) {
        EXPECT_NEAR(got.gradient.norm(), 1, 1e-9);
        EXPECT_NEAR(got.gradient.dot(p_W - got.closest_point), got.distance, 1e-9 * (size + expected));
      }
    }
  }
}

TEST(PointQuery, UpperBoundKeepsOnlyCloserTriangles) {
  test::Rng rng(12);
  const CflModel model = buildCflModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6));
  const Eigen::Isometry3d X_WM = test::randomPose(rng, 2.0);
  PointQueryOptions bounded;
  bounded.upper_bound = 0.2;
  for (const Eigen::Vector3d& p_M : samplePoints(model, 2000, rng)) {
    const Eigen::Vector3d p_W = X_WM * p_M;
    const PointDistance full = computePointDistance(model, X_WM, p_W);
    const PointDistance got = computePointDistance(model, X_WM, p_W, bounded);
    if (full.distance < 0.2 * (1 - 1e-12)) {
      EXPECT_EQ(got.distance, full.distance);
      EXPECT_EQ(got.triangle, full.triangle);
    } else if (full.distance > 0.2 * (1 + 1e-12)) {
      EXPECT_EQ(got.distance, std::numeric_limits<double>::infinity());
      EXPECT_EQ(got.triangle, -1);
    }
  }
  PointQueryOptions zero;
  zero.upper_bound = 0;
  EXPECT_EQ(computePointDistance(model, X_WM, X_WM * model.geometry.corners[0][0], zero).triangle, -1);
  PointQueryOptions negative;
  negative.upper_bound = -1;
  EXPECT_THROW(computePointDistance(model, X_WM, Eigen::Vector3d::Zero(), negative), Error);
}

// Sharp and concave features, where a face normal alone signs wrongly and pseudonormals are needed: a
// tetrahedron (dihedral angles under 90 degrees), and a cube whose top is a four-triangle fan around a
// center pushed in (a concave vertex and edges) or pulled out into a spike.
TriangleMesh tetrahedron() {
  TriangleMesh mesh;
  mesh.vertices = {{1, 1, 1}, {1, -1, -1}, {-1, 1, -1}, {-1, -1, 1}};
  mesh.triangles = {{0, 1, 2}, {0, 3, 1}, {0, 2, 3}, {1, 3, 2}};
  return mesh;
}

TriangleMesh cubeWithTopAt(double apex_height) {
  TriangleMesh cube = unitCube();
  std::vector<std::array<int, 3>> kept;
  for (const auto& t : cube.triangles) {
    if (!(t[0] >= 4 && t[1] >= 4 && t[2] >= 4)) kept.push_back(t);  // drop the top face (vertices 4 to 7)
  }
  cube.triangles = kept;
  const int c = int(cube.vertices.size());
  cube.vertices.push_back({0.5, 0.5, apex_height});
  for (const auto& t : std::vector<std::array<int, 3>>{{4, 5, c}, {5, 7, c}, {7, 6, c}, {6, 4, c}}) cube.triangles.push_back(t);
  return cube;
}

// Signs on closed meshes against the brute-force winding number, away from the surface where it is
// immaterial.
TEST(PointQuery, SignsMatchTheWindingNumberOnClosedMeshes) {
  const std::vector<NamedMesh> meshes = {
      {"sphere", test::makeSphere()},
      {"torus", test::makeTorus(1.0, 0.35, 16, 8)},
      {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6)},
      {"cube soup", test::toSoup(unitCube())},
      {"inside-out knot", test::flipped(test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6))},
      {"tetrahedron", tetrahedron()},
      {"dented cube", cubeWithTopAt(0.4)},
      {"spiked cube", cubeWithTopAt(4.0)},
      {"bunny", test::loadBunny()},
  };
  test::Rng rng(13);
  for (const NamedMesh& named : meshes) {
    SCOPED_TRACE(named.name);
    const CflModel model = buildCflModel(named.mesh);
    ASSERT_TRUE(model.sign.closure.closed) << model.sign.closure.reason;
    const Eigen::Isometry3d X_WM = test::randomPose(rng, 5.0);
    const double size = model.geometry.bounds.diagonal();
    for (SignMethod method : {SignMethod::kAuto, SignMethod::kWindingNumber}) {
      PointQueryOptions options;
      options.signed_distance = true;
      options.sign_method = method;
      int inside_count = 0;
      for (const Eigen::Vector3d& p_M : samplePoints(model, 2000, rng)) {
        const Eigen::Vector3d p_W = X_WM * p_M;
        const PointDistance got = computePointDistance(model, X_WM, p_W, options);
        const PointDistance plain = computePointDistance(model, X_WM, p_W);
        ASSERT_EQ(std::abs(got.distance), plain.distance);
        if (plain.distance < 1e-9 * size) continue;
        const double w = test::referenceWindingNumber(named.mesh, p_M);
        ASSERT_NEAR(std::abs(w), std::round(std::abs(w)), 1e-6);
        const bool inside = std::abs(w) > 0.5;
        inside_count += inside;
        ASSERT_EQ(got.distance < 0, inside) << "p_M " << p_M.transpose() << " distance " << got.distance << " w " << w
                                            << " method " << int(method);
        // The gradient points away from the closest point outside, towards it inside.
        EXPECT_NEAR(got.gradient.dot(p_W - got.closest_point), got.distance, 1e-9 * (size + plain.distance));
      }
      EXPECT_GT(inside_count, 50);
    }
  }
}

TEST(PointQuery, UnitCubeInsideIsMinusTheDistanceToTheNearestFace) {
  test::Rng rng(14);
  for (bool inside_out : {false, true}) {
    SCOPED_TRACE(inside_out ? "inside out" : "outward");
    const CflModel model = buildCflModel(inside_out ? test::flipped(unitCube()) : unitCube());
    const Eigen::Isometry3d X_WM = test::randomPose(rng, 3.0);
    PointQueryOptions options;
    options.signed_distance = true;
    std::uniform_real_distribution<double> coordinate(-0.5, 1.5);
    for (int i = 0; i < 3000; ++i) {
      const Eigen::Vector3d p_M(coordinate(rng), coordinate(rng), coordinate(rng));
      const Eigen::Vector3d clamped = p_M.cwiseMax(0.0).cwiseMin(1.0);
      double expected = (p_M - clamped).norm();
      if (expected == 0) {
        expected = -std::min({p_M.x(), 1 - p_M.x(), p_M.y(), 1 - p_M.y(), p_M.z(), 1 - p_M.z()});
      }
      const PointDistance got = computePointDistance(model, X_WM, X_WM * p_M, options);
      ASSERT_NEAR(got.distance, expected, 1e-12) << "p_M " << p_M.transpose();
    }
    // On the surface: distance 0, gradient the outward normal.
    const PointDistance on_face = computePointDistance(model, X_WM, X_WM * Eigen::Vector3d(0.3, 0.6, 1.0), options);
    EXPECT_NEAR(on_face.distance, 0, 1e-15);
    EXPECT_NEAR((on_face.gradient - X_WM.linear() * Eigen::Vector3d::UnitZ()).norm(), 0, 1e-12);
    // Beyond an upper bound the side is still known.
    options.upper_bound = 0.1;
    EXPECT_EQ(computePointDistance(model, X_WM, X_WM * Eigen::Vector3d::Constant(0.5), options).distance,
              -std::numeric_limits<double>::infinity());
    EXPECT_EQ(computePointDistance(model, X_WM, X_WM * Eigen::Vector3d::Constant(5), options).distance,
              std::numeric_limits<double>::infinity());
  }
}

TEST(PointQuery, SignedRequestOnAnOpenMeshNamesTheBoundary) {
  const CflModel model = buildCflModel(test::makeHemisphere(1.0, 6, 16));
  PointQueryOptions options;
  options.signed_distance = true;
  try {
    computePointDistance(model, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero(), options);
    FAIL() << "no error";
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("cannot sign distances to this mesh: open:"), std::string::npos) << message;
    EXPECT_NE(message.find("boundary"), std::string::npos) << message;
    EXPECT_NE(message.find("SignMethod::kWindingNumber"), std::string::npos) << message;
  }
  // Unsigned is fine.
  EXPECT_NO_THROW(computePointDistance(model, Eigen::Isometry3d::Identity(), Eigen::Vector3d::Zero()));
}

TEST(PointQuery, WindingNumberSignsASphereWithAHole) {
  TriangleMesh sphere = test::makeSphere(1.0, 12, 24);
  sphere.triangles.erase(sphere.triangles.begin() + 100);
  for (bool inside_out : {false, true}) {
    SCOPED_TRACE(inside_out ? "inside out" : "outward");
    const CflModel model = buildCflModel(inside_out ? test::flipped(sphere) : sphere);
    ASSERT_FALSE(model.sign.closure.closed);
    test::Rng rng(15);
    const Eigen::Isometry3d X_WM = test::randomPose(rng, 3.0);
    PointQueryOptions options;
    options.signed_distance = true;
    options.sign_method = SignMethod::kWindingNumber;
    std::normal_distribution<double> gauss;
    std::uniform_real_distribution<double> unit(0, 1);
    for (int i = 0; i < 2000; ++i) {
      const Eigen::Vector3d direction = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
      const bool inside = i % 2 == 0;
      const double radius = inside ? 0.8 * unit(rng) : 1.2 + 5 * unit(rng);
      const PointDistance got = computePointDistance(model, X_WM, X_WM * (radius * direction), options);
      ASSERT_EQ(got.distance < 0, inside) << "radius " << radius;
    }
  }
}

TEST(PointQuery, BatchEqualsSerialBitForBit) {
  test::Rng rng(16);
  const CflModel model = buildCflModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6));
  const Eigen::Isometry3d X_WM = test::randomPose(rng, 2.0);
  std::vector<Eigen::Vector3d> points;
  for (const Eigen::Vector3d& p_M : samplePoints(model, 3000, rng)) points.push_back(X_WM * p_M);
  // The batch queries in its own (spatial) order, each point warm-started from the one before; with an upper
  // bound too, some points find nothing.
  for (int variant = 0; variant < 4; ++variant) {
    PointQueryOptions options;
    options.signed_distance = variant % 2 == 1;
    if (variant >= 2) options.upper_bound = 0.2;
    std::vector<PointDistance> serial;
    for (const auto& p : points) serial.push_back(computePointDistance(model, X_WM, p, options));
    for (int threads : {1, 2}) {
      options.threads = threads;
      std::vector<PointDistance> batch(points.size());
      computePointDistances(model, X_WM, points.data(), points.size(), batch.data(), options);
      for (std::size_t i = 0; i < points.size(); ++i) {
        ASSERT_EQ(std::memcmp(&batch[i].distance, &serial[i].distance, sizeof(double)), 0) << i;
        ASSERT_EQ(batch[i].triangle, serial[i].triangle) << i;
        ASSERT_EQ(batch[i].closest_point, serial[i].closest_point) << i;
        ASSERT_EQ(batch[i].gradient, serial[i].gradient) << i;
      }
    }
  }
}

// The batch's cached list scan bounds slivers by half-spaces of their own (edge normals within the accurate
// plane, or, without a plane, along and across the longest edge): on fans of slivers, every answer must be the
// brute force's and the serial call's, bit for bit, near the strips and in the box about them.
TEST(PointQuery, BatchOnSliversMatchesBruteForceAndSerial) {
  test::Rng rng(23);
  const CflModel model = buildCflModel(makeSliverStrip());
  const double size = model.geometry.bounds.diagonal();
  for (int pose = 0; pose < 3; ++pose) {
    const Eigen::Isometry3d X_WM = pose == 0 ? Eigen::Isometry3d::Identity() : test::randomPose(rng, 5.0);
    std::vector<Eigen::Vector3d> points;
    for (const Eigen::Vector3d& p_M : samplePoints(model, 4000, rng)) points.push_back(X_WM * p_M);
    for (int i = 0; i < 4000; ++i) {
      // Clusters just above the strips: consecutive points share leaves, the cached scan's case.
      const auto& t = model.geometry.mesh.triangles[std::size_t(i / 40) % model.geometry.mesh.triangles.size()];
      const Eigen::Vector3d on = model.geometry.mesh.vertices[t[0]] * 0.5 + model.geometry.mesh.vertices[t[2]] * 0.5;
      points.push_back(X_WM * (on + 0.01 * size * Eigen::Vector3d::Random()));
    }
    for (int threads : {1, 2}) {
      PointQueryOptions options;
      options.threads = threads;
      std::vector<PointDistance> batch(points.size());
      computePointDistances(model, X_WM, points.data(), points.size(), batch.data(), options);
      for (std::size_t i = 0; i < points.size(); ++i) {
        const Eigen::Vector3d p_M = X_WM.inverse(Eigen::Isometry) * points[i];
        const double expected = std::sqrt(bruteForceSquared(model.geometry, p_M));
        ASSERT_NEAR(batch[i].distance, expected, 1e-12 * (size + expected)) << i << " p_M " << p_M.transpose();
        const PointDistance serial = computePointDistance(model, X_WM, points[i], options);
        ASSERT_EQ(std::memcmp(&batch[i].distance, &serial.distance, sizeof(double)), 0) << i;
        ASSERT_EQ(batch[i].triangle, serial.triangle) << i;
        ASSERT_EQ(batch[i].closest_point, serial.closest_point) << i;
      }
    }
  }
}

// A grid about a cube: many points at equal distance from several faces, edges or corners (ties, which the
// batch's warm starts must break as the serial calls do).
TEST(PointQuery, BatchBreaksTiesAsSerial) {
  const CflModel model = buildCflModel(unitCube());
  std::vector<Eigen::Vector3d> points;
  for (int i = 0; i < 16; ++i)
    for (int j = 0; j < 16; ++j)
      for (int k = 0; k < 16; ++k) points.push_back(Eigen::Vector3d(i, j, k) * 0.125 - Eigen::Vector3d::Constant(0.4375));
  for (bool signed_distance : {false, true}) {
    PointQueryOptions options;
    options.signed_distance = signed_distance;
    std::vector<PointDistance> batch(points.size());
    computePointDistances(model, Eigen::Isometry3d::Identity(), points.data(), points.size(), batch.data(), options);
    for (std::size_t i = 0; i < points.size(); ++i) {
      const PointDistance serial = computePointDistance(model, Eigen::Isometry3d::Identity(), points[i], options);
      ASSERT_EQ(batch[i].distance, serial.distance) << i;
      ASSERT_EQ(batch[i].triangle, serial.triangle) << i;
      ASSERT_EQ(batch[i].closest_point, serial.closest_point) << i;
      ASSERT_EQ(batch[i].gradient, serial.gradient) << i;
    }
  }
}

// Points on and a rounding or two off the faces and corners of region cells, in clusters: consecutive points
// of the batch straddle a cell boundary, where a batch that reused the previous point's cell without the
// tree's descent would put a point in the wrong leaf. Every answer must be the serial call's, bit for bit,
// and the brute force's.
TEST(PointQuery, BatchOnCellBoundariesEqualsSerial) {
  test::Rng rng(33);
  // The cube's cell corners are dyadic, many equidistant from two faces: ties, which a wrong leaf's list
  // breaks its own way.
  const CflModel model = buildCflModel(unitCube());
  const Aabb box = model.regions.bounds();
  std::uniform_real_distribution<double> unit(0, 1);
  std::uniform_int_distribution<int> offset(-3, 3);
  std::vector<Eigen::Vector3d> points;
  while (points.size() < 4000) {
    Eigen::Vector3d p;
    for (int axis = 0; axis < 3; ++axis) p[axis] = box.min[axis] + unit(rng) * (box.max[axis] - box.min[axis]);
    const RegionCell cell = model.regions.locate(p);
    // A corner of the cell, each coordinate moved by a few ulps either way (or not at all).
    for (int k = 0; k < 16; ++k) {
      Eigen::Vector3d q = cell.min_corner;
      if (k & 1) q.x() += cell.size;
      for (int axis = 0; axis < 3; ++axis) {
        for (int step = offset(rng); step != 0; step += step > 0 ? -1 : 1)
          q[axis] = std::nextafter(q[axis], step > 0 ? INFINITY : -INFINITY);
      }
      points.push_back(q);
    }
  }
  PointQueryOptions options;
  std::vector<PointDistance> batch(points.size());
  computePointDistances(model, Eigen::Isometry3d::Identity(), points.data(), points.size(), batch.data(), options);
  for (std::size_t i = 0; i < points.size(); ++i) {
    const PointDistance serial = computePointDistance(model, Eigen::Isometry3d::Identity(), points[i], options);
    ASSERT_EQ(std::memcmp(&batch[i].distance, &serial.distance, sizeof(double)), 0) << i;
    ASSERT_EQ(batch[i].triangle, serial.triangle) << i;
    ASSERT_EQ(batch[i].closest_point, serial.closest_point) << i;
    double brute = INFINITY;
    for (const auto& c : model.geometry.corners.in_leaf_order) brute = std::min(brute, pointTriangleSquaredDistance(points[i], c[0], c[1], c[2]));
    ASSERT_NEAR(batch[i].distance, std::sqrt(brute), 1e-12) << i;
  }
}

// Crowds of points in a few leaves with long lists, each point repeated at scattered places, the whole in a
// shuffled order, queried through two poses: the batch reorders the points along its curve and shares each
// leaf's list and hints among the points of a crowd, and every answer must still land at its own point's
// index. Checked against brute force (distance, and a closest point on the reported triangle at that
// distance from the point), against the serial call bit for bit, and equal across duplicates.
TEST(PointQuery, BatchCrowdsInOneLeafKeepTheCallersOrder) {
  test::Rng rng(71);
  const CflModel model = buildCflModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6));
  const MeshModel& geometry = model.geometry;
  const Aabb box = model.regions.bounds();
  std::uniform_real_distribution<double> unit(0, 1);
  // Leaves with the longest lists among those a few random points fall in: many candidates per point, so
  // that results from another point of the crowd would be wrong.
  std::vector<RegionCell> crowded;
  while (crowded.size() < 3) {
    Eigen::Vector3d p;
    for (int axis = 0; axis < 3; ++axis) p[axis] = box.min[axis] + unit(rng) * (box.max[axis] - box.min[axis]);
    const RegionCell cell = model.regions.locate(p);
    if (model.regions.hasList(cell.leaf) && model.regions.leafListLength(cell.leaf) >= 8) crowded.push_back(cell);
  }
  std::vector<Eigen::Vector3d> points_M;
  for (const RegionCell& cell : crowded) {
    for (int k = 0; k < 300; ++k) {
      points_M.push_back(cell.min_corner + cell.size * Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
    }
  }
  const std::size_t distinct = points_M.size();
  for (std::size_t k = 0; k < distinct; k += 3) points_M.push_back(points_M[k]);  // duplicates
  std::vector<std::size_t> original(points_M.size());
  for (std::size_t i = 0; i < original.size(); ++i) original[i] = i < distinct ? i : 3 * (i - distinct);
  for (std::size_t i = points_M.size() - 1; i > 0; --i) {
    const std::size_t j = std::uniform_int_distribution<std::size_t>(0, i)(rng);
    std::swap(points_M[i], points_M[j]);
    std::swap(original[i], original[j]);
  }
  for (const Eigen::Isometry3d& X_WM : {Eigen::Isometry3d(Eigen::Isometry3d::Identity()), test::randomPose(rng, 3.0)}) {
    std::vector<Eigen::Vector3d> points_W;
    for (const Eigen::Vector3d& p_M : points_M) points_W.push_back(X_WM * p_M);
    for (bool signed_distance : {false, true}) {
      PointQueryOptions options;
      options.signed_distance = signed_distance;
      options.threads = 1;
      std::vector<PointDistance> batch(points_W.size());
      computePointDistances(model, X_WM, points_W.data(), points_W.size(), batch.data(), options);
      std::vector<const PointDistance*> first(distinct, nullptr);
      for (std::size_t i = 0; i < points_W.size(); ++i) {
        const PointDistance& r = batch[i];
        const double brute = std::sqrt(bruteForceSquared(geometry, points_M[i]));
        ASSERT_NEAR(std::abs(r.distance), brute, 1e-12) << i;
        ASSERT_GE(r.triangle, 0) << i;
        const auto& c = geometry.corners[r.triangle];
        Eigen::Vector3d on_triangle;
        pointTriangleSquaredDistance(points_M[i], c[0], c[1], c[2], &on_triangle);
        ASSERT_LT((X_WM * on_triangle - r.closest_point).norm(), 1e-12) << i;
        ASSERT_NEAR((points_W[i] - r.closest_point).norm(), brute, 1e-12) << i;
        const PointDistance serial = computePointDistance(model, X_WM, points_W[i], options);
        ASSERT_EQ(std::memcmp(&r.distance, &serial.distance, sizeof(double)), 0) << i;
        ASSERT_EQ(r.triangle, serial.triangle) << i;
        ASSERT_EQ(r.closest_point, serial.closest_point) << i;
        ASSERT_EQ(r.gradient, serial.gradient) << i;
        const PointDistance*& twin = first[original[i]];
        if (twin == nullptr) {
          twin = &r;
        } else {
          ASSERT_EQ(std::memcmp(&r.distance, &twin->distance, sizeof(double)), 0) << i;
          ASSERT_EQ(r.triangle, twin->triangle) << i;
          ASSERT_EQ(r.closest_point, twin->closest_point) << i;
        }
      }
    }
  }
}

TEST(PointQuery, ConcurrentCallersGetTheSerialAnswers) {
  test::Rng rng(17);
  const CflModel model = buildCflModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6));
  const Eigen::Isometry3d X_WM = test::randomPose(rng, 2.0);
  const std::vector<Eigen::Vector3d> points = samplePoints(model, 1000, rng);
  PointQueryOptions options;
  options.signed_distance = true;
  options.sign_method = SignMethod::kWindingNumber;
  std::vector<double> serial;
  for (const auto& p : points) serial.push_back(computePointDistance(model, X_WM, p, options).distance);
  std::vector<double> a(points.size()), b(points.size());
  std::thread first([&] {
    for (std::size_t i = 0; i < points.size(); ++i) a[i] = computePointDistance(model, X_WM, points[i], options).distance;
  });
  std::thread second([&] {
    for (std::size_t i = points.size(); i-- > 0;) b[i] = computePointDistance(model, X_WM, points[i], options).distance;
  });
  first.join();
  second.join();
  EXPECT_EQ(a, serial);
  EXPECT_EQ(b, serial);
}

// The x86-64-v3 build runs the exact tests four triangles at a time, and its scans let through candidates a
// batch old; the answers must still be the generic build's, bit for bit, ties included (the cube grid), near
// and far, signed and unsigned, one point and batches.
TEST(PointQuery, EveryBuildGivesTheGenericBuildsBits) {
  if (!queryKernelsAvailable(QueryKernels::kX86_64_V3)) GTEST_SKIP() << "only the generic build runs here";
  const QueryKernels previous = activeQueryKernels();
  test::Rng rng(17);
  struct Case {
    std::string name;
    CflModel model;
    std::vector<Eigen::Vector3d> points;
  };
  std::vector<Case> cases;
  for (NamedMesh& named : unsignedMeshes()) {
    Case c{named.name, buildCflModel(named.mesh), {}};
    c.points = samplePoints(c.model, 3000, rng);
    cases.push_back(std::move(c));
  }
  {
    Case c{"cube grid", buildCflModel(unitCube()), {}};
    for (int i = 0; i < 16; ++i)
      for (int j = 0; j < 16; ++j)
        for (int k = 0; k < 16; ++k)
          c.points.push_back(Eigen::Vector3d(i, j, k) * 0.125 - Eigen::Vector3d::Constant(0.4375));
    cases.push_back(std::move(c));
  }
  for (const Case& c : cases) {
    SCOPED_TRACE(c.name);
    for (bool signed_distance : {false, true}) {
      if (signed_distance && !c.model.sign.closure.closed) continue;
      PointQueryOptions options;
      options.signed_distance = signed_distance;
      std::vector<PointDistance> answers[2];
      std::vector<PointDistance> single[2];
      for (int build = 0; build < 2; ++build) {
        setQueryKernels(build == 0 ? QueryKernels::kGeneric : QueryKernels::kX86_64_V3);
        answers[build].resize(c.points.size());
        computePointDistances(c.model, Eigen::Isometry3d::Identity(), c.points.data(), c.points.size(),
                              answers[build].data(), options);
        for (std::size_t i = 0; i < c.points.size(); i += 7)
          single[build].push_back(computePointDistance(c.model, Eigen::Isometry3d::Identity(), c.points[i], options));
      }
      for (std::size_t i = 0; i < c.points.size(); ++i) {
        const PointDistance& x = answers[0][i];
        const PointDistance& y = answers[1][i];
        ASSERT_EQ(std::memcmp(&x.distance, &y.distance, sizeof(double)), 0) << i;
        ASSERT_EQ(x.triangle, y.triangle) << i;
        ASSERT_EQ(x.closest_point, y.closest_point) << i;
        ASSERT_EQ(x.gradient, y.gradient) << i;
      }
      for (std::size_t i = 0; i < single[0].size(); ++i) {
        ASSERT_EQ(std::memcmp(&single[0][i].distance, &single[1][i].distance, sizeof(double)), 0) << i;
        ASSERT_EQ(single[0][i].triangle, single[1][i].triangle) << i;
        ASSERT_EQ(single[0][i].closest_point, single[1][i].closest_point) << i;
      }
    }
  }
  setQueryKernels(previous);
}

TEST(PointQuery, BadPointIsNamedByIndex) {
  const CflModel model = buildCflModel(unitCube());
  std::vector<Eigen::Vector3d> points(5, Eigen::Vector3d(2, 0, 0));
  points[3].y() = std::numeric_limits<double>::quiet_NaN();
  std::vector<PointDistance> results(points.size());
  results[0].triangle = 42;
  try {
    computePointDistances(model, Eigen::Isometry3d::Identity(), points.data(), points.size(), results.data());
    FAIL() << "no error";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("points_W[3]"), std::string::npos) << error.what();
  }
  EXPECT_EQ(results[0].triangle, 42);  // untouched
  EXPECT_THROW(computePointDistance(model, Eigen::Isometry3d::Identity(), points[3]), Error);
  Eigen::Isometry3d scaled = Eigen::Isometry3d::Identity();
  scaled.linear() *= 2;
  EXPECT_THROW(computePointDistance(model, scaled, Eigen::Vector3d::Zero()), Error);
}

}  // namespace
}  // namespace cfl
