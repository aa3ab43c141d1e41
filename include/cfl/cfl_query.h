#pragma once
/// @file
/// Exact minimum distance between a CflModel A and a mesh B at two rigid poses (paper section 4), and the
/// contact query built on the same data.

#include "cfl/cfl_model.h"

#include <Eigen/Geometry>

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace cfl {

/// Which algorithm answers a distance query. Both are exact.
enum class QueryMode {
  /// The default: B's Bvh is walked best-first against the lower bounds and distance field of A's region
  /// cells, B's triangles are tested against the CFLs of the leaf cells they touch, and parts of B outside
  /// A's regions against A's Bvh.
  kHierarchical,
  /// The paper's four steps, kept to reproduce its Table 2 (voxels are the regions' leaf cells; with
  /// BuildOptions::resolution > 0 they form the paper's uniform grid): collect the voxels of A touched by B's
  /// triangles, (with B's CFLs) keep the pairs passing the mutual closest-feature condition, visit the voxels
  /// in increasing lower bound, test each voxel's CFL against the triangles of B in it, stop when the next
  /// lower bound is not below the best distance. Parts outside the regions use A's Bvh, so it stays exact.
  kPaper,
};

/// Options of a distance query; the defaults give the exact distance.
struct DistanceOptions {
  QueryMode mode = QueryMode::kHierarchical;
  /// FCL's early-termination tolerances: a part of the search is skipped when its lower bound lb satisfies
  /// lb >= best - abs_err and lb * (1 + rel_err) >= best. The returned distance d then satisfies
  /// d <= true + abs_err and d <= true * (1 + rel_err); it is still the distance of the returned pair. Both
  /// conditions must hold, as in FCL, so rel_err alone (abs_err = 0) keeps the query exact; set abs_err too
  /// (e.g. to the diagonal) to let rel_err act alone.
  double rel_err = 0;
  double abs_err = 0;
  /// Warm start: a triangle pair (A id, B id) whose distance seeds the search as an upper bound, such as the
  /// previous result of a moving pair. Ignored when either id is out of range. Never changes the answer.
  int hint_triangle_a = -1;
  int hint_triangle_b = -1;
  /// Only pairs strictly closer than this are looked for (a length, >= 0). A broadphase that already holds a
  /// distance D passes D: a pair of models that cannot beat it is dismissed at the cost of the first bounds
  /// that reach D. When no pair is closer, the result has distance infinity and triangle ids -1; otherwise
  /// it is the exact answer, as without a bound. The default, infinity, always finds the closest pair.
  double upper_bound = std::numeric_limits<double>::infinity();
};

/// Work done by one query (paper Table 2).
struct QueryCounters {
  std::int64_t triangle_pairs = 0;  ///< N_p: triangle-triangle distances computed.
  std::int64_t voxel_tests = 0;     ///< N_v: voxel and bounding-volume tests.
};

/// The answer of a distance query.
struct DistanceResult {
  double distance = std::numeric_limits<double>::infinity();  ///< >= 0; 0 when the meshes touch or overlap.
  Eigen::Vector3d point_a = Eigen::Vector3d::Zero();  ///< p_WA: closest point on A, world frame.
  Eigen::Vector3d point_b = Eigen::Vector3d::Zero();  ///< p_WB: closest point on B, world frame.
  int triangle_a = -1;  ///< Id of the triangle of A holding point_a.
  int triangle_b = -1;  ///< Id of the triangle of B holding point_b.
  QueryCounters counters;
};

/// Distance between A (with CFLs) at pose X_WA and the mesh B at pose X_WB. Poses are rigid transforms
/// (rotation + translation); a non-finite or non-orthonormal rotation throws cfl::Error.
///
/// Exact at every range: `distance` equals the minimum over all triangle pairs, up to rounding. When the
/// meshes intersect, distance is 0 and point_a == point_b is a point of the intersection. Ties between
/// equally close pairs are broken deterministically but arbitrarily.
/// Thread safety: the models are only read; concurrent queries on shared models are safe. No allocation
/// happens in kHierarchical mode beyond a small thread-local scratch reused across calls.
DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options = {});

/// What one query leaves for the next query of the same pair of models, so that a moving pair (a
/// simulator's contact pair, one query per frame) can skip most of the search while staying exact.
///
/// After a full search, the cache holds a certificate for the relative pose searched
/// (`certified_rotation` / `certified_translation`, B in A's frame): a list of triangle pairs such that,
/// wherever a point of B moves by up to `reach`, either it stays at least `level` minus its motion from A,
/// or one of its closest triangles of A is listed with its triangle of B. The search builds the list as it
/// goes: every pair it does not prune below `level`, taking each triangle of B against the voxel lists
/// within `reach` of it (the lists hold the closest triangles of A to every point of their cells) or, past
/// the regions, against A's Bvh. The next query moves B by `motion` from that pose (a bound over every point
/// of B, from the two poses) and tests only the listed pairs; when `motion <= reach` and their best
/// distance is at most `level - motion`, nothing else can be closer and it is the exact answer. Otherwise
/// the query searches again, starting from the best pair found, and refreshes the certificate: it looks a
/// margin (the reach) past its best distance, sized from the motion since the previous query so that the
/// certificate lasts several frames. When B moves more than 5% of a leaf cell's edge per query, a
/// certificate would cost more than it saves: the query then searches with the previous answer as a hint (see
/// hint_triangle_a), as fast as a hinted query, and lists nothing.
///
/// The certificate pays when B moves by a small fraction of a leaf cell per frame, as a robot tracking a
/// trajectory does; `cfl bench --moving N` measures it against cold queries (docs/performance.md has the
/// figures).
///
/// Plain data written by computeDistance: create one per pair of models and pass it to every query of
/// that pair. Calling with other models, another mode, a non-zero rel_err / abs_err or a finite upper_bound
/// resets it (the cache then does nothing for that call). Not thread-safe: one cache per thread and pair.
struct DistanceCache {
  /// Queries answered from the certificate, and queries that searched (statistics for benchmarks).
  std::int64_t reused = 0;
  std::int64_t searched = 0;

  // The state below is read and written by computeDistance only.
  const CflModel* model_a = nullptr;
  const MeshModel* model_b = nullptr;
  std::size_t triangle_counts[2] = {0, 0};  ///< Of A and B, so that a model rebuilt in place is noticed.
  bool certified = false;
  Eigen::Matrix3d certified_rotation = Eigen::Matrix3d::Identity();  ///< R_AB at the certificate.
  Eigen::Vector3d certified_translation = Eigen::Vector3d::Zero();   ///< p_AB at the certificate.
  double level = 0;  ///< Length; see above.
  double reach = 0;  ///< How far B may move from the certified pose before the certificate lapses (length).
  /// The listed (triangle of A, triangle of B) pairs, each once, grouped by B's triangle.
  std::vector<std::array<int, 2>> near_pairs;
  bool has_previous = false;
  Eigen::Matrix3d previous_rotation = Eigen::Matrix3d::Identity();  ///< R_AB of the previous query.
  Eigen::Vector3d previous_translation = Eigen::Vector3d::Zero();
  int previous_triangle_a = -1;  ///< The previous answer's pair, the next search's first upper bound.
  int previous_triangle_b = -1;

  /// Forgets the certificate and the previous pose (keeps the statistics and the memory).
  void reset() {
    model_a = nullptr;
    model_b = nullptr;
    triangle_counts[0] = triangle_counts[1] = 0;
    certified = has_previous = false;
    near_pairs.clear();
    previous_triangle_a = previous_triangle_b = -1;
  }
};

/// computeDistance for a pair in motion: as exact as the call without a cache, and usually much faster
/// when B has moved little relative to A since the previous call with the same cache (see
/// DistanceCache). O(number of cached pairs) when the certificate holds; a full search otherwise.
DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                               const Eigen::Isometry3d& X_WB, DistanceCache& cache,
                               const DistanceOptions& options = {});

/// As above with CFLs on both sides; the query may use B's voxels as well (kPaper uses the mutual
/// closest-feature condition, equation 5 of the paper).
DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options = {});

/// Reference answer by brute force over all triangle pairs, for tests and checks: no voxel, list or Bvh,
/// only the exact triangle distance and each triangle's bounding sphere (MeshModel::spheres), which skips a
/// pair whose spheres are farther apart than the best distance so far (the answer and its pair are those of
/// the full loop). O(|A| |B|): the bunny against itself, 13.5 million pairs, in tens of milliseconds.
/// Like every query here, throws cfl::Error naming the array when a model's arrays disagree in length (a
/// model assembled by hand rather than by makeMeshModel).
DistanceResult bruteForceDistance(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                  const Eigen::Isometry3d& X_WB);

/// One pair of intersecting triangles.
struct Contact {
  int triangle_a = -1;
  int triangle_b = -1;
  Eigen::Vector3d position = Eigen::Vector3d::Zero();  ///< A point of both triangles, world frame.
};

/// Whether A at X_WA and B at X_WB share a point (touching counts), through both Bvhs. Appends up to
/// `max_contacts` intersecting triangle pairs to `contacts` when it is not null (stops at the first one when
/// it is null). Returns true when at least one pair intersects. Thread-safe like computeDistance.
bool computeCollision(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                      const Eigen::Isometry3d& X_WB, std::size_t max_contacts = 1,
                      std::vector<Contact>* contacts = nullptr);

/// Throws cfl::Error naming the problem when X is not a finite rigid transform (orthonormal rotation with
/// determinant +1, to 1e-6). `what` names the pose in the message.
void validatePose(const Eigen::Isometry3d& X, const char* what);

}  // namespace cfl
