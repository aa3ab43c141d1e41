#pragma once
/// @file
/// A bounding volume hierarchy over the triangles of a mesh: plain data, no pointers.

#include "cfl/mesh.h"

#include <cstdint>
#include <vector>

namespace cfl {

/// One node of a Bvh. Inner nodes have count == 0 and children at `first` and `first + 1`; leaves have
/// count > 0 and own Bvh::triangle_ids[first, first + count).
struct alignas(64) BvhNode {
  // Fields in the order a distance query reads them, one cache line per group: the sphere and the links
  // for every node it reaches, the oriented box for the nodes it bounds closely, the axis-aligned box for
  // the Bvh-against-Bvh paths.
  Eigen::Vector3d center;   ///< Center of a sphere bounding every triangle below (not the box's circumsphere).
  double radius = 0;        ///< Radius of that sphere.
  std::int32_t first = 0;
  std::int32_t count = 0;
  /// Every triangle below the node, leaf or not: Bvh::triangle_ids[subtree_first, subtree_first +
  /// subtree_count). Lets a query test two small subtrees pair by pair instead of splitting them further.
  std::int32_t subtree_first = 0;
  std::int32_t subtree_count = 0;
  /// An oriented box bounding every triangle below: its points p satisfy |obb_axes.col(i) . (p - obb_center)|
  /// <= obb_half[i]. The axes are the principal axes of the node's vertices (orthonormal, least spread
  /// first), so the box is thin across a nearly flat patch; distance queries bound node pairs with it where
  /// axis-aligned boxes and spheres are loose.
  alignas(64) Eigen::Matrix3d obb_axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d obb_center = Eigen::Vector3d::Zero();
  Eigen::Vector3d obb_half = Eigen::Vector3d::Zero();
  alignas(64) Aabb box;     ///< Bounds of every triangle below, mesh frame.

  bool isLeaf() const { return count > 0; }
};

/// The hierarchy; nodes[0] is the root. Built top-down by splitting the longest axis of the centroid
/// bounds at the median (binned SAH would be tighter; median split keeps builds fast and deterministic).
/// Immutable after construction, so concurrent readers are safe.
struct Bvh {
  std::vector<BvhNode> nodes;
  std::vector<std::int32_t> triangle_ids;  ///< Triangle ids in leaf order.
};

/// Builds the hierarchy of `mesh` (which must pass validateMesh) with at most `max_leaf_size` triangles
/// per leaf. O(n log n) time, O(n) memory.
Bvh buildBvh(const TriangleMesh& mesh, int max_leaf_size = 1);

}  // namespace cfl
