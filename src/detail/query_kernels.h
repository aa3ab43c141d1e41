#pragma once
// The query's builds (see cfl/query_kernels.h): what each one defines, and everything the files that compile
// them include before they include detail/distance_search.inc and detail/triangle_distance_kernels.inc, which
// include nothing themselves.
//
// Each build is its own translation unit: with both copies of the search in one unit, GCC inlined less into
// Search::runHierarchical, and the baseline copy ran more instructions per query.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "cfl/triangle_distance.h"
#include "box_triangle_bound.h"
#include "exact_arithmetic.h"
#include "nearest_triangle.h"

#include <Eigen/Geometry>

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <sstream>
#include <string>
#include <tuple>
#include <vector>

// The bounds' grid lookups (roundToInteger) and the distance kernels' error-free transformations rely on
// IEEE double arithmetic as written; -ffast-math would reassociate them into wrong answers.
#if defined(__FAST_MATH__)
#error "cfl must be compiled without -ffast-math: its exact queries rely on IEEE double rounding"
#endif

// Inlining decisions measured in instructions per query (see each use); other compilers take their own.
#if defined(__GNUC__)
#define CFL_NOINLINE __attribute__((noinline))
#define CFL_ALWAYS_INLINE __attribute__((always_inline))
#else
#define CFL_NOINLINE
#define CFL_ALWAYS_INLINE
#endif

// Whether this library holds the x86-64-v3 build: GCC 12 or later (the target "arch=x86-64-v3" and
// __builtin_cpu_supports("x86-64-v3")) on x86-64, unless the library's own flags already target AVX2.
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 12 && defined(__x86_64__) && !defined(__AVX2__)
#define CFL_X86_64_V3_KERNELS 1
#else
#define CFL_X86_64_V3_KERNELS 0
#endif

namespace cfl::detail {

// One build's entry points, one per public query of cfl_query.h.
struct QueryKernelTable {
  QueryKernels kernels;
  DistanceResult (*distance)(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                             const Eigen::Isometry3d& X_WB, const DistanceOptions& options, const CflModel* b_model);
  DistanceResult (*cached_distance)(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                    const Eigen::Isometry3d& X_WB, DistanceCache& cache,
                                    const DistanceOptions& options);
  DistanceResult (*brute_force)(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                const Eigen::Isometry3d& X_WB);
  bool (*collision)(const MeshModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                    const Eigen::Isometry3d& X_WB, std::size_t max_contacts, std::vector<Contact>* contacts);
};

extern const QueryKernelTable kGenericQueryKernels;  // query_kernels_generic.cpp
#if CFL_X86_64_V3_KERNELS
extern const QueryKernelTable kX86_64_V3QueryKernels;  // query_kernels_x86_64_v3.cpp
#endif

}  // namespace cfl::detail

#if CFL_X86_64_V3_KERNELS
// The x86-64-v3 build's triangle kernels (triangle_distance_x86_64_v3.cpp), which its search calls: the same
// contracts as the public functions of cfl/triangle_distance.h. In a translation unit of their own, as the
// public ones are: in the search's unit they changed how GCC inlined the search itself
// (Search::runHierarchical), for more instructions per query.
namespace cfl::detail::x86_64_v3 {
double pointTriangleSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, Eigen::Vector3d* closest);
double segmentSegmentSquaredDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                                     const Eigen::Vector3d& q1, Eigen::Vector3d* closest_p, Eigen::Vector3d* closest_q);
double triangleTriangleSquaredDistance(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3],
                                       Eigen::Vector3d* closest_p, Eigen::Vector3d* closest_q);
bool trianglesIntersect(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3], Eigen::Vector3d* point);

// pointTriangleSquaredDistance from p to four triangles at once (AVX2, four lanes of doubles): squared[k] and
// closest[k] are bit for bit what pointTriangleSquaredDistance(p, (*triangles[k])[0], [1], [2], &closest[k])
// returns, every operation rounding as the scalar code's does (no fused multiply-add); a sliver, which the
// scalar code treats apart, gets that scalar code. The point query runs its exact tests through it, so that
// a batch of candidates costs about one scalar test.
void pointTriangleSquaredDistances4(const Eigen::Vector3d& p, const std::array<Eigen::Vector3d, 3>* const triangles[4],
                                    double squared[4], Eigen::Vector3d closest[4]);

// The point query's scan of a closest feature list, its bounds four entries at a time and its exact tests
// through pointTriangleSquaredDistances4: the same contract and answer, ties included, as the generic scan
// in point_query.cpp (best_squared, best_triangle and closest are the best so far on entry, the list's best
// strictly below it on exit).
void scanPointList(const Eigen::Vector3d& p, const PointListScan& list, const MeshModel& geometry,
                   double& best_squared, int& best_triangle, Eigen::Vector3d& closest);
// nearestTriangleCompactBounded (detail/nearest_triangle.h) with each leaf's sphere and plane bounds four
// triangles at a time and the exact tests through pointTriangleSquaredDistances4: the same answer.
void nearestTriangleBounded(const MeshModel& model, const Eigen::Vector3d& p, double& best_squared, int& best_triangle,
                            Eigen::Vector3d* closest);
// scanPointList on a list laid out in a PointListCache (blocks laid out as the scan reaches them): the same
// answer.
void scanPointListCached(const Eigen::Vector3d& p, PointListCache& list, const MeshModel& geometry,
                         double& best_squared, int& best_triangle, Eigen::Vector3d& closest);
}  // namespace cfl::detail::x86_64_v3
#endif
