// Inputs that are legal but hostile: each gets the exact answer, or a cfl::Error naming the problem.
// References: brute force over all triangle pairs, on the same mesh in a benign placement.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <string>

namespace cfl {
namespace {

using test::Rng;

BuildOptions withResolution(int resolution) {
  BuildOptions options;
  options.resolution = resolution;
  return options;
}

// Every query of `a` against `b` at `count` random poses equals brute force within 1e-9 of A's diagonal.
void expectExactOnRandomPoses(const TriangleMesh& mesh_a, const TriangleMesh& mesh_b, int resolution, int count,
                              double range, const std::string& label) {
  const CflModel a = buildCflModel(mesh_a, withResolution(resolution));
  const MeshModel b = makeMeshModel(mesh_b);
  const double tolerance = 1e-9 * std::max(a.geometry.bounds.diagonal(), b.bounds.diagonal());
  Rng rng(11);
  for (int i = 0; i < count; ++i) {
    const Eigen::Isometry3d X_WB = test::randomPose(rng, range);
    const DistanceResult expected = bruteForceDistance(a.geometry, Eigen::Isometry3d::Identity(), b, X_WB);
    const DistanceResult got = computeDistance(a, Eigen::Isometry3d::Identity(), b, X_WB);
    ASSERT_NEAR(got.distance, expected.distance, tolerance) << label << ", pose " << i;
  }
}

TEST(BadInput, OneTriangleMeshesGiveExactDistances) {
  TriangleMesh one;
  one.vertices = {{0, 0, 0}, {1, 0, 0}, {0.3, 0.8, 0.1}};
  one.triangles = {{0, 1, 2}};
  expectExactOnRandomPoses(one, one, 8, 200, 1.5, "triangle vs triangle");
  expectExactOnRandomPoses(one, test::makeTorus(1.0, 0.35, 10, 5), 8, 100, 2.0, "triangle vs torus");
  expectExactOnRandomPoses(test::makeTorus(1.0, 0.35, 10, 5), one, 10, 100, 2.0, "torus vs triangle");
}

TEST(BadInput, DuplicateVerticesGiveTheSameDistancesAsSharedOnes) {
  // Every triangle gets its own copies of its corners: no index is shared, so no topology is found.
  const TriangleMesh shared = test::makeTorus(1.0, 0.35, 10, 5);
  TriangleMesh unshared;
  for (const auto& t : shared.triangles) {
    const int base = static_cast<int>(unshared.vertices.size());
    for (int index : t) unshared.vertices.push_back(shared.vertices[index]);
    unshared.triangles.push_back({base, base + 1, base + 2});
  }
  const CflModel a_shared = buildCflModel(shared, withResolution(12));
  const CflModel a_unshared = buildCflModel(unshared, withResolution(12));
  const MeshModel b = makeMeshModel(test::makeTorusKnot(2, 3, 0.6, 0.15, 32, 6));
  Rng rng(5);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Isometry3d X_WB = test::randomPose(rng, 2.0);
    const DistanceResult expected = bruteForceDistance(a_shared.geometry, Eigen::Isometry3d::Identity(), b, X_WB);
    EXPECT_NEAR(computeDistance(a_unshared, Eigen::Isometry3d::Identity(), b, X_WB).distance, expected.distance,
                1e-9 * a_shared.geometry.bounds.diagonal())
        << "pose " << i;
  }
}

TEST(BadInput, CoordinatesOffsetBy1e6KeepAccuracyRelativeToTheMesh) {
  // The same torus, its vertices moved by 1e6 and the pose moving it back: the answer must match the
  // unmoved configuration to 1e-9 of the mesh's diagonal (input rounding at 1e6 is about 1e-10).
  const TriangleMesh mesh = test::makeTorus(1.0, 0.35, 10, 5);
  const Eigen::Vector3d offset(1e6, -1e6, 1e6);
  TriangleMesh moved = mesh;
  for (auto& v : moved.vertices) v += offset;
  const CflModel a = buildCflModel(mesh, withResolution(12));
  const CflModel a_moved = buildCflModel(moved, withResolution(12));
  const MeshModel b = makeMeshModel(mesh);
  const MeshModel b_moved = makeMeshModel(moved);
  const Eigen::Isometry3d back(Eigen::Translation3d(-offset));
  const double tolerance = 1e-9 * a.geometry.bounds.diagonal();
  Rng rng(7);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Isometry3d X_WB = test::randomPose(rng, 2.0);
    const double expected = bruteForceDistance(a.geometry, Eigen::Isometry3d::Identity(), b, X_WB).distance;
    EXPECT_NEAR(computeDistance(a_moved, back, b_moved, X_WB * back).distance, expected, tolerance) << "pose " << i;
  }
}

TEST(BadInput, MeshesScaledTo1eMinus6KeepRelativeAccuracy) {
  const TriangleMesh mesh = test::makeTorusKnot(2, 3, 1.0, 0.3, 32, 6);
  const double scale = 1e-6;
  TriangleMesh small = mesh;
  for (auto& v : small.vertices) v *= scale;
  const CflModel a = buildCflModel(mesh, withResolution(12));
  const CflModel a_small = buildCflModel(small, withResolution(12));
  const MeshModel b = makeMeshModel(mesh);
  const MeshModel b_small = makeMeshModel(small);
  const double tolerance = 1e-9 * a.geometry.bounds.diagonal();
  Rng rng(3);
  for (int i = 0; i < 100; ++i) {
    const Eigen::Isometry3d X_WB = test::randomPose(rng, 3.0);
    Eigen::Isometry3d X_WB_small = X_WB;
    X_WB_small.translation() *= scale;
    const double expected = bruteForceDistance(a.geometry, Eigen::Isometry3d::Identity(), b, X_WB).distance;
    const double got = computeDistance(a_small, Eigen::Isometry3d::Identity(), b_small, X_WB_small).distance / scale;
    EXPECT_NEAR(got, expected, tolerance) << "pose " << i;
  }
}

TEST(BadInput, ResolutionTooLargeForMemorySaysHowManyBytesItNeeds) {
  try {
    buildCflModel(test::makeTorus(1.0, 0.35, 10, 5), withResolution(200000));
    FAIL() << "a resolution of 200000 was accepted";
  } catch (const Error& error) {
    const std::string message = error.what();
    EXPECT_NE(message.find("resolution 200000"), std::string::npos) << message;
    EXPECT_NE(message.find("bytes"), std::string::npos) << message;
  }
}

TEST(BadInput, ResolutionZeroBuildsAdaptiveRegions) {
  const TriangleMesh mesh = test::loadBunny();
  const CflModel model = buildCflModel(mesh, withResolution(0));
  EXPECT_GT(model.regions.max_depth, 0);
  EXPECT_GT(model.statistics.resolution, model.regions.root_dims[0]);
}

TEST(BadInput, NegativeMemoryLimitIsRefusedByName) {
  BuildOptions options;
  options.memory_limit = -1;
  try {
    buildCflModel(test::makeTorus(1.0, 0.35, 10, 5), options);
    FAIL() << "a negative memory limit was accepted";
  } catch (const Error& error) {
    EXPECT_NE(std::string(error.what()).find("memory_limit"), std::string::npos) << error.what();
  }
}

}  // namespace
}  // namespace cfl
