// Point-mesh distance, unsigned or signed (point_query.h).

#include "cfl/point_query.h"

#include "cfl/batch_query.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/triangle_distance.h"
#include "detail/exact_arithmetic.h"
#include "detail/nearest_triangle.h"
#include "detail/parallel_chunks.h"
#include "detail/query_kernels.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <limits>
#include <memory>
#include <sstream>
#include <string>
#include <utility>
#include <vector>

namespace cfl {
namespace {

// The list scan compares lower bounds with the best distance so far; both went through a rounding or two, so
// a bound is shrunk by far more than their error before it may end the scan.
constexpr double kBoundShrink = 1 - 1e-12;

inline void prefetch([[maybe_unused]] const void* address) {
#if defined(__GNUC__)
  __builtin_prefetch(address);
#endif
}
inline void prefetchForWrite([[maybe_unused]] const void* address) {
#if defined(__GNUC__)
  __builtin_prefetch(address, 1);
#endif
}

// A batch too small to sort (spatialOrder) queries points in the caller's order, whose leaves may be
// scattered over arrays of many megabytes (the rock's lists: 18 MB), and each query's first reads form a
// chain of cache misses: leaf -> list index -> list offset -> the list's ids and entry bounds. The batch
// walks that chain for the points a few places ahead, one link per stage, with prefetches, so that a query
// finds them cached. It only reads the model: results do not change.
class LeafPrefetcher {
 public:
  static constexpr std::ptrdiff_t kStep = 4;  // points between two stages of one point
  static constexpr std::ptrdiff_t kAhead = 3 * kStep;

  LeafPrefetcher(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d* points_W)
      : regions_(model.regions), X_MW_(X_WM.inverse(Eigen::Isometry)), points_W_(points_W) {
    const Aabb box = regions_.bounds();
    min_ = box.min;
    max_ = box.max;
    usable_ = !regions_.nodes.empty();
  }

  // Before querying point i of [begin, end): stage 1 for i + 3 kStep, 2 for i + 2 kStep, 3 for i + kStep.
  void advance(std::ptrdiff_t i, std::ptrdiff_t end) {
    if (!usable_) return;
    if (i + kAhead < end) locateAhead(i + kAhead);
    if (i + 2 * kStep < end && i + 2 * kStep >= begin_) {
      const std::uint32_t leaf = slot(i + 2 * kStep);
      if (leaf != kNone) {
        const std::uint32_t list = regions_.leaf_list[leaf];
        if (list != RegionTree::kNoList) prefetch(&regions_.list_offsets[list]);
        else prefetch(&regions_.leaf_corner_distance[leaf]);
      }
    }
    if (i + kStep < end && i + kStep >= begin_) {
      const std::uint32_t leaf = slot(i + kStep);
      if (leaf != kNone && regions_.leaf_list[leaf] != RegionTree::kNoList) {
        const std::uint32_t list = regions_.leaf_list[leaf];
        prefetch(regions_.list_entry_ids.data() + regions_.listIdsBegin(list));
        prefetch(regions_.list_entry_bounds.data() + regions_.list_offsets[list]);
      }
    }
  }

  // Fills the pipeline for a range starting at begin.
  void start(std::ptrdiff_t begin, std::ptrdiff_t end) {
    begin_ = begin;
    for (std::ptrdiff_t i = begin - kAhead; i < begin; ++i) advance(i, end);
  }

 private:
  static constexpr std::uint32_t kNone = 0xffffffffu;
  std::uint32_t& slot(std::ptrdiff_t j) { return ring_[std::size_t(j) % kRing]; }
  void locateAhead(std::ptrdiff_t j) {
    std::uint32_t& leaf = slot(j);
    leaf = kNone;
    if (j < begin_) return;
    const Eigen::Vector3d p_M = X_MW_ * points_W_[j];
    if (!((p_M.array() >= min_.array()).all() && (p_M.array() <= max_.array()).all())) return;
    leaf = regions_.locate(p_M).leaf;
    prefetch(&regions_.leaf_list[leaf]);
    prefetch(&regions_.leaf_lower_bound[leaf]);
  }

  static constexpr std::size_t kRing = 16;  // > kAhead, a power of two
  const RegionTree& regions_;
  Eigen::Isometry3d X_MW_;
  const Eigen::Vector3d* points_W_;
  Eigen::Vector3d min_, max_;
  bool usable_ = false;
  std::ptrdiff_t begin_ = 0;
  std::uint32_t ring_[kRing];
};

// The bits 0..9 of v spread to bits 0, 3, ..., 27.
constexpr std::uint32_t spreadBits(std::uint32_t v) {
  v &= 0x3ffu;
  v = (v | v << 16) & 0x030000ffu;
  v = (v | v << 8) & 0x0300f00fu;
  v = (v | v << 4) & 0x030c30c3u;
  v = (v | v << 2) & 0x09249249u;
  return v;
}

// spreadBits of every 10-bit value: a load per axis instead of the shifts and masks, for every point of a batch.
constexpr std::array<std::uint32_t, 1024> kSpreadBits = [] {
  std::array<std::uint32_t, 1024> table{};
  for (std::uint32_t v = 0; v < 1024; ++v) table[v] = spreadBits(v);
  return table;
}();

// Callers' points come in any order, often random: consecutive queries then touch unrelated leaves, lists
// and triangles, each a cache miss in arrays of many megabytes. Queried along a Morton curve (10 bits per
// axis over the regions' box, where the lists are; points outside share its border cells), neighbours in
// the walk are neighbours in space and mostly read what the previous query left in cache.
// Returns the point indices in that order (an LSD radix sort, three passes of 10 bits: linear, stable, so
// the order is deterministic), or nothing when the batch is too small or too large to index in 32 bits.
// forEachBlock(body) calls body(begin, end) over blocks covering [0, count), on the batch's threads: the
// keys, the part of the sort that costs arithmetic, are computed there. The arrays are left uninitialized
// (every element is written before it is read): zeroing them cost as much as a pass.
template <class ForEachBlock>
std::unique_ptr<std::uint32_t[]> spatialOrder(const CflModel& model, const Eigen::Isometry3d& X_WM,
                                              const Eigen::Vector3d* points_W, std::size_t count,
                                              ForEachBlock&& forEachBlock) {
  constexpr std::size_t kMinimum = 256;  // a few leaves' worth: little to share, and the histograms' fixed cost
  if (count < kMinimum || count > std::size_t(std::numeric_limits<std::uint32_t>::max())) return {};
  const Aabb box = model.regions.nodes.empty() ? model.geometry.bounds : model.regions.bounds();
  const double extent = std::max(box.size().maxCoeff(), std::numeric_limits<double>::min());
  const Eigen::Vector3d low = box.min;
  const double scale = 1024 / extent;
  const Eigen::Isometry3d X_MW = X_WM.inverse(Eigen::Isometry);
  // (key << 32 | index): one 8-byte word per point moves in each pass.
  std::unique_ptr<std::uint64_t[]> items(new std::uint64_t[count]), scratch(new std::uint64_t[count]);
  forEachBlock([&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i != end; ++i) {
      const Eigen::Vector3d q = (X_MW * points_W[i] - low) * scale;
      std::uint32_t cell[3];
      for (int axis = 0; axis < 3; ++axis) cell[axis] = std::uint32_t(std::clamp(q[axis], 0.0, 1023.0));
      const std::uint32_t key = kSpreadBits[cell[0]] | kSpreadBits[cell[1]] << 1 | kSpreadBits[cell[2]] << 2;
      items[i] = std::uint64_t(key) << 32 | i;
    }
  });
  std::array<std::array<std::uint32_t, 1024>, 3> histogram{};
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint64_t item = items[i];
    for (int pass = 0; pass < 3; ++pass) ++histogram[pass][(item >> (32 + 10 * pass)) & 0x3ffu];
  }
  for (int pass = 0; pass < 3; ++pass) {
    std::uint32_t sum = 0;
    for (std::uint32_t& bucket : histogram[pass]) sum += std::exchange(bucket, sum);
  }
  for (int pass = 0; pass < 2; ++pass) {
    const int shift = 32 + 10 * pass;
    for (std::size_t i = 0; i < count; ++i) {
      const std::uint64_t item = items[i];
      scratch[histogram[pass][(item >> shift) & 0x3ffu]++] = item;
    }
    items.swap(scratch);
  }
  // The last pass places the indices alone.
  std::unique_ptr<std::uint32_t[]> order(new std::uint32_t[count]);
  for (std::size_t i = 0; i < count; ++i) {
    const std::uint64_t item = items[i];
    order[histogram[2][(item >> 52) & 0x3ffu]++] = std::uint32_t(item);
  }
  return order;
}

// The Bvh walk: on the compact nodes when the model has them (makeMeshModel builds them; a MeshModel put
// together by hand may not).
void nearestTriangleFast(const MeshModel& geometry, const Eigen::Vector3d& p, double& best_squared, int& best_triangle,
                         Eigen::Vector3d* closest, const detail::QueryKernelTable& kernels) {
  const std::size_t leaves = geometry.bvh.triangle_ids.size();
  if (geometry.compact_nodes.size() == geometry.bvh.nodes.size() && geometry.corners.in_leaf_order.size() == leaves &&
      geometry.leaf_spheres.size() == leaves && geometry.leaf_planes.size() == leaves) {
    if (kernels.nearest_triangle_bounded != nullptr) {
      kernels.nearest_triangle_bounded(geometry, p, best_squared, best_triangle, closest);
      return;
    }
    detail::nearestTriangleCompactBounded(geometry, p, best_squared, best_triangle, closest, kernels.point_triangles4);
  } else if (geometry.compact_nodes.size() == geometry.bvh.nodes.size() &&
             geometry.corners.in_leaf_order.size() == leaves) {
    detail::nearestTriangleCompact(geometry, p, best_squared, best_triangle, closest);
  } else {
    detail::nearestTriangle(geometry, p, best_squared, best_triangle, closest);
  }
}

// Whether p_M lies inside the cache's located cell by more than its margin (see locateNear).
inline bool insideCachedCell(const detail::PointListCache& cache, const Eigen::Vector3d& p_M) {
  const RegionCell& cell = cache.cell;
  return ((p_M - cell.min_corner).array() > cache.margin).all() &&
         ((cell.min_corner.array() + cell.size) - p_M.array() > cache.margin).all();
}

// regions.locate(p_M), through the cell the cache's last point was in when p_M lies inside that cell by more
// than a margin: locate's fixed point and the cell's corner round at about 1e-16 of the coordinates' scale
// (the grid's extent plus its offset from the origin), so such a point descends to that very cell, and
// consecutive points of a batch mostly do. Points nearer a face take the descent.
RegionCell locateNear(const RegionTree& regions, const Eigen::Vector3d& p_M, detail::PointListCache* cache) {
  if (cache == nullptr) return regions.locate(p_M);
  if (cache->located && insideCachedCell(*cache, p_M)) return cache->cell;
  cache->cell = regions.locate(p_M);
  cache->located = true;
  const int widest = std::max({regions.root_dims[0], regions.root_dims[1], regions.root_dims[2]});
  cache->margin = 1e-12 * (regions.root_size * double(widest) + regions.origin.cwiseAbs().maxCoeff());
  return cache->cell;
}

// The closest triangle to p_M strictly within sqrt(best_squared) (the entry value), through the point's leaf
// when it lies in the regions and has a list, else through the Bvh. best_triangle stays -1 when there is none.
// `hint_triangle`: a triangle likely to be nearly as close as the closest (a nearby point's), or -1.
void searchNearest(const CflModel& model, const Eigen::Vector3d& p_M, double& best_squared, int& best_triangle,
                   Eigen::Vector3d& closest, const detail::QueryKernelTable& kernels, detail::PointListCache* cache,
                   int hint_triangle = -1) {
  const RegionTree& regions = model.regions;
  if (kernels.scan_point_list_cached != nullptr && cache != nullptr && cache->located &&
      cache->leaf == cache->cell.leaf && insideCachedCell(*cache, p_M)) {
    // The point lies in the leaf whose list the cache holds laid out (it has a list, not empty): what the
    // path below does for it, without finding the cell and the list again.
    const double leaf_bound = double(regions.leaf_lower_bound[cache->leaf]) * kBoundShrink;
    if (leaf_bound * leaf_bound >= best_squared && leaf_bound > 0) return;
    kernels.scan_point_list_cached(p_M, *cache, model.geometry, best_squared, best_triangle, closest);
    return;
  }
  const Aabb box = regions.bounds();
  const bool inside = !regions.nodes.empty() && (p_M.array() >= box.min.array()).all() &&
                      (p_M.array() <= box.max.array()).all();
  if (inside) {
    const RegionCell cell = locateNear(regions, p_M, cache);
    if (regions.hasList(cell.leaf)) {
      // No point of the leaf is closer to the mesh than its lower bound.
      const double leaf_bound = double(regions.leaf_lower_bound[cell.leaf]) * kBoundShrink;
      if (leaf_bound * leaf_bound >= best_squared && leaf_bound > 0) return;
      const std::uint32_t list = regions.leaf_list[cell.leaf];
      const std::uint32_t length = regions.listLength(list);
      const std::uint8_t* bounds = regions.listBoundsBegin(cell.leaf);
      const double unit = regions.entryBoundUnit(cell.depth) * kBoundShrink;
      if (kernels.scan_point_list_cached != nullptr && cache != nullptr && length > 0) {
        if (cache->leaf != cell.leaf) {
          // A new leaf: its list's blocks are laid out as scans reach them.
          const std::int32_t base = regions.listBase(list);
          const std::uint16_t* low = regions.list_entry_ids.data() + regions.listIdsBegin(list) + 2;
          cache->source = {low, base >= 0 ? nullptr : regions.list_high_ids.data() + std::uint32_t(~base), base, bounds,
                           length, unit};
          cache->leaf = cell.leaf;
          cache->filled = 0;
          const std::size_t blocks = (length + 3) / 4;
          if (cache->ids.size() < 4 * blocks) {
            cache->ids.resize(4 * blocks);
            cache->lanes.resize(blocks * detail::PointListCache::kBlock);
          }
        }
        kernels.scan_point_list_cached(p_M, *cache, model.geometry, best_squared, best_triangle, closest);
        return;
      }
      if (kernels.scan_point_list != nullptr) {
        // The kernels' scan (x86-64-v3: the same bounds four entries at a time), the same answer as below.
        const std::int32_t base = regions.listBase(list);
        const std::uint16_t* low = regions.list_entry_ids.data() + regions.listIdsBegin(list) + 2;
        const detail::PointListScan scan{low, base >= 0 ? nullptr : regions.list_high_ids.data() + std::uint32_t(~base),
                                         base, bounds, length, unit};
        kernels.scan_point_list(p_M, scan, model.geometry, best_squared, best_triangle, closest);
        return;
      }
      const auto& corners = model.geometry.corners;
      const auto& spheres = model.geometry.spheres;
      const auto& planes = model.geometry.planes;
      // The best distance so far, also unsquared for the per-triangle bounds below (square roots only when
      // it improves, a few times per point).
      double best = std::sqrt(best_squared);
      // The plane bound's rounding: the products n . p and the offset round at the scale of the
      // coordinates, and the corners sit off the plane by a few ulps of the triangle's size.
      const double scale = p_M.cwiseAbs().sum();
      detail::PendingTriangleTests tests;
      tests.four = kernels.point_triangles4;
      if (cache != nullptr) {
        tests.known_id = cache->known_triangle;
        tests.known_squared = cache->known_squared;
        tests.known_closest = cache->known_closest;
      }
      for (std::uint32_t n = 0; n < length; ++n, ++bounds) {
        // Entries are sorted by bound: once one reaches the best distance, none after it can beat it.
        const double bound = double(*bounds) * unit;
        if (bound * bound >= best_squared) break;
        const std::int32_t t = regions.listTriangle(list, n);
        // The triangle's bounding sphere, squared: |p - center| >= radius + best puts it beyond the best.
        const Eigen::Vector4d& sphere = spheres[t];
        const double reach_squared = (p_M - sphere.head<3>()).squaredNorm();
        const double rim = sphere[3] + best;
        if (reach_squared * kBoundShrink >= rim * rim) continue;
        // Its plane (zero for a sliver, which then passes): the distance to the plane bounds the distance
        // to the triangle from below.
        const Eigen::Vector4d& plane = planes[t];
        const double height = std::abs(plane.head<3>().dot(p_M) - plane[3]) -
                              1e-13 * (scale + std::abs(plane[3]) + sphere[3]);
        if (height * kBoundShrink >= best) continue;
        if (tests.add(p_M, corners[t], t, best_squared, best_triangle, &closest)) best = std::sqrt(best_squared);
      }
      tests.run(p_M, best_squared, best_triangle, &closest);
      return;
    }
    // The leaf's corner distances promise a triangle within (corner distance + |p - corner|) of p, distance
    // being 1-Lipschitz. The stored corner distances give upper bounds (RegionTree::cornerDistanceUpper):
    // inflated by far more than the build's float rounding, the promise holds. (Near the surface, where
    // leaves have lists, the first entries' exact tests beat it: the scan above does without.)
    const std::array<std::uint16_t, 8>& corner_distance = regions.leaf_corner_distance[cell.leaf];
    const double corner_unit = regions.cornerDistanceUnit(cell.size);
    double promise = std::numeric_limits<double>::infinity();
    for (int c = 0; c < 8; ++c) {
      const Eigen::Vector3d corner =
          cell.min_corner + cell.size * Eigen::Vector3d(double(c & 1), double((c >> 1) & 1), double(c >> 2));
      promise = std::min(promise, RegionTree::cornerDistanceUpper(corner_distance[c], corner_unit) * (1 + 1e-6) +
                                      (p_M - corner).norm());
    }
    promise *= 1 + 1e-9;
    double seed_squared = promise * promise;
    if (hint_triangle >= 0) {
      // A nearby point's closest triangle is at most a little farther than this point's closest: its exact
      // distance, barely inflated, is a tighter seed than a loose promise (a big leaf far from the mesh).
      // Above the closest distance whenever it is positive, it leaves the walk's answer as it was.
      const auto& c = model.geometry.corners[hint_triangle];
      seed_squared = std::min(seed_squared, pointTriangleSquaredDistance(p_M, c[0], c[1], c[2]) * (1 + 1e-9));
    }
    // No list: the Bvh answers, seeded with the promise, so that the walk skips every node farther (for a
    // point deep inside a solid or far above a flat part, most of the tree).
    if (seed_squared < best_squared) {
      double found_squared = seed_squared;
      int found = -1;
      Eigen::Vector3d q;
      nearestTriangleFast(model.geometry, p_M, found_squared, found, &q, kernels);
      if (found >= 0) {
        best_squared = found_squared;
        best_triangle = found;
        closest = q;
        return;
      }
      // Unreachable unless a corner distance were wrong: the unseeded walk below stays exact regardless.
    }
  }
  nearestTriangleFast(model.geometry, p_M, best_squared, best_triangle, &closest, kernels);
}

// searchNearestFrom's searches, once the hint is known.
void searchSeeded(const CflModel& model, double hint_squared, const Eigen::Vector3d& p_M, double& best_squared,
                  int& best_triangle, Eigen::Vector3d& closest, const detail::QueryKernelTable& kernels,
                  detail::PointListCache* cache, int hint_triangle) {
  const double seed = hint_squared * (1 + 1e-9);
  if (seed > 0 && seed < best_squared) {
    double found_squared = seed;
    int found = -1;
    Eigen::Vector3d q;
    // The seed already holds the hint triangle's distance: no need for the Bvh walk to test it again.
    searchNearest(model, p_M, found_squared, found, q, kernels, cache);
    if (found >= 0) {
      best_squared = found_squared;
      best_triangle = found;
      closest = q;
      return;
    }
  }
  searchNearest(model, p_M, best_squared, best_triangle, closest, kernels, cache, hint_triangle);
}

// searchNearest with a hint: `hint_squared` (or infinity), a bound that is likely to be a little above the
// closest distance, e.g. from the answer for a point nearby (distance being 1-Lipschitz, no more than that
// point's distance plus the step between them). Barely inflated, it bounds a first search, so that fewer
// candidates pass the bounds; the first search finds what the plain one would (the same triangle, ties
// included: either finds the first triangle of its list or walk at the least distance, and a bound above
// that distance leaves that triangle in), unless nothing lies below the bound (rounding put it a hair
// under the closest), and then the plain search runs. `hint_triangle` (or -1): a nearby point's closest
// triangle, whose exact distance tightens the hint.
void searchNearestFrom(const CflModel& model, double hint_squared, const Eigen::Vector3d& p_M, double& best_squared,
                       int& best_triangle, Eigen::Vector3d& closest, const detail::QueryKernelTable& kernels,
                       detail::PointListCache* cache, int hint_triangle) {
  if (hint_triangle >= 0) {
    // The nearby point's closest triangle, at its exact distance from this point, is mostly this point's
    // closest too: a bound at (barely above) the answer from the start, so that the scan stops at the first
    // entry bound reaching the answer and the others' bounds reject more. Its distance is one of those the
    // search minimizes, so the least is no more.
    const auto& c = model.geometry.corners[hint_triangle];
    Eigen::Vector3d q;
    const double d = kernels.point_triangle(p_M, c[0], c[1], c[2], &q);
    hint_squared = std::min(hint_squared, d);
    if (cache != nullptr) {
      // The scans take this result (the kernel of their build's bits) when they reach the triangle.
      cache->known_triangle = hint_triangle;
      cache->known_squared = d;
      cache->known_closest = q;
    }
  }
  searchSeeded(model, hint_squared, p_M, best_squared, best_triangle, closest, kernels, cache, hint_triangle);
  if (cache != nullptr) cache->known_triangle = -1;
}

// Which feature of triangle (a, b, c) holds the point closest to p: 0 the face, 1 + e edge e (corners e and
// e + 1 mod 3), 4 + k vertex k. The Voronoi-region tests of Ericson (Real-Time Collision Detection, 5.1.5):
// p's region decides, so the feature is the one that holds the closest point, as the pseudonormal theorem
// needs; a point within rounding of a region's border gets either side, where p - q is (nearly) normal to
// both features and either pseudonormal signs it.
int closestFeature(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                   const Eigen::Vector3d& c) {
  const Eigen::Vector3d ab = b - a, ac = c - a;
  const Eigen::Vector3d ap = p - a;
  const double d1 = ab.dot(ap), d2 = ac.dot(ap);
  if (d1 <= 0 && d2 <= 0) return 4;
  const Eigen::Vector3d bp = p - b;
  const double d3 = ab.dot(bp), d4 = ac.dot(bp);
  if (d3 >= 0 && d4 <= d3) return 5;
  const double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) return 1;
  const Eigen::Vector3d cp = p - c;
  const double d5 = ab.dot(cp), d6 = ac.dot(cp);
  if (d6 >= 0 && d5 <= d6) return 6;
  const double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) return 3;
  const double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) return 2;
  return 0;
}

Eigen::Vector3d unitNormal(const MeshModel& geometry, int t) {
  // MeshModel::planes holds this very unit normal (the same accurate normal over its length) except for
  // slivers, whose plane is zero.
  if (std::size_t(t) < geometry.planes.size()) {
    const Eigen::Vector4d& plane = geometry.planes[t];
    if (plane[0] != 0 || plane[1] != 0 || plane[2] != 0) return plane.head<3>();
  }
  const Eigen::Vector3d n = detail::accurateNormal(geometry.corners[t].data());
  const double length = n.norm();
  return length > 0 ? Eigen::Vector3d(n / length) : Eigen::Vector3d::Zero();
}

// The outward pseudonormal of the feature of triangle t that holds p's closest point (not normalized).
Eigen::Vector3d pseudonormal(const CflModel& model, int t, const Eigen::Vector3d& p_M) {
  const MeshModel& geometry = model.geometry;
  const MeshSign& sign = model.sign;
  const auto& c = geometry.corners[t];
  const int feature = closestFeature(p_M, c[0], c[1], c[2]);
  const double orientation = sign.closure.orientation;
  if (feature == 0) return orientation * unitNormal(geometry, t);
  if (feature <= 3) {
    const int e = feature - 1;
    const int other = sign.neighbors[t][e];
    Eigen::Vector3d n = unitNormal(geometry, t);
    if (other >= 0) n += unitNormal(geometry, other);
    return orientation * n;
  }
  const int k = feature - 4;
  return sign.vertex_normals[sign.welded_vertex[geometry.mesh.triangles[t][k]]];
}

void validateOptions(const CflModel& model, const PointQueryOptions& options) {
  if (!(options.upper_bound >= 0)) {
    std::ostringstream message;
    message << "PointQueryOptions::upper_bound must be >= 0 (infinity: no bound), got " << options.upper_bound;
    throw Error(message.str());
  }
  if (options.sign_method != SignMethod::kAuto && options.sign_method != SignMethod::kWindingNumber) {
    throw Error("SignMethod value " + std::to_string(static_cast<int>(options.sign_method)) + " names no method");
  }
  if (options.signed_distance && options.sign_method == SignMethod::kAuto && !model.sign.closure.closed) {
    throw Error("cannot sign distances to this mesh: " + model.sign.closure.reason +
                " (SignMethod::kWindingNumber signs any mesh by its generalized winding number)");
  }
  if (options.signed_distance && options.sign_method == SignMethod::kWindingNumber &&
      !model.sign.winding) {
    throw Error("cannot sign distances to this mesh: its MeshSign was not computed (see analyzeMeshSign)");
  }
}

void validatePoint(const Eigen::Vector3d& p_W, const char* what) {
  if (!p_W.allFinite()) {
    std::ostringstream message;
    message << what << " is not finite (" << p_W.x() << ", " << p_W.y() << ", " << p_W.z() << ")";
    throw Error(message.str());
  }
}

// The query proper, once pose, point and options are known to be good. X_MW: X_WM.inverse(Eigen::Isometry),
// computed once per batch. `hint_squared`: see searchNearestFrom.
PointDistance pointDistance(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Isometry3d& X_MW,
                            const Eigen::Vector3d& p_W,
                            const PointQueryOptions& options, const detail::QueryKernelTable& kernels,
                            detail::PointListCache* cache = nullptr,
                            double hint_squared = std::numeric_limits<double>::infinity(), int hint_triangle = -1) {
  const Eigen::Vector3d p_M = X_MW * p_W;
  const double infinity = std::numeric_limits<double>::infinity();
  double best_squared = std::isinf(options.upper_bound) ? infinity : options.upper_bound * options.upper_bound;
  int triangle = -1;
  Eigen::Vector3d closest_M = Eigen::Vector3d::Zero();
  searchNearestFrom(model, hint_squared, p_M, best_squared, triangle, closest_M, kernels, cache, hint_triangle);
  double distance = triangle >= 0 ? std::sqrt(best_squared) : infinity;
  if (triangle >= 0 && !(distance < options.upper_bound)) triangle = -1, distance = infinity;  // rounding at the bound

  PointDistance result;
  if (!options.signed_distance) {
    if (triangle < 0) return result;
    result.distance = distance;
    result.triangle = triangle;
    result.closest_point = X_WM * closest_M;
    // The kernel's distance and closest point round separately: a tiny distance may come with p == q.
    const Eigen::Vector3d offset = p_M - closest_M;
    const double length = offset.norm();
    const Eigen::Vector3d g_M =
        length > 0 ? Eigen::Vector3d(offset / length)
                   : Eigen::Vector3d(model.sign.closure.orientation * unitNormal(model.geometry, triangle));
    result.gradient = X_WM.linear() * g_M;
    return result;
  }

  // Signed. Beyond the bound only the side is wanted: the winding number, or the exact closest feature.
  bool inside = false;
  if (options.sign_method == SignMethod::kWindingNumber) {
    if (distance > 0) inside = model.sign.closure.orientation * windingNumber(model.geometry, model.sign, p_M) >= 0.5;
  } else if (triangle >= 0) {
    inside = distance > 0 && pseudonormal(model, triangle, p_M).dot(p_M - closest_M) < 0;
  } else {
    double any_squared = infinity;
    int any_triangle = -1;
    Eigen::Vector3d any_closest = Eigen::Vector3d::Zero();
    searchNearest(model, p_M, any_squared, any_triangle, any_closest, kernels, cache);
    inside = any_triangle >= 0 && any_squared > 0 && pseudonormal(model, any_triangle, p_M).dot(p_M - any_closest) < 0;
  }
  if (triangle < 0) {
    result.distance = inside ? -infinity : infinity;
    return result;
  }
  result.distance = inside ? -distance : distance;
  result.triangle = triangle;
  result.closest_point = X_WM * closest_M;
  Eigen::Vector3d g_M = Eigen::Vector3d::Zero();
  const Eigen::Vector3d offset = p_M - closest_M;
  const double offset_length = offset.norm();
  if (offset_length > 0) {
    g_M = offset / offset_length;
    if (inside) g_M = -g_M;
  } else {
    // On the surface: the outward pseudonormal, which on a mesh that is not closed may be missing or point
    // anywhere; the oriented face normal then.
    const Eigen::Vector3d n = model.sign.closure.closed ? pseudonormal(model, triangle, p_M) : Eigen::Vector3d::Zero();
    const double length = n.norm();
    g_M = length > 0 ? Eigen::Vector3d(n / length)
                     : Eigen::Vector3d(model.sign.closure.orientation * unitNormal(model.geometry, triangle));
  }
  result.gradient = X_WM.linear() * g_M;
  return result;
}

}  // namespace

PointDistance computePointDistance(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d& p_W,
                                   const PointQueryOptions& options) {
  validatePose(X_WM, "X_WM");
  validatePoint(p_W, "p_W");
  validateOptions(model, options);
  const detail::QueryKernelTable& kernels = detail::activeQueryKernelTable();
  return pointDistance(model, X_WM, X_WM.inverse(Eigen::Isometry), p_W, options, kernels);
}

void computePointDistances(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d* points_W,
                           std::size_t count, PointDistance* results, const PointQueryOptions& options) {
  if (count > 0 && (points_W == nullptr || results == nullptr)) {
    throw Error("computePointDistances: null points or results");
  }
  validatePose(X_WM, "X_WM");
  std::string name;
  for (std::size_t i = 0; i < count; ++i) {
    if (!points_W[i].allFinite()) {
      name = "points_W[" + std::to_string(i) + "]";
      validatePoint(points_W[i], name.c_str());
    }
  }
  validateOptions(model, options);
  const int threads = batchThreadCount(options.threads, count);
  const detail::QueryKernelTable& kernels = detail::activeQueryKernelTable();
  const Eigen::Isometry3d X_MW = X_WM.inverse(Eigen::Isometry);
  // detail::parallelChunks, as computeDistances: each task writes only its own outputs, so they do not depend
  // on the schedule.
  auto inParallel = [&](std::size_t chunk, auto&& body) { detail::parallelChunks(count, threads, chunk, body); };
  const std::unique_ptr<std::uint32_t[]> order =
      spatialOrder(model, X_WM, points_W, count, [&](auto&& body) { inParallel(4096, body); });
  const std::uint32_t* ordered = order.get();
  // Queries positions [begin, end) of the walk; each answer goes to its caller's index.
  auto queryRange = [&](std::size_t begin, std::size_t end) {
    if (ordered) {
      // Along the curve the previous point is close by, and so is its closest point: this point's distance
      // to that point of the mesh bounds its own distance from above, tighter than the previous distance
      // plus the step (a hint never changes an answer, see searchNearestFrom). The
      // leaves and lists are those of the previous queries, mostly cached: no prefetcher.
      // Consecutive points mostly share a leaf: its list, laid out once, serves them all.
      detail::PointListCache cache;
      Eigen::Vector3d previous_closest_W = Eigen::Vector3d::Zero();
      int previous_triangle = -1;
      // The caller's arrays are read and written out of order: each point and result its own cache miss,
      // fetched ahead.
      constexpr std::size_t kAhead = 8;  // queries ahead: several hundred cycles, time for a miss to land
      for (std::size_t j = begin; j != end; ++j) {
        if (j + kAhead < end) {
          const std::size_t ahead = ordered[j + kAhead];
          prefetch(&points_W[ahead]);
          prefetch(reinterpret_cast<const char*>(&points_W[ahead] + 1) - 1);
          prefetchForWrite(&results[ahead]);
          prefetchForWrite(reinterpret_cast<const char*>(&results[ahead] + 1) - 1);
        }
        const std::size_t i = ordered[j];
        const double hint = previous_triangle >= 0 ? (points_W[i] - previous_closest_W).squaredNorm()
                                                   : std::numeric_limits<double>::infinity();
        results[i] =
            pointDistance(model, X_WM, X_MW, points_W[i], options, kernels, &cache, hint, previous_triangle);
        previous_closest_W = results[i].closest_point;
        previous_triangle = results[i].triangle;
      }
      return;
    }
    // In the caller's order, with the leaf data of the points ahead prefetched.
    LeafPrefetcher prefetcher(model, X_WM, points_W);
    prefetcher.start(std::ptrdiff_t(begin), std::ptrdiff_t(end));
    for (std::size_t i = begin; i != end; ++i) {
      prefetcher.advance(std::ptrdiff_t(i), std::ptrdiff_t(end));
      results[i] = pointDistance(model, X_WM, X_MW, points_W[i], options, kernels);
    }
  };
  inParallel(std::clamp<std::size_t>(count / (8 * std::size_t(threads)), 1, 256), queryRange);
}

}  // namespace cfl
