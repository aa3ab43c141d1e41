#pragma once
/// @file
/// Internal: buildBvh with its parallel grain exposed, so that tests can compare the parallel build with the
/// one-thread build of the same mesh.

#include "cfl/bvh.h"

namespace cfl::detail {

/// buildBvh(mesh, max_leaf_size), with ranges of at least `parallel_grain` triangles building their two
/// halves in parallel (on the calling thread's TBB arena); any grain above the triangle count builds on the
/// calling thread alone. The result does not depend on the grain or the schedule.
Bvh buildBvhWithGrain(const TriangleMesh& mesh, int max_leaf_size, int parallel_grain);

}  // namespace cfl::detail
