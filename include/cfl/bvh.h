#pragma once
/// @file
/// A bounding volume hierarchy over the triangles of a mesh: plain data, no pointers.

#include "cfl/mesh.h"

#include <cstdint>
#include <vector>

namespace cfl {

/// One node of a Bvh, 192 bytes in three cache lines. Inner nodes have count == 0 and children at `first`
/// and `first + 1`; leaves have count > 0 and own Bvh::triangle_ids[first, first + count). All bounds are in
/// the mesh's frame M and length unit, and each holds every triangle below the node.
struct alignas(64) BvhNode {
  // Fields in the order a query reads them: the first cache line holds the sphere, the links and the
  // axis-aligned box (every node a walk reaches reads it), the other two the subtree range and the oriented
  // box (for the nodes a distance query bounds closely).
  Eigen::Vector3d center;   ///< Center of a sphere bounding every triangle below (not the box's circumsphere).
  double radius = 0;        ///< Radius of that sphere.
  std::int32_t first = 0;
  std::int32_t count = 0;
  /// Axis-aligned bounds of every triangle below, in float rounded outward: they hold the double bounds of
  /// the vertices, so that tests on them stay conservative. Read them through box().
  float box_min[3] = {0, 0, 0};
  float box_max[3] = {0, 0, 0};
  /// Every triangle below the node, leaf or not: Bvh::triangle_ids[subtree_first, subtree_first +
  /// subtree_count). Lets a query test two small subtrees pair by pair instead of splitting them further.
  std::int32_t subtree_first = 0;
  std::int32_t subtree_count = 0;
  /// An oriented box bounding every triangle below: its points p satisfy |obb_axes.col(i) . (p - obb_center)|
  /// <= obb_half[i]. The axes are the principal axes of the node's vertices (orthonormal, least spread
  /// first), so the box is thin across a nearly flat patch; distance queries bound node pairs with it where
  /// axis-aligned boxes and spheres are loose.
  Eigen::Matrix3d obb_axes = Eigen::Matrix3d::Identity();
  Eigen::Vector3d obb_center = Eigen::Vector3d::Zero();
  Eigen::Vector3d obb_half = Eigen::Vector3d::Zero();

  bool isLeaf() const { return count > 0; }
  /// The axis-aligned box in double (exact conversions of box_min and box_max).
  Aabb box() const {
    Aabb b;
    b.min = Eigen::Vector3d(box_min[0], box_min[1], box_min[2]);
    b.max = Eigen::Vector3d(box_max[0], box_max[1], box_max[2]);
    return b;
  }
};

/// The hierarchy; nodes[0] is the root. Built top-down: each node splits the longest axis of its
/// triangles' centroid bounds at the median, unless a binned surface-area split (along any axis) costs
/// under half as much, which happens where triangle sizes are very uneven (a few huge triangles among many
/// tiny ones end up near the root). Deterministic. Immutable after construction, so concurrent readers
/// are safe.
struct Bvh {
  /// No leaf lies deeper than this below the root (the root is at depth 0), so a depth-first walk that keeps
  /// one pending sibling per level fits in a fixed stack of kMaxDepth + 1 entries.
  static constexpr int kMaxDepth = 96;
  std::vector<BvhNode> nodes;
  std::vector<std::int32_t> triangle_ids;  ///< Triangle ids in leaf order.
};

/// Builds the hierarchy of `mesh` (which must pass validateMesh) with at most `max_leaf_size` triangles
/// per leaf (values below 1 count as 1): about 2n / max_leaf_size nodes. O(n log n) time, O(n) memory.
Bvh buildBvh(const TriangleMesh& mesh, int max_leaf_size = 1);

}  // namespace cfl
