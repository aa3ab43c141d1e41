#pragma once
// Internal: closest triangle of a MeshModel to a point, through its Bvh.

#include "cfl/mesh_model.h"
#include "cfl/region_tree.h"
#include "cfl/triangle_distance.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

namespace cfl::detail {

// The Bvh walks' fixed stacks hold 128 pending nodes: one per level below the root, and the root.
static_assert(Bvh::kMaxDepth + 1 <= 128, "fixed walk stacks are too small for the Bvh's depth");

/// Squared distance from p to the box (0 inside).
inline double pointBoxSquaredDistance(const Eigen::Vector3d& p, const Aabb& box) {
  const Eigen::Vector3d below = (box.min - p).cwiseMax(0.0);
  const Eigen::Vector3d above = (p - box.max).cwiseMax(0.0);
  return (below + above).squaredNorm();
}

/// pointBoxSquaredDistance(p, node.box()) read straight from the node's float bounds, as scalar sums in a
/// fixed order: the mesh-mesh search bounds every node pair with it, and it is built for a baseline ISA,
/// where Eigen's small vector expressions cost more than the arithmetic.
inline double nodeBoxSquaredDistance(const Eigen::Vector3d& p, const BvhNode& node) {
  double gap[3];
  for (int i = 0; i < 3; ++i) {
    gap[i] = std::max(std::max(double(node.box_min[i]) - p[i], p[i] - double(node.box_max[i])), 0.0);
  }
  return (gap[0] * gap[0] + gap[1] * gap[1]) + gap[2] * gap[2];
}

/// As nearestTriangle, same contract, on MeshModel::compact_nodes (which must match the Bvh) and the
/// corners in leaf order: an eighth of the node memory, one indirection less per triangle. Depth-first,
/// nearer child first; a node popped after the best fell below its bound is skipped. Ties go to the triangle
/// found first (deterministic, but the float boxes may order children unlike nearestTriangle).
inline void nearestTriangleCompact(const MeshModel& model, const Eigen::Vector3d& p, double& best_squared,
                                   int& best_triangle, Eigen::Vector3d* closest = nullptr) {
  const auto& nodes = model.compact_nodes;
  if (nodes.empty()) return;
  const auto boxSquared = [&p](const CompactBvhNode& node) {
    double sum = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double gap =
          std::max(double(node.min[axis]) - p[axis], 0.0) + std::max(p[axis] - double(node.max[axis]), 0.0);
      sum += gap * gap;
    }
    return sum;
  };
  struct Pending {
    double bound;
    int node;
  };
  Pending stack[128];  // one pending sibling per level, as nearestTriangle
  int top = 0;
  stack[top++] = {boxSquared(nodes[0]), 0};
  while (top > 0) {
    const Pending pending = stack[--top];
    if (pending.bound > best_squared) continue;
    const CompactBvhNode& node = nodes[pending.node];
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const auto& c = model.corners.in_leaf_order[i];
        Eigen::Vector3d q;
        const double d = pointTriangleSquaredDistance(p, c[0], c[1], c[2], &q);
        if (d < best_squared) {
          best_squared = d;
          best_triangle = model.bvh.triangle_ids[i];
          if (closest) *closest = q;
        }
      }
      continue;
    }
    const double d_left = boxSquared(nodes[node.first]);
    const double d_right = boxSquared(nodes[node.first + 1]);
    const bool left_first = d_left <= d_right;
    const double d_far = left_first ? d_right : d_left;
    const double d_near = left_first ? d_left : d_right;
    if (d_far <= best_squared) stack[top++] = {d_far, left_first ? node.first + 1 : node.first};
    if (d_near <= best_squared) stack[top++] = {d_near, left_first ? node.first : node.first + 1};
  }
}
/// A kernel computing pointTriangleSquaredDistance from p to four triangles at once, bit for bit (see
/// x86_64_v3::pointTriangleSquaredDistances4 in detail/query_kernels.h), or nullptr: one at a time.
using PointTriangles4 = void (*)(const Eigen::Vector3d& p, const std::array<Eigen::Vector3d, 3>* const triangles[4],
                                 double squared[4], Eigen::Vector3d closest[4]);

/// pointTriangleSquaredDistance of some build (same contract, same bits).
using PointTriangle1 = double (*)(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                  const Eigen::Vector3d& c, Eigen::Vector3d* closest);

/// Exact tests waiting to run four at a time. A scan adds the candidates its bounds let through and runs the
/// batch when four wait or the scan ends; the batch then accepts, in the order they were added, each
/// triangle strictly closer than the best so far, as the scan testing them one by one would. Its bounds meanwhile
/// compare with a best that may be a batch old, which lets through candidates the one-by-one scan would have
/// skipped; those cannot be strictly closer than the best when their turn comes, so the answer, ties
/// included, is the one-by-one scan's. Without a kernel each candidate is tested as it comes.
struct PendingTriangleTests {
  PointTriangles4 four = nullptr;
  /// The one-triangle kernel of the same build as `four` (the same bits as pointTriangleSquaredDistance,
  /// fewer instructions in the x86-64-v3 build), or nullptr: pointTriangleSquaredDistance.
  PointTriangle1 one = nullptr;
  /// A triangle whose test from this point is already done (the point query's hint), or -1, and its result
  /// as the kernels give it: added, it takes its turn in the order as any other, without a kernel lane.
  int known_id = -1;
  double known_squared = 0;
  Eigen::Vector3d known_closest = Eigen::Vector3d::Zero();
  const std::array<Eigen::Vector3d, 3>* triangles[5];
  int ids[5];
  int count = 0;
  int known_slot = -1;

  /// Adds triangle `id` with corners `c`; returns whether the best improved (then best_squared, best_triangle
  /// and *closest are the new best's).
  bool add(const Eigen::Vector3d& p, const std::array<Eigen::Vector3d, 3>& c, int id, double& best_squared,
           int& best_triangle, Eigen::Vector3d* closest) {
    triangles[count] = &c;
    ids[count] = id;
    if (id == known_id) known_slot = count;
    ++count;
    if (four != nullptr && count - (known_slot >= 0) < 4) return false;
    return run(p, best_squared, best_triangle, closest);
  }

  /// Runs the waiting tests; returns whether the best improved.
  bool run(const Eigen::Vector3d& p, double& best_squared, int& best_triangle, Eigen::Vector3d* closest) {
    if (known_slot < 0) return runAll(p, best_squared, best_triangle, closest);
    double squared[5];
    Eigen::Vector3d q[5];
    // The tests to run: every waiting one but the known.
    const std::array<Eigen::Vector3d, 3>* tested[4];
    int slot[4];
    int m = 0;
    for (int k = 0; k < count; ++k) {
      if (k == known_slot) {
        squared[k] = known_squared;
        q[k] = known_closest;
      } else {
        tested[m] = triangles[k];
        slot[m++] = k;
      }
    }
    if (m == 1 || four == nullptr) {
      // One alone costs less in the one-triangle kernel, whose answer is the same.
      for (int j = 0; j < m; ++j) {
        const auto& c = *tested[j];
        squared[slot[j]] = one != nullptr ? one(p, c[0], c[1], c[2], &q[slot[j]])
                                          : pointTriangleSquaredDistance(p, c[0], c[1], c[2], &q[slot[j]]);
      }
    } else if (m > 1) {
      for (int j = m; j < 4; ++j) tested[j] = tested[0];
      double four_squared[4];
      Eigen::Vector3d four_closest[4];
      four(p, tested, four_squared, four_closest);
      for (int j = 0; j < m; ++j) {
        squared[slot[j]] = four_squared[j];
        q[slot[j]] = four_closest[j];
      }
    }
    known_slot = -1;
    return accept(squared, q, best_squared, best_triangle, closest);
  }

  /// run without a known result among the waiting tests.
  bool runAll(const Eigen::Vector3d& p, double& best_squared, int& best_triangle, Eigen::Vector3d* closest) {
    double squared[4];
    Eigen::Vector3d q[4];
    if (count == 1 || four == nullptr) {
      // One alone costs less in the one-triangle kernel, whose answer is the same.
      for (int k = 0; k < count; ++k) {
        const auto& c = *triangles[k];
        squared[k] =
            one != nullptr ? one(p, c[0], c[1], c[2], &q[k]) : pointTriangleSquaredDistance(p, c[0], c[1], c[2], &q[k]);
      }
    } else if (count > 1) {
      for (int k = count; k < 4; ++k) triangles[k] = triangles[0];
      four(p, triangles, squared, q);
    }
    return accept(squared, q, best_squared, best_triangle, closest);
  }

  /// Accepts the `count` waiting results in the order added, each strictly closer than the best so far, and
  /// empties the batch; returns whether the best improved.
  bool accept(const double* squared, const Eigen::Vector3d* q, double& best_squared, int& best_triangle,
              Eigen::Vector3d* closest) {
    bool improved = false;
    for (int k = 0; k < count; ++k) {
      if (squared[k] < best_squared) {
        best_squared = squared[k];
        best_triangle = ids[k];
        if (closest) *closest = q[k];
        improved = true;
      }
    }
    count = 0;
    return improved;
  }
};

/// The triangle of `model` nearest to p (frame M). `best_squared` is an upper bound on entry (infinity, or
/// the squared distance of `best_triangle`, a warm start) and the answer's squared distance on exit.
/// Triangles farther than the entry bound are never reported. Allocation-free; visits nodes nearest-first.
/// `four`: a kernel testing four triangles at once (PointTriangles4), which tests each leaf's triangles
/// in batches and accepts them in order: the same answer, ties included; nullptr tests them one at a time.
inline void nearestTriangle(const MeshModel& model, const Eigen::Vector3d& p, double& best_squared, int& best_triangle,
                            Eigen::Vector3d* closest = nullptr, PointTriangles4 four = nullptr) {
  const auto& nodes = model.bvh.nodes;
  if (nodes.empty()) return;
  // The tree is at most Bvh::kMaxDepth deep and depth-first search keeps at most one pending sibling per
  // level, so 128 entries cannot overflow.
  int stack[128];
  int top = 0;
  if (pointBoxSquaredDistance(p, nodes[0].box()) > best_squared) return;
  stack[top++] = 0;
  while (top > 0) {
    const BvhNode& node = nodes[stack[--top]];
    if (node.isLeaf()) {
      // Without a kernel the tests run one by one as they are added.
      PendingTriangleTests tests;
      tests.four = four;
      for (int i = node.first; i < node.first + node.count; ++i) {
        tests.add(p, model.corners.in_leaf_order[i], model.bvh.triangle_ids[i], best_squared, best_triangle, closest);
      }
      tests.run(p, best_squared, best_triangle, closest);
      continue;
    }
    const double d_left = pointBoxSquaredDistance(p, nodes[node.first].box());
    const double d_right = pointBoxSquaredDistance(p, nodes[node.first + 1].box());
    // Push the farther child first so the nearer one is searched first and tightens the bound.
    const bool left_first = d_left <= d_right;
    const double d_far = left_first ? d_right : d_left;
    const double d_near = left_first ? d_left : d_right;
    if (d_far <= best_squared) stack[top++] = left_first ? node.first + 1 : node.first;
    if (d_near <= best_squared) stack[top++] = left_first ? node.first : node.first + 1;
  }
}

/// A closest feature list as the point query scans it (see RegionTree): entry n is triangle base + low[n],
/// or low[n] | high[n] << 16 when high is set (a wide list); bounds[n] * unit (unit shrunk for rounding)
/// bounds its distance from below, ascending.
struct PointListScan {
  const std::uint16_t* low;
  const std::uint16_t* high;
  std::int32_t base;
  const std::uint8_t* bounds;
  std::uint32_t length;
  double unit;
};

/// One leaf's closest feature list laid out for scanPointListCached: consecutive points of a batch (Morton
/// order) mostly fall in the leaf of the point before, and their scans then read the entries' bounds, spheres
/// and planes as contiguous lanes instead of gathering them by triangle id. Blocks of four entries, each
/// kBlock doubles: the squared entry bounds, then the spheres' x, y, z and radius, then the planes' x, y, z
/// and offset, then for each edge of the triangle (ab, bc, ca) its outward normal in the triangle's plane
/// (unit; for a sliver, in its accurate plane, or without a plane three half-spaces of its own) x, y, z and
/// offset (plus rounding slack), then the plane's rounding slack, four lanes each. The last block is padded with infinite
/// bounds, which end every scan. Blocks are laid out as scans first reach them (`filled` so far): most scans
/// end well before the list does.
struct PointListCache {
  static constexpr int kBlock = 88;
  static constexpr std::uint32_t kNoLeaf = 0xffffffffu;
  std::uint32_t leaf = kNoLeaf;
  PointListScan source{};
  std::uint32_t filled = 0;
  std::vector<double> lanes;
  std::vector<std::int32_t> ids;  // padded as the lanes, with the last entry's id
  /// The region cell of the last point located through this cache, when `located`: the next point, likely in
  /// it too, may skip the tree's descent (see the point query's locateNear).
  RegionCell cell;
  bool located = false;
  /// How far inside `cell` a point must lie to be in it whatever the rounding (see locateNear).
  double margin = 0;
  /// A triangle already tested from the point being queried (its hint), or -1, and that test's result from
  /// the kernels of the scan's build: scans take it instead of testing the triangle again
  /// (PendingTriangleTests::known_id).
  int known_triangle = -1;
  double known_squared = 0;
  Eigen::Vector3d known_closest = Eigen::Vector3d::Zero();
};

/// nearestTriangleCompact with each triangle of a leaf first bounded by its own sphere and plane
/// (MeshModel::leaf_spheres, leaf_planes, which must match the Bvh), as the list scan of the point query
/// bounds its entries: far from the mesh the node boxes are loose and a walk reaches many leaves whose
/// triangles are all beyond the best distance. The bounds only skip triangles that could not be strictly
/// closer than the best, and the walk is the same: same answer, ties included, as nearestTriangleCompact.
/// `four`: the exact tests' kernel (PendingTriangleTests), nullptr for one at a time.
inline void nearestTriangleCompactBounded(const MeshModel& model, const Eigen::Vector3d& p, double& best_squared,
                                          int& best_triangle, Eigen::Vector3d* closest = nullptr,
                                          PointTriangles4 four = nullptr) {
  // Both bounds went through a rounding or two: shrunk by far more than their error before they may prune.
  constexpr double kShrink = 1 - 1e-12;
  const auto& nodes = model.compact_nodes;
  if (nodes.empty()) return;
  const auto boxSquared = [&p](const CompactBvhNode& node) {
    double sum = 0;
    for (int axis = 0; axis < 3; ++axis) {
      const double gap =
          std::max(double(node.min[axis]) - p[axis], 0.0) + std::max(p[axis] - double(node.max[axis]), 0.0);
      sum += gap * gap;
    }
    return sum;
  };
  struct Pending {
    double bound;
    int node;
  };
  Pending stack[128];
  int top = 0;
  stack[top++] = {boxSquared(nodes[0]), 0};
  // The best distance unsquared, for the bounds (a square root only when it improves). Infinite entry bounds
  // stay infinite: every bound passes.
  double best = std::sqrt(best_squared);
  // The plane bound's rounding, as in the list scan: the products n . p and the offset round at the scale
  // of the coordinates, and the corners sit off the plane by a few ulps of the triangle's size.
  const double scale = p.cwiseAbs().sum();
  PendingTriangleTests tests;
  tests.four = four;
  while (top > 0) {
    const Pending pending = stack[--top];
    if (pending.bound > best_squared) continue;
    const CompactBvhNode& node = nodes[pending.node];
    if (node.count > 0) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const Eigen::Vector4d& sphere = model.leaf_spheres[i];
        const double reach_squared = (p - sphere.head<3>()).squaredNorm();
        const double rim = sphere[3] + best;
        if (reach_squared * kShrink >= rim * rim) continue;
        const Eigen::Vector4d& plane = model.leaf_planes[i];
        const double height = std::abs(plane.head<3>().dot(p) - plane[3]) -
                              1e-13 * (scale + std::abs(plane[3]) + sphere[3]);
        if (height * kShrink >= best) continue;
        if (tests.add(p, model.corners.in_leaf_order[i], model.bvh.triangle_ids[i], best_squared, best_triangle,
                      closest)) {
          best = std::sqrt(best_squared);
        }
      }
      // The batch runs before the walk goes on: the nodes' bounds compare with the best.
      if (tests.run(p, best_squared, best_triangle, closest)) best = std::sqrt(best_squared);
      continue;
    }
    const double d_left = boxSquared(nodes[node.first]);
    const double d_right = boxSquared(nodes[node.first + 1]);
    const bool left_first = d_left <= d_right;
    const double d_far = left_first ? d_right : d_left;
    const double d_near = left_first ? d_left : d_right;
    if (d_far <= best_squared) stack[top++] = {d_far, left_first ? node.first + 1 : node.first};
    if (d_near <= best_squared) stack[top++] = {d_near, left_first ? node.first : node.first + 1};
  }
}
}  // namespace cfl::detail
