// The search behind computeDistance, computeCollision and bruteForceDistance, in A's frame, compiled once for
// the library's flags. Its hot kernels (the triangle kernels and the list filter) are those of the
// instruction set that cfl_query.cpp picks: it passes their table to each entry point, and the search calls
// them through it (detail/query_kernels.h).

#include "detail/distance_search.h"

#include "detail/query_kernels.h"
#include "detail/search_heap.h"
#include "detail/triangle_spine.h"

namespace cfl::detail {
namespace {

constexpr double kInfinity = std::numeric_limits<double>::infinity();

// Two Bvh subtrees with at most this many triangle pairs between them are tested pair by pair (each pair
// behind mayBeCloser's cheap bounds) instead of split further. Far apart, many node pairs nearly tie, and the
// last levels of splitting cost more in node bounds and heap traffic than the pairs they avoid; but where
// many triangle pairs nearly tie too (a thin plate against itself, whose two faces are equally far), every
// pair of a large block passes the spheres' gap and pays the later filters. A single triangle of B against
// a subtree of A is walked instead (see expand), so larger blocks now mostly pair several triangles of B
// with several of A, and 16 costs fewer instructions than the 64 once chosen on most far bands
// (docs/performance.md).
constexpr std::int64_t kSmallPairTriangles = 16;

// A node of B with at most this many triangles, popped against A's grid, bounds its triangles one by one
// and tests them nearest first instead of splitting further: the last levels of a best-first search cost
// more in heap traffic than they save (docs/performance.md).
constexpr int kSmallSubtreeTriangles = 8;

// A triangle of B whose box meets more of A's leaves than this (a large triangle next to small cells) is
// tested against A's Bvh instead of their lists: past a few dozen leaves, a Bvh walk costs less than the
// leaves' plane tests and list scans.
constexpr int kMostLeavesPerTriangle = 64;
// A triangle of B whose bounding radius exceeds this many edges of the leaf at its center goes to A's Bvh
// without trying the leaves first (its subtree of B goes on as node pairs, sharing the walk down A's Bvh
// with its neighbours). Lower, triangles about a leaf's size leave lists that serve them well (wuson at
// short range); higher, triangles a few leaves across scan the many long lists they meet where the shared
// node pairs would prune them in groups (a ground plane, slivers fanned around a refined patch).
constexpr double kLargeTriangleCells = 2;
// A pair of triangles whose threshold exceeds this many times the sum of their bounding radii is tested
// on the axis between their centers before B's plane (see mayBeCloser).
constexpr double kFarPairRadii = 4;
// A triangle of B that goes to A's Bvh walks at most this many nodes depth-first before the rest of its walk
// joins the best-first search (see testTriangleAtLeaf). Fewer cost the typical short walks of a ground
// plane's large triangles (ground_bunny) the heap traffic and oriented bounds they do not need; many more
// gave back part of what the slivers of refined_patch gained.
constexpr int kTriangleWalkNodes = 64;
// The search's first descent towards an intersecting triangle pair (Search::probeForContact) takes at most
// this many node-pair bounds, only where B's largest leaf has at least kContactProbeLargeLeaf of B's radius,
// and only where the roots' oriented boxes overlap by more than kContactProbeOverlap of the larger root's
// radius, or of the thicker root box's thinnest extent where that is less (a part much smaller than A
// overlaps A's root box wherever it lies within it). Looser gates (an overlap of half or 0.7 of the radius,
// or any B) also let in poses near contact but apart (a ground plane under a bunny) and overlapping compact
// meshes, where the descent runs its whole budget for nothing. It also runs where either mesh is a fan
// (its smallest leaf, too, has kContactProbeLargeLeaf of its radius), on any overlap of the roots, and then
// takes up to kContactProbeFanBounds bounds: a leaf whose box crosses the fan where its triangles do not
// (near the hub, where every wedge meets it) sends the descent back up more often than elsewhere.
constexpr int kContactProbeBounds = 128;
constexpr int kContactProbeFanBounds = 256;
constexpr double kContactProbeLargeLeaf = 0.3;
constexpr double kContactProbeOverlap = 0.85;
// The descent tests only triangle pairs that may lie within this share of A's radius of each other: a
// hair above 0, so that rounding in the filter's bounds does not turn away a pair that touches.
constexpr double kContactProbeTouching = 1e-9;
// A node of B whose box meets at most kShortListLeaves leaves of A, whose lists hold at most
// kShortListTriangles triangles together, is paired with those triangles (see pairWithShortLists).
constexpr int kShortListTriangles = 8;
constexpr int kShortListLeaves = 8;

// B's pose in A's frame, applied by hand: Eigen's Isometry product carries a homogeneous row we don't need.
struct RigidTransform {
  Eigen::Matrix3d rotation;
  Eigen::Vector3d translation;
  // By columns: Eigen's matrix-vector product went through an out-of-line assignment loop (forcing it
  // inline cost more).
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
  check(model.corners.in_leaf_order.size(), "corners.in_leaf_order");
  check(model.leaf_spheres.size(), "leaf_spheres");
  check(model.leaf_planes.size(), "leaf_planes");
  check(model.spines.size(), "spines");
  if (model.bvh.nodes.empty()) {
    throw Error(std::string(which) + ": MeshModel::bvh has no nodes (build the model with makeMeshModel)");
  }
  if (model.node_spine_radii.size() != model.bvh.nodes.size()) {
    std::ostringstream message;
    message << which << ": MeshModel::node_spine_radii has " << model.node_spine_radii.size() << " entries for "
            << model.bvh.nodes.size() << " Bvh nodes (build the model with makeMeshModel)";
    throw Error(message.str());
  }
}

// HeapEntry::node_a values that name no node of A.
constexpr int kAgainstGrid = -1;
constexpr int kTriangleOfB = -2;
// node_a at or below this names one triangle of A, at Bvh leaf position kFirstTriangleOfA - node_a, against
// node_b (see Search::expand).
constexpr int kFirstTriangleOfA = -3;
// HeapEntry::node_b at or below this names one triangle of B, at Bvh leaf position kFirstTriangleOfB - node_b,
// against node node_a of A.
constexpr int kFirstTriangleOfB = -1;

// The search order's key for a step whose lower bound is `lower_bound` and whose piece of B has bounding
// radius `radius` (see HeapEntry::key).
inline double searchKey(double lower_bound, double radius) {
  return lower_bound > 0 ? lower_bound : -1 / (1 + radius + std::max(0.0, lower_bound + radius));
}

// How many of a list's entry bounds, sorted increasing, lie below `limit` (1 to 256): the entries a scan
// takes. Sixteen bytes at a time where the bounds array (ending at `array_end`) has them, rather than a
// byte at a time with two branches per entry.
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
// overlap instead of following one another. That pays where the caches are cold (a busy neighbour on the
// machine empties them); warm, it only adds a few instructions.
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

// How many far corners farCornerBound tries per piece of B, at increasing distances along the field's gradient.
constexpr int kFarCornerProbes = 3;

// RegionTree::locate through a one-leaf cache, as NanoVDB's accessors do: the search bounds B's nodes and
// triangles in the order it meets them, mostly near one another, so the leaf of the previous lookup often
// holds the next point and the walk from the root is skipped.
struct LeafCache {
  RegionCell cell;
  Eigen::Array3d end = Eigen::Array3d::Constant(-kInfinity);  // far corner; an empty box until the first lookup

  const RegionCell& find(const RegionTree& regions, const Eigen::Vector3d& p) {
    if (!((p.array() >= cell.min_corner.array()).all() && (p.array() < end).all())) {
      cell = regions.locate(p);
      end = cell.min_corner.array() + cell.size;
    }
    return cell;
  }
};

// Scratch reused across queries on one thread, so queries allocate only while it grows.
struct Scratch {
  std::vector<std::uint32_t> stamp;  // per triangle of A: the B leaf that last tested it
  std::uint32_t generation = 0;
  struct VoxelCandidate {
    double lower_bound;
    std::uint32_t leaf;
    int triangle_b;
  };
  std::vector<VoxelCandidate> voxel_candidates;
  std::vector<int> outside_triangles;
  // testTriangleAgainstLists' merged lists: the prefixes of the lists it took, and their triangles of A,
  // each once, kept for the next triangle of B, which often meets the same leaves; then those still in play.
  struct ListPrefix {
    std::uint32_t list;
    std::uint32_t length;
    bool operator==(const ListPrefix& other) const { return list == other.list && length == other.length; }
  };
  std::vector<ListPrefix> list_prefixes;
  std::vector<ListPrefix> merged_prefixes;
  std::vector<int> merged_candidates;  // merged_count of them in use
  std::size_t merged_count = 0;
  std::vector<int> list_candidates;
  struct HeapEntry {
    // Order of the search, nearest first: the node's lower bound when positive. Bounds <= 0 say only "may
    // overlap", and ordering by them would pop the largest nodes first: a breadth-first search where
    // overlapping meshes need a depth-first dive to the first intersecting pair, which ends the query. They
    // get -1 / (1 + radius + max(0, bound + radius)) instead (searchKey), radius that of B's node or
    // triangle: before every positive bound, the smallest piece first, and of two alike the one whose bound
    // leaves it nearer A (faster on overlapping meshes than the radius alone, whose choice between siblings
    // is arbitrary).
    // Pruning on the key stays valid: a key <= 0 is never pruned by a positive threshold, and a threshold
    // of 0 ends the query anyway.
    double key;
    int node_b;  // a node of B's Bvh, or with node_a == kTriangleOfB a triangle of B by its leaf position, or
                 // <= kFirstTriangleOfB a triangle of B against node node_a of A
    int node_a;  // kAgainstGrid: B's node against A's grid; <= kFirstTriangleOfA: a triangle of A against
                 // B's node; otherwise a node pair of the two Bvhs
  };
  std::vector<HeapEntry> heap;  // a 4-ary min-heap on key (detail/search_heap.h)
  std::vector<std::pair<int, int>> node_pairs;  // computeCollision's pending node pairs

  void beginQuery(std::size_t triangle_count) {
    merged_prefixes.clear();  // another query may scan another model's lists
    merged_count = 0;
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
  Search(const QueryKernelTable& kernels, const CflModel& a, const MeshModel& b, const RigidTransform& X_AB,
         const DistanceOptions& options, Scratch& scratch)
      : kernels_(kernels), a_(a), mesh_a_(a.geometry), b_(b), X_AB_(X_AB), options_(options), scratch_(scratch) {
    validateModelShape(mesh_a_, "A's geometry");
    validateModelShape(b_, "B");
    scratch_.beginQuery(mesh_a_.corners.size());
    prepared_leaf_.fill(-1);
    grid_box_ = a_.regions.bounds();
    exact_ = options.abs_err == 0 && options.rel_err == 0;
    // An upper bound seeds the best distance without a pair: only strictly closer pairs are taken.
    best_ = options.upper_bound;
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
  // certificate names them, and by Bvh leaf position (corners.in_leaf_order, leaf_spheres, leaf_planes)
  // where the search walks B's Bvh: a subtree's triangles then lie side by side, which pays where the
  // caches are cold.
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
    Eigen::Vector3d box_min, box_max;  // of the corners
    std::uint8_t spine_code;      // MeshModel::spines
    Eigen::Vector3d spine_offset;  // TriangleSpine::offset, for a sliver only
  };

  void prepare(int id, const std::array<Eigen::Vector3d, 3>& corners, const Eigen::Vector4d& sphere,
               const Eigen::Vector4d& plane, PreparedTriangle& out) const {
    out.id = id;
    out.spine_code = b_.spines[std::size_t(id)];
    transformTriangle(corners, out.corners);
    out.center = X_AB_.apply(sphere.head<3>());
    out.radius = sphere[3];
    out.normal = X_AB_.rotation * plane.head<3>();
    out.offset = out.normal.dot(out.corners[0]);
    out.box_min = out.corners[0].cwiseMin(out.corners[1]).cwiseMin(out.corners[2]);
    out.box_max = out.corners[0].cwiseMax(out.corners[1]).cwiseMax(out.corners[2]);
    if ((out.spine_code & kSliverSpine) != 0) out.spine_offset = triangleSpine(out.corners, out.spine_code & 3).offset;
  }
  void prepare(int t, PreparedTriangle& out) const { prepare(t, b_.corners[t], b_.spheres[t], b_.planes[t], out); }
  void prepareAtLeaf(int n, PreparedTriangle& out) const {
    prepare(b_.bvh.triangle_ids[n], b_.corners.in_leaf_order[n], b_.leaf_spheres[n], b_.leaf_planes[n], out);
  }
  // B's triangle at leaf position n in A's frame, through a small direct-mapped cache: the node-pair steps
  // meet the same few triangles of B many times (a leaf of A split into its triangles takes each of them
  // to the same small subtree of B), and placing one costs more than the pair filter that follows. The
  // reference lasts until the next call.
  const PreparedTriangle& preparedAtLeaf(int n) {
    const int slot = n & (kPreparedCacheSize - 1);
    if (prepared_leaf_[slot] != n) {
      prepareAtLeaf(n, prepared_[slot]);
      prepared_leaf_[slot] = n;
    }
    return prepared_[slot];
  }

  // Exact distance between triangle a of A and triangle b of B (already in A's frame); a certifying search
  // lists the pair when it is within the margin.
  // Out of line: the loops that call it run it on few of their candidates, and inlined it would make them
  // save and restore its registers on every candidate.
  CFL_NOINLINE
  void testPair(int a, const PreparedTriangle& tb) {
    ++counters_.triangle_pairs;
    Eigen::Vector3d p, q;
    const double squared = kernels_.triangle_distance(mesh_a_.corners[a].data(), tb.corners, &p, &q);
    const double distance = std::sqrt(squared);
    if (near_pairs_ != nullptr && distance < best_ + margin_) near_pairs_->push_back({a, tb.id});
    if (distance < best_ || (best_a_ < 0 && best_ == kInfinity)) {
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
  // axes. Past B's plane, the triangles' axis-aligned boxes come first (see mayBeCloserPastBPlane).
  bool mayBeCloser(int a, const PreparedTriangle& tb, double threshold) const {
    const Eigen::Vector4d& sphere = mesh_a_.spheres[a];
    const double reach = threshold + sphere[3] + tb.radius;
    const Eigen::Vector3d axis = tb.center - sphere.head<3>();
    const double axis_squared = axis.squaredNorm();
    if (axis_squared >= reach * reach) return false;
    // Far apart for their size, the projections on the axis between the centers are nearly the distance
    // and B's plane rarely decides (two blades' tips far apart pass it on nearly every pair): the axis
    // first.
    if (threshold > kFarPairRadii * (sphere[3] + tb.radius) &&
        centerAxisSeparates(a, tb, axis, axis_squared, threshold)) {
      return false;
    }
    return mayBeCloserBeyondSpheres(a, tb, threshold);
  }
  // Whether the projections of triangle a of A and `tb` on `axis` (from A's sphere center to tb's, squared
  // length `axis_squared`) are at least `threshold` apart.
  bool centerAxisSeparates(int a, const PreparedTriangle& tb, const Eigen::Vector3d& axis, double axis_squared,
                           double threshold) const {
    if (!(axis_squared > 0)) return false;
    const auto& c = mesh_a_.corners[a];
    const double a_max = std::max({axis.dot(c[0]), axis.dot(c[1]), axis.dot(c[2])});
    const double b_min = std::min({axis.dot(tb.corners[0]), axis.dot(tb.corners[1]), axis.dot(tb.corners[2])});
    const double gap = b_min - a_max;
    return gap > 0 && gap * gap >= threshold * threshold * axis_squared;
  }
  // mayBeCloser past the spheres' gap, for candidates already filtered on it at a threshold the search has
  // since lowered: the spheres again at the lowered one rule out too few to pay for themselves.
  CFL_ALWAYS_INLINE
  bool mayBeCloserBeyondSpheres(int a, const PreparedTriangle& tb, double threshold) const {
    const auto& c = mesh_a_.corners[a];
    // B's plane first, the more selective of the two planes. The center axis (compared squared, no root)
    // pays between them: before A's plane, not before B's.
    const double t0 = planeOffset(tb.normal, tb.offset, c[0]), t1 = planeOffset(tb.normal, tb.offset, c[1]),
                 t2 = planeOffset(tb.normal, tb.offset, c[2]);
    if (std::max(std::min({t0, t1, t2}), -std::max({t0, t1, t2})) >= threshold) return false;
    return mayBeCloserPastBPlane(a, tb, threshold, t0, t1, t2);
  }
  // The rest of the filter, out of line: B's plane, inlined in the loops, stops most candidates, and calling
  // out for all of them cost more.
  CFL_NOINLINE
  bool mayBeCloserPastBPlane(int a, const PreparedTriangle& tb, double threshold, double t0, double t1,
                             double t2) const {
    const auto& c = mesh_a_.corners[a];
    const Eigen::Vector4d& plane = mesh_a_.planes[a];
    const Eigen::Vector3d normal_a = plane.head<3>();
    // The gap between the two triangles' boxes on one coordinate axis bounds their distance. Where the pairs
    // that pass B's plane are nearly coplanar (a plate against itself), their boxes apart along the plate
    // rule out many at the cost of a few min/max, before the center axis's six projections.
    const Eigen::Vector3d box_min_a = c[0].cwiseMin(c[1]).cwiseMin(c[2]);
    const Eigen::Vector3d box_max_a = c[0].cwiseMax(c[1]).cwiseMax(c[2]);
    if (std::max((box_min_a - tb.box_max).maxCoeff(), (tb.box_min - box_max_a).maxCoeff()) >= threshold) return false;
    const Eigen::Vector3d axis = tb.center - mesh_a_.spheres[a].head<3>();
    if (centerAxisSeparates(a, tb, axis, axis.squaredNorm(), threshold)) return false;
    const double s0 = planeOffset(normal_a, plane[3], tb.corners[0]),
                 s1 = planeOffset(normal_a, plane[3], tb.corners[1]),
                 s2 = planeOffset(normal_a, plane[3], tb.corners[2]);
    if (std::max(std::min({s0, s1, s2}), -std::max({s0, s1, s2})) >= threshold) return false;
    // The spines (detail/triangle_spine.h): slivers pass every test above, spheres and boxes being loose
    // around them, and most that the spines do not stop would pass the edge axes too.
    const std::uint8_t spine_a = mesh_a_.spines[std::size_t(a)];
    if (((spine_a | tb.spine_code) & kSliverSpine) != 0) {
      const int edge_b = tb.spine_code & 3;
      const TriangleSpine spine_b = (tb.spine_code & kSliverSpine) != 0 ? TriangleSpine{edge_b, tb.spine_offset}
                                                                        : triangleSpine(tb.corners, edge_b);
      if (spineLowerBound(c.data(), triangleSpine(c.data(), spine_a & 3), tb.corners, spine_b,
                          kernels_.segment_segment) >= threshold) {
        return false;
      }
    }
    // The edge axes (QueryKernelTable::edge_axes_separate): only the few candidates that pass every other
    // test get there.
    return !kernels_.edge_axes_separate(c.data(), tb.corners, nearestToPlane(t0, t1, t2), nearestToPlane(s0, s1, s2),
                                        threshold);
  }

  // The signed offset of p from the plane normal . x = offset, summed in this order: the x86-64-v3 filter
  // (filter_list_candidates) repeats it four candidates at a time and must get the same bits.
  static double planeOffset(const Eigen::Vector3d& normal, double offset, const Eigen::Vector3d& p) {
    return normal[0] * p[0] + normal[1] * p[1] + normal[2] * p[2] - offset;
  }
  static double dot3(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
    return u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
  }

  // Index of the smallest of three plane offsets in absolute value.
  static int nearestToPlane(double x0, double x1, double x2) {
    const double a0 = std::abs(x0), a1 = std::abs(x1), a2 = std::abs(x2);
    return a0 <= a1 ? (a0 <= a2 ? 0 : 2) : (a1 <= a2 ? 1 : 2);
  }

  // `spheres_filtered`: the pair passed the spheres' gap at an earlier threshold (see mayBeCloserBeyondSpheres).
  CFL_ALWAYS_INLINE void testPairIfClose(int a, const PreparedTriangle& tb, bool spheres_filtered = false) {
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

  // RegionTree::locate through a one-leaf cache (LeafCache).
  const RegionCell& locate(const Eigen::Vector3d& p) const { return located_.find(a_.regions, p); }

  // The corner nearest p of the leaf holding p, and the distance field there.
  struct FieldCorner {
    double distance;
    Eigen::Vector3d position;
  };
  // `probe`: which of farCornerBound's distances p was found at. Each has a cache of its own (locate's
  // serves the next node): the probes at one distance from neighbouring pieces of B, far from A, mostly
  // fall in one leaf, where the walk from the root cost more than the bound itself. Any leaf gives a valid
  // bound, so one whose box holds p only up to rounding serves as well as the walk's.
  FieldCorner nearestCorner(const Eigen::Vector3d& p, int probe) const {
    const RegionCell& cell = probed_[probe].find(a_.regions, p);
    const Eigen::Vector3d offset = (p - cell.min_corner) / cell.size;
    const int corner = (offset[0] >= 0.5) | (offset[1] >= 0.5) << 1 | (offset[2] >= 0.5) << 2;
    return {RegionTree::cornerDistanceLower(a_.regions.leaf_corner_distance[cell.leaf][corner],
                                            a_.regions.cornerDistanceUnit(cell.size)),
            cell.min_corner + cell.size * Eigen::Vector3d(corner & 1, (corner >> 1) & 1, corner >> 2)};
  }

  // The leaf holding a point (clamped to the regions) and the field at its eight corners, read once for
  // the bounds that use both (cellLowerBound, farCornerLowerBound).
  struct GridCell {
    std::uint32_t leaf;
    Eigen::Vector3d point;   // the point it was found for
    Eigen::Vector3d corner;  // position of corner (0, 0, 0)
    double size;             // edge
    double distance[8];      // the field at corner (i, j, k) = distance[i + 2 j + 4 k]
  };
  GridCell cellAt(const Eigen::Vector3d& position) const {
    const RegionCell found = locate(position);
    GridCell cell;
    cell.leaf = found.leaf;
    cell.point = position;
    cell.corner = found.min_corner;
    cell.size = found.size;
    const std::array<std::uint16_t, 8>& d = a_.regions.leaf_corner_distance[found.leaf];
    const double unit = a_.regions.cornerDistanceUnit(found.size);
    for (int corner = 0; corner < 8; ++corner) cell.distance[corner] = RegionTree::cornerDistanceLower(d[corner], unit);
    return cell;
  }

  // Lower bound on the distance from any point within `radius` of `center` to A, in O(1): for each of the
  // eight corners of the grid cell holding `center`, the corner's distance minus how far the point can be
  // from it (distance to a set is 1-Lipschitz), or the distance to A's bounding box when that is larger.
  // Any cell gives a valid bound. The nearest corner alone loses up to |center - corner| whatever the
  // direction to the mesh; the eight pay for themselves, for B's nodes too (their far-corner bound then
  // reuses the cell).
  double cellLowerBound(const GridCell& cell, const Eigen::Vector3d& center, double radius) const {
    // Squared offsets from `center` to the cell's two corner planes on each axis, then the eight corners'
    // squared distances as a plain array, whose square roots go two by two through the vector unit, where
    // GCC left them scalar.
    const Eigen::Vector3d offset = center - cell.corner;
    const double h = cell.size;
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
  // loses only about radius^2 / (2 k voxel) across a flat gap.
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
    // Farther corners lose less across flat gaps, nearer ones less where A curves away: {1.5, 3, 6} voxels
    // did best of the sets tried (docs/performance.md).
    static constexpr double kProbeVoxels[kFarCornerProbes] = {1.5, 3.0, 6.0};
    for (int probe = 0; probe < kFarCornerProbes; ++probe) {
      const FieldCorner corner = nearestCorner(cell.point + kProbeVoxels[probe] * cell.size * direction, probe);
      const double reach = std::sqrt(farthestSquared(corner.position));
      bound = std::max(bound, corner.distance - reach);
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
    transformTriangle(b_.corners.in_leaf_order[n], corners);
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
  // Returns false, having tested nothing, where a leaf in the box has no list or the box meets more leaves
  // than a walk of A's Bvh costs: the triangle must then go to A's Bvh.
  bool testTriangleAgainstLists(const PreparedTriangle& tb, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    const RegionTree& regions = a_.regions;
    if (best_ == kInfinity) {
      // No pair yet: every entry would pass the filters below and reach the exact test. The nearest entry of
      // the leaf holding the triangle's center goes first, and its distance filters the rest.
      const std::uint32_t leaf = locate(tb.center).leaf;
      if (regions.hasList(leaf) && regions.leafListLength(leaf) > 0) testPair(regions.leafListTriangle(leaf, 0), tb);
    }
    const double threshold = pruneThreshold();
    auto& prefixes = scratch_.list_prefixes;
    prefixes.clear();
    std::size_t total = 0;  // the prefixes' entries
    const std::uint8_t* bounds_end = regions.list_entry_bounds.data() + regions.list_entry_bounds.size();
    // Leaves that tb's plane misses by more than the margin hold no point within the margin of tb, and are
    // skipped. A cell reaches h/2 |n|_1 either side of its center along the unit normal n. The slack,
    // 1e-9 of the coordinates' size, dwarfs the rounding of these sums and tb's corners' offsets from its
    // plane (a few eps, see makeMeshModel), so no leaf holding a point of tb is skipped. A degenerate
    // triangle's zero normal skips none.
    const double scale = std::abs(tb.offset) + lo.cwiseAbs().sum() + hi.cwiseAbs().sum() + (hi - lo).sum();
    const double normal_l1 = tb.normal.lpNorm<1>();
    int leaves_left = kMostLeavesPerTriangle;
    auto visit = [&](const RegionCell& cell) {
      ++counters_.voxel_tests;
      const double h = cell.size;
      const Eigen::Vector3d center = cell.min_corner + Eigen::Vector3d::Constant(0.5 * h);
      const double slab = 0.5 * h * normal_l1 + margin_ + 1e-9 * (scale + 3 * h);
      if (std::abs(tb.normal.dot(center) - tb.offset) > slab) return true;
      if (regions.leaf_lower_bound[cell.leaf] >= threshold) return true;
      // A leaf without a list, or more leaves than a walk of A's Bvh costs: the Bvh takes the triangle.
      if (!regions.hasList(cell.leaf) || --leaves_left < 0) return false;
      // The part of tb inside this leaf is at least an entry's bound from its triangle, and any other part
      // of tb lies in a leaf of its own: once the bounds reach the threshold, the rest of this list cannot
      // give a closer pair. Entries are sorted by bound, nearest first. An entry whose bound, in units of
      // h / 32, is code_limit or more is at least the threshold away: floor(threshold / unit) + 1 >
      // threshold / unit exactly, whatever the division's rounding (it is monotone).
      const double units = threshold / regions.entryBoundUnit(cell.depth);
      const int code_limit = units < 255 ? int(units) + 1 : 256;
      const std::uint32_t list = regions.leaf_list[cell.leaf];
      const std::uint32_t begin = regions.list_offsets[list];
      const std::uint8_t* bounds = regions.list_entry_bounds.data() + begin;
      const std::ptrdiff_t length = regions.list_offsets[list + 1] - begin;
      const std::ptrdiff_t end = passingPrefix(bounds, length, code_limit, bounds_end);
      if (end > 0) prefixes.push_back({list, std::uint32_t(end)});
      total += std::size_t(end);
      return true;
    };
    // A box inside one leaf (most of B's triangles, next to A's larger cells) needs no walk from the root.
    const RegionCell& first = locate(lo);
    const bool listed = (hi.array() < (first.min_corner.array() + first.size)).all()
                            ? visit(RegionCell(first))
                            : regions.forEachLeafInBox(lo, hi, visit);
    if (!listed) {
      return false;
    }
    // The same prefixes of the same lists, in the same order, merge to the same triangles in the same order.
    if (prefixes != scratch_.merged_prefixes) {
      // A list names each triangle once: no stamps to write. Were a damaged file to repeat one, its pair
      // would only be tested twice.
      scratch_.merged_count = prefixes.size() == 1 ? mergeListPrefixes<false>(prefixes, total)
                                                   : mergeListPrefixes<true>(prefixes, total);
      std::swap(prefixes, scratch_.merged_prefixes);
    }
    const int* merged = scratch_.merged_candidates.data();
    const std::size_t count = scratch_.merged_count;
    auto& candidates = scratch_.list_candidates;
    if (candidates.size() < count) candidates.resize(count);
    int* ids = candidates.data();
    std::size_t near = 0;
    std::size_t n = 0;
    if (kernels_.filter_list_candidates != nullptr) {
      n = kernels_.filter_list_candidates(listFilter(tb, threshold), merged, count, ids, near);
    }
    // Bounding spheres, squared: the center gap against the reach.
    for (; n < count; ++n) {
      const int t = merged[n];
      const Eigen::Vector4d& sphere = mesh_a_.spheres[t];
      const double reach = threshold + sphere[3] + tb.radius;
      const double dx = tb.center[0] - sphere[0], dy = tb.center[1] - sphere[1], dz = tb.center[2] - sphere[2];
      ids[near] = t;
      near += dx * dx + dy * dy + dz * dz < reach * reach;
    }
    for (std::size_t k = 0; k < near && best_ > 0; ++k) testPairIfClose(ids[k], tb, true);  // 0 ends the query
    return true;
  }

  // The triangles of A in the given prefixes of A's lists, `total` entries, in list order, into
  // Scratch::merged_candidates; returns how many.
  // kDeduplicate keeps each once (a triangle is in the lists of all the leaves its region meets).
  template <bool kDeduplicate>
  std::size_t mergeListPrefixes(const std::vector<Scratch::ListPrefix>& prefixes, std::size_t total) {
    const RegionTree& regions = a_.regions;
    std::vector<int>& merged = scratch_.merged_candidates;
    if (merged.size() < total) merged.resize(total);
    const std::uint32_t mark = kDeduplicate ? scratch_.nextGeneration() : 0;
    std::uint32_t* stamp = scratch_.stamp.data();
    int* out = merged.data();
    std::size_t taken = 0;
    auto take = [stamp, mark](int t) {
      if (!kDeduplicate) return true;
      const bool fresh = stamp[t] != mark;
      stamp[t] = mark;
      return fresh;
    };
    // The ids decoded in the loop itself (RegionTree::list_entry_ids: a base, then 16 bits per entry), the
    // count in a local: through RegionTree::forEachListTriangle's callback the 16-bit ids cost more time than
    // 32-bit ones had.
    for (const Scratch::ListPrefix& prefix : prefixes) {
      const std::ptrdiff_t end = prefix.length;
      const std::uint16_t* slots = regions.list_entry_ids.data() + regions.listIdsBegin(prefix.list);
      const std::int32_t base = std::int32_t(std::uint32_t(slots[0]) | std::uint32_t(slots[1]) << 16);
      const std::uint16_t* low = slots + 2;
      if (base >= 0) {
        for (std::ptrdiff_t n = 0; n < end; ++n) {
          const int t = base + int(low[n]);
          out[taken] = t;
          taken += take(t);
        }
      } else {
        const std::uint16_t* high = regions.list_high_ids.data() + std::uint32_t(~base);
        for (std::ptrdiff_t n = 0; n < end; ++n) {
          const int t = int(std::uint32_t(low[n]) | std::uint32_t(high[n]) << 16);
          out[taken] = t;
          taken += take(t);
        }
      }
    }
    return taken;
  }

  // testTriangleAgainstLists' first filter's inputs (QueryKernelTable::filter_list_candidates).
  ListFilter listFilter(const PreparedTriangle& tb, double threshold) const {
    return {mesh_a_.spheres.data(), mesh_a_.planes.data(), mesh_a_.corners.in_leaf_order.data(),
            mesh_a_.corners.leaf_position.data(), tb.corners, tb.center, tb.radius, tb.normal, tb.offset,
            tb.box_min, tb.box_max, threshold};
  }

  // Triangle tb of B against the subtree of A's Bvh below node `root`: exact wherever the triangle is, for
  // the parts outside the grid.
  void testTriangleAgainstBvh(const PreparedTriangle& tb, int root = 0) {
    auto keep = [](int) {};
    walkTriangleAgainstBvh(tb, root, std::numeric_limits<int>::max(), keep);
  }
  // testTriangleAgainstBvh that stops after `budget` nodes and hands each node still pending to spill(node).
  template <class Spill>
  void walkTriangleAgainstBvh(const PreparedTriangle& tb, int root, int budget, Spill& spill) {
    const auto& nodes = mesh_a_.bvh.nodes;
    int stack[128];  // depth-first, one pending sibling per level: Bvh::kMaxDepth + 1 at most
    int top = 0;
    stack[top++] = root;
    while (top > 0) {
      if (--budget < 0) {
        while (top > 0) spill(stack[--top]);
        return;
      }
      const BvhNode& node = nodes[stack[--top]];
      ++counters_.voxel_tests;
      const Aabb box = node.box();
      const double gap = std::sqrt(detail::pointBoxSquaredDistance(tb.center, box)) - tb.radius;
      if (gap >= pruneThreshold()) continue;
      // The box against tb's plane: tight where the sphere around a large triangle is loose. The slack covers
      // the rounding of these sums and of tb's corners' offsets from its plane (a few eps, see makeMeshModel).
      const Eigen::Vector3d box_center = 0.5 * (box.min + box.max);
      const Eigen::Vector3d box_half = 0.5 * (box.max - box.min);
      const double slack = 1e-12 * (std::abs(tb.offset) + box_center.cwiseAbs().sum() + box_half.sum());
      if (std::abs(tb.normal.dot(box_center) - tb.offset) - box_half.dot(tb.normal.cwiseAbs()) - slack >=
          pruneThreshold()) {
        continue;
      }
      if (node.isLeaf()) {
        for (int n = node.first; n < node.first + node.count; ++n) {
          testPairIfClose(mesh_a_.bvh.triangle_ids[n], tb);
        }
        continue;
      }
      const double d_left = detail::nodeBoxSquaredDistance(tb.center, nodes[node.first]);
      const double d_right = detail::nodeBoxSquaredDistance(tb.center, nodes[node.first + 1]);
      if (d_left <= d_right) {
        stack[top++] = node.first + 1;
        stack[top++] = node.first;
      } else {
        stack[top++] = node.first;
        stack[top++] = node.first + 1;
      }
    }
  }

  // B's triangle at leaf position n against A: against the lists of the leaves it meets, or where they
  // cannot take it, by a short walk of A's Bvh, whose nodes still pending after kTriangleWalkNodes go to the
  // heap as pairs with the triangle, on the larger of `lower_bound` (an earlier lower bound of the
  // triangle's, or -infinity) and their box's gap. Those pairs split best-first on A's oriented boxes with
  // every other pending step, and stop where the best distance found elsewhere prunes them: a walk to the
  // end bounds each node only by its axis-aligned box and the triangle's plane, nearly useless against a
  // long sliver, and nothing else can lower the threshold meanwhile (a sliver of refined_patch walked most
  // of A's Bvh). Most walks end within the budget, where the walk costs less than the heap's pairs. The
  // pushed pairs get the cheap box gap, not the oriented bound: many are never popped.
  template <class Push>
  void testTriangleAtLeaf(int n, double lower_bound, Push& push) {
    PreparedTriangle tb;
    prepareAtLeaf(n, tb);
    // A certifying search lists the pairs the triangle may form at the poses its certificate answers, B
    // moved by up to the margin: the closest triangles of A to every point it can reach are in the lists of
    // the voxels within the margin of it (or, past the grid, anywhere: the Bvh path).
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(margin_);
    const Eigen::Vector3d lo = tb.box_min - reach;
    const Eigen::Vector3d hi = tb.box_max + reach;
    // A triangle much larger than the leaf at its center (a ground plane's, next to a small detailed part)
    // would meet more leaves than a Bvh walk costs.
    if ((lo.array() >= grid_box_.min.array()).all() && (hi.array() <= grid_box_.max.array()).all() &&
        tb.radius < kLargeTriangleCells * locate(tb.center).size && testTriangleAgainstLists(tb, lo, hi)) {
      return;
    }
    auto spill = [&](int node) {
      const double gap =
          std::sqrt(detail::nodeBoxSquaredDistance(tb.center, mesh_a_.bvh.nodes[node])) - tb.radius;
      const double bound = std::max(lower_bound, gap);
      if (bound < pruneThreshold()) push(Scratch::HeapEntry{searchKey(bound, tb.radius), kFirstTriangleOfB - n, node});
    };
    walkTriangleAgainstBvh(tb, 0, kTriangleWalkNodes, spill);
  }

  // A node of B's Bvh moved into A's frame, once for all the nodes of A it meets.
  struct PlacedNode {
    const BvhNode* node;
    Eigen::Vector3d center;  // of the node's sphere
    Eigen::Matrix3d obb_axes;
    Eigen::Vector3d obb_center;
  };

  CFL_ALWAYS_INLINE PlacedNode place(int b, const Eigen::Vector3d& center) const {
    const BvhNode& node = b_.bvh.nodes[b];
    return {&node, center, X_AB_.rotation * node.obb_axes, X_AB_.apply(node.obb_center)};
  }

  // Whether an oriented box's middle extent is at most a quarter of its longest.
  static bool isNeedle(const Eigen::Vector3d& half) {
    const double longest = half.maxCoeff();
    return half.sum() - longest - half.minCoeff() <= 0.25 * longest;
  }

  // Lower bound between node a of A's Bvh and a placed node of B: the larger of the sphere-box gap and the
  // separation of the two oriented boxes along the seven axes that matter for distance (the line joining
  // their centers, and each box's three axes). The oriented boxes are thin across flat patches, where facing
  // surfaces are separated along their normals. Where either box is a needle, last, the boxes' spines
  // (boxSpineLowerBound): the nodes of a disk fanned into slivers are needles all reaching the disk's
  // center, which those axes leave far apart only where the needles are parallel or square to each other;
  // compact boxes skip it, the line between their centers being as tight and cheaper, and so does the
  // contact probe (threshold 0), which only follows overlapping boxes. Cheapest first:
  // returns as soon as the bound reaches `threshold`, where the pair is pruned whatever the later axes say.
  double nodePairLowerBound(int a, const PlacedNode& b, double threshold) const {
    const BvhNode& node_a = mesh_a_.bvh.nodes[a];
    const BvhNode& node_b = *b.node;
    const double line[3] = {b.center[0] - node_a.center[0], b.center[1] - node_a.center[1],
                            b.center[2] - node_a.center[2]};
    const double centers = std::sqrt((line[0] * line[0] + line[1] * line[1]) + line[2] * line[2]);
    double bound =
        std::max(std::sqrt(detail::nodeBoxSquaredDistance(b.center, node_a)), centers - node_a.radius) - node_b.radius;
    if (bound >= threshold) return bound;
    const Eigen::Vector3d& half_a = node_a.obb_half;
    const Eigen::Vector3d& half_b = node_b.obb_half;
    bound = kernels_.box_pair_bound != nullptr
                ? kernels_.box_pair_bound(node_a.obb_axes, node_a.obb_center, half_a, b.obb_axes, b.obb_center,
                                          half_b, bound, threshold)
                : detail::orientedBoxPairBound(node_a.obb_axes, node_a.obb_center, half_a, b.obb_axes,
                                               b.obb_center, half_b, bound, threshold);
    if (bound >= threshold || !(threshold > 0) || !(isNeedle(half_a) || isNeedle(half_b))) return bound;
    return std::max(bound, boxSpineLowerBound(node_a.obb_axes, node_a.obb_center, half_a, b.obb_axes, b.obb_center,
                                              half_b, kernels_.segment_segment, mesh_a_.node_spine_radii[std::size_t(a)],
                                              b_.node_spine_radii[std::size_t(b.node - b_.bvh.nodes.data())]));
  }

  // Lower bound between a triangle and a node's sphere and oriented box, all in A's frame: the larger of the
  // spheres' gap, the gap along the line between the two centers (far apart, nearly exact), the box's gap
  // from the triangle's plane (`normal`: unit, or zero for a degenerate triangle, which gets no such bound),
  // the gap along each box axis (the triangle's corners against the box's extent), and in the plane across
  // each edge; for a sliver (`spine_code`, MeshModel::spines), also across its spine and each box axis. What
  // a node pair's bound takes of two boxes, with one of them a single triangle of a leaf that is split into
  // its triangles. Cheapest and most often deciding first: returns as soon as the bound reaches `threshold`,
  // where the pair is pruned whatever the later terms say.
  static double triangleNodeLowerBound(const Eigen::Vector3d corners[3], const Eigen::Vector3d& triangle_center,
                                       double triangle_radius, const Eigen::Vector3d& normal, double offset,
                                       const Eigen::Vector3d& node_center, double node_radius,
                                       const Eigen::Matrix3d& axes, const Eigen::Vector3d& box_center,
                                       const Eigen::Vector3d& half, double threshold, std::uint8_t spine_code) {
    double bound = (node_center - triangle_center).norm() - triangle_radius - node_radius;
    if (bound >= threshold) return bound;
    const Eigen::Vector3d line = box_center - triangle_center;
    const double length = line.norm();
    if (length > 0) {
      const double reach_triangle =
          std::max({line.dot(corners[0] - triangle_center), line.dot(corners[1] - triangle_center),
                    line.dot(corners[2] - triangle_center)});
      const double reach_box = half.dot((axes.transpose() * line).cwiseAbs());
      bound = std::max(bound, (length * length - reach_triangle - reach_box) / length);
      if (bound >= threshold) return bound;
    }
    const Eigen::Vector3d normal_in_box = axes.transpose() * normal;
    const double plane_reach = half.dot(normal_in_box.cwiseAbs());
    bound = std::max(bound, std::abs(normal.dot(box_center) - offset) - plane_reach);
    if (bound >= threshold) return bound;
    for (int axis = 0; axis < 3; ++axis) {
      const Eigen::Vector3d u = axes.col(axis);
      const double middle = u.dot(box_center);
      const double p0 = u.dot(corners[0]) - middle, p1 = u.dot(corners[1]) - middle, p2 = u.dot(corners[2]) - middle;
      bound = std::max({bound, std::min({p0, p1, p2}) - half[axis], -half[axis] - std::max({p0, p1, p2})});
    }
    if (bound >= threshold) return bound;
    // The triangle's axis-aligned box: against the node's sphere, and along each coordinate axis against the
    // node's box (tight beside the faces of an axis-aligned part).
    const Eigen::Vector3d low = corners[0].cwiseMin(corners[1]).cwiseMin(corners[2]);
    const Eigen::Vector3d high = corners[0].cwiseMax(corners[1]).cwiseMax(corners[2]);
    const Eigen::Vector3d outside = (low - node_center).cwiseMax(node_center - high).cwiseMax(0.0);
    const Eigen::Vector3d box_reach = axes.cwiseAbs() * half;
    const Eigen::Vector3d box_gap = (low - box_center).cwiseMax(box_center - high) - box_reach;
    bound = std::max({bound, outside.norm() - node_radius, box_gap.maxCoeff()});
    if (bound >= threshold) return bound;
    // A sliver is nearly a segment, and a segment and a box are separated along their directions' cross
    // products as often as along the box's axes; its sphere and plane say little about a node beside it (a
    // CAD cylinder's sides, 235 times longer than wide, against a modelled figure's nodes passed nearly all of
    // the terms above, and each node's triangles then went to the pair filter).
    if ((spine_code & kSliverSpine) != 0) {
      const int edge = spine_code & 3;
      const Eigen::Vector3d along = corners[edge == 2 ? 0 : edge + 1] - corners[edge];
      const Eigen::Vector3d in_box = axes.transpose() * along;
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d axis = along.cross(axes.col(k));
        const double axis_squared = axis.squaredNorm();
        if (!(axis_squared > 1e-12 * along.squaredNorm())) continue;
        const double p0 = axis.dot(corners[0]), p1 = axis.dot(corners[1]), p2 = axis.dot(corners[2]);
        const double middle = axis.dot(box_center);
        // |axis . u_j| for the box's axes: (along x u_k) . u_j = along . (u_k x u_j), zero for j = k.
        const int i = (k + 1) % 3, j = (k + 2) % 3;
        const double reach = half[i] * std::abs(in_box[j]) + half[j] * std::abs(in_box[i]);
        const double gap = std::max(std::min({p0, p1, p2}) - middle - reach, middle - reach - std::max({p0, p1, p2}));
        if (gap > 0) bound = std::max(bound, gap / std::sqrt(axis_squared));
      }
      if (bound >= threshold) return bound;
    }
    // In the plane, across each edge: where the node lies beside a large triangle rather than over it.
    for (int edge = 0; edge < 3; ++edge) {
      const Eigen::Vector3d& from = corners[edge];
      const Eigen::Vector3d across = normal.cross(corners[edge == 2 ? 0 : edge + 1] - from);
      const double across_squared = across.squaredNorm();
      if (!(across_squared > 0)) continue;
      const double outward = -across.dot(corners[edge == 0 ? 2 : edge - 1] - from);  // the third corner inward
      const double sign = outward < 0 ? -1.0 : 1.0;
      const double gap = sign * across.dot(box_center - from) - half.dot((axes.transpose() * across).cwiseAbs());
      bound = std::max(bound, gap / std::sqrt(across_squared));
    }
    return bound;
  }
  // A's triangle at leaf position m against a placed node of B.
  double triangleOfANodeLowerBound(int m, const PlacedNode& b, double threshold) const {
    const Eigen::Vector4d& sphere = mesh_a_.leaf_spheres[m];
    const Eigen::Vector4d& plane = mesh_a_.leaf_planes[m];
    return triangleNodeLowerBound(mesh_a_.corners.in_leaf_order[m].data(), sphere.head<3>(), sphere[3], plane.head<3>(),
                                  plane[3], b.center, b.node->radius, b.obb_axes, b.obb_center, b.node->obb_half,
                                  threshold, mesh_a_.spines[std::size_t(mesh_a_.bvh.triangle_ids[m])]);
  }
  // A prepared triangle of B against node a of A's Bvh.
  double triangleOfBNodeLowerBound(const PreparedTriangle& tb, int a, double threshold) const {
    const BvhNode& node = mesh_a_.bvh.nodes[a];
    const double box_gap = std::sqrt(detail::nodeBoxSquaredDistance(tb.center, node)) - tb.radius;
    if (box_gap >= threshold) return box_gap;
    return std::max(box_gap, triangleNodeLowerBound(tb.corners, tb.center, tb.radius, tb.normal, tb.offset, node.center,
                                                    node.radius, node.obb_axes, node.obb_center, node.obb_half,
                                                    threshold, tb.spine_code));
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
    auto offer = [&](double lower_bound, int node_b, int node_a) CFL_ALWAYS_INLINE {
      if (lower_bound >= pruneThreshold()) return;
      offered[offered_count++] = {searchKey(lower_bound, nodes_b[node_b].radius), node_b, node_a};
    };
    auto push = [&](const Scratch::HeapEntry& entry) CFL_ALWAYS_INLINE {
      heapPush(heap, entry);
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
      // Outside the regions, or within a leaf that keeps no list (far above a flat part, among many tiny
      // triangles), the node continues as node pairs of the two Bvhs: best-first on oriented boxes, cheaper
      // there than taking its triangles to A's Bvh one by one. A node larger than that leaf reaches past it
      // and keeps the field's bounds: switching the upper nodes of B whose centers happen to lie in such a
      // leaf took the rock's short-range queries from lists to node pairs, which cost them far more.
      if ((nearest - center).squaredNorm() > radius * radius ||
          (!a_.regions.hasList(cell.leaf) && radius < cell.size)) {
        offer(std::max(lower_bound, nodePairLowerBound(0, place(n, center), pruneThreshold())), n, 0);
      } else if (lower_bound > 0 && lower_bound < pruneThreshold() && radius < cell.size &&
                 a_.regions.leafListLength(cell.leaf) <= std::uint32_t(kShortListTriangles) &&
                 pairWithShortLists(n, center, radius, lower_bound, push)) {
        // (The leaf at the node's center is one of those pairWithShortLists reads: a long list there
        // rules the pairing out before the walk over the leaves its box meets.)
        // Paired with the few triangles of A listed around it (see pairWithShortLists), where the field is
        // loosest: a node smaller than the coarse leaf it lies in. Not where the node may overlap A, whose
        // dive to the first contact the grid's bounds lead faster (ground_bunny against itself at contact
        // took longer with fewer tests).
      } else if (lower_bound < pruneThreshold() && radius < 1.5 * cell.size) {
        // Larger nodes are rarely flat enough for the far corners to beat the sphere's bound. 1.5 voxels
        // rather than 2 since the nodes' spheres are near the smallest: fewer instructions at short range,
        // more overlapping (docs/performance.md).
        const PlacedNode placed = place(n, center);
        const double far =
            farCornerLowerBound(cell, placed.obb_center, placed.obb_axes, placed.node->obb_half);
        offer(std::max(lower_bound, far), n, kAgainstGrid);
      } else {
        offer(lower_bound, n, kAgainstGrid);
      }
    };
    // Not in a certifying search, whose pair list must follow the best-first order's pruning.
    if (near_pairs_ == nullptr && best_ > 0) probeForContact();
    if (best_ <= 0) return;
    offerAgainstGrid(0);
    Scratch::HeapEntry entry;
    bool have_entry = false;
    if (offered_count > 0) entry = offered[0], have_entry = true;
    while (true) {
      if (!have_entry) {
        if (heap.empty()) break;
        entry = heapPop(heap);
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

  // A short depth-first descent of node pairs of the two Bvhs whose oriented boxes overlap, for a triangle
  // pair that intersects: where the meshes overlap, that ends the query (distance 0 cannot be beaten), and
  // the best-first search, whose bounds are all 0 there, would otherwise spread over many pieces before it
  // tests one. Triangle pairs met on the way are tested as usual, so what the descent finds is at worst an
  // upper bound for the search that follows; it prunes nothing, and stops after kContactProbeBounds bounds
  // (kContactProbeFanBounds with a fan).
  void probeForContact() {
    struct PairStep {
      int node_b, node_a;
    };
    const auto& nodes_a = mesh_a_.bvh.nodes;
    const auto& nodes_b = b_.bvh.nodes;
    // B's largest leaf (found down the larger child) as a share of B's radius.
    int largest = 0;
    while (!nodes_b[largest].isLeaf()) {
      const int first = nodes_b[largest].first;
      largest = nodes_b[first + 1].radius > nodes_b[first].radius ? first + 1 : first;
    }
    // Whether a mesh is a fan: every node down the smaller child keeps kContactProbeLargeLeaf of the root's
    // radius. Other meshes leave after the first few levels, near the root, where the search starts too.
    auto isFan = [](const std::vector<BvhNode>& nodes) {
      const double least = kContactProbeLargeLeaf * nodes[0].radius;
      int n = 0;
      while (!nodes[n].isLeaf()) {
        const int first = nodes[n].first;
        n = nodes[first + 1].radius < nodes[first].radius ? first + 1 : first;
        if (!(nodes[n].radius >= least)) return false;
      }
      return true;
    };
    // Only where B holds triangles about as large as itself (its largest leaf), whose spheres reach A
    // wherever they lie and leave the grid's bounds at 0 over most of B: the search then spreads over B
    // breadth-first. Over smaller triangles the grid's bounds find the crossing triangles sooner than this
    // descent, and it would only add its cost. Or where either mesh is a fan, every leaf of it as large
    // (slivers fanned about one vertex: each wedge of the fan reaches from its hub to its rim, so nodes of
    // the fan do not shrink as they split): node pairs with a fan of A then split A's wedges, which keep
    // their radius, before the other mesh, and spread over the whole fan before any triangle pair is met.
    const bool large_b = nodes_b[largest].radius >= kContactProbeLargeLeaf * nodes_b[0].radius;
    const bool fan_a = isFan(nodes_a);
    const bool fan_b = large_b && isFan(nodes_b);
    if (!large_b && !fan_a) return;
    // And only where the two roots' oriented boxes overlap deeply for their size: near contact but apart, or
    // where a small B lies anywhere inside A's box, the descent runs its whole budget for nothing. Their size
    // is at most the thicker root box's thinnest extent: two crossing slabs overlap by about their
    // thickness however wide they are, so that the radius alone kept the descent from every such pose.
    // With a fan, any overlap of the roots: a fan is flat or nearly so, and a mesh crossing it overlaps its
    // box by no more than the part of that mesh that reaches through, however deep the crossing looks.
    const double root = nodePairLowerBound(0, place(0, X_AB_.apply(nodes_b[0].center)), kInfinity);
    const double size = std::min(std::max(nodes_b[0].radius, nodes_a[0].radius),
                                 2 * std::max(nodes_a[0].obb_half.minCoeff(), nodes_b[0].obb_half.minCoeff()));
    if (!(root < (fan_a || fan_b ? 0 : -kContactProbeOverlap * size))) return;
    // Against a fan, the other mesh splits first, down to its leaves: a small box of it that crosses the fan
    // then meets few of the wedges, where a wedge split first meets the other mesh's whole box wherever that
    // lies along the wedge. Otherwise the larger node splits, by sphere radius.
    const bool fan_last = fan_a != fan_b;
    // With a fan, leaf pairs test only the triangle pairs that may touch (within a hair of the scale, for
    // the filter's rounding): a small leaf near the hub meets every wedge, and its pairs with their slivers,
    // all near each other, pass the filter at the best distance so far and would each pay the exact test.
    // Without one, every pair the filter passes: where the descent finds no contact (the meshes apart), the
    // pairs it tested leave the search an upper bound that prunes from the start.
    const double touching = kContactProbeTouching * nodes_a[0].radius;
    PairStep stack[128];
    int top = 0;
    stack[top++] = {0, 0};
    int budget = fan_a || fan_b ? kContactProbeFanBounds : kContactProbeBounds;
    while (top > 0 && best_ > 0) {
      const PairStep step = stack[--top];
      const BvhNode& node_a = nodes_a[step.node_a];
      const BvhNode& node_b = nodes_b[step.node_b];
      if (node_a.isLeaf() && node_b.isLeaf()) {
        for (int n = node_b.first; n < node_b.first + node_b.count && best_ > 0; ++n) {
          const PreparedTriangle& tb = preparedAtLeaf(n);
          for (int m = node_a.first; m < node_a.first + node_a.count && best_ > 0; ++m) {
            if (fan_a || fan_b) {
              testPairIfTouching(mesh_a_.bvh.triangle_ids[m], tb, touching);
            } else {
              testPairIfCloseOutOfLine(mesh_a_.bvh.triangle_ids[m], tb);
            }
          }
        }
        continue;
      }
      if (budget <= 0 || top + 2 > 128) continue;
      budget -= 2;
      const bool a_splits =
          !node_a.isLeaf() && (node_b.isLeaf() || (fan_last ? fan_b : node_a.radius >= node_b.radius));
      double bounds[2];
      PairStep children[2];
      if (a_splits) {
        const PlacedNode placed = place(step.node_b, X_AB_.apply(node_b.center));
        for (int k = 0; k < 2; ++k) {
          ++counters_.voxel_tests;
          children[k] = {step.node_b, node_a.first + k};
          bounds[k] = nodePairLowerBound(node_a.first + k, placed, 0);
        }
      } else {
        for (int k = 0; k < 2; ++k) {
          ++counters_.voxel_tests;
          const int child = node_b.first + k;
          children[k] = {child, step.node_a};
          bounds[k] = nodePairLowerBound(step.node_a, place(child, X_AB_.apply(nodes_b[child].center)), 0);
        }
      }
      // The pair whose boxes overlap deeper first, on top of the stack.
      const int first = bounds[1] < bounds[0] ? 1 : 0;
      if (bounds[1 - first] < 0) stack[top++] = children[1 - first];
      if (bounds[first] < 0) stack[top++] = children[first];
    }
  }

  // B's node n (sphere `center`, `radius`, in A's frame) against the triangles of A listed in the leaves its
  // sphere's box meets, when those are few (over a large flat part of A: a ground plane's two triangles):
  // each becomes a pair (node, triangle of A), bounded on the node's oriented box, and split as node pairs
  // are. Every point of the node lies in one of these leaves, whose list holds its closest triangle of A, so
  // these pairs cover the node. The field's bounds there lose a fraction of a coarse leaf's edge, more than
  // the gaps between B's nearly level triangles above a plane: each triangle of B then went through the
  // grid one by one, where the triangle's plane against the node's thin box prunes whole subtrees.
  // A certifying search takes the leaves within its margin too, as testTriangleAgainstLists does: the
  // closest triangles of every point the node can reach are then among the pairs.
  // `lower_bound`: the field's bound on the node. Returns false, having pushed nothing, where a leaf has no
  // list or the lists hold more than kShortListTriangles triangles.
  template <class Push>
  bool pairWithShortLists(int n, const Eigen::Vector3d& center, double radius, double lower_bound, Push& push) {
    const RegionTree& regions = a_.regions;
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(radius + margin_);
    // Points past the grid have no leaf, and so no list that holds their closest triangle.
    if (!((center - reach).array() >= grid_box_.min.array()).all() ||
        !((center + reach).array() <= grid_box_.max.array()).all()) {
      return false;
    }
    int triangles[kShortListTriangles];
    int count = 0;
    int leaves_left = kShortListLeaves;
    const bool short_lists = regions.forEachLeafInBox(center - reach, center + reach, [&](const RegionCell& cell) {
      if (!regions.hasList(cell.leaf) || --leaves_left < 0) return false;
      const std::uint32_t length = regions.leafListLength(cell.leaf);
      if (length > std::uint32_t(kShortListTriangles)) return false;
      for (std::uint32_t e = 0; e < length; ++e) {
        const int t = regions.leafListTriangle(cell.leaf, e);
        if (std::find(triangles, triangles + count, t) != triangles + count) continue;
        if (count == kShortListTriangles) return false;
        triangles[count++] = t;
      }
      return true;
    });
    if (!short_lists) return false;
    const PlacedNode placed = place(n, center);
    for (int k = 0; k < count; ++k) {
      const int m = mesh_a_.corners.leaf_position[triangles[k]];
      ++counters_.voxel_tests;
      const double bound = std::max(lower_bound, triangleOfANodeLowerBound(m, placed, pruneThreshold()));
      if (bound < pruneThreshold()) push(Scratch::HeapEntry{searchKey(bound, radius), n, kFirstTriangleOfA - m});
    }
    return true;
  }

  // Whether a node of B lies wholly in A's grid (by its sphere): its triangles then take the lists' path,
  // and bounding them one by one against the grid cannot cost the node pairs' pruning outside it.
  bool insideGrid(const BvhNode& node) const {
    const Eigen::Vector3d center = X_AB_.apply(node.center);
    const Eigen::Vector3d reach = Eigen::Vector3d::Constant(node.radius);
    return ((center - reach).array() >= grid_box_.min.array()).all() &&
           ((center + reach).array() <= grid_box_.max.array()).all();
  }

  // Whether a triangle of the subtree below `node` (inside the grid) is too large for the lists of the leaf
  // at its center (testTriangleAtLeaf's test), or that leaf keeps no list: each triangle would then walk
  // A's Bvh alone, bounded by its sphere, where the subtree's node pairs share the walk and prune on
  // oriented boxes (a disk fanned into slivers keeps no list anywhere).
  bool holdsLargeTriangle(const BvhNode& node) const {
    for (int n = node.subtree_first; n < node.subtree_first + node.subtree_count; ++n) {
      const Eigen::Vector4d& sphere = b_.leaf_spheres[n];
      const RegionCell& cell = locate(X_AB_.apply(sphere.head<3>()));
      if (sphere[3] >= kLargeTriangleCells * cell.size || !a_.regions.hasList(cell.leaf)) return true;
    }
    return false;
  }

  // Offers B's node of a grid entry as a node pair with A's root, on the larger of the entry's bound and the
  // pair's: the node's triangles are then bounded against A's Bvh in groups, as FCL does, instead of each
  // walking A's whole Bvh. An entry's key is its lower bound where positive (searchKey); 0 bounds any pair.
  template <class Offer>
  void offerPairs(const Scratch::HeapEntry& entry, const BvhNode& node_b, Offer& offer) {
    const PlacedNode placed = place(entry.node_b, X_AB_.apply(node_b.center));
    offer(std::max({entry.key, 0.0, nodePairLowerBound(0, placed, pruneThreshold())}), entry.node_b, 0);
  }

  // One step of runHierarchical: tests a triangle or a leaf's triangles, or offers the children of a node
  // (the larger piece of a pair, by sphere radius; a leaf of several triangles splits into its triangles).
  template <class Offer, class OfferAgainstGrid, class Push>
  void expand(const Scratch::HeapEntry& entry, Offer& offer, OfferAgainstGrid& offerAgainstGrid, Push& push) {
    if (entry.node_a == kTriangleOfB) {
      testTriangleAtLeaf(entry.node_b, entry.key > 0 ? entry.key : -kInfinity, push);
      return;
    }
    if (entry.node_b <= kFirstTriangleOfB) {
      expandTriangleOfB(entry, push);
      return;
    }
    const BvhNode& node_b = b_.bvh.nodes[entry.node_b];
    if (entry.node_a == kAgainstGrid) {
      if (node_b.isLeaf() && !insideGrid(node_b)) {
        // A leaf reaching past A's grid goes on whole as a node pair with A's root: its triangles share the
        // walk down A's Bvh, bounded on oriented boxes, as in FCL's traversal. Split into its triangles
        // against the grid instead, those reaching past it each walked A's Bvh alone (the lists cannot take
        // them) and the others kept the grid's loose bounds far from A: slivers of refined_patch far apart
        // walked most of A's Bvh one by one.
        offerPairs(entry, node_b, offer);
        return;
      }
      if (node_b.subtree_count <= kSmallSubtreeTriangles && insideGrid(node_b)) {
        // Queued on its nearest corner's bound; each triangle's cell may already rule it out. Its triangles
        // are tested nearest first, without the heap traffic of the last levels, while none pending is
        // nearer; the rest go back to the heap on their own bounds. Testing them all at once would scan
        // triangles far from the answer before any pair is known, when every list entry passes the
        // filters.
        const int first = node_b.subtree_first, last = first + node_b.subtree_count;
        prefetchRange(&b_.leaf_spheres[first], b_.leaf_spheres.data() + last);
        prefetchRange(&b_.corners.in_leaf_order[first], b_.corners.in_leaf_order.data() + last);
        prefetchRange(&b_.leaf_planes[first], b_.leaf_planes.data() + last);
        // A triangle larger than the leaves around it would leave the lists for a walk of A's Bvh of its
        // own. The subtree goes on as node pairs instead: the walk down A's Bvh is then shared by the
        // subtree's triangles and pruned on oriented boxes, the way FCL's traversal is (see offerPairs).
        if (holdsLargeTriangle(node_b)) {
          offerPairs(entry, node_b, offer);
          return;
        }
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
            testTriangleAtLeaf(leaf, lower_bound, push);
          }
        }
      } else if (node_b.isLeaf()) {
        for (int n = node_b.first; n < node_b.first + node_b.count; ++n) testTriangleAtLeaf(n, -kInfinity, push);
      } else {
        offerAgainstGrid(node_b.first);
        offerAgainstGrid(node_b.first + 1);
      }
      return;
    }
    if (entry.node_a <= kFirstTriangleOfA) {
      expandTriangleOfA(entry, offer);
      return;
    }
    const BvhNode& node_a = mesh_a_.bvh.nodes[entry.node_a];
    if ((node_a.isLeaf() && node_b.isLeaf()) ||
        std::int64_t(node_a.subtree_count) * node_b.subtree_count <= kSmallPairTriangles) {
      if (node_b.subtree_count == 1 && !node_a.isLeaf()) {
        // One triangle of B against a small subtree of A: a walk of the subtree, nearest child first, prunes
        // them on its boxes and B's plane, where testing them pair by pair in the subtree's order bounds
        // each only by the best pair found so far. A large triangle (a ground plane's) against a detailed
        // part of A otherwise reaches the exact test with most of them.
        PreparedTriangle tb;
        prepareAtLeaf(node_b.subtree_first, tb);
        testTriangleAgainstBvh(tb, entry.node_a);
        return;
      }
      if (testFarBlock(node_a, node_b)) return;
      for (int n = node_b.subtree_first; n < node_b.subtree_first + node_b.subtree_count; ++n) {
        const PreparedTriangle& tb = preparedAtLeaf(n);
        for (int m = node_a.subtree_first; m < node_a.subtree_first + node_a.subtree_count; ++m) {
          testPairIfClose(mesh_a_.bvh.triangle_ids[m], tb);
        }
      }
      return;
    }
    // The larger piece splits, by sphere radius: a node into its children, a leaf of several triangles into
    // its triangles, each bounded on its own as a child would be. But a leaf against a node at least as
    // large as the leaf is wide (its middle half extent) stays whole and the node splits: split first, each
    // of the leaf's triangles walked the node's subtree alone (a fan's slivers, side by side in a needle
    // whose radius is half its length, against a bunny's nodes; a pipe's rings against another pipe).
    // Against a smaller node or a leaf, the leaf's triangles are apart for the other's size, and splitting
    // the leaf pays (a bolt's small nodes against an assembly's long parts).
    auto splitsFirst = [](const BvhNode& leaf, const BvhNode& other) {
      const Eigen::Vector3d& half = leaf.obb_half;
      return other.isLeaf() || other.radius < half.sum() - half.maxCoeff() - half.minCoeff();
    };
    const bool a_splits = !node_a.isLeaf() || (node_a.count > 1 && splitsFirst(node_a, node_b));
    const bool b_splits = !node_b.isLeaf() || (node_b.count > 1 && splitsFirst(node_b, node_a));
    if (a_splits && (!b_splits || node_a.radius >= node_b.radius)) {
      const PlacedNode placed = place(entry.node_b, X_AB_.apply(node_b.center));
      if (!node_a.isLeaf()) {
        for (int child = node_a.first; child <= node_a.first + 1; ++child) {
          ++counters_.voxel_tests;
          offer(std::max(entry.key, nodePairLowerBound(child, placed, pruneThreshold())), entry.node_b, child);
        }
        return;
      }
      splitLeafOfA(entry, node_a, placed, offer, push);
    } else if (!node_b.isLeaf()) {
      for (int child = node_b.first; child <= node_b.first + 1; ++child) {
        ++counters_.voxel_tests;
        const PlacedNode placed = place(child, X_AB_.apply(b_.bvh.nodes[child].center));
        offer(nodePairLowerBound(entry.node_a, placed, pruneThreshold()), child, entry.node_a);
      }
    } else {
      splitLeafOfB(entry, node_b, push);
    }
  }

  // The triangle pairs of two small subtrees far apart for their size, behind one shared bound first: their
  // projections on the line between the two nodes' centers. Each pair's own filter (mayBeCloser) projects
  // its two triangles on the line between their own centers, six projections a pair; far apart the shared
  // line is nearly as tight, and costs three projections a triangle. Returns false, having tested nothing,
  // where the subtrees are too large for its buffers or too near for one line to serve every pair.
  bool testFarBlock(const BvhNode& node_a, const BvhNode& node_b) {
    if (node_a.subtree_count > kSmallPairTriangles || node_b.subtree_count > kSmallPairTriangles) return false;
    if (!(pruneThreshold() > kFarPairRadii * (node_a.radius + node_b.radius))) return false;
    const Eigen::Vector3d axis = X_AB_.apply(node_b.center) - node_a.center;
    const double axis_squared = axis.squaredNorm();
    // Along the axis, the far end of each triangle of A and the near end of each triangle of B.
    double high_a[kSmallPairTriangles];
    for (int k = 0; k < node_a.subtree_count; ++k) {
      const auto& c = mesh_a_.corners[mesh_a_.bvh.triangle_ids[node_a.subtree_first + k]];
      high_a[k] = std::max({dot3(axis, c[0]), dot3(axis, c[1]), dot3(axis, c[2])});
    }
    for (int n = node_b.subtree_first; n < node_b.subtree_first + node_b.subtree_count && best_ > 0; ++n) {
      const PreparedTriangle& tb = preparedAtLeaf(n);
      const double low_b =
          std::min({dot3(axis, tb.corners[0]), dot3(axis, tb.corners[1]), dot3(axis, tb.corners[2])});
      for (int k = 0; k < node_a.subtree_count; ++k) {
        const double gap = low_b - high_a[k];
        const double threshold = pruneThreshold();
        if (gap > 0 && gap * gap >= threshold * threshold * axis_squared) continue;
        testPairIfClose(mesh_a_.bvh.triangle_ids[node_a.subtree_first + k], tb);
      }
    }
    return true;
  }

  // testPairIfClose for the rare steps below: a further inlined copy tipped GCC into keeping every copy out
  // of line, the hot loops' included.
  CFL_NOINLINE void testPairIfCloseOutOfLine(int a, const PreparedTriangle& tb) { testPairIfClose(a, tb); }
  // The contact probe's pair test: only a pair that may lie within `touching` (a length near 0) of each
  // other, by mayBeCloser's bounds.
  CFL_NOINLINE void testPairIfTouching(int a, const PreparedTriangle& tb, double touching) {
    if (mayBeCloser(a, tb, std::min(touching, pruneThreshold()))) testPair(a, tb);
  }

  // The rarer steps of expand, out of line: inlined, they made expand too large for GCC to inline into
  // runHierarchical, which then paid a call and its register saves on every step.

  // A triangle of B (a leaf of several, split into its triangles) against a node of A.
  template <class Push>
  CFL_NOINLINE void expandTriangleOfB(const Scratch::HeapEntry& entry, Push& push) {
    const PreparedTriangle& tb = preparedAtLeaf(kFirstTriangleOfB - entry.node_b);
    const BvhNode& node_a = mesh_a_.bvh.nodes[entry.node_a];
    if (node_a.isLeaf() || node_a.subtree_count <= kSmallPairTriangles) {
      for (int m = node_a.subtree_first; m < node_a.subtree_first + node_a.subtree_count && best_ > 0; ++m) {
        testPairIfCloseOutOfLine(mesh_a_.bvh.triangle_ids[m], tb);
      }
      return;
    }
    for (int child = node_a.first; child <= node_a.first + 1; ++child) {
      ++counters_.voxel_tests;
      const double lower_bound = std::max(entry.key, triangleOfBNodeLowerBound(tb, child, pruneThreshold()));
      if (lower_bound < pruneThreshold())
        push(Scratch::HeapEntry{searchKey(lower_bound, tb.radius), entry.node_b, child});
    }
  }

  // A triangle of A (a leaf of several, split into its triangles) against a node of B.
  template <class Offer>
  CFL_NOINLINE void expandTriangleOfA(const Scratch::HeapEntry& entry, Offer& offer) {
    const BvhNode& node_b = b_.bvh.nodes[entry.node_b];
    const int m = kFirstTriangleOfA - entry.node_a;
    if (node_b.isLeaf() || node_b.subtree_count <= kSmallPairTriangles) {
      const int a = mesh_a_.bvh.triangle_ids[m];
      for (int n = node_b.subtree_first; n < node_b.subtree_first + node_b.subtree_count && best_ > 0; ++n) {
        testPairIfCloseOutOfLine(a, preparedAtLeaf(n));
      }
      return;
    }
    for (int child = node_b.first; child <= node_b.first + 1; ++child) {
      ++counters_.voxel_tests;
      const PlacedNode placed = place(child, X_AB_.apply(b_.bvh.nodes[child].center));
      offer(triangleOfANodeLowerBound(m, placed, pruneThreshold()), child, entry.node_a);
    }
  }

  // A leaf of A split into its triangles against B's node (placed).
  template <class Offer, class Push>
  CFL_NOINLINE void splitLeafOfA(const Scratch::HeapEntry& entry, const BvhNode& node_a, const PlacedNode& placed,
                                 Offer& offer, Push& push) {
    for (int m = node_a.first; m < node_a.first + node_a.count; ++m) {
      ++counters_.voxel_tests;
      const double lower_bound = std::max(entry.key, triangleOfANodeLowerBound(m, placed, pruneThreshold()));
      if (m - node_a.first < 2) {  // offer() takes two entries a step
        offer(lower_bound, entry.node_b, kFirstTriangleOfA - m);
      } else if (lower_bound < pruneThreshold()) {
        push(Scratch::HeapEntry{searchKey(lower_bound, placed.node->radius), entry.node_b, kFirstTriangleOfA - m});
      }
    }
  }

  // A leaf of B split into its triangles against node entry.node_a of A.
  template <class Push>
  CFL_NOINLINE void splitLeafOfB(const Scratch::HeapEntry& entry, const BvhNode& node_b, Push& push) {
    for (int n = node_b.first; n < node_b.first + node_b.count; ++n) {
      ++counters_.voxel_tests;
      const PreparedTriangle& tb = preparedAtLeaf(n);
      const double lower_bound = triangleOfBNodeLowerBound(tb, entry.node_a, pruneThreshold());
      if (lower_bound < pruneThreshold()) {
        push(Scratch::HeapEntry{searchKey(lower_bound, tb.radius), kFirstTriangleOfB - n, entry.node_a});
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
    const RegionTree& regions = b_model.regions;
    const Aabb box = regions.bounds();
    if (!(lo.array() >= box.min.array()).all() || !(hi.array() <= box.max.array()).all()) return true;
    bool listed = false;
    regions.forEachLeafInBox(lo, hi, [&](const RegionCell& cell) {
      ++counters_.voxel_tests;
      // A leaf without a list cannot tell.
      listed = !regions.hasList(cell.leaf);
      for (std::uint32_t n = 0; !listed && n < regions.leafListLength(cell.leaf); ++n) {
        listed = regions.leafListTriangle(cell.leaf, n) == j;
      }
      return !listed;
    });
    return listed;
  }

  // The paper's four steps (section 4). `b_model` is B's CflModel when it has one (for step 2).
  void runPaper(const CflModel* b_model, const RigidTransform* X_BA) {
    auto& candidates = scratch_.voxel_candidates;
    auto& outside = scratch_.outside_triangles;
    candidates.clear();
    outside.clear();
    const RegionTree& regions = a_.regions;
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
        transformTriangle(b_.corners.in_leaf_order[n], tb);
        const Eigen::Vector3d lo = tb[0].cwiseMin(tb[1]).cwiseMin(tb[2]);
        const Eigen::Vector3d hi = tb[0].cwiseMax(tb[1]).cwiseMax(tb[2]);
        if (!(lo.array() >= grid_box_.min.array()).all() || !(hi.array() <= grid_box_.max.array()).all()) {
          outside.push_back(t);
          continue;
        }
        const std::size_t first_candidate = candidates.size();
        const bool listed = regions.forEachLeafInBox(lo, hi, [&](const RegionCell& cell) {
          ++counters_.voxel_tests;
          const double half = 0.5 * cell.size;
          const Eigen::Vector3d cell_center = cell.min_corner + Eigen::Vector3d::Constant(half);
          // Only leaves the triangle really touches (separating axis test). The slack keeps a triangle lying
          // exactly on a cell face in both cells whatever the rounding.
          Eigen::Vector3d closest;
          kernels_.point_triangle(cell_center, tb[0], tb[1], tb[2], &closest);
          if (detail::cubeTriangleLowerBound(cell_center, half, tb[0], tb[1], tb[2], closest) > 1e-9 * cell.size) {
            return true;
          }
          if (!regions.hasList(cell.leaf)) return false;
          candidates.push_back({double(regions.leaf_lower_bound[cell.leaf]), cell.leaf, t});
          return true;
        });
        // A leaf without a list: the triangle goes to A's Bvh, as outside the regions.
        if (!listed) {
          candidates.resize(first_candidate);
          outside.push_back(t);
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
      for (std::uint32_t n = 0; n < regions.leafListLength(candidate.leaf); ++n) {
        const int a = regions.leafListTriangle(candidate.leaf, n);
        if (b_model && !mutualCondition(*b_model, *X_BA, a, candidate.triangle_b)) continue;
        testPair(a, tb);
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
  const QueryKernelTable& kernels_;
  const CflModel& a_;
  const MeshModel& mesh_a_;
  const MeshModel& b_;
  RigidTransform X_AB_;
  const DistanceOptions& options_;
  Scratch& scratch_;
  Aabb grid_box_;  // the regions' box
  mutable LeafCache located_;                   // locate()'s
  mutable LeafCache probed_[kFarCornerProbes];  // nearestCorner()'s, one per probe distance
  bool exact_ = true;  // no abs_err / rel_err: pruneThreshold's common case, read on every pair
  QueryCounters counters_;
  double best_ = kInfinity;
  double margin_ = 0;
  std::vector<std::array<int, 2>>* near_pairs_ = nullptr;  // (triangle of A, triangle of B)
  int best_a_ = -1, best_b_ = -1;
  Eigen::Vector3d point_a_, point_b_;
  // preparedAtLeaf's cache, by leaf position modulo its size; the leaf positions apart from the triangles,
  // so that a query starts by clearing a few cache lines, not the whole cache.
  static constexpr int kPreparedCacheSize = 128;
  std::array<int, kPreparedCacheSize> prepared_leaf_;
  std::array<PreparedTriangle, kPreparedCacheSize> prepared_;
};

void validateOptions(const DistanceOptions& options) {
  if (!(options.upper_bound >= 0)) {
    std::ostringstream message;
    message << "upper_bound must be >= 0 (infinity for none), got " << options.upper_bound;
    throw Error(message.str());
  }
  if (!(options.rel_err >= 0) || !std::isfinite(options.rel_err) || !(options.abs_err >= 0) ||
      !std::isfinite(options.abs_err)) {
    std::ostringstream message;
    message << "rel_err and abs_err must be finite and >= 0, got rel_err " << options.rel_err << " and abs_err "
            << options.abs_err;
    throw Error(message.str());
  }
}

}  // namespace

DistanceResult distanceImpl(const QueryKernelTable& kernels, const CflModel& a, const Eigen::Isometry3d& X_WA,
                            const MeshModel& b, const Eigen::Isometry3d& X_WB, const DistanceOptions& options,
                            const CflModel* b_model) {
  validateOptions(options);
  const RigidTransform X_AB = relativePose(X_WA, X_WB);
  Search search(kernels, a, b, X_AB, options, tls_scratch);
  if (options.mode == QueryMode::kPaper) {
    RigidTransform X_BA;
    if (b_model) X_BA = RigidTransform{X_AB.rotation.transpose(), -(X_AB.rotation.transpose() * X_AB.translation)};
    search.runPaper(b_model, b_model ? &X_BA : nullptr);
  } else {
    search.runHierarchical();
  }
  return search.result(X_WA);
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
// m lasts about m / step frames; the search that sets it costs more as m grows, and so do the frames that
// reuse it (they test every triangle within the margin). Their sum per frame is least near
// m = sqrt(step * voxel / kMarginCost). Past kLargestCertifiedStep voxels per step, even that margin costs
// more per frame than a search with the previous pair as a hint, and the query searches without one.
constexpr double kMarginCost = 1.5;
constexpr double kLargestCertifiedStep = 0.05;

}  // namespace

DistanceResult cachedDistanceImpl(const QueryKernelTable& kernels, const CflModel& a, const Eigen::Isometry3d& X_WA,
                                  const MeshModel& b, const Eigen::Isometry3d& X_WB, DistanceCache& cache,
                                  const DistanceOptions& options) {
  validateOptions(options);
  if (options.mode != QueryMode::kHierarchical || options.rel_err != 0 || options.abs_err != 0 ||
      options.upper_bound != kInfinity) {
    cache.reset();
    return distanceImpl(kernels, a, X_WA, b, X_WB, options, nullptr);
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
  Search search(kernels, a, b, X_AB, search_options, tls_scratch);
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
  const double voxel = a.regions.cellSize(a.regions.max_depth);
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

DistanceResult bruteForceImpl(const QueryKernelTable& kernels, const MeshModel& a, const Eigen::Isometry3d& X_WA,
                              const MeshModel& b, const Eigen::Isometry3d& X_WB) {
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
      const double squared = kernels.triangle_distance(a.corners[i].data(), tb, &p, &q);
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

bool collisionImpl(const QueryKernelTable& kernels, const MeshModel& a, const Eigen::Isometry3d& X_WA,
                   const MeshModel& b, const Eigen::Isometry3d& X_WB, std::size_t max_contacts,
                   std::vector<Contact>* contacts) {
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
    if (detail::pointBoxSquaredDistance(center_b, na.box()) > nb.radius * nb.radius) continue;
    const double reach = na.radius + nb.radius;
    if ((center_b - na.center).squaredNorm() > reach * reach) continue;
    if (na.isLeaf() && nb.isLeaf()) {
      for (int i = na.first; i < na.first + na.count && found < limit; ++i) {
        for (int j = nb.first; j < nb.first + nb.count && found < limit; ++j) {
          const int ta = a.bvh.triangle_ids[i], tb_id = b.bvh.triangle_ids[j];
          Eigen::Vector3d tb[3];
          for (int n = 0; n < 3; ++n) tb[n] = X_AB.apply(b.corners[tb_id][n]);
          Eigen::Vector3d point;
          if (kernels.triangles_intersect(a.corners[ta].data(), tb, &point)) {
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

}  // namespace cfl::detail
