#pragma once
/// @file
/// Inside and outside of a mesh: whether it bounds a solid (it is closed), and the data that gives a point's
/// distance a sign (angle-weighted pseudonormals, Baerentzen & Aanaes 2005) or a winding number (Jacobson et
/// al. 2013) where it is not closed.

#include "cfl/mesh_model.h"

#include <array>
#include <cstdint>
#include <memory>
#include <mutex>
#include <string>
#include <vector>

namespace cfl {

/// How the sign of a point's distance is decided.
enum class SignMethod {
  /// Pseudonormals on a closed mesh (exact: the sign of (p - q) . n at the closest point q, n the
  /// angle-weighted pseudonormal of the feature holding q); a cfl::Error naming MeshClosure::reason on a mesh
  /// that is not closed. The default: never a silently wrong sign.
  kAuto,
  /// The generalized winding number w(p) (inside when w >= 1/2), on any mesh: robust on nearly closed meshes
  /// (small holes, cracks, duplicated or flipped pieces), where no exact answer exists. Exact summation close
  /// to p, a second-order far-field expansion of Bvh nodes farther than kWindingFarFactor node radii
  /// (Barill et al. 2018), whose error per node is of order (radius / distance)^2 times the solid angle the
  /// node subtends (area / distance^2). These add up over the nodes and levels of the tree to a small
  /// fraction of the 1/2 between inside and outside on ordinary meshes; tests hold it under 0.05 of w on
  /// spheres, knots, the bunny and open meshes. Points near a large hole get w near 1/2 and either sign.
  /// The sign follows MeshClosure::orientation, so an inside-out mesh is signed like an outward one.
  kWindingNumber,
};

/// Why a mesh does or does not bound a solid. Computed once per model (buildCflModel, loadCflModel).
struct MeshClosure {
  /// True when every edge (vertices welded by exact position, so triangle soups count as connected) has
  /// exactly two triangles that traverse it in opposite directions, no triangle is degenerate, and no two
  /// triangles without a common vertex intersect. Points then have a well-defined inside.
  bool closed = false;
  std::int64_t boundary_edges = 0;       ///< Edges with one triangle.
  std::int64_t nonmanifold_edges = 0;    ///< Edges with three or more triangles.
  std::int64_t inconsistent_edges = 0;   ///< Edges whose two triangles traverse it in the same direction.
  /// Zero area: collinear or repeated corners (the normal, computed in twice the working precision, is zero).
  std::int64_t degenerate_triangles = 0;
  /// Pairs of triangles without a common vertex that intersect (counted up to 1000).
  std::int64_t intersecting_pairs = 0;
  /// +1 when the triangles wind counterclockwise seen from outside (positive enclosed volume), -1 when the mesh
  /// is inside out; signs account for it, so an inside-out closed mesh is still signed correctly.
  int orientation = 1;
  /// Empty when closed; otherwise the first reason, naming an example, e.g. "open: 12 boundary edges (the
  /// first between vertices 3 and 7 of triangle 5)".
  std::string reason;
};

/// The far field of the triangles below one Bvh node, for the winding number (Barill et al. 2018): seen from
/// a point p farther than kWindingFarFactor * radius from `center`, their solid angle is expanded to second
/// order about `center`. Frame M.
struct WindingDipole {
  Eigen::Vector3d center = Eigen::Vector3d::Zero();      ///< Area-weighted centroid of the triangles.
  /// Sum of the triangles' area vectors (area times unit normal).
  Eigen::Vector3d area_normal = Eigen::Vector3d::Zero();
  /// Sum over the triangles of area vector * (centroid - center)^T: the second-order term.
  Eigen::Matrix3d moment = Eigen::Matrix3d::Zero();
  double radius = 0;  ///< Every vertex below the node lies within this of `center`.
};

/// A Bvh node is summed by its WindingDipole when the point is farther than this many radii from its center.
/// Barill et al. use 2; errors add up over the levels of the tree, and 3 keeps their sum a small fraction
/// of the 1/2 that separates inside from outside on the test meshes, for a few more exact triangles.
constexpr double kWindingFarFactor = 3.0;

/// The winding number's far field: node n of the model's Bvh is summed by node_dipoles[dipole_index[n]].
/// Leaves have none (dipole_index -1): one triangle's exact solid angle costs about what its expansion would.
struct WindingField {
  std::vector<WindingDipole> node_dipoles;
  std::vector<std::int32_t> dipole_index;
};

/// Where a MeshSign keeps its WindingField once built (see windingField).
struct WindingFieldCache {
  std::once_flag once;
  WindingField field;
};

/// What signing needs beyond the MeshModel, in frame M. About 36 bytes per triangle, and about 136 more once
/// a winding number has been asked for.
struct MeshSign {
  MeshClosure closure;
  /// welded_vertex[v]: the representative of mesh vertex v among vertices at the same position.
  std::vector<std::int32_t> welded_vertex;
  /// Per triangle, per edge e (corners e and e+1 mod 3): the triangle across it (whether or not the two agree
  /// in orientation), -1 on a boundary or non-manifold edge. The edge pseudonormal is the sum of the two unit
  /// face normals.
  std::vector<std::array<std::int32_t, 3>> neighbors;
  /// Angle-weighted pseudonormal of each welded vertex (indexed by welded_vertex[v]; unit, oriented outward
  /// using closure.orientation; zero where not defined).
  std::vector<Eigen::Vector3d> vertex_normals;
  /// The winding number's far field, built by windingField on first use (SignMethod::kWindingNumber), so
  /// that models never signed by winding number do not carry it. Copies of a model share it; null in a
  /// MeshSign not made by analyzeMeshSign.
  std::shared_ptr<WindingFieldCache> winding;
};

/// The far field of `sign` for `model` (the model it was analysed with), built on the first call (O(n),
/// thread-safe: concurrent first calls build it once) and reused after. Empty when sign.winding is null.
const WindingField& windingField(const MeshModel& model, const MeshSign& sign);

/// Bytes the arrays of `sign` hold (capacity).
std::int64_t memoryBytes(const MeshSign& sign);

/// Analyses `model`'s mesh: welding, edges, orientation, degenerate triangles, self-intersections (through
/// its Bvh), pseudonormals (the winding number's far field comes later, on demand). O(n log n) on one
/// thread; deterministic. Never throws for a valid MeshModel: a mesh that cannot be signed gets closed ==
/// false and a reason.
MeshSign analyzeMeshSign(const MeshModel& model);

/// The generalized winding number of the mesh around p (frame M): 1 inside a closed outward mesh (-1 inside an
/// inside-out one: multiply by MeshClosure::orientation), 0 outside, fractional near holes. Uses
/// `model.bvh` and windingField(model, sign) for the far field (see SignMethod::kWindingNumber); 0 when `sign` was
/// not computed for `model`. Thread-safe, allocation-free; O(log n) nodes far from the mesh, more near it.
double windingNumber(const MeshModel& model, const MeshSign& sign, const Eigen::Vector3d& p_M);

}  // namespace cfl
