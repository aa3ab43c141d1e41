// The adapter under FCL's broadphase: every candidate pair gets the result holding the best distance so far,
// which the adapter passes to the core as cfl::DistanceOptions::upper_bound.
//  - Pair by pair: a result that already holds a closer pair comes back bit for bit unchanged (with the
//    return value FCL gives, the held distance); one holding a farther pair gets the exact answer. For every
//    kind of pair the adapter handles: CFL / CFL, CFL / BVHModel, CFL / primitive shape, CFL / halfspace.
//  - Whole scenes: randomized robot-and-world scenes of several meshes, DynamicAABBTreeCollisionManager
//    against DynamicAABBTreeCollisionManager with fcl::DefaultDistanceFunction, against the same scene with
//    every CFL geometry replaced by FCL's BVHModel<OBBRSS> of the same triangles, run by libfcl's own
//    fcl::distance (plain_fcl.h) in a callback that does what DefaultDistanceFunction does.

#include "cfl_fcl/cfl_geometry.h"
#include "plain_fcl.h"
#include "support/test_meshes.h"

#include <fcl/fcl.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <iostream>
#include <limits>
#include <memory>
#include <random>
#include <string>
#include <vector>

namespace cfl_fcl {
namespace {

using test::plainFcl;

// One mesh of the scenes, in both forms: the CFL geometry under test and FCL's BVHModel<OBBRSS> reference.
struct SceneMesh {
  std::string name;
  cfl::TriangleMesh mesh;
  std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> obbrss;
  std::shared_ptr<CFLGeometry> cfl;
  double diagonal = 0;
};

std::unique_ptr<SceneMesh> makeSceneMesh(const std::string& name, cfl::TriangleMesh mesh, double size,
                                         int resolution) {
  // Scale to a bounding-box diagonal of `size`, so that the scenes mix objects of different sizes.
  const double scale = size / cfl::boundingBox(mesh).diagonal();
  for (auto& v : mesh.vertices) v *= scale;
  auto m = std::make_unique<SceneMesh>();
  m->name = name;
  m->mesh = mesh;
  std::vector<fcl::Vector3d> vertices = mesh.vertices;
  std::vector<fcl::Triangle> triangles;
  for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  m->obbrss = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  m->obbrss->beginModel();
  m->obbrss->addSubModel(vertices, triangles);
  m->obbrss->endModel();
  cfl::BuildOptions options;
  options.resolution = resolution;
  m->cfl = std::make_shared<CFLGeometry>(vertices, triangles, options);
  m->diagonal = cfl::boundingBox(m->mesh).diagonal();
  return m;
}

// Closed and open, smooth and messy, of 3674 down to a few hundred triangles, at sizes 0.4 to 2.5.
const std::vector<std::unique_ptr<SceneMesh>>& sceneMeshes() {
  static const auto meshes = [] {
    std::vector<std::unique_ptr<SceneMesh>> m;
    m.push_back(makeSceneMesh("bunny", cfl::test::loadBunny(), 1.0, 20));
    m.push_back(makeSceneMesh("knot", cfl::test::makeTorusKnot(2, 3, 0.5, 0.3, 48, 6), 0.6, 16));
    m.push_back(makeSceneMesh("messy", cfl::test::makeMessyMesh(), 0.8, 16));
    m.push_back(makeSceneMesh("wavy sheet", cfl::test::makeWavySheet(), 2.5, 16));
    m.push_back(makeSceneMesh("hemisphere", cfl::test::makeHemisphere(), 0.4, 12));
    m.push_back(makeSceneMesh("self-intersecting", cfl::test::makeSelfIntersectingMesh(), 1.5, 16));
    return m;
  }();
  return meshes;
}

double largestDiagonal() {
  double d = 0;
  for (const auto& m : sceneMeshes()) d = std::max(d, m->diagonal);
  return d;
}

// Distance from world point p to triangle t of `m` placed at X.
double pointTriangleDistance(const SceneMesh& m, std::intptr_t t, const fcl::Transform3d& X, const fcl::Vector3d& p) {
  if (t < 0 || t >= std::intptr_t(m.mesh.triangles.size())) return INFINITY;
  const auto& tri = m.mesh.triangles[std::size_t(t)];
  return std::sqrt(cfl::test::referencePointTriangleSquaredDistance(X.inverse() * p, m.mesh.vertices[tri[0]],
                                                                     m.mesh.vertices[tri[1]], m.mesh.vertices[tri[2]]));
}

fcl::Transform3d randomTransform(std::mt19937_64& rng, const fcl::Vector3d& center, double spread) {
  std::normal_distribution<double> normal;
  fcl::Transform3d X = fcl::Transform3d::Identity();
  X.linear() = cfl::test::randomRotation(rng);
  X.translation() = center + spread * fcl::Vector3d(normal(rng), normal(rng), normal(rng));
  return X;
}

// A result as a broadphase leaves it after an earlier pair: a distance and that pair's fields, all of which
// must survive a pair that does not beat it.
fcl::DistanceResultd heldResult(double distance, const fcl::CollisionGeometryd* holder) {
  fcl::DistanceResultd r;
  r.update(distance, holder, holder, 17, 23, fcl::Vector3d(1, 2, 3), fcl::Vector3d(4, 5, 6));
  return r;
}

void expectUnchanged(const fcl::DistanceResultd& got, const fcl::DistanceResultd& held, const std::string& at) {
  EXPECT_EQ(got.min_distance, held.min_distance) << at;
  EXPECT_EQ(got.o1, held.o1) << at;
  EXPECT_EQ(got.o2, held.o2) << at;
  EXPECT_EQ(got.b1, held.b1) << at;
  EXPECT_EQ(got.b2, held.b2) << at;
  EXPECT_EQ(got.nearest_points[0], held.nearest_points[0]) << at;
  EXPECT_EQ(got.nearest_points[1], held.nearest_points[1]) << at;
}

// CFL against another CFL geometry and against a BVHModel, both orders and both overloads: with a held
// distance below the pair's, nothing changes and the held distance is returned; above it, the pair's exact
// answer replaces it.
TEST(FclAdapterUpperBound, MeshPairsBeatingTheHeldDistanceReplaceItAndOthersLeaveItBitForBit) {
  const auto& meshes = sceneMeshes();
  const double tolerance = 1e-9 * largestDiagonal();
  const auto holder = std::make_shared<fcl::Sphered>(1.0);  // Stands for the earlier pair's geometries.
  std::mt19937_64 rng(31);
  int replaced = 0, kept = 0;
  for (int trial = 0; trial < 60; ++trial) {
    const SceneMesh& m1 = *meshes[trial % meshes.size()];
    const SceneMesh& m2 = *meshes[(trial / meshes.size() + trial + 1) % meshes.size()];
    const fcl::Transform3d tf1 = randomTransform(rng, fcl::Vector3d::Zero(), 0.1);
    const fcl::Transform3d tf2 = randomTransform(rng, fcl::Vector3d::Zero(), 0.5 * (m1.diagonal + m2.diagonal));
    fcl::DistanceRequestd request(true);
    fcl::DistanceResultd reference;
    plainFcl().distance_geometries(m1.obbrss.get(), tf1, m2.obbrss.get(), tf2, request, reference);
    const double d = reference.min_distance;
    if (d <= 0) continue;  // Overlapping: nothing to hold below it.
    // o2 as a CFL geometry, then as the BVHModel (the path that copies the BVHModel's triangles).
    for (const fcl::CollisionGeometryd* g2 : {static_cast<const fcl::CollisionGeometryd*>(m2.cfl.get()),
                                              static_cast<const fcl::CollisionGeometryd*>(m2.obbrss.get())}) {
      const std::shared_ptr<fcl::CollisionGeometryd> g2_owner =
          g2 == m2.cfl.get() ? std::shared_ptr<fcl::CollisionGeometryd>(m2.cfl) : m2.obbrss;
      fcl::CollisionObjectd a(m1.cfl, tf1), b(g2_owner, tf2);
      for (bool swapped : {false, true}) {
        for (bool objects : {false, true}) {
          const std::string at = m1.name + " vs " + m2.name + (g2 == m2.cfl.get() ? " (CFL)" : " (BVHModel)") +
                                 (swapped ? " swapped" : "") + (objects ? " objects" : " geometries") + " trial " +
                                 std::to_string(trial);
          const auto run = [&](fcl::DistanceResultd& r) {
            if (objects) return swapped ? fcl::distance(&b, &a, request, r) : fcl::distance(&a, &b, request, r);
            return swapped ? fcl::distance(g2, tf2, m1.cfl.get(), tf1, request, r)
                           : fcl::distance(m1.cfl.get(), tf1, g2, tf2, request, r);
          };
          const fcl::DistanceResultd below = heldResult(0.5 * d, holder.get());
          fcl::DistanceResultd got = below;
          EXPECT_EQ(run(got), below.min_distance) << at;
          expectUnchanged(got, below, at + " (held below)");
          ++kept;

          fcl::DistanceResultd above = heldResult(d * 1.01 + tolerance, holder.get());
          const double returned = run(above);
          EXPECT_NEAR(above.min_distance, d, tolerance) << at << " (held above)";
          EXPECT_EQ(returned, above.min_distance) << at;
          const fcl::CollisionGeometryd* first = swapped ? g2 : m1.cfl.get();
          const fcl::CollisionGeometryd* second = swapped ? m1.cfl.get() : g2;
          EXPECT_EQ(above.o1, first) << at;
          EXPECT_EQ(above.o2, second) << at;
          const SceneMesh& mesh1 = swapped ? m2 : m1;
          const SceneMesh& mesh2 = swapped ? m1 : m2;
          EXPECT_LE(pointTriangleDistance(mesh1, above.b1, swapped ? tf2 : tf1, above.nearest_points[0]), tolerance)
              << at;
          EXPECT_LE(pointTriangleDistance(mesh2, above.b2, swapped ? tf1 : tf2, above.nearest_points[1]), tolerance)
              << at;
          ++replaced;
        }
      }
    }
  }
  EXPECT_GT(kept, 100);
  EXPECT_GT(replaced, 100);
}

// Separated spheres and boxes are answered from the CFL model under the held distance as upper bound; a
// halfspace by the adapter's corner formula. Both must keep a closer held result and replace a farther one
// with what a fresh result gets.
TEST(FclAdapterUpperBound, ShapeAndHalfspacePairsKeepACloserHeldResultAndReplaceAFartherOne) {
  const SceneMesh& m = *sceneMeshes()[0];
  const auto holder = std::make_shared<fcl::Sphered>(1.0);
  const std::vector<std::shared_ptr<fcl::CollisionGeometryd>> shapes = {
      std::make_shared<fcl::Sphered>(0.1), std::make_shared<fcl::Boxd>(0.2, 0.1, 0.3),
      std::make_shared<fcl::Halfspaced>(fcl::Vector3d(0.2, -0.5, 0.8).normalized(), -0.7)};
  std::mt19937_64 rng(32);
  int tested = 0;
  for (const auto& shape : shapes) {
    for (int i = 0; i < 10; ++i) {
      const fcl::Transform3d tf_m = randomTransform(rng, fcl::Vector3d::Zero(), 0.1);
      const fcl::Transform3d tf_s = randomTransform(rng, fcl::Vector3d::Zero(), 0.8);
      fcl::CollisionObjectd mesh(m.cfl, tf_m), s(shape, tf_s);
      fcl::DistanceRequestd request(true);
      fcl::DistanceResultd fresh;
      fcl::distance(&s, &mesh, request, fresh);
      if (fresh.min_distance <= 0) continue;
      const std::string at = "shape " + std::to_string(shape->getNodeType()) + " pose " + std::to_string(i);
      for (bool shape_first : {true, false}) {
        const fcl::DistanceResultd below = heldResult(0.5 * fresh.min_distance, holder.get());
        fcl::DistanceResultd got = below;
        const double returned = shape_first ? fcl::distance(&s, &mesh, request, got)
                                            : fcl::distance(&mesh, &s, request, got);
        EXPECT_EQ(returned, below.min_distance) << at;
        expectUnchanged(got, below, at + " (held below)");

        fcl::DistanceResultd above = heldResult(2 * fresh.min_distance, holder.get());
        shape_first ? fcl::distance(&s, &mesh, request, above) : fcl::distance(&mesh, &s, request, above);
        // The same computation as the fresh one, on a result that only starts higher.
        EXPECT_EQ(above.min_distance, fresh.min_distance) << at;
        EXPECT_EQ(above.o1, fresh.o1) << at;
        if (shape->getNodeType() == fcl::GEOM_BOX) {
          // The box goes through the mesh-mesh query, whose bound may pick another of several equally close
          // triangles (a shared vertex or edge): the same points, maybe another id.
          EXPECT_LE((above.nearest_points[0] - fresh.nearest_points[0]).norm(), 1e-12) << at;
          EXPECT_LE((above.nearest_points[1] - fresh.nearest_points[1]).norm(), 1e-12) << at;
        } else {
          EXPECT_EQ(above.b1, fresh.b1) << at;
          EXPECT_EQ(above.nearest_points[0], fresh.nearest_points[0]) << at;
          EXPECT_EQ(above.nearest_points[1], fresh.nearest_points[1]) << at;
        }
        ++tested;
      }
    }
  }
  EXPECT_GT(tested, 30);
}

// libfcl's own distance in the callback FCL's DefaultDistanceFunction is: the reference scenes' callback.
bool plainFclDistanceFunction(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data, double& dist) {
  auto* cdata = static_cast<fcl::DefaultDistanceData<double>*>(data);
  if (cdata->done) {
    dist = cdata->result.min_distance;
    return true;
  }
  plainFcl().distance_objects(o1, o2, cdata->request, cdata->result);
  dist = cdata->result.min_distance;
  return dist <= 0;
}

// One object of a scene: its geometry under test and the reference's, and what mesh it is (null for shapes).
struct SceneItem {
  std::shared_ptr<fcl::CollisionGeometryd> geometry, reference;
  const SceneMesh* mesh;
};

// Randomized scenes: a "robot" of four link meshes as CFL geometries against a "world" of six objects (CFL
// geometries, plain BVHModel<OBBRSS> meshes handled through cfl, and primitive shapes), manager against
// manager. Spreads from crowded (some poses collide) to apart.
TEST(FclAdapterBroadphase, ManagerAgainstManagerEqualsTheObbrssSceneInDistancePointsAndIds) {
  const auto& meshes = sceneMeshes();
  const double tolerance = 1e-9 * largestDiagonal();
  std::mt19937_64 rng(33);
  std::uniform_int_distribution<std::size_t> pick(0, meshes.size() - 1);
  const auto sphere = std::make_shared<fcl::Sphered>(0.15);
  const auto box = std::make_shared<fcl::Boxd>(0.3, 0.2, 0.5);
  int separated = 0, colliding = 0, through_bvh = 0, through_shape = 0, same_ids = 0, skipped = 0;
  for (int scene = 0; scene < 48; ++scene) {
    std::vector<SceneItem> robot_items, world_items;
    for (int i = 0; i < 4; ++i) {
      // Not the messy mesh: it meets the shapes, and FCL 0.7's sphere-triangle distance returns an unset
      // distance for its zero-area triangles (a denormal came back here), so the reference would be wrong.
      const SceneMesh* m;
      do m = meshes[pick(rng)].get();
      while (m->name == "messy");
      robot_items.push_back({m->cfl, m->obbrss, m});
    }
    for (int i = 0; i < 6; ++i) {
      const SceneMesh* m = meshes[pick(rng)].get();
      if (i == 4) {
        world_items.push_back({sphere, sphere, nullptr});
      } else if (i == 5) {
        world_items.push_back({box, box, nullptr});
      } else if (i % 2 == 1) {
        world_items.push_back({m->obbrss, m->obbrss, m});  // A plain BVHModel among CFL geometries.
      } else {
        world_items.push_back({m->cfl, m->obbrss, m});
      }
    }
    const double spread = std::vector<double>{0.4, 1.0, 1.8, 3.0}[scene % 4];
    std::vector<std::unique_ptr<fcl::CollisionObjectd>> objects, references;
    fcl::DynamicAABBTreeCollisionManagerd robot, world, reference_robot, reference_world;
    std::vector<const SceneItem*> item_of;  // Parallel to objects.
    const auto place = [&](const SceneItem& item, const fcl::Vector3d& center, fcl::DynamicAABBTreeCollisionManagerd& m,
                           fcl::DynamicAABBTreeCollisionManagerd& reference_m) {
      const fcl::Transform3d X = randomTransform(rng, center, spread);
      objects.push_back(std::make_unique<fcl::CollisionObjectd>(item.geometry, X));
      // Each reference object gets its own copy of its BVHModel: FCL 0.7 gives wrong nearest points when
      // objects share one in a broadphase pass. Its distancePostprocessOrientedNode (OBBRSS, RSS, kIOS) moves
      // the points from o1's frame to the world whenever result.o1 and result.o2 are the pair's geometries,
      // so a later pair of the same two geometries that does not beat the result moves them again.
      // The objects under test do share geometries (a mesh picked twice): the adapter has no such state.
      std::shared_ptr<fcl::CollisionGeometryd> reference = item.reference;
      if (item.mesh != nullptr) reference = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>(*item.mesh->obbrss);
      references.push_back(std::make_unique<fcl::CollisionObjectd>(reference, X));
      item_of.push_back(&item);
      m.registerObject(objects.back().get());
      reference_m.registerObject(references.back().get());
    };
    for (const SceneItem& item : robot_items) place(item, fcl::Vector3d(0, 0, 0.5), robot, reference_robot);
    for (const SceneItem& item : world_items) place(item, fcl::Vector3d::Zero(), world, reference_world);
    for (auto* m : {&robot, &world, &reference_robot, &reference_world}) m->setup();

    // FCL 0.7's distance between a mesh and an overlapping sphere or box is undefined: its shape-triangle
    // distance returns "intersecting" without setting the distance, which the mesh-shape traversal then
    // records (a denormal came back here). Such scenes have no reference answer.
    const std::string at = "scene " + std::to_string(scene);
    bool shape_overlaps = false;
    for (std::size_t r = 0; r < robot_items.size(); ++r)
      for (std::size_t w = robot_items.size(); w < references.size(); ++w) {
        if (item_of[w]->mesh != nullptr) continue;
        fcl::CollisionRequestd request;
        fcl::CollisionResultd result;
        shape_overlaps = shape_overlaps || plainFcl().collide_objects(references[r].get(), references[w].get(),
                                                                      request, result) > 0;
      }
    if (shape_overlaps) {
      ++skipped;
      continue;
    }

    fcl::DefaultDistanceData<double> got, expected;
    got.request.enable_nearest_points = expected.request.enable_nearest_points = true;
    robot.distance(&world, &got, fcl::DefaultDistanceFunction);
    reference_robot.distance(&reference_world, &expected, plainFclDistanceFunction);

    ASSERT_LT(expected.result.min_distance, std::numeric_limits<double>::max()) << at;
    if (expected.result.min_distance <= 0) {
      // Overlap stops the pass at the first overlapping pair: 0 for two meshes, and FCL's -1 for a mesh and a
      // shape. CFL's nearest points are then one point of the intersection and FCL's two triangle points, and
      // any intersecting triangle pair is right.
      EXPECT_LE(got.result.min_distance, 0.0) << at;
      ++colliding;
      continue;
    }
    EXPECT_NEAR(got.result.min_distance, expected.result.min_distance, tolerance) << at;
    ++separated;
    // The reference's objects have geometries of their own.
    const auto reference_object = [&](const fcl::CollisionGeometryd* g) {
      for (std::size_t k = 0; k < references.size(); ++k)
        if (references[k]->collisionGeometry().get() == g) return int(k);
      return -1;
    };
    const int expected1 = reference_object(expected.result.o1), expected2 = reference_object(expected.result.o2);
    ASSERT_GE(expected1, 0) << at;
    ASSERT_GE(expected2, 0) << at;
    if (item_of[expected1]->mesh == nullptr || item_of[expected2]->mesh == nullptr) {
      // A mesh and a separated sphere or box: answered from the CFL model, exactly, with FCL's roles (mesh o1,
      // b1 its triangle, shape o2, b2 NONE) but world-frame nearest points (FCL 0.7's are in each object's own
      // frame), and any of several equally close triangles.
      EXPECT_EQ(got.result.o1, item_of[expected1]->geometry.get()) << at;
      EXPECT_EQ(got.result.o2, item_of[expected2]->geometry.get()) << at;
      EXPECT_EQ(got.result.b2, expected.result.b2) << at;
      bool on_triangle = false;
      for (std::size_t k = 0; k < objects.size(); ++k)
        if (item_of[k]->mesh != nullptr && objects[k]->collisionGeometry().get() == got.result.o1)
          on_triangle = on_triangle || pointTriangleDistance(*item_of[k]->mesh, got.result.b1, objects[k]->getTransform(),
                                                             got.result.nearest_points[0]) <= tolerance;
      EXPECT_TRUE(on_triangle) << at;
      EXPECT_NEAR((got.result.nearest_points[0] - got.result.nearest_points[1]).norm(), got.result.min_distance,
                  tolerance)
          << at;
      ++through_shape;
    } else {
      EXPECT_LE((got.result.nearest_points[0] - expected.result.nearest_points[0]).norm(), tolerance) << at;
      EXPECT_LE((got.result.nearest_points[1] - expected.result.nearest_points[1]).norm(), tolerance) << at;
      // Two meshes. A geometry under test may stand for several objects (a mesh picked twice): the object
      // meant is the one whose reported triangle holds the reported (world) point.
      const auto object_of = [&](const fcl::DistanceResultd& r, int side, bool reference) {
        for (std::size_t k = 0; k < objects.size(); ++k) {
          const auto& o = reference ? references[k] : objects[k];
          if (o->collisionGeometry().get() == (side == 0 ? r.o1 : r.o2) &&
              pointTriangleDistance(*item_of[k]->mesh, side == 0 ? r.b1 : r.b2, o->getTransform(),
                                    r.nearest_points[side]) <= tolerance)
            return int(k);
        }
        return -1;
      };
      ASSERT_EQ(object_of(expected.result, 0, true), expected1) << at << ": reference point 0 off its triangle";
      ASSERT_EQ(object_of(expected.result, 1, true), expected2) << at << ": reference point 1 off its triangle";
      EXPECT_EQ(object_of(got.result, 0, false), expected1) << at;
      EXPECT_EQ(object_of(got.result, 1, false), expected2) << at;
      // Triangle ids: FCL's, except where several triangles hold the nearest point (a vertex or an edge they
      // share); the checks above (each point on its reported triangle and equal to FCL's) cover those.
      EXPECT_NEAR((got.result.nearest_points[0] - got.result.nearest_points[1]).norm(), got.result.min_distance,
                  tolerance)
          << at;
      same_ids += got.result.b1 == expected.result.b1 && got.result.b2 == expected.result.b2;
      through_bvh += item_of[expected1]->geometry == item_of[expected1]->reference ||
                     item_of[expected2]->geometry == item_of[expected2]->reference;
    }
  }
  // The scenes must have exercised what they are for.
  EXPECT_GT(separated, 24);
  EXPECT_GT(through_bvh, 3);
  EXPECT_GT(through_shape, 3);
  EXPECT_GT(colliding, 0);
  std::cout << separated << " separated scenes (closest pair through a BVHModel " << through_bvh
            << ", through a shape " << through_shape << ", mesh pairs with FCL's ids " << same_ids << "), "
            << colliding << " overlapping, " << skipped << " with a shape overlapping a link (skipped)\n";
}

}  // namespace
}  // namespace cfl_fcl
