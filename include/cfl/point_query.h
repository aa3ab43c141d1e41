#pragma once
/// @file
/// Distance from points to a CflModel's mesh, unsigned or signed: an exact distance field, not a sampled
/// one. The point's leaf of the regions names the few triangles that can be closest.

#include "cfl/cfl_model.h"
#include "cfl/mesh_sign.h"

#include <Eigen/Geometry>

#include <cstddef>
#include <limits>

namespace cfl {

/// Options of a point query.
struct PointQueryOptions {
  /// Negative distances inside the mesh. Requires a mesh that can be signed by `sign_method`: with kAuto, a
  /// mesh that is not closed gets a cfl::Error naming MeshClosure::reason.
  bool signed_distance = false;
  SignMethod sign_method = SignMethod::kAuto;
  /// Only triangles strictly closer than this are looked for (unsigned length >= 0, in the mesh's units; a
  /// negative or NaN bound is a cfl::Error): a point farther gets distance +infinity (or -infinity when signed
  /// and inside), triangle -1, zero closest point and gradient. Infinity finds the closest. A signed query
  /// beyond the bound still decides the side: with kAuto by an unbounded search for the closest feature, so
  /// the bound saves less there; with kWindingNumber by the winding number.
  double upper_bound = std::numeric_limits<double>::infinity();
  /// Worker threads of the batch form (0: every hardware thread); results do not depend on it.
  int threads = 0;
};

/// The answer for one point.
struct PointDistance {
  /// The exact distance to the mesh (up to rounding); when signed, negative inside.
  double distance = std::numeric_limits<double>::infinity();
  Eigen::Vector3d closest_point = Eigen::Vector3d::Zero();  ///< On the mesh, world frame.
  /// The gradient of the (signed) distance at the point, world frame, unit: (p - closest) / |p - closest|,
  /// times -1 inside when signed. On the surface (distance 0): the outward pseudonormal of the feature
  /// holding the point when the mesh is closed and the query signed, else the triangle's unit normal oriented
  /// by MeshClosure::orientation; zero only on a degenerate triangle.
  Eigen::Vector3d gradient = Eigen::Vector3d::Zero();
  int triangle = -1;  ///< The triangle holding closest_point.
};

/// Distance from p_W (world frame) to the mesh of `model` at pose X_WM. Throws cfl::Error for a bad pose or
/// a non-finite point, and for a signed request the mesh cannot honour (see PointQueryOptions). Thread-safe,
/// allocation-free. Cost: one leaf lookup and a scan of its list (a few triangles) near the mesh; a Bvh walk
/// where the leaf stores no list or p lies outside the regions; with SignMethod::kWindingNumber, a winding
/// number on top (O(log n) nodes far from the mesh, more close to it).
///
/// Signs with kAuto are exact on a closed mesh (MeshClosure::closed) up to rounding: the closest feature
/// (face, edge or vertex of the closest triangle, by the Voronoi regions of the triangle) and its
/// angle-weighted pseudonormal decide (Baerentzen & Aanaes 2005). Points within rounding of the surface
/// (distance of order 1e-15 of the mesh's coordinates) may get either sign. Ties between triangles at the
/// same distance are broken deterministically (list or Bvh order).
PointDistance computePointDistance(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d& p_W,
                                   const PointQueryOptions& options = {});

/// results[i] = computePointDistance(model, X_WM, points_W[i], options) for i in [0, count), on
/// options.threads threads (oneTBB), bit-identical to the serial calls. Every point is checked first; a bad
/// one throws cfl::Error naming its index and leaves `results` untouched. The points are queried in spatial
/// (Morton) order rather than the caller's, so that neighbouring queries share cached leaves and triangles:
/// a batch of 256 points or more allocates that order once (20 bytes per point while it is sorted, 4 while
/// the queries run), in O(count) time; the results still go to the caller's indices.
void computePointDistances(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d* points_W,
                           std::size_t count, PointDistance* results, const PointQueryOptions& options = {});

}  // namespace cfl
