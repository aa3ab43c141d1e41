#pragma once
/// @file
/// Internals of the FCL adapter shared by its translation units (not installed).

#include <cfl/mesh_model.h>

#include <fcl/geometry/collision_geometry.h>

#include <memory>

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

}  // namespace cfl_fcl::detail
