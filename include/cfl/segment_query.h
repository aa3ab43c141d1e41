#pragma once
/// @file
/// Distance from a segment to a CflModel's mesh, unsigned or signed: the core of capsule queries (a capsule
/// is the set of points within its radius of a segment), and of spheres when the segment is a point.

#include "cfl/cfl_model.h"

#include <Eigen/Geometry>

#include <cstddef>
#include <limits>
#include <vector>

namespace cfl {

/// The squared distance between segment [p0, p1] and triangle (a, b, c), with the closest point on each.
/// Exact up to rounding: the least of the endpoint-triangle and segment-edge distances, and of the point
/// where the segment crosses the triangle's plane (0 when it crosses inside). A zero-length segment is a
/// point; a degenerate triangle is the segment or point it is. Pure, allocation-free, thread-safe; any
/// shared frame.
double segmentTriangleSquaredDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                      Eigen::Vector3d* closest_segment = nullptr,
                                      Eigen::Vector3d* closest_triangle = nullptr);

/// Options of a segment query.
struct SegmentQueryOptions {
  /// Negative distances where the segment reaches inside the mesh: the answer is then minus the largest
  /// depth of a point of the segment (see computeSegmentDistance). Requires a closed mesh
  /// (CflModel::sign.closure.closed); otherwise a cfl::Error naming MeshClosure::reason.
  bool signed_distance = false;
  /// Only triangles strictly closer than this are looked for (unsigned length >= 0). A segment farther away
  /// gets distance +infinity and triangle -1. Infinity finds the closest. A signed query uses it only while
  /// the segment is outside.
  double upper_bound = std::numeric_limits<double>::infinity();
  /// Signed queries only: the width of the certified interval on the largest depth (a length > 0); 0 means
  /// 1e-6 of the mesh's bounding-box diagonal.
  double depth_tolerance = 0;
};

/// The answer of a segment query. World frame.
struct SegmentDistance {
  /// Unsigned: the exact distance (0 when the segment touches or crosses the surface). Signed: the same when
  /// no point of the segment is inside; otherwise minus the largest depth found, within
  /// SegmentQueryOptions::depth_tolerance of the true largest depth (the true value lies in
  /// [distance - tolerance, distance]).
  double distance = std::numeric_limits<double>::infinity();
  Eigen::Vector3d segment_point = Eigen::Vector3d::Zero();  ///< The point of the segment attaining `distance`.
  Eigen::Vector3d mesh_point = Eigen::Vector3d::Zero();     ///< Its closest point on the mesh.
  /// Unit direction of increasing (signed) distance at segment_point: from mesh_point towards segment_point
  /// outside, the reverse inside (the outward direction there); on the surface, the triangle's normal.
  /// Zero only on a degenerate triangle.
  Eigen::Vector3d direction = Eigen::Vector3d::Zero();
  int triangle = -1;  ///< The triangle holding mesh_point.
};

/// Distance from the segment [p0_W, p1_W] (world frame; p0 == p1 is a point) to the mesh of `model` at
/// pose X_WM.
///
/// Unsigned: a depth-first, nearer-child-first walk of the mesh's Bvh, nodes bounded by their spheres and boxes,
/// triangles by their planes; exact. Of a triangle, only the pairs that can be closest are measured (a segment
/// end only if the triangle reaches behind it along the segment, a triangle edge only if the segment reaches
/// past its line, and the plane crossing). (The regions' leaf lists at the segment's ends as a first bound cost more
/// than they saved.) The signed query's point queries use the regions.
/// Signed (closed mesh): when the segment neither touches the surface nor starts inside, the unsigned answer.
/// Otherwise a branch and bound over the segment on the signed point distance f, which is 1-Lipschitz: an
/// interval [y0, y1] with closest points q0, q1 cannot hold a point deeper than both
/// (depth(y0) + depth(y1) + |y1 - y0|) / 2 and max over y of min(|y - q0|, |y - q1|) (every point's depth is
/// at most its distance to any surface point); intervals that cannot beat the deepest point found by more
/// than the tolerance are dropped. Cost: O(length / sqrt(depth * tolerance)) point queries in the worst case
/// (a segment parallel to a face at constant depth), a few dozen on a rounded surface.
///
/// Throws cfl::Error for a bad pose, non-finite points, a negative or NaN upper bound, or a signed request
/// on a mesh that is not closed. Thread-safe; the unsigned query is allocation-free.
SegmentDistance computeSegmentDistance(const CflModel& model, const Eigen::Isometry3d& X_WM,
                                       const Eigen::Vector3d& p0_W, const Eigen::Vector3d& p1_W,
                                       const SegmentQueryOptions& options = {});

/// Appends to `found` the triangles of the mesh within `radius` (a length >= 0) of the segment [p0_W, p1_W]
/// (touching counts), each with its unsigned SegmentDistance, nearest-first within Bvh leaves but in no
/// global order, until `max_count` are appended. Returns the number appended. The contacts of a capsule or
/// sphere with the mesh. Throws like computeSegmentDistance. Thread-safe. Cost: a Bvh walk pruned at radius.
std::size_t findTrianglesNearSegment(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d& p0_W,
                                     const Eigen::Vector3d& p1_W, double radius, std::size_t max_count,
                                     std::vector<SegmentDistance>* found);

}  // namespace cfl
