#pragma once
/// @file
/// Internals of the FCL adapter shared by its translation units (not installed).

#include <cfl/cfl_model.h>
#include <cfl/mesh_model.h>

#include <fcl/geometry/collision_geometry.h>
#include <fcl/narrowphase/collision_request.h>
#include <fcl/narrowphase/collision_result.h>
#include <fcl/narrowphase/distance_request.h>
#include <fcl/narrowphase/distance_result.h>

#include <memory>
#include <mutex>
#include <vector>

namespace cfl_fcl::detail {

/// Throws cfl::Error, with the fix, when fcl::distance<double> or fcl::collide<double> as this program resolves
/// them are libfcl's own definitions, which would bypass CFL geometries (print "not supported" and return
/// DBL_MAX). Checked once per process; later calls rethrow the same verdict at no cost.
void checkEntryPoints();

/// The cfl::MeshModel copy of `geometry` when it is an fcl::BVHModel<BV> of a BV type FCL ships, null
/// otherwise. `owner`, when not null, is the shared_ptr the caller's CollisionObject holds: it lets the cache
/// tell a live model from a new one at the same address. See cfl_fcl::forgetBvhModel for the lifetime rule.
/// Throws cfl::Error for a BVHModel without triangles or with invalid ones.
std::shared_ptr<const cfl::MeshModel> bvhMeshModel(const fcl::CollisionGeometry<double>* geometry,
                                                   const std::shared_ptr<const fcl::CollisionGeometry<double>>* owner);

/// The triangles of a convex polyhedral shape (fcl::Box, fcl::Convex), frame S (the shape's), closed and
/// wound outward, for the mesh-mesh query; and, built on first use, its CflModel for signed queries.
/// Immutable once made (the solid model is built once, thread-safe).
struct ShapeMesh {
  std::shared_ptr<const cfl::MeshModel> mesh;
  /// Face planes (unit outward normal n, offset n . x on the face): inside is n . x <= offset for all.
  std::vector<Eigen::Vector4d> planes;
  /// Whether p (frame S) lies in the solid shape (on its surface counts).
  bool contains(const Eigen::Vector3d& p_S) const;
  /// The shape as a CflModel (the penetration query needs one per body). O(1) after the first call.
  const cfl::CflModel& solid() const;

  mutable std::once_flag solid_once;
  mutable std::unique_ptr<cfl::CflModel> solid_model;
};

/// The cached ShapeMesh of an fcl::Box or fcl::Convex, null for other geometries. Boxes are keyed by their
/// sides, convexes by address with their vertices and faces compared on every lookup, so an entry never
/// outlives what it describes. Throws cfl::Error for a box with a side <= 0 or a convex with bad faces.
/// Thread-safe.
std::shared_ptr<const ShapeMesh> shapeMesh(const fcl::CollisionGeometry<double>& shape);

/// Distance between the CFL geometry `cfl` (pose tf_c) and a sphere, capsule, box or convex `shape` (pose
/// tf_s), answered from the regions and recorded in `result` as FCL records its shape-mesh pairs (o1 = the
/// CFL geometry, b1 = its triangle, o2 = the shape, b2 = NONE, in both argument orders). Returns false,
/// leaving `result` untouched, when FCL's own algorithm must answer instead: other shapes, and requests
/// where the shape touches or overlaps a mesh that is not signed (unsigned request, or a mesh that is not
/// closed; see shape_queries.cpp).
bool shapeDistance(const fcl::CollisionGeometry<double>& cfl, const cfl::CflModel& model,
                   const fcl::Transform3<double>& tf_c, const fcl::CollisionGeometry<double>& shape,
                   const fcl::Transform3<double>& tf_s, const fcl::DistanceRequest<double>& request,
                   fcl::DistanceResult<double>& result);

/// Collision between the CFL geometry and a sphere, capsule, box or convex, with contacts recorded as FCL
/// records them for shape-mesh pairs (one per mesh triangle meeting the shape). Returns false, leaving
/// `result` untouched, for other shapes, which FCL's own algorithm answers.
bool shapeCollide(const fcl::CollisionGeometry<double>& cfl, const cfl::CflModel& model,
                  const fcl::Transform3<double>& tf_c, const fcl::CollisionGeometry<double>& shape,
                  const fcl::Transform3<double>& tf_s, const fcl::CollisionRequest<double>& request,
                  fcl::CollisionResult<double>& result);

}  // namespace cfl_fcl::detail
