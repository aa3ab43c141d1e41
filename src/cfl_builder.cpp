#include "cfl/cfl_model.h"

#include "cfl/error.h"
#include "cfl/triangle_distance.h"
#include "detail/box_triangle_bound.h"
#include "detail/builder_test_hooks.h"
#include "detail/hash_id_table.h"
#include "detail/nearest_triangle.h"
#include "detail/query_kernels.h"

#include <tbb/blocked_range.h>
#include <tbb/enumerable_thread_specific.h>
#include <tbb/parallel_for.h>
#include <tbb/parallel_sort.h>
#include <tbb/partitioner.h>
#include <tbb/task_group.h>
#include <tbb/task_arena.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cmath>
#include <cstring>
#include <limits>
#include <sstream>
#include <thread>
#include <utility>
#include <unordered_map>
#include <unistd.h>

namespace cfl {
namespace {

std::atomic<bool> early_split_decisions{true};
std::atomic<std::int64_t> early_split_decision_count{0};

}  // namespace

void detail::setEarlySplitDecisions(bool enabled) { early_split_decisions = enabled; }
std::int64_t detail::earlySplitDecisionCount() { return early_split_decision_count.load(); }

namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

int workerCount(int requested) {
  if (requested > 0) return requested;
  const unsigned hardware = std::thread::hardware_concurrency();
  return hardware == 0 ? 1 : static_cast<int>(hardware);
}

// Runs work() in `arena` and, from the calling thread only (the progress callback's contract), calls
// report() every 20 ms or so while it runs: the calling thread takes part in the work and reports between
// its own items, through tick().
class ProgressTicker {
 public:
  ProgressTicker(const std::function<void(double)>& progress, std::function<void()> report)
      : enabled_(bool(progress)), report_(std::move(report)), caller_(std::this_thread::get_id()),
        last_(std::chrono::steady_clock::now()) {}
  void tick() {
    if (!enabled_ || std::this_thread::get_id() != caller_) return;
    const auto now = std::chrono::steady_clock::now();
    if (now - last_ < std::chrono::milliseconds(20)) return;
    last_ = now;
    report_();
  }

 private:
  bool enabled_;
  std::function<void()> report_;
  std::thread::id caller_;
  std::chrono::steady_clock::time_point last_;
};

// The directions from any point of a sphere to any point of a ball around p lie in a cone around the axis
// from the sphere's center to p, of half-angle asin((ball radius + sphere radius) / axis length), provided
// the two are disjoint. Kept as the sine and cosine of the half-angle, so that the cone test needs no
// inverse trigonometry.
struct DirectionCone {
  Eigen::Vector3d axis;  // unit
  double sine = 0, cosine = 1;
};

// The cone for the axis `axis` (from the sphere's center to p), r = ball radius + sphere radius < |axis|.
DirectionCone makeDirectionCone(const Eigen::Vector3d& axis, double r) {
  const double length = axis.norm();
  DirectionCone cone;
  cone.axis = axis / length;
  cone.sine = r / length;
  cone.cosine = std::sqrt((length - r) * (length + r)) / length;
  return cone;
}

// An upper bound on |u - v|^2 for u in cone a and v in the cone of axis `axis` and reach r (disjoint ball and
// sphere: r < |axis|, of squared length length_squared): 2 - 2 cos(theta) for the largest angle theta
// between them, the angle alpha between the axes plus both half-angles (4 once that reaches pi). Sums of
// angles go through their sines and cosines; sin(alpha) comes from a cross product, accurate at small
// angles where acos and 1 - cos^2 are not. Rounding leaves cos(theta) a few ulps of 1 off, which the 1e-12
// added here covers; the caller's relative factor covers the rest.
double coneChordSquaredBound(const DirectionCone& a, const Eigen::Vector3d& axis, double length_squared, double r) {
  const double length = std::sqrt(length_squared);
  const double inverse = 1 / length;
  const double sin_b = r * inverse;
  const double cos_b = std::sqrt((length - r) * (length + r)) * inverse;
  const double cos_alpha = a.axis.dot(axis) * inverse;
  const double sin_alpha = a.axis.cross(axis).norm() * inverse;
  // delta = both half-angles, each below pi / 2.
  const double cos_delta = a.cosine * cos_b - a.sine * sin_b;
  const double sin_delta = a.sine * cos_b + a.cosine * sin_b;
  if (!(cos_alpha > -cos_delta)) return 4.0;  // alpha + delta >= pi: any two unit vectors
  const double cos_theta = cos_alpha * cos_delta - sin_alpha * sin_delta;
  return std::min(4.0, 2 - 2 * cos_theta + 1e-12);
}

std::int64_t physicalMemoryBytes() {
  const long pages = sysconf(_SC_PHYS_PAGES);
  const long page_size = sysconf(_SC_PAGE_SIZE);
  if (pages <= 0 || page_size <= 0) return std::numeric_limits<std::int64_t>::max();
  return std::int64_t(pages) * page_size;
}

// Topology culling data of one triangle. Edge e runs from corner a = c[e] to b = c[e + 1], d = c[e + 2] is
// the opposite corner. Every point p in all three half-spaces (p - a) . outward >= 0, (p - a) . (d - a) <= 0
// and (p - b) . (d - b) <= 0 has its closest point of the triangle on the edge: projected into the
// triangle's plane it lies beyond the edge's line and outside the Voronoi regions of the other two edges'
// interiors. Only the outward normals are kept; the rest is rebuilt from the corners when a cell is tested:
// a cell reads the corners of its candidates anyway, and keeping it all here took several cache lines per
// candidate.
struct TriangleTopology {
  // Per edge: (b - a) x n, n = (c[1] - c[0]) x (c[2] - c[0]), turned away from d.
  Eigen::Vector3d outward[3] = {Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero(), Eigen::Vector3d::Zero()};
  // Edge e's other triangles are edge_neighbours[neighbours[e], neighbours[e + 1]); an empty range (no
  // neighbour, a repeated vertex, or a degenerate triangle) means the edge never culls.
  std::int32_t neighbours[4] = {0, 0, 0, 0};
};

// Indexed by the triangles' positions in the Bvh's leaf order (Bvh::triangle_ids), as are the builder's
// candidates: a cell's candidates come from a few Bvh leaves, each a run of consecutive positions, so their
// topology, corners and spheres (MeshModel::corners.in_leaf_order, leaf_spheres) lie side by side in memory.
struct Topology {
  std::vector<TriangleTopology> triangles;
  std::vector<int> edge_neighbours;  // leaf positions too
};

// See makeTopology.
constexpr std::ptrdiff_t kMostTrianglesPerCullingEdge = 16;

Topology makeTopology(const MeshModel& geometry) {
  const auto& triangles = geometry.mesh.triangles;
  const auto& order = geometry.bvh.triangle_ids;
  const int count = int(order.size());
  constexpr int kGrain = 4096;
  // Every edge as (its vertex pair, its triangle's position), sorted: the triangles of one edge side by side,
  // found by a binary search (a hash map of vectors cost several times more on large meshes). The pairs are
  // totally ordered, so the parallel sort leaves them as a serial one would.
  auto key = [](int u, int v) { return (std::uint64_t(std::min(u, v)) << 32) | std::uint32_t(std::max(u, v)); };
  std::vector<std::pair<std::uint64_t, int>> edges(3 * order.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, count, kGrain), [&](const tbb::blocked_range<int>& range) {
    for (int n = range.begin(); n < range.end(); ++n) {
      const auto& triangle = triangles[order[n]];
      for (int e = 0; e < 3; ++e) edges[3 * std::size_t(n) + e] = {key(triangle[e], triangle[(e + 1) % 3]), n};
    }
  });
  tbb::parallel_sort(edges.begin(), edges.end());
  Topology topology;
  topology.triangles.resize(order.size());
  // Each edge's run of sorted pairs (its own triangle's among them, or none for an edge that never culls),
  // then the runs' neighbour counts summed into offsets, then the neighbours copied: the same array as
  // appending triangle by triangle, built in parallel.
  std::vector<std::array<std::int32_t, 3>> run_begin(order.size()), run_end(order.size());
  tbb::parallel_for(tbb::blocked_range<int>(0, count, kGrain), [&](const tbb::blocked_range<int>& range) {
    for (int n = range.begin(); n < range.end(); ++n) {
      const int t = order[n];
      const auto& c = geometry.corners.in_leaf_order[n];
      TriangleTopology& entry = topology.triangles[n];
      const Eigen::Vector3d normal = (c[1] - c[0]).cross(c[2] - c[0]);
      const double scale =
          std::max({(c[1] - c[0]).squaredNorm(), (c[2] - c[1]).squaredNorm(), (c[0] - c[2]).squaredNorm()});
      const bool degenerate = !(normal.norm() > 1e-8 * scale);
      int neighbours = 0;
      for (int e = 0; e < 3; ++e) {
        const int u = triangles[t][e], v = triangles[t][(e + 1) % 3];
        run_begin[n][e] = run_end[n][e] = 0;
        if (degenerate || u == v) continue;
        Eigen::Vector3d outward = (c[(e + 1) % 3] - c[e]).cross(normal);
        if (outward.dot(c[(e + 2) % 3] - c[e]) > 0) outward = -outward;
        entry.outward[e] = outward;
        const std::uint64_t edge = key(u, v);
        auto first = std::lower_bound(edges.begin(), edges.end(), std::make_pair(edge, std::numeric_limits<int>::min()));
        auto last = first;
        while (last != edges.end() && last->first == edge) ++last;
        // Every triangle of an edge lists all the others, so an edge shared by k triangles costs k^2
        // neighbours and each culling test of them scans k: quadratic time and memory on a mesh of many
        // copies of one face. Past a few triangles (non-manifold fins, duplicated faces) such an edge never
        // culls, for all of its triangles alike, so that the neighbour relation stays symmetric; culling
        // less keeps longer lists, never wrong ones.
        if (last - first > kMostTrianglesPerCullingEdge) continue;
        for (auto it = first; it != last; ++it) neighbours += it->second != n;
        run_begin[n][e] = std::int32_t(first - edges.begin());
        run_end[n][e] = std::int32_t(last - edges.begin());
      }
      entry.neighbours[3] = neighbours;  // for now the count, summed below
    }
  });
  std::int64_t total = 0;
  for (TriangleTopology& entry : topology.triangles) {
    const std::int64_t neighbours = entry.neighbours[3];
    entry.neighbours[0] = std::int32_t(total);
    total += neighbours;
  }
  if (total > std::numeric_limits<std::int32_t>::max()) throw Error("the mesh has too many edge neighbours");
  topology.edge_neighbours.resize(std::size_t(total));
  tbb::parallel_for(tbb::blocked_range<int>(0, count, kGrain), [&](const tbb::blocked_range<int>& range) {
    for (int n = range.begin(); n < range.end(); ++n) {
      TriangleTopology& entry = topology.triangles[n];
      std::int32_t next = entry.neighbours[0];
      for (int e = 0; e < 3; ++e) {
        entry.neighbours[e] = next;
        for (std::int32_t i = run_begin[n][e]; i < run_end[n][e]; ++i) {
          if (edges[i].second != n) topology.edge_neighbours[next++] = edges[i].second;
        }
      }
      entry.neighbours[3] = next;
    }
  });
  return topology;
}

// Whether all of the cube of center `center` and half edge `half` lies strictly inside the region of edge e
// of the triangle with corners c, with a margin so that rounding never decides. Each half-space is linear, so
// its lowest value over the cube is at a corner: the center's value minus the reach, half edge times the
// 1-norm of its normal plus the margin times its 2-norm. The 2-norm (a square root) is taken only when the
// center clears the 1-norm part, which adding a nonnegative margin can only raise, and clears it by less than
// the margin times twice the 1-norm: the 2-norm is at most the 1-norm, and rounding preserves order, so
// clearing that larger reach answers the same.
// Always inlined, as the lambdas of computeCellList that call it: that function is large enough that GCC's
// inliner otherwise makes other choices, which cost more than the calls' work.
CFL_ALWAYS_INLINE inline bool cellInEdgeRegion(const std::array<Eigen::Vector3d, 3>& c, const Eigen::Vector3d& outward,
                                               int e, const Eigen::Vector3d& center, double half, double margin) {
  const Eigen::Vector3d& a = c[e];
  const Eigen::Vector3d& b = c[(e + 1) % 3];
  const Eigen::Vector3d& d = c[(e + 2) % 3];
  auto clears = [&](double value, const Eigen::Vector3d& direction) {
    const double l1 = direction.lpNorm<1>();
    const double reach = half * l1;
    if (!(value > reach)) return false;
    if (value > reach + margin * (2 * l1)) return true;
    return value > reach + margin * direction.norm();
  };
  if (!clears((center - a).dot(outward), outward)) return false;
  const Eigen::Vector3d to_d_from_a = d - a;
  if (!clears(-(center - a).dot(to_d_from_a), to_d_from_a)) return false;
  const Eigen::Vector3d to_d_from_b = d - b;
  return clears(-(center - b).dot(to_d_from_b), to_d_from_b);
}

// dmin in units of `unit`, rounded down and saturated, so that unit * result <= dmin (a lower bound).
std::uint8_t quantizeEntryBound(double d_min, double unit) {
  const double units = std::floor(d_min * (1 - 1e-9) / unit);
  return static_cast<std::uint8_t>(std::clamp(units, 0.0, 255.0));
}

// Per-worker scratch of the list pass, reused from cell to cell.
struct ListScratch {
  // Topology culling: marks[i] in [last_mark - 3, last_mark] when the triangle at leaf position i (see
  // Topology) is a candidate of the current voxel, saying whether a test excluded it, it stays, may leave or has left;
  // any other value means not a candidate. Sized on first use, so that idle workers cost nothing; with triangle_masks,
  // 5 bytes per triangle per worker.
  std::vector<std::uint32_t> marks;
  std::uint32_t last_mark = 0;
  // Per leaf position: the edges whose region holds the voxel, read only for undecided candidates.
  std::vector<std::uint8_t> triangle_masks;
  std::vector<std::int32_t> pending;     // triangles that left, whose neighbours may follow
  std::vector<std::uint64_t> sort_keys;  // (bound, id)
  std::vector<std::int32_t> candidates;  // of the current voxel, from the Bvh walk: leaf positions
  std::vector<double> quick_bounds;      // per list entry: cubeTriangleQuickBound, before the full bound
  std::vector<double> center_distances;  // per list entry: its distance from the cell's center
  // With a four-triangle kernel: the candidates (their indices in `candidates`) whose exclusion tests run
  // after the first culling round, and per candidate its squared distance from the center and closest point.
  std::vector<std::uint32_t> tested;
  std::vector<double> tested_squared;
  std::vector<Eigen::Vector3d> tested_closest;
  // Per candidate that the gather already tested (see computeCellList's testEarly), by its index in
  // `candidates`. Written by index into a vector that only grows: pushed one by one, its elements went
  // through a call each.
  struct EarlyTest {
    double quick_bound;      // when kept
    double center_distance;  // when kept
    std::uint8_t state;      // kNotTested, kExcluded or kKept (the exclusion tests' verdict)
    std::uint8_t mask;       // its edge region mask, with culling
  };
  std::vector<EarlyTest> early;
  // Per entry of the cell's list: its full bound when exact, else its quick bound (finishCellList).
  struct EntryBound {
    double bound;
    bool exact;
  };
  std::vector<EntryBound> entry_bounds;
  // The lattice points (see Lattice) of the current root cell's splits, by their coordinates' bits: the
  // squared distance and the first nearest triangle the search visits. Neighbouring cells that both split
  // share a face's points and up to four cells an edge's, which without it were each searched again; the
  // bits must match, so that a point is never answered for a neighbour a rounding away.
  struct PointKeyHash {
    std::size_t operator()(const std::array<std::uint64_t, 3>& key) const {
      return std::size_t((key[0] * 0x9e3779b97f4a7c15ull ^ key[1]) * 0xc2b2ae3d27d4eb4full ^ key[2]) *
             0x165667b19e3779f9ull;
    }
  };
  std::unordered_map<std::array<std::uint64_t, 3>, std::pair<double, int>, PointKeyHash> lattice_nearest;
};

// The default memory limit of the regions: the smaller of half the machine's memory and this much, so that
// a mesh whose refinement would run away (tiny features everywhere) gets coarser leaves instead of gigabytes.
constexpr std::int64_t kDefaultRegionBytes = std::int64_t(32) << 20;
constexpr std::int64_t kDefaultRegionBytesPerTriangle = 2048;

// Root cells along the longest axis of an adaptive build's box: coarse enough that far space costs little,
// fine enough that the cells near the mesh spread over the workers.
constexpr int kAdaptiveRootCells = 16;

// The root grid over `mesh_bounds` grown by (padding - 1) / 2 times the longest extent on every side, with
// `cells` cubic cells along the longest axis and as many as needed (at least one) along the others.
RegionTree makeRootGrid(const Aabb& mesh_bounds, int cells, double padding) {
  if (mesh_bounds.empty() || !mesh_bounds.min.allFinite() || !mesh_bounds.max.allFinite()) {
    throw Error("the mesh's bounds are empty or not finite");
  }
  // A flat or point-like mesh still needs cells of positive size; the floor scales with the coordinates so
  // that a mesh far from the origin keeps representable cell corners.
  const double floor = 1e-9 * std::max(1.0, mesh_bounds.max.cwiseAbs().cwiseMax(mesh_bounds.min.cwiseAbs()).maxCoeff());
  const double longest = std::max(mesh_bounds.size().maxCoeff(), floor);
  const Eigen::Vector3d extent = mesh_bounds.size().array() + (padding - 1) * longest;
  RegionTree tree;
  tree.root_size = extent.maxCoeff() / cells;
  for (int axis = 0; axis < 3; ++axis) {
    // Round up so the grid never covers less than the padded box; the slack avoids a layer that rounding
    // alone would add.
    tree.root_dims[axis] = std::max(1, static_cast<int>(std::ceil(extent[axis] / tree.root_size - 1e-9)));
  }
  const Eigen::Vector3d covered =
      tree.root_size * Eigen::Vector3d(tree.root_dims[0], tree.root_dims[1], tree.root_dims[2]);
  tree.origin = mesh_bounds.center() - 0.5 * covered;
  return tree;
}

template <class T>
std::int64_t capacityBytes(const std::vector<T>& v) {
  return std::int64_t(v.capacity() * sizeof(T));
}


// When to split a cell: its list is longer than kListTarget, it is larger than kSmallestCell times the mean
// edge of the triangles it lists (smaller cells would not shorten a list of triangles around one vertex, and
// would multiply the leaves a query visits and the cache lines it reads: at 1.25 edges, the uniform grid's
// best voxel, the rock's short-range queries took 1.3x to 1.6x the time they take at 2), and it is
// larger than kFarCellRatio times its distance from the mesh (far away, a list shortens only in cells that
// shrink with the distance, and far cells serve only far queries, which the Bvh bounds mostly answer).
constexpr std::uint32_t kListTarget = 8;
constexpr double kSmallestCell = 2;
constexpr double kFarCellRatio = 0.5;
// A leaf whose list stays longer than this stores none (RegionTree::kNoList): scanning it would cost more
// than testing what falls there against the Bvh, and storing it more memory than the rest of the model.
// Next to the mesh (a leaf no farther from it than kNearCells edges) lists are what short-range queries
// scan, and the entry bounds cut most of a long one short; a thin plate's leaves list both faces. Farther
// out a leaf serves only farther queries, which its lower bound mostly dismisses. A query meeting a leaf
// without a list continues on the Bvhs, which near the mesh costs more than a long list: on the bunny,
// caps of 32 within one edge doubled the short-range query time.
constexpr double kNearCells = 4;
constexpr std::uint32_t kLongestNearList = 256;
constexpr std::uint32_t kLongestFarList = 64;
constexpr int kDeepest = 20;  // levels below the root, within RegionTree::kMaxDepth
// What an adaptive build's regions (nodes, leaf arrays and lists) may hold: this much plus so much per
// triangle (see fitListsInBudget). Around a thin part (a long pipe, a rod) every leaf a few of its edges
// away lists a whole stretch of the part's circumference, since the cell is wider than the part and the
// conservative tests cannot tell the part's far side from its near side: those leaves took the model past
// twice an OBBRSS hierarchy while the lists next to the surface cost what they cost elsewhere. The fixed
// part spares small meshes, whose root grid alone is a large share of their model.
constexpr std::int64_t kListBudgetBytes = std::int64_t(1) << 20;
constexpr std::int64_t kListBudgetBytesPerTriangle = 688;
// What computeCellList returns for a cell certain to split, whose list it did not compute.
constexpr std::uint32_t kCertainSplit = RegionTree::kNoList - 1;

// What every cell's list computation reads.
struct BuildContext {
  const MeshModel& geometry;
  const Topology& topology;
  bool culling;
  bool early_split;  // see detail::setEarlySplitDecisions
  // The point-triangle distances of the active query kernels four at a time (the same bits as one at a
  // time), or nullptr.
  detail::PointTriangles4 four;
  // pointTriangleSquaredDistance of the same kernels (the same bits).
  detail::PointTriangle1 one;
  double largest_edge;  // the largest mean edge of a triangle
  bool prune_by_spheres;  // the candidate walk also tests the nodes' spheres (see buildCflModel)

  double squaredDistance(const Eigen::Vector3d& p, const std::array<Eigen::Vector3d, 3>& c,
                         Eigen::Vector3d* closest = nullptr) const {
    return one(p, c[0], c[1], c[2], closest);
  }
};

// A cell's list, appended to `ids` / `bounds` (bounds in units of size / 32), and its lower bound.
struct CellListOutput {
  std::vector<std::int32_t> ids;
  std::vector<std::uint8_t> bounds;
  double lower_bound = 0;
};

// Computes the list of the cube [min_corner, min_corner + size]^3, given the nearest triangle of each of its
// corners (corner n at min_corner + size (n & 1, (n >> 1) & 1, n >> 2)). For cell V with center c,
// U = min_k dmax(V, k) over the nearest triangles of the corners and of c is an upper bound on the distance
// from any point of V to the mesh. Triangle i belongs to the list unless dmin(V, i) > U (a Bvh node whose box
// is farther than U from V holds none that belong), unless the cone test shows c's nearest triangle strictly
// closer everywhere in V, and unless topology culling removes it. Appends the list to `out` sorted by
// (bound, id) and returns its length.
//
// `parent_lower` is a lower bound on the distance from the cell to the mesh (0 if none). When the cell's
// center shows it so far from the mesh that it cannot split, and more than the longest list it could store
// (kLongestNearList or kLongestFarList, as the same bound shows) are certain to stay on its list, the rest
// of the list is never needed: returns RegionTree::kNoList, appends nothing and leaves in out.lower_bound
// the center's bound, looser than the listed triangles' but enough for a leaf that queries pass to the Bvh.
//
// `split_edges` (the triangles' mean edges, or null when the cell may not split for its depth or the budget):
// when the split rule (see shouldSplit) is certain to hold whatever the rest of the list, returns
// kCertainSplit, appends nothing and leaves in out.lower_bound the center's bound, a valid lower bound for the
// children: the list is not needed.
std::uint32_t computeCellList(const BuildContext& context, ListScratch& scratch, const Eigen::Vector3d& min_corner,
                              double size, const int corner_triangle[8], double parent_lower, bool adaptive,
                              const std::vector<double>* split_edges, CellListOutput& out) {
  const MeshModel& geometry = context.geometry;
  const Topology& topology = context.topology;
  const double half = 0.5 * size;
  const double half_diagonal = std::sqrt(3.0) * half;
  const double margin = 1e-9 * size;
  const Eigen::Vector3d center = min_corner + Eigen::Vector3d::Constant(half);
  Eigen::Vector3d corners[8];
  int upper_candidates[9];
  int upper_candidate_count = 0;
  for (int n = 0; n < 8; ++n) {
    corners[n] = min_corner + size * Eigen::Vector3d(n & 1, (n >> 1) & 1, n >> 2);
    const int t = corner_triangle[n];
    if (std::find(upper_candidates, upper_candidates + upper_candidate_count, t) ==
        upper_candidates + upper_candidate_count) {
      upper_candidates[upper_candidate_count++] = t;
    }
  }
  // The triangle nearest to the center: a candidate for U, and the reference of the cone test below.
  // The corners' triangles bound the search, but only as a distance just above theirs: the search then
  // prunes the same nodes it would have pruned anyway and still returns the first nearest triangle in
  // its visiting order, so ties (a shared vertex is often nearest) break as in a search from infinity.
  // A tied hint as the reference instead lengthened the bunny's lists slightly.
  double center_squared = kInfinity;
  for (int n = 0; n < upper_candidate_count; ++n) {
    const auto& c = geometry.corners[upper_candidates[n]];
    center_squared = std::min(center_squared, context.squaredDistance(center, c));
  }
  center_squared = std::nextafter(center_squared * (1 + 1e-12), kInfinity);
  int center_triangle = -1;
  detail::nearestTriangle(geometry, center, center_squared, center_triangle, nullptr, context.four);
  if (center_triangle < 0) {
    // Nothing was found below the corners' bound: their distances were not finite (coordinates near
    // the limits of double). Any triangle serves as U's candidate and the cone's reference, as long as
    // center_squared is its own distance.
    center_squared = kInfinity;
    detail::nearestTriangle(geometry, center, center_squared, center_triangle, nullptr, context.four);
    if (center_triangle < 0) {
      center_triangle = upper_candidates[0];
      const auto& c = geometry.corners[center_triangle];
      center_squared = context.squaredDistance(center, c);
    }
  }
  if (std::find(upper_candidates, upper_candidates + upper_candidate_count, center_triangle) ==
      upper_candidates + upper_candidate_count) {
    upper_candidates[upper_candidate_count++] = center_triangle;
  }
  // The center's triangle first: it usually gives the smallest U, after which the others mostly stop at
  // their first corners that reach it. U is a minimum, so the order does not change it.
  std::swap(*std::find(upper_candidates, upper_candidates + upper_candidate_count, center_triangle),
            upper_candidates[0]);
  double upper = kInfinity;  // squared
  for (int n = 0; n < upper_candidate_count; ++n) {
    const auto& c = geometry.corners[upper_candidates[n]];
    double farthest = 0;
    for (int m = 0; m < 8 && farthest < upper; ++m) {
      farthest = std::max(farthest, context.squaredDistance(corners[m], c));
    }
    upper = std::min(upper, farthest);
  }
  // Rounded up: a list may hold one triangle too many, never one too few.
  const double upper_bound = std::nextafter(std::sqrt(upper), kInfinity) * (1 + 1e-12);
  const double upper_bound_squared = upper_bound * upper_bound;
  const double center_distance = std::sqrt(center_squared);
  // The distance is 1-Lipschitz, so no point of the cell is nearer the mesh than center_distance less the
  // half diagonal; rounded down like the listed bound below, and never below what the parent showed.
  const double rounding = 1e-15 * (center.cwiseAbs().maxCoeff() + size);
  const double center_lower = std::max(
      parent_lower, std::nextafter(center_distance - half_diagonal, 0.0) * (1 - 1e-12) -
                        1e-12 * (center_distance + half_diagonal) - rounding);
  // A cell no larger than kFarCellRatio times any lower bound never splits; past kNearCells edges it is far
  // whatever its listed bound, and within, the near cap is the larger, so exceeding it means no list either way.
  const std::uint32_t longest_stored =
      adaptive && size <= kFarCellRatio * center_lower
          ? (center_lower > kNearCells * size ? kLongestFarList : kLongestNearList)
          : RegionTree::kNoList;
  // Cone test. For p in the voxel (within half_diagonal of the center), f(p) = dist(p, i) - dist(p, k)
  // with k = center_triangle changes at most |u_i - u_k| per unit length, u being the unit direction
  // from a triangle's closest point to p. While the voxel's ball stays clear of a sphere around a
  // triangle, u lies in that sphere's DirectionCone, so |u_i - u_k|^2 is at most coneChordSquaredBound.
  // If f(center) > half_diagonal * its root, k is strictly closer than i everywhere in the voxel. Far from
  // the mesh this drops the wide rim of triangles that the dmin/dmax test alone keeps. Any sphere holding
  // the triangle serves, so a Bvh node's sphere and its box distance exclude the whole subtree at once.
  const Eigen::Vector4d& sphere_k = geometry.spheres[center_triangle];
  const Eigen::Vector3d axis_k = center - sphere_k.head<3>();
  const double axis_k_length = axis_k.norm();
  const bool cone_usable = axis_k_length > half_diagonal + sphere_k[3];
  const DirectionCone cone_k =
      cone_usable ? makeDirectionCone(axis_k, half_diagonal + sphere_k[3]) : DirectionCone();
  // Whether k beats every triangle within the sphere (sphere_center, sphere_radius) everywhere in the voxel,
  // given a lower bound `near` on their distances to the center: whether near - dist(center, k) exceeds
  // half_diagonal times the chord bound, compared squared. Margin: a few ulps of every term, relative to
  // the voxel's reach. The chord is at least 2 sin(gamma / 2) >= sin(gamma) for k's half-angle gamma, a
  // cheap necessary condition first (0.999 keeps it strictly weaker, so it only saves time).
  const double chord_floor_k = 0.999 * half_diagonal * cone_k.sine;
  auto coneExcludes = [&](double near, const Eigen::Vector3d& sphere_center, double sphere_radius) {
    const double spare = near - center_distance - 1e-12 * (center_distance + near + half_diagonal);
    if (!(spare > chord_floor_k)) return false;
    const Eigen::Vector3d axis_i = center - sphere_center;
    const double length_i_squared = axis_i.squaredNorm();
    const double r_i = half_diagonal + sphere_radius;
    if (!(length_i_squared > r_i * r_i)) return false;
    const double chord_squared = coneChordSquaredBound(cone_k, axis_i, length_i_squared, r_i);
    return spare * spare > half_diagonal * half_diagonal * chord_squared * (1 + 3e-9);
  };

  // Triangles that may belong: a Bvh walk that skips nodes whose box is farther than U from the voxel's
  // cube (then dmin > U for all below), or that the cone test excludes as a whole.
  // Candidates are leaf positions (see Topology). The exclusion tests of candidate i: whether they exclude
  // it, else its quick bound and center distance.
  const auto& leaf_triangle = geometry.bvh.triangle_ids;
  // From candidate i's squared distance to the center and its closest point there.
  auto exclusionTestsGiven = [&](int i, double squared, const Eigen::Vector3d& closest, double& d_min,
                                 double& d_center) CFL_ALWAYS_INLINE {
    const auto& c = geometry.corners.in_leaf_order[i];
    d_center = std::sqrt(squared);
    bool excluded = d_center - half_diagonal > upper_bound;
    d_min = 0;
    if (!excluded) {
      d_min = detail::cubeTriangleQuickBound(center, half, c[0], c[1], c[2], closest);
      excluded = d_min > upper_bound;
    }
    if (!excluded && cone_usable && leaf_triangle[i] != center_triangle) {
      const Eigen::Vector4d& sphere_i = geometry.leaf_spheres[i];
      excluded = coneExcludes(d_center, sphere_i.head<3>(), sphere_i[3]);
    }
    return excluded;
  };
  auto exclusionTests = [&](int i, double& d_min, double& d_center) CFL_ALWAYS_INLINE {
    const auto& c = geometry.corners.in_leaf_order[i];
    Eigen::Vector3d closest;
    const double squared = context.squaredDistance(center, c, &closest);
    return exclusionTestsGiven(i, squared, closest, d_min, d_center);
  };
  // Entries listed whatever comes after: not droppable (no edge region holds the cell, so culling keeps them
  // whatever the other candidates do), and close enough to the center that the full bound cannot exclude
  // them (see the full bounds below). A cell that cannot split counts them as the walk finds them, and stops
  // once they outnumber what it could store: the walk, culling and the tests of the rest are never needed.
  const double certain = upper_bound - 1e-9 * (center.cwiseAbs().maxCoeff() + size + upper_bound);
  const bool count_early = longest_stored != RegionTree::kNoList;
  std::uint32_t certain_count = 0;
  enum : std::uint8_t { kNotTested, kExcluded, kKept };
  // The edges of candidate i with a neighbour whose region holds the cell: topology culling may drop it
  // when this is not 0.
  auto edgeRegionMask = [&](int i) CFL_ALWAYS_INLINE {
    const TriangleTopology& entry = topology.triangles[i];
    std::uint8_t mask = 0;
    for (int e = 0; e < 3; ++e) {
      if (entry.neighbours[e + 1] > entry.neighbours[e] &&
          cellInEdgeRegion(geometry.corners.in_leaf_order[i], entry.outward[e], e, center, half, margin)) {
        mask |= std::uint8_t(1 << e);
      }
    }
    return mask;
  };
  // The masks computed while counting are kept for culling below.
  std::vector<std::int32_t>& candidates = scratch.candidates;
  // The candidates whose culling mask and exclusion tests have been computed while counting: candidates
  // [0, early_masked) have their masks in scratch.early, and those without a mask (the only ones that can be
  // certain) their tests too, except the last few in `early_pending`, which wait for a batch of four of the
  // query kernels (the same bits as one at a time). Entry n is certainly listed when its mask is 0, the tests
  // keep it and its center distance is below `certain`; each such entry is passed to `listed`, in the order
  // of the candidates, until `listed` returns true (and then so does the test).
  std::uint32_t early_masked = 0;
  std::uint32_t early_pending[4];
  int early_pending_count = 0;
  auto runEarlyPending = [&](auto&& listed) CFL_ALWAYS_INLINE {
    const int lanes = early_pending_count;
    early_pending_count = 0;
    double squared[4];
    Eigen::Vector3d closest[4];
    if (context.four != nullptr && lanes > 1) {
      const std::array<Eigen::Vector3d, 3>* triangles[4];
      for (int j = 0; j < 4; ++j) {
        triangles[j] = &geometry.corners.in_leaf_order[candidates[early_pending[j < lanes ? j : 0]]];
      }
      context.four(center, triangles, squared, closest);
    } else {
      for (int j = 0; j < lanes; ++j) {
        squared[j] = context.squaredDistance(center, geometry.corners.in_leaf_order[candidates[early_pending[j]]],
                                             &closest[j]);
      }
    }
    for (int j = 0; j < lanes; ++j) {
      const std::uint32_t n = early_pending[j];
      double d_min, d_center;
      const bool excluded = exclusionTestsGiven(candidates[n], squared[j], closest[j], d_min, d_center);
      scratch.early[n] = {d_min, d_center, excluded ? kExcluded : kKept, 0};
      if (!excluded && d_center < certain && listed(n)) return true;
    }
    return false;
  };
  // Tests candidates [early_masked, end), leaving up to three in early_pending unless `flush`.
  auto testEarly = [&](std::uint32_t end, bool flush, auto&& listed) CFL_ALWAYS_INLINE {
    for (; early_masked < end; ++early_masked) {
      const std::uint32_t n = early_masked;
      const std::uint8_t mask = context.culling ? edgeRegionMask(candidates[n]) : 0;
      if (mask) {
        scratch.early[n] = {0, 0, kNotTested, mask};
        continue;
      }
      early_pending[early_pending_count++] = n;
      if (early_pending_count == 4 && runEarlyPending(listed)) return true;
    }
    return flush && early_pending_count > 0 && runEarlyPending(listed);
  };

  // The rule's distance test compares the size with the listed lower bound, the least full bound of the
  // entries, which may lie far below the center's distance (a cell beside the mesh, whose center is just
  // outside the split range). When the center's nearest triangle is certain to be listed, its full bound caps
  // the listed one: if the test holds on it, it holds whatever the rest of the list.
  auto nearestListedNear = [&] {
    const int k = geometry.corners.leaf_position[center_triangle];
    if (context.culling && edgeRegionMask(k) != 0) return false;
    double d_min, d_center;
    if (exclusionTests(k, d_min, d_center) || !(d_center < certain)) return false;
    const auto& c = geometry.corners.in_leaf_order[k];
    const double full = detail::cubeTriangleSeparatingAxisBound(center, half, c[0], c[1], c[2], d_min);
    return size > kFarCellRatio * full * (1 + 1e-6);
  };
  // Whether the cell splits whatever the rest of its list (see the rule after the walk), and the state of that
  // rule: the certain entries so far and their shortfalls.
  const bool split_early = split_edges && context.early_split && !count_early &&
                           (size > kFarCellRatio * center_distance * (1 + 1e-6) || nearestListedNear());
  const double largest_mean = size / (kSmallestCell * (1 + 1e-6));
  double shortfall = 0;
  std::uint32_t certain_entries = 0;
  // When no triangle of the mesh has a mean edge above largest_mean, every excess is 0 whatever the
  // candidates, and the rule holds as soon as it holds for the candidates found so far (both sums only
  // grow): the walk tests the candidates as it finds them and stops there.
  const bool split_while_walking = split_early && context.largest_edge <= largest_mean;
  // Counts certain entry n for the rule; returns whether the rule now holds, excess being the candidates' excess.
  auto splitsCertainly = [&](std::uint32_t n, double excess) CFL_ALWAYS_INLINE {
    const int i = candidates[n];
    ++certain_entries;
    shortfall += std::max(0.0, largest_mean - (*split_edges)[leaf_triangle[i]]);
    return certain_entries > kListTarget && shortfall > excess * (1 + 1e-6);
  };
  auto splitsWhileWalking = [&](std::uint32_t n) CFL_ALWAYS_INLINE { return splitsCertainly(n, 0.0); };
  auto countsPastStored = [&](std::uint32_t) CFL_ALWAYS_INLINE { return ++certain_count > longest_stored; };
  auto farLeafWithoutList = [&] {
    out.lower_bound = std::max(0.0, center_lower);
    return RegionTree::kNoList;
  };
  auto certainSplit = [&] {
    out.lower_bound = std::max(0.0, center_lower);
    early_split_decision_count.fetch_add(1, std::memory_order_relaxed);
    return kCertainSplit;
  };

  candidates.clear();
  const auto& nodes = geometry.bvh.nodes;
  int stack[128];  // see detail::nearestTriangle for why this is enough
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BvhNode& node = nodes[stack[--top]];
    const Eigen::Vector3d outside =
        (node.box().min - center).cwiseMax(center - node.box().max).cwiseMax(0.0);
    if ((outside.array() - half).max(0.0).matrix().squaredNorm() > upper_bound_squared) continue;
    // Past the sphere, every triangle below is farther than upper_bound from the cube, which the first
    // exclusion test would find triangle by triangle: the same list, fewer candidates.
    if (context.prune_by_spheres) {
      const double sphere_reach = node.radius + half_diagonal + upper_bound;
      if ((center - node.center).squaredNorm() > sphere_reach * sphere_reach * (1 + 1e-9)) continue;
    }
    if (cone_usable && coneExcludes(outside.norm(), node.center, node.radius)) continue;
    if (node.isLeaf()) {
      for (int i = node.first; i < node.first + node.count; ++i) candidates.push_back(i);
      if ((count_early || split_while_walking) && scratch.early.size() < candidates.size()) {
        scratch.early.resize(2 * candidates.size());
      }
      if (count_early) {
        if (testEarly(std::uint32_t(candidates.size()), false, countsPastStored)) return farLeafWithoutList();
      } else if (split_while_walking) {
        if (testEarly(std::uint32_t(candidates.size()), false, splitsWhileWalking)) return certainSplit();
      }
    } else {
      // Counting, the nearer child first: triangles nearer the center are the likelier to be certain, so the
      // count passes its threshold sooner. Either order lists the same triangles.
      const bool swap = (count_early || split_while_walking) &&
                        (nodes[node.first].center - center).squaredNorm() <
                            (nodes[node.first + 1].center - center).squaredNorm();
      stack[top++] = node.first + swap;
      stack[top++] = node.first + !swap;
    }
  }
  const std::uint32_t candidate_count = static_cast<std::uint32_t>(candidates.size());
  if (count_early && testEarly(candidate_count, true, countsPastStored)) return farLeafWithoutList();
  if (split_while_walking && testEarly(candidate_count, true, splitsWhileWalking)) return certainSplit();
  // Candidates whose culling mask and exclusion tests testEarly has computed, in order.
  std::uint32_t early_tested = count_early || split_while_walking ? candidate_count : 0;
  // Whether the cell splits whatever the rest of its list. The listed lower bound is at most the center's
  // distance (the list holds a nearest triangle of the center). With T the largest mean edge that lets the
  // cell split, any list L holding the certain entries C has mean edge below T when the sum over L of (edge - T)
  // is negative; its largest value over such L, the sum over C plus the positive excesses of the other
  // candidates, is the excess of all candidates less the shortfalls of C. The margins, far above the rounding
  // of the bounds and of the sums, only make the rule more careful than shouldSplit.
  if (split_early && !split_while_walking) {
    if (scratch.early.size() < candidate_count) scratch.early.resize(candidate_count);
    double excess = 0;
    for (std::uint32_t n = 0; n < candidate_count; ++n) {
      excess += std::max(0.0, (*split_edges)[leaf_triangle[candidates[n]]] - largest_mean);
    }
    if (testEarly(candidate_count, true, [&](std::uint32_t n) { return splitsCertainly(n, excess); })) {
      return certainSplit();
    }
    early_tested = candidate_count;
  }

  // Paper section 3.6, in a form that is provably conservative on any mesh: triangle i may leave the
  // list when every point of the voxel has its closest point of i on an edge shared with a triangle j
  // (its witness), so that j is at least as close everywhere. It does leave when some witness stays,
  // is missing from the list, or has itself left through such a chain. Why that is safe: a triangle
  // missing from the list is strictly beaten everywhere by another, so for any point p, following
  // witnesses from one of p's nearest triangles never increases the distance and ends at a triangle
  // that stays (a missing one would be strictly beaten, so not nearest). Witnesses that only lean on
  // each other in a cycle all stay. The result is the least fixed point of a monotone rule, so it
  // does not depend on the order of the list.
  //
  // It runs before the exclusion tests, with every candidate counted as listed, and again after them,
  // with the excluded ones counted as missing: the first round is the cheap one and removes most of the
  // triangles that the costly tests would otherwise examine, and since it only drops what the rule
  // drops, the second round reaches the same least fixed point as a single round after the tests.
  const bool culling = context.culling && candidate_count > 1;
  std::uint32_t missing = 0, stays = 0, undecided = 0, left = 0;
  // Whether undecided candidate i may leave now: some edge whose region holds the voxel has a neighbour that
  // is not undecided.
  auto mayLeave = [&](int i) {
    const TriangleTopology& entry = topology.triangles[i];
    const std::uint8_t mask = scratch.triangle_masks[i];
    for (int e = 0; e < 3; ++e) {
      if (!(mask >> e & 1)) continue;
      for (int m = entry.neighbours[e]; m < entry.neighbours[e + 1]; ++m) {
        if (scratch.marks[topology.edge_neighbours[m]] != undecided) return true;
      }
    }
    return false;
  };
  // The rule only ever turns undecided into left, so its fixed point does not depend on the order: one pass
  // over the candidates, then only the neighbours of what left, the only triangles whose answer can change.
  auto propagate = [&](std::uint32_t size) {  // over candidates[0, size)
    std::vector<std::int32_t>& pending = scratch.pending;
    pending.clear();
    for (std::uint32_t n = 0; n < size; ++n) {
      const int i = candidates[n];
      if (scratch.marks[i] == undecided && mayLeave(i)) {
        scratch.marks[i] = left;
        pending.push_back(i);
      }
    }
    while (!pending.empty()) {
      const int i = pending.back();
      pending.pop_back();
      const TriangleTopology& entry = topology.triangles[i];
      for (int m = entry.neighbours[0]; m < entry.neighbours[3]; ++m) {
        const int other = topology.edge_neighbours[m];
        if (scratch.marks[other] == undecided && mayLeave(other)) {
          scratch.marks[other] = left;
          pending.push_back(other);
        }
      }
    }
  };
  bool any_droppable = false;
  if (culling) {
    if (scratch.marks.empty() || scratch.last_mark > std::numeric_limits<std::uint32_t>::max() - 4) {
      scratch.marks.assign(geometry.mesh.triangles.size(), 0);
      scratch.triangle_masks.assign(geometry.mesh.triangles.size(), 0);
      scratch.last_mark = 0;
    }
    missing = (scratch.last_mark += 4) - 3;  // excluded by a test; any older mark: never a candidate
    stays = missing + 1;                    // listed, not droppable
    undecided = missing + 2;                // droppable, not yet shown to leave
    left = missing + 3;                     // shown to leave
    for (std::uint32_t n = 0; n < candidate_count; ++n) {
      const int i = candidates[n];
      const std::uint8_t mask = n < early_tested ? scratch.early[n].mask : edgeRegionMask(i);
      scratch.marks[i] = mask ? undecided : stays;
      scratch.triangle_masks[i] = mask;
      any_droppable = any_droppable || mask;
    }
    if (any_droppable) propagate(candidate_count);
  }

  // The exclusion tests, on what the first round kept. The full separating-axis bound comes after
  // culling, for the entries that stay: it is the costly test and seldom excludes, so culling sees
  // those few as listed, which may keep more, never fewer (a witness that is listed or missing is good
  // either way).
  std::uint32_t count = 0;
  scratch.quick_bounds.clear();
  scratch.center_distances.clear();
  bool any_excluded = false;
  auto needsTests = [&](std::uint32_t n) {
    return !(culling && scratch.marks[candidates[n]] == left) &&
           !(n < early_tested && scratch.early[n].state != kNotTested);
  };
  // With a four-triangle kernel, the distances from the center of every candidate still to be tested, four at
  // a time: the same bits as one at a time.
  if (context.four != nullptr) {
    scratch.tested.clear();
    for (std::uint32_t n = 0; n < candidate_count; ++n) {
      if (needsTests(n)) scratch.tested.push_back(n);
    }
    const std::size_t tested_count = scratch.tested.size();
    scratch.tested_squared.resize(candidate_count);
    scratch.tested_closest.resize(candidate_count);
    for (std::size_t k = 0; k < tested_count; k += 4) {
      const int lanes = int(std::min<std::size_t>(4, tested_count - k));
      const std::array<Eigen::Vector3d, 3>* triangles[4];
      for (int j = 0; j < 4; ++j) {
        triangles[j] = &geometry.corners.in_leaf_order[candidates[scratch.tested[k + (j < lanes ? j : 0)]]];
      }
      double squared[4];
      Eigen::Vector3d closest[4];
      context.four(center, triangles, squared, closest);
      for (int j = 0; j < lanes; ++j) {
        scratch.tested_squared[scratch.tested[k + j]] = squared[j];
        scratch.tested_closest[scratch.tested[k + j]] = closest[j];
      }
    }
  }
  for (std::uint32_t n = 0; n < candidate_count; ++n) {
    const int i = candidates[n];
    if (culling && scratch.marks[i] == left) continue;
    double d_min, d_center;
    bool excluded;
    if (n < early_tested && scratch.early[n].state != kNotTested) {
      excluded = scratch.early[n].state == kExcluded;
      d_min = scratch.early[n].quick_bound;
      d_center = scratch.early[n].center_distance;
    } else if (context.four != nullptr) {
      excluded = exclusionTestsGiven(i, scratch.tested_squared[n], scratch.tested_closest[n], d_min, d_center);
    } else {
      excluded = exclusionTests(i, d_min, d_center);
    }
    if (excluded) {
      if (culling) scratch.marks[i] = missing;
      any_excluded = true;
      continue;
    }
    candidates[count] = i;  // compacted in place: n >= count
    scratch.quick_bounds.push_back(d_min);
    scratch.center_distances.push_back(d_center);
    ++count;
  }
  if (culling && any_droppable && any_excluded) propagate(count);
  // What culling kept. The full bound can only exclude an entry whose distance from the center exceeds
  // upper_bound, less rounding (it bounds the cube-triangle distance, which the center's bounds); the others
  // are listed whatever it says, so their full bounds wait for finishCellList, which only the leaves that
  // store their list call: the cells that split or store none need only the list's length, its triangles and
  // its lower bound.
  const std::size_t list_begin = out.ids.size();
  scratch.entry_bounds.clear();
  for (std::uint32_t n = 0; n < count; ++n) {
    const int i = candidates[n];
    if (culling && scratch.marks[i] == left) continue;
    double d_min = scratch.quick_bounds[n];
    const bool exact = !(scratch.center_distances[n] < certain);
    if (exact) {
      const auto& c = geometry.corners.in_leaf_order[i];
      d_min = detail::cubeTriangleSeparatingAxisBound(center, half, c[0], c[1], c[2], d_min);
      if (d_min > upper_bound) continue;
    }
    out.ids.push_back(leaf_triangle[i]);
    scratch.entry_bounds.push_back({d_min, exact});
  }
  count = static_cast<std::uint32_t>(out.ids.size() - list_begin);
  // The lower bound of the voxel: the closest triangle to any of its points is listed, so the smallest
  // listed full bound bounds the voxel-mesh distance from below. A quick bound never exceeds its full
  // bound, so only the entries whose quick bound is below the smallest full bound so far need theirs.
  double lower = kInfinity;
  for (std::uint32_t n = 0; n < count; ++n) {
    if (scratch.entry_bounds[n].exact) lower = std::min(lower, scratch.entry_bounds[n].bound);
  }
  for (;;) {
    std::uint32_t next = count;
    for (std::uint32_t n = 0; n < count; ++n) {
      if (!scratch.entry_bounds[n].exact && scratch.entry_bounds[n].bound < lower &&
          (next == count || scratch.entry_bounds[n].bound < scratch.entry_bounds[next].bound)) {
        next = n;
      }
    }
    if (next == count) break;
    const auto& c = geometry.corners[out.ids[list_begin + next]];
    ListScratch::EntryBound& entry = scratch.entry_bounds[next];
    entry.bound = detail::cubeTriangleSeparatingAxisBound(center, half, c[0], c[1], c[2], entry.bound);
    entry.exact = true;
    lower = std::min(lower, entry.bound);
  }
  // Rounded down, past the rounding of the bounds' sums too, which scales with the coordinates rather than
  // with the distance: a cell touching the mesh must not get a positive bound from rounding alone.
  out.lower_bound = std::max(0.0, std::nextafter(lower, 0.0) * (1 - 1e-12) - rounding);
  return count;
}

// Completes the list computeCellList just appended (its last `count` ids) for a leaf that stores it: the
// full bound of every entry, as entry bounds in units of size / 32, and the order a query scans, by
// (bound, id): it stops at the first entry whose bound reaches its best distance so far.
void finishCellList(const BuildContext& context, ListScratch& scratch, const Eigen::Vector3d& min_corner,
                    double size, std::uint32_t count, CellListOutput& out) {
  const double half = 0.5 * size;
  const Eigen::Vector3d center = min_corner + Eigen::Vector3d::Constant(half);
  const double bound_unit = size / 32;
  const std::size_t list_begin = out.ids.size() - count;
  std::int32_t* list = out.ids.data() + list_begin;
  scratch.sort_keys.clear();
  for (std::uint32_t n = 0; n < count; ++n) {
    double d_min = scratch.entry_bounds[n].bound;
    if (!scratch.entry_bounds[n].exact) {
      const auto& c = context.geometry.corners[list[n]];
      d_min = detail::cubeTriangleSeparatingAxisBound(center, half, c[0], c[1], c[2], d_min);
    }
    scratch.sort_keys.push_back(std::uint64_t(quantizeEntryBound(d_min, bound_unit)) << 32 | std::uint32_t(list[n]));
  }
  std::sort(scratch.sort_keys.begin(), scratch.sort_keys.end());
  out.bounds.resize(list_begin + count);
  std::uint8_t* bounds = out.bounds.data() + list_begin;
  for (std::uint32_t n = 0; n < count; ++n) {
    bounds[n] = static_cast<std::uint8_t>(scratch.sort_keys[n] >> 32);
    list[n] = static_cast<std::int32_t>(scratch.sort_keys[n] & 0xffffffffu);
  }
}

// The 3 x 3 x 3 lattice of a cell being split: its corners, face and edge midpoints and center, point
// (a, b, c) at min_corner + size / 2 (a, b, c). Nearest triangles and distances of each.
struct Lattice {
  int triangle[27];
  double distance[27];
  static int index(int a, int b, int c) { return a + 3 * b + 9 * c; }
};

// The leaves of one root cell's subtree, in depth-first order; children of a node stored consecutively.
struct Subtree {
  std::vector<std::uint32_t> nodes;  // nodes[0]: the root cell; first-child values index this vector
  std::vector<std::uint32_t> list_length;
  std::vector<std::uint8_t> depth;
  std::vector<float> lower_bound;
  std::vector<std::array<float, 8>> corner_distance;
  CellListOutput lists;  // the leaves' lists, one after another
  // listHash of each leaf with a stored list, in leaf order: computed with the subtree, in parallel, for the
  // serial step that stores each distinct list once.
  std::vector<std::uint64_t> list_hash;
};

// The hash by which identical lists (same ids, bounds and depth) are found.
std::uint64_t listHash(const std::int32_t* list, const std::uint8_t* bounds, std::uint32_t length,
                       std::uint8_t depth) {
  std::uint64_t hash = (1469598103934665603ull ^ length ^ std::uint64_t(depth) << 40) * 1099511628211ull;
  for (std::uint32_t n = 0; n < length; ++n) {
    hash = (hash ^ (std::uint32_t(list[n]) | std::uint64_t(bounds[n]) << 32)) * 1099511628211ull;
  }
  return hash;
}

// Distance from p to the mesh with its nearest triangle, starting from a triangle near p.
std::pair<double, int> nearestWithHint(const BuildContext& context, const Eigen::Vector3d& p, int hint) {
  const MeshModel& geometry = context.geometry;
  double best = kInfinity;
  int best_triangle = -1;
  if (hint >= 0) {
    const auto& c = geometry.corners[hint];
    best = context.squaredDistance(p, c);
    best_triangle = hint;
  }
  detail::nearestTriangle(geometry, p, best, best_triangle, nullptr, context.four);
  return {std::sqrt(best), best_triangle};
}

// As nearestWithHint(context, p, hint), ties included, through `cache`: that answer is `hint` unless a
// triangle is strictly nearer, else the first nearest triangle the search visits, the same whatever the
// search's initial bound (the bound prunes nodes, it never reorders them, and one just above a guess's
// distance prunes no node holding a nearest triangle). So the cache keeps the search's first nearest and
// each cell compares it with its own hint. `guesses` (triangles near p, such as the cell's corners') give
// the bound when p is new.
std::pair<double, int> cachedNearestWithHint(const BuildContext& context, const Eigen::Vector3d& p, int hint,
                                             const int* guesses, int guess_count, ListScratch& cache) {
  const MeshModel& geometry = context.geometry;
  auto squaredDistance = [&](int t) {
    const auto& c = geometry.corners[t];
    return context.squaredDistance(p, c);
  };
  if (hint < 0) return nearestWithHint(context, p, hint);
  const double hint_squared = squaredDistance(hint);
  std::array<std::uint64_t, 3> key;
  std::memcpy(key.data(), p.data(), sizeof key);
  auto found = cache.lattice_nearest.find(key);
  if (found == cache.lattice_nearest.end()) {
    double bound = hint_squared;
    for (int n = 0; n < guess_count; ++n) bound = std::min(bound, squaredDistance(guesses[n]));
    double best = std::nextafter(bound * (1 + 1e-12), kInfinity);
    int best_triangle = -1;
    detail::nearestTriangle(geometry, p, best, best_triangle, nullptr, context.four);
    // Nothing below the bound: distances that are not finite (coordinates near the limits of double).
    if (best_triangle < 0) return nearestWithHint(context, p, hint);
    found = cache.lattice_nearest.emplace(key, std::make_pair(best, best_triangle)).first;
  }
  const auto [nearest_squared, nearest_triangle] = found->second;
  if (!(nearest_squared < hint_squared)) return {std::sqrt(hint_squared), hint};
  return {std::sqrt(nearest_squared), nearest_triangle};
}

// Rounded down to float so that it stays a lower bound however it was rounded on the way.
float lowerFloat(double x) {
  if (!(x < double(std::numeric_limits<float>::max()))) return std::numeric_limits<float>::max();
  float f = static_cast<float>(x);
  while (double(f) > x) f = std::nextafter(f, 0.0f);
  return f;
}

// Waits for `group` inside `arena` when leaving a scope early: a wait from outside the arena could not run
// the group's task itself, which with a single thread nothing else would. Whatever the task threw is
// dropped there, as an exception is already on its way; the normal path waits (and rethrows) explicitly.
struct TaskGroupWaiter {
  tbb::task_arena& arena;
  tbb::task_group& group;
  ~TaskGroupWaiter() {
    try {
      arena.execute([&] { group.wait(); });
    } catch (...) {
    }
  }
};

// RegionTree::corner_distance_unit for corners up to `farthest` edges of their leaf from the mesh: the finest
// power of two that stores them below saturation, with a little room.
double cornerDistanceUnitFor(double farthest) {
  double unit = RegionTree::kFinestCornerDistanceUnit;
  while (unit < 1 && !(farthest < 0.99 * double(RegionTree::kCornerDistanceSaturated) * unit)) unit *= 2;
  return unit;
}

// Shared across the root cells' builds: the bytes committed so far, against the memory limit.
struct Budget {
  std::atomic<std::int64_t> bytes{0};
  std::int64_t limit = 0;
  std::atomic<bool> exceeded{false};
};

class SubtreeBuilder {
 public:
  SubtreeBuilder(const BuildContext& context, const std::vector<double>& triangle_edge, Budget& budget,
                 bool adaptive)
      : context_(context), triangle_edge_(triangle_edge), budget_(budget), adaptive_(adaptive) {}

  // Builds the cell at `slot` of out.nodes and, when it splits, its descendants.
  // parent_lower: a lower bound on the cell's distance to the mesh, its parent's (0 for a root cell).
  void build(ListScratch& scratch, const Eigen::Vector3d& min_corner, double size, int depth, double parent_lower,
             const double corner_distance[8], const int corner_triangle[8], std::uint32_t slot, Subtree& out) const {
    const std::size_t begin = out.lists.ids.size();
    const bool may_split =
        adaptive_ && depth < kDeepest && budget_.bytes.load(std::memory_order_relaxed) <= budget_.limit;
    const std::uint32_t length = computeCellList(context_, scratch, min_corner, size, corner_triangle, parent_lower,
                                                 adaptive_, may_split ? &triangle_edge_ : nullptr, out.lists);
    if (length == kCertainSplit ||
        (length != RegionTree::kNoList && shouldSplit(out, begin, length, size, depth))) {
      out.lists.ids.resize(begin);
      out.lists.bounds.resize(begin);
      split(scratch, min_corner, size, depth, out.lists.lower_bound, corner_distance, corner_triangle, slot, out);
      return;
    }
    const std::uint32_t leaf = static_cast<std::uint32_t>(out.list_length.size());
    out.nodes[slot] = RegionTree::kLeafBit | leaf;
    const bool near = out.lists.lower_bound <= kNearCells * size;
    const bool stored =
        length != RegionTree::kNoList && (!adaptive_ || length <= (near ? kLongestNearList : kLongestFarList));
    if (stored) {
      finishCellList(context_, scratch, min_corner, size, length, out.lists);
    } else {
      out.lists.ids.resize(begin);
      out.lists.bounds.resize(begin);
    }
    out.list_length.push_back(stored ? length : RegionTree::kNoList);
    out.depth.push_back(static_cast<std::uint8_t>(depth));
    out.lower_bound.push_back(lowerFloat(out.lists.lower_bound));
    std::array<float, 8> corners;
    for (int n = 0; n < 8; ++n) corners[n] = lowerFloat(corner_distance[n]);
    out.corner_distance.push_back(corners);
    // A stored list: its base id, and per entry a 16-bit id and a bound (RegionTree::list_entry_ids).
    budget_.bytes += std::int64_t(kLeafBytes + (stored ? 4 + length * 3 : 0));
  }

 private:
  // A leaf's own arrays and its node, not counting its list.
  static constexpr std::int64_t kLeafBytes =
      sizeof(std::uint32_t) * 2 + sizeof(float) + sizeof(decltype(RegionTree::leaf_corner_distance)::value_type);

  bool shouldSplit(const Subtree& out, std::size_t begin, std::uint32_t length, double size, int depth) const {
    if (!adaptive_ || depth >= kDeepest) return false;
    // The detail the cell is near: its listed triangles' mean edge.
    double edge = 0;
    for (std::size_t n = begin; n < begin + length; ++n) edge += triangle_edge_[out.lists.ids[n]];
    if (!(size > kSmallestCell * edge / std::max<std::uint32_t>(length, 1))) return false;
    if (length <= kListTarget || size <= kFarCellRatio * out.lists.lower_bound) return false;
    if (budget_.bytes.load(std::memory_order_relaxed) > budget_.limit) {
      budget_.exceeded = true;
      return false;
    }
    return true;
  }

  void split(ListScratch& scratch, const Eigen::Vector3d& min_corner, double size, int depth, double lower,
             const double corner_distance[8], const int corner_triangle[8], std::uint32_t slot, Subtree& out) const {
    Lattice lattice;
    const double half = 0.5 * size;
    // The corners' distinct triangles: near every lattice point, they bound its search.
    int guesses[8];
    int guess_count = 0;
    for (int n = 0; n < 8; ++n) {
      if (corner_triangle[n] >= 0 &&
          std::find(guesses, guesses + guess_count, corner_triangle[n]) == guesses + guess_count) {
        guesses[guess_count++] = corner_triangle[n];
      }
    }
    for (int c = 0; c < 3; ++c) {
      for (int b = 0; b < 3; ++b) {
        for (int a = 0; a < 3; ++a) {
          const int n = Lattice::index(a, b, c);
          if (a != 1 && b != 1 && c != 1) {  // a corner of the cell: known
            const int corner = (a / 2) | (b / 2) << 1 | (c / 2) << 2;
            lattice.distance[n] = corner_distance[corner];
            lattice.triangle[n] = corner_triangle[corner];
            continue;
          }
          const int hint = corner_triangle[(a / 2) | (b / 2) << 1 | (c / 2) << 2];
          const auto [distance, triangle] =
              cachedNearestWithHint(context_, min_corner + half * Eigen::Vector3d(a, b, c), hint,
                                    guesses, guess_count, scratch);
          lattice.distance[n] = std::nextafter(distance, 0.0);
          lattice.triangle[n] = triangle;
        }
      }
    }
    const std::uint32_t first = static_cast<std::uint32_t>(out.nodes.size());
    out.nodes[slot] = first;
    out.nodes.resize(first + 8);
    budget_.bytes += 8 * std::int64_t(sizeof(std::uint32_t));
    for (int octant = 0; octant < 8; ++octant) {
      const int ox = octant & 1, oy = (octant >> 1) & 1, oz = octant >> 2;
      double child_distance[8];
      int child_triangle[8];
      for (int n = 0; n < 8; ++n) {
        const int index = Lattice::index(ox + (n & 1), oy + ((n >> 1) & 1), oz + (n >> 2));
        child_distance[n] = lattice.distance[index];
        child_triangle[n] = lattice.triangle[index];
      }
      build(scratch, min_corner + half * Eigen::Vector3d(ox, oy, oz), half, depth + 1, lower, child_distance,
            child_triangle, first + octant, out);
    }
  }

  const BuildContext& context_;
  const std::vector<double>& triangle_edge_;
  Budget& budget_;
  bool adaptive_;
};

// Keeps an adaptive build's regions within `budget` bytes (see kListBudgetBytes), counting every list as
// stored (identical lists are stored once, so the model may come out smaller). Past it, first the eight
// leaves of a split cell share one list, the union of theirs with bounds from the whole cell (valid for each
// of them, in their unit), which the flattening stores once: around a thin part eight neighbouring lists
// mostly name the same stretch of it, so the union costs little more than one of them. Each leaf keeps its
// own lower bound and corner distances, which prune most of a query. The cells farthest from the mesh go
// first: their lists serve only farther queries, and the lists next to the surface, which short-range
// queries scan, stay as they are. If that is not enough, the lists farthest from the mesh are dropped
// (RegionTree::kNoList: queries take the Bvh there). Ties go by position, so that the result does not depend
// on the number of workers.
void fitListsInBudget(const BuildContext& context, const RegionTree& tree, std::vector<Subtree>& subtrees,
                      std::int64_t budget) {
  // A leaf's node and arrays (RegionTree: nodes, leaf_list, leaf_lower_bound, leaf_corner_distance), and a
  // stored list's offset, base and entries (ids and bounds).
  constexpr std::int64_t kLeafBytes = sizeof(std::uint32_t) * 2 + sizeof(float) +
                                      sizeof(decltype(RegionTree::leaf_corner_distance)::value_type);
  auto listBytes = [](std::int64_t length) {
    return std::int64_t(sizeof(std::uint32_t) + 2 * sizeof(std::uint16_t)) +
           length * std::int64_t(sizeof(std::uint16_t) + sizeof(std::uint8_t));
  };
  const std::int64_t root_count = std::int64_t(subtrees.size());
  std::int64_t bytes = std::int64_t(sizeof(std::uint32_t)) * root_count;
  for (const Subtree& subtree : subtrees) {
    bytes += std::int64_t(sizeof(std::uint32_t)) * (std::int64_t(subtree.nodes.size()) - 1) +
             kLeafBytes * std::int64_t(subtree.list_length.size());
    for (std::uint32_t length : subtree.list_length) {
      if (length != RegionTree::kNoList) bytes += listBytes(length);
    }
  }
  if (bytes <= budget) return;

  // Per subtree: where each leaf's list starts in subtree.lists, and the cells whose eight children are
  // leaves that all store a list, with the union of those lists.
  struct Group {
    std::vector<std::uint32_t> leaves;  // the cell's children that are leaves with a list
    float lower_bound;                  // the smallest of theirs
    Eigen::Vector3d center;             // the cell's
    double half;
    int depth;
    std::vector<std::int32_t> ids;      // the union of the lists, by id; by (bound, id) once merged
    std::vector<std::uint8_t> bounds;   // computed only for the groups that merge
  };
  std::vector<std::vector<std::size_t>> list_begin(subtrees.size());
  std::vector<std::vector<Group>> groups(subtrees.size());
  tbb::enumerable_thread_specific<ListScratch> scratches;
  struct Stamps {
    std::vector<std::uint32_t> stamp;  // per triangle: the last union that took it
    std::uint32_t last = 0;
  };
  tbb::enumerable_thread_specific<Stamps> stamps_per_worker;
  tbb::parallel_for(std::int64_t(0), root_count, [&](std::int64_t r) {
    const Subtree& subtree = subtrees[r];
    std::vector<std::size_t>& begin = list_begin[r];
    begin.resize(subtree.list_length.size() + 1);
    begin[0] = 0;
    for (std::size_t leaf = 0; leaf < subtree.list_length.size(); ++leaf) {
      const std::uint32_t length = subtree.list_length[leaf];
      begin[leaf + 1] = begin[leaf] + (length == RegionTree::kNoList ? 0 : length);
    }
    const int i = int(r % tree.root_dims[0]);
    const int j = int((r / tree.root_dims[0]) % tree.root_dims[1]);
    const int k = int(r / (std::int64_t(tree.root_dims[0]) * tree.root_dims[1]));
    struct Pending {
      std::uint32_t node;
      int depth;
      Eigen::Vector3d min_corner;
    };
    std::vector<Pending> stack{{0, 0, tree.origin + tree.root_size * Eigen::Vector3d(i, j, k)}};
    while (!stack.empty()) {
      const Pending cell = stack.back();
      stack.pop_back();
      const std::uint32_t value = subtree.nodes[cell.node];
      if (value & RegionTree::kLeafBit) continue;
      const double half = 0.5 * tree.cellSize(cell.depth);
      Group group;
      for (int octant = 0; octant < 8; ++octant) {
        const std::uint32_t child = subtree.nodes[value + octant];
        if (!(child & RegionTree::kLeafBit)) {
          stack.push_back({value + std::uint32_t(octant), cell.depth + 1,
                           cell.min_corner + half * Eigen::Vector3d(octant & 1, (octant >> 1) & 1, octant >> 2)});
        } else if (subtree.list_length[child & ~RegionTree::kLeafBit] != RegionTree::kNoList) {
          group.leaves.push_back(child & ~RegionTree::kLeafBit);
        }
      }
      if (group.leaves.size() < 2) continue;
      // The union in first-seen order (the merged list is sorted by its bounds later), each id once by a stamp
      // per triangle: sorting every candidate's ids took most of this step.
      Stamps& stamps = stamps_per_worker.local();
      if (stamps.stamp.empty() || stamps.last == std::numeric_limits<std::uint32_t>::max()) {
        stamps.stamp.assign(context.geometry.mesh.triangles.size(), 0);
        stamps.last = 0;
      }
      const std::uint32_t stamp = ++stamps.last;
      group.lower_bound = std::numeric_limits<float>::max();
      for (const std::uint32_t leaf : group.leaves) {
        group.lower_bound = std::min(group.lower_bound, subtree.lower_bound[leaf]);
        for (std::size_t n = begin[leaf]; n < begin[leaf + 1]; ++n) {
          const std::int32_t id = subtree.lists.ids[n];
          if (stamps.stamp[id] == stamp) continue;
          stamps.stamp[id] = stamp;
          group.ids.push_back(id);
        }
      }
      group.center = cell.min_corner + Eigen::Vector3d::Constant(half);
      group.half = half;
      group.depth = cell.depth;
      groups[r].push_back(std::move(group));
    }
  });

  // Merges, farthest cells first, while it saves and the budget is exceeded.
  struct Choice {
    float lower_bound;
    std::int64_t r;
    std::uint32_t index;  // of the group, or of the leaf
  };
  std::vector<Choice> order;
  for (std::int64_t r = 0; r < root_count; ++r) {
    for (std::uint32_t g = 0; g < groups[r].size(); ++g) order.push_back({groups[r][g].lower_bound, r, g});
  }
  auto farthestFirst = [](const Choice& a, const Choice& b) {
    if (a.lower_bound != b.lower_bound) return a.lower_bound > b.lower_bound;
    return a.r != b.r ? a.r < b.r : a.index < b.index;
  };
  std::sort(order.begin(), order.end(), farthestFirst);
  std::vector<std::vector<std::uint8_t>> merged(subtrees.size());
  for (std::int64_t r = 0; r < root_count; ++r) merged[r].assign(groups[r].size(), 0);
  for (const Choice& choice : order) {
    if (bytes <= budget) break;
    const Subtree& subtree = subtrees[choice.r];
    const Group& group = groups[choice.r][choice.index];
    std::int64_t before = 0;
    for (const std::uint32_t leaf : group.leaves) before += listBytes(subtree.list_length[leaf]);
    const std::int64_t after = listBytes(std::int64_t(group.ids.size()));
    if (after >= before) continue;
    merged[choice.r][choice.index] = 1;
    bytes -= before - after;
  }

  // The merged lists' bounds, from the whole cell (a lower bound for each of its children), in the children's
  // unit, sorted by (bound, id) as every list.
  tbb::parallel_for(std::int64_t(0), root_count, [&](std::int64_t r) {
    std::vector<std::uint64_t>& keys = scratches.local().sort_keys;
    for (std::size_t g = 0; g < groups[r].size(); ++g) {
      if (!merged[r][g]) continue;
      Group& group = groups[r][g];
      const double unit = tree.entryBoundUnit(group.depth + 1);
      keys.clear();
      // The closest points to the center four at a time where the kernels allow (the same bits).
      const std::size_t count = group.ids.size();
      for (std::size_t k = 0; k < count; k += 4) {
        const int lanes = int(std::min<std::size_t>(4, count - k));
        Eigen::Vector3d closest[4];
        if (context.four != nullptr) {
          const std::array<Eigen::Vector3d, 3>* triangles[4];
          for (int j = 0; j < 4; ++j) triangles[j] = &context.geometry.corners[group.ids[k + (j < lanes ? j : 0)]];
          double squared[4];
          context.four(group.center, triangles, squared, closest);
        } else {
          for (int j = 0; j < lanes; ++j) {
            context.squaredDistance(group.center, context.geometry.corners[group.ids[k + j]], &closest[j]);
          }
        }
        for (int j = 0; j < lanes; ++j) {
          const std::int32_t id = group.ids[k + j];
          const auto& c = context.geometry.corners[id];
          const double d_min = detail::cubeTriangleLowerBound(group.center, group.half, c[0], c[1], c[2], closest[j]);
          keys.push_back(std::uint64_t(quantizeEntryBound(d_min, unit)) << 32 | std::uint32_t(id));
        }
      }
      std::sort(keys.begin(), keys.end());
      group.bounds.resize(keys.size());
      for (std::size_t n = 0; n < keys.size(); ++n) {
        group.bounds[n] = std::uint8_t(keys[n] >> 32);
        group.ids[n] = std::int32_t(keys[n] & 0xffffffffu);
      }
    }
  });

  // Drops, farthest leaves first (a merged group's list goes with its last leaf), while still exceeded.
  std::vector<std::vector<std::uint32_t>> group_of(subtrees.size());  // per leaf: 1 + merged group, or 0
  std::vector<std::vector<std::uint8_t>> dropped(subtrees.size());
  std::vector<std::vector<std::uint8_t>> group_left(subtrees.size());  // per group: its leaves still listing
  order.clear();
  for (std::int64_t r = 0; r < root_count; ++r) {
    const Subtree& subtree = subtrees[r];
    group_of[r].assign(subtree.list_length.size(), 0);
    dropped[r].assign(subtree.list_length.size(), 0);
    group_left[r].resize(groups[r].size());
    for (std::uint32_t g = 0; g < groups[r].size(); ++g) {
      group_left[r][g] = std::uint8_t(groups[r][g].leaves.size());
      if (!merged[r][g]) continue;
      for (const std::uint32_t leaf : groups[r][g].leaves) group_of[r][leaf] = g + 1;
    }
    if (bytes <= budget) continue;
    for (std::uint32_t leaf = 0; leaf < subtree.list_length.size(); ++leaf) {
      if (subtree.list_length[leaf] != RegionTree::kNoList) order.push_back({subtree.lower_bound[leaf], r, leaf});
    }
  }
  std::sort(order.begin(), order.end(), farthestFirst);
  for (const Choice& choice : order) {
    if (bytes <= budget) break;
    dropped[choice.r][choice.index] = 1;
    const std::uint32_t g = group_of[choice.r][choice.index];
    if (g == 0) {
      bytes -= listBytes(subtrees[choice.r].list_length[choice.index]);
    } else if (--group_left[choice.r][g - 1] == 0) {
      bytes -= listBytes(std::int64_t(groups[choice.r][g - 1].ids.size()));
    }
  }

  // Rewrites the lists of the subtrees that changed, and their hashes.
  tbb::parallel_for(std::int64_t(0), root_count, [&](std::int64_t r) {
    Subtree& subtree = subtrees[r];
    bool changed = false;
    for (std::uint32_t leaf = 0; leaf < subtree.list_length.size(); ++leaf) {
      changed = changed || dropped[r][leaf] || group_of[r][leaf] != 0;
    }
    if (!changed) return;
    CellListOutput lists;
    subtree.list_hash.clear();
    for (std::uint32_t leaf = 0; leaf < subtree.list_length.size(); ++leaf) {
      std::uint32_t& length = subtree.list_length[leaf];
      if (length == RegionTree::kNoList) continue;
      if (dropped[r][leaf]) {
        length = RegionTree::kNoList;
        continue;
      }
      const std::size_t begin = lists.ids.size();
      if (const std::uint32_t g = group_of[r][leaf]) {
        const Group& group = groups[r][g - 1];
        lists.ids.insert(lists.ids.end(), group.ids.begin(), group.ids.end());
        lists.bounds.insert(lists.bounds.end(), group.bounds.begin(), group.bounds.end());
        length = std::uint32_t(group.ids.size());
      } else {
        const auto from = std::ptrdiff_t(list_begin[r][leaf]);
        lists.ids.insert(lists.ids.end(), subtree.lists.ids.begin() + from, subtree.lists.ids.begin() + from + length);
        lists.bounds.insert(lists.bounds.end(), subtree.lists.bounds.begin() + from,
                            subtree.lists.bounds.begin() + from + length);
      }
      subtree.list_hash.push_back(listHash(lists.ids.data() + begin, lists.bounds.data() + begin, length,
                                           subtree.depth[leaf]));
    }
    subtree.lists.ids = std::move(lists.ids);
    subtree.lists.bounds = std::move(lists.bounds);
  });
}

}  // namespace

std::int64_t detail::topologyNeighbourCount(const MeshModel& geometry) {
  return std::int64_t(makeTopology(geometry).edge_neighbours.size());
}

CflModel buildCflModel(TriangleMesh mesh, const BuildOptions& options) {
  const auto start = std::chrono::steady_clock::now();
  if (options.resolution < 0) {
    throw Error("resolution must be >= 1 (or 0 for adaptive regions), got " + std::to_string(options.resolution));
  }
  if (!std::isfinite(options.padding) || options.padding < 1.0) {
    std::ostringstream message;
    message << "padding must be a finite factor >= 1, got " << options.padding;
    throw Error(message.str());
  }
  if (options.memory_limit < 0) {
    throw Error("memory_limit must be >= 0 (0: half of physical memory), got " + std::to_string(options.memory_limit));
  }
  const int threads = workerCount(options.threads);
  tbb::task_arena arena(threads);
  CflModel model;
  arena.execute([&] { model.geometry = makeMeshModel(std::move(mesh)); });
  const MeshModel& geometry = model.geometry;
  model.padding = options.padding;
  model.topology_culling = options.topology_culling;
  RegionTree& tree = model.regions;
  const bool adaptive = options.resolution == 0;
  // Adaptive: a coarse root grid whose cells split where needed; uniform: the paper's grid, no splits.
  tree = makeRootGrid(geometry.bounds, adaptive ? kAdaptiveRootCells : options.resolution, options.padding);
  const std::int64_t root_count = tree.rootCount();
  const std::int64_t memory_limit =
      options.memory_limit > 0
          ? options.memory_limit
          : std::min(physicalMemoryBytes() / 2,
                     kDefaultRegionBytes + kDefaultRegionBytesPerTriangle * std::int64_t(geometry.corners.size()));
  // Every root cell costs its node, its corners and its leaf arrays at the least.
  const std::int64_t floor_bytes = root_count * std::int64_t(sizeof(std::uint32_t) * 3 + sizeof(float) * 9);
  if (root_count > std::numeric_limits<std::uint32_t>::max() / 4 || floor_bytes > memory_limit) {
    std::ostringstream message;
    message << (adaptive ? std::string("the adaptive regions' root grid")
                         : "resolution " + std::to_string(options.resolution))
            << " needs " << tree.root_dims[0] << " x " << tree.root_dims[1] << " x " << tree.root_dims[2] << " = "
            << root_count << " cells and at least " << floor_bytes << " bytes, more than the memory limit of "
            << memory_limit << " bytes; " << (adaptive ? "raise memory_limit" : "use a smaller resolution");
    throw Error(message.str());
  }
  // The sign analysis is serial and nothing else reads it: one worker runs it while the others go on with
  // the topology, the corners and the cells.
  tbb::task_group sign_task;
  arena.execute([&] { sign_task.run([&] { model.sign = analyzeMeshSign(geometry); }); });
  const TaskGroupWaiter sign_waiter{arena, sign_task};
  Topology topology;
  if (options.topology_culling) arena.execute([&] { topology = makeTopology(geometry); });
  const detail::QueryKernelTable& kernels = detail::activeQueryKernelTable();
  const detail::PointTriangles4 four = kernels.point_triangles4;
  const detail::PointTriangle1 one = kernels.point_triangle;
  std::vector<double> triangle_edge(geometry.corners.size());
  for (std::size_t t = 0; t < triangle_edge.size(); ++t) {
    const auto& c = geometry.corners[t];
    triangle_edge[t] = ((c[1] - c[0]).norm() + (c[2] - c[1]).norm() + (c[0] - c[2]).norm()) / 3;
  }
  const double largest_edge =
      triangle_edge.empty() ? 0.0 : *std::max_element(triangle_edge.begin(), triangle_edge.end());
  // Float node boxes round at about 2^-24 of the coordinates: past a ten-thousandth of the mesh's extent they
  // no longer tell its parts apart (a small part placed far from the origin), and the candidate walk prunes
  // by the nodes' spheres too.
  const double coordinate_scale = geometry.bounds.max.cwiseAbs().cwiseMax(geometry.bounds.min.cwiseAbs()).maxCoeff();
  const bool prune_by_spheres = coordinate_scale * 0x1p-23 > 1e-4 * geometry.bounds.size().maxCoeff();
  const BuildContext context{geometry, topology, options.topology_culling, early_split_decisions.load(), four, one,
                             largest_edge, prune_by_spheres};
  const auto& progress = options.progress;

  // 1. The distance field at the root grid's corners, with the nearest triangle of each. Rows are walked in
  //    order so that each corner starts from its neighbour's nearest triangle, which usually is its own.
  const int corner_dims[3] = {tree.root_dims[0] + 1, tree.root_dims[1] + 1, tree.root_dims[2] + 1};
  const std::int64_t corner_count = std::int64_t(corner_dims[0]) * corner_dims[1] * corner_dims[2];
  std::vector<double> root_corner_distance(corner_count);
  std::vector<int> root_corner_triangle(corner_count, -1);
  auto cornerIndex = [&](int i, int j, int k) {
    return i + std::int64_t(corner_dims[0]) * (j + std::int64_t(corner_dims[1]) * k);
  };
  std::atomic<std::int64_t> done{0};
  auto report = [&](double begin, double end, std::int64_t total) {
    progress(begin + (end - begin) * double(done.load()) / double(std::max<std::int64_t>(total, 1)));
  };
  const std::int64_t corner_rows = std::int64_t(corner_dims[1]) * corner_dims[2];
  ProgressTicker corner_ticker(progress, [&] { report(0.0, 0.1, corner_rows); });
  arena.execute([&] {
    tbb::parallel_for(std::int64_t(0), corner_rows, [&](std::int64_t row) {
      const int j = static_cast<int>(row % corner_dims[1]);
      const int k = static_cast<int>(row / corner_dims[1]);
      int hint = -1;
      for (int i = 0; i < corner_dims[0]; ++i) {
        const auto [distance, triangle] =
            nearestWithHint(context, tree.origin + tree.root_size * Eigen::Vector3d(i, j, k), hint);
        root_corner_distance[cornerIndex(i, j, k)] = std::nextafter(distance, 0.0);
        root_corner_triangle[cornerIndex(i, j, k)] = triangle;
        hint = triangle;
      }
      ++done;
      corner_ticker.tick();
    });
  });

  // 2. Each root cell's subtree, in parallel: work stealing balances the cells near the surface, which split
  //    deep, against the far ones, which stay whole.
  Budget budget;
  budget.limit = memory_limit;
  std::vector<Subtree> subtrees(root_count);
  tbb::enumerable_thread_specific<ListScratch> scratches;
  const SubtreeBuilder builder(context, triangle_edge, budget, adaptive);
  done = 0;
  ProgressTicker cell_ticker(progress, [&] { report(0.1, 0.95, root_count); });
  arena.execute([&] {
    tbb::parallel_for(std::int64_t(0), root_count, [&](std::int64_t r) {
      const int i = static_cast<int>(r % tree.root_dims[0]);
      const int j = static_cast<int>((r / tree.root_dims[0]) % tree.root_dims[1]);
      const int k = static_cast<int>(r / (std::int64_t(tree.root_dims[0]) * tree.root_dims[1]));
      double corner_distance[8];
      int corner_triangle[8];
      for (int n = 0; n < 8; ++n) {
        const std::int64_t c = cornerIndex(i + (n & 1), j + ((n >> 1) & 1), k + (n >> 2));
        corner_distance[n] = root_corner_distance[c];
        corner_triangle[n] = root_corner_triangle[c];
      }
      Subtree& out = subtrees[r];
      out.nodes.assign(1, 0);
      ListScratch& scratch = scratches.local();
      scratch.lattice_nearest.clear();  // points of other root cells: seldom met again
      builder.build(scratch, tree.origin + tree.root_size * Eigen::Vector3d(i, j, k), tree.root_size, 0, 0.0,
                    corner_distance, corner_triangle, 0, out);
      std::size_t offset = 0;
      for (std::size_t leaf = 0; leaf < out.list_length.size(); ++leaf) {
        const std::uint32_t length = out.list_length[leaf];
        if (length == RegionTree::kNoList) continue;
        out.list_hash.push_back(listHash(out.lists.ids.data() + offset, out.lists.bounds.data() + offset, length,
                                         out.depth[leaf]));
        offset += length;
      }
      ++done;
      cell_ticker.tick();
    }, tbb::simple_partitioner());
  });
  root_corner_distance = {};
  root_corner_triangle = {};
  if (adaptive) {
    arena.execute([&] {
      fitListsInBudget(context, tree, subtrees,
                       kListBudgetBytes + kListBudgetBytesPerTriangle * std::int64_t(geometry.corners.size()));
    });
  }
  arena.execute([&] { sign_task.wait(); });

  // 3. Flatten: root cells first, then each root cell's descendants in turn; identical lists (same ids,
  //    bounds and depth, so the bounds' unit agrees) stored once.
  std::int64_t node_count = root_count, leaf_count = 0, entry_count = 0, stored_count = 0;
  double farthest_corner = 0;  // in edges of the corner's leaf
  for (const Subtree& subtree : subtrees) {
    node_count += std::int64_t(subtree.nodes.size()) - 1;
    leaf_count += std::int64_t(subtree.list_length.size());
    entry_count += std::int64_t(subtree.lists.ids.size());
    for (std::uint32_t length : subtree.list_length) stored_count += length != RegionTree::kNoList;
    for (std::size_t leaf = 0; leaf < subtree.corner_distance.size(); ++leaf) {
      const double size = tree.cellSize(subtree.depth[leaf]);
      for (float distance : subtree.corner_distance[leaf]) farthest_corner = std::max(farthest_corner, distance / size);
    }
  }
  tree.corner_distance_unit = cornerDistanceUnitFor(farthest_corner);
  if (node_count >= std::int64_t(RegionTree::kLeafBit) || leaf_count >= std::int64_t(RegionTree::kLeafBit)) {
    throw Error("the regions need " + std::to_string(node_count) + " cells, more than a RegionTree indexes");
  }
  tree.nodes.assign(root_count, 0);
  tree.nodes.reserve(node_count);
  tree.leaf_list.reserve(leaf_count);
  tree.leaf_lower_bound.reserve(leaf_count);
  tree.leaf_corner_distance.reserve(leaf_count);
  tree.list_offsets.assign(1, 0);
  // Every stored list at most once: grown by doubling instead, the list arrays held up to twice their final
  // size, three times while being copied, next to the subtrees not yet released, and that was the peak.
  tree.list_offsets.reserve(stored_count + 1);
  tree.list_entry_ids.reserve(entry_count + 2 * stored_count);
  tree.list_entry_bounds.reserve(entry_count);
  BuildStatistics& stats = model.statistics;
  detail::HashIdTable lists_by_hash = detail::makeHashIdTable(std::size_t(stored_count));
  std::vector<std::uint8_t> list_depth;
  std::int64_t total_length = 0, longest = 0;
  for (std::int64_t r = 0; r < root_count; ++r) {
    Subtree& subtree = subtrees[r];
    const std::uint32_t node_base = static_cast<std::uint32_t>(tree.nodes.size());  // of local node 1
    const std::uint32_t leaf_base = static_cast<std::uint32_t>(tree.leaf_list.size());
    auto relocate = [&](std::uint32_t value) {
      return (value & RegionTree::kLeafBit) ? RegionTree::kLeafBit | (leaf_base + (value & ~RegionTree::kLeafBit))
                                            : node_base + value - 1;
    };
    tree.nodes[r] = relocate(subtree.nodes[0]);
    for (std::size_t n = 1; n < subtree.nodes.size(); ++n) tree.nodes.push_back(relocate(subtree.nodes[n]));
    std::size_t offset = 0, stored = 0;
    for (std::size_t leaf = 0; leaf < subtree.list_length.size(); ++leaf) {
      const std::int32_t* list = subtree.lists.ids.data() + offset;
      const std::uint8_t* bounds = subtree.lists.bounds.data() + offset;
      const std::uint8_t depth = subtree.depth[leaf];
      if (stats.leaves_per_depth.size() <= depth) stats.leaves_per_depth.resize(depth + 1, 0);
      ++stats.leaves_per_depth[depth];
      tree.max_depth = std::max<int>(tree.max_depth, depth);
      tree.leaf_lower_bound.push_back(subtree.lower_bound[leaf]);
      const double corner_unit = tree.cornerDistanceUnit(tree.cellSize(depth));
      std::array<std::uint16_t, 8> corners;
      for (int c = 0; c < 8; ++c)
        corners[c] = RegionTree::encodeCornerDistance(subtree.corner_distance[leaf][c], corner_unit);
      tree.leaf_corner_distance.push_back(corners);
      if (subtree.list_length[leaf] == RegionTree::kNoList) {
        tree.leaf_list.push_back(RegionTree::kNoList);
        ++stats.leaves_without_list;
        continue;
      }
      const std::uint32_t length = subtree.list_length[leaf];
      offset += length;
      total_length += length;
      longest = std::max<std::int64_t>(longest, length);
      const std::uint64_t hash = subtree.list_hash[stored++];
      const detail::HashIdProbe probe = detail::findHashId(lists_by_hash, hash, [&](std::uint32_t id) {
        if (tree.listLength(id) != length || list_depth[id] != depth ||
            !std::equal(bounds, bounds + length, tree.list_entry_bounds.begin() + tree.list_offsets[id])) {
          return false;
        }
        for (std::uint32_t n = 0; n < length; ++n) {
          if (tree.listTriangle(id, n) != list[n]) return false;
        }
        return true;
      });
      std::uint32_t found = probe.id;
      if (found == detail::kNoHashId) {
        found = tree.appendList(list, bounds, length);
        list_depth.push_back(depth);
        detail::insertHashId(lists_by_hash, probe.slot, hash, found);
      }
      tree.leaf_list.push_back(found);
    }
    subtree = Subtree();  // release as we go
  }
  tree.list_entry_ids.shrink_to_fit();
  tree.list_high_ids.shrink_to_fit();
  tree.list_entry_bounds.shrink_to_fit();
  tree.list_offsets.shrink_to_fit();

  stats.resolution = static_cast<int>(std::llround(tree.bounds().size().maxCoeff() / tree.cellSize(tree.max_depth)));
  stats.voxel_count = leaf_count;
  stats.average_list_length =
      double(total_length) / double(std::max<std::int64_t>(leaf_count - stats.leaves_without_list, 1));
  stats.longest_list = longest;
  stats.distinct_lists = std::int64_t(tree.list_offsets.size()) - 1;
  stats.coarsened = budget.exceeded;
  stats.memory_bytes =
      capacityBytes(tree.nodes) + capacityBytes(tree.leaf_list) + capacityBytes(tree.leaf_lower_bound) +
      capacityBytes(tree.leaf_corner_distance) + capacityBytes(tree.list_offsets) + capacityBytes(tree.list_entry_ids) +
      capacityBytes(tree.list_high_ids) + capacityBytes(tree.list_entry_bounds) +
      capacityBytes(geometry.mesh.vertices) + capacityBytes(geometry.mesh.triangles) +
      capacityBytes(geometry.corners.in_leaf_order) + capacityBytes(geometry.corners.leaf_position) +
      capacityBytes(geometry.spheres) + capacityBytes(geometry.planes) + capacityBytes(geometry.leaf_spheres) +
      capacityBytes(geometry.leaf_planes) + capacityBytes(geometry.spines) + capacityBytes(geometry.bvh.nodes) +
      capacityBytes(geometry.compact_nodes) + capacityBytes(geometry.node_spine_radii) +
      capacityBytes(geometry.bvh.triangle_ids) + memoryBytes(model.sign);
  stats.build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (progress) progress(1.0);
  return model;
}

}  // namespace cfl
