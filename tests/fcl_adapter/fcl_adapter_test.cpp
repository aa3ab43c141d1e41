// The FCL adapter, used only through fcl::distance / fcl::collide and FCL's broadphase managers, against
// libfcl's own results (called through dlsym, see plain_fcl.h) on FCL's BVHModel<OBBRSS> of the same
// triangles, on randomized poses from overlapping to far apart, on the bunny and a torus knot.

#include "cfl_fcl/cfl_geometry.h"
#include "cfl/cfl_file.h"
#include "plain_fcl.h"
#include "support/test_meshes.h"

#include <fcl/fcl.h>

#include <gtest/gtest.h>

#include <cmath>
#include <cstdio>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace cfl_fcl {
namespace {

using test::plainFcl;

// One test mesh in every form the tests need.
struct Mesh {
  std::string name;
  cfl::TriangleMesh mesh;
  std::vector<fcl::Vector3d> vertices;
  std::vector<fcl::Triangle> triangles;
  std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> obbrss;  // The reference.
  std::shared_ptr<CFLGeometry> cfl;                     // From the triangle lists.
  std::shared_ptr<CFLGeometry> cfl_from_bvh;            // From the BVHModel<OBBRSS>.
  double diagonal = 0;
  double tolerance = 0;  // 1e-9 of the bounding box diagonal.
};

template <typename BV>
std::shared_ptr<fcl::BVHModel<BV>> makeBvh(const std::vector<fcl::Vector3d>& v, const std::vector<fcl::Triangle>& t) {
  auto model = std::make_shared<fcl::BVHModel<BV>>();
  model->beginModel();
  model->addSubModel(v, t);
  model->endModel();
  return model;
}

std::unique_ptr<Mesh> makeMesh(const std::string& name, cfl::TriangleMesh mesh, int resolution) {
  auto m = std::make_unique<Mesh>();
  m->name = name;
  m->mesh = mesh;
  m->vertices = mesh.vertices;
  for (const auto& t : mesh.triangles) m->triangles.emplace_back(t[0], t[1], t[2]);
  m->obbrss = makeBvh<fcl::OBBRSSd>(m->vertices, m->triangles);
  cfl::BuildOptions options;
  options.resolution = resolution;
  m->cfl = std::make_shared<CFLGeometry>(m->vertices, m->triangles, options);
  m->cfl_from_bvh = std::make_shared<CFLGeometry>(*m->obbrss, options);
  m->diagonal = cfl::boundingBox(mesh).diagonal();
  m->tolerance = 1e-9 * m->diagonal;
  return m;
}

const Mesh& bunny() {
  static const auto m = makeMesh("bunny", cfl::test::loadBunny(), 20);
  return *m;
}
const Mesh& knot() {
  static const auto m = makeMesh("knot", cfl::test::makeTorusKnot(2, 3, 0.5, 0.3, 48, 6), 16);
  return *m;
}

// A pose pair from overlapping (B's origin on A's) to about 1.3 diagonals apart, random rotations.
struct Poses {
  fcl::Transform3d a, b;
};
Poses randomPoses(std::mt19937_64& rng, double diagonal, double max_separation = 1.3) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  std::normal_distribution<double> normal;
  Poses p;
  p.a = fcl::Transform3d::Identity();
  p.a.linear() = cfl::test::randomRotation(rng);
  p.a.translation() = fcl::Vector3d(normal(rng), normal(rng), normal(rng));
  p.b = fcl::Transform3d::Identity();
  p.b.linear() = cfl::test::randomRotation(rng);
  const fcl::Vector3d direction = fcl::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
  p.b.translation() = p.a.translation() + direction * (diagonal * max_separation * uniform(rng));
  return p;
}

// Distance from world point p to triangle t of `mesh` placed at X.
double pointTriangleDistance(const Mesh& mesh, int t, const fcl::Transform3d& X, const fcl::Vector3d& p) {
  const auto& tri = mesh.mesh.triangles[t];
  const fcl::Vector3d q = X.inverse() * p;
  return std::sqrt(cfl::test::referencePointTriangleSquaredDistance(q, mesh.mesh.vertices[tri[0]],
                                                                     mesh.mesh.vertices[tri[1]],
                                                                     mesh.mesh.vertices[tri[2]]));
}

// Everything a distance result through the adapter must satisfy for the mesh pair (m1 at tf1 as g1, m2 at
// tf2 as g2), whose exact distance is `expected`.
void expectDistanceResult(const fcl::DistanceResultd& got, double expected, const Mesh& m1,
                          const fcl::Transform3d& tf1, const fcl::CollisionGeometryd* g1, const Mesh& m2,
                          const fcl::Transform3d& tf2, const fcl::CollisionGeometryd* g2, double tol,
                          const std::string& at) {
  EXPECT_NEAR(got.min_distance, expected, tol) << at;
  EXPECT_EQ(got.o1, g1) << at;
  EXPECT_EQ(got.o2, g2) << at;
  ASSERT_GE(got.b1, 0) << at;
  ASSERT_LT(got.b1, (intptr_t)m1.mesh.triangles.size()) << at;
  ASSERT_GE(got.b2, 0) << at;
  ASSERT_LT(got.b2, (intptr_t)m2.mesh.triangles.size()) << at;
  EXPECT_LE(pointTriangleDistance(m1, int(got.b1), tf1, got.nearest_points[0]), tol) << at << " point 0 on b1";
  EXPECT_LE(pointTriangleDistance(m2, int(got.b2), tf2, got.nearest_points[1]), tol) << at << " point 1 on b2";
  EXPECT_NEAR((got.nearest_points[0] - got.nearest_points[1]).norm(), got.min_distance, tol) << at;
}

double referenceDistance(const Mesh& m1, const fcl::Transform3d& tf1, const Mesh& m2, const fcl::Transform3d& tf2) {
  fcl::DistanceRequestd request;
  fcl::DistanceResultd result;
  plainFcl().distance_geometries(m1.obbrss.get(), tf1, m2.obbrss.get(), tf2, request, result);
  return result.min_distance;
}

bool referenceCollide(const Mesh& m1, const fcl::Transform3d& tf1, const Mesh& m2, const fcl::Transform3d& tf2) {
  fcl::CollisionRequestd request;
  fcl::CollisionResultd result;
  plainFcl().collide_geometries(m1.obbrss.get(), tf1, m2.obbrss.get(), tf2, request, result);
  return result.isCollision();
}

// CFL-CFL, both overloads, both orders; B is the CFL geometry built from the BVHModel, so its ids must be
// the BVHModel's.
void checkCflCfl(const Mesh& m, int poses, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  const fcl::DistanceRequestd request(true);
  for (int i = 0; i < poses; ++i) {
    const Poses p = randomPoses(rng, m.diagonal);
    const double expected = referenceDistance(m, p.a, m, p.b);
    const std::string at = m.name + " pose " + std::to_string(i);
    fcl::CollisionObjectd a(m.cfl, p.a), b(m.cfl_from_bvh, p.b);
    fcl::DistanceResultd by_objects, swapped, by_geometries;
    fcl::distance(&a, &b, request, by_objects);
    expectDistanceResult(by_objects, expected, m, p.a, m.cfl.get(), m, p.b, m.cfl_from_bvh.get(), m.tolerance, at);
    fcl::distance(&b, &a, request, swapped);
    expectDistanceResult(swapped, expected, m, p.b, m.cfl_from_bvh.get(), m, p.a, m.cfl.get(), m.tolerance,
                         at + " swapped");
    fcl::distance(m.cfl.get(), p.a, m.cfl_from_bvh.get(), p.b, request, by_geometries);
    expectDistanceResult(by_geometries, expected, m, p.a, m.cfl.get(), m, p.b, m.cfl_from_bvh.get(), m.tolerance,
                         at + " geometries");

    fcl::CollisionRequestd creq;
    fcl::CollisionResultd cobjects, cgeometries;
    const bool collides = referenceCollide(m, p.a, m, p.b);
    fcl::collide(&a, &b, creq, cobjects);
    fcl::collide(m.cfl_from_bvh.get(), p.b, m.cfl.get(), p.a, creq, cgeometries);
    EXPECT_EQ(cobjects.isCollision(), collides) << at;
    EXPECT_EQ(cgeometries.isCollision(), collides) << at;
    EXPECT_EQ(collides, expected <= m.tolerance) << at << " (reference collide and distance disagree)";
  }
}

TEST(FclAdapterDistance, CflAgainstCflEqualsObbrssOnTheBunnyInBothOrdersAndOverloads) { checkCflCfl(bunny(), 120, 1); }

TEST(FclAdapterDistance, CflAgainstCflEqualsObbrssOnATorusKnotInBothOrdersAndOverloads) { checkCflCfl(knot(), 80, 2); }

// CFL against fcl::BVHModel<BV>, for every BV type FCL ships.
template <typename BV>
class CflAgainstBvhModel : public ::testing::Test {};
using BvTypes = ::testing::Types<fcl::AABBd, fcl::OBBd, fcl::RSSd, fcl::OBBRSSd, fcl::kIOSd, fcl::KDOPd<16>,
                                 fcl::KDOPd<18>, fcl::KDOPd<24>>;
TYPED_TEST_SUITE(CflAgainstBvhModel, BvTypes);

TYPED_TEST(CflAgainstBvhModel, DistanceEqualsObbrssAndCollisionAgreesInBothOrdersAndOverloads) {
  for (const Mesh* m : {&bunny(), &knot()}) {
    std::mt19937_64 rng(3);
    auto bvh = makeBvh<TypeParam>(m->vertices, m->triangles);
    const fcl::DistanceRequestd request(true);
    for (int i = 0; i < 10; ++i) {
      const Poses p = randomPoses(rng, m->diagonal);
      const double expected = referenceDistance(*m, p.a, *m, p.b);
      const bool collides = referenceCollide(*m, p.a, *m, p.b);
      const std::string at = m->name + " pose " + std::to_string(i);
      fcl::CollisionObjectd c(m->cfl, p.a), b(bvh, p.b);
      fcl::DistanceResultd cfl_first, bvh_first, by_geometries;
      fcl::distance(&c, &b, request, cfl_first);
      expectDistanceResult(cfl_first, expected, *m, p.a, m->cfl.get(), *m, p.b, bvh.get(), m->tolerance, at);
      fcl::distance(&b, &c, request, bvh_first);
      expectDistanceResult(bvh_first, expected, *m, p.b, bvh.get(), *m, p.a, m->cfl.get(), m->tolerance,
                           at + " swapped");
      fcl::distance(bvh.get(), p.b, m->cfl.get(), p.a, request, by_geometries);
      expectDistanceResult(by_geometries, expected, *m, p.b, bvh.get(), *m, p.a, m->cfl.get(), m->tolerance,
                           at + " geometries");

      fcl::CollisionRequestd creq(5, true);
      fcl::CollisionResultd r1, r2;
      fcl::collide(&c, &b, creq, r1);
      fcl::collide(bvh.get(), p.b, m->cfl.get(), p.a, creq, r2);
      EXPECT_EQ(r1.isCollision(), collides) << at;
      EXPECT_EQ(r2.isCollision(), collides) << at;
      for (std::size_t k = 0; k < r2.numContacts(); ++k) {
        const auto& contact = r2.getContact(k);
        EXPECT_EQ(contact.o1, bvh.get());
        EXPECT_EQ(contact.o2, m->cfl.get());
        EXPECT_LE(pointTriangleDistance(*m, int(contact.b1), p.b, contact.pos), m->tolerance) << at;
        EXPECT_LE(pointTriangleDistance(*m, int(contact.b2), p.a, contact.pos), m->tolerance) << at;
      }
    }
  }
}

TEST(FclAdapterCollide, ContactsLieOnBothTrianglesAndRespectTheContactBudget) {
  const Mesh& m = knot();
  std::mt19937_64 rng(4);
  int colliding = 0;
  for (int i = 0; i < 40; ++i) {
    const Poses p = randomPoses(rng, m.diagonal, 0.5);
    fcl::CollisionObjectd a(m.cfl, p.a), b(m.cfl_from_bvh, p.b);
    for (std::size_t budget : {std::size_t(1), std::size_t(7), std::size_t(100000)}) {
      fcl::CollisionRequestd request(budget, true);
      fcl::CollisionResultd result, reference;
      fcl::collide(&a, &b, request, result);
      plainFcl().collide_geometries(m.obbrss.get(), p.a, m.obbrss.get(), p.b, request, reference);
      const std::string at = "pose " + std::to_string(i) + " budget " + std::to_string(budget);
      EXPECT_EQ(result.isCollision(), reference.isCollision()) << at;
      EXPECT_LE(result.numContacts(), budget) << at;
      if (budget == 100000) {
        // Every intersecting pair: as many as FCL finds, up to touching pairs decided differently by rounding.
        EXPECT_NEAR(double(result.numContacts()), double(reference.numContacts()),
                    0.02 * reference.numContacts() + 2) << at;
        colliding += result.isCollision();
      }
      for (std::size_t k = 0; k < result.numContacts(); ++k) {
        const auto& contact = result.getContact(k);
        EXPECT_EQ(contact.o1, m.cfl.get());
        EXPECT_EQ(contact.o2, m.cfl_from_bvh.get());
        EXPECT_LE(pointTriangleDistance(m, int(contact.b1), p.a, contact.pos), m.tolerance) << at;
        EXPECT_LE(pointTriangleDistance(m, int(contact.b2), p.b, contact.pos), m.tolerance) << at;
        EXPECT_NEAR(contact.normal.norm(), 1.0, 1e-12) << at;
      }
    }
  }
  EXPECT_GT(colliding, 5) << "the poses should exercise colliding configurations";
}

// Primitive shapes: FCL's own shape-mesh algorithm on the CFL geometry's OBBRSS twin, so the results must be
// FCL's (the bar is FCL's GJK tolerance), with the CFL geometry reported in place of the twin.
std::vector<std::shared_ptr<fcl::CollisionGeometryd>> shapes(double size) {
  auto vertices = std::make_shared<std::vector<fcl::Vector3d>>(std::vector<fcl::Vector3d>{
      {size, 0, 0}, {-size, 0, 0}, {0, size, 0}, {0, -size, 0}, {0, 0, size}, {0, 0, -size}});
  // An octahedron: 8 faces of 3 vertices, FCL's (count, ids...) face list.
  auto faces = std::make_shared<std::vector<int>>(std::vector<int>{
      3, 0, 2, 4, 3, 2, 1, 4, 3, 1, 3, 4, 3, 3, 0, 4, 3, 2, 0, 5, 3, 1, 2, 5, 3, 3, 1, 5, 3, 0, 3, 5});
  return {std::make_shared<fcl::Sphered>(size),
          std::make_shared<fcl::Boxd>(size, 1.5 * size, 0.7 * size),
          std::make_shared<fcl::Capsuled>(0.5 * size, 2 * size),
          std::make_shared<fcl::Cylinderd>(0.6 * size, 1.5 * size),
          std::make_shared<fcl::Coned>(0.8 * size, 1.5 * size),
          std::make_shared<fcl::Ellipsoidd>(size, 0.6 * size, 0.4 * size),
          std::make_shared<fcl::Convexd>(vertices, 8, faces),
          std::make_shared<fcl::Planed>(fcl::Vector3d(0.3, 0.5, 0.8).normalized(), 0.0),
          std::make_shared<fcl::Halfspaced>(fcl::Vector3d(-0.6, 0.2, 0.7).normalized(), 0.0)};
}

// A plane or halfspace against the mesh: the signed distance is linear, so its extremes are at vertices.
void checkPlaneDistance(const Mesh& m, const fcl::Transform3d& tf_m, const fcl::CollisionGeometryd& shape,
                        const fcl::Transform3d& tf_s, const fcl::DistanceResultd& got, const std::string& at) {
  const bool halfspace = shape.getNodeType() == fcl::GEOM_HALFSPACE;
  const fcl::Vector3d n_S = halfspace ? static_cast<const fcl::Halfspaced&>(shape).n
                                      : static_cast<const fcl::Planed&>(shape).n;
  const double d_S = halfspace ? static_cast<const fcl::Halfspaced&>(shape).d : static_cast<const fcl::Planed&>(shape).d;
  const fcl::Vector3d n = tf_s.linear() * n_S;
  const double d = d_S + n.dot(tf_s.translation());
  double lo = INFINITY, hi = -INFINITY;
  for (const fcl::Vector3d& v : m.vertices) {
    const double signed_distance = n.dot(tf_m * v) - d;
    lo = std::min(lo, signed_distance);
    hi = std::max(hi, signed_distance);
  }
  const double expected = halfspace ? std::max(lo, 0.0) : (lo <= 0 && hi >= 0 ? 0.0 : std::min(std::abs(lo), std::abs(hi)));
  EXPECT_NEAR(got.min_distance, expected, m.tolerance) << at;
  EXPECT_EQ(got.o1, m.cfl.get()) << at;
  EXPECT_EQ(got.o2, &shape) << at;
  ASSERT_GE(got.b1, 0) << at;
  EXPECT_LE(pointTriangleDistance(m, int(got.b1), tf_m, got.nearest_points[0]), m.tolerance) << at;
  const double s1 = n.dot(got.nearest_points[1]) - d;
  EXPECT_TRUE(halfspace ? s1 <= m.tolerance : std::abs(s1) <= m.tolerance) << at;
  EXPECT_NEAR((got.nearest_points[0] - got.nearest_points[1]).norm(), got.min_distance, m.tolerance) << at;
}

TEST(FclAdapterShapes, EveryPrimitiveShapeAgainstCflEqualsTheShapeAgainstObbrssInBothOrders) {
  const Mesh& m = bunny();
  std::mt19937_64 rng(5);
  std::normal_distribution<double> normal;
  const fcl::Vector3d center = cfl::boundingBox(m.mesh).center();
  for (const auto& shape : shapes(0.08 * m.diagonal)) {
    for (const auto solver : {fcl::GST_LIBCCD, fcl::GST_INDEP}) {
      for (int i = 0; i < 6; ++i) {
        fcl::Transform3d tf_s = fcl::Transform3d::Identity();
        tf_s.linear() = cfl::test::randomRotation(rng);
        tf_s.translation() = center + fcl::Vector3d(normal(rng), normal(rng), normal(rng)) * (0.4 * m.diagonal);
        fcl::Transform3d tf_m = fcl::Transform3d::Identity();
        tf_m.linear() = cfl::test::randomRotation(rng);
        const std::string at = "shape node type " + std::to_string(shape->getNodeType()) + " solver " +
                               std::to_string(solver) + " pose " + std::to_string(i);
        fcl::DistanceRequestd request(true);
        request.gjk_solver_type = solver;
        fcl::CollisionObjectd s(shape, tf_s), c(m.cfl, tf_m), o(m.obbrss, tf_m);
        fcl::DistanceResultd expected, shape_first, cfl_first;
        fcl::distance(&s, &c, request, shape_first);
        fcl::distance(m.cfl.get(), tf_m, shape.get(), tf_s, request, cfl_first);
        const bool plane = shape->getNodeType() == fcl::GEOM_PLANE || shape->getNodeType() == fcl::GEOM_HALFSPACE;
        if (plane) {
          // FCL 0.7 crashes on these (no GJK support function), so the reference is the corners themselves.
          checkPlaneDistance(m, tf_m, *shape, tf_s, shape_first, at);
          checkPlaneDistance(m, tf_m, *shape, tf_s, cfl_first, at + " cfl first");
        } else {
          plainFcl().distance_objects(&s, &o, request, expected);
        }
        // Spheres, capsules, boxes and convexes are answered from the CFL model where they do not touch the
        // mesh (fcl_shape_test.cpp checks them in depth): same distance and roles, their own triangle and points.
        const int type = shape->getNodeType();
        const bool from_regions = type == fcl::GEOM_SPHERE || type == fcl::GEOM_CAPSULE || type == fcl::GEOM_BOX ||
                                  type == fcl::GEOM_CONVEX;
        for (const fcl::DistanceResultd* got : {&shape_first, &cfl_first}) {
          if (plane) break;
          EXPECT_NEAR(got->min_distance, expected.min_distance, request.distance_tolerance) << at;
          if (from_regions) {
            EXPECT_EQ(got->o1, m.cfl.get()) << at;
            EXPECT_EQ(got->b2, -1) << at;  // DistanceResult::NONE
            continue;
          }
          EXPECT_EQ(got->b1, expected.b1) << at;
          EXPECT_EQ(got->b2, expected.b2) << at;
          // FCL reports the mesh as o1 in both orders; the CFL geometry must stand where the mesh stood.
          EXPECT_EQ(got->o1, expected.o1 == m.obbrss.get() ? m.cfl.get() : expected.o1) << at;
          EXPECT_EQ(got->o2, expected.o2 == m.obbrss.get() ? m.cfl.get() : expected.o2) << at;
          EXPECT_TRUE(got->nearest_points[0].isApprox(expected.nearest_points[0], 1e-9) ||
                      (got->nearest_points[0] - expected.nearest_points[0]).norm() <= request.distance_tolerance)
              << at;
        }

        fcl::CollisionRequestd creq(10, true);
        creq.gjk_solver_type = solver;
        fcl::CollisionResultd cexpected, cgot, cgot_geometries;
        plainFcl().collide_objects(&s, &o, creq, cexpected);
        fcl::collide(&s, &c, creq, cgot);
        fcl::collide(m.cfl.get(), tf_m, shape.get(), tf_s, creq, cgot_geometries);
        EXPECT_EQ(cgot.isCollision(), cexpected.isCollision()) << at;
        EXPECT_EQ(cgot_geometries.isCollision(), cexpected.isCollision()) << at;
        if (from_regions) continue;
        EXPECT_EQ(cgot.numContacts(), cexpected.numContacts()) << at;
        const fcl::CollisionGeometryd* twin = &m.cfl->shapeProxy();
        for (std::size_t k = 0; k < cgot.numContacts(); ++k) {
          EXPECT_NE(cgot.getContact(k).o1, twin) << at;
          EXPECT_NE(cgot.getContact(k).o2, twin) << at;
          EXPECT_EQ(cgot.getContact(k).pos, cexpected.getContact(k).pos) << at;
        }
      }
    }
  }
}

TEST(FclAdapterPassThrough, PairsWithoutCflGiveBitIdenticalPlainFclResults) {
  const Mesh& m = knot();
  std::mt19937_64 rng(6);
  auto sphere = std::make_shared<fcl::Sphered>(0.1 * m.diagonal);
  auto rss = makeBvh<fcl::RSSd>(m.vertices, m.triangles);
  for (int i = 0; i < 20; ++i) {
    const Poses p = randomPoses(rng, m.diagonal);
    const std::vector<std::pair<std::shared_ptr<fcl::CollisionGeometryd>, std::shared_ptr<fcl::CollisionGeometryd>>>
        pairs = {{m.obbrss, m.obbrss}, {rss, rss}, {sphere, m.obbrss}, {m.obbrss, sphere}, {sphere, sphere}};
    for (const auto& [g1, g2] : pairs) {
      fcl::CollisionObjectd a(g1, p.a), b(g2, p.b);
      fcl::DistanceRequestd request(true);
      fcl::DistanceResultd got, expected;
      const double d_got = fcl::distance(&a, &b, request, got);
      const double d_expected = plainFcl().distance_objects(&a, &b, request, expected);
      EXPECT_EQ(d_got, d_expected);
      EXPECT_EQ(got.min_distance, expected.min_distance);
      EXPECT_EQ(got.b1, expected.b1);
      EXPECT_EQ(got.b2, expected.b2);
      EXPECT_EQ(got.nearest_points[0], expected.nearest_points[0]);
      EXPECT_EQ(got.nearest_points[1], expected.nearest_points[1]);
      fcl::CollisionRequestd creq(50, true);
      fcl::CollisionResultd cgot, cexpected;
      EXPECT_EQ(fcl::collide(g1.get(), p.a, g2.get(), p.b, creq, cgot),
                plainFcl().collide_geometries(g1.get(), p.a, g2.get(), p.b, creq, cexpected));
      ASSERT_EQ(cgot.numContacts(), cexpected.numContacts());
      for (std::size_t k = 0; k < cgot.numContacts(); ++k) EXPECT_EQ(cgot.getContact(k).pos, cexpected.getContact(k).pos);
    }
  }
}

TEST(FclAdapterRequest, RelAndAbsErrBoundTheReportedDistanceWhichStaysThatOfItsTrianglePair) {
  const Mesh& m = bunny();
  std::mt19937_64 rng(7);
  for (int i = 0; i < 30; ++i) {
    const Poses p = randomPoses(rng, m.diagonal);
    const double exact = referenceDistance(m, p.a, m, p.b);
    fcl::DistanceRequestd request(true, false, 0.25, 0.02 * m.diagonal);
    fcl::DistanceResultd got;
    fcl::CollisionObjectd a(m.cfl, p.a), b(m.obbrss, p.b);
    fcl::distance(&a, &b, request, got);
    const std::string at = "pose " + std::to_string(i);
    EXPECT_GE(got.min_distance, exact - m.tolerance) << at;
    EXPECT_LE(got.min_distance, exact + request.abs_err + m.tolerance) << at;
    EXPECT_LE(got.min_distance, exact * (1 + request.rel_err) + m.tolerance) << at;
    expectDistanceResult(got, got.min_distance, m, p.a, m.cfl.get(), m, p.b, m.obbrss.get(), m.tolerance, at);
  }
}

// Closed meshes get a negative distance on overlap (fcl_signed_test.cpp); a mesh that cannot be signed, such as
// an open bowl, answers as FCL answers for meshes.
TEST(FclAdapterRequest, SignedDistanceRequestOnAnOpenMeshGivesZeroOnOverlapLikeFclMeshes) {
  static const auto bowl = makeMesh("bowl", cfl::test::makeHemisphere(1.0, 12, 32), 0);
  const Mesh& m = *bowl;
  ASSERT_FALSE(m.cfl->model().sign.closure.closed);
  std::mt19937_64 rng(8);
  int overlapping = 0;
  for (int i = 0; i < 30; ++i) {
    const Poses p = randomPoses(rng, m.diagonal, 0.3);
    fcl::DistanceRequestd request(true, true);
    fcl::DistanceResultd got, expected;
    fcl::CollisionObjectd a(m.cfl, p.a), b(m.cfl_from_bvh, p.b), ra(m.obbrss, p.a), rb(m.obbrss, p.b);
    fcl::distance(&a, &b, request, got);
    plainFcl().distance_objects(&ra, &rb, request, expected);
    EXPECT_GE(got.min_distance, 0.0);
    EXPECT_NEAR(got.min_distance, expected.min_distance, m.tolerance);
    overlapping += got.min_distance == 0;
  }
  EXPECT_GT(overlapping, 5) << "the poses should exercise overlapping configurations";
}

TEST(FclAdapterRequest, SatisfiedRequestReturnsAtOnceLeavingTheResultUntouched) {
  const Mesh& m = knot();
  fcl::CollisionObjectd a(m.cfl), b(m.cfl_from_bvh);  // Identical poses: overlapping.
  fcl::DistanceRequestd request(true);
  fcl::DistanceResultd result;
  result.min_distance = 0;  // Already satisfied, as a broadphase pass that met an overlap leaves it.
  EXPECT_EQ(fcl::distance(&a, &b, request, result), 0.0);
  EXPECT_EQ(result.o1, nullptr);
  EXPECT_EQ(result.b1, intptr_t(fcl::DistanceResultd::NONE));

  fcl::CollisionRequestd creq(1);
  fcl::CollisionResultd cresult;
  fcl::collide(&a, &b, creq, cresult);
  ASSERT_EQ(cresult.numContacts(), 1u);
  fcl::collide(&a, &b, creq, cresult);  // Satisfied: no second contact.
  EXPECT_EQ(cresult.numContacts(), 1u);
}

// Broadphase managers with FCL's default callbacks, a mix of CFL, BVHModel and shape objects, against the
// minimum over all pairs of the plain FCL answers with every CFL geometry replaced by its OBBRSS twin.
template <typename Manager>
void checkManager(const std::string& name) {
  const Mesh& m = bunny();
  const Mesh& k = knot();
  std::mt19937_64 rng(9);
  std::uniform_real_distribution<double> uniform(-1.0, 1.0);
  auto sphere = std::make_shared<fcl::Sphered>(0.1 * m.diagonal);
  struct Item {
    std::shared_ptr<fcl::CollisionGeometryd> geometry, twin;
  };
  const std::vector<Item> items = {{m.cfl, m.obbrss}, {m.obbrss, m.obbrss}, {k.cfl, k.obbrss},
                                   {sphere, sphere},   {m.cfl_from_bvh, m.obbrss}, {k.obbrss, k.obbrss}};
  int colliding_trials = 0;
  for (int trial = 0; trial < 8; ++trial) {
    std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects, twins;
    Manager manager;
    const double spread = (trial % 2 ? 3.0 : 0.6) * m.diagonal;  // Apart, then crowded.
    for (const Item& item : items) {
      fcl::Transform3d tf = fcl::Transform3d::Identity();
      tf.linear() = cfl::test::randomRotation(rng);
      tf.translation() = fcl::Vector3d(uniform(rng), uniform(rng), uniform(rng)) * spread;
      objects.push_back(std::make_unique<fcl::CollisionObjectd>(item.geometry, tf));
      twins.push_back(std::make_unique<fcl::CollisionObjectd>(item.twin, tf));
      manager.registerObject(objects.back().get());
    }
    manager.setup();
    double expected = INFINITY;
    bool expected_collision = false;
    for (std::size_t i = 0; i < twins.size(); ++i)
      for (std::size_t j = i + 1; j < twins.size(); ++j) {
        fcl::DistanceRequestd request;
        fcl::DistanceResultd r;
        plainFcl().distance_objects(twins[i].get(), twins[j].get(), request, r);
        expected = std::min(expected, r.min_distance);
        fcl::CollisionRequestd creq;
        fcl::CollisionResultd cr;
        plainFcl().collide_objects(twins[i].get(), twins[j].get(), creq, cr);
        expected_collision = expected_collision || cr.isCollision();
      }
    fcl::DefaultDistanceData<double> distance_data;
    manager.distance(&distance_data, fcl::DefaultDistanceFunction);
    EXPECT_NEAR(distance_data.result.min_distance, std::max(expected, 0.0), 1e-6 * m.diagonal)
        << name << " trial " << trial;
    fcl::DefaultCollisionData<double> collision_data;
    manager.collide(&collision_data, fcl::DefaultCollisionFunction);
    Manager twin_manager;
    for (auto& twin : twins) twin_manager.registerObject(twin.get());
    twin_manager.setup();
    fcl::DefaultCollisionData<double> twin_collision_data;
    twin_manager.collide(&twin_collision_data, fcl::DefaultCollisionFunction);
    EXPECT_EQ(collision_data.result.isCollision(), twin_collision_data.result.isCollision()) << name << " trial " << trial;
    EXPECT_EQ(collision_data.result.isCollision(), expected_collision) << name << " trial " << trial;
    colliding_trials += expected_collision;
  }
  EXPECT_GT(colliding_trials, 0) << "the crowded trials should make some objects collide";
}

TEST(FclAdapterBroadphase, DynamicAabbTreeManagerMatchesThePairwiseMinimum) {
  checkManager<fcl::DynamicAABBTreeCollisionManagerd>("DynamicAABBTree");
}

// Not SaPCollisionManager: with plain FCL geometries alone it misses colliding pairs these poses produce.
TEST(FclAdapterBroadphase, IntervalTreeManagerMatchesThePairwiseMinimum) {
  checkManager<fcl::IntervalTreeCollisionManagerd>("IntervalTree");
}

TEST(FclAdapterGeometry, LocalAabbAndRadiusEncloseEveryVertex) {
  for (const Mesh* m : {&bunny(), &knot()}) {
    const CFLGeometry& g = *m->cfl;
    for (const fcl::Vector3d& v : m->vertices) {
      EXPECT_TRUE(g.aabb_local.contain(v)) << m->name;
      EXPECT_LE((v - g.aabb_center).norm(), g.aabb_radius * (1 + 1e-12)) << m->name;
    }
    EXPECT_NE(g.getObjectType(), fcl::OT_UNKNOWN);
  }
}

TEST(FclAdapterGeometry, GeometriesSharingOneModelGiveTheSameAnswers) {
  const Mesh& m = knot();
  auto shared = std::make_shared<CFLGeometry>(m.cfl->sharedModel());
  EXPECT_EQ(&shared->model(), &m.cfl->model());
  std::mt19937_64 rng(10);
  for (int i = 0; i < 10; ++i) {
    const Poses p = randomPoses(rng, m.diagonal);
    fcl::DistanceRequestd request(true);
    fcl::DistanceResultd r1, r2;
    fcl::distance(m.cfl.get(), p.a, m.obbrss.get(), p.b, request, r1);
    fcl::distance(shared.get(), p.a, m.obbrss.get(), p.b, request, r2);
    EXPECT_EQ(r1.min_distance, r2.min_distance);
    EXPECT_EQ(r2.o1, shared.get());
  }
}

TEST(FclAdapterGeometry, GeometryLoadedFromASavedModelAnswersLikeTheOriginal) {
  const Mesh& m = knot();
  const std::string path = ::testing::TempDir() + "fcl_adapter_knot.cfl";
  cfl::saveCflModel(m.cfl->model(), path);
  const std::shared_ptr<CFLGeometry> loaded = CFLGeometry::load(path);
  std::mt19937_64 rng(12);
  for (int i = 0; i < 10; ++i) {
    const Poses p = randomPoses(rng, m.diagonal);
    fcl::DistanceRequestd request(true);
    fcl::DistanceResultd original, reloaded;
    fcl::distance(m.cfl.get(), p.a, m.obbrss.get(), p.b, request, original);
    fcl::distance(loaded.get(), p.a, m.obbrss.get(), p.b, request, reloaded);
    EXPECT_EQ(original.min_distance, reloaded.min_distance);
    EXPECT_EQ(original.b1, reloaded.b1);
    EXPECT_EQ(reloaded.o1, loaded.get());
  }
  std::remove(path.c_str());
  try {
    CFLGeometry::load(path);
    FAIL() << "a missing file was accepted";
  } catch (const cfl::Error& e) {
    EXPECT_NE(std::string(e.what()).find(path), std::string::npos) << e.what();
  }
}

TEST(FclAdapterCache, CachedBvhModelCopyFollowsUpdateReplaceAndForget) {
  const Mesh& m = knot();
  auto bvh = makeBvh<fcl::OBBRSSd>(m.vertices, m.triangles);
  fcl::Transform3d tf_c = fcl::Transform3d::Identity();
  fcl::Transform3d tf_b = fcl::Transform3d::Identity();
  tf_b.translation() = fcl::Vector3d(0.9 * m.diagonal, 0, 0);
  const fcl::DistanceRequestd request(true);
  auto agrees = [&](const std::string& at) {
    fcl::DistanceResultd got, expected;
    fcl::CollisionObjectd c(m.cfl, tf_c), b(bvh, tf_b);
    fcl::distance(&c, &b, request, got);
    // The reference is a fresh BVHModel of the current vertices: FCL's own refit after beginReplaceModel
    // leaves OBBRSS bounds that make its distance wrong.
    auto fresh = makeBvh<fcl::OBBRSSd>(std::vector<fcl::Vector3d>(bvh->vertices, bvh->vertices + bvh->num_vertices),
                                       std::vector<fcl::Triangle>(bvh->tri_indices, bvh->tri_indices + bvh->num_tris));
    plainFcl().distance_geometries(m.obbrss.get(), tf_c, fresh.get(), tf_b, request, expected);
    EXPECT_NEAR(got.min_distance, expected.min_distance, m.tolerance) << at;
    return got.min_distance;
  };
  const double before = agrees("initial");
  std::vector<fcl::Vector3d> moved = m.vertices;
  for (auto& v : moved) v += fcl::Vector3d(-0.2 * m.diagonal, 0, 0);
  // In place: same arrays, same counts, same build state; the sampled vertices see the move.
  ASSERT_EQ(bvh->beginReplaceModel(), fcl::BVH_OK);
  bvh->replaceSubModel(moved);
  ASSERT_EQ(bvh->endReplaceModel(), fcl::BVH_OK);
  EXPECT_LT(agrees("after beginReplaceModel"), before - 0.1 * m.diagonal);
  // FCL swaps the vertex array with the previous frame's.
  ASSERT_EQ(bvh->beginUpdateModel(), fcl::BVH_OK);
  bvh->updateSubModel(m.vertices);
  ASSERT_EQ(bvh->endUpdateModel(), fcl::BVH_OK);
  EXPECT_NEAR(agrees("after beginUpdateModel"), before, m.tolerance);
  // Rebuilt from scratch (FCL's second beginModel clears the first): the arrays may be reallocated at the
  // same addresses with the same counts, which is what forgetBvhModel is for.
  bvh->beginModel();
  ASSERT_EQ(bvh->beginModel(), fcl::BVH_OK);
  bvh->addSubModel(moved, m.triangles);
  ASSERT_EQ(bvh->endModel(), fcl::BVH_OK);
  forgetBvhModel(*bvh);
  EXPECT_LT(agrees("after beginModel and forgetBvhModel"), before - 0.1 * m.diagonal);
}

TEST(FclAdapterErrors, BadInputThrowsCflErrorNamingTheCulprit) {
  std::vector<fcl::Vector3d> v = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}};
  std::vector<fcl::Triangle> t = {fcl::Triangle(0, 1, 2), fcl::Triangle(0, 1, 7)};
  try {
    CFLGeometry g(v, t);
    FAIL() << "out-of-range vertex index accepted";
  } catch (const cfl::Error& e) {
    EXPECT_NE(std::string(e.what()).find("triangle 1"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("7"), std::string::npos) << e.what();
  }
  fcl::BVHModel<fcl::OBBd> empty;
  EXPECT_THROW(CFLGeometry{empty}, cfl::Error);
  EXPECT_THROW(CFLGeometry{std::shared_ptr<const cfl::CflModel>()}, cfl::Error);

  // A BVHModel with a bad index met by a CFL geometry in a query.
  const Mesh& m = knot();
  auto bad = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  bad->beginModel();
  bad->addSubModel(v, std::vector<fcl::Triangle>{fcl::Triangle(0, 1, 2)});
  bad->endModel();
  bad->tri_indices[0] = fcl::Triangle(0, 1, 5);
  fcl::DistanceRequestd request;
  fcl::DistanceResultd result;
  EXPECT_THROW(fcl::distance(m.cfl.get(), fcl::Transform3d::Identity(), bad.get(), fcl::Transform3d::Identity(),
                             request, result),
               cfl::Error);
}

}  // namespace
}  // namespace cfl_fcl
