#pragma once
/// @file
/// How deep two closed meshes overlap: the deepest point of either surface inside the other body.

#include "cfl/cfl_model.h"

#include <Eigen/Geometry>

#include <limits>

namespace cfl {

/// Options of a penetration query.
struct PenetrationOptions {
  /// Width of the certified interval [depth, depth_upper] (a length > 0); 0 means 1e-4 of the larger
  /// bounding-box diagonal of the two meshes.
  double tolerance = 0;
};

/// The answer of computePenetration. World frame throughout.
///
/// Definition: depth = max over points x of either surface lying inside the other body of the distance from
/// x to the other body's surface (0 when the bodies do not overlap). It is a lower bound on the translational
/// penetration depth (the shortest translation that separates the bodies: after a translation shorter than
/// depth, the deepest point is still inside), and equals it for two overlapping balls and for two
/// overlapping axis-aligned boxes.
struct PenetrationResult {
  bool overlapping = false;  ///< The bodies share a point (surfaces touch or cross, or one holds the other).
  /// Which body holds the other wholly inside it without the surfaces meeting: 0 none, 1 A holds B, 2 B holds A.
  int contained = 0;
  /// The certified interval: the true depth lies in [depth, depth_upper], depth_upper - depth <= tolerance.
  /// depth is attained: it is the depth of `deepest_point`, a point of one surface inside the other body.
  double depth = 0;
  double depth_upper = 0;
  /// The deepest point found, on the surface of body `deepest_body` (0: A, 1: B), inside the other body.
  Eigen::Vector3d deepest_point = Eigen::Vector3d::Zero();
  /// Its closest point on the other body's surface (depth away).
  Eigen::Vector3d surface_point = Eigen::Vector3d::Zero();
  /// Unit, from deepest_point towards surface_point: the direction that moves body deepest_body's point out
  /// of the other (the other body's outward pseudonormal at surface_point when they coincide).
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  int deepest_body = -1;
  int triangle_a = -1;  ///< The triangles of A and B holding deepest_point and surface_point.
  int triangle_b = -1;
};

/// Penetration of A at X_WA and B at X_WB (both closed; see MeshClosure). Throws cfl::Error naming the mesh
/// and MeshClosure::reason when either is not closed, and for bad poses or options. Thread-safe.
/// Cost: a signed point query per triangle of the part of each surface within the other body's bounds, then
/// a branch and bound over subdivided triangles, bounded by the 1-Lipschitz distance, until the interval
/// is narrower than the tolerance.
PenetrationResult computePenetration(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                                     const Eigen::Isometry3d& X_WB, const PenetrationOptions& options = {});

}  // namespace cfl
