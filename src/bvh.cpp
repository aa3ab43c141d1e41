#include "cfl/bvh.h"

#include "detail/bvh_build.h"
#include "detail/float_rounding.h"

#include <Eigen/Eigenvalues>

#include <algorithm>
#include <cmath>
#include <limits>
#include <numeric>

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_invoke.h>

namespace cfl {
namespace {

// A center for a small sphere holding the points `forEachPoint` visits, starting from `start`: 24 steps of
// Badoiu and Clarkson's iteration (towards the farthest point by 1 / (i + 1)) on the points extreme along 13
// directions (axes, face and space diagonals), which nearly always carry the smallest sphere's support. The
// query's node bounds lose the node's radius, so radius is query time, worth a longer Bvh build than the
// sphere about the box's center takes. Any center gives a true sphere: the caller sizes it on every point.
template <class ForEachPoint>
Eigen::Vector3d enclosingCenter(const ForEachPoint& forEachPoint, const Eigen::Vector3d& start) {
  static const Eigen::Vector3d kDirections[13] = {
      {1, 0, 0}, {0, 1, 0}, {0, 0, 1}, {1, 1, 0}, {1, -1, 0}, {1, 0, 1}, {1, 0, -1},
      {0, 1, 1}, {0, 1, -1}, {1, 1, 1}, {1, 1, -1}, {1, -1, 1}, {-1, 1, 1}};
  Eigen::Vector3d extremes[26];
  double low[13], high[13];
  std::fill(low, low + 13, std::numeric_limits<double>::infinity());
  std::fill(high, high + 13, -std::numeric_limits<double>::infinity());
  forEachPoint([&](const Eigen::Vector3d& p) {
    for (int d = 0; d < 13; ++d) {
      const double x = kDirections[d].dot(p);
      if (x < low[d]) low[d] = x, extremes[2 * d] = p;
      if (x > high[d]) high[d] = x, extremes[2 * d + 1] = p;
    }
  });
  // Many directions share an extreme vertex.
  int count = 0;
  for (const Eigen::Vector3d& p : extremes) {
    if (std::find(extremes, extremes + count, p) == extremes + count) extremes[count++] = p;
  }
  auto reachSquared = [&](const Eigen::Vector3d& center, Eigen::Vector3d* farthest) {
    double most = -1;
    for (int n = 0; n < count; ++n) {
      const Eigen::Vector3d& p = extremes[n];
      const double d2 = (p - center).squaredNorm();
      if (d2 > most) most = d2, *farthest = p;
    }
    return most;
  };
  Eigen::Vector3d center = start, best = start;
  double best_reach = std::numeric_limits<double>::infinity();
  for (int i = 1; i <= 24; ++i) {
    Eigen::Vector3d farthest = center;  // stays put if every distance is NaN
    const double reach = reachSquared(center, &farthest);
    if (reach < best_reach) best_reach = reach, best = center;
    center += (farthest - center) / double(i + 1);
  }
  return best;
}

// Split choice. The median split by count keeps the tree balanced, which is right where the triangles are
// of a size; where a few huge triangles lie among many tiny ones, it pairs them with runs of tiny ones, so
// that every node down to the huge triangles' leaves has their size, and a query meets them only after a
// dozen levels of loose bounds. A binned surface-area cost (each side's box area times its triangle count,
// the expected work of a query meeting a node in proportion to its size) isolates such triangles near the
// root; it replaces the median only where it is much cheaper, so that meshes of even triangles keep their
// balanced trees.
constexpr int kSahBins = 16;
// The binned split is taken where its cost is below this fraction of the median split's.
constexpr double kSahGain = 0.5;
// ... and only above this depth. Each binned split may peel off as little as one triangle (triangles each
// much larger than all the smaller ones together), while a median split halves the count: below this depth
// a tree of up to 2^31 triangles has at most 32 more levels, within Bvh::kMaxDepth.
constexpr int kSahDeepest = Bvh::kMaxDepth - 32;

double surfaceArea(const Aabb& box) {
  if (box.empty()) return 0;
  const Eigen::Vector3d size = box.size();
  return size[0] * size[1] + size[1] * size[2] + size[2] * size[0];
}

// The bin of a centroid coordinate `x` along `axis` of `centroid_box` (whose extent there is positive):
// the binning and the partition that follows it must compute it the same way. Clamped in double before
// the conversion: near the largest doubles the extent overflows and the position comes out infinite or NaN
// (NaN goes to bin 0; with every centroid in one bin the median split is taken).
int binOf(double x, const Aabb& centroid_box, int axis) {
  const double extent = centroid_box.max[axis] - centroid_box.min[axis];
  const double position = (x - centroid_box.min[axis]) * (kSahBins / extent);
  if (!(position > 0)) return 0;
  return position < kSahBins - 1 ? static_cast<int>(position) : kSahBins - 1;
}

struct SahSplit {
  int axis = -1;  // -1: no split with both sides non-empty
  int bin = 0;    // triangles whose centroid's bin is below this go left
  double cost = std::numeric_limits<double>::infinity();
};

// The cheapest split, by the cost above, between kSahBins bins of the centroids along any axis of
// `centroid_box` (one pass over the triangles bins them along all three).
SahSplit bestBinnedSplit(const std::int32_t* ids, int count, const std::vector<Eigen::Vector3d>& centroids,
                         const std::vector<Aabb>& triangle_boxes, const Aabb& centroid_box) {
  bool splits[3];
  for (int axis = 0; axis < 3; ++axis) splits[axis] = centroid_box.max[axis] > centroid_box.min[axis];
  Aabb boxes[3][kSahBins];
  int counts[3][kSahBins] = {};
  for (int i = 0; i < count; ++i) {
    const int t = ids[i];
    for (int axis = 0; axis < 3; ++axis) {
      if (!splits[axis]) continue;
      const int bin = binOf(centroids[t][axis], centroid_box, axis);
      boxes[axis][bin].extend(triangle_boxes[t]);
      ++counts[axis][bin];
    }
  }
  SahSplit best;
  for (int axis = 0; axis < 3; ++axis) {
    if (!splits[axis]) continue;
    // right_cost[b]: the cost of bins [b, kSahBins) as one side.
    double right_cost[kSahBins];
    int right_count[kSahBins];
    Aabb right;
    int right_total = 0;
    for (int b = kSahBins - 1; b > 0; --b) {
      if (counts[axis][b] > 0) right.extend(boxes[axis][b]);
      right_total += counts[axis][b];
      right_cost[b] = surfaceArea(right) * right_total;
      right_count[b] = right_total;
    }
    Aabb left;
    int left_total = 0;
    for (int b = 1; b < kSahBins; ++b) {
      if (counts[axis][b - 1] > 0) left.extend(boxes[axis][b - 1]);
      left_total += counts[axis][b - 1];
      if (left_total == 0 || right_count[b] == 0) continue;
      const double cost = surfaceArea(left) * left_total + right_cost[b];
      if (cost < best.cost) best.axis = axis, best.bin = b, best.cost = cost;
    }
  }
  return best;
}

// The cost, as bestBinnedSplit counts it, of splitting `ids` after its first `middle` entries.
double medianSplitCost(const std::int32_t* ids, int count, int middle, const std::vector<Aabb>& triangle_boxes) {
  Aabb left, right;
  for (int i = 0; i < middle; ++i) left.extend(triangle_boxes[ids[i]]);
  for (int i = middle; i < count; ++i) {
    right.extend(triangle_boxes[ids[i]]);
  }
  return surfaceArea(left) * middle + surfaceArea(right) * (count - middle);
}

}  // namespace

namespace {

// Builds the nodes of one range of Bvh::triangle_ids. Sibling ranges touch disjoint parts of `ids`, so their
// subtrees may be built at once.
struct BvhBuilder {
  const TriangleMesh& mesh;
  int max_leaf_size;
  std::vector<std::int32_t>& ids;
  const std::vector<Eigen::Vector3d>& centroids;
  const std::vector<Aabb>& triangle_boxes;

  // Fills `node`'s bounds for ids[begin, end) and reorders that range for its split; returns the split
  // position, or -1 after making `node` a leaf.
  int fillNode(BvhNode& node, int begin, int end, int depth) const {
    Aabb box, centroid_box;
    for (int i = begin; i < end; ++i) {
      const int t = ids[i];
      for (int index : mesh.triangles[t]) box.extend(mesh.vertices[index]);
      centroid_box.extend(centroids[t]);
    }
    // The sphere is centered on the box but sized by the actual vertices: tighter than the box's
    // circumsphere, and the query's lower bounds scale with it. The same pass gathers the scatter matrix
    // of the oriented box: principal axes of the vertices (duplicates counted, which is harmless: any
    // orthonormal axes give a true box, these just tend to give a tight one).
    const Eigen::Vector3d center = box.center();
    // The scatter is gathered in units of a power of two near the node's extent: squared offsets of
    // triangles around 1e-200 units would underflow to denormals, on which the solver returns zero
    // eigenvectors, and a power of two scales exactly, so ordinary meshes get the same axes bit for bit.
    int extent_exponent = 0;
    const double extent = box.size().maxCoeff();
    if (extent > 0 && std::isfinite(extent)) std::frexp(extent, &extent_exponent);
    const double scatter_unit = std::ldexp(1.0, -std::clamp(extent_exponent, -1000, 1000));
    double radius_squared = 0;
    Eigen::Matrix3d scatter = Eigen::Matrix3d::Zero();
    for (int i = begin; i < end; ++i) {
      for (int index : mesh.triangles[ids[i]]) {
        const Eigen::Vector3d offset = mesh.vertices[index] - center;
        radius_squared = std::max(radius_squared, offset.squaredNorm());
        const Eigen::Vector3d scaled = scatter_unit * offset;
        scatter += scaled * scaled.transpose();
      }
    }
    Eigen::Matrix3d axes = Eigen::Matrix3d::Identity();
    if (scatter.allFinite()) {
      const Eigen::SelfAdjointEigenSolver<Eigen::Matrix3d> solver(scatter);
      // Re-orthonormalized so that the box stays a true bound whatever the solver's rounding; a first
      // column far from unit length (the solver failing quietly) keeps the identity.
      if (solver.info() == Eigen::Success && solver.eigenvectors().allFinite() &&
          solver.eigenvectors().col(0).norm() > 0.5) {
        const Eigen::Vector3d first = solver.eigenvectors().col(0).normalized();
        Eigen::Vector3d second = solver.eigenvectors().col(1) - first * first.dot(solver.eigenvectors().col(1));
        if (first.allFinite() && second.norm() > 0.5) {
          second.normalize();
          axes.col(0) = first;
          axes.col(1) = second;
          axes.col(2) = first.cross(second);
        }
      }
    }
    Eigen::Vector3d low = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity()), high = -low;
    for (int i = begin; i < end; ++i) {
      for (int index : mesh.triangles[ids[i]]) {
        const Eigen::Vector3d projection = axes.transpose() * mesh.vertices[index];
        low = low.cwiseMin(projection);
        high = high.cwiseMax(projection);
      }
    }
    {
      for (int axis = 0; axis < 3; ++axis) {
        node.box_min[axis] = detail::floatBelow(box.min[axis]);
        node.box_max[axis] = detail::floatAbove(box.max[axis]);
      }
      node.center = center;
      node.radius = std::sqrt(radius_squared);
      auto forEachVertex = [&](const auto& visit) {
        for (int i = begin; i < end; ++i) {
          for (int index : mesh.triangles[ids[i]]) visit(mesh.vertices[index]);
        }
      };
      const Eigen::Vector3d refined = enclosingCenter(forEachVertex, center);
      double refined_squared = 0;
      forEachVertex(
          [&](const Eigen::Vector3d& p) { refined_squared = std::max(refined_squared, (p - refined).squaredNorm()); });
      if (refined_squared < radius_squared) {
        node.center = refined;
        node.radius = std::sqrt(refined_squared);
      }
      node.obb_axes = axes;
      // Half extents grown by a hair of the node's scale and position, so that rounding in the query's
      // projections (of coordinates that large) never makes the box miss a vertex, flat patches included.
      const Eigen::Vector3d middle = 0.5 * (low + high);
      node.obb_center = axes * middle;
      // Measured without squares, which underflow for nodes of triangles around 1e-160 units and less.
      const double slack = 1e-12 * (center.cwiseAbs().maxCoeff() + extent) + 1e-300;
      node.obb_half = (0.5 * (high - low)).array() + slack;
      node.subtree_first = begin;
      node.subtree_count = end - begin;
    }
    const int count = end - begin;
    if (count <= max_leaf_size) {
      node.first = begin;
      node.count = count;
      return -1;
    }
    int axis = 0;
    centroid_box.size().maxCoeff(&axis);
    int middle = begin + count / 2;
    std::nth_element(ids.begin() + begin, ids.begin() + middle, ids.begin() + end,
                     [&](int x, int y) { return centroids[x][axis] < centroids[y][axis]; });
    const SahSplit sah = depth < kSahDeepest
                             ? bestBinnedSplit(ids.data() + begin, count, centroids, triangle_boxes, centroid_box)
                             : SahSplit{};
    if (sah.axis >= 0 && sah.cost < kSahGain * medianSplitCost(ids.data() + begin, count, count / 2, triangle_boxes)) {
      const auto split = std::partition(ids.begin() + begin, ids.begin() + end, [&](int t) {
        return binOf(centroids[t][sah.axis], centroid_box, sah.axis) < sah.bin;
      });
      middle = static_cast<int>(split - ids.begin());
    }
    return middle;
  }

  // The subtree of ids[begin, end) below nodes[root], which is allocated: the two children of a node are
  // appended side by side, and the left child's subtree is finished before the right child's children are
  // appended (depth first, left first).
  void buildSerial(std::vector<BvhNode>& nodes, int root, int begin, int end, int depth) const {
    struct Range {
      int node, begin, end, depth;
    };
    std::vector<Range> stack{{root, begin, end, depth}};
    while (!stack.empty()) {
      const Range range = stack.back();
      stack.pop_back();
      const int middle = fillNode(nodes[range.node], range.begin, range.end, range.depth);
      if (middle < 0) continue;
      const int left = static_cast<int>(nodes.size());
      nodes.emplace_back();
      nodes.emplace_back();
      nodes[range.node].first = left;
      nodes[range.node].count = 0;
      stack.push_back({left + 1, middle, range.end, range.depth + 1});
      stack.push_back({left, range.begin, middle, range.depth + 1});
    }
  }

  // The subtree of ids[begin, end), its root first, numbered as buildSerial numbers it: the root, its two
  // children, the left child's descendants, then the right child's. Ranges of at least `grain` triangles
  // build their two halves in parallel and splice them.
  std::vector<BvhNode> build(int begin, int end, int depth, int grain) const {
    std::vector<BvhNode> nodes(1);
    if (end - begin < grain) {
      buildSerial(nodes, 0, begin, end, depth);
      return nodes;
    }
    const int middle = fillNode(nodes[0], begin, end, depth);
    if (middle < 0) return nodes;
    std::vector<BvhNode> left, right;
    tbb::parallel_invoke([&] { left = build(begin, middle, depth + 1, grain); },
                         [&] { right = build(middle, end, depth + 1, grain); });
    nodes.reserve(1 + left.size() + right.size());
    nodes[0].first = 1;
    nodes[0].count = 0;
    // Local index i > 0 of the left subtree lands at i + 2, of the right one at i + left.size() + 1.
    auto place = [&](BvhNode node, int shift) {
      if (node.count == 0) node.first += shift;
      nodes.push_back(node);
    };
    place(left[0], 2);
    place(right[0], int(left.size()) + 1);
    for (std::size_t n = 1; n < left.size(); ++n) place(left[n], 2);
    for (std::size_t n = 1; n < right.size(); ++n) place(right[n], int(left.size()) + 1);
    return nodes;
  }
};

}  // namespace

namespace detail {

Bvh buildBvhWithGrain(const TriangleMesh& mesh, int max_leaf_size, int parallel_grain) {
  max_leaf_size = std::max(1, max_leaf_size);
  const int triangle_count = static_cast<int>(mesh.triangles.size());
  Bvh bvh;
  bvh.triangle_ids.resize(triangle_count);
  std::iota(bvh.triangle_ids.begin(), bvh.triangle_ids.end(), 0);
  if (triangle_count == 0) return bvh;

  std::vector<Eigen::Vector3d> centroids(triangle_count);
  std::vector<Aabb> triangle_boxes(triangle_count);
  tbb::parallel_for(tbb::blocked_range<int>(0, triangle_count, 4096), [&](const tbb::blocked_range<int>& r) {
    for (int t = r.begin(); t < r.end(); ++t) {
      const auto& tri = mesh.triangles[t];
      centroids[t] = (mesh.vertices[tri[0]] + mesh.vertices[tri[1]] + mesh.vertices[tri[2]]) / 3.0;
      for (int index : tri) triangle_boxes[t].extend(mesh.vertices[index]);
    }
  });
  const BvhBuilder builder{mesh, max_leaf_size, bvh.triangle_ids, centroids, triangle_boxes};
  if (triangle_count < parallel_grain) {
    bvh.nodes.reserve(2 * triangle_count);  // for leaves of one triangle
    bvh.nodes.emplace_back();
    builder.buildSerial(bvh.nodes, 0, 0, triangle_count, 0);
    bvh.nodes.shrink_to_fit();
  } else {
    bvh.nodes = builder.build(0, triangle_count, 0, std::max(parallel_grain, 2));
  }
  return bvh;
}

}  // namespace detail

Bvh buildBvh(const TriangleMesh& mesh, int max_leaf_size) {
  // Subtrees of fewer triangles than this are built by one thread: large enough that splicing the
  // subtrees' nodes together costs little next to building them.
  constexpr int kParallelGrain = 8192;
  return detail::buildBvhWithGrain(mesh, max_leaf_size, kParallelGrain);
}

}  // namespace cfl
