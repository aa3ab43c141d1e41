#pragma once
/// @file
/// Distance from many spheres to one CflModel's mesh: a robot approximated by spheres, checked at a
/// configuration, is a batch of point queries minus radii.

#include "cfl/point_query.h"

#include <Eigen/Geometry>

#include <cstddef>
#include <limits>

namespace cfl {

/// The answer for one sphere. World frame.
struct SphereDistance {
  /// The sphere's distance to the mesh: the center's (signed, when asked) point distance minus the radius.
  /// Negative when the sphere reaches the surface (unsigned) or into a closed mesh (signed).
  double distance = std::numeric_limits<double>::infinity();
  Eigen::Vector3d mesh_point = Eigen::Vector3d::Zero();    ///< The center's closest point on the mesh.
  /// The sphere's point nearest the mesh (center - radius * gradient); when signed and inside, its deepest
  /// point. |sphere_point - mesh_point| == |distance| whenever the center is not on the surface.
  Eigen::Vector3d sphere_point = Eigen::Vector3d::Zero();
  int triangle = -1;  ///< The triangle holding mesh_point.
};

/// results[i] for the sphere of center centers_W[i] and radius radii[i], i in [0, count), against the mesh of
/// `model` at X_WM, through computePointDistances (same options, threads included; results do not depend on
/// the thread count). options.upper_bound applies to the sphere distances: a sphere whose distance is not
/// below it gets distance +infinity and triangle -1 (not so when signed: a deep sphere is never dropped).
/// Throws cfl::Error naming the index of a non-finite center or a negative or non-finite radius, before any
/// work, leaving `results` untouched; and like computePointDistance otherwise. Allocates one PointDistance
/// per sphere. Thread-safe.
void computeSphereDistances(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d* centers_W,
                            const double* radii, std::size_t count, SphereDistance* results,
                            const PointQueryOptions& options = {});

/// The closest of the spheres to the mesh (a robot's distance to an obstacle): the SphereDistance of least
/// distance, with its index in `*index` when not null (-1 when none beats options.upper_bound). Serial, each
/// point query bounded by the best sphere so far plus its radius, so spheres that cannot beat it cost a
/// leaf lookup or the top of a Bvh walk. options.threads is ignored. Unsigned only (a signed request throws
/// cfl::Error: a running bound cannot skip a sphere that may be deep inside). Throws like
/// computeSphereDistances. Allocation-free.
SphereDistance computeLeastSphereDistance(const CflModel& model, const Eigen::Isometry3d& X_WM,
                                          const Eigen::Vector3d* centers_W, const double* radii, std::size_t count,
                                          const PointQueryOptions& options = {}, int* index = nullptr);

}  // namespace cfl
