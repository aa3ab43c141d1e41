// The triangle kernels of the query's x86-64-v3 build (see query_kernels_x86_64_v3.cpp for why the target
// pragma comes after every include, and detail/query_kernels.h for why these have a file of their own).

#include "detail/query_kernels.h"

#if CFL_X86_64_V3_KERNELS

#pragma GCC push_options
#pragma GCC target("arch=x86-64-v3")

namespace cfl::detail::x86_64_v3 {
#include "detail/triangle_distance_kernels.inc"
}  // namespace cfl::detail::x86_64_v3

#pragma GCC pop_options

#endif  // CFL_X86_64_V3_KERNELS
