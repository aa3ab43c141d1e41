#include "cfl/bvh.h"

#include <algorithm>
#include <cmath>
#include <numeric>

namespace cfl {

Bvh buildBvh(const TriangleMesh& mesh, int max_leaf_size) {
  max_leaf_size = std::max(1, max_leaf_size);
  const int triangle_count = static_cast<int>(mesh.triangles.size());
  Bvh bvh;
  bvh.triangle_ids.resize(triangle_count);
  std::iota(bvh.triangle_ids.begin(), bvh.triangle_ids.end(), 0);
  if (triangle_count == 0) return bvh;

  std::vector<Eigen::Vector3d> centroids(triangle_count);
  for (int t = 0; t < triangle_count; ++t) {
    const auto& tri = mesh.triangles[t];
    centroids[t] = (mesh.vertices[tri[0]] + mesh.vertices[tri[1]] + mesh.vertices[tri[2]]) / 3.0;
  }

  struct Range {
    int node, begin, end;
  };
  bvh.nodes.reserve(2 * triangle_count);
  bvh.nodes.emplace_back();
  std::vector<Range> stack{{0, 0, triangle_count}};
  while (!stack.empty()) {
    const Range range = stack.back();
    stack.pop_back();
    Aabb box, centroid_box;
    for (int i = range.begin; i < range.end; ++i) {
      const int t = bvh.triangle_ids[i];
      for (int index : mesh.triangles[t]) box.extend(mesh.vertices[index]);
      centroid_box.extend(centroids[t]);
    }
    // The sphere is centered on the box but sized by the actual vertices: tighter than the box's
    // circumsphere, and the query's lower bounds scale with it.
    const Eigen::Vector3d center = box.center();
    double radius_squared = 0;
    for (int i = range.begin; i < range.end; ++i) {
      for (int index : mesh.triangles[bvh.triangle_ids[i]]) {
        radius_squared = std::max(radius_squared, (mesh.vertices[index] - center).squaredNorm());
      }
    }
    {
      BvhNode& node = bvh.nodes[range.node];
      node.box = box;
      node.center = center;
      node.radius = std::sqrt(radius_squared);
    }
    const int count = range.end - range.begin;
    if (count <= max_leaf_size) {
      bvh.nodes[range.node].first = range.begin;
      bvh.nodes[range.node].count = count;
      continue;
    }
    int axis = 0;
    centroid_box.size().maxCoeff(&axis);
    const int middle = range.begin + count / 2;
    std::nth_element(bvh.triangle_ids.begin() + range.begin, bvh.triangle_ids.begin() + middle,
                     bvh.triangle_ids.begin() + range.end,
                     [&](int x, int y) { return centroids[x][axis] < centroids[y][axis]; });
    const int left = static_cast<int>(bvh.nodes.size());
    bvh.nodes.emplace_back();
    bvh.nodes.emplace_back();
    bvh.nodes[range.node].first = left;
    bvh.nodes[range.node].count = 0;
    stack.push_back({left + 1, middle, range.end});
    stack.push_back({left, range.begin, middle});
  }
  return bvh;
}

}  // namespace cfl
