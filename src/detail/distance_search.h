#pragma once
// The mesh-mesh search (distance_search.cpp): one entry point per public query of cfl/cfl_query.h, each
// running the hot kernels of `kernels` (the table cfl_query.cpp picks, see detail/query_kernels.h).

#include "cfl/cfl_query.h"

#include <Eigen/Geometry>

#include <cstddef>
#include <vector>

namespace cfl::detail {

struct QueryKernelTable;

/// computeDistance; `b_model`: B's own CflModel when it has one (the paper's mode uses B's regions too).
DistanceResult distanceImpl(const QueryKernelTable& kernels, const CflModel& a, const Eigen::Isometry3d& X_WA,
                            const MeshModel& b, const Eigen::Isometry3d& X_WB, const DistanceOptions& options,
                            const CflModel* b_model);
/// computeDistance with a DistanceCache.
DistanceResult cachedDistanceImpl(const QueryKernelTable& kernels, const CflModel& a, const Eigen::Isometry3d& X_WA,
                                  const MeshModel& b, const Eigen::Isometry3d& X_WB, DistanceCache& cache,
                                  const DistanceOptions& options);
/// bruteForceDistance.
DistanceResult bruteForceImpl(const QueryKernelTable& kernels, const MeshModel& a, const Eigen::Isometry3d& X_WA,
                              const MeshModel& b, const Eigen::Isometry3d& X_WB);
/// computeCollision.
bool collisionImpl(const QueryKernelTable& kernels, const MeshModel& a, const Eigen::Isometry3d& X_WA,
                   const MeshModel& b, const Eigen::Isometry3d& X_WB, std::size_t max_contacts,
                   std::vector<Contact>* contacts);

}  // namespace cfl::detail
