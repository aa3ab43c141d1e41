#include "cfl/mesh_model.h"

#include "detail/exact_arithmetic.h"
#include "detail/float_rounding.h"
#include "detail/triangle_spine.h"

#include <algorithm>
#include <cmath>
#include <limits>

#include <Eigen/Geometry>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>

namespace cfl {
namespace {

// Radius of the smallest sphere about `center` holding the three corners.
double reachFrom(const std::array<Eigen::Vector3d, 3>& c, const Eigen::Vector3d& center) {
  return std::sqrt(std::max({(c[0] - center).squaredNorm(), (c[1] - center).squaredNorm(),
                             (c[2] - center).squaredNorm()}));
}

// The smallest sphere holding the triangle (center, radius): about the longest edge's midpoint when the
// triangle is right or obtuse, about the circumcenter otherwise; the centroid's sphere whenever rounding
// makes that one no smaller. The query's reach test is threshold + both radii, with a threshold about one
// triangle across at short range, so the radii weigh: the smallest sphere, not the centroid's, is what keeps
// the test tight (docs/performance.md has the measurement).
Eigen::Vector4d boundingSphere(const std::array<Eigen::Vector3d, 3>& c) {
  Eigen::Vector3d center = (c[0] + c[1] + c[2]) / 3.0;
  double radius = reachFrom(c, center);
  Eigen::Vector3d smallest = center;
  bool found = false;
  for (int k = 0; k < 3 && !found; ++k) {
    const Eigen::Vector3d& p = c[(k + 1) % 3];
    const Eigen::Vector3d& q = c[(k + 2) % 3];
    if ((p - c[k]).dot(q - c[k]) <= 0) {  // right or obtuse at corner k: the opposite edge is a diameter
      smallest = 0.5 * (p + q);
      found = true;
    }
  }
  const Eigen::Vector3d ab = c[1] - c[0], ac = c[2] - c[0];
  const Eigen::Vector3d n = ab.cross(ac);
  const double nn = n.squaredNorm();
  if (!found && nn > 0) {  // acute: the circumcenter
    smallest = c[0] + (ac.squaredNorm() * n.cross(ab) + ab.squaredNorm() * ac.cross(n)) / (2 * nn);
  }
  const double smallest_radius = reachFrom(c, smallest);
  if (smallest_radius < radius) center = smallest, radius = smallest_radius;
  Eigen::Vector4d sphere;
  sphere << center, radius;
  return sphere;
}

// Triangles per Bvh leaf, at most. With one, the 2n - 1 nodes were most of the model next to the lists; the
// queries split a leaf of several into its triangles wherever they would have split an inner node, so the
// levels below a leaf cost no pruning. The median split makes leaves of between half this and this many
// triangles, depending on n: 6 gives leaves of 3 to 6, where 8 gave some meshes leaves of 7 and 8, whose
// splitting into single triangles cost far-apart queries more than the nodes of 4 it replaced. (Where
// buildBvh takes its surface-area split instead, among triangles of very uneven sizes, a leaf may hold
// fewer: a huge triangle gets a leaf of its own near the root.)
constexpr int kBvhLeafTriangles = 6;

// MeshModel::node_spine_radii. A vertex's offset from the spine line is measured from the box's center, the
// rounding of which, and of the projection, the upward margin covers many times over; a float rounded
// upward keeps it a bound. Each vertex is read once per level of the tree above it: O(n log n).
std::vector<float> nodeSpineRadii(const TriangleMesh& mesh, const Bvh& bvh) {
  std::vector<float> radii(bvh.nodes.size());
  tbb::parallel_for(tbb::blocked_range<std::size_t>(0, bvh.nodes.size(), 256),
                    [&](const tbb::blocked_range<std::size_t>& range) {
                      for (std::size_t n = range.begin(); n < range.end(); ++n) {
                        const BvhNode& node = bvh.nodes[n];
                        int longest;
                        node.obb_half.maxCoeff(&longest);
                        const Eigen::Vector3d axis = node.obb_axes.col(longest);
                        double squared = 0;
                        for (int k = node.subtree_first; k < node.subtree_first + node.subtree_count; ++k) {
                          for (int index : mesh.triangles[std::size_t(bvh.triangle_ids[std::size_t(k)])]) {
                            const Eigen::Vector3d offset = mesh.vertices[std::size_t(index)] - node.obb_center;
                            squared = std::max(squared, (offset - offset.dot(axis) * axis).squaredNorm());
                          }
                        }
                        const double margin = 1e-12 * (node.obb_center.cwiseAbs().sum() + node.obb_half.sum());
                        radii[n] = detail::floatAbove(std::sqrt(squared) * (1 + 1e-12) + margin);
                      }
                    });
  return radii;
}

}  // namespace

MeshModel makeMeshModel(TriangleMesh mesh) {
  validateMesh(mesh);
  MeshModel model;
  model.mesh = std::move(mesh);
  // A mesh read from a file grew by push_back: up to half of its capacity is slack.
  model.mesh.vertices.shrink_to_fit();
  model.mesh.triangles.shrink_to_fit();
  model.bvh = buildBvh(model.mesh, kBvhLeafTriangles);
  const std::size_t count = model.bvh.triangle_ids.size();
  TriangleCorners& corners = model.corners;
  corners.in_leaf_order.resize(count);
  corners.leaf_position.resize(count);
  for (std::size_t n = 0; n < count; ++n) {
    const int t = model.bvh.triangle_ids[n];
    corners.leaf_position[std::size_t(t)] = std::int32_t(n);
    for (int k = 0; k < 3; ++k)
      corners.in_leaf_order[n][k] = model.mesh.vertices[model.mesh.triangles[std::size_t(t)][k]];
  }
  model.spheres.resize(count);
  model.planes.resize(count);
  for (std::size_t t = 0; t < count; ++t) {
    const auto& c = corners[t];
    model.spheres[t] = boundingSphere(c);
    // The query prunes a pair when the plane puts the other triangle beyond the best distance so far: a
    // normal off by an angle a moves that bound by a times the corners' offsets. The plain cross product of
    // a sliver is off by about eps / sin(angle), enough to prune the closest pair of a triangle whose
    // height is 1e-10 of its length; the accurate one is off by a few eps.
    const Eigen::Vector3d normal = detail::accurateNormal(c.data());
    const double length = normal.norm();
    // Thinner than this (height 1e-12 of the longest edge) it gets no plane: its pairs go without that bound.
    const double longest_edge = std::sqrt(std::max({(c[1] - c[0]).squaredNorm(), (c[2] - c[1]).squaredNorm(),
                                                    (c[0] - c[2]).squaredNorm()}));
    if (length > 1e-12 * longest_edge * longest_edge && length > 0) {
      const Eigen::Vector3d unit = normal / length;
      model.planes[t] << unit, unit.dot(c[0]);
    } else {
      model.planes[t].setZero();
    }
  }
  model.spines.resize(count);
  for (std::size_t t = 0; t < count; ++t) model.spines[t] = detail::spineCode(corners[t].data());
  model.leaf_spheres.resize(count);
  model.leaf_planes.resize(count);
  for (std::size_t n = 0; n < count; ++n) {
    const int t = model.bvh.triangle_ids[n];
    model.leaf_spheres[n] = model.spheres[t];
    model.leaf_planes[n] = model.planes[t];
  }
  model.compact_nodes.resize(model.bvh.nodes.size());
  for (std::size_t n = 0; n < model.bvh.nodes.size(); ++n) {
    const BvhNode& node = model.bvh.nodes[n];
    CompactBvhNode& compact = model.compact_nodes[n];
    for (int axis = 0; axis < 3; ++axis) {
      compact.min[axis] = node.box_min[axis];
      compact.max[axis] = node.box_max[axis];
    }
    compact.first = node.first;
    compact.count = node.count;
  }
  model.node_spine_radii = nodeSpineRadii(model.mesh, model.bvh);
  model.bounds = boundingBox(model.mesh);
  return model;
}

}  // namespace cfl
