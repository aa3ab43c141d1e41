// Input validation: every defect throws cfl::Error naming the culprit; valid but ugly geometry is accepted.

#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/mesh.h"
#include "cfl/mesh_model.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

namespace cfl {
namespace {

constexpr double kNan = std::numeric_limits<double>::quiet_NaN();
constexpr double kInf = std::numeric_limits<double>::infinity();

std::string lower(std::string s) {
  std::transform(s.begin(), s.end(), s.begin(), [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return s;
}

// Runs `f`, expects a cfl::Error, and returns its message (lower case) for the caller to inspect.
std::string errorMessage(const std::function<void()>& f) {
  try {
    f();
  } catch (const Error& e) {
    return lower(e.what());
  } catch (const std::exception& e) {
    ADD_FAILURE() << "expected cfl::Error, got another exception: " << e.what();
    return {};
  }
  ADD_FAILURE() << "expected cfl::Error, nothing was thrown";
  return {};
}

// A valid 10-vertex, 12-triangle mesh to break in controlled ways.
TriangleMesh smallMesh() {
  TriangleMesh mesh = test::makeBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 2, 3));
  mesh.vertices.push_back(Eigen::Vector3d(0.5, 0.5, 0.5));
  mesh.vertices.push_back(Eigen::Vector3d(0.25, 0.5, 0.75));
  return mesh;
}

// The three entry points that must reject an invalid mesh with the same diagnosis.
void expectEveryEntryPointRejects(const TriangleMesh& mesh, const std::vector<std::string>& expected_words) {
  BuildOptions options;
  options.resolution = 6;
  const std::string messages[] = {
      errorMessage([&] { validateMesh(mesh); }),
      errorMessage([&] { makeMeshModel(mesh); }),
      errorMessage([&] { buildCflModel(mesh, options); }),
  };
  for (const std::string& message : messages) {
    for (const std::string& word : expected_words) {
      EXPECT_NE(message.find(word), std::string::npos) << "message \"" << message << "\" does not name \"" << word << "\"";
    }
  }
}

TEST(MeshValidation, ValidMeshIsAccepted) {
  EXPECT_NO_THROW(validateMesh(smallMesh()));
  EXPECT_NO_THROW(makeMeshModel(smallMesh()));
}

TEST(MeshValidation, EmptyMeshIsRejected) {
  expectEveryEntryPointRejects(TriangleMesh{}, {"triangle"});
  TriangleMesh vertices_only;
  vertices_only.vertices.push_back(Eigen::Vector3d::Zero());
  expectEveryEntryPointRejects(vertices_only, {"triangle"});
}

TEST(MeshValidation, NanCoordinateIsRejectedNamingTheVertex) {
  TriangleMesh mesh = smallMesh();
  mesh.vertices[7].y() = kNan;
  expectEveryEntryPointRejects(mesh, {"vertex 7", "nan"});
}

TEST(MeshValidation, InfiniteCoordinateIsRejectedNamingTheVertex) {
  TriangleMesh mesh = smallMesh();
  mesh.vertices[6].z() = -kInf;
  expectEveryEntryPointRejects(mesh, {"vertex 6", "inf"});
}

TEST(MeshValidation, NonFiniteUnusedVertexIsRejected) {
  // Vertex 9 is used by no triangle; the contract still requires every coordinate to be finite.
  TriangleMesh mesh = smallMesh();
  mesh.vertices[9].x() = kInf;
  expectEveryEntryPointRejects(mesh, {"vertex 9"});
}

TEST(MeshValidation, CoordinatesBeyondTheSupportedRangeAreRejected) {
  // 2e302 is finite, but its square is not: accepted, it sent the builder's grid arithmetic to NaN and a
  // negative index (found by the OBJ fuzzer once the reader kept doubles).
  TriangleMesh mesh = smallMesh();
  mesh.vertices[5].y() = -2e302;
  expectEveryEntryPointRejects(mesh, {"vertex 5", "beyond"});
  mesh = smallMesh();
  mesh.vertices[2].z() = 1.01 * kMaxCoordinate;
  expectEveryEntryPointRejects(mesh, {"vertex 2", "beyond"});
  mesh = smallMesh();
  mesh.vertices[2].z() = kMaxCoordinate;  // the limit itself is allowed
  EXPECT_NO_THROW(validateMesh(mesh));
}

TEST(MeshValidation, MeshesTooSmallForTheKernelsAreRejectedButPointsAreNot) {
  for (const double scale : {1e-60, 1e-160, 1e-200, 1e-310}) {
    TriangleMesh mesh = smallMesh();
    for (Eigen::Vector3d& v : mesh.vertices) v *= scale;
    SCOPED_TRACE(scale);
    expectEveryEntryPointRejects(mesh, {"across", "underflow"});
  }
  TriangleMesh mesh = smallMesh();
  const double across = boundingBox(mesh).size().norm();
  for (Eigen::Vector3d& v : mesh.vertices) v *= 1.001 * kMinDiagonal / across;
  EXPECT_NO_THROW(validateMesh(mesh));
  EXPECT_NO_THROW(makeMeshModel(mesh));
  // Every vertex at one place: a point, whatever its units.
  for (Eigen::Vector3d& v : mesh.vertices) v = Eigen::Vector3d(1e-300, 0, 0);
  EXPECT_NO_THROW(validateMesh(mesh));
}

TEST(MeshValidation, OutOfRangeIndexIsRejectedNamingTriangleAndIndex) {
  TriangleMesh mesh = smallMesh();
  mesh.triangles[11][2] = 900;
  expectEveryEntryPointRejects(mesh, {"triangle 11", "900"});
  mesh = smallMesh();
  mesh.triangles[4][0] = static_cast<int>(mesh.vertices.size());  // one past the end
  expectEveryEntryPointRejects(mesh, {"triangle 4", std::to_string(mesh.vertices.size())});
}

TEST(MeshValidation, NegativeIndexIsRejectedNamingTriangleAndIndex) {
  TriangleMesh mesh = smallMesh();
  mesh.triangles[3][1] = -4;
  expectEveryEntryPointRejects(mesh, {"triangle 3", "-4"});
}

TEST(MeshValidation, DegenerateAndDuplicateTrianglesAreAccepted) {
  const TriangleMesh messy = test::makeMessyMesh();
  EXPECT_NO_THROW(validateMesh(messy));
  EXPECT_NO_THROW(makeMeshModel(messy));
  BuildOptions options;
  options.resolution = 6;
  EXPECT_NO_THROW(buildCflModel(messy, options));

  // A mesh of nothing but one point-triangle is still a valid (if degenerate) mesh.
  TriangleMesh point;
  point.vertices.push_back(Eigen::Vector3d(1, 2, 3));
  point.triangles.push_back({0, 0, 0});
  EXPECT_NO_THROW(validateMesh(point));
  EXPECT_NO_THROW(buildCflModel(point, options));
}

TEST(MeshValidation, BoundingBoxIgnoresVerticesNoTriangleUses) {
  const TriangleMesh messy = test::makeMessyMesh();  // has an unused vertex at (100, -100, 100)
  const Aabb box = boundingBox(messy);
  Aabb expected;
  for (const auto& t : messy.triangles) {
    for (int k = 0; k < 3; ++k) expected.extend(messy.vertices[t[k]]);
  }
  EXPECT_EQ(box.min, expected.min);
  EXPECT_EQ(box.max, expected.max);
  EXPECT_EQ(makeMeshModel(messy).bounds.max, expected.max);
}

TEST(MeshModel, CornersAreTheTrianglesVertices) {
  const TriangleMesh messy = test::makeMessyMesh();
  const MeshModel model = makeMeshModel(messy);
  ASSERT_EQ(model.corners.size(), messy.triangles.size());
  for (std::size_t t = 0; t < messy.triangles.size(); ++t) {
    for (int k = 0; k < 3; ++k) EXPECT_EQ(model.corners[t][k], messy.vertices[messy.triangles[t][k]]) << "triangle " << t;
  }
}

// The search reads the other mesh's triangles by Bvh leaf position: each entry must be the very data of the
// triangle that position names, bit for bit, or the search would bound and test a different triangle.
TEST(MeshModel, LeafOrderedCopiesAreTheDataOfTheTrianglesTheBvhNames) {
  for (const TriangleMesh& mesh : {test::makeMessyMesh(), test::makeTorusKnot(), test::makeTriangleSoup(300, 5)}) {
    const MeshModel model = makeMeshModel(mesh);
    const std::size_t count = mesh.triangles.size();
    ASSERT_EQ(model.bvh.triangle_ids.size(), count);
    ASSERT_EQ(model.corners.in_leaf_order.size(), count);
    ASSERT_EQ(model.corners.leaf_position.size(), count);
    ASSERT_EQ(model.leaf_spheres.size(), count);
    ASSERT_EQ(model.leaf_planes.size(), count);
    for (std::size_t n = 0; n < count; ++n) {
      const int t = model.bvh.triangle_ids[n];
      // Stored once in leaf order, read by id through the position index: both must name the same data.
      ASSERT_EQ(model.corners.leaf_position[t], static_cast<std::int32_t>(n)) << "triangle " << t;
      for (int k = 0; k < 3; ++k) {
        EXPECT_EQ(model.corners.in_leaf_order[n][k], mesh.vertices[mesh.triangles[t][k]]) << "position " << n;
      }
      EXPECT_EQ(model.leaf_spheres[n], model.spheres[t]) << "position " << n;
      EXPECT_EQ(model.leaf_planes[n], model.planes[t]) << "position " << n;
    }
  }
}

// Point queries walk the Bvh on its compact copy: same links, and float boxes that hold the double ones (a
// box rounded inward would prune a node holding the closest triangle).
TEST(MeshModel, CompactNodesHoldTheBvhBoxesAndLinks) {
  for (const TriangleMesh& mesh : {test::makeMessyMesh(), test::makeTorusKnot(), test::makeTriangleSoup(300, 5)}) {
    const MeshModel model = makeMeshModel(mesh);
    ASSERT_EQ(model.compact_nodes.size(), model.bvh.nodes.size());
    for (std::size_t n = 0; n < model.bvh.nodes.size(); ++n) {
      const BvhNode& node = model.bvh.nodes[n];
      const CompactBvhNode& compact = model.compact_nodes[n];
      EXPECT_EQ(compact.first, node.first) << "node " << n;
      EXPECT_EQ(compact.count, node.count) << "node " << n;
      for (int axis = 0; axis < 3; ++axis) {
        EXPECT_LE(double(compact.min[axis]), node.box().min[axis]) << "node " << n;
        EXPECT_GE(double(compact.max[axis]), node.box().max[axis]) << "node " << n;
      }
    }
  }
}

// Node pairs are bounded on these radii as segments swept by disks: every vertex below a node must lie within
// its radius of the line along its box's longest axis, measured here in long double, and the radius must be
// that largest distance, not a loose one (a bound taking 1.4 times the radius would still pass the first).
TEST(MeshModel, NodeSpineRadiiHoldEveryVertexBelowTheNodeTightly) {
  for (const TriangleMesh& mesh : {test::makeMessyMesh(), test::makeTorusKnot(), test::makeTriangleSoup(300, 5),
                                   test::makeTorus(1.0, 0.05, 400, 6)}) {
    const MeshModel model = makeMeshModel(mesh);
    ASSERT_EQ(model.node_spine_radii.size(), model.bvh.nodes.size());
    for (std::size_t n = 0; n < model.bvh.nodes.size(); ++n) {
      const BvhNode& node = model.bvh.nodes[n];
      int longest;
      node.obb_half.maxCoeff(&longest);
      using Vec = Eigen::Matrix<long double, 3, 1>;
      const Vec axis = node.obb_axes.col(longest).cast<long double>();
      const Vec center = node.obb_center.cast<long double>();
      long double farthest = 0;
      for (int k = node.subtree_first; k < node.subtree_first + node.subtree_count; ++k) {
        for (int index : mesh.triangles[std::size_t(model.bvh.triangle_ids[std::size_t(k)])]) {
          const Vec offset = mesh.vertices[std::size_t(index)].cast<long double>() - center;
          farthest = std::max(farthest, (offset - offset.dot(axis) * axis).norm());
        }
      }
      const long double radius = model.node_spine_radii[n];
      EXPECT_GE(radius, farthest) << "node " << n;
      EXPECT_LE(radius, farthest * (1 + 1e-6L) + 1e-9L * (center.cwiseAbs().sum() + 1)) << "node " << n;
    }
  }
}

// The query prunes pairs on these spheres and on the disk each cuts from its triangle's plane: every point of
// a triangle must be inside its sphere, and the center must lie in the plane. The sphere must also be the
// smallest: no center among random points of the plane near it (an independent search) needs less radius.
TEST(MeshModel, SpheresAreTheSmallestHoldingEachTriangleCenteredInItsPlane) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> unit(-1, 1);
  TriangleMesh mesh;
  auto add = [&](const Eigen::Vector3d& a, const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
    const int first = int(mesh.vertices.size());
    mesh.vertices.insert(mesh.vertices.end(), {a, b, c});
    mesh.triangles.push_back({first, first + 1, first + 2});
  };
  for (int n = 0; n < 200; ++n) {
    add(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)), Eigen::Vector3d(unit(rng), unit(rng), unit(rng)),
        Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
  }
  add({0, 0, 0}, {1, 0, 0}, {0, 1, 0});                  // right
  add({0, 0, 0}, {1, 0, 0}, {0.5, 1e-9, 0});             // sliver, obtuse
  add({0, 0, 0}, {1, 0, 0}, {2, 0, 0});                  // collinear
  add({1, 1, 1}, {1, 1, 1}, {1, 1, 1});                  // a point
  add({0, 0, 0}, {1, 0, 0}, {0.5, std::sqrt(0.75), 0});  // equilateral
  const MeshModel model = makeMeshModel(mesh);
  for (std::size_t t = 0; t < model.corners.size(); ++t) {
    const auto& c = model.corners[t];
    const Eigen::Vector3d center = model.spheres[t].head<3>();
    const double radius = model.spheres[t][3];
    const double size = (c[1] - c[0]).norm() + (c[2] - c[1]).norm() + (c[0] - c[2]).norm();
    const double slack = 1e-14 * (1 + size);
    auto reach = [&](const Eigen::Vector3d& from) {
      return std::max({(c[0] - from).norm(), (c[1] - from).norm(), (c[2] - from).norm()});
    };
    EXPECT_LE(reach(center), radius + slack) << "triangle " << t;
    const Eigen::Vector3d normal = (c[1] - c[0]).cross(c[2] - c[0]);
    if (normal.norm() > 1e-6 * size * size) {
      EXPECT_NEAR(normal.normalized().dot(center - c[0]), 0, slack) << "triangle " << t;
    }
    // Random points of the triangle's plane (its corners' affine hull) near the center.
    for (int k = 0; k < 200; ++k) {
      const double u = 0.3 * unit(rng), v = 0.3 * unit(rng);
      const Eigen::Vector3d other = center + u * (c[1] - c[0]) + v * (c[2] - c[0]);
      EXPECT_GE(reach(other), radius - slack) << "triangle " << t << " sample " << k;
    }
  }
}

TEST(BuildOptionsValidation, NegativeResolutionIsRejectedNamingTheValue) {
  BuildOptions options;
  options.resolution = -3;
  const std::string message = errorMessage([&] { buildCflModel(smallMesh(), options); });
  EXPECT_NE(message.find("resolution"), std::string::npos) << message;
  EXPECT_NE(message.find("-3"), std::string::npos) << message;
}

TEST(BuildOptionsValidation, PaddingBelowOneIsRejectedNamingTheValue) {
  BuildOptions options;
  options.resolution = 6;
  options.padding = 0.5;
  const std::string message = errorMessage([&] { buildCflModel(smallMesh(), options); });
  EXPECT_NE(message.find("padding"), std::string::npos) << message;
  EXPECT_NE(message.find("0.5"), std::string::npos) << message;
}

TEST(BuildOptionsValidation, NonFinitePaddingIsRejected) {
  BuildOptions options;
  options.resolution = 6;
  for (double padding : {kNan, kInf, -kInf}) {
    options.padding = padding;
    const std::string message = errorMessage([&] { buildCflModel(smallMesh(), options); });
    EXPECT_NE(message.find("padding"), std::string::npos) << message;
    EXPECT_TRUE(message.find("nan") != std::string::npos || message.find("inf") != std::string::npos) << message;
  }
}

TEST(BuildOptionsValidation, PaddingOfExactlyOneIsAccepted) {
  BuildOptions options;
  options.resolution = 6;
  options.padding = 1.0;
  EXPECT_NO_THROW(buildCflModel(smallMesh(), options));
}

Eigen::Isometry3d somePose() {
  test::Rng rng(7);
  return test::randomPose(rng, 2.0);
}

TEST(PoseValidation, RigidPosesAreAccepted) {
  test::Rng rng(11);
  for (int i = 0; i < 100; ++i) EXPECT_NO_THROW(validatePose(test::randomPose(rng, 100.0), "X_WA"));
  // Well inside the documented 1e-6 tolerance: a rotation that went through a few float operations.
  Eigen::Isometry3d X = somePose();
  X.linear() *= 1 + 1e-9;
  EXPECT_NO_THROW(validatePose(X, "X_WA"));
}

TEST(PoseValidation, NonFinitePoseIsRejectedNamingThePose) {
  Eigen::Isometry3d X = somePose();
  X.translation().y() = kNan;
  std::string message = errorMessage([&] { validatePose(X, "X_WB"); });
  EXPECT_NE(message.find("x_wb"), std::string::npos) << message;

  X = somePose();
  X.linear()(1, 2) = kInf;
  message = errorMessage([&] { validatePose(X, "X_WA"); });
  EXPECT_NE(message.find("x_wa"), std::string::npos) << message;
}

TEST(PoseValidation, NonOrthonormalRotationIsRejectedNamingThePose) {
  Eigen::Isometry3d scaled = somePose();
  scaled.linear() *= 1.01;
  Eigen::Isometry3d sheared = somePose();
  sheared.linear()(0, 1) += 1e-3;
  Eigen::Isometry3d reflected = somePose();
  reflected.linear().col(2) *= -1;  // orthonormal but determinant -1
  Eigen::Isometry3d zero = somePose();
  zero.linear().setZero();
  for (const Eigen::Isometry3d& X : {scaled, sheared, reflected, zero}) {
    const std::string message = errorMessage([&] { validatePose(X, "X_WB"); });
    EXPECT_NE(message.find("x_wb"), std::string::npos) << message;
  }
}

TEST(PoseValidation, DistanceQueryRejectsBadPoses) {
  BuildOptions options;
  options.resolution = 6;
  const CflModel a = buildCflModel(test::makeTorus(1.0, 0.3, 8, 4), options);
  const MeshModel b = makeMeshModel(test::makeTorus(1.0, 0.3, 8, 4));
  Eigen::Isometry3d bad = somePose();
  bad.linear() *= 2;
  errorMessage([&] { computeDistance(a, bad, b, Eigen::Isometry3d::Identity()); });
  errorMessage([&] { computeDistance(a, Eigen::Isometry3d::Identity(), b, bad); });
  errorMessage([&] { computeDistance(a, Eigen::Isometry3d::Identity(), a, bad); });
  // Finite, rigid, but B so far from A that squared distances overflow (the answer came out infinite).
  Eigen::Isometry3d far = Eigen::Isometry3d::Identity();
  far.translation() = Eigen::Vector3d(1e155, 0, 0);
  const std::string message = errorMessage([&] { computeDistance(a, Eigen::Isometry3d::Identity(), b, far); });
  EXPECT_NE(message.find("in a's frame, beyond"), std::string::npos) << message;
  // Both far from the world origin but near each other is fine.
  Eigen::Isometry3d near_far = far;
  near_far.translation().y() = 3;
  EXPECT_NO_THROW(computeDistance(a, far, b, near_far));
}

// MeshModel and CflModel are plain structs: one assembled or edited by hand can hold arrays of different
// lengths. A query names the array and the model instead of reading past the end of one.
TEST(ModelShapeValidation, DistanceQueryRejectsModelsWhoseArraysDisagree) {
  BuildOptions options;
  options.resolution = 6;
  const CflModel a = buildCflModel(test::makeTorus(1.0, 0.3, 8, 4), options);
  const MeshModel b = makeMeshModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 16, 4));
  const Eigen::Isometry3d X_WB = somePose();
  const std::vector<std::pair<std::function<void(MeshModel&)>, std::string>> damages = {
      {[](MeshModel& m) { m.corners.in_leaf_order.clear(); }, "corners.in_leaf_order"},
      {[](MeshModel& m) { m.leaf_spheres.pop_back(); }, "leaf_spheres"},
      {[](MeshModel& m) { m.leaf_planes.emplace_back(); }, "leaf_planes"},
      {[](MeshModel& m) { m.corners.leaf_position.pop_back(); }, "corners"},
      {[](MeshModel& m) { m.spheres.clear(); }, "spheres"},
      {[](MeshModel& m) { m.planes.pop_back(); }, "planes"},
      {[](MeshModel& m) { m.spines.pop_back(); }, "spines"},
      {[](MeshModel& m) { m.bvh.triangle_ids.pop_back(); }, "bvh.triangle_ids"},
      {[](MeshModel& m) { m.bvh.nodes.clear(); }, "bvh has no nodes"},
      {[](MeshModel& m) { m.node_spine_radii.pop_back(); }, "node_spine_radii"},
  };
  for (const auto& [damage, field] : damages) {
    MeshModel damaged_b = b;
    damage(damaged_b);
    std::string message = errorMessage([&] { computeDistance(a, Eigen::Isometry3d::Identity(), damaged_b, X_WB); });
    EXPECT_NE(message.find(field), std::string::npos) << message;
    EXPECT_NE(message.find("b: meshmodel"), std::string::npos) << message;
    CflModel damaged_a = a;
    damage(damaged_a.geometry);
    message = errorMessage([&] { computeDistance(damaged_a, Eigen::Isometry3d::Identity(), b, X_WB); });
    EXPECT_NE(message.find(field), std::string::npos) << message;
    EXPECT_NE(message.find("a's geometry"), std::string::npos) << message;
    // The certificate-keeping overload runs the same search.
    DistanceCache cache;
    message = errorMessage([&] { computeDistance(a, Eigen::Isometry3d::Identity(), damaged_b, X_WB, cache); });
    EXPECT_NE(message.find(field), std::string::npos) << message;
  }
  EXPECT_NO_THROW(computeDistance(a, Eigen::Isometry3d::Identity(), b, X_WB));
}

// The collision query and the brute-force reference read the same arrays, so they refuse the same models.
TEST(ModelShapeValidation, CollisionAndBruteForceRejectModelsWhoseArraysDisagree) {
  const MeshModel a = makeMeshModel(test::makeTorus(1.0, 0.3, 8, 4));
  const MeshModel b = makeMeshModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 16, 4));
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  MeshModel short_spheres = b;
  short_spheres.spheres.pop_back();
  std::string message = errorMessage([&] { bruteForceDistance(a, I, short_spheres, I); });
  EXPECT_NE(message.find("b: meshmodel::spheres"), std::string::npos) << message;
  MeshModel short_ids = a;
  short_ids.bvh.triangle_ids.pop_back();
  message = errorMessage([&] { computeCollision(short_ids, I, b, I); });
  EXPECT_NE(message.find("a: meshmodel::bvh.triangle_ids"), std::string::npos) << message;
  MeshModel no_nodes = b;
  no_nodes.bvh.nodes.clear();
  message = errorMessage([&] { computeCollision(a, I, no_nodes, I); });
  EXPECT_NE(message.find("bvh has no nodes"), std::string::npos) << message;
  EXPECT_NO_THROW(computeCollision(a, I, b, I));
  EXPECT_NO_THROW(bruteForceDistance(a, I, b, I));
}

}  // namespace
}  // namespace cfl
