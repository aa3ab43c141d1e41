// The query's baseline build: the search compiled with the library's flags. The triangle kernels it runs are
// the public ones (triangle_distance.cpp), built with the same flags.

#include "detail/query_kernels.h"

namespace cfl::detail {
namespace {
#include "detail/distance_search.inc"
}  // namespace

const QueryKernelTable kGenericQueryKernels{QueryKernels::kGeneric, &distanceImpl, &cachedDistanceImpl,
                                            &bruteForceImpl, &collisionImpl};

}  // namespace cfl::detail
