#pragma once
/// @file
/// How deep two closed meshes overlap: the deepest point of either surface inside the other body.

#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"

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
/// penetration depth (the shortest translation that separates the bodies): after a translation shorter than
/// depth, the deepest point is still inside. It equals it for two balls while neither center is inside the
/// other ball, and for two axis-aligned boxes one of which enters the other through one face; deeper
/// overlaps give less (two unit balls with centers s < 1 apart: s, against 2 - s), because the deepest
/// point of a surface is bounded by how far the surface reaches into the other body.
///
/// The interval: depth is the depth of a point actually found (so the true value is at least that), and
/// depth_upper bounds every point of both surfaces (branch and bound over the surfaces' Bvh nodes and
/// triangles, subdivided, with two bounds: the signed distance is 1-Lipschitz, and over a triangle the
/// distance to the other surface is at most the smallest, over that surface's triangles, of the largest
/// distance from the triangle's corners, distance to a triangle being convex). Arithmetic is in doubles:
/// "certified" up to their rounding, far below any tolerance that can be asked.
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

/// For two closed meshes whose surfaces do not meet: 1 when A holds B (a vertex of B is inside A), 2 when B
/// holds A, 0 when the bodies are apart. Two signed point queries; the answer means nothing when the surfaces
/// meet. Throws cfl::Error naming the mesh and the reason when either is not closed. Thread-safe.
int bodyContainment(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                    const Eigen::Isometry3d& X_WB);

/// Signed distance between two closed meshes: the distance between them when the bodies are apart
/// (computeDistance, with `options`), minus the penetration depth when they overlap (computePenetration, with
/// `penetration`; its certified lower end, so the value is never more negative than the truth), a body wholly
/// inside the other included. On overlap point_a / point_b are the deepest point and its closest point on the
/// other surface, each on its own mesh (|point_a - point_b| = depth), and counters stay zero. A finite
/// options.upper_bound dismisses a pair that is apart and not closer, as in computeDistance (distance
/// infinity, ids -1); an overlapping pair is always reported. Throws cfl::Error naming the mesh and the
/// reason when either is not closed. Thread-safe.
DistanceResult computeSignedDistance(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                                     const Eigen::Isometry3d& X_WB, const DistanceOptions& options = {},
                                     const PenetrationOptions& penetration = {});

}  // namespace cfl
