#pragma once
/// @file
/// Distance from a solid box to a CflModel's mesh: the core of fcl::Box queries.

#include "cfl/cfl_model.h"

#include <Eigen/Geometry>

#include <limits>

namespace cfl {

/// The answer of a box query. World frame.
struct BoxDistance {
  /// The exact distance between the solid box and the mesh's triangles: 0 when a triangle touches or enters
  /// the box (also one wholly inside it); +infinity when none is closer than the upper bound.
  double distance = std::numeric_limits<double>::infinity();
  Eigen::Vector3d box_point = Eigen::Vector3d::Zero();   ///< On the box (its surface when apart).
  Eigen::Vector3d mesh_point = Eigen::Vector3d::Zero();  ///< On triangle `triangle`.
  int triangle = -1;
};

/// Distance between the box of half extents `half` (> 0), centered at the origin of its frame B and aligned
/// with its axes, at pose X_WB, and the mesh of `model` at X_WM. Only triangles strictly closer than
/// `upper_bound` (a length >= 0) are looked for.
///
/// Exact: a best-first walk of the mesh's Bvh, nodes bounded by their spheres against the box, triangles by
/// their spheres, their bounding boxes in the box's frame, their planes against the box's support and their
/// corners along the line from the box to their sphere's center, then
/// by the separating-axis gap (box axes, triangle normal, the nine axis-edge cross products), which is <= 0
/// exactly when the triangle meets the box. Apart, a triangle's distance is the least over the features a
/// closest pair can have (a triangle corner against the box, a box corner against the triangle, a box edge
/// against a triangle edge), each tried only where the other shape reaches into its normal cone; meeting it,
/// 0, with a common point (a corner inside, an edge of the box crossing it, or an edge of it crossing the
/// box). Throws cfl::Error for bad poses, non-positive or non-finite half extents,
/// or a negative bound. Thread-safe, allocation-free.
BoxDistance computeBoxDistance(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Isometry3d& X_WB,
                               const Eigen::Vector3d& half,
                               double upper_bound = std::numeric_limits<double>::infinity());

}  // namespace cfl
