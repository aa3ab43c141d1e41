#pragma once
/// @file
/// The benches' exact reference for a primitive shape against a mesh, where FCL's answer and CFL's differ.

#include "fcl_baseline.h"

#include "cfl/mesh.h"

#include <Eigen/Geometry>

namespace cfl::bench {

/// The distance between `shape` at pose X_MS and `mesh` (both in the mesh's frame M), by brute force over
/// every triangle with the core's exact kernels: a sphere's center and a capsule's segment (along the shape's
/// z axis, as FCL's) with the point- and segment-triangle distances less the radius, a box as its 12
/// triangles against each triangle with the triangle-triangle distance, 0 where a mesh vertex lies in the
/// box. Never below 0. O(triangles); thread-safe.
double bruteForceShapeDistance(const FclShape& shape, const Eigen::Isometry3d& X_MS, const TriangleMesh& mesh);

}  // namespace cfl::bench
