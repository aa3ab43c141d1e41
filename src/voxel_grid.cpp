#include "cfl/voxel_grid.h"

#include "cfl/error.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace cfl {

VoxelGrid makeVoxelGrid(const Aabb& mesh_bounds, int resolution, double padding) {
  if (resolution < 1) {
    throw Error("grid resolution must be at least 1 voxel along the longest axis, got " + std::to_string(resolution));
  }
  if (!std::isfinite(padding) || padding < 1.0) {
    std::ostringstream message;
    message << "grid padding must be a finite factor >= 1, got " << padding;
    throw Error(message.str());
  }
  if (mesh_bounds.empty() || !mesh_bounds.min.allFinite() || !mesh_bounds.max.allFinite()) {
    throw Error("grid bounds are empty or not finite");
  }
  const Eigen::Vector3d extent = mesh_bounds.size() * padding;
  double longest = extent.maxCoeff();
  // A flat or point-like mesh still needs voxels of positive size; scale the floor with the coordinates so
  // that a mesh far from the origin keeps representable voxel corners.
  const double floor = 1e-9 * std::max(1.0, mesh_bounds.max.cwiseAbs().cwiseMax(mesh_bounds.min.cwiseAbs()).maxCoeff());
  longest = std::max(longest, floor);
  VoxelGrid grid;
  grid.voxel_size = longest / resolution;
  for (int axis = 0; axis < 3; ++axis) {
    // Round up so the grid never covers less than the padded box; a small slack avoids an extra layer
    // caused by rounding alone.
    const double cells = extent[axis] / grid.voxel_size;
    grid.dims[axis] = std::max(1, static_cast<int>(std::ceil(cells - 1e-9)));
  }
  const Eigen::Vector3d covered = grid.voxel_size * Eigen::Vector3d(grid.dims[0], grid.dims[1], grid.dims[2]);
  grid.origin = mesh_bounds.center() - 0.5 * covered;
  return grid;
}

}  // namespace cfl
