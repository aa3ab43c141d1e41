// The generic kernel table: the public triangle kernels (triangle_distance.cpp) and the search's edge-axes
// filter (detail/edge_axes_kernel.inc), compiled with the library's flags. Its other entries are null: the
// search, the point query and the builder then run their own scalar code, which each x86-64-v3 kernel
// matches bit for bit (see detail/query_kernels.h).

#include "detail/query_kernels.h"

namespace cfl::detail {
namespace generic {
#include "detail/edge_axes_kernel.inc"
}  // namespace generic

const QueryKernelTable kGenericQueryKernels{QueryKernels::kGeneric,
                                            &cfl::triangleTriangleSquaredDistance,
                                            &cfl::trianglesIntersect,
                                            &cfl::pointTriangleSquaredDistance,
                                            &cfl::segmentSegmentSquaredDistance,
                                            /*point_triangles4=*/nullptr,
                                            /*filter_list_candidates=*/nullptr,
                                            &generic::edgeAxesSeparate,
                                            /*scan_point_list=*/nullptr,
                                            /*scan_point_list_cached=*/nullptr,
                                            /*nearest_triangle_bounded=*/nullptr,
                                            /*box_pair_bound=*/nullptr};

}  // namespace cfl::detail
