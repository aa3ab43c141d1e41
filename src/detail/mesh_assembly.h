#pragma once
// Assembling a TriangleMesh from a file's vertices and polygons, shared by the mesh readers (assimp's scenes
// and the native OBJ reader) so that every format gets the same vertex merging and triangulation.

#include "cfl/mesh.h"

#include <cstdint>
#include <cstring>
#include <unordered_map>
#include <vector>

namespace cfl::detail {

// A triangle soup under construction. Vertices with bit-identical positions become one (numbered in order of
// first use); polygons become consecutive triangles with the polygon's orientation (see addPolygon).
class MeshAssembler {
 public:
  // The id of the vertex at `p` (finite), added if no vertex has that position yet.
  int vertexId(const Eigen::Vector3d& p);
  // Appends the n - 2 triangles of the polygon whose corners are `corners` (ids from vertexId, n >= 3), in
  // order. Convex polygons, degenerate ones and those of more than 256 corners are fanned from corner 0;
  // other concave polygons are ear clipped in the plane of their Newell normal, falling back to the fan when
  // they are not simple. The count, and with it every later triangle id, does not depend on the geometry.
  void addPolygon(const std::vector<int>& corners);
  const TriangleMesh& mesh() const { return mesh_; }
  TriangleMesh take() { return std::move(mesh_); }

 private:
  // -0.0 and 0.0 are the same point.
  struct PositionKey {
    double x, y, z;
    bool operator==(const PositionKey& o) const { return x == o.x && y == o.y && z == o.z; }
  };
  struct PositionHash {
    std::size_t operator()(const PositionKey& k) const;
  };
  TriangleMesh mesh_;
  std::unordered_map<PositionKey, int, PositionHash> ids_;
};

}  // namespace cfl::detail
