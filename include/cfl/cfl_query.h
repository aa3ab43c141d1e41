#pragma once
/// @file
/// Exact minimum distance between a CflModel A and a mesh B at two rigid poses (paper section 4), and the
/// contact query built on the same data.

#include "cfl/cfl_model.h"

#include <Eigen/Geometry>

#include <cstdint>
#include <limits>
#include <vector>

namespace cfl {

/// Which algorithm answers a distance query. Both are exact.
enum class QueryMode {
  /// The default: B's Bvh is walked best-first against A's voxel lower bounds and distance field, B's
  /// triangles are tested against the CFLs of the voxels they touch, and parts of B outside A's grid against
  /// A's Bvh.
  kHierarchical,
  /// The paper's four steps, kept to reproduce its Table 2: collect the voxels of A touched by B's
  /// triangles, (with B's CFLs) keep the pairs passing the mutual closest-feature condition, visit the voxels
  /// in increasing lower bound, test each voxel's CFL against the triangles of B in it, stop when the next
  /// lower bound is not below the best distance. Parts outside the grid use A's Bvh, so it stays exact.
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

/// As above with CFLs on both sides; the query may use B's voxels as well (kPaper uses the mutual
/// closest-feature condition, equation 5 of the paper).
DistanceResult computeDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                               const Eigen::Isometry3d& X_WB, const DistanceOptions& options = {});

/// Reference answer by brute force over all triangle pairs. O(|A| |B|); for tests and checks.
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
