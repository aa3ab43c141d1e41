#include "fcl_baseline.h"

#include "cfl/error.h"

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/math/bv/OBBRSS.h>
#include <fcl/math/bv/RSS.h>
#include <fcl/narrowphase/detail/traversal/collision_node.h>
#include <fcl/narrowphase/detail/traversal/distance/mesh_distance_traversal_node.h>
#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/capsule.h>
#include <fcl/geometry/shape/sphere.h>
#include <fcl/narrowphase/collision.h>
#include <fcl/narrowphase/distance.h>

#include <algorithm>
#include <chrono>
#include <vector>

namespace cfl::bench {

struct FclModel::Impl {
  std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> obbrss;
  std::shared_ptr<fcl::BVHModel<fcl::RSSd>> rss;

  const fcl::CollisionGeometryd* geometry() const {
    return obbrss ? static_cast<const fcl::CollisionGeometryd*>(obbrss.get())
                  : static_cast<const fcl::CollisionGeometryd*>(rss.get());
  }
};

namespace {

template <typename Bv>
std::shared_ptr<fcl::BVHModel<Bv>> buildModel(const TriangleMesh& mesh) {
  std::vector<fcl::Vector3d> vertices(mesh.vertices.begin(), mesh.vertices.end());
  std::vector<fcl::Triangle> triangles;
  triangles.reserve(mesh.triangles.size());
  for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  auto model = std::make_shared<fcl::BVHModel<Bv>>();
  if (model->beginModel(int(triangles.size()), int(vertices.size())) != fcl::BVH_OK ||
      model->addSubModel(vertices, triangles) != fcl::BVH_OK || model->endModel() != fcl::BVH_OK) {
    throw Error("FCL could not build its BVHModel of a mesh with " + std::to_string(triangles.size()) +
                " triangles");
  }
  return model;
}

template <typename Node, typename Bv>
FclCountedDistance countedDistance(const fcl::BVHModel<Bv>& a, const Eigen::Isometry3d& X_WA,
                                   const fcl::BVHModel<Bv>& b, const Eigen::Isometry3d& X_WB) {
  fcl::DistanceRequestd request(true);
  fcl::DistanceResultd result;
  Node node;
  fcl::detail::initialize(node, a, X_WA, b, X_WB, request, result);
  node.enable_statistics = true;
  fcl::detail::distance(&node);
  return {result.min_distance, node.num_leaf_tests, node.num_bv_tests};
}

void requireSameBv(const FclModel& a, const FclModel& b) {
  if (a.bv() != b.bv()) throw Error("FCL distance between models of different bounding volumes");
}

}  // namespace

const char* fclBvName(FclBv bv) { return bv == FclBv::kOBBRSS ? "OBBRSS" : "RSS"; }

FclModel::FclModel(const TriangleMesh& mesh, FclBv bv) : bv_(bv), impl_(std::make_unique<Impl>()) {
  const auto start = std::chrono::steady_clock::now();
  if (bv == FclBv::kOBBRSS) {
    impl_->obbrss = buildModel<fcl::OBBRSSd>(mesh);
  } else {
    impl_->rss = buildModel<fcl::RSSd>(mesh);
  }
  build_seconds_ = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
}

FclModel::~FclModel() = default;
FclModel::FclModel(FclModel&&) noexcept = default;
FclModel& FclModel::operator=(FclModel&&) noexcept = default;

FclDistance fclDistance(const FclModel& a, const Eigen::Isometry3d& X_WA, const FclModel& b,
                        const Eigen::Isometry3d& X_WB) {
  requireSameBv(a, b);
  fcl::DistanceRequestd request(true);
  fcl::DistanceResultd result;
  fcl::distance(a.impl().geometry(), X_WA, b.impl().geometry(), X_WB, request, result);
  FclDistance out;
  out.distance = result.min_distance;
  out.point_a = result.nearest_points[0];
  out.point_b = result.nearest_points[1];
  out.triangle_a = result.b1;
  out.triangle_b = result.b2;
  return out;
}

FclCountedDistance fclCountedDistance(const FclModel& a, const Eigen::Isometry3d& X_WA, const FclModel& b,
                                      const Eigen::Isometry3d& X_WB) {
  requireSameBv(a, b);
  if (a.bv() == FclBv::kOBBRSS) {
    return countedDistance<fcl::detail::MeshDistanceTraversalNodeOBBRSS<double>>(*a.impl().obbrss, X_WA,
                                                                                *b.impl().obbrss, X_WB);
  }
  return countedDistance<fcl::detail::MeshDistanceTraversalNodeRSS<double>>(*a.impl().rss, X_WA, *b.impl().rss,
                                                                           X_WB);
}

double fclShapeDistance(const FclShape& shape, const Eigen::Isometry3d& X_WS, const FclModel& model,
                        const Eigen::Isometry3d& X_WM) {
  if (model.bv() != FclBv::kOBBRSS) throw Error("FCL shape distance: the mesh model must be OBBRSS");
  fcl::DistanceRequestd request(true);
  fcl::DistanceResultd result;
  switch (shape.kind) {
    case FclShape::Kind::kSphere: {
      const fcl::Sphered sphere(shape.radius);
      return fcl::distance(&sphere, X_WS, model.impl().geometry(), X_WM, request, result);
    }
    case FclShape::Kind::kCapsule: {
      const fcl::Capsuled capsule(shape.radius, shape.length);
      return fcl::distance(&capsule, X_WS, model.impl().geometry(), X_WM, request, result);
    }
    case FclShape::Kind::kBox: {
      const fcl::Boxd box(shape.sides);
      return fcl::distance(&box, X_WS, model.impl().geometry(), X_WM, request, result);
    }
  }
  throw Error("FCL shape distance: unknown shape kind");
}

double fclDeepestContact(const FclModel& a, const Eigen::Isometry3d& X_WA, const FclModel& b,
                         const Eigen::Isometry3d& X_WB, std::size_t max_contacts) {
  requireSameBv(a, b);
  fcl::CollisionRequestd request(max_contacts, true);
  fcl::CollisionResultd result;
  fcl::collide(a.impl().geometry(), X_WA, b.impl().geometry(), X_WB, request, result);
  double deepest = 0;
  for (std::size_t i = 0; i < result.numContacts(); ++i)
    deepest = std::max(deepest, result.getContact(i).penetration_depth);
  return deepest;
}

}  // namespace cfl::bench
