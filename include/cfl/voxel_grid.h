#pragma once
/// @file
/// The axis-aligned grid of cubic voxels that carries the discrete Voronoi regions (paper section 3).

#include "cfl/mesh.h"

#include <array>
#include <cstdint>

namespace cfl {

/// A regular grid of dims[0] x dims[1] x dims[2] cubic voxels of edge `voxel_size`, starting at `origin`
/// (its min corner), in the mesh frame M. Voxel (i, j, k) covers
/// origin + voxel_size * [i, i+1] x [j, j+1] x [k, k+1]; its linear index is i + dims[0] * (j + dims[1] * k).
/// Grid corners (voxel vertices) are numbered the same way on a (dims + 1)^3 lattice.
struct VoxelGrid {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  double voxel_size = 0;
  std::array<int, 3> dims{0, 0, 0};

  std::int64_t voxelCount() const { return std::int64_t(dims[0]) * dims[1] * dims[2]; }
  std::int64_t cornerCount() const { return std::int64_t(dims[0] + 1) * (dims[1] + 1) * (dims[2] + 1); }
  std::int64_t voxelIndex(int i, int j, int k) const { return i + std::int64_t(dims[0]) * (j + std::int64_t(dims[1]) * k); }
  std::int64_t cornerIndex(int i, int j, int k) const {
    return i + std::int64_t(dims[0] + 1) * (j + std::int64_t(dims[1] + 1) * k);
  }
  Eigen::Vector3d cornerPosition(int i, int j, int k) const { return origin + voxel_size * Eigen::Vector3d(i, j, k); }
  Eigen::Vector3d voxelCenter(int i, int j, int k) const {
    return origin + voxel_size * Eigen::Vector3d(i + 0.5, j + 0.5, k + 0.5);
  }
  Aabb voxelBox(int i, int j, int k) const {
    Aabb box;
    box.min = cornerPosition(i, j, k);
    box.max = box.min + Eigen::Vector3d::Constant(voxel_size);
    return box;
  }
  /// The whole grid's box.
  Aabb bounds() const {
    Aabb box;
    box.min = origin;
    box.max = origin + voxel_size * Eigen::Vector3d(dims[0], dims[1], dims[2]);
    return box;
  }
};

/// The grid covering `mesh_bounds` scaled by `padding` about its center, with `resolution` voxels along the
/// longest axis and as many as needed (at least one) along the others. Throws cfl::Error for resolution < 1,
/// padding < 1 or non-finite bounds. A flat or point-like mesh gets a grid of edge max(extent, tiny).
VoxelGrid makeVoxelGrid(const Aabb& mesh_bounds, int resolution, double padding);

}  // namespace cfl
