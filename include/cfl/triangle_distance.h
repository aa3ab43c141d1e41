#pragma once
/// @file
/// Exact distance kernels between points, segments and triangles: the narrow phase of every query.
///
/// All functions work in whatever frame their arguments share and return squared distances (take the
/// square root once, at the end of a query). They are pure, allocation-free and thread-safe.
/// Degenerate triangles (zero area, collinear or coincident corners) are handled as the segment or point
/// they are; no function divides by a vanishing quantity.

#include <Eigen/Core>

namespace cfl {

/// The closest point to `p` on triangle (a, b, c); also the squared distance.
/// Ties (several closest points, only possible for degenerate triangles) are broken arbitrarily but
/// deterministically.
double pointTriangleSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, Eigen::Vector3d* closest = nullptr);

/// The squared distance between segments [p0, p1] and [q0, q1], with the closest point on each.
/// Zero-length segments are points.
double segmentSegmentSquaredDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                                     const Eigen::Vector3d& q1, Eigen::Vector3d* closest_p = nullptr,
                                     Eigen::Vector3d* closest_q = nullptr);

/// The squared distance between triangles P = (p[0], p[1], p[2]) and Q = (q[0], q[1], q[2]), with the
/// closest point on each (`closest_p` on P, `closest_q` on Q).
///
/// When the triangles intersect (or touch) the distance is 0 and both closest points are the same point of
/// the intersection, unlike FCL 0.7 and PQP, which return points on each triangle that may be far apart.
/// Cost: 6 point-triangle and 9 segment-segment distances, plus at most 6 segment-triangle crossings.
double triangleTriangleSquaredDistance(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3],
                                       Eigen::Vector3d* closest_p = nullptr, Eigen::Vector3d* closest_q = nullptr);

/// Whether triangles P and Q share at least one point (touching counts). Consistent with
/// triangleTriangleSquaredDistance(p, q) == 0 and cheaper. When they do and `point` is given, it receives a
/// point of the intersection.
bool trianglesIntersect(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3], Eigen::Vector3d* point = nullptr);

}  // namespace cfl
