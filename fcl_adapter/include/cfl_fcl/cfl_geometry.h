#pragma once
/// @file
/// A CFL model as an FCL 0.7 collision geometry: swap a `fcl::BVHModel` mesh for a `CFLGeometry` and keep
/// calling the unmodified `fcl::distance` / `fcl::collide` and the broadphase managers.
///
/// How the calls reach CFL: this library defines its own `fcl::distance<double>` and `fcl::collide<double>`
/// (both overloads each). They handle every pair that involves a CFLGeometry and hand every other pair to
/// libfcl's own definitions unchanged, so FCL-only pairs give exactly what plain FCL gives. A program
/// uses these definitions when the library comes before libfcl in symbol lookup, which
/// `target_link_libraries(app cfl::cfl_fcl)` arranges; when it does not, the first CFLGeometry constructed
/// throws cfl::Error explaining how to fix the link (see docs/fcl_adapter.md).
///
/// Pairs with a CFLGeometry, in either order and through both overloads:
///   - CFLGeometry / CFLGeometry: cfl::computeDistance on both models, cfl::computeCollision. When both
///     meshes are closed (cfl::MeshClosure): with request.enable_signed_distance, cfl::computeSignedDistance
///     (minus the penetration depth when the bodies overlap, one inside the other included, with the deepest
///     point and its closest point as nearest points); collide also reports one body wholly inside the
///     other, and with enable_contact every contact carries the bodies' depth and normal
///     (cfl::computePenetration). See docs/signed_distance.md.
///   - CFLGeometry / fcl::BVHModel<BV> for every BV FCL ships: the same, with the BVHModel's triangles as the
///     other mesh (a cfl::MeshModel copy cached per BVHModel, see forgetBvhModel for its lifetime rule).
///   - CFLGeometry / fcl::Sphere, fcl::Capsule, fcl::Box, fcl::Convex: from the CFL model, exact, reported as
///     FCL reports shape-mesh pairs in both orders (o1 = the CFLGeometry with b1 = its triangle, o2 = the
///     shape with b2 = NONE) with world-frame nearest points. Sphere: the point distance of its center minus
///     the radius; capsule: the distance of its axis segment (cfl::computeSegmentDistance) minus the radius;
///     box: cfl::computeBoxDistance; convex: cfl::computeDistance against its triangles (cached per convex,
///     compared on every lookup, so an entry never outlives its shape). Where the shape touches or overlaps
///     the mesh, an unsigned request (or any request on a mesh that is not closed) gets FCL's own answer
///     from the BVHModel<OBBRSS> twin below, FCL 0.7's answer being undefined there and programs comparing
///     with it; a signed request on a closed mesh gets the negative signed distance: for spheres and
///     capsules that of the center or axis minus the radius (the capsule's depth certified to 1e-6 of the
///     mesh's diagonal), for boxes and convexes minus the penetration depth (cfl::computeSignedDistance
///     against the shape's own CflModel, built once per box size or convex). collide: one contact per
///     triangle that meets the shape, FCL's roles (depth: positive for spheres and capsules; for boxes and
///     convexes the pair's penetration depth on a closed mesh, 0 otherwise); on a closed mesh a shape wholly
///     inside collides too. See docs/fcl_adapter.md, "Primitive
///     shapes".
///   - CFLGeometry / anything else (cylinders, cones, ellipsoids, octrees):
///     FCL's own algorithm for that object against a BVHModel<OBBRSS> of the same triangles, which the
///     geometry builds on first use. Results are therefore exactly FCL's, including FCL's habit of reporting
///     the mesh as o1 (b1 = triangle) in both orders. Exception: the distance to a plane or halfspace, which
///     FCL 0.7 cannot compute for meshes (its GJK crashes), is computed exactly by the adapter from the
///     triangle corners and reported the same way.
///
/// Results follow FCL's conventions for BVHModel meshes: world-frame nearest points when
/// request.enable_nearest_points is set; b1/b2 are triangle ids in each model's own triangle list; o1/o2
/// are the geometries in argument order; distance is 0 (never negative) when the meshes touch or overlap,
/// with request.enable_signed_distance or without (no penetration depth is computed, as with BVHModel),
/// except for the closed pairs above: two closed CFL meshes, and shapes on a closed mesh (negative inside
/// when signed). A CFLGeometry against a BVHModel is never signed: the BVHModel has no inside.
/// request.rel_err / abs_err become cfl::DistanceOptions::rel_err / abs_err (early termination with the
/// guarantee stated there). request.isSatisfied(result) on entry returns at once, as FCL's dispatch does.

#include <cfl/cfl_model.h>
#include <cfl/error.h>

#include <fcl/geometry/bvh/BVH_model.h>
#include <fcl/geometry/collision_geometry.h>
#include <fcl/math/triangle.h>

#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace cfl_fcl {

/// A triangle mesh with its CFL voxels (a shared, immutable cfl::CflModel) as an
/// fcl::CollisionGeometry<double>. Frame: the mesh's own (M), placed by the CollisionObject's or the
/// call's Transform3. Units: the mesh's.
///
/// FCL identity: getObjectType() == OT_BVH, getNodeType() == BV_UNKNOWN. OT_BVH makes FCL put the CFL
/// geometry first when it meets a shape (so FCL never treats it as a shape); BV_UNKNOWN is the one node
/// slot no FCL geometry uses, and no FCL code path casts a BV_UNKNOWN geometry to a concrete type (continuous
/// collision's BVH-only branch checks node types first and declines).
///
/// Thread safety: const after construction; any number of threads may query the same geometry at once.
/// Many geometries may share one model (see the shared_ptr constructor), e.g. the same link mesh in
/// several robots.
class CFLGeometry final : public fcl::CollisionGeometry<double> {
 public:
  /// Builds the CFL model of the triangles (ids = positions in `triangles`). Throws cfl::Error for an invalid
  /// mesh or options (the message names the triangle, vertex or value), or when the program is linked so
  /// that fcl::distance would bypass this adapter. Cost: cfl::buildCflModel.
  CFLGeometry(const std::vector<fcl::Vector3d>& vertices, const std::vector<fcl::Triangle>& triangles,
              const cfl::BuildOptions& options = {});

  /// Builds the CFL model of a BVHModel's triangles, keeping its triangle ids. Any BV type; the model must
  /// hold triangles (endModel() called). The BVHModel is only read, not kept.
  template <typename BV>
  explicit CFLGeometry(const fcl::BVHModel<BV>& model, const cfl::BuildOptions& options = {})
      : CFLGeometry(verticesOf(model), trianglesOf(model), options) {}

  /// Wraps an existing model without copying it, so that many geometries share one precomputation.
  /// Throws cfl::Error for a null model.
  explicit CFLGeometry(std::shared_ptr<const cfl::CflModel> model);

  /// A geometry on a model saved with cfl::saveCflModel (no rebuild: load time is file reading). Throws
  /// cfl::Error naming the path for a missing, unreadable or invalid file (see cfl::loadCflModel).
  static std::shared_ptr<CFLGeometry> load(const std::string& path);

  CFLGeometry(const CFLGeometry&) = delete;
  CFLGeometry& operator=(const CFLGeometry&) = delete;

  const cfl::CflModel& model() const { return *model_; }
  const std::shared_ptr<const cfl::CflModel>& sharedModel() const { return model_; }

  fcl::OBJECT_TYPE getObjectType() const override { return fcl::OT_BVH; }
  fcl::NODE_TYPE getNodeType() const override { return fcl::BV_UNKNOWN; }

  /// Sets aabb_local, aabb_center and aabb_radius from the mesh's bounds (frame M), which is all the
  /// broadphase managers read. Called by the constructors (and again by fcl::CollisionObject).
  void computeLocalAABB() override;

  /// FCL's own BVHModel<OBBRSS> of the same triangles and ids, used for the shape pairs FCL answers. Built on
  /// the first call (thread-safe), O(n log n); kept until the geometry is destroyed.
  const fcl::BVHModel<fcl::OBBRSSd>& shapeProxy() const;

 private:
  template <typename BV>
  static std::vector<fcl::Vector3d> verticesOf(const fcl::BVHModel<BV>& model) {
    if (model.vertices == nullptr || model.num_vertices <= 0 || model.tri_indices == nullptr || model.num_tris <= 0)
      throw cfl::Error("CFLGeometry: the BVHModel has no triangles (num_tris " + std::to_string(model.num_tris) +
                       "); build it with beginModel/addSubModel/endModel first");
    return std::vector<fcl::Vector3d>(model.vertices, model.vertices + model.num_vertices);
  }
  template <typename BV>
  static std::vector<fcl::Triangle> trianglesOf(const fcl::BVHModel<BV>& model) {
    return std::vector<fcl::Triangle>(model.tri_indices, model.tri_indices + model.num_tris);
  }

  std::shared_ptr<const cfl::CflModel> model_;
  mutable std::once_flag shape_proxy_once_;
  mutable std::unique_ptr<fcl::BVHModel<fcl::OBBRSSd>> shape_proxy_;
};

/// The adapter keeps, per fcl::BVHModel met by a CFLGeometry, a cfl::MeshModel copy of its triangles,
/// made on the first query against that BVHModel (O(n log n)) and reused afterwards (O(1) lookup).
///
/// Lifetime rule: an entry is rebuilt automatically when the BVHModel is a different object (queries
/// through fcl::CollisionObject track the owning shared_ptr, so a destroyed model reallocated at the same
/// address is always seen), or when its vertex or triangle array pointers, counts or build state change
/// (beginModel ... endModel, beginUpdateModel ... endUpdateModel), or when one of 64 sampled vertices
/// moved. Edits that keep all of these are NOT seen, namely beginReplaceModel ... endReplaceModel that move
/// unsampled vertices only, and raw-pointer queries (CollisionGeometry + Transform3 overload) on a new
/// BVHModel constructed at a destroyed one's address with equally sized arrays: call forgetBvhModel(model)
/// after such an edit or before such a reuse. Thread-safe.
void forgetBvhModel(const fcl::CollisionGeometry<double>& model);

/// Drops every cached BVHModel copy (frees their memory). Thread-safe; queries in flight keep their copy.
void clearBvhModelCache();

}  // namespace cfl_fcl
