#pragma once
/// @file
/// What the tool checks CFL's distances against: FCL OBBRSS where the two agree, brute force where not.

#include "cfl/cfl_model.h"

#include <Eigen/Geometry>

#include <initializer_list>

namespace cfl::tool {

/// Settles each pose's reference distance. FCL OBBRSS is fast and usually exact, but not always: FCL 0.7's
/// triangle distance skips its vertex-face case when a triangle's squared edge cross product is below an
/// absolute 1e-15, i.e. for triangles of area under 1.6e-8 square units (edges under about 2e-4 units, as
/// in a mesh in metres with 0.2 mm detail), and then answers with an edge distance, or 0 for triangles
/// 1e-5 apart. So where a CFL answer and OBBRSS disagree by more than the tolerance, brute force over all
/// triangle pairs (bruteForceDistance) decides, and the pose is counted against FCL when it sides with
/// CFL. Not thread-safe; one per table.
class Referee {
 public:
  /// A at the identity with `a`'s geometry, B as `b`; `tolerance` in A's units (the tool uses 1e-9 of the
  /// diagonal).
  Referee(const MeshModel& a, const MeshModel& b, double tolerance) : a_(a), b_(b), tolerance_(tolerance) {}

  /// The reference distance at pose X_WB: `obbrss` when every one of `cfl_answers` is within the tolerance
  /// of it, else brute force's (O(|A| |B|)).
  double reference(const Eigen::Isometry3d& X_WB, double obbrss, std::initializer_list<double> cfl_answers);

  /// Poses where brute force found OBBRSS off by more than the tolerance, and the largest such error.
  int fclErrors() const { return fcl_errors_; }
  double largestFclError() const { return largest_fcl_error_; }
  /// Poses brute force was asked to settle.
  int bruteForceChecks() const { return brute_force_checks_; }

 private:
  const MeshModel& a_;
  const MeshModel& b_;
  double tolerance_;
  int fcl_errors_ = 0;
  double largest_fcl_error_ = 0;
  int brute_force_checks_ = 0;
};

}  // namespace cfl::tool
