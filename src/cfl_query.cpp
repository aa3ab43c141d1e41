#include "cfl/cfl_query.h"

#include "cfl/error.h"
#include "cfl/triangle_distance.h"
#include "detail/box_triangle_bound.h"
#include "detail/nearest_triangle.h"

#include <Eigen/Geometry>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <sstream>
#include <tuple>

// The bounds' grid lookups (roundToInteger) and the distance kernels' error-free transformations rely on
// IEEE double arithmetic as written; -ffast-math would reassociate them into wrong answers.
#if defined(__FAST_MATH__)
#error "cfl must be compiled without -ffast-math: its exact queries rely on IEEE double rounding"
#endif

// Inlining decisions measured in instructions per query (see each use); other compilers take their own.
#if defined(__GNUC__)
#define CFL_NOINLINE __attribute__((noinline))
#define CFL_ALWAYS_INLINE __attribute__((always_inline))
#else
#define CFL_NOINLINE
#define CFL_ALWAYS_INLINE
#endif

namespace cfl {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Two Bvh subtrees with at most this many triangle pairs between them are tested pair by pair (each pair
// behind mayBeCloser's cheap bounds) instead of split further. Far apart, many node pairs nearly tie, and the
// last levels of splitting cost more in node bounds and heap traffic than the pairs they avoid. In `cfl bench
// data/torus_knot.obj --bands 1,2`, CFL's median went from 566 / 672 us to 263 / 314 us (OBBRSS 544 / 590);
// 16, 32, 128 and 256 were measured too, and the gain flattens past 64.
constexpr std::int64_t kSmallPairTriangles = 64;

// A node of B with at most this many triangles, popped against A's grid, bounds its triangles one by one
// and tests them nearest first instead of splitting further: the last levels of a best-first search cost
// more in heap traffic than they save. Together with the staged list scan, on 800 bunny poses at 0.5% to
// 10% of the diagonal, 8 took 12% to 20% off the median query of the version that split to single
// triangles (2: 9% to 14%; 16: about as 8).
constexpr int kSmallSubtreeTriangles = 8;

// B's pose in A's frame, applied by hand: Eigen's Isometry product carries a homogeneous row we don't need.
struct RigidTransform {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  // By columns: Eigen's matrix-vector product went through an out-of-line assignment loop; this form took
  // 0.9% to 1.6% off the instructions per query at 0.5% and 2% of the diagonal (forcing it inline cost more).
  Eigen::Vector3d apply(const Eigen::Vector3d& p) const {
    return rotation.col(0) * p[0] + rotation.col(1) * p[1] + rotation.col(2) * p[2] + translation;
  }
};

RigidTransform relativePose(const Eigen::Isometry3d& X_WA, const Eigen::Isometry3d& X_WB) {
  validatePose(X_WA, "pose of A");
  validatePose(X_WB, "pose of B");
  const Eigen::Matrix3d R_AW = X_WA.linear().transpose();
  const RigidTransform X_AB{R_AW * X_WB.linear(), R_AW * (X_WB.translation() - X_WA.translation())};
  // B's vertices in A's frame must stay within validateMesh's range, or squared distances overflow and the
  // answer would come out infinite.
  if (!(X_AB.translation.cwiseAbs().maxCoeff() <= kMaxCoordinate)) {
    std::ostringstream message;
    message << "B's origin lies at (" << X_AB.translation.transpose() << ") in A's frame, beyond " << kMaxCoordinate
            << " in magnitude: the distance would overflow double arithmetic";
    throw Error(message.str());
  }
  return X_AB;
}

// Every array of a MeshModel describes the same triangles. makeMeshModel builds them so; a model assembled or
// edited by hand may not be, and the search would read past the end of the shorter arrays.
void validateModelShape(const MeshModel& model, const char* which) {
  const std::size_t triangles = model.mesh.triangles.size();
  auto check = [&](std::size_t size, const char* field) {
    if (size == triangles) return;
    std::ostringstream message;
    message << which << ": MeshModel::" << field << " has " << size << " entries for " << triangles
            << " triangles (build the model with makeMeshModel)";
    throw Error(message.str());
  };
  check(model.corners.size(), "corners");
  check(model.spheres.size(), "spheres");
  check(model.planes.size(), "planes");
  check(model.bvh.triangle_ids.size(), "bvh.triangle_ids");
  check(model.leaf_corners.size(), "leaf_corners");
  check(model.leaf_spheres.size(), "leaf_spheres");
  check(model.leaf_planes.size(), "leaf_planes");
  if (model.bvh.nodes.empty()) {
    throw Error(std::string(which) + ": MeshModel::bvh has no nodes (build the model with makeMeshModel)");
  }
}

// Voxel index range of `grid` covering the box [lo, hi] (clamped to the grid).
void voxelRange(const VoxelGrid& grid, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi, int first[3], int last[3]) {
  for (int axis = 0; axis < 3; ++axis) {
    first[axis] = std::clamp(int(std::floor((lo[axis] - grid.origin[axis]) / grid.voxel_size)), 0, grid.dims[axis] - 1);
    last[axis] = std::clamp(int(std::floor((hi[axis] - grid.origin[axis]) / grid.voxel_size)), 0, grid.dims[axis] - 1);
  }
}

// x rounded to the nearest integer, for |x| < 2^51: adding 1.5 2^52 leaves no bits below the units, so the
// sum rounds (to nearest, the default mode); subtracting it back is exact. Unlike std::floor or a conversion
// to int and back, it stays in the vector registers: the grid lookups of the bounds below do a dozen of
// these per triangle, and with SSE2 alone (no roundsd) each std::floor is a sequence of conversions.
inline Eigen::Array3d roundToInteger(const Eigen::Array3d& x) {
  constexpr double kShift = 6755399441055744.0;  // 1.5 * 2^52
  return (x + kShift) - kShift;
}

// HeapEntry::node_a values that name no node of A.
constexpr int kAgainstGrid = -1;
constexpr int kTriangleOfB = -2;

// The search order's key for a step whose lower bound is `lower_bound` and whose piece of B has bounding
// radius `radius` (see HeapEntry::key).
inline double searchKey(double lower_bound, double radius) {
  return lower_bound > 0 ? lower_bound : -1 / (1 + radius + std::max(0.0, lower_bound + radius));
}

// How many of a list's entry bounds, sorted increasing, lie below `limit` (1 to 256): the entries a scan
// takes. Sixteen bytes at a time where the bounds array (ending at `array_end`) has them; a byte at a time,
// this loop's two branches per entry cost 2.8% of a query's instructions on wuson at 2% of the diagonal, and
// the vector form took 1.2% to 2.1% off the whole query on the bunny, the torus knot and wuson.
inline std::ptrdiff_t passingPrefix(const std::uint8_t* bounds, std::ptrdiff_t length, int limit,
                                    const std::uint8_t* array_end) {
  if (limit > 255) return length;
  std::ptrdiff_t n = 0;
#if defined(__SSE2__)
  const __m128i limits = _mm_set1_epi8(static_cast<char>(limit));
  while (n < length && array_end - (bounds + n) >= 16) {
    const __m128i block = _mm_loadu_si128(reinterpret_cast<const __m128i*>(bounds + n));
    // Bytes at or above the limit: those the unsigned max leaves unchanged.
    const int reached = _mm_movemask_epi8(_mm_cmpeq_epi8(_mm_max_epu8(block, limits), block));
    if (reached != 0) return std::min(length, n + __builtin_ctz(static_cast<unsigned>(reached)));
    n += 16;
  }
  if (n >= length) return length;
#else
  (void)array_end;
#endif
  while (n < length && bounds[n] < limit) ++n;
  return n;
}

// Asks for cache lines ahead of their use. Where the search knows an address one step before it reads it
// (the children of a node it bounds, the triangles of a subtree it is about to bound), the misses then
// overlap instead of following one another. With 64 MB read before each query (the caches emptied, as a busy
// neighbour on the machine does), the median query at 2% of the diagonal fell by 11% on wuson (73.5 to 65.3
// us), 14% on the bunny (73.8 to 63.6), 18% on the torus knot (77.3 to 63.3) and 22% on the rock (111.5 to
// 87.5); with 16 MB read, by 9% (wuson) and 16% (rock); warm, no change (wuson 21.7 against 22.0 us), for
// 0.7% to 0.9% more instructions (100 poses, alternated runs of a test program outside the repository).
// In `cfl bench`'s interleaved runs the rock's median at 0.5% / 2% went from 55.6 / 55.9 to 42.5 / 51.5 us
// (three runs each, alternated); wuson's, whose model is a fifth of the rock's, did not move.
inline void prefetch(const void* address) {
#if defined(__GNUC__)
  __builtin_prefetch(address);
#else
  (void)address;
#endif
}
inline void prefetchRange(const void* begin, const void* end) {
  constexpr std::uintptr_t kLine = 64;
  const auto first = reinterpret_cast<std::uintptr_t>(begin) & ~(kLine - 1);
  const auto last = reinterpret_cast<std::uintptr_t>(end);
  for (std::uintptr_t line = first; line < last; line += kLine) prefetch(reinterpret_cast<const void*>(line));
}

// Scratch reused across queries on one thread, so queries allocate only while it grows.
struct Scratch {
  std::vector<std::uint32_t> stamp;  // per triangle of A: the B leaf that last tested it
  std::uint32_t generation = 0;
  struct VoxelCandidate {
    double lower_bound;
    std::int64_t voxel;
    int triangle_b;
  };
  std::vector<VoxelCandidate> voxel_candidates;
  std::vector<int> outside_triangles;
  std::vector<int> list_candidates;  // testTriangleAgainstLists' triangles of A still in play
  struct HeapEntry {
    // Order of the search, nearest first: the node's lower bound when positive. Bounds <= 0 say only "may
    // overlap", and ordering by them would pop the largest nodes first: a breadth-first search where
    // overlapping meshes need a depth-first dive to the first intersecting pair, which ends the query. They
    // get -1 / (1 + radius + max(0, bound + radius)) instead (searchKey), radius that of B's node or
    // triangle: before every positive bound, the smallest piece first, and of two alike the one whose bound
    // leaves it nearer A (on overlapping bunnies 1.78x faster than the radius alone, whose choice between
    // siblings is arbitrary).
    // Pruning on the key stays valid: a key <= 0 is never pruned by a positive threshold, and a threshold
    // of 0 ends the query anyway.
    double key;
    int node_b;  // a node of B's Bvh, or with node_a == kTriangleOfB a triangle of B by its leaf position
    int node_a;  // kAgainstGrid: B's node against A's grid; otherwise a node pair of the two Bvhs
    // std::push_heap keeps the greatest on top; the nearest entry must be the greatest.
    bool operator<(const HeapEntry& other) const { return key > other.key; }
  };
  std::vector<HeapEntry> heap;
  std::vector<std::pair<int, int>> node_pairs;  // computeCollision's pending node pairs

  void beginQuery(std::size_t triangle_count) {
    if (stamp.size() < triangle_count) {
      stamp.assign(triangle_count, 0);
      generation = 0;
    }
  }
  std::uint32_t nextGeneration() {
    if (++generation == 0) {
      std::fill(stamp.begin(), stamp.end(), 0);
      generation = 1;
    }
    return generation;
  }
};

thread_local Scratch tls_scratch;

// The search state shared by both modes, everything in A's frame.
class Search {
 public:
  Search(const CflModel& a, const MeshModel& b, const RigidTransform& X_AB, const DistanceOptions& options,
         Scratch& scratch)
      : a_(a), mesh_a_(a.geometry), b_(b), X_AB_(X_AB), options_(options), scratch_(scratch) {
    validateModelShape(mesh_a_, "A's geometry");
    validateModelShape(b_, "B");
    scratch_.beginQuery(mesh_a_.corners.size());
    grid_box_ = a_.grid.bounds();
    inverse_voxel_size_ = 1 / a_.grid.voxel_size;
    const auto& dims = a_.grid.dims;
    corner_limit_ = Eigen::Array3d(dims[0], dims[1], dims[2]);
    corner_stride_ = Eigen::Array3d(1, dims[0] + 1, double(dims[0] + 1) * (dims[1] + 1));
    exact_ = options.abs_err == 0 && options.rel_err == 0;
    if (options.hint_triangle_a >= 0 && options.hint_triangle_a < int(mesh_a_.corners.size()) &&
        options.hint_triangle_b >= 0 && options.hint_triangle_b < int(b_.corners.size())) {
      PreparedTriangle tb;
      prepare(options.hint_triangle_b, tb);
      testPair(options.hint_triangle_a, tb);
    }
  }

  // A search step whose lower bound is at least this is skipped (FCL's canStop rule). A certifying search
  // (DistanceCache) looks `margin_` further, so that what it skips is known to be that far.
  double pruneThreshold() const {
    if (exact_) return best_ + margin_;
    return std::max(best_ - options_.abs_err, best_ / (1 + options_.rel_err));
  }

  // B's triangles are read by id (MeshModel::corners, spheres, planes) where a hint, the paper's mode or a
  // certificate names them, and by Bvh leaf position (MeshModel::leaf_corners, ...) where the search walks
  // B's Bvh: a subtree's triangles then lie side by side. At 2% of the diagonal (100 poses, median of 3
  // runs), with 64 MB read before each query, the median query fell from 76.8 to 65.0 us on the bunny and
  // from 77.8 to 68.6 us on wuson (torus knot 76.4 to 73.3); with 2 MB read, by 0% to 5%; warm, no change.
  void transformTriangle(const std::array<Eigen::Vector3d, 3>& c, Eigen::Vector3d out[3]) const {
    for (int n = 0; n < 3; ++n) out[n] = X_AB_.apply(c[n]);
  }

  // A triangle of B moved into A's frame, with what the pair lower bounds need.
  struct PreparedTriangle {
    int id;
    Eigen::Vector3d corners[3];
    Eigen::Vector3d center;
    double radius;
    Eigen::Vector3d normal;  // zero for a degenerate triangle
    double offset;
  };

  void prepare(int id, const std::array<Eigen::Vector3d, 3>& corners, const Eigen::Vector4d& sphere,
               const Eigen::Vector4d& plane, PreparedTriangle& out) const {
    out.id = id;
    transformTriangle(corners, out.corners);
    out.center = X_AB_.apply(sphere.head<3>());
    out.radius = sphere[3];
    out.normal = X_AB_.rotation * plane.head<3>();
    out.offset = out.normal.dot(out.corners[0]);
  }
  void prepare(int t, PreparedTriangle& out) const { prepare(t, b_.corners[t], b_.spheres[t], b_.planes[t], out); }
  void prepareAtLeaf(int n, PreparedTriangle& out) const {
    prepare(b_.bvh.triangle_ids[n], b_.leaf_corners[n], b_.leaf_spheres[n], b_.leaf_planes[n], out);
  }

  // Exact distance between triangle a of A and triangle b of B (already in A's frame); a certifying search
  // lists the pair when it is within the margin.
  // Out of line: the loops that call it run it on a few percent of their candidates, and inlined it would
  // make them save and restore its registers on every candidate.
  CFL_NOINLINE
  void testPair(int a, const PreparedTriangle& tb) {
    ++counters_.triangle_pairs;
    Eigen::Vector3d p, q;
    const double squared = triangleTriangleSquaredDistance(mesh_a_.corners[a].data(), tb.corners, &p, &q);
    const double distance = std::sqrt(squared);
    if (near_pairs_ != nullptr && distance < best_ + margin_) near_pairs_->push_back({a, tb.id});
    if (distance < best_ || best_a_ < 0) {
      best_ = distance;
      best_a_ = a;
      best_b_ = tb.id;
      point_a_ = p;
      point_b_ = q;
    }
  }

  // Whether triangle a of A may be closer to `tb` than `threshold`, by cheap lower bounds taken cheapest
  // first, each returning as soon as it decides: the bounding spheres' gap (squared, no root), the gap
  // between B's plane and A's corners (at short range the planes carry the bound: the spheres are bigger
  // than the gap), the projection on the axis between the spheres' centers (never looser than the spheres'
  // gap, and far apart nearly exact), the gap between A's plane and B's corners, and edge-edge separating
  // axes.
  bool mayBeCloser(int a, const PreparedTriangle& tb, double threshold) const {
    const Eigen::Vector4d& sphere = mesh_a_.spheres[a];
    const double reach = threshold + sphere[3] + tb.radius;
    if ((tb.center - sphere.head<3>()).squaredNorm() >= reach * reach) return false;
    return mayBeCloserBeyondSpheres(a, tb, threshold);
  }
  // mayBeCloser past the spheres' gap, for candidates already filtered on it at a threshold the search has
  // since lowered: again at the lowered one, it ruled out 5 of the 396 candidates per query on wuson at 2% of
  // the diagonal, and skipping it took 2.4% off the query's instructions (torus knot 1.1%, bunny 0.7%).
  CFL_ALWAYS_INLINE
  bool mayBeCloserBeyondSpheres(int a, const PreparedTriangle& tb, double threshold) const {
    const auto& c = mesh_a_.corners[a];
    // B's plane first, the more selective of the two: in the other order, on wuson at 2% of the diagonal, A's
    // plane ruled out 107 candidates per query and B's 205 of those left. Swapped, 1.0% to 1.3% fewer
    // instructions at 2% on the bunny, the torus knot and wuson. The center axis before A's plane, compared
    // squared (no root): 0.5% to 1.4% fewer at 0.5% and 2% on those three and the rock; before B's plane it
    // cost 0.9% to 1.6% more.
    const double t0 = tb.normal.dot(c[0]) - tb.offset, t1 = tb.normal.dot(c[1]) - tb.offset,
                 t2 = tb.normal.dot(c[2]) - tb.offset;
    if (std::max(std::min({t0, t1, t2}), -std::max({t0, t1, t2})) >= threshold) return false;
    return mayBeCloserPastBPlane(a, tb, threshold, t0, t1, t2);
  }
  // The rest of the filter, out of line: B's plane, inlined in the loops, stops most candidates (on wuson at
  // 2% of the diagonal 185 of 317 per query), and calling out for all of them cost 1.3% to 2.1% more
  // instructions per query at 2% on the four benchmark meshes (wuson 2.1% at 0.5%).
  CFL_NOINLINE
  bool mayBeCloserPastBPlane(int a, const PreparedTriangle& tb, double threshold, double t0, double t1, double t2) const {
    const auto& c = mesh_a_.corners[a];
    const Eigen::Vector4d& plane = mesh_a_.planes[a];
    const Eigen::Vector3d normal_a = plane.head<3>();
    const Eigen::Vector3d axis = tb.center - mesh_a_.spheres[a].head<3>();
    const double axis_squared = axis.squaredNorm();
    if (axis_squared > 0) {
      const double a_max = std::max({axis.dot(c[0]), axis.dot(c[1]), axis.dot(c[2])});
      const double b_min = std::min({axis.dot(tb.corners[0]), axis.dot(tb.corners[1]), axis.dot(tb.corners[2])});
      const double gap = b_min - a_max;
      if (gap > 0 && gap * gap >= threshold * threshold * axis_squared) return false;
    }
    const double s0 = normal_a.dot(tb.corners[0]) - plane[3], s1 = normal_a.dot(tb.corners[1]) - plane[3],
                 s2 = normal_a.dot(tb.corners[2]) - plane[3];
    if (std::max(std::min({s0, s1, s2}), -std::max({s0, s1, s2})) >= threshold) return false;
    return !edgeAxesSeparate(c, tb, nearestToPlane(t0, t1, t2), nearestToPlane(s0, s1, s2), threshold);
  }

  // Index of the smallest of three plane offsets in absolute value.
  static int nearestToPlane(double x0, double x1, double x2) {
    const double a0 = std::abs(x0), a1 = std::abs(x1), a2 = std::abs(x2);
    return a0 <= a1 ? (a0 <= a2 ? 0 : 2) : (a1 <= a2 ? 1 : 2);
  }

  // Whether the projections of triangle c of A and `tb` on one of four axes e_a x e_b (edges of each) are at
  // least `threshold` apart: a lower bound on their distance, tight where the closest features are two
  // edges. The pairs that pass the plane tests are mostly such near-parallel patches, and 87-90% of the
  // pairs the exact kernel then tested were no closer than the threshold. Of 3991 such pairs dumped from
  // bunny queries at 2%, all nine edge-edge axes rule out 2134; the four from the two edges at each
  // triangle's corner nearest the other's plane, taken here, 1682 for 4/9 of the cost; the one axis of the
  // two edges nearest each other's plane, 572. On 200 poses per mesh (callgrind, whole queries): at 2% of
  // the diagonal the bunny's exact tests fell from 45.6 to 28.5 per query and its instructions by 5.2%, the
  // torus knot's by 3.5%, wuson's by 2.5%; at 0.5% the bunny's by 6.7%.
  // All six corners are projected, though an edge's ends share one value in exact arithmetic: between
  // nearly parallel edges the rounded cross product is far from orthogonal to them (a sliver test failed
  // by 5.4e-9 with the shortcut), and any axis bounds the distance only if every corner is projected on it.
  // Out of line, like testPair: only the few candidates that pass every other test get here, and inlined
  // its registers were saved and restored on every call of mayBeCloser (wuson: 0.8% more instructions).
  CFL_NOINLINE
  static bool edgeAxesSeparate(const std::array<Eigen::Vector3d, 3>& c, const PreparedTriangle& tb, int corner_a,
                               int corner_b, double threshold) {
    static constexpr int kNext[3] = {1, 2, 0}, kPrevious[3] = {2, 0, 1};
    // Everything relative to A's corner: its edges, B's corner, and B's edges out of that corner.
    const Eigen::Vector3d& origin = c[corner_a];
    const Eigen::Vector3d edges_a[2] = {c[kNext[corner_a]] - origin, c[kPrevious[corner_a]] - origin};
    const Eigen::Vector3d& corner = tb.corners[corner_b];
    const Eigen::Vector3d edges_b[2] = {tb.corners[kNext[corner_b]] - corner, tb.corners[kPrevious[corner_b]] - corner};
    const Eigen::Vector3d offset = corner - origin;
    const double threshold_squared = threshold * threshold;
    for (const Eigen::Vector3d& edge_b : edges_b) {
      for (const Eigen::Vector3d& edge_a : edges_a) {
        const Eigen::Vector3d axis = edge_a.cross(edge_b);
        const double a1 = edges_a[0].dot(axis), a2 = edges_a[1].dot(axis);  // A's corner projects at 0
        const double b0 = offset.dot(axis), b1 = b0 + edges_b[0].dot(axis), b2 = b0 + edges_b[1].dot(axis);
        const double low_a = std::min(0.0, std::min(a1, a2)), high_a = std::max(0.0, std::max(a1, a2));
        const double low_b = std::min(b0, std::min(b1, b2)), high_b = std::max(b0, std::max(b1, b2));
        const double gap = std::max(low_b - high_a, low_a - high_b);
        if (gap > 0 && gap * gap >= threshold_squared * axis.squaredNorm()) return true;
      }
    }
    return false;
  }

  // `spheres_filtered`: the pair passed the spheres' gap at an earlier threshold (see mayBeCloserBeyondSpheres).
  void testPairIfClose(int a, const PreparedTriangle& tb, bool spheres_filtered = false) {
    const double threshold = pruneThreshold();
    if (!(spheres_filtered ? mayBeCloserBeyondSpheres(a, tb, threshold) : mayBeCloser(a, tb, threshold))) return;
    // A certifying search lists every pair that may lie within its margin, but tests only those that may
    // beat the best distance: the others are listed on their lower bounds, untested.
    if (near_pairs_ != nullptr && !mayBeCloser(a, tb, best_)) {
      near_pairs_->push_back({a, tb.id});
      return;
    }
    testPair(a, tb);
  }

  // The larger of a distance-field bound at `center` and the distance from `center` to A's bounding box;
  // the box's square root is taken only when the box wins.
  double fieldOrBoxBound(const Eigen::Vector3d& center, double field) const {
    const double box_squared = detail::pointBoxSquaredDistance(center, mesh_a_.bounds);
    return box_squared > field * std::abs(field) ? std::sqrt(box_squared) : field;
  }

  // The grid corner nearest a point given in voxel edges from the grid's origin (clamped to the grid).
  struct GridCorner {
    std::int64_t index;  // into corner_distance
    Eigen::Vector3d position;
  };
  GridCorner nearestCorner(const Eigen::Vector3d& point) const {
    const Eigen::Array3d rounded = roundToInteger(point.array().max(0.0).min(corner_limit_));
    return {static_cast<std::int64_t>((rounded * corner_stride_).sum()),
            a_.grid.origin + a_.grid.voxel_size * rounded.matrix()};
  }

  // The grid cell holding a point (clamped to the grid) and the field at its eight corners, read once for
  // the bounds that use both (cellLowerBound, farCornerLowerBound).
  struct GridCell {
    Eigen::Vector3d point;   // the point in voxel edges from the grid's origin
    Eigen::Vector3d corner;  // position of corner (0, 0, 0)
    double distance[8];      // corner_distance at corner (i, j, k) = distance[i + 2 j + 4 k]
  };
  GridCell cellAt(const Eigen::Vector3d& position) const {
    GridCell cell;
    cell.point = (position - a_.grid.origin) * inverse_voxel_size_;
    // The cell whose lower corner is point - 0.5 rounded; at an integer coordinate that may be the cell
    // below, which holds the point on its face.
    const Eigen::Array3d lower = roundToInteger(cell.point.array().max(0.5).min(corner_limit_ - 0.5) - 0.5);
    cell.corner = a_.grid.origin + a_.grid.voxel_size * lower.matrix();
    const double* d = a_.corner_distance.data() + static_cast<std::int64_t>((lower * corner_stride_).sum());
    const auto step_j = static_cast<std::int64_t>(corner_stride_[1]);
    const auto step_k = static_cast<std::int64_t>(corner_stride_[2]);
    for (int corner = 0; corner < 8; ++corner) {
      cell.distance[corner] = d[(corner & 1) + ((corner >> 1) & 1) * step_j + (corner >> 2) * step_k];
    }
    return cell;
  }

  // Lower bound on the distance from any point within `radius` of `center` to A, in O(1): for each of the
  // eight corners of the grid cell holding `center`, the corner's distance minus how far the point can be
  // from it (distance to a set is 1-Lipschitz), or the distance to A's bounding box when that is larger.
  // Any cell gives a valid bound. The nearest corner alone loses up to |center - corner| whatever the
  // direction to the mesh: for B's nodes too (their far-corner bound then reuses the cell), the eight took
  // 1.5% to 2.3% off the instructions per query at 0.5% and 2% of the diagonal on the bunny, the torus knot
  // and wuson.
  double cellLowerBound(const GridCell& cell, const Eigen::Vector3d& center, double radius) const {
    // Squared offsets from `center` to the cell's two corner planes on each axis, then the eight corners'
    // squared distances as a plain array, whose square roots go two by two through the vector unit: GCC
    // left them scalar, and the intrinsics took 2.2% to 3.3% off the instructions per query at 0.5% and 2%
    // of the diagonal on the bunny, the torus knot and wuson.
    const Eigen::Vector3d offset = center - cell.corner;
    const double h = a_.grid.voxel_size;
    const double dx[2] = {offset[0] * offset[0], (offset[0] - h) * (offset[0] - h)};
    const double dy[2] = {offset[1] * offset[1], (offset[1] - h) * (offset[1] - h)};
    const double dz[2] = {offset[2] * offset[2], (offset[2] - h) * (offset[2] - h)};
    double squared[8];
    for (int corner = 0; corner < 8; ++corner) {
      squared[corner] = dx[corner & 1] + dy[(corner >> 1) & 1] + dz[corner >> 2];
    }
#if defined(__SSE2__)
    __m128d best = _mm_set1_pd(-kInfinity);
    for (int corner = 0; corner < 8; corner += 2) {
      const __m128d reach = _mm_sqrt_pd(_mm_loadu_pd(squared + corner));
      // maxpd returns its second operand when either is NaN: a NaN corner is ignored, as std::max(field, x).
      best = _mm_max_pd(_mm_sub_pd(_mm_loadu_pd(cell.distance + corner), reach), best);
    }
    const double field = std::max(_mm_cvtsd_f64(best), _mm_cvtsd_f64(_mm_unpackhi_pd(best, best)));
#else
    double field = -kInfinity;
    for (int corner = 0; corner < 8; ++corner) {
      field = std::max(field, cell.distance[corner] - std::sqrt(squared[corner]));
    }
#endif
    return fieldOrBoxBound(center, field) - radius;
  }

  // Lower bounds on the distance from a convex piece of B (a triangle, an oriented box) to A, from grid
  // corners on A's far side of it. For any corner c, every point x of the piece is at least D(c) - |x - c|
  // from A, and the farthest point of a convex piece from c is one of its vertices. The corners next to the
  // piece (cellLowerBound) lose its whole radius when it faces A across a gap narrower than that radius,
  // which at short range is every piece near the answer. A corner k voxels out along the field's gradient
  // loses only about radius^2 / (2 k voxel) across a flat gap. On 300 bunny poses per band this took 23% to
  // 35% off the median query from overlapping to 50% apart and halved the nodes and triangles of B bounded.
  // `cell`: the cell holding the piece's center.
  double farCornerLowerBound(const GridCell& cell, const Eigen::Vector3d corners[3]) const {
    return farCornerBound(cell, [&](const Eigen::Vector3d& position) {
      return std::max({(corners[0] - position).squaredNorm(), (corners[1] - position).squaredNorm(),
                       (corners[2] - position).squaredNorm()});
    });
  }
  // Box axes as columns, half extents along them, all in A's frame.
  double farCornerLowerBound(const GridCell& cell, const Eigen::Vector3d& box_center, const Eigen::Matrix3d& axes,
                             const Eigen::Vector3d& half) const {
    return farCornerBound(cell, [&](const Eigen::Vector3d& position) {
      // The farthest box corner takes, on each axis, the side away from `position`.
      const Eigen::Vector3d offset = box_center - position;
      return offset.squaredNorm() + half.squaredNorm() + 2 * half.dot((axes.transpose() * offset).cwiseAbs());
    });
  }
  // `farthestSquared(p)`: the squared distance from p to the piece's farthest point.
  template <class FarthestSquared>
  double farCornerBound(const GridCell& cell, const FarthestSquared& farthestSquared) const {
    // The direction away from A: the field's gradient over the cell (any direction gives valid bounds; this
    // one gives tight ones).
    const double* d = cell.distance;
    const double d000 = d[0], d100 = d[1], d010 = d[2], d110 = d[3], d001 = d[4], d101 = d[5], d011 = d[6],
                 d111 = d[7];
    const Eigen::Vector3d gradient((d100 + d110 + d101 + d111) - (d000 + d010 + d001 + d011),
                                   (d010 + d110 + d011 + d111) - (d000 + d100 + d001 + d101),
                                   (d001 + d101 + d011 + d111) - (d000 + d100 + d010 + d110));
    const double norm = gradient.norm();
    double bound = -kInfinity;
    // A flat field gives no direction; one whose sums overflow (distances near the double range, which only
    // a damaged model file holds) none usable: a NaN direction would reach the corner index's conversion.
    if (!(norm > 0) || !std::isfinite(norm)) return bound;
    const Eigen::Vector3d direction = gradient / norm;
    // Farther corners lose less across flat gaps, nearer ones less where A curves away. {1.5, 3, 6} voxels
    // took 1.8% to 3.5% off the instructions per query of {1, 2, 3.5, 5} at 0.5% and 2% of the diagonal on
    // the bunny, the torus knot and wuson (0.9% to 3.8% overlapping and at 10% and 50%); {1, 2.5, 5},
    // {1.5, 3, 5}, {2, 3, 5} and {1, 2, 3.5, 5, 7} measured in between.
    for (double voxels : {1.5, 3.0, 6.0}) {
      const GridCorner corner = nearestCorner(cell.point + voxels * direction);
      const double reach = std::sqrt(farthestSquared(corner.position));
      bound = std::max(bound, a_.corner_distance[corner.index] - reach);
    }
    return bound;
  }

  // Lower bound on the distance from B's triangle at leaf position n to A: its sphere against the corners of
  // its cell, then, if that does not reach the threshold, the far corners.
  double triangleLowerBoundAtLeaf(int n) {
    const Eigen::Vector4d& sphere = b_.leaf_spheres[n];
    const Eigen::Vector3d center = X_AB_.apply(sphere.head<3>());
    ++counters_.voxel_tests;
    const GridCell cell = cellAt(center);
    const double bound = cellLowerBound(cell, center, sphere[3]);
    if (bound >= pruneThreshold()) return bound;
    Eigen::Vector3d corners[3];
    transformTriangle(b_.leaf_corners[n], corners);
    return std::max(bound, farCornerLowerBound(cell, corners));
  }

  // Triangle tb of B against the CFLs of the voxels the box [lo, hi] covers (its bounding box, grown in a
  // certifying search). Every point of the triangle lies in one of them, and each point's closest triangle
  // of A is in its voxel's list, so the minimum over these lists is the triangle's exact distance to A.
  //
  // In stages, each a loop without data-dependent branches that writes its survivors to a buffer: first
  // the lists' entries (each triangle once), then the bounding spheres. Most entries fail the sphere test
  // and which ones do is unpredictable; branching on it per entry cost more in mispredictions than the
  // tests themselves. Stages use the threshold at the start, which only errs on the side of testing more.
  void testTriangleAgainstLists(const PreparedTriangle& tb, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    int first[3], last[3];
    voxelRange(a_.grid, lo, hi, first, last);
    const std::uint32_t generation = scratch_.nextGeneration();
    const VoxelGrid& grid = a_.grid;
    if (best_a_ < 0) {
      // No pair yet: every entry would pass the filters below and reach the exact test. The nearest entry of
      // the voxel holding the triangle's center goes first, and its distance filters the rest (on 200 poses
      // at 2% of the diagonal, 0.4% to 2.5% fewer instructions on the torus knot, the bunny and wuson).
      const Eigen::Vector3d cell = (tb.center - grid.origin) * inverse_voxel_size_;
      const std::int64_t v = grid.voxelIndex(std::clamp(int(cell[0]), first[0], last[0]),
                                             std::clamp(int(cell[1]), first[1], last[1]),
                                             std::clamp(int(cell[2]), first[2], last[2]));
      if (a_.listBegin(v) != a_.listEnd(v)) testPair(*a_.listBegin(v), tb);
    }
    const double threshold = pruneThreshold();
    auto& candidates = scratch_.list_candidates;
    std::size_t count = 0;
    // An entry whose bound, in entryBoundUnit()s, is code_limit or more is at least the threshold away:
    // floor(threshold / unit) + 1 > threshold / unit exactly, whatever the division's rounding (it is
    // monotone). Bytes compared as integers, not converted entry by entry.
    const double units = threshold / a_.entryBoundUnit();
    const int code_limit = units < 255 ? int(units) + 1 : 256;
    const std::uint8_t* bounds_end = a_.list_entry_bounds.data() + a_.list_entry_bounds.size();
    // Voxels of the box that tb's plane misses by more than the margin hold no point within the margin of
    // tb: on wuson at 2% of the diagonal, 15% of the box's voxels (instructions -2.4%; bunny -0.9%, torus
    // knot -0.4%). A voxel reaches h/2 |n|_1 either side of its center along the unit normal n. The slack,
    // 1e-9 of the coordinates' size, dwarfs the rounding of these sums and tb's corners' offsets from its
    // plane (a few eps, see makeMeshModel), so no voxel holding a point of tb is skipped. A degenerate
    // triangle's zero normal skips none.
    const double h = grid.voxel_size;
    const Eigen::Vector3d first_center = grid.voxelCenter(first[0], first[1], first[2]);
    const double size = std::abs(tb.offset) + first_center.cwiseAbs().sum() + (hi - lo).sum() + 3 * h;
    const double slab = 0.5 * h * tb.normal.lpNorm<1>() + margin_ + 1e-9 * size;
    const Eigen::Vector3d plane_step = h * tb.normal;  // from a voxel to the next along each axis
    const double plane_first = tb.normal.dot(first_center) - tb.offset;
    for (int k = first[2]; k <= last[2]; ++k) {
      for (int j = first[1]; j <= last[1]; ++j) {
        const double plane_row = plane_first + (k - first[2]) * plane_step[2] + (j - first[1]) * plane_step[1];
        for (int i = first[0]; i <= last[0]; ++i) {
          const std::int64_t v = grid.voxelIndex(i, j, k);
          ++counters_.voxel_tests;
          if (std::abs(plane_row + (i - first[0]) * plane_step[0]) > slab) continue;
          if (a_.voxel_lower_bound[v] >= threshold) continue;
          // The part of tb inside this voxel is at least an entry's bound from its triangle, and any other
          // part of tb lies in a voxel of its own: once the bounds reach the threshold, the rest of this
          // list cannot give a closer pair. Entries are sorted by bound, nearest first.
          const std::int32_t* ids = a_.listBegin(v);
          const std::uint8_t* bounds = a_.listBoundsBegin(v);
          const std::ptrdiff_t length = a_.listEnd(v) - ids;
          const std::ptrdiff_t end = passingPrefix(bounds, length, code_limit, bounds_end);
          if (candidates.size() < count + std::size_t(end)) candidates.resize(2 * (count + end));
          std::uint32_t* stamp = scratch_.stamp.data();
          int* out = candidates.data();
          for (std::ptrdiff_t n = 0; n < end; ++n) {
            const int t = ids[n];
            const bool fresh = stamp[t] != generation;
            stamp[t] = generation;
            out[count] = t;
            count += fresh;
          }
        }
      }
    }
    // Bounding spheres, squared: the center gap against the reach.
    int* ids = candidates.data();
    std::size_t near = 0;
    for (std::size_t n = 0; n < count; ++n) {
      const int t = ids[n];
      const Eigen::Vector4d& sphere = mesh_a_.spheres[t];
      const double reach = threshold + sphere[3] + tb.radius;
      const double dx = tb.center[0] - sphere[0], dy = tb.center[1] - sphere[1], dz = tb.center[2] - sphere[2];
      ids[near] = t;
      near += dx * dx + dy * dy + dz * dz < reach * reach;
    }
    for (std::size_t n = 0; n < near && best_ > 0; ++n) testPairIfClose(ids[n], tb, true);  // 0 ends the query
  }

  // Triangle tb of B against A's Bvh: exact wherever the triangle is, for the parts outside the grid.
  void testTriangleAgainstBvh(const PreparedTriangle& tb) {
    const auto& nodes = mesh_a_.bvh.nodes;
    int stack[128];  // depth-first, one pending sibling per level of a median-split tree
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const BvhNode& node = nodes[stack[--top]];
      ++counters_.voxel_tests;
      const double gap = std::sqrt(detail::pointBoxSquaredDistance(tb.center, node.box)) - tb.radius;
      if (gap >= pruneThreshold()) continue;
      if (node.isLeaf()) {
        for (int n = node.first; n < node.first + node.count; ++n) {
          testPairIfClose(mesh_a_.bvh.triangle_ids[n], tb);
        }
        continue;
      }
      const double d_left = detail::pointBoxSquaredDistance(tb.center, nodes[node.first].box);
      const double d_right = detail::pointBoxSquaredDistance(tb.center, nodes[node.first + 1].box);
      if (d_left <= d_right) {
        stack[top++] = node.first + 1;
        stack[top++] = node.first;
      } else {
        stack[top++] = node.first;
        stack[top++] = node.first + 1;
      }
    }
  }

  // B's triangle at leaf position n against A.
  void testTriangleAtLeaf(int n) {
    PreparedTriangle tb;
    prepareAtLeaf(n, tb);
    // A certifying search lists the pairs the triangle may form at the poses its certificate answers, B
    // moved by up to the margin: the closest triangles of A to every point it can reach are in the lists of
    // the voxels within the margin of it (or, past the grid, anywhere: the Bvh path).
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(margin_);
    const Eigen::Vector3d lo = tb.corners[0].cwiseMin(tb.corners[1]).cwiseMin(tb.corners[2]) - reach;
    const Eigen::Vector3d hi = tb.corners[0].cwiseMax(tb.corners[1]).cwiseMax(tb.corners[2]) + reach;
    if ((lo.array() >= grid_box_.min.array()).all() && (hi.array() <= grid_box_.max.array()).all()) {
      testTriangleAgainstLists(tb, lo, hi);
    } else {
      testTriangleAgainstBvh(tb);
    }
  }

  // A node of B's Bvh moved into A's frame, once for all the nodes of A it meets.
  struct PlacedNode {
    const BvhNode* node;
    Eigen::Vector3d center;  // of the node's sphere
    Eigen::Matrix3d obb_axes;
    Eigen::Vector3d obb_center;
  };

  PlacedNode place(int b, const Eigen::Vector3d& center) const {
    const BvhNode& node = b_.bvh.nodes[b];
    return {&node, center, X_AB_.rotation * node.obb_axes, X_AB_.apply(node.obb_center)};
  }

  // Lower bound between node a of A's Bvh and a placed node of B: the larger of the sphere-box gap and the
  // separation of the two oriented boxes along the seven axes that matter for distance (each box's three
  // axes and the line joining their centers). The oriented boxes are thin across flat patches, where facing
  // surfaces are separated along their normals. Returns as soon as the spheres alone reach `threshold`: the
  // pair is pruned whatever the boxes say.
  double nodePairLowerBound(int a, const PlacedNode& b, double threshold) const {
    const BvhNode& node_a = mesh_a_.bvh.nodes[a];
    const BvhNode& node_b = *b.node;
    double bound = std::max(std::sqrt(detail::pointBoxSquaredDistance(b.center, node_a.box)),
                            (b.center - node_a.center).norm() - node_a.radius) -
                   node_b.radius;
    if (bound >= threshold) return bound;
    // Everything in A's box frame: B's axes as columns, the offset between the centers, and the absolute
    // cosines between the two sets of axes.
    const Eigen::Matrix3d axes_b = node_a.obb_axes.transpose() * b.obb_axes;
    const Eigen::Vector3d offset = node_a.obb_axes.transpose() * (b.obb_center - node_a.obb_center);
    const Eigen::Matrix3d cosines = axes_b.cwiseAbs();
    const Eigen::Vector3d& half_a = node_a.obb_half;
    const Eigen::Vector3d& half_b = node_b.obb_half;
    // A's axes: the box of A reaches half_a[i], B's box reaches sum_j cosines(i, j) half_b[j].
    const Eigen::Vector3d gap_a = offset.cwiseAbs() - half_a - cosines * half_b;
    // B's axes.
    const Eigen::Vector3d offset_in_b = axes_b.transpose() * offset;
    const Eigen::Vector3d gap_b = offset_in_b.cwiseAbs() - half_b - cosines.transpose() * half_a;
    bound = std::max({bound, gap_a.maxCoeff(), gap_b.maxCoeff()});
    const double length = offset.norm();
    if (length > 0) {
      const double reach_a = half_a.dot(offset.cwiseAbs());
      const double reach_b = half_b.dot(offset_in_b.cwiseAbs());
      bound = std::max(bound, (length * length - reach_a - reach_b) / length);
    }
    return bound;
  }

  // Default mode: best-first over B's Bvh. A node of B is bounded against A's distance field in O(1); once
  // a node lies wholly outside A's grid it continues as node pairs of the two Bvhs. The search ends when the
  // smallest pending lower bound cannot beat the best pair.
  //
  // An expanded entry offers at most two children. The nearer one is taken next without passing through the
  // heap whenever nothing pending is nearer: the order stays best-first, and a push and a pop, a good part
  // of a node test's cost, are saved on most steps.
  void runHierarchical() {
    const auto& nodes_b = b_.bvh.nodes;
    auto& heap = scratch_.heap;
    heap.clear();
    Scratch::HeapEntry offered[2];
    int offered_count = 0;
    auto offer = [&](double lower_bound, int node_b, int node_a) {
      if (lower_bound >= pruneThreshold()) return;
      offered[offered_count++] = {searchKey(lower_bound, nodes_b[node_b].radius), node_b, node_a};
    };
    auto offerAgainstGrid = [&](int n) {
      ++counters_.voxel_tests;
      const Eigen::Vector3d center = X_AB_.apply(nodes_b[n].center);
      const double radius = nodes_b[n].radius;
      if (!nodes_b[n].isLeaf()) {
        // If this node is expanded, its children's spheres and oriented boxes are read next (not their
        // axis-aligned boxes, which only the Bvh-against-Bvh paths use).
        const BvhNode* children = &nodes_b[nodes_b[n].first];
        for (int child = 0; child < 2; ++child) {
          prefetch(&children[child].center);
          prefetch(&children[child].obb_axes);
          prefetch(&children[child].obb_half);
        }
      }
      const GridCell cell = cellAt(center);
      const double lower_bound = cellLowerBound(cell, center, radius);
      const Eigen::Vector3d nearest = center.cwiseMax(grid_box_.min).cwiseMin(grid_box_.max);
      if ((nearest - center).squaredNorm() > radius * radius) {
        offer(std::max(lower_bound, nodePairLowerBound(0, place(n, center), pruneThreshold())), n, 0);
      } else if (lower_bound < pruneThreshold() && radius < 1.5 * a_.grid.voxel_size) {
        // Larger nodes are rarely flat enough for the far corners to beat the sphere's bound (overlapping
        // bunnies: 1.59x with this limit, 1.41x without). 1.5 voxels rather than 2 since the nodes' spheres
        // are near the smallest: 0.5% to 2.3% fewer instructions at 0.5% and 2% of the diagonal on the
        // bunny, the torus knot and wuson; at 10% bunny -2.9%, torus knot +0.9%; 3% to 7% more overlapping.
        const PlacedNode placed = place(n, center);
        const double far =
            farCornerLowerBound(cell, placed.obb_center, placed.obb_axes, placed.node->obb_half);
        offer(std::max(lower_bound, far), n, kAgainstGrid);
      } else {
        offer(lower_bound, n, kAgainstGrid);
      }
    };
    auto push = [&](const Scratch::HeapEntry& entry) {
      heap.push_back(entry);
      std::push_heap(heap.begin(), heap.end());
    };
    offerAgainstGrid(0);
    Scratch::HeapEntry entry;
    bool have_entry = false;
    if (offered_count > 0) entry = offered[0], have_entry = true;
    while (true) {
      if (!have_entry) {
        if (heap.empty()) break;
        std::pop_heap(heap.begin(), heap.end());
        entry = heap.back();
        heap.pop_back();
      }
      have_entry = false;
      // `entry` is the nearest pending one. Distance 0 cannot be beaten.
      if (entry.key >= pruneThreshold() || best_ <= 0) break;
      offered_count = 0;
      expand(entry, offer, offerAgainstGrid, push);
      if (offered_count == 2 && offered[1].key < offered[0].key) std::swap(offered[0], offered[1]);
      if (offered_count == 2) push(offered[1]);
      if (offered_count >= 1) {
        if (heap.empty() || offered[0].key <= heap.front().key) {
          entry = offered[0];
          have_entry = true;
        } else {
          push(offered[0]);
        }
      }
    }
  }

  // Whether a node of B lies wholly in A's grid (by its sphere): its triangles then take the lists' path,
  // and bounding them one by one against the grid cannot cost the node pairs' pruning outside it.
  bool insideGrid(const BvhNode& node) const {
    const Eigen::Vector3d center = X_AB_.apply(node.center);
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(node.radius);
    return ((center - reach).array() >= grid_box_.min.array()).all() &&
           ((center + reach).array() <= grid_box_.max.array()).all();
  }

  // One step of runHierarchical: tests a triangle or a leaf's triangles, or offers the children of a node
  // (the larger node of a pair, by sphere radius; a leaf is never split).
  template <class Offer, class OfferAgainstGrid, class Push>
  void expand(const Scratch::HeapEntry& entry, Offer& offer, OfferAgainstGrid& offerAgainstGrid, Push& push) {
    if (entry.node_a == kTriangleOfB) {
      testTriangleAtLeaf(entry.node_b);
      return;
    }
    const BvhNode& node_b = b_.bvh.nodes[entry.node_b];
    if (entry.node_a == kAgainstGrid) {
      if (node_b.subtree_count <= kSmallSubtreeTriangles && insideGrid(node_b)) {
        // Queued on its nearest corner's bound; each triangle's cell may already rule it out. Its triangles
        // are tested nearest first, without the heap traffic of the last levels, while none pending is
        // nearer; the rest go back to the heap on their own bounds. Testing them all at once would scan
        // triangles far from the answer before any pair is known, when every list entry passes the
        // filters: on wuson at 2% of the diagonal the exact pair tests fell from 39.4 to 29.4 per query
        // and the instructions by 7.6% (bunny 1.8% at 2%, 3.8% at 0.5%; torus knot 2.4% at 2%).
        const int first = node_b.subtree_first, last = first + node_b.subtree_count;
        prefetchRange(&b_.leaf_spheres[first], b_.leaf_spheres.data() + last);
        prefetchRange(&b_.leaf_corners[first], b_.leaf_corners.data() + last);
        prefetchRange(&b_.leaf_planes[first], b_.leaf_planes.data() + last);
        std::pair<double, int> order[kSmallSubtreeTriangles];
        int count = 0;
        for (int n = node_b.subtree_first; n < node_b.subtree_first + node_b.subtree_count; ++n) {
          order[count++] = {triangleLowerBoundAtLeaf(n), n};
        }
        std::sort(order, order + count);
        const auto& heap = scratch_.heap;
        bool deferred = false;
        for (int n = 0; n < count && order[n].first < pruneThreshold() && best_ > 0; ++n) {
          const auto [lower_bound, leaf] = order[n];
          const double key = searchKey(lower_bound, b_.leaf_spheres[leaf][3]);
          deferred = deferred || (!heap.empty() && key > heap.front().key);
          if (deferred) {
            push(Scratch::HeapEntry{key, leaf, kTriangleOfB});
          } else {
            testTriangleAtLeaf(leaf);
          }
        }
      } else if (node_b.isLeaf()) {  // a Bvh built with larger leaves
        for (int n = node_b.first; n < node_b.first + node_b.count; ++n) testTriangleAtLeaf(n);
      } else {
        offerAgainstGrid(node_b.first);
        offerAgainstGrid(node_b.first + 1);
      }
      return;
    }
    const BvhNode& node_a = mesh_a_.bvh.nodes[entry.node_a];
    if ((node_a.isLeaf() && node_b.isLeaf()) ||
        std::int64_t(node_a.subtree_count) * node_b.subtree_count <= kSmallPairTriangles) {
      for (int n = node_b.subtree_first; n < node_b.subtree_first + node_b.subtree_count; ++n) {
        PreparedTriangle tb;
        prepareAtLeaf(n, tb);
        for (int m = node_a.subtree_first; m < node_a.subtree_first + node_a.subtree_count; ++m) {
          testPairIfClose(mesh_a_.bvh.triangle_ids[m], tb);
        }
      }
      return;
    }
    if (!node_a.isLeaf() && (node_b.isLeaf() || node_a.radius >= node_b.radius)) {
      const PlacedNode placed = place(entry.node_b, X_AB_.apply(node_b.center));
      for (int child = node_a.first; child <= node_a.first + 1; ++child) {
        ++counters_.voxel_tests;
        offer(std::max(entry.key, nodePairLowerBound(child, placed, pruneThreshold())), entry.node_b, child);
      }
    } else {
      for (int child = node_b.first; child <= node_b.first + 1; ++child) {
        ++counters_.voxel_tests;
        const PlacedNode placed = place(child, X_AB_.apply(b_.bvh.nodes[child].center));
        offer(nodePairLowerBound(entry.node_a, placed, pruneThreshold()), child, entry.node_a);
      }
    }
  }

  // Is triangle j of B listed in a voxel of B's grid that triangle a of A touches? A necessary condition
  // for (a, j) to be the closest pair (the mutual closest-feature condition, paper equation 5): at the
  // closest pair (p on a, q on j), j is the closest triangle of B to p. Returns true when it cannot tell
  // (a outside B's grid).
  bool mutualCondition(const CflModel& b_model, const RigidTransform& X_BA, int a, int j) {
    const auto& c = mesh_a_.corners[a];
    const Eigen::Vector3d p0 = X_BA.apply(c[0]), p1 = X_BA.apply(c[1]), p2 = X_BA.apply(c[2]);
    const Eigen::Vector3d lo = p0.cwiseMin(p1).cwiseMin(p2), hi = p0.cwiseMax(p1).cwiseMax(p2);
    const Aabb box = b_model.grid.bounds();
    if (!(lo.array() >= box.min.array()).all() || !(hi.array() <= box.max.array()).all()) return true;
    const VoxelGrid& grid = b_model.grid;
    int first[3], last[3];
    voxelRange(grid, lo, hi, first, last);
    for (int k = first[2]; k <= last[2]; ++k) {
      for (int jj = first[1]; jj <= last[1]; ++jj) {
        for (int i = first[0]; i <= last[0]; ++i) {
          const std::int64_t v = grid.voxelIndex(i, jj, k);
          ++counters_.voxel_tests;
          if (std::find(b_model.listBegin(v), b_model.listEnd(v), j) != b_model.listEnd(v)) return true;
        }
      }
    }
    return false;
  }

  // The paper's four steps (section 4). `b_model` is B's CflModel when it has one (for step 2).
  void runPaper(const CflModel* b_model, const RigidTransform* X_BA) {
    auto& candidates = scratch_.voxel_candidates;
    auto& outside = scratch_.outside_triangles;
    candidates.clear();
    outside.clear();
    const VoxelGrid& grid = a_.grid;
    const double half = 0.5 * grid.voxel_size;
    const double touch_slack = 1e-9 * grid.voxel_size;
    // Step 1: voxels of A touched by triangles of B, through B's Bvh (nodes missing the grid are skipped).
    const auto& nodes = b_.bvh.nodes;
    int stack[128];
    int top = 0;
    stack[top++] = 0;
    while (top > 0) {
      const BvhNode& node = nodes[stack[--top]];
      ++counters_.voxel_tests;
      if (!node.isLeaf()) {
        stack[top++] = node.first;
        stack[top++] = node.first + 1;
        continue;
      }
      for (int n = node.first; n < node.first + node.count; ++n) {
        const int t = b_.bvh.triangle_ids[n];
        Eigen::Vector3d tb[3];
        transformTriangle(b_.leaf_corners[n], tb);
        const Eigen::Vector3d lo = tb[0].cwiseMin(tb[1]).cwiseMin(tb[2]);
        const Eigen::Vector3d hi = tb[0].cwiseMax(tb[1]).cwiseMax(tb[2]);
        if (!(lo.array() >= grid_box_.min.array()).all() || !(hi.array() <= grid_box_.max.array()).all()) {
          outside.push_back(t);
          continue;
        }
        int first[3], last[3];
        voxelRange(a_.grid, lo, hi, first, last);
        for (int k = first[2]; k <= last[2]; ++k) {
          for (int j = first[1]; j <= last[1]; ++j) {
            for (int i = first[0]; i <= last[0]; ++i) {
              ++counters_.voxel_tests;
              const Eigen::Vector3d voxel_center = grid.voxelCenter(i, j, k);
              // Only voxels the triangle really touches (separating axis test). The slack keeps a triangle
              // lying exactly on a voxel face in both voxels whatever the rounding.
              Eigen::Vector3d closest;
              pointTriangleSquaredDistance(voxel_center, tb[0], tb[1], tb[2], &closest);
              if (detail::cubeTriangleLowerBound(voxel_center, half, tb[0], tb[1], tb[2], closest) > touch_slack) continue;
              const std::int64_t v = grid.voxelIndex(i, j, k);
              candidates.push_back({a_.voxel_lower_bound[v], v, t});
            }
          }
        }
      }
    }
    // Steps 3 and 4: voxels in increasing lower bound, each list against the triangles of B in it.
    std::sort(candidates.begin(), candidates.end(),
              [](const auto& x, const auto& y) { return x.lower_bound < y.lower_bound; });
    for (const auto& candidate : candidates) {
      if (candidate.lower_bound >= pruneThreshold()) break;
      PreparedTriangle tb;
      prepare(candidate.triangle_b, tb);
      for (const std::int32_t* it = a_.listBegin(candidate.voxel); it != a_.listEnd(candidate.voxel); ++it) {
        if (b_model && !mutualCondition(*b_model, *X_BA, *it, candidate.triangle_b)) continue;
        testPair(*it, tb);
      }
    }
    for (int t : outside) {
      PreparedTriangle tb;
      prepare(t, tb);
      testTriangleAgainstBvh(tb);
    }
  }

  double best() const { return best_; }
  bool found() const { return best_a_ >= 0; }

  // From now on, search `margin` past the best distance, take each triangle of B against the voxel lists
  // within `margin` of it, and append to `near` every pair not pruned below the best distance + margin at
  // the time (repeats allowed). After a complete search, with level = best() + margin: every pair missing
  // from `near` was pruned by a lower bound of at least level, or tested and found that far, or never came
  // up because its triangle of A is in no list within `margin` of its triangle of B. So wherever a point
  // of B moves by r <= margin, either it stays at least level - r from A, or a closest triangle of A to it is
  // listed with its triangle of B.
  void certify(double margin, std::vector<std::array<int, 2>>* near) {
    margin_ = margin;
    near_pairs_ = near;
  }

  // The pairs (triangle of A, triangle of B) in [begin, end), grouped by B's triangle, each behind
  // mayBeCloser: a certificate's pairs at a new pose.
  void testPairs(const std::array<int, 2>* begin, const std::array<int, 2>* end) {
    PreparedTriangle tb;
    tb.id = -1;
    for (const std::array<int, 2>* pair = begin; pair != end && best_ > 0; ++pair) {
      if ((*pair)[1] != tb.id) prepare((*pair)[1], tb);
      testPairIfClose((*pair)[0], tb);
    }
  }

  DistanceResult result(const Eigen::Isometry3d& X_WA) const {
    DistanceResult r;
    r.counters = counters_;
    if (best_a_ < 0) return r;
    r.distance = best_;
    r.triangle_a = best_a_;
    r.triangle_b = best_b_;
    r.point_a = X_WA * point_a_;
    r.point_b = r.distance == 0 ? r.point_a : Eigen::Vector3d(X_WA * point_b_);
    return r;
  }

 private:
  const CflModel& a_;
  const MeshModel& mesh_a_;
  const MeshModel& b_;
  RigidTransform X_AB_;
  const DistanceOptions& options_;
  Scratch& scratch_;
  Aabb grid_box_;
  double inverse_voxel_size_ = 0;
  // Grid corners as doubles: the largest corner index on each axis, and how far apart consecutive corners
  // along each axis sit in corner_distance (an index is the dot product with it, exact in double).
  Eigen::Array3d corner_limit_ = Eigen::Array3d::Zero();
  Eigen::Array3d corner_stride_ = Eigen::Array3d::Zero();
  bool exact_ = true;  // no abs_err / rel_err: pruneThreshold's common case, read on every pair
  QueryCounters counters_;
  double best_ = kInfinity;
  double margin_ = 0;
  std::vector<std::array<int, 2>>* near_pairs_ = nullptr;  // (triangle of A, triangle of B)
  int best_a_ = -1, best_b_ = -1;
  Eigen::Vector3d point_a_, point_b_;
};

void validateOptions(const DistanceOptions& options) {
  if (!(options.rel_err >= 0) || !std::isfinite(options.rel_err) || !(options.abs_err >= 0) ||
      !std::isfinite(options.abs_err)) {
    std::ostringstream message;
    message << "rel_err and abs_err must be finite and >= 0, got rel_err " << options.rel_err << " and abs_err "
            << options.abs_err;
    throw Error(message.str());
  }
}

DistanceResult distanceImpl(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                            const Eigen::Isometry3d& X_WB, const DistanceOptions& options, const CflModel* b_model) {
  validateOptions(options);
  const RigidTransform X_AB = relativePose(X_WA, X_WB);
  Search search(a, b, X_AB, options, tls_scratch);
  if (options.mode == QueryMode::kPaper) {
    RigidTransform X_BA;
    if (b_model) X_BA = RigidTransform{X_AB.rotation.transpose(), -(X_AB.rotation.transpose() * X_AB.translation)};
    search.runPaper(b_model, b_model ? &X_BA : nullptr);
  } else {
    search.runHierarchical();
  }
  return search.result(X_WA);
}

}  // namespace

void validatePose(const Eigen::Isometry3d& X, const char* what) {
  const Eigen::Matrix4d& m = X.matrix();
  if (!m.allFinite()) {
    std::ostringstream message;
    message << what << " is not finite:\n" << m;
    throw Error(message.str());
  }
  const Eigen::Matrix3d R = X.linear();
  const double orthonormality = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  const double determinant = R.determinant();
  if (orthonormality > 1e-6 || std::abs(determinant - 1) > 1e-6) {
    std::ostringstream message;
    message << what << " is not a rigid transform: its rotation has |R^T R - I| = " << orthonormality
            << " and det(R) = " << determinant << " (both must be within 1e-6 of a rotation)";
    throw Error(message.str());
  }
}

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options) {
  return distanceImpl(a, X_WA, b, X_WB, options, nullptr);
}

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options) {
  return distanceImpl(a, X_WA, b.geometry, X_WB, options, &b);
}

namespace {

// Bound on how far any point of B (inside the box `bounds_b`, B's frame) moves in A's frame between the
// relative poses (R0, p0) and (R1, p1): the box's center moves by |(R1 - R0) c + p1 - p0|, and any other
// point at most |R1 - R0| r farther. The spectral norm |R1 - R0| is bounded without an eigen solver: the
// largest eigenvalue of the positive semi-definite M^T M is at most its largest absolute row sum, and at
// most its trace (the Frobenius norm squared). For two rotations that is within 1.16x of exact, where the
// Frobenius norm alone is 1.41x. The slack covers rounding in these products and in the poses' own.
double motionBound(const Aabb& bounds_b, const Eigen::Matrix3d& R0, const Eigen::Vector3d& p0,
                   const Eigen::Matrix3d& R1, const Eigen::Vector3d& p1) {
  const Eigen::Vector3d center = bounds_b.center();
  const double radius = 0.5 * bounds_b.diagonal();
  const Eigen::Matrix3d turn = R1 - R0;
  const Eigen::Matrix3d gram = turn.transpose() * turn;
  const double largest_eigenvalue = std::min(gram.cwiseAbs().rowwise().sum().maxCoeff(), gram.trace());
  const double spectral_norm = std::sqrt(std::max(largest_eigenvalue, 0.0));
  const double bound = (turn * center + (p1 - p0)).norm() + spectral_norm * radius;
  const double scale = center.norm() + radius + p0.norm() + p1.norm();
  return bound * (1 + 1e-9) + 1e-14 * scale;
}

// The margin of a certifying search, from the step (the motion bound since the previous query). A margin
// m lasts about m / step frames; the search that sets it costs more as m grows (about 1 + 5 m / voxel times
// a plain search on the bunny at 1% apart), and so do the frames that reuse it (they test every triangle
// within the margin). Their sum per frame is least near m = sqrt(step * voxel / kMarginCost). Past
// kLargestCertifiedStep voxels per step, even that margin costs more per frame than a search with the
// previous pair as a hint, and the query searches without one.
constexpr double kMarginCost = 1.5;
constexpr double kLargestCertifiedStep = 0.05;

}  // namespace

DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                               const Eigen::Isometry3d& X_WB, DistanceCache& cache, const DistanceOptions& options) {
  validateOptions(options);
  if (options.mode != QueryMode::kHierarchical || options.rel_err != 0 || options.abs_err != 0) {
    cache.reset();
    return computeDistance(a, X_WA, b, X_WB, options);
  }
  const RigidTransform X_AB = relativePose(X_WA, X_WB);
  if (cache.model_a != &a || cache.model_b != &b || cache.triangle_counts[0] != a.geometry.corners.size() ||
      cache.triangle_counts[1] != b.corners.size()) {
    cache.reset();
    cache.model_a = &a;
    cache.model_b = &b;
    cache.triangle_counts[0] = a.geometry.corners.size();
    cache.triangle_counts[1] = b.corners.size();
  }
  const double step = cache.has_previous ? motionBound(b.bounds, cache.previous_rotation, cache.previous_translation,
                                                       X_AB.rotation, X_AB.translation)
                                         : kInfinity;
  cache.has_previous = true;
  cache.previous_rotation = X_AB.rotation;
  cache.previous_translation = X_AB.translation;

  // The previous answer's pair is tested first, certificate or not: it bounds the distance close to the
  // answer before anything else is tested, so that the pair bounds prune most of the listed pairs.
  DistanceOptions search_options = options;
  if (options.hint_triangle_a < 0) {
    search_options.hint_triangle_a = cache.previous_triangle_a;
    search_options.hint_triangle_b = cache.previous_triangle_b;
  }
  Search search(a, b, X_AB, search_options, tls_scratch);
  // The answer's pair is the next search's first upper bound.
  auto answer = [&]() {
    DistanceResult r = search.result(X_WA);
    cache.previous_triangle_a = r.triangle_a;
    cache.previous_triangle_b = r.triangle_b;
    return r;
  };
  if (cache.certified) {
    // While B has moved by at most the reach, every point of it is at least level - motion from A or has a
    // closest triangle of A listed with its own (see Search::certify): the best listed pair is the answer
    // when it is within level - motion. The pairs are tested behind the pair bounds, nearest first.
    search.testPairs(cache.near_pairs.data(), cache.near_pairs.data() + cache.near_pairs.size());
    const double motion =
        motionBound(b.bounds, cache.certified_rotation, cache.certified_translation, X_AB.rotation, X_AB.translation);
    if (search.found() && (search.best() <= 0 || (motion <= cache.reach && search.best() <= cache.level - motion))) {
      ++cache.reused;
      return answer();
    }
  }
  ++cache.searched;
  const double voxel = a.grid.voxel_size;
  // An infinite step (the first query) fails the comparison too.
  const double margin = step <= kLargestCertifiedStep * voxel ? std::sqrt(step * voxel / kMarginCost) : 0.0;
  cache.near_pairs.clear();
  // Without a margin the certificate would hold only while B approaches A, and B moves too far per query
  // for one to pay: the previous pair (the hint) is then all the next query uses, and the search lists
  // nothing.
  cache.certified = false;
  if (margin <= 0) {
    search.runHierarchical();
    return answer();
  }
  auto& near = cache.near_pairs;
  search.certify(margin, &near);
  search.runHierarchical();
  // Each pair once, grouped by B's triangle, placed once per group. The previous answer's pair, tested
  // first, bounds the distance before any of them.
  std::sort(near.begin(), near.end(), [](const std::array<int, 2>& x, const std::array<int, 2>& y) {
    return std::tie(x[1], x[0]) < std::tie(y[1], y[0]);
  });
  near.erase(std::unique(near.begin(), near.end()), near.end());
  // A search that found distance 0 stops at once: its list then certifies nothing beyond 0.
  cache.certified = search.found();
  cache.level = search.best() > 0 ? search.best() + margin : 0.0;
  cache.reach = margin;
  cache.certified_rotation = X_AB.rotation;
  cache.certified_translation = X_AB.translation;
  return answer();
}

DistanceResult bruteForceDistance(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                  const Eigen::Isometry3d& X_WB) {
  validateModelShape(a, "A");
  validateModelShape(b, "B");
  const RigidTransform X_AB = relativePose(X_WA, X_WB);
  DistanceResult r;
  double best = kInfinity;  // squared
  double best_distance = kInfinity;
  Eigen::Vector3d tb[3];
  for (std::size_t j = 0; j < b.corners.size(); ++j) {
    for (int n = 0; n < 3; ++n) tb[n] = X_AB.apply(b.corners[j][n]);
    const Eigen::Vector3d center_b = X_AB.apply(b.spheres[j].head<3>());
    const double radius_b = b.spheres[j][3];
    for (std::size_t i = 0; i < a.corners.size(); ++i) {
      // A pair whose spheres are farther apart than the best distance cannot reach it: skipped, with a slack
      // for the rounding of the centers' placement and gap far above it. Only strictly farther pairs are
      // skipped, so the answer (and, among ties, its pair) is what the full loop gives.
      const Eigen::Vector4d& sphere_a = a.spheres[i];
      const double reach = best_distance + sphere_a[3] + radius_b;
      const double slack = 1e-12 * (reach + center_b.cwiseAbs().sum() + sphere_a.head<3>().cwiseAbs().sum());
      if ((center_b - sphere_a.head<3>()).norm() > reach + slack) continue;
      Eigen::Vector3d p, q;
      ++r.counters.triangle_pairs;
      const double squared = triangleTriangleSquaredDistance(a.corners[i].data(), tb, &p, &q);
      if (squared < best) {
        best = squared;
        best_distance = std::sqrt(squared);
        r.triangle_a = int(i);
        r.triangle_b = int(j);
        r.point_a = p;
        r.point_b = q;
      }
    }
  }
  r.distance = std::sqrt(best);
  r.point_a = X_WA * r.point_a;
  r.point_b = r.distance == 0 ? r.point_a : Eigen::Vector3d(X_WA * r.point_b);
  return r;
}

bool computeCollision(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                      const Eigen::Isometry3d& X_WB, std::size_t max_contacts, std::vector<Contact>* contacts) {
  validateModelShape(a, "A");
  validateModelShape(b, "B");
  const RigidTransform X_AB = relativePose(X_WA, X_WB);
  std::size_t found = 0;
  const std::size_t limit = contacts ? std::max<std::size_t>(max_contacts, 1) : 1;
  auto& stack = tls_scratch.node_pairs;
  stack.assign(1, {0, 0});
  while (!stack.empty() && found < limit) {
    const auto [node_a, node_b] = stack.back();
    stack.pop_back();
    const BvhNode& na = a.bvh.nodes[node_a];
    const BvhNode& nb = b.bvh.nodes[node_b];
    const Eigen::Vector3d center_b = X_AB.apply(nb.center);
    // Overlap needs the sphere of B's node to reach A's box and A's sphere.
    if (detail::pointBoxSquaredDistance(center_b, na.box) > nb.radius * nb.radius) continue;
    const double reach = na.radius + nb.radius;
    if ((center_b - na.center).squaredNorm() > reach * reach) continue;
    if (na.isLeaf() && nb.isLeaf()) {
      for (int i = na.first; i < na.first + na.count && found < limit; ++i) {
        for (int j = nb.first; j < nb.first + nb.count && found < limit; ++j) {
          const int ta = a.bvh.triangle_ids[i], tb_id = b.bvh.triangle_ids[j];
          Eigen::Vector3d tb[3];
          for (int n = 0; n < 3; ++n) tb[n] = X_AB.apply(b.corners[tb_id][n]);
          Eigen::Vector3d point;
          if (trianglesIntersect(a.corners[ta].data(), tb, &point)) {
            ++found;
            if (contacts) contacts->push_back({ta, tb_id, X_WA * point});
          }
        }
      }
      continue;
    }
    const bool split_a = !na.isLeaf() && (nb.isLeaf() || na.radius >= nb.radius);
    if (split_a) {
      stack.push_back({na.first, node_b});
      stack.push_back({na.first + 1, node_b});
    } else {
      stack.push_back({node_a, nb.first});
      stack.push_back({node_a, nb.first + 1});
    }
  }
  return found > 0;
}

}  // namespace cfl
