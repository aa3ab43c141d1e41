// Signed distance and penetration between closed CFL meshes through unmodified fcl::distance / fcl::collide,
// against closed forms (boxes) and the core's computePenetration, which tests/penetration_test.cpp checks
// against exact and sampled references. Open meshes keep FCL's answers (0 on contact).

#include "cfl/penetration.h"
#include "cfl_fcl/cfl_geometry.h"
#include "plain_fcl.h"
#include "support/test_meshes.h"

#include <fcl/fcl.h>
#include <gtest/gtest.h>

#include <memory>
#include <random>

namespace cfl_fcl {
namespace {

std::shared_ptr<CFLGeometry> geometry(const cfl::TriangleMesh& mesh) {
  std::vector<fcl::Vector3d> vertices(mesh.vertices.begin(), mesh.vertices.end());
  std::vector<fcl::Triangle> triangles;
  for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  return std::make_shared<CFLGeometry>(vertices, triangles);
}

fcl::Transform3d at(double x, double y, double z) {
  fcl::Transform3d X = fcl::Transform3d::Identity();
  X.translation() = fcl::Vector3d(x, y, z);
  return X;
}

TEST(FclSigned, BoxesEnteringThroughAFaceGiveMinusTheDepthWithWitnessPoints) {
  // B enters A's face x = 1 by 0.1: depth 0.1; the deepest points are B's face x = 0.9 (inside A) and A's
  // face x = 1 (inside B), 0.1 from the other surface.
  const auto a = geometry(cfl::test::makeBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1)));
  const auto b = geometry(cfl::test::makeBox(Eigen::Vector3d(0, 0.2, 0.2), Eigen::Vector3d(1.1, 0.8, 0.8)));
  fcl::CollisionObjectd oa(a, fcl::Transform3d::Identity()), ob(b, at(0.9, 0, 0));
  fcl::DistanceRequestd request(true, true);
  fcl::DistanceResultd result;
  const double d = fcl::distance(&oa, &ob, request, result);
  EXPECT_NEAR(d, -0.1, 1e-9);
  EXPECT_NEAR(result.min_distance, -0.1, 1e-9);
  EXPECT_NEAR((result.nearest_points[0] - result.nearest_points[1]).norm(), 0.1, 1e-9);
  EXPECT_EQ(result.o1, a.get());
  EXPECT_EQ(result.o2, b.get());
  // Apart, the same request gives the plain distance.
  fcl::CollisionObjectd far_b(b, at(1.25, 0, 0));
  fcl::DistanceResultd apart;
  EXPECT_NEAR(fcl::distance(&oa, &far_b, request, apart), 0.25, 1e-9);

  fcl::CollisionRequestd contact_request(4, true);
  fcl::CollisionResultd contacts;
  ASSERT_GT(fcl::collide(&oa, &ob, contact_request, contacts), 0u);
  const fcl::Contactd& first = contacts.getContact(0);
  EXPECT_NEAR(first.penetration_depth, 0.1, 1e-9);
  // FCL's normal points from o1 to o2: moving B along it separates them.
  EXPECT_NEAR(first.normal.x(), 1.0, 1e-9);
  // Contacts stay intersection points of the two surfaces, each with the bodies' depth and normal.
  for (std::size_t i = 0; i < contacts.numContacts(); ++i) {
    const fcl::Contactd& c = contacts.getContact(i);
    EXPECT_NEAR(c.penetration_depth, 0.1, 1e-9);
    EXPECT_NEAR(c.normal.x(), 1.0, 1e-9);
    EXPECT_GE(c.pos.x(), 0.9 - 1e-12);
    EXPECT_LE(c.pos.x(), 1.0 + 1e-12);
  }
}

TEST(FclSigned, ABodyWhollyInsideAnotherCollidesAndHasNegativeDistance) {
  // FCL reports no collision for a mesh wholly inside another (fcl issue #492); closed CFL meshes do.
  const auto outer = geometry(cfl::test::makeBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1)));
  const auto inner = geometry(cfl::test::makeBox(Eigen::Vector3d(-0.1, -0.1, -0.1), Eigen::Vector3d(0.1, 0.1, 0.1)));
  fcl::CollisionObjectd o(outer, fcl::Transform3d::Identity()), i(inner, at(0.5, 0.5, 0.3));
  fcl::CollisionRequestd request(1, true);
  fcl::CollisionResultd result;
  EXPECT_EQ(fcl::collide(&o, &i, request, result), 1u);
  // The inner box spans [0.4, 0.6] x [0.4, 0.6] x [0.2, 0.4]: the middle of its top face is 0.4 from A's
  // faces, the deepest point; its bottom face is 0.2 from A's face z = 0, the distance between the surfaces.
  const cfl::PenetrationResult p =
      cfl::computePenetration(outer->model(), Eigen::Isometry3d::Identity(), inner->model(),
                              Eigen::Isometry3d(at(0.5, 0.5, 0.3).matrix()));
  EXPECT_EQ(p.contained, 1);
  EXPECT_NEAR(p.depth, 0.4, 1e-9);
  EXPECT_NEAR(result.getContact(0).penetration_depth, p.depth, 1e-12);
  fcl::DistanceRequestd signed_request(true, true);
  fcl::DistanceResultd distance;
  EXPECT_NEAR(fcl::distance(&o, &i, signed_request, distance), -p.depth, 1e-12);
  EXPECT_LT(distance.min_distance, 0);
  // Without enable_signed_distance, FCL's convention: the distance between the surfaces.
  fcl::DistanceRequestd unsigned_request(true);
  fcl::DistanceResultd unsigned_result;
  EXPECT_NEAR(fcl::distance(&o, &i, unsigned_request, unsigned_result), 0.2, 1e-9);
}

TEST(FclSigned, RandomOverlapsAgreeWithTheCoreAndOpenMeshesKeepFclAnswers) {
  const cfl::TriangleMesh torus = cfl::test::makeTorus(1.0, 0.35, 24, 12);
  const auto a = geometry(torus);
  ASSERT_TRUE(a->model().sign.closure.closed) << a->model().sign.closure.reason;
  std::mt19937_64 rng(5);
  int overlapping = 0;
  for (int trial = 0; trial < 30; ++trial) {
    const Eigen::Isometry3d X = cfl::test::randomPose(rng, 1.0);
    fcl::CollisionObjectd oa(a, fcl::Transform3d::Identity()), ob(a, fcl::Transform3d(X.matrix()));
    fcl::DistanceRequestd request(true, true);
    fcl::DistanceResultd result;
    const double d = fcl::distance(&oa, &ob, request, result);
    const cfl::DistanceResult expected =
        cfl::computeSignedDistance(a->model(), Eigen::Isometry3d::Identity(), a->model(), X);
    EXPECT_NEAR(d, expected.distance, 1e-12) << trial;
    if (d < 0) {
      ++overlapping;
      EXPECT_NEAR((result.nearest_points[0] - result.nearest_points[1]).norm(), -d, 1e-9) << trial;
    }
  }
  EXPECT_GE(overlapping, 5);

  // An open mesh cannot be signed: 0 on contact, as FCL gives for meshes.
  const auto open = geometry(cfl::test::makeHemisphere());
  fcl::CollisionObjectd oa(a, fcl::Transform3d::Identity()), oo(open, at(1.0, 0, 0));
  fcl::DistanceRequestd request(true, true);
  fcl::DistanceResultd result;
  EXPECT_EQ(fcl::distance(&oa, &oo, request, result), 0.0);
}

}  // namespace
}  // namespace cfl_fcl
