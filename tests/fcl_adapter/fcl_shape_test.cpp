// Spheres, capsules, boxes and convexes against CFL geometries, through the unmodified fcl::distance /
// fcl::collide, on a closed 10k-triangle torus knot, an open sheet and a triangle soup, at short and long
// range and overlapping. References: libfcl's own shape-vs-BVHModel<OBBRSS> (plain_fcl.h), exact for
// spheres; for capsules, boxes and convexes FCL runs GJK, which stops at its own tolerance, so their bar is
// a brute force over every triangle with the library's exact triangle kernel, and FCL only to its GJK
// tolerance. Signed values are checked against a brute-force distance signed by a brute-force winding number.

#include "cfl_fcl/cfl_geometry.h"
#include "cfl/cfl_query.h"
#include "cfl/triangle_distance.h"
#include "plain_fcl.h"
#include "support/sign_references.h"
#include "support/test_meshes.h"

#include <fcl/fcl.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace cfl_fcl {
namespace {

using test::plainFcl;

struct Scene {
  std::string name;
  cfl::TriangleMesh mesh;
  std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> obbrss;
  std::shared_ptr<CFLGeometry> cfl;
  double diagonal = 0;
  double tolerance = 0;  // 1e-9 of the diagonal: exact up to rounding.
  bool closed = false;
};

std::unique_ptr<Scene> makeScene(const std::string& name, cfl::TriangleMesh mesh) {
  auto s = std::make_unique<Scene>();
  s->name = name;
  s->mesh = mesh;
  std::vector<fcl::Triangle> triangles;
  for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  s->obbrss = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  s->obbrss->beginModel();
  s->obbrss->addSubModel(mesh.vertices, triangles);
  s->obbrss->endModel();
  s->cfl = std::make_shared<CFLGeometry>(mesh.vertices, triangles);
  s->diagonal = cfl::boundingBox(mesh).diagonal();
  s->tolerance = 1e-9 * s->diagonal;
  s->closed = s->cfl->model().sign.closure.closed;
  return s;
}

// Closed, 10240 triangles.
const Scene& knot() {
  static const auto s = makeScene("knot", cfl::test::makeTorusKnot(2, 3, 1.0, 0.3, 640, 8));
  return *s;
}
const Scene& sheet() {
  static const auto s = makeScene("sheet", cfl::test::makeWavySheet(1.5, 0.4, 40));
  return *s;
}
const Scene& soup() {
  static const auto s = makeScene("soup", cfl::test::makeTriangleSoup(1500, 11));
  return *s;
}

// Brute-force references, world frame, mesh at X.
double segmentMeshDistance(const Scene& s, const fcl::Transform3d& X, const fcl::Vector3d& p0, const fcl::Vector3d& p1) {
  double best = INFINITY;
  const Eigen::Vector3d segment[3] = {p0, p1, p1};
  for (const auto& t : s.mesh.triangles) {
    const Eigen::Vector3d q[3] = {X * s.mesh.vertices[t[0]], X * s.mesh.vertices[t[1]], X * s.mesh.vertices[t[2]]};
    best = std::min(best, cfl::triangleTriangleSquaredDistance(segment, q));
  }
  return std::sqrt(best);
}

double signedPointDistance(const Scene& s, const fcl::Transform3d& X, const fcl::Vector3d& p) {
  const double d = cfl::test::referencePointMeshDistance(s.mesh, p, Eigen::Isometry3d(X));
  const double w = cfl::test::referenceWindingNumber(s.mesh, X.inverse() * p);
  return std::abs(w) >= 0.5 ? -d : d;  // Either orientation: the knot winds inward.
}

// Brute-force least signed distance along a segment: dense samples give an upper bound; the distance is
// 1-Lipschitz, so the true value is at most half a spacing below it.
double signedSegmentDistance(const Scene& s, const fcl::Transform3d& X, const fcl::Vector3d& p0, const fcl::Vector3d& p1,
                             int samples, double* slack) {
  double best = INFINITY;
  for (int i = 0; i <= samples; ++i) best = std::min(best, signedPointDistance(s, X, p0 + (p1 - p0) * (double(i) / samples)));
  *slack = 0.5 * (p1 - p0).norm() / samples;
  const double unsigned_distance = segmentMeshDistance(s, X, p0, p1);
  // Outside (or touching): the unsigned distance is exact.
  return best >= 0 ? unsigned_distance : best;
}

double pointTriangleDistance(const Scene& s, int t, const fcl::Transform3d& X, const fcl::Vector3d& p) {
  const auto& tri = s.mesh.triangles.at(t);
  return std::sqrt(cfl::test::referencePointTriangleSquaredDistance(X.inverse() * p, s.mesh.vertices[tri[0]],
                                                                     s.mesh.vertices[tri[1]], s.mesh.vertices[tri[2]]));
}

// A shape pose near a random point of the mesh: offset along a random direction by a fraction of the
// diagonal drawn from [-near, far] (negative: towards the inside), random rotation.
fcl::Transform3d shapePose(const Scene& s, std::mt19937_64& rng, double near, double far) {
  std::uniform_int_distribution<int> pick(0, int(s.mesh.triangles.size()) - 1);
  std::uniform_real_distribution<double> offset(-near, far);
  std::normal_distribution<double> normal;
  const int t = pick(rng);
  const Eigen::Vector3d on = cfl::test::randomPointOnTriangle(s.mesh, t, rng);
  const Eigen::Vector3d direction = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
  fcl::Transform3d tf = fcl::Transform3d::Identity();
  tf.linear() = cfl::test::randomRotation(rng);
  tf.translation() = on + direction * (offset(rng) * s.diagonal);
  return tf;
}

fcl::Transform3d meshPose(std::mt19937_64& rng) {
  fcl::Transform3d tf = fcl::Transform3d::Identity();
  tf.linear() = cfl::test::randomRotation(rng);
  tf.translation() = fcl::Vector3d(0.3, -0.2, 0.1);
  return tf;
}

std::vector<const Scene*> scenes() { return {&knot(), &sheet(), &soup()}; }

// Every distance result of a shape answered from the regions: FCL's roles (mesh o1 with its triangle, shape
// o2 with NONE, whichever order it was called in), nearest points on the mesh triangle and on the shape,
// world frame, |p1 - p2| = |distance|.
void expectShapeResult(const Scene& s, const fcl::Transform3d& tf_m, const fcl::CollisionGeometryd* shape,
                       const fcl::DistanceResultd& got, const std::string& at) {
  EXPECT_EQ(got.o1, s.cfl.get()) << at;
  EXPECT_EQ(got.o2, shape) << at;
  EXPECT_EQ(got.b2, -1) << at;  // DistanceResult::NONE
  ASSERT_GE(got.b1, 0) << at;
  EXPECT_LE(pointTriangleDistance(s, int(got.b1), tf_m, got.nearest_points[0]), s.tolerance) << at;
  EXPECT_NEAR((got.nearest_points[0] - got.nearest_points[1]).norm(), std::abs(got.min_distance), s.tolerance) << at;
}

TEST(FclShapeDistance, SphereEqualsFclExactlyWhereSeparatedAndIsFclsOwnWhereItTouches) {
  std::mt19937_64 rng(1);
  for (const Scene* s : scenes()) {
    int separated = 0, touching = 0;
    for (int i = 0; i < 60; ++i) {
      const double radius = (i % 2 ? 0.005 : 0.02) * s->diagonal;
      auto sphere = std::make_shared<fcl::Sphered>(radius);
      const fcl::Transform3d tf_m = meshPose(rng);
      const fcl::Transform3d tf_s = tf_m * shapePose(*s, rng, 0.01, i % 3 ? 0.03 : 0.5);
      const std::string at = s->name + " pose " + std::to_string(i);
      fcl::DistanceRequestd request(true);
      fcl::CollisionObjectd so(sphere, tf_s), co(s->cfl, tf_m), ref(s->obbrss, tf_m);
      fcl::DistanceResultd expected, shape_first, cfl_first;
      plainFcl().distance_objects(&so, &ref, request, expected);
      fcl::distance(&so, &co, request, shape_first);
      fcl::distance(s->cfl.get(), tf_m, sphere.get(), tf_s, request, cfl_first);
      const double exact = cfl::test::referencePointMeshDistance(s->mesh, tf_s.translation(), Eigen::Isometry3d(tf_m)) - radius;
      if (exact > s->tolerance) {
        ++separated;
        for (const fcl::DistanceResultd* got : {&shape_first, &cfl_first}) {
          EXPECT_NEAR(got->min_distance, exact, s->tolerance) << at;
          EXPECT_NEAR(got->min_distance, expected.min_distance, s->tolerance) << at;
          expectShapeResult(*s, tf_m, sphere.get(), *got, at);
          EXPECT_NEAR((got->nearest_points[1] - tf_s.translation()).norm(), radius, s->tolerance) << at;
        }
        // FCL 0.7 reports this pair's nearest points in each object's own frame (its sphere-triangle code
        // never maps them back); the adapter reports world frame, as FCL does for every other pair.
        EXPECT_LE((tf_m.inverse() * shape_first.nearest_points[0] - expected.nearest_points[0]).norm(), 1e-6 * s->diagonal)
            << at;
      } else if (exact < -s->tolerance) {
        ++touching;
        // FCL's own path on the OBBRSS twin: the very same number.
        EXPECT_EQ(shape_first.min_distance, expected.min_distance) << at;
        EXPECT_EQ(cfl_first.min_distance, expected.min_distance) << at;
      }
    }
    EXPECT_GT(separated, 10) << s->name;
    EXPECT_GT(touching, 3) << s->name;
  }
}

TEST(FclShapeDistance, CapsuleEqualsTheBruteForceSegmentDistanceAndFclToItsGjkTolerance) {
  std::mt19937_64 rng(2);
  for (const Scene* s : scenes()) {
    int separated = 0;
    for (int i = 0; i < 40; ++i) {
      const double radius = 0.01 * s->diagonal;
      auto capsule = std::make_shared<fcl::Capsuled>(radius, (i % 2 ? 0.05 : 0.2) * s->diagonal);
      const fcl::Transform3d tf_m = meshPose(rng);
      const fcl::Transform3d tf_s = tf_m * shapePose(*s, rng, 0.0, i % 3 ? 0.04 : 0.5);
      const std::string at = s->name + " pose " + std::to_string(i);
      const fcl::Vector3d p0 = tf_s * fcl::Vector3d(0, 0, -0.5 * capsule->lz), p1 = tf_s * fcl::Vector3d(0, 0, 0.5 * capsule->lz);
      const double exact = segmentMeshDistance(*s, tf_m, p0, p1) - radius;
      fcl::DistanceRequestd request(true);
      fcl::CollisionObjectd so(capsule, tf_s), co(s->cfl, tf_m), ref(s->obbrss, tf_m);
      fcl::DistanceResultd expected, shape_first, cfl_first;
      plainFcl().distance_objects(&so, &ref, request, expected);
      fcl::distance(&so, &co, request, shape_first);
      fcl::distance(s->cfl.get(), tf_m, capsule.get(), tf_s, request, cfl_first);
      if (!(exact > s->tolerance)) continue;
      ++separated;
      for (const fcl::DistanceResultd* got : {&shape_first, &cfl_first}) {
        EXPECT_NEAR(got->min_distance, exact, s->tolerance) << at;
        // GJK stops within about its tolerance of the answer, relative to the shapes' size.
        EXPECT_NEAR(got->min_distance, expected.min_distance, 1e-5 * s->diagonal) << at;
        expectShapeResult(*s, tf_m, capsule.get(), *got, at);
        // The point on the capsule lies on its surface.
        Eigen::Vector3d on_axis;
        const fcl::Vector3d q = got->nearest_points[1];
        const double t = std::clamp((q - p0).dot(p1 - p0) / (p1 - p0).squaredNorm(), 0.0, 1.0);
        on_axis = p0 + t * (p1 - p0);
        EXPECT_NEAR((q - on_axis).norm(), radius, s->tolerance) << at;
      }
    }
    EXPECT_GT(separated, 4) << s->name;
  }
}

std::shared_ptr<fcl::Convexd> octahedron(double size) {
  auto vertices = std::make_shared<std::vector<fcl::Vector3d>>(std::vector<fcl::Vector3d>{
      {size, 0, 0}, {-size, 0, 0}, {0, size, 0}, {0, -size, 0}, {0, 0, size}, {0, 0, -size}});
  auto faces = std::make_shared<std::vector<int>>(std::vector<int>{
      3, 0, 2, 4, 3, 2, 1, 4, 3, 1, 3, 4, 3, 3, 0, 4, 3, 2, 0, 5, 3, 1, 2, 5, 3, 3, 1, 5, 3, 0, 3, 5});
  return std::make_shared<fcl::Convexd>(vertices, 8, faces);
}

TEST(FclShapeDistance, BoxAndConvexEqualTheBruteForceMeshDistanceAndFclToItsGjkTolerance) {
  std::mt19937_64 rng(3);
  for (const Scene* s : scenes()) {
    const cfl::MeshModel mesh_model = cfl::makeMeshModel(s->mesh);
    int separated = 0;
    for (int i = 0; i < 40; ++i) {
      const double size = (i % 2 ? 0.01 : 0.05) * s->diagonal;
      std::shared_ptr<fcl::CollisionGeometryd> shape;
      cfl::TriangleMesh shape_mesh;
      if (i % 4 < 2) {
        shape = std::make_shared<fcl::Boxd>(size, 1.5 * size, 0.7 * size);
        shape_mesh = cfl::test::makeBox(-0.5 * Eigen::Vector3d(size, 1.5 * size, 0.7 * size),
                                        0.5 * Eigen::Vector3d(size, 1.5 * size, 0.7 * size));
      } else {
        auto convex = octahedron(size);
        shape = convex;
        shape_mesh.vertices = convex->getVertices();
        const auto& f = convex->getFaces();
        for (std::size_t k = 0; k < f.size(); k += 4) shape_mesh.triangles.push_back({f[k + 1], f[k + 2], f[k + 3]});
      }
      const fcl::Transform3d tf_m = meshPose(rng);
      const fcl::Transform3d tf_s = tf_m * shapePose(*s, rng, 0.0, i % 3 ? 0.05 : 0.5);
      const std::string at = s->name + " pose " + std::to_string(i) + " shape " + std::to_string(shape->getNodeType());
      const cfl::DistanceResult brute = cfl::bruteForceDistance(mesh_model, Eigen::Isometry3d(tf_m),
                                                                cfl::makeMeshModel(shape_mesh), Eigen::Isometry3d(tf_s));
      fcl::DistanceRequestd request(true);
      fcl::CollisionObjectd so(shape, tf_s), co(s->cfl, tf_m), ref(s->obbrss, tf_m);
      fcl::DistanceResultd expected, shape_first, cfl_first;
      plainFcl().distance_objects(&so, &ref, request, expected);
      fcl::distance(&so, &co, request, shape_first);
      fcl::distance(s->cfl.get(), tf_m, shape.get(), tf_s, request, cfl_first);
      // Separated surfaces, and no triangle inside the shape (which FCL would see at distance 0).
      if (!(brute.distance > s->tolerance) || expected.min_distance < 0.5 * brute.distance) continue;
      ++separated;
      for (const fcl::DistanceResultd* got : {&shape_first, &cfl_first}) {
        EXPECT_NEAR(got->min_distance, brute.distance, s->tolerance) << at;
        EXPECT_NEAR(got->min_distance, expected.min_distance, 1e-5 * s->diagonal) << at;
        expectShapeResult(*s, tf_m, shape.get(), *got, at);
      }
    }
    EXPECT_GT(separated, 10) << s->name;
  }
}

TEST(FclShapeDistance, MeshInsideABoxIsFclsZeroNotTheDistanceBetweenSurfaces) {
  const Scene& s = sheet();
  auto box = std::make_shared<fcl::Boxd>(2 * s.diagonal, 2 * s.diagonal, 2 * s.diagonal);
  const fcl::Transform3d tf = fcl::Transform3d::Identity();
  fcl::DistanceRequestd request(true);
  fcl::DistanceResultd expected, got;
  plainFcl().distance_geometries(box.get(), tf, s.obbrss.get(), tf, request, expected);
  fcl::distance(box.get(), tf, s.cfl.get(), tf, request, got);
  EXPECT_EQ(got.min_distance, expected.min_distance);
  EXPECT_LE(got.min_distance, 0.0);
}

TEST(FclShapeDistance, SignedSphereAndCapsuleOnAClosedMeshAreTheBruteForceSignedDistances) {
  const Scene& s = knot();
  ASSERT_TRUE(s.closed) << s.cfl->model().sign.closure.reason;
  std::mt19937_64 rng(4);
  int inside = 0;
  for (int i = 0; i < 30; ++i) {
    const fcl::Transform3d tf_m = meshPose(rng);
    const fcl::Transform3d tf_s = tf_m * shapePose(s, rng, 0.04, 0.04);
    const std::string at = "pose " + std::to_string(i);
    fcl::DistanceRequestd request(true, true);

    const double radius = 0.01 * s.diagonal;
    auto sphere = std::make_shared<fcl::Sphered>(radius);
    fcl::DistanceResultd got_sphere;
    fcl::distance(sphere.get(), tf_s, s.cfl.get(), tf_m, request, got_sphere);
    const double exact_sphere = signedPointDistance(s, tf_m, tf_s.translation()) - radius;
    EXPECT_NEAR(got_sphere.min_distance, exact_sphere, s.tolerance) << at;
    expectShapeResult(s, tf_m, sphere.get(), got_sphere, at + " sphere");
    inside += exact_sphere < 0;

    auto capsule = std::make_shared<fcl::Capsuled>(radius, 0.1 * s.diagonal);
    fcl::DistanceResultd got_capsule;
    fcl::distance(s.cfl.get(), tf_m, capsule.get(), tf_s, request, got_capsule);
    const fcl::Vector3d p0 = tf_s * fcl::Vector3d(0, 0, -0.5 * capsule->lz), p1 = tf_s * fcl::Vector3d(0, 0, 0.5 * capsule->lz);
    double slack = 0;
    const double exact_capsule = signedSegmentDistance(s, tf_m, p0, p1, 400, &slack) - radius;
    // The branch and bound certifies its depth to 1e-6 of the diagonal (segment_query.h); the samples
    // bound the true value within `slack`.
    const double certified = 1e-6 * s.diagonal + s.tolerance;
    EXPECT_LE(got_capsule.min_distance, exact_capsule + certified) << at;
    EXPECT_GE(got_capsule.min_distance, exact_capsule - slack - certified) << at;
    expectShapeResult(s, tf_m, capsule.get(), got_capsule, at + " capsule");
  }
  EXPECT_GT(inside, 5);
}

// Distance from p (world) to the surface of the box of half extents `half` at tf, and whether p is inside.
double boxSurfaceDistance(const fcl::Transform3d& tf, const Eigen::Vector3d& half, const fcl::Vector3d& p, bool* inside) {
  const Eigen::Vector3d q = tf.inverse() * p;
  const Eigen::Vector3d excess = q.cwiseAbs() - half;
  *inside = excess.maxCoeff() <= 0;
  return *inside ? -excess.maxCoeff() : excess.cwiseMax(0.0).norm();
}

TEST(FclShapeDistance, SignedBoxOnAClosedMeshIsMinusAnAttainedPenetrationDepth) {
  const Scene& s = knot();
  std::mt19937_64 rng(8);
  int overlapping = 0;
  for (int i = 0; i < 30; ++i) {
    const fcl::Transform3d tf_m = meshPose(rng);
    const fcl::Transform3d tf_s = tf_m * shapePose(s, rng, 0.03, 0.03);
    const Eigen::Vector3d half = Eigen::Vector3d(0.02, 0.015, 0.01) * s.diagonal;
    auto box = std::make_shared<fcl::Boxd>(2 * half);
    fcl::DistanceRequestd request(true, true);
    fcl::DistanceResultd got;
    fcl::distance(box.get(), tf_s, s.cfl.get(), tf_m, request, got);
    const std::string at = "pose " + std::to_string(i);
    expectShapeResult(s, tf_m, box.get(), got, at);
    // Apart: the exact distance (brute force); overlapping: negative, and the depth is attained by one of the
    // two nearest points: the box's point inside the mesh at that depth, or the mesh's point inside the box.
    const cfl::DistanceResult apart = cfl::bruteForceDistance(cfl::makeMeshModel(s.mesh), Eigen::Isometry3d(tf_m),
                                                              cfl::makeMeshModel(cfl::test::makeBox(-half, half)),
                                                              Eigen::Isometry3d(tf_s));
    const bool box_inside = signedPointDistance(s, tf_m, tf_s.translation()) < 0 && apart.distance > 0;
    if (apart.distance > s.tolerance && !box_inside) {
      EXPECT_NEAR(got.min_distance, apart.distance, s.tolerance) << at;
      continue;
    }
    ++overlapping;
    EXPECT_LT(got.min_distance, 0.0) << at;
    bool mesh_point_in_box = false;
    const double mesh_point_depth = boxSurfaceDistance(tf_s, half, got.nearest_points[0], &mesh_point_in_box);
    const bool box_point_attains = std::abs(signedPointDistance(s, tf_m, got.nearest_points[1]) - got.min_distance) <=
                                   1e-6 * s.diagonal;
    const bool mesh_point_attains = mesh_point_in_box && std::abs(mesh_point_depth + got.min_distance) <= 1e-6 * s.diagonal;
    EXPECT_TRUE(box_point_attains || mesh_point_attains) << at << " distance " << got.min_distance;
  }
  EXPECT_GT(overlapping, 5);
}

TEST(FclShapeDistance, SignedRequestOnAnOpenMeshOrSoupIsFclsAnswer) {
  std::mt19937_64 rng(5);
  for (const Scene* s : {&sheet(), &soup()}) {
    ASSERT_FALSE(s->closed);
    for (int i = 0; i < 20; ++i) {
      const fcl::Transform3d tf_m = meshPose(rng);
      const fcl::Transform3d tf_s = tf_m * shapePose(*s, rng, 0.02, 0.02);
      auto sphere = std::make_shared<fcl::Sphered>(0.01 * s->diagonal);
      fcl::DistanceRequestd request(true, true);
      fcl::DistanceResultd expected, got;
      plainFcl().distance_geometries(sphere.get(), tf_s, s->obbrss.get(), tf_m, request, expected);
      fcl::distance(sphere.get(), tf_s, s->cfl.get(), tf_m, request, got);
      EXPECT_NEAR(got.min_distance, expected.min_distance, s->tolerance) << s->name << " pose " << i;
    }
  }
}

TEST(FclShapeCollide, SphereCapsuleBoxAndConvexCollideAsFclSaysWithFclsContactRoles) {
  std::mt19937_64 rng(6);
  for (const Scene* s : scenes()) {
    int colliding = 0, deep = 0;
    for (int i = 0; i < 80; ++i) {
      const fcl::Transform3d tf_m = meshPose(rng);
      const fcl::Transform3d tf_s = tf_m * shapePose(*s, rng, 0.02, 0.03);
      const double radius = 0.01 * s->diagonal;
      std::shared_ptr<fcl::CollisionGeometryd> shape;
      if (i % 4 == 0)
        shape = std::make_shared<fcl::Sphered>(radius);
      else if (i % 4 == 1)
        shape = std::make_shared<fcl::Capsuled>(radius, 0.1 * s->diagonal);
      else if (i % 4 == 2)
        shape = std::make_shared<fcl::Boxd>(2 * radius, 3 * radius, 1.5 * radius);
      else
        shape = octahedron(2 * radius);
      const std::string at = s->name + " pose " + std::to_string(i);
      fcl::CollisionRequestd request(5, true);
      fcl::CollisionResultd expected, got, got_swapped;
      plainFcl().collide_geometries(shape.get(), tf_s, s->obbrss.get(), tf_m, request, expected);
      fcl::collide(shape.get(), tf_s, s->cfl.get(), tf_m, request, got);
      fcl::collide(s->cfl.get(), tf_m, shape.get(), tf_s, request, got_swapped);
      // A closed mesh is a solid: a shape wholly inside collides, where FCL, seeing triangles only, says no.
      const bool contained = s->closed && !expected.isCollision() && got.isCollision();
      if (contained) {
        ASSERT_EQ(got.numContacts(), 1u) << at;
        EXPECT_GT(got.getContact(0).penetration_depth, 0.0) << at;
      } else {
        EXPECT_EQ(got.isCollision(), expected.isCollision()) << at;
        EXPECT_EQ(got.numContacts(), expected.numContacts()) << at;
      }
      EXPECT_EQ(got_swapped.numContacts(), got.numContacts()) << at;
      colliding += got.isCollision();
      for (std::size_t k = 0; k < got.numContacts(); ++k) {
        const fcl::Contactd& c = got.getContact(k);
        EXPECT_EQ(c.o1, s->cfl.get()) << at;
        EXPECT_EQ(c.o2, shape.get()) << at;
        EXPECT_EQ(c.b2, -1) << at;  // Contact::NONE
        ASSERT_GE(c.b1, 0) << at;
        EXPECT_NEAR(c.normal.norm(), 1.0, 1e-9) << at;
        EXPECT_GT(c.penetration_depth, -s->tolerance) << at;
        if (!contained) EXPECT_LE(pointTriangleDistance(*s, c.b1, tf_m, c.pos), s->tolerance) << at;
        // On the closed knot every contact carries a depth (a box's or convex's: the pair's penetration).
        deep += s->closed && c.penetration_depth > 0;
      }
    }
    EXPECT_GT(colliding, 5) << s->name;
    if (s->closed) EXPECT_GT(deep, 5) << s->name;
  }
}

TEST(FclShapeBroadphase, SpheresInAManagerGiveTheLeastSphereDistance) {
  const Scene& s = knot();
  std::mt19937_64 rng(7);
  fcl::DynamicAABBTreeCollisionManagerd manager;
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> spheres;
  double least = INFINITY;
  while (spheres.size() < 30) {
    const double radius = 0.01 * s.diagonal;
    const fcl::Transform3d tf = shapePose(s, rng, -0.02, 0.1);
    // Separated spheres only: where one overlaps the mesh, an unsigned request gets FCL's own answer,
    // which 0.7 leaves undefined (sphereTriangleDistance does not set it).
    if (cfl::test::referencePointMeshDistance(s.mesh, tf.translation()) <= radius) continue;
    spheres.push_back(std::make_unique<fcl::CollisionObjectd>(std::make_shared<fcl::Sphered>(radius), tf));
    least = std::min(least, cfl::test::referencePointMeshDistance(s.mesh, tf.translation()) - radius);
  }
  for (auto& o : spheres) manager.registerObject(o.get());
  manager.setup();
  fcl::CollisionObjectd mesh(s.cfl, fcl::Transform3d::Identity());
  fcl::DefaultDistanceData<double> data;
  data.request.enable_nearest_points = true;
  manager.distance(&mesh, &data, fcl::DefaultDistanceFunction);
  EXPECT_NEAR(data.result.min_distance, least, s.tolerance);
}

}  // namespace
}  // namespace cfl_fcl
