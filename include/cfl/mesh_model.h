#pragma once
/// @file
/// A validated mesh with the acceleration data every query needs.

#include "cfl/bvh.h"
#include "cfl/mesh.h"

#include <array>
#include <cstdint>
#include <vector>

namespace cfl {

/// A Bvh node as a point query reads it: its float box (BvhNode::box_min and box_max, rounded outward) and its
/// links (BvhNode's first and count), 32 bytes where a BvhNode takes 192, so that a walk reading only boxes
/// touches a sixth of the memory.
struct CompactBvhNode {
  float min[3];
  std::int32_t first;
  float max[3];
  std::int32_t count;
};

/// Each triangle's three corners (frame M), stored once, in the Bvh's leaf order, and read by triangle id
/// through a position index. Both orders are read on hot paths: by leaf position where a query walks the
/// Bvh (neighbouring triangles side by side, as MeshModel::leaf_spheres), by id where
/// it scans a list. A second copy in id order cost 72 bytes per triangle; the index costs 4 and one more
/// read, which the list scans pay only for the triangles their sphere and plane tests let through.
struct TriangleCorners {
  using Corners = std::array<Eigen::Vector3d, 3>;
  std::vector<Corners> in_leaf_order;       ///< Entry n: triangle bvh.triangle_ids[n].
  std::vector<std::int32_t> leaf_position;  ///< leaf_position[t]: the entry of triangle t in in_leaf_order.
  /// The corners of triangle t (t < size()).
  const Corners& operator[](std::size_t t) const { return in_leaf_order[std::size_t(leaf_position[t])]; }
  /// The triangle count.
  std::size_t size() const { return leaf_position.size(); }
};

/// A validated triangle mesh, its triangles' corners gathered for the distance kernels, and its Bvh.
/// This is what the query needs of the "other" mesh B; a CflModel holds one for its own mesh.
/// Immutable after construction: concurrent queries are safe.
struct MeshModel {
  TriangleMesh mesh;
  /// corners[t] = the 3 vertices of triangle t, frame M; corners.in_leaf_order[n] those of triangle
  /// bvh.triangle_ids[n].
  TriangleCorners corners;
  /// The smallest sphere holding each triangle (center and radius, frame M; the center lies in the triangle's
  /// plane): a cheap lower bound before exact tests.
  std::vector<Eigen::Vector4d> spheres;
  /// Each triangle's plane (unit normal n, offset n . corner 0; all zero for a degenerate triangle): the
  /// distance to the plane bounds the distance to the triangle from below.
  std::vector<Eigen::Vector4d> planes;
  Bvh bvh;
  /// spheres and planes again in the Bvh's leaf order (the corners are in corners.in_leaf_order): entry n
  /// describes triangle bvh.triangle_ids[n]. A query walks the other mesh's Bvh and reads a small subtree's
  /// triangles together; side by side, their corners and spheres span about a third fewer cache lines than
  /// by triangle id (bunny: 13.0 instead of 20.7 per subtree of 5 to 8 triangles), which counts where the
  /// cache is shared and busy. 64 more bytes per triangle.
  std::vector<Eigen::Vector4d> leaf_spheres;
  std::vector<Eigen::Vector4d> leaf_planes;
  /// spines[t]: triangle t's longest edge (0: corners 0-1, 1: 1-2, 2: 2-0), plus 4 where the triangle is a
  /// sliver (its third corner lies within a quarter of that edge's length of it). Slivers' spheres and
  /// boxes are loose; distance queries bound pairs of them by their longest edges instead.
  std::vector<std::uint8_t> spines;
  /// bvh.nodes again as CompactBvhNode, same indices and the same float boxes.
  std::vector<CompactBvhNode> compact_nodes;
  /// node_spine_radii[n]: the largest distance (rounded up, length unit of M) from a vertex below Bvh node n
  /// to the line through its oriented box's center along the box's longest axis. With the box, the node is a
  /// segment swept by a disk of that radius: a piece of a pipe or a rod, whose box corners reach 1.4 times
  /// as far across, is bounded as the cylinder it nearly is where two such nodes are far apart for their
  /// width. 4 bytes per node.
  std::vector<float> node_spine_radii;
  Aabb bounds;  ///< Bounds of the vertices that triangles use.
};

/// Validates `mesh` (throws cfl::Error naming the defect, see validateMesh) and builds its model; every
/// field but `mesh` is derived from it deterministically.
/// O(n log n).
MeshModel makeMeshModel(TriangleMesh mesh);

}  // namespace cfl
