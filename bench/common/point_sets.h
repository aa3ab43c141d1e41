#pragma once
/// @file
/// The point sets the point-query benchmarks use (`cfl bench --points`, cfl_point_bench), so that their
/// figures describe the same queries.

#include "cfl/mesh.h"

#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace cfl::bench {

/// `count` points near the surface: a surface point drawn uniformly by area, moved in a uniformly random
/// direction by a length uniform in [0, reach]. Mesh frame. Deterministic for a given seed. Throws
/// cfl::Error when the mesh has no triangle of positive area.
std::vector<Eigen::Vector3d> nearSurfacePoints(const TriangleMesh& mesh, std::size_t count, double reach,
                                               std::uint64_t seed);

/// `count` points uniform in `box` grown to twice its size about its center. Deterministic for a given seed.
std::vector<Eigen::Vector3d> boxPoints(const Aabb& box, std::size_t count, std::uint64_t seed);

}  // namespace cfl::bench
