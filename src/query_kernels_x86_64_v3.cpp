// The query's x86-64-v3 build: the search compiled for AVX2, BMI2 and the VEX encodings (see
// cfl/query_kernels.h; chosen at run time in cfl_query.cpp). Its triangle kernels are in
// triangle_distance_x86_64_v3.cpp.
//
// Everything the search calls from a header (Eigen, the standard library, cfl's own headers) is declared in
// detail/query_kernels.h, included before the target pragma: GCC compiles a function for the target in force
// where it is declared, so the header functions this copy does not inline stay baseline code, and the linker,
// which keeps one copy of each such function for the whole program, never picks one that needs AVX2 (objdump
// finds no VEX instruction in this object's weak functions). Only what the include below defines, in its own
// namespace, is compiled for x86-64-v3; and Eigen, configured before the pragma, keeps its 16-byte alignment
// (that of FCL's and the caller's Isometry3d).
//
// Fused multiply-adds would save instructions again, but the results would differ from the baseline's in
// the last bits, so from one machine to another, and the triangle kernels' exact arithmetic
// (detail/exact_arithmetic.h) needs products rounded as written: the library builds with -ffp-contract=off.

#include "detail/query_kernels.h"

#if CFL_X86_64_V3_KERNELS
// The list filter's AVX2 intrinsics (see distance_search.inc), before the pragma as every other include.
#include <immintrin.h>

#pragma GCC push_options
#pragma GCC target("arch=x86-64-v3")

namespace cfl::detail {
namespace x86_64_v3 {
namespace {
// Inside x86_64_v3, the search's calls to the triangle kernels find this build's (detail/query_kernels.h).
// GCC's target pragma does not define __AVX2__: the search learns of it from this macro.
#define CFL_SEARCH_AVX2 1
#include "detail/distance_search.inc"
#undef CFL_SEARCH_AVX2
}  // namespace
}  // namespace x86_64_v3

const QueryKernelTable kX86_64_V3QueryKernels{QueryKernels::kX86_64_V3, &x86_64_v3::distanceImpl,
                                              &x86_64_v3::cachedDistanceImpl, &x86_64_v3::bruteForceImpl,
                                              &x86_64_v3::collisionImpl};

}  // namespace cfl::detail

#pragma GCC pop_options

#endif  // CFL_X86_64_V3_KERNELS
