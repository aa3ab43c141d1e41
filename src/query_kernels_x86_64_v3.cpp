// The x86-64-v3 kernel table (see cfl/query_kernels.h; chosen at run time in cfl_query.cpp) and the mesh
// search's list filter and node pair bound for it. The triangle kernels and the point query's scans of this
// table are in triangle_distance_x86_64_v3.cpp.
//
// Every header is included before the target pragma: GCC compiles a function for the target in force where
// it is declared, so the header functions this file does not inline stay baseline code, and the linker,
// which keeps one copy of each such function for the whole program, never picks one that needs AVX2. Only
// what this file defines is compiled for x86-64-v3; and Eigen, configured before the pragma, keeps its
// 16-byte alignment (that of the caller's Isometry3d).
//
// Fused multiply-adds would save instructions, but the results would differ from the baseline's in the last
// bits, so from one machine to another, and the triangle kernels' exact arithmetic
// (detail/exact_arithmetic.h) needs products rounded as written: the library builds with -ffp-contract=off.

#include "detail/query_kernels.h"

#if CFL_X86_64_V3_KERNELS
#include <immintrin.h>

#pragma GCC push_options
#pragma GCC target("arch=x86-64-v3")

namespace cfl::detail {
namespace x86_64_v3 {
namespace {

// planeOffset (distance_search.cpp) for four points, coordinates point[0..2], against four planes or one.
__m256d planeOffsets(const __m256d normal[3], __m256d offset, const __m256d point[3]) {
  return _mm256_sub_pd(
      _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(normal[0], point[0]), _mm256_mul_pd(normal[1], point[1])),
                    _mm256_mul_pd(normal[2], point[2])),
      offset);
}
__m256d dot3(const __m256d u[3], const __m256d v[3]) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(u[0], v[0]), _mm256_mul_pd(u[1], v[1])),
                       _mm256_mul_pd(u[2], v[2]));
}
// The corners of four triangles (corner[3 i + j]: coordinate j of corner i), rotated per lane so that the
// corner nearestToPlane picks by its plane offsets comes first: origin, next, previous. Inlined: out of line,
// its arrays of lanes went through memory.
CFL_ALWAYS_INLINE inline void rotateToNearest(const __m256d corner[9], const __m256d offsets[3], __m256d origin[3],
                                                __m256d next[3], __m256d previous[3]) {
  const __m256d sign = _mm256_set1_pd(-0.0);
  const __m256d a0 = _mm256_andnot_pd(sign, offsets[0]), a1 = _mm256_andnot_pd(sign, offsets[1]),
                a2 = _mm256_andnot_pd(sign, offsets[2]);
  // nearestToPlane: a0 <= a1 ? (a0 <= a2 ? 0 : 2) : (a1 <= a2 ? 1 : 2).
  const __m256d first_le_second = _mm256_cmp_pd(a0, a1, _CMP_LE_OQ);
  const __m256d is0 = _mm256_and_pd(first_le_second, _mm256_cmp_pd(a0, a2, _CMP_LE_OQ));
  const __m256d is1 = _mm256_andnot_pd(first_le_second, _mm256_cmp_pd(a1, a2, _CMP_LE_OQ));
  const __m256d is2 = _mm256_andnot_pd(_mm256_or_pd(is0, is1), _mm256_castsi256_pd(_mm256_set1_epi64x(-1)));
  for (int j = 0; j < 3; ++j) {
    const __m256d c0 = corner[j], c1 = corner[3 + j], c2 = corner[6 + j];
    origin[j] = _mm256_blendv_pd(_mm256_blendv_pd(c0, c1, is1), c2, is2);
    next[j] = _mm256_blendv_pd(_mm256_blendv_pd(c1, c2, is1), c0, is2);
    previous[j] = _mm256_blendv_pd(_mm256_blendv_pd(c2, c0, is1), c1, is2);
  }
}
// edgeAxesSeparate (detail/edge_axes_kernel.inc) four pairs at a time, the same operations in the same order
// (std::min(x, y) is _mm256_min_pd(y, x), NaNs included), at `limit`: all lanes set where the axes separate the pair.
// `corner_a`: A's four triangles' corners, `side`: their offsets from B's plane; `corner_b`: B's corners
// (the same in every lane), `others`: their offsets from each of A's planes.
__m256d edgeAxesSeparateByFour(const __m256d corner_a[9], const __m256d side[3], const __m256d corner_b[9],
                               const __m256d others[3], __m256d limit) {
  __m256d origin_a[3], next_a[3], previous_a[3], origin_b[3], next_b[3], previous_b[3];
  rotateToNearest(corner_a, side, origin_a, next_a, previous_a);
  rotateToNearest(corner_b, others, origin_b, next_b, previous_b);
  __m256d edges_a[2][3], edges_b[2][3], offset[3];
  for (int j = 0; j < 3; ++j) {
    edges_a[0][j] = _mm256_sub_pd(next_a[j], origin_a[j]);
    edges_a[1][j] = _mm256_sub_pd(previous_a[j], origin_a[j]);
    edges_b[0][j] = _mm256_sub_pd(next_b[j], origin_b[j]);
    edges_b[1][j] = _mm256_sub_pd(previous_b[j], origin_b[j]);
    offset[j] = _mm256_sub_pd(origin_b[j], origin_a[j]);
  }
  const __m256d zero = _mm256_setzero_pd();
  const __m256d limit_squared = _mm256_mul_pd(limit, limit);
  __m256d separated = zero;
  for (const auto& edge_b : edges_b) {
    for (const auto& edge_a : edges_a) {
      const __m256d axis[3] = {
          _mm256_sub_pd(_mm256_mul_pd(edge_a[1], edge_b[2]), _mm256_mul_pd(edge_a[2], edge_b[1])),
          _mm256_sub_pd(_mm256_mul_pd(edge_a[2], edge_b[0]), _mm256_mul_pd(edge_a[0], edge_b[2])),
          _mm256_sub_pd(_mm256_mul_pd(edge_a[0], edge_b[1]), _mm256_mul_pd(edge_a[1], edge_b[0]))};
      const __m256d a1 = dot3(edges_a[0], axis), a2 = dot3(edges_a[1], axis);
      const __m256d b0 = dot3(offset, axis);
      const __m256d b1 = _mm256_add_pd(b0, dot3(edges_b[0], axis)), b2 = _mm256_add_pd(b0, dot3(edges_b[1], axis));
      const __m256d low_a = _mm256_min_pd(_mm256_min_pd(a2, a1), zero);
      const __m256d high_a = _mm256_max_pd(_mm256_max_pd(a2, a1), zero);
      const __m256d low_b = _mm256_min_pd(_mm256_min_pd(b2, b1), b0);
      const __m256d high_b = _mm256_max_pd(_mm256_max_pd(b2, b1), b0);
      const __m256d gap = _mm256_max_pd(_mm256_sub_pd(low_a, high_b), _mm256_sub_pd(low_b, high_a));
      const __m256d apart = _mm256_and_pd(
          _mm256_cmp_pd(gap, zero, _CMP_GT_OQ),
          _mm256_cmp_pd(_mm256_mul_pd(gap, gap), _mm256_mul_pd(limit_squared, dot3(axis, axis)), _CMP_GE_OQ));
      separated = _mm256_or_pd(separated, apart);
    }
  }
  return separated;
}

// Rows of four doubles, one per candidate, into columns, one per value.
inline void transpose(const __m256d r[4], __m256d* column) {
  const __m256d t0 = _mm256_unpacklo_pd(r[0], r[1]), t1 = _mm256_unpackhi_pd(r[0], r[1]);
  const __m256d t2 = _mm256_unpacklo_pd(r[2], r[3]), t3 = _mm256_unpackhi_pd(r[2], r[3]);
  column[0] = _mm256_permute2f128_pd(t0, t2, 0x20);
  column[1] = _mm256_permute2f128_pd(t1, t3, 0x20);
  column[2] = _mm256_permute2f128_pd(t0, t2, 0x31);
  column[3] = _mm256_permute2f128_pd(t1, t3, 0x31);
}

}  // namespace

// On a flat plate the lists are long and the spheres pass most of their entries, and B's plane and the
// boxes, one candidate at a time behind them, cost more than the spheres: four at a time they cost less.
std::size_t filterListCandidates(const ListFilter& filter, const int* ids, std::size_t count, int* kept,
                                 std::size_t& near) {
  constexpr double kInfinity = std::numeric_limits<double>::infinity();
  const Eigen::Vector4d* spheres = filter.spheres_a;
  const std::array<Eigen::Vector3d, 3>* corners = filter.corners_a;
  const std::int32_t* leaf_position = filter.leaf_position_a;
  const __m256d limit = _mm256_set1_pd(filter.threshold);
  const __m256d radius_b = _mm256_set1_pd(filter.radius_b);
  const __m256d center[3] = {_mm256_set1_pd(filter.center_b[0]), _mm256_set1_pd(filter.center_b[1]),
                             _mm256_set1_pd(filter.center_b[2])};
  const __m256d normal[3] = {_mm256_set1_pd(filter.normal_b[0]), _mm256_set1_pd(filter.normal_b[1]),
                             _mm256_set1_pd(filter.normal_b[2])};
  const __m256d offset = _mm256_set1_pd(filter.offset_b);
  const __m256d box_min_b[3] = {_mm256_set1_pd(filter.box_min_b[0]), _mm256_set1_pd(filter.box_min_b[1]),
                                _mm256_set1_pd(filter.box_min_b[2])};
  const __m256d box_max_b[3] = {_mm256_set1_pd(filter.box_max_b[0]), _mm256_set1_pd(filter.box_max_b[1]),
                                _mm256_set1_pd(filter.box_max_b[2])};
  const __m256d sign = _mm256_set1_pd(-0.0);
  const Eigen::Vector4d* planes = filter.planes_a;
  __m256d corner_b[9];
  for (int k = 0; k < 9; ++k) corner_b[k] = _mm256_set1_pd(filter.corners_b[k / 3][k % 3]);
  std::size_t n = 0;
  for (; n + 4 <= count; n += 4) {
    const int* t = ids + n;
    // Loads and shuffles: on the AMD machine measured, gathers took longer than the scalar filter.
    __m256d rows[4], sphere[4];
    for (int k = 0; k < 4; ++k) rows[k] = _mm256_loadu_pd(spheres[t[k]].data());
    transpose(rows, sphere);
    // Spheres: |center gap|^2 < (threshold + r_a + r_b)^2, as in the search's scalar loop.
    __m256d gap_squared = _mm256_setzero_pd();
    for (int k = 0; k < 3; ++k) {
      const __m256d d = _mm256_sub_pd(center[k], sphere[k]);
      gap_squared = _mm256_add_pd(gap_squared, _mm256_mul_pd(d, d));
    }
    const __m256d reach = _mm256_add_pd(_mm256_add_pd(limit, sphere[3]), radius_b);
    __m256d pass = _mm256_cmp_pd(gap_squared, _mm256_mul_pd(reach, reach), _CMP_LT_OQ);
    // A's corners, nine values per candidate: two rows of four and the last one.
    const double* c[4];
    for (int k = 0; k < 4; ++k) c[k] = corners[std::size_t(leaf_position[t[k]])][0].data();
    __m256d p[9];
    for (int k = 0; k < 4; ++k) rows[k] = _mm256_loadu_pd(c[k]);
    transpose(rows, p);
    for (int k = 0; k < 4; ++k) rows[k] = _mm256_loadu_pd(c[k] + 4);
    transpose(rows, p + 4);
    p[8] = _mm256_set_pd(c[3][8], c[2][8], c[1][8], c[0][8]);
    // B's plane: the corners' signed offsets all at least the threshold on one side.
    __m256d low = _mm256_set1_pd(kInfinity), high = _mm256_set1_pd(-kInfinity);
    __m256d side[3];  // A's corners against B's plane, as planeOffset
    for (int k = 0; k < 3; ++k) {
      side[k] = planeOffsets(normal, offset, p + 3 * k);
      low = _mm256_min_pd(low, side[k]);
      high = _mm256_max_pd(high, side[k]);
    }
    const __m256d plane_gap = _mm256_max_pd(low, _mm256_xor_pd(high, sign));
    pass = _mm256_and_pd(pass, _mm256_cmp_pd(plane_gap, limit, _CMP_LT_OQ));
    // The boxes: apart by the threshold along some coordinate axis.
    __m256d box_gap = _mm256_set1_pd(-kInfinity);
    for (int k = 0; k < 3; ++k) {
      const __m256d box_min = _mm256_min_pd(_mm256_min_pd(p[k], p[k + 3]), p[k + 6]);
      const __m256d box_max = _mm256_max_pd(_mm256_max_pd(p[k], p[k + 3]), p[k + 6]);
      box_gap = _mm256_max_pd(box_gap, _mm256_max_pd(_mm256_sub_pd(box_min, box_max_b[k]),
                                                     _mm256_sub_pd(box_min_b[k], box_max)));
    }
    pass = _mm256_and_pd(pass, _mm256_cmp_pd(box_gap, limit, _CMP_LT_OQ));
    // Past the boxes, nearly every candidate on a sliver's list (huge fanned triangles whose boxes and
    // planes cover the scan) goes on to the edge axes; they too are cheaper four at a time. One or two
    // survivors are left to the scalar filter, whose cheaper tests dismiss some before the edge axes: on
    // compact meshes, where few candidates survive the boxes, the four-wide test costs more than it saves.
    if (__builtin_popcount(unsigned(_mm256_movemask_pd(pass))) >= 3) {
      for (int k = 0; k < 4; ++k) rows[k] = _mm256_loadu_pd(planes[t[k]].data());
      __m256d plane_a[4];
      transpose(rows, plane_a);
      __m256d others[3];  // B's corners against A's plane
      for (int k = 0; k < 3; ++k) others[k] = planeOffsets(plane_a, plane_a[3], corner_b + 3 * k);
      pass = _mm256_andnot_pd(edgeAxesSeparateByFour(p, side, corner_b, others, limit), pass);
    }
    const int mask = _mm256_movemask_pd(pass);
    for (int k = 0; k < 4; ++k) {
      kept[near] = t[k];
      near += (mask >> k) & 1;
    }
  }
  return n;
}

namespace {

// Three doubles into lanes 0-2, lane 3 zero, reading nothing past the third (a node's obb_half ends its
// BvhNode, and the vector of nodes may end there).
__m256d load3(const double* p) { return _mm256_maskload_pd(p, _mm256_set_epi64x(0, -1, -1, -1)); }

// The rows of a 3x3 matrix (column-major, Eigen's order): row[k] holds coordinate k of its three columns in
// lanes 0-2, and zero in lane 3. Reads only the matrix's nine doubles.
inline void rowsOf(const double* m, __m256d row[3]) {
  const __m256d c0 = _mm256_loadu_pd(m);      // m0 m1 m2 m3
  const __m256d c1 = _mm256_loadu_pd(m + 3);  // m3 m4 m5 m6
  const __m256d c2 = _mm256_permute4x64_pd(_mm256_loadu_pd(m + 5), _MM_SHUFFLE(0, 3, 2, 1));  // m6 m7 m8 m5
  const __m256d zero = _mm256_setzero_pd();
  const __m256d t0 = _mm256_unpacklo_pd(c0, c1);    // m0 m3 m2 m5
  const __m256d t1 = _mm256_unpackhi_pd(c0, c1);    // m1 m4 -  -
  const __m256d t2 = _mm256_unpacklo_pd(c2, zero);  // m6 0  m8 0
  const __m256d t3 = _mm256_unpackhi_pd(c2, zero);  // m7 0  -  0
  row[0] = _mm256_permute2f128_pd(t0, t2, 0x20);
  row[1] = _mm256_permute2f128_pd(t1, t3, 0x20);
  row[2] = _mm256_permute2f128_pd(t0, t2, 0x31);
}

// (row[0] x + row[1] y) + row[2] z, for x, y, z broadcast from memory: lane i is column i's dot product
// with (x, y, z), added as orientedBoxPairBound adds it.
inline __m256d rowsTimes(const __m256d row[3], const double* x, const double* y, const double* z) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(row[0], _mm256_broadcast_sd(x)),
                                     _mm256_mul_pd(row[1], _mm256_broadcast_sd(y))),
                       _mm256_mul_pd(row[2], _mm256_broadcast_sd(z)));
}

}  // namespace

// The node pair bound's three 3x3 products (the line and the other box's axes in each box's frame), one
// vector sum of three products per column, with each box's axes in lanes.
double orientedBoxPairBound(const Eigen::Matrix3d& axes_a, const Eigen::Vector3d& center_a,
                            const Eigen::Vector3d& half_a, const Eigen::Matrix3d& axes_b,
                            const Eigen::Vector3d& center_b, const Eigen::Vector3d& half_b, double bound,
                            double threshold) {
  const __m256d sign = _mm256_set1_pd(-0.0);
  const double line[3] = {center_b[0] - center_a[0], center_b[1] - center_a[1], center_b[2] - center_a[2]};
  __m256d rows_a[3], rows_b[3];
  rowsOf(axes_a.data(), rows_a);
  rowsOf(axes_b.data(), rows_b);
  const __m256d offset_a = _mm256_andnot_pd(sign, rowsTimes(rows_a, line, line + 1, line + 2));
  const __m256d offset_b = _mm256_andnot_pd(sign, rowsTimes(rows_b, line, line + 1, line + 2));
  const __m256d h_a = load3(half_a.data()), h_b = load3(half_b.data());
  const double length = std::sqrt((line[0] * line[0] + line[1] * line[1]) + line[2] * line[2]);
  if (length > 0) {
    // Lanes 0 and 2 of the pairwise sums: (a0 + a1) and a2 + 0 for A, (b0 + b1) and b2 + 0 for B.
    const __m256d pairs = _mm256_hadd_pd(_mm256_mul_pd(h_a, offset_a), _mm256_mul_pd(h_b, offset_b));
    const __m128d reach = _mm_add_pd(_mm256_castpd256_pd128(pairs), _mm256_extractf128_pd(pairs, 1));
    const double reach_a = _mm_cvtsd_f64(reach), reach_b = _mm_cvtsd_f64(_mm_unpackhi_pd(reach, reach));
    bound = std::max(bound, ((length * length - reach_a) - reach_b) / length);
    if (bound >= threshold) return bound;
  }
  // Lane i of cosine_column[j]: |axis i of a . axis j of b|; lane j of cosine_row[i]: the same.
  const double* a = axes_a.data();
  const double* b = axes_b.data();
  __m256d cosine_column[3], cosine_row[3];
  for (int k = 0; k < 3; ++k) {
    cosine_column[k] = _mm256_andnot_pd(sign, rowsTimes(rows_a, b + 3 * k, b + 3 * k + 1, b + 3 * k + 2));
    cosine_row[k] = _mm256_andnot_pd(sign, rowsTimes(rows_b, a + 3 * k, a + 3 * k + 1, a + 3 * k + 2));
  }
  const __m256d reach_b = rowsTimes(cosine_column, half_b.data(), half_b.data() + 1, half_b.data() + 2);
  const __m256d reach_a = rowsTimes(cosine_row, half_a.data(), half_a.data() + 1, half_a.data() + 2);
  __m256d gap = _mm256_max_pd(_mm256_sub_pd(_mm256_sub_pd(offset_a, h_a), reach_b),
                              _mm256_sub_pd(_mm256_sub_pd(offset_b, h_b), reach_a));
  // Lane 3 holds no axis.
  gap = _mm256_blend_pd(gap, _mm256_set1_pd(-std::numeric_limits<double>::infinity()), 0x8);
  __m128d most = _mm_max_pd(_mm256_castpd256_pd128(gap), _mm256_extractf128_pd(gap, 1));
  most = _mm_max_sd(most, _mm_unpackhi_pd(most, most));
  return std::max(bound, _mm_cvtsd_f64(most));
}

#include "detail/edge_axes_kernel.inc"

}  // namespace x86_64_v3

const QueryKernelTable kX86_64_V3QueryKernels{QueryKernels::kX86_64_V3,
                                              &x86_64_v3::triangleTriangleSquaredDistance,
                                              &x86_64_v3::trianglesIntersect,
                                              &x86_64_v3::pointTriangleSquaredDistance,
                                              &x86_64_v3::segmentSegmentSquaredDistance,
                                              &x86_64_v3::pointTriangleSquaredDistances4,
                                              &x86_64_v3::filterListCandidates,
                                              &x86_64_v3::edgeAxesSeparate,
                                              &x86_64_v3::scanPointList,
                                              &x86_64_v3::scanPointListCached,
                                              &x86_64_v3::nearestTriangleBounded,
                                              &x86_64_v3::orientedBoxPairBound};

}  // namespace cfl::detail

#pragma GCC pop_options

#endif  // CFL_X86_64_V3_KERNELS
