#pragma once
/// @file
/// The input of the library: a triangle soup.

#include <Eigen/Core>

#include <array>
#include <cstdint>
#include <limits>
#include <vector>

namespace cfl {

/// An axis-aligned box. An empty box has min > max on every axis.
struct Aabb {
  Eigen::Vector3d min = Eigen::Vector3d::Constant(std::numeric_limits<double>::infinity());
  Eigen::Vector3d max = Eigen::Vector3d::Constant(-std::numeric_limits<double>::infinity());

  void extend(const Eigen::Vector3d& p) {
    min = min.cwiseMin(p);
    max = max.cwiseMax(p);
  }
  void extend(const Aabb& box) {
    min = min.cwiseMin(box.min);
    max = max.cwiseMax(box.max);
  }
  bool empty() const { return !(min.array() <= max.array()).all(); }
  Eigen::Vector3d center() const { return 0.5 * (min + max); }
  Eigen::Vector3d size() const { return max - min; }
  double diagonal() const { return empty() ? 0.0 : (max - min).norm(); }
};

/// A triangle soup in the mesh's own frame M and its own length unit.
///
/// No topology is required: triangles may be open, non-manifold, duplicated, intersecting or degenerate
/// (zero area, collinear, repeated vertices). Triangles are two-sided, so every distance is >= 0.
/// Triangle ids used throughout the library are indices into `triangles`.
struct TriangleMesh {
  std::vector<Eigen::Vector3d> vertices;     ///< p_MV for each vertex V.
  std::vector<std::array<int, 3>> triangles;  ///< Three indices into `vertices` per triangle.
};

/// The largest vertex coordinate magnitude validateMesh accepts. The distance kernels take products of up
/// to four coordinate differences (a triangle normal's squared length); beyond this they could overflow
/// the double range, which reaches 1.8e308. At the other end the same products underflow for triangles
/// with edges under about 1e-75 units, which are then measured as their edges (off by up to their size):
/// no physical unit comes near either end (tests cover meshes scaled by 1e-6 to 1e6).
constexpr double kMaxCoordinate = 1e50;

/// The smallest nonzero bounding-box diagonal validateMesh accepts. Below it the same products underflow
/// for the whole mesh, not for a few tiny triangles in it, and answers would be off by a large fraction of
/// its size. A mesh whose vertices all coincide (diagonal 0) is accepted: it is a point.
constexpr double kMinDiagonal = 1e-50;

/// Checks that `mesh` can be used: at least one triangle, every vertex coordinate finite and at most
/// kMaxCoordinate in magnitude, every index in [0, vertices.size()), the bounding box of the vertices the
/// triangles use 0 or at least kMinDiagonal across. Throws cfl::Error naming the first
/// defect, e.g. "triangle 12: vertex index 900 is out of range [0, 512)" or "vertex 3 has a non-finite
/// coordinate (nan, 0, 1)". Degenerate and duplicate triangles are accepted: they are valid geometry (a
/// segment or a point). O(vertices + triangles).
void validateMesh(const TriangleMesh& mesh);

/// The bounding box of the vertices that triangles use, in the mesh frame. O(triangles).
Aabb boundingBox(const TriangleMesh& mesh);

}  // namespace cfl
