#pragma once
// The query's hot kernels, one table per instruction set (see cfl/query_kernels.h): the triangle kernels,
// the mesh search's list filter and node pair bound, and the point query's scans. The search
// (distance_search.cpp), the point query and the builder are compiled once, for the library's flags, and
// call these through the table that activeQueryKernelTable() returns. Each table lives in a file of its
// own: query_kernels_generic.cpp, and query_kernels_x86_64_v3.cpp with triangle_distance_x86_64_v3.cpp,
// the only code compiled for x86-64-v3.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "cfl/triangle_distance.h"
#include "box_pair_bound.h"
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

/// What the mesh search's list filter reads (QueryKernelTable::filter_list_candidates): A's triangles by id,
/// and one triangle of B placed in A's frame with its bounds, at the search's threshold.
struct ListFilter {
  const Eigen::Vector4d* spheres_a;                 // MeshModel::spheres
  const Eigen::Vector4d* planes_a;                  // MeshModel::planes
  const std::array<Eigen::Vector3d, 3>* corners_a;  // TriangleCorners::in_leaf_order
  const std::int32_t* leaf_position_a;              // TriangleCorners::leaf_position
  const Eigen::Vector3d* corners_b;                 // three
  Eigen::Vector3d center_b;                         // of B's bounding sphere
  double radius_b;
  Eigen::Vector3d normal_b;  // zero for a degenerate triangle
  double offset_b;           // normal_b . corners_b[0]
  Eigen::Vector3d box_min_b, box_max_b;
  double threshold;
};

/// One instruction set's kernels. Every entry returns, bit for bit, what the generic table's returns (no
/// fused multiply-add anywhere: the library builds with -ffp-contract=off, and the intrinsics spell each
/// product and sum); the x86-64-v3 ones run fewer instructions. An entry that is null has no faster version
/// for this instruction set: the caller runs its own scalar code, which is the contract's reference.
struct QueryKernelTable {
  QueryKernels kernels;
  /// cfl::triangleTriangleSquaredDistance.
  double (*triangle_distance)(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3], Eigen::Vector3d* closest_p,
                              Eigen::Vector3d* closest_q);
  /// cfl::trianglesIntersect.
  bool (*triangles_intersect)(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3], Eigen::Vector3d* point);
  /// cfl::pointTriangleSquaredDistance.
  PointTriangle1 point_triangle;
  /// cfl::segmentSegmentSquaredDistance.
  double (*segment_segment)(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                            const Eigen::Vector3d& q1, Eigen::Vector3d* closest_p, Eigen::Vector3d* closest_q);
  /// pointTriangleSquaredDistance from p to four triangles at once: squared[k] and closest[k] are bit for bit
  /// what point_triangle(p, (*triangles[k])[0], [1], [2], &closest[k]) returns (PendingTriangleTests).
  PointTriangles4 point_triangles4;
  /// The first filter of the search's list scan (Search::testTriangleAgainstLists), four candidates of A at
  /// a time: the bounding spheres' gap, B's plane against A's corners, the gap between the two triangles'
  /// axis-aligned boxes and, where three or four candidates pass those, the edge axes (the tests of
  /// Search::mayBeCloser, computed as there, at filter.threshold). Copies the candidates kept among ids[0,
  /// returned) to kept[near] on, in order, and returns how many it examined, a multiple of 4. It only drops
  /// candidates that mayBeCloser would drop, which the search still tests, so the search's answer, pairs and
  /// counters do not depend on it.
  std::size_t (*filter_list_candidates)(const ListFilter& filter, const int* ids, std::size_t count, int* kept,
                                        std::size_t& near);
  /// Whether the projections of triangles a and b (A's frame) on one of the four axes e_a x e_b, from the
  /// two edges at a's corner_a and at b's corner_b, are at least `threshold` apart: the last bound of
  /// Search::mayBeCloser before the exact distance (detail/edge_axes_kernel.inc). Never null; the same answer
  /// in every table.
  bool (*edge_axes_separate)(const Eigen::Vector3d a[3], const Eigen::Vector3d b[3], int corner_a, int corner_b,
                             double threshold);
  /// The point query's scan of a closest feature list (best_squared, best_triangle and closest are the best
  /// so far on entry, the list's best strictly below it on exit): the same answer, ties included, as the
  /// scalar scan in point_query.cpp.
  void (*scan_point_list)(const Eigen::Vector3d& p, const PointListScan& list, const MeshModel& geometry,
                          double& best_squared, int& best_triangle, Eigen::Vector3d& closest);
  /// scan_point_list on a list laid out in a PointListCache (blocks laid out as the scan reaches them).
  void (*scan_point_list_cached)(const Eigen::Vector3d& p, PointListCache& list, const MeshModel& geometry,
                                 double& best_squared, int& best_triangle, Eigen::Vector3d& closest);
  /// nearestTriangleCompactBounded (detail/nearest_triangle.h): the same answer.
  void (*nearest_triangle_bounded)(const MeshModel& model, const Eigen::Vector3d& p, double& best_squared,
                                   int& best_triangle, Eigen::Vector3d* closest);
  /// orientedBoxPairBound (detail/box_pair_bound.h), the oriented boxes' part of the search's bound between
  /// two Bvh nodes: the same answer, bit for bit.
  double (*box_pair_bound)(const Eigen::Matrix3d& axes_a, const Eigen::Vector3d& center_a,
                           const Eigen::Vector3d& half_a, const Eigen::Matrix3d& axes_b,
                           const Eigen::Vector3d& center_b, const Eigen::Vector3d& half_b, double bound,
                           double threshold);
};

extern const QueryKernelTable kGenericQueryKernels;  // query_kernels_generic.cpp
#if CFL_X86_64_V3_KERNELS
extern const QueryKernelTable kX86_64_V3QueryKernels;  // query_kernels_x86_64_v3.cpp
#endif

/// The table of the build that activeQueryKernels() names (cfl_query.cpp): one atomic load. A query reads it
/// once and runs in that build to the end.
const QueryKernelTable& activeQueryKernelTable();

}  // namespace cfl::detail

#if CFL_X86_64_V3_KERNELS
// The x86-64-v3 kernels (triangle_distance_x86_64_v3.cpp and query_kernels_x86_64_v3.cpp), each with the
// contract of its entry in QueryKernelTable.
namespace cfl::detail::x86_64_v3 {
double pointTriangleSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b,
                                    const Eigen::Vector3d& c, Eigen::Vector3d* closest);
double segmentSegmentSquaredDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& q0,
                                     const Eigen::Vector3d& q1, Eigen::Vector3d* closest_p, Eigen::Vector3d* closest_q);
double triangleTriangleSquaredDistance(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3],
                                       Eigen::Vector3d* closest_p, Eigen::Vector3d* closest_q);
bool trianglesIntersect(const Eigen::Vector3d p[3], const Eigen::Vector3d q[3], Eigen::Vector3d* point);
// AVX2, four lanes of doubles, every operation rounding as the scalar code's does; a sliver, which the
// scalar code treats apart, gets that scalar code.
void pointTriangleSquaredDistances4(const Eigen::Vector3d& p, const std::array<Eigen::Vector3d, 3>* const triangles[4],
                                    double squared[4], Eigen::Vector3d closest[4]);
// Bounds four entries at a time, exact tests through pointTriangleSquaredDistances4.
void scanPointList(const Eigen::Vector3d& p, const PointListScan& list, const MeshModel& geometry,
                   double& best_squared, int& best_triangle, Eigen::Vector3d& closest);
void nearestTriangleBounded(const MeshModel& model, const Eigen::Vector3d& p, double& best_squared, int& best_triangle,
                            Eigen::Vector3d* closest);
void scanPointListCached(const Eigen::Vector3d& p, PointListCache& list, const MeshModel& geometry,
                         double& best_squared, int& best_triangle, Eigen::Vector3d& closest);
std::size_t filterListCandidates(const ListFilter& filter, const int* ids, std::size_t count, int* kept,
                                 std::size_t& near);
bool edgeAxesSeparate(const Eigen::Vector3d a[3], const Eigen::Vector3d b[3], int corner_a, int corner_b,
                      double threshold);
// The two boxes' axes as rows of three lanes (one lane per axis), their products broadcast by coordinate.
double orientedBoxPairBound(const Eigen::Matrix3d& axes_a, const Eigen::Vector3d& center_a,
                            const Eigen::Vector3d& half_a, const Eigen::Matrix3d& axes_b,
                            const Eigen::Vector3d& center_b, const Eigen::Vector3d& half_b, double bound,
                            double threshold);
}  // namespace cfl::detail::x86_64_v3
#endif
