// Linked as `fcl` first, then cfl_fcl, into an executable: a definition in a linked object beats one in a
// shared library, so the adapter's fcl::distance / fcl::collide still win and CFL geometries work.
#include "cfl_fcl/cfl_geometry.h"
#include "plain_fcl.h"
#include "support/test_meshes.h"

#include <fcl/fcl.h>

#include <gtest/gtest.h>

#include <random>

namespace {

TEST(FclAdapterLinkOrder, ExecutableLinkingFclBeforeCflFclStillReachesCfl) {
  const cfl::TriangleMesh mesh = cfl::test::makeTorusKnot(2, 3, 0.5, 0.3, 32, 5);
  std::vector<fcl::Vector3d> v = mesh.vertices;
  std::vector<fcl::Triangle> t;
  for (const auto& f : mesh.triangles) t.emplace_back(f[0], f[1], f[2]);
  auto obbrss = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  obbrss->beginModel();
  obbrss->addSubModel(v, t);
  obbrss->endModel();
  cfl::BuildOptions options;
  options.resolution = 12;
  auto cfl = std::make_shared<cfl_fcl::CFLGeometry>(v, t, options);
  const double diagonal = cfl::boundingBox(mesh).diagonal();
  std::mt19937_64 rng(11);
  for (int i = 0; i < 20; ++i) {
    const fcl::Transform3d tf_a(cfl::test::randomPose(rng, diagonal));
    const fcl::Transform3d tf_b(cfl::test::randomPose(rng, diagonal));
    fcl::DistanceRequestd request;
    fcl::DistanceResultd got, expected;
    fcl::CollisionObjectd a(cfl, tf_a), b(cfl, tf_b), ra(obbrss, tf_a), rb(obbrss, tf_b);
    fcl::distance(&a, &b, request, got);
    cfl_fcl::test::plainFcl().distance_objects(&ra, &rb, request, expected);
    EXPECT_NEAR(got.min_distance, expected.min_distance, 1e-9 * diagonal) << "pose " << i;
    EXPECT_EQ(got.o1, cfl.get());
  }
}

}  // namespace
