// computeBoxDistance (box_query.h) against brute force: every mesh triangle against the box's 12 triangles with
// the exact triangle kernel, and 0 when a mesh triangle lies wholly inside the box.

#include "cfl/box_query.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstring>
#include <random>
#include <string>

namespace cfl {
namespace {

// The distance by brute force: every mesh triangle against the box's 12 triangles, and 0 when a mesh vertex
// lies inside the box.
double bruteForceBoxDistance(const CflModel& model, const TriangleMesh& mesh, const Eigen::Isometry3d& X_WM,
                             const Eigen::Isometry3d& X_WB, const Eigen::Vector3d& half) {
  const MeshModel box = makeMeshModel(test::makeBox(-half, half));
  double expected = bruteForceDistance(model.geometry, X_WM, box, X_WB).distance;
  for (const auto& v : mesh.vertices)
    if (((X_WB.inverse() * (X_WM * v)).cwiseAbs() - half).maxCoeff() <= 0) expected = 0;
  return expected;
}

TEST(BoxQuery, EqualsBruteForceApartTouchingAndAroundTheMesh) {
  std::mt19937_64 rng(1);
  std::normal_distribution<double> gauss;
  for (const auto& [name, mesh] : std::vector<std::pair<std::string, TriangleMesh>>{
           {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 64, 6)},
           {"sheet", test::makeWavySheet(1.5, 0.4, 16)},
           {"soup", test::makeTriangleSoup(300, 5)}}) {
    const CflModel model = buildCflModel(mesh);
    const double size = model.geometry.bounds.diagonal();
    int apart = 0, touching = 0;
    for (int i = 0; i < 150; ++i) {
      const Eigen::Isometry3d X_WM = test::randomPose(rng, 1.0);
      Eigen::Isometry3d X_WB = test::randomPose(rng, 1.0);
      const Eigen::Vector3d on = test::randomPointOnTriangle(mesh, int(rng() % mesh.triangles.size()), rng);
      X_WB.translation() = X_WM * on + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)) * 0.05 * size;
      Eigen::Vector3d half(0.02 + 0.01 * (i % 3), 0.03, 0.015);
      half *= size;
      if (i % 25 == 0) half = Eigen::Vector3d::Constant(size);  // The mesh wholly inside.
      const double expected = bruteForceBoxDistance(model, mesh, X_WM, X_WB, half);
      const BoxDistance got = computeBoxDistance(model, X_WM, X_WB, half);
      const std::string at = name + " pose " + std::to_string(i);
      ASSERT_GE(got.triangle, 0) << at;
      EXPECT_NEAR(got.distance, expected, 1e-9 * size) << at;
      EXPECT_NEAR((got.box_point - got.mesh_point).norm(), got.distance, 1e-9 * size) << at;
      (expected > 0 ? apart : touching)++;
      if (expected > 0) EXPECT_EQ(computeBoxDistance(model, X_WM, X_WB, half, got.distance * (1 - 1e-9)).triangle, -1) << at;
    }
    EXPECT_GT(apart, 20) << name;
    EXPECT_GT(touching, 10) << name;
  }
}

// Where only some of a triangle's features can be closest (the pruning by normal cones and separating gaps):
// boxes aligned with an axis-aligned mesh, so that faces and edges are parallel and touch exactly, boxes
// turned by small angles, far boxes, and a mesh with zero-area and duplicated triangles.
TEST(BoxQuery, EqualsBruteForceOnParallelFacesDegenerateTrianglesAndFarBoxes) {
  std::mt19937_64 rng(5);
  std::uniform_real_distribution<double> uniform(-1, 1);
  for (const auto& [name, mesh] : test::makeFeaturePruningMeshes()) {
    const CflModel model = buildCflModel(mesh);
    const double size = model.geometry.bounds.diagonal();
    int apart = 0, touching = 0;
    for (int i = 0; i < 200; ++i) {
      const Eigen::Isometry3d X_WM = Eigen::Isometry3d::Identity();
      Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
      // Aligned (a quarter of the poses), slightly turned, or anyhow.
      if (i % 4 == 1) X_WB.linear() = Eigen::AngleAxisd(1e-3 * uniform(rng), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      if (i % 4 == 2) X_WB = test::randomPose(rng, 1.0);
      if (i % 4 == 3) X_WB.linear() = Eigen::AngleAxisd(0.5 * M_PI, Eigen::Vector3d::UnitX()).toRotationMatrix();
      const Eigen::Vector3d half = Eigen::Vector3d(0.1 + 0.1 * std::abs(uniform(rng)), 0.05, 0.2) * size;
      // Grid-snapped centers put faces exactly level with the mesh's; a few boxes are far away.
      Eigen::Vector3d center(std::round(4 * uniform(rng)) / 4, std::round(4 * uniform(rng)) / 4, uniform(rng));
      if (i % 10 == 0) center *= 5;
      X_WB.translation() = center * size;
      const double expected = bruteForceBoxDistance(model, mesh, X_WM, X_WB, half);
      const BoxDistance got = computeBoxDistance(model, X_WM, X_WB, half);
      const std::string at = name + " pose " + std::to_string(i);
      ASSERT_GE(got.triangle, 0) << at;
      EXPECT_NEAR(got.distance, expected, 1e-9 * size) << at;
      EXPECT_NEAR((got.box_point - got.mesh_point).norm(), got.distance, 1e-9 * size) << at;
      (expected > 0 ? apart : touching)++;
    }
    EXPECT_GT(apart, 20) << name;
    EXPECT_GT(touching, 3) << name;
  }
}

// Boxes of every aspect (cubes, flat plates, needles, slabs) turned anyhow near the surface, 0.2% to 3% of the
// diagonal away as the shape benches place them, where the walk's node spheres reach past the best distance
// most often; and an upper bound just above and just below the answer, which the walk's bounds start from.
TEST(BoxQuery, FlatAndNeedleBoxesNearTheSurfaceEqualBruteForceUnderUpperBounds) {
  std::mt19937_64 rng(17);
  std::uniform_real_distribution<double> uniform(0, 1);
  std::normal_distribution<double> gauss;
  const std::vector<std::pair<std::string, Eigen::Vector3d>> aspects = {{"cube", {1, 1, 1}},
                                                                        {"plate", {1, 0.7, 1e-3}},
                                                                        {"needle", {1, 2e-3, 1e-3}},
                                                                        {"slab", {1, 0.3, 0.02}}};
  for (const auto& [name, mesh] : std::vector<std::pair<std::string, TriangleMesh>>{
           {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 96, 8)},
           {"bunny", test::loadBunny()},
           {"sheet", test::makeWavySheet(1.5, 0.4, 24)},
           {"soup", test::makeTriangleSoup(400, 7)}}) {
    const CflModel model = buildCflModel(mesh);
    const double size = model.geometry.bounds.diagonal();
    for (const auto& [aspect_name, aspect] : aspects) {
      int apart = 0;
      for (int i = 0; i < 25; ++i) {
        const Eigen::Isometry3d X_WM = test::randomPose(rng, 1.0);
        Eigen::Isometry3d X_WB = test::randomPose(rng, 1.0);
        const Eigen::Vector3d half = (0.005 + 0.02 * uniform(rng)) * size * aspect;
        // A surface point, pushed off along a random direction by the box's reach that way plus a gap (into
        // the solid about half the time, where the box may still touch the surface).
        const Eigen::Vector3d on = X_WM * test::randomPointOnTriangle(mesh, int(rng() % mesh.triangles.size()), rng);
        const Eigen::Vector3d direction = Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)).normalized();
        const double reach = (X_WB.linear().transpose() * direction).cwiseAbs().dot(half);
        X_WB.translation() = on + (reach + (0.002 + 0.028 * uniform(rng)) * size) * direction;
        const double expected = bruteForceBoxDistance(model, mesh, X_WM, X_WB, half);
        const BoxDistance got = computeBoxDistance(model, X_WM, X_WB, half);
        const std::string at = name + " " + aspect_name + " pose " + std::to_string(i);
        ASSERT_GE(got.triangle, 0) << at;
        EXPECT_NEAR(got.distance, expected, 1e-9 * size) << at;
        EXPECT_NEAR((got.box_point - got.mesh_point).norm(), got.distance, 1e-9 * size) << at;
        if (!(expected > 0)) continue;
        ++apart;
        const BoxDistance above = computeBoxDistance(model, X_WM, X_WB, half, expected * (1 + 1e-6));
        EXPECT_GE(above.triangle, 0) << at;
        EXPECT_NEAR(above.distance, expected, 1e-9 * size) << at;
        EXPECT_EQ(computeBoxDistance(model, X_WM, X_WB, half, expected * (1 - 1e-6)).triangle, -1) << at;
      }
      EXPECT_GT(apart, 5) << name << " " << aspect_name;
    }
  }
}

// The query takes its exact point-triangle and segment-segment distances from the active kernel build
// (cfl/query_kernels.h): every build this CPU runs must give the same bits (distance, points, triangle), and
// the generic one must match brute force, on poses near the mesh where many triangles reach the exact tests.
TEST(BoxQuery, EveryKernelBuildGivesTheSameBitsAndBruteForcesDistance) {
  const QueryKernels previous = activeQueryKernels();
  std::mt19937_64 rng(9);
  std::normal_distribution<double> gauss;
  auto same = [](double x, double y) { return std::memcmp(&x, &y, sizeof x) == 0; };
  auto sameVector = [&](const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
    return same(x[0], y[0]) && same(x[1], y[1]) && same(x[2], y[2]);
  };
  int compared = 0;
  for (const auto& [name, mesh] : std::vector<std::pair<std::string, TriangleMesh>>{
           {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 64, 6)}, {"bunny", test::loadBunny()}}) {
    const CflModel model = buildCflModel(mesh);
    const double size = model.geometry.bounds.diagonal();
    for (int i = 0; i < 100; ++i) {
      const Eigen::Isometry3d X_WM = test::randomPose(rng, 1.0);
      Eigen::Isometry3d X_WB = test::randomPose(rng, 1.0);
      const Eigen::Vector3d on = test::randomPointOnTriangle(mesh, int(rng() % mesh.triangles.size()), rng);
      X_WB.translation() = X_WM * on + Eigen::Vector3d(gauss(rng), gauss(rng), gauss(rng)) * 0.03 * size;
      const Eigen::Vector3d half = Eigen::Vector3d(0.015, 0.01, 0.0075 + 0.005 * (i % 3)) * size;
      const std::string at = name + " pose " + std::to_string(i);
      setQueryKernels(QueryKernels::kGeneric);
      const BoxDistance generic = computeBoxDistance(model, X_WM, X_WB, half);
      EXPECT_NEAR(generic.distance, bruteForceBoxDistance(model, mesh, X_WM, X_WB, half), 1e-9 * size) << at;
      for (const QueryKernels kernels : {QueryKernels::kX86_64_V3}) {
        if (!queryKernelsAvailable(kernels)) continue;
        setQueryKernels(kernels);
        const BoxDistance got = computeBoxDistance(model, X_WM, X_WB, half);
        EXPECT_TRUE(same(got.distance, generic.distance)) << at << ": " << got.distance << " vs " << generic.distance;
        EXPECT_TRUE(sameVector(got.box_point, generic.box_point)) << at;
        EXPECT_TRUE(sameVector(got.mesh_point, generic.mesh_point)) << at;
        EXPECT_EQ(got.triangle, generic.triangle) << at;
        ++compared;
      }
    }
  }
  setQueryKernels(previous);
  if (!queryKernelsAvailable(QueryKernels::kX86_64_V3)) GTEST_SKIP() << "only the generic build runs here";
  EXPECT_EQ(compared, 200);
}

TEST(BoxQuery, BadInputThrowsCflError) {
  const CflModel model = buildCflModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 32, 6));
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  EXPECT_THROW(computeBoxDistance(model, I, I, Eigen::Vector3d(1, 0, 1)), Error);
  EXPECT_THROW(computeBoxDistance(model, I, I, Eigen::Vector3d(1, NAN, 1)), Error);
  EXPECT_THROW(computeBoxDistance(model, I, I, Eigen::Vector3d::Ones(), -1), Error);
}

}  // namespace
}  // namespace cfl
