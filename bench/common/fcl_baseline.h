#pragma once
/// @file
/// FCL 0.7 BVHModel<OBBRSS> and BVHModel<RSS>, the baselines every benchmark compares CFL with, behind a
/// small interface so that only fcl_baseline.cpp compiles FCL's templates.

#include "cfl/mesh.h"

#include <Eigen/Geometry>

#include <cstdint>
#include <memory>

namespace cfl::bench {

/// The bounding volume of an FCL mesh hierarchy.
enum class FclBv { kOBBRSS, kRSS };

/// "OBBRSS" or "RSS".
const char* fclBvName(FclBv bv);

/// An fcl::BVHModel of a mesh, triangles added in mesh order (so FCL's primitive ids are our triangle ids).
/// Immutable after construction; concurrent distance queries on one model are safe (FCL only reads it).
class FclModel {
 public:
  /// Builds the hierarchy (fcl's default top-down splitter). `mesh` must pass validateMesh.
  FclModel(const TriangleMesh& mesh, FclBv bv);
  ~FclModel();
  FclModel(FclModel&&) noexcept;
  FclModel& operator=(FclModel&&) noexcept;

  FclBv bv() const { return bv_; }
  /// Wall time of beginModel/addSubModel/endModel, seconds.
  double buildSeconds() const { return build_seconds_; }

  struct Impl;
  const Impl& impl() const { return *impl_; }

 private:
  FclBv bv_;
  double build_seconds_ = 0;
  std::unique_ptr<Impl> impl_;
};

/// One FCL answer, in the shape of cfl::DistanceResult.
struct FclDistance {
  double distance = 0;
  Eigen::Vector3d point_a = Eigen::Vector3d::Zero();  ///< World frame (FCL 0.7 transforms mesh points to it).
  Eigen::Vector3d point_b = Eigen::Vector3d::Zero();
  int triangle_a = -1;
  int triangle_b = -1;
};

/// What users call: fcl::distance on the two geometries with enable_nearest_points = true and otherwise
/// default request. Both models must have the same bv. This is the timed baseline.
FclDistance fclDistance(const FclModel& a, const Eigen::Isometry3d& X_WA, const FclModel& b,
                        const Eigen::Isometry3d& X_WB);

/// The same query run through FCL's own traversal node with enable_statistics on, which is how FCL counts
/// its work: `triangle_pairs` is its num_leaf_tests (triangle-triangle distances, N_p) and `bv_tests` its
/// num_bv_tests (bounding-volume pair distances, N_v). fcl::distance builds the same node and runs the same
/// traversal without statistics, so the counts describe the timed query; not timed itself.
struct FclCountedDistance {
  double distance = 0;
  std::int64_t triangle_pairs = 0;
  std::int64_t bv_tests = 0;
};
FclCountedDistance fclCountedDistance(const FclModel& a, const Eigen::Isometry3d& X_WA, const FclModel& b,
                                      const Eigen::Isometry3d& X_WB);

/// A primitive shape as FCL 0.7 takes it, centered at its frame's origin: a sphere of radius `radius`
/// (0 makes it a point), a capsule of radius `radius` and segment length `length` along z, or a box of side
/// lengths `sides`.
struct FclShape {
  enum class Kind { kSphere, kCapsule, kBox } kind = Kind::kSphere;
  double radius = 0;
  double length = 0;
  Eigen::Vector3d sides = Eigen::Vector3d::Zero();
};

/// fcl::distance between the shape at X_WS and the mesh of `model` at X_WM (FCL's shape-against-BVHModel
/// traversal, GJK per triangle except for spheres), enable_nearest_points = true: the baseline of the shape
/// and point sections. The model must be OBBRSS. Builds FCL's shape object on every call, as an FCL user
/// holding a CollisionObject does not; the cost is a few allocations, far below the query's.
double fclShapeDistance(const FclShape& shape, const Eigen::Isometry3d& X_WS, const FclModel& model,
                        const Eigen::Isometry3d& X_WM);

/// The deepest contact of fcl::collide between two models (same bv) with contacts enabled and at most
/// `max_contacts` of them: FCL's per-triangle-pair local depth, 0 when the meshes do not touch. The baseline
/// of the penetration section.
double fclDeepestContact(const FclModel& a, const Eigen::Isometry3d& X_WA, const FclModel& b,
                         const Eigen::Isometry3d& X_WB, std::size_t max_contacts);

}  // namespace cfl::bench
