// The x86-64-v3 triangle kernels and point query scans (see detail/query_kernels.h for their table, and
// query_kernels_x86_64_v3.cpp for why the target pragma comes after every include).

#include "detail/query_kernels.h"

#if CFL_X86_64_V3_KERNELS
#include <immintrin.h>

#pragma GCC push_options
#pragma GCC target("arch=x86-64-v3")

namespace cfl::detail::x86_64_v3 {
#include "detail/triangle_distance_kernels.inc"

namespace {

// Three coordinates, each over the four lanes (one triangle per lane). The arithmetic below spells out the
// scalar kernel's Eigen expressions operation by operation, in their order: sums of products left to right,
// cross products as Eigen writes them.
struct Lanes3 {
  __m256d x, y, z;
};

inline Lanes3 sub(const Lanes3& a, const Lanes3& b) {
  return {_mm256_sub_pd(a.x, b.x), _mm256_sub_pd(a.y, b.y), _mm256_sub_pd(a.z, b.z)};
}
inline __m256d dot(const Lanes3& a, const Lanes3& b) {
  return _mm256_add_pd(_mm256_add_pd(_mm256_mul_pd(a.x, b.x), _mm256_mul_pd(a.y, b.y)), _mm256_mul_pd(a.z, b.z));
}
inline Lanes3 cross(const Lanes3& l, const Lanes3& r) {
  return {_mm256_sub_pd(_mm256_mul_pd(l.y, r.z), _mm256_mul_pd(l.z, r.y)),
          _mm256_sub_pd(_mm256_mul_pd(l.z, r.x), _mm256_mul_pd(l.x, r.z)),
          _mm256_sub_pd(_mm256_mul_pd(l.x, r.y), _mm256_mul_pd(l.y, r.x))};
}
inline Lanes3 blend(const Lanes3& a, const Lanes3& b, __m256d take_b) {
  return {_mm256_blendv_pd(a.x, b.x, take_b), _mm256_blendv_pd(a.y, b.y, take_b), _mm256_blendv_pd(a.z, b.z, take_b)};
}
// start + s dir, per coordinate start + (s * dir) as Eigen evaluates it.
inline Lanes3 along(const Lanes3& start, __m256d s, const Lanes3& dir) {
  return {_mm256_add_pd(start.x, _mm256_mul_pd(s, dir.x)), _mm256_add_pd(start.y, _mm256_mul_pd(s, dir.y)),
          _mm256_add_pd(start.z, _mm256_mul_pd(s, dir.z))};
}

// Rows r0..r3 (one per triangle) become columns: r_k holds element k of every row.
inline void transpose(__m256d& r0, __m256d& r1, __m256d& r2, __m256d& r3) {
  const __m256d t0 = _mm256_unpacklo_pd(r0, r1);
  const __m256d t1 = _mm256_unpackhi_pd(r0, r1);
  const __m256d t2 = _mm256_unpacklo_pd(r2, r3);
  const __m256d t3 = _mm256_unpackhi_pd(r2, r3);
  r0 = _mm256_permute2f128_pd(t0, t2, 0x20);
  r1 = _mm256_permute2f128_pd(t1, t3, 0x20);
  r2 = _mm256_permute2f128_pd(t0, t2, 0x31);
  r3 = _mm256_permute2f128_pd(t1, t3, 0x31);
}

// pointSegment of the scalar kernel: the squared distance from p to a + s e (s clamped to [0, 1]), and s.
inline __m256d pointSegment4(const Lanes3& p, const Lanes3& a, const Lanes3& e, __m256d e2, __m256d& s_out) {
  const Lanes3 d = sub(p, a);
  const __m256d s = dot(e, d);
  __m256d t = _mm256_div_pd(s, e2);
  t = _mm256_blendv_pd(t, _mm256_set1_pd(1.0), _mm256_cmp_pd(s, e2, _CMP_GE_OQ));
  t = _mm256_blendv_pd(t, _mm256_setzero_pd(), _mm256_cmp_pd(s, _mm256_setzero_pd(), _CMP_LE_OQ));
  s_out = t;
  const Lanes3 offset = sub(d, {_mm256_mul_pd(t, e.x), _mm256_mul_pd(t, e.y), _mm256_mul_pd(t, e.z)});
  return dot(offset, offset);
}

// The corners a, b, c of four triangles as lanes.
inline void loadTriangles(const std::array<Vec, 3>* const triangles[4], Lanes3& a, Lanes3& b, Lanes3& c) {
  // Each triangle is nine doubles in a row: (a, b.x) and (b.y, b.z, c.x, c.y) transposed by fours, c.z apart.
  __m256d r0 = _mm256_loadu_pd(triangles[0]->data()->data());
  __m256d r1 = _mm256_loadu_pd(triangles[1]->data()->data());
  __m256d r2 = _mm256_loadu_pd(triangles[2]->data()->data());
  __m256d r3 = _mm256_loadu_pd(triangles[3]->data()->data());
  transpose(r0, r1, r2, r3);
  __m256d u0 = _mm256_loadu_pd(triangles[0]->data()->data() + 4);
  __m256d u1 = _mm256_loadu_pd(triangles[1]->data()->data() + 4);
  __m256d u2 = _mm256_loadu_pd(triangles[2]->data()->data() + 4);
  __m256d u3 = _mm256_loadu_pd(triangles[3]->data()->data() + 4);
  transpose(u0, u1, u2, u3);
  const __m256d cz = _mm256_set_pd((*triangles[3])[2].z(), (*triangles[2])[2].z(), (*triangles[1])[2].z(),
                                   (*triangles[0])[2].z());
  a = {r0, r1, r2};
  b = {r3, u0, u1};
  c = {u2, u3, cz};
}

}  // namespace

void pointTriangleSquaredDistances4(const Vec& p, const std::array<Vec, 3>* const triangles[4], double squared[4],
                                    Vec closest[4]) {
  Lanes3 a, b, c;
  loadTriangles(triangles, a, b, c);
  const Lanes3 q{_mm256_set1_pd(p.x()), _mm256_set1_pd(p.y()), _mm256_set1_pd(p.z())};

  const Lanes3 ab = sub(b, a), ac = sub(c, a);
  const Lanes3 n = cross(ab, ac);
  const __m256d nn = dot(n, n);
  const __m256d ab2 = dot(ab, ab), ac2 = dot(ac, ac);
  const __m256d fast =
      _mm256_cmp_pd(nn, _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(kFastSin2), ab2), ac2), _CMP_GT_OQ);
  const Lanes3 ap = sub(q, a);
  const Lanes3 bc = sub(c, b);
  const __m256d s0 = dot(n, cross(ab, ap));
  const __m256d s1 = dot(n, cross(bc, sub(q, b)));
  const __m256d s2 = dot(n, cross(ap, ac));
  const __m256d zero = _mm256_setzero_pd();

  // Inside the face: the height over the plane.
  const __m256d h = dot(n, ap);
  const __m256d k = _mm256_div_pd(h, nn);
  const __m256d face_squared = _mm256_mul_pd(h, k);
  const Lanes3 face_closest = sub(q, {_mm256_mul_pd(k, n.x), _mm256_mul_pd(k, n.y), _mm256_mul_pd(k, n.z)});

  // Else the edges whose lines separate p from the triangle, in the scalar kernel's order, a later one taken
  // when !(d >= best) as there.
  __m256d t0, t1, t2;
  const __m256d d0 = pointSegment4(q, a, ab, ab2, t0);
  const __m256d d1 = pointSegment4(q, b, bc, dot(bc, bc), t1);
  const __m256d d2 = pointSegment4(q, a, ac, ac2, t2);
  const __m256d out0 = _mm256_cmp_pd(s0, zero, _CMP_NGE_UQ);
  const __m256d out1 = _mm256_cmp_pd(s1, zero, _CMP_NGE_UQ);
  const __m256d out2 = _mm256_cmp_pd(s2, zero, _CMP_NGE_UQ);
  __m256d best = _mm256_blendv_pd(_mm256_set1_pd(std::numeric_limits<double>::infinity()), d0, out0);
  __m256d t = _mm256_blendv_pd(zero, t0, out0);
  Lanes3 start = a, dir = ab;
  const __m256d take1 = _mm256_and_pd(out1, _mm256_cmp_pd(d1, best, _CMP_NGE_UQ));
  best = _mm256_blendv_pd(best, d1, take1);
  t = _mm256_blendv_pd(t, t1, take1);
  start = blend(start, b, take1);
  dir = blend(dir, bc, take1);
  const __m256d take2 = _mm256_and_pd(out2, _mm256_cmp_pd(d2, best, _CMP_NGE_UQ));
  best = _mm256_blendv_pd(best, d2, take2);
  t = _mm256_blendv_pd(t, t2, take2);
  start = blend(start, a, take2);
  dir = blend(dir, ac, take2);
  const Lanes3 edge_closest = along(start, t, dir);

  const __m256d inside =
      _mm256_and_pd(_mm256_and_pd(_mm256_cmp_pd(s0, zero, _CMP_GE_OQ), _mm256_cmp_pd(s1, zero, _CMP_GE_OQ)),
                    _mm256_cmp_pd(s2, zero, _CMP_GE_OQ));
  const __m256d result = _mm256_blendv_pd(best, face_squared, inside);
  const Lanes3 point = blend(edge_closest, face_closest, inside);
  alignas(32) double xs[4], ys[4], zs[4];
  _mm256_storeu_pd(squared, result);
  _mm256_store_pd(xs, point.x);
  _mm256_store_pd(ys, point.y);
  _mm256_store_pd(zs, point.z);
  const int fast_lanes = _mm256_movemask_pd(fast);
  for (int lane = 0; lane < 4; ++lane) {
    if (fast_lanes & (1 << lane)) {
      closest[lane] = Vec(xs[lane], ys[lane], zs[lane]);
    } else {
      const auto& c3 = *triangles[lane];
      squared[lane] = pointTriangleSquaredDistance(p, c3[0], c3[1], c3[2], &closest[lane]);
    }
  }
}

namespace {

// The point query's two bounds on four triangles at once, in the scalar scans' operations and order: a
// triangle passes unless |p - center| >= radius + best (its bounding sphere) or its plane lies at least
// `best` from p (zero for a sliver, which then passes), each bound shrunk by far more than its rounding.
// One point's lanes, set once per query.
struct PointBoundLanes {
  Lanes3 p;
  __m256d shrink, slack_scale, slack_unit, sign_bit;

  explicit PointBoundLanes(const Vec& point)
      : p{_mm256_set1_pd(point.x()), _mm256_set1_pd(point.y()), _mm256_set1_pd(point.z())},
        shrink(_mm256_set1_pd(1 - 1e-12)),
        slack_scale(_mm256_set1_pd(std::abs(point.x()) + std::abs(point.y()) + std::abs(point.z()))),
        slack_unit(_mm256_set1_pd(1e-13)),
        sign_bit(_mm256_set1_pd(-0.0)) {}

  // The lanes (bit k for triangle k, all four tested) whose sphere (center c, radius r) and plane (normal n,
  // offset w) both let them through at the best distance `best`.
  int passing(const Lanes3& c, __m256d r, const Lanes3& n, __m256d w, double best) const {
    const __m256d near_sphere = nearSphere(c, r, best);
    const __m256d along_normal = _mm256_sub_pd(dot(n, p), w);
    const __m256d slack =
        _mm256_mul_pd(slack_unit, _mm256_add_pd(_mm256_add_pd(slack_scale, _mm256_andnot_pd(sign_bit, w)), r));
    const __m256d height = _mm256_sub_pd(_mm256_andnot_pd(sign_bit, along_normal), slack);
    const __m256d near_plane = _mm256_cmp_pd(_mm256_mul_pd(height, shrink), _mm256_set1_pd(best), _CMP_NGE_UQ);
    return _mm256_movemask_pd(_mm256_and_pd(near_sphere, near_plane));
  }

  // The sphere bound of `passing` alone, as a lane mask.
  __m256d nearSphere(const Lanes3& c, __m256d r, double best) const {
    const Lanes3 offset = sub(p, c);
    const __m256d reach_squared = dot(offset, offset);
    const __m256d rim = _mm256_add_pd(r, _mm256_set1_pd(best));
    return _mm256_cmp_pd(_mm256_mul_pd(reach_squared, shrink), _mm256_mul_pd(rim, rim), _CMP_NGE_UQ);
  }

  // The lanes of a cached block (PointListCache) whose prism bound lets them through at `best_squared`: the
  // distance to a triangle is at least sqrt(h^2 + l^2), h the height over its plane and l how far p lies
  // beyond the farthest of its edges' lines within the plane (the triangle lies behind each; the two are
  // orthogonal). Tighter than the plane alone for the triangles around the closest one, which pass the
  // sphere and the plane when the closest point lies near their common edge or corner. Each of h and l is
  // reduced by the plane bound's slack first (its part that depends on the triangle is in the block); a
  // sliver's zero edge normals leave l at 0, the plane bound. Only a bound: fused products are fine here.
  int passingPrism(const double* block, double best_squared) const {
    const __m256d zero = _mm256_setzero_pd();
    const __m256d point_slack = _mm256_mul_pd(slack_unit, slack_scale);
    const auto plane = [&](const double* lanes) {
      return _mm256_fmadd_pd(
          _mm256_loadu_pd(lanes), p.x,
          _mm256_fmadd_pd(_mm256_loadu_pd(lanes + 4), p.y,
                          _mm256_fmsub_pd(_mm256_loadu_pd(lanes + 8), p.z, _mm256_loadu_pd(lanes + 12))));
    };
    const __m256d h = _mm256_max_pd(
        _mm256_sub_pd(_mm256_sub_pd(_mm256_andnot_pd(sign_bit, plane(block + 20)), _mm256_loadu_pd(block + 84)),
                      point_slack),
        zero);
    const __m256d beyond = _mm256_max_pd(_mm256_max_pd(plane(block + 36), plane(block + 52)), plane(block + 68));
    const __m256d l = _mm256_max_pd(_mm256_sub_pd(beyond, point_slack), zero);
    const __m256d bound_squared = _mm256_fmadd_pd(h, h, _mm256_mul_pd(l, l));
    return _mm256_movemask_pd(
        _mm256_cmp_pd(_mm256_mul_pd(bound_squared, shrink), _mm256_set1_pd(best_squared), _CMP_NGE_UQ));
  }
};

// Four spheres or planes (x, y, z, w each) as lanes: x, y, z and w of the four.
inline void loadLanes(const Eigen::Vector4d& a, const Eigen::Vector4d& b, const Eigen::Vector4d& c,
                      const Eigen::Vector4d& d, Lanes3& xyz, __m256d& w) {
  xyz.x = _mm256_loadu_pd(a.data());
  xyz.y = _mm256_loadu_pd(b.data());
  xyz.z = _mm256_loadu_pd(c.data());
  w = _mm256_loadu_pd(d.data());
  transpose(xyz.x, xyz.y, xyz.z, w);
}

// Adds to `tests` the triangles of the lanes set in `pass`, lowest first (lane k: corners corner(k), id
// id(k)), keeping `best` the square root of best_squared as it improves.
template <class Corner, class Id>
inline void addPassing(int pass, const Vec& p, const Corner& corner, const Id& id, PendingTriangleTests& tests,
                       double& best_squared, int& best_triangle, Vec* closest, double& best) {
  while (pass != 0) {
    const int k = __builtin_ctz(unsigned(pass));
    pass &= pass - 1;
    if (tests.add(p, corner(k), id(k), best_squared, best_triangle, closest)) best = std::sqrt(best_squared);
  }
}

}  // namespace

void scanPointList(const Vec& p, const PointListScan& list, const MeshModel& geometry, double& best_squared,
                   int& best_triangle, Vec& closest) {
  const Eigen::Vector4d* spheres = geometry.spheres.data();
  const Eigen::Vector4d* planes = geometry.planes.data();
  const TriangleCorners& corners = geometry.corners;
  PendingTriangleTests tests;
  tests.four = &pointTriangleSquaredDistances4;
  tests.one = &pointTriangleSquaredDistance;
  double best = std::sqrt(best_squared);
  const PointBoundLanes lanes(p);
  for (std::uint32_t n = 0; n < list.length; n += 4) {
    // The entries of this block before the first whose bound reaches the best: sorted, none after it can
    // beat the best (a block's best may be a batch old, see PendingTriangleTests).
    int ids[4];
    int count = 0;
    const std::uint32_t end = std::min(list.length, n + 4);
    bool stop = false;
    for (std::uint32_t m = n; m < end; ++m) {
      const double bound = double(list.bounds[m]) * list.unit;
      if (bound * bound >= best_squared) {
        stop = true;
        break;
      }
      ids[count++] = list.high ? std::int32_t(std::uint32_t(list.low[m]) | std::uint32_t(list.high[m]) << 16)
                               : list.base + std::int32_t(list.low[m]);
    }
    if (count > 0) {
      for (int k = count; k < 4; ++k) ids[k] = ids[0];
      Lanes3 center, normal;
      __m256d radius, offset;
      loadLanes(spheres[ids[0]], spheres[ids[1]], spheres[ids[2]], spheres[ids[3]], center, radius);
      loadLanes(planes[ids[0]], planes[ids[1]], planes[ids[2]], planes[ids[3]], normal, offset);
      const int pass = lanes.passing(center, radius, normal, offset, best) & ((1 << count) - 1);
      addPassing(pass, p, [&](int k) -> const auto& { return corners[ids[k]]; }, [&](int k) { return ids[k]; }, tests,
                 best_squared, best_triangle, &closest, best);
    }
    if (stop) break;
  }
  tests.run(p, best_squared, best_triangle, &closest);
}

namespace {

// Lays out block b of the cached list (see PointListCache).
void fillBlock(PointListCache& cache, const MeshModel& geometry, std::uint32_t b) {
  const PointListScan& list = cache.source;
  std::int32_t* ids = cache.ids.data() + 4 * std::size_t(b);
  double* block = cache.lanes.data() + std::size_t(b) * PointListCache::kBlock;
  const std::uint32_t first = 4 * b;
  const std::uint32_t count = std::min<std::uint32_t>(4, list.length - first);
  for (std::uint32_t k = 0; k < 4; ++k) {
    // Lanes past the list repeat its last entry, behind an infinite bound.
    const std::uint32_t n = first + std::min(k, count - 1);
    ids[k] = list.high ? std::int32_t(std::uint32_t(list.low[n]) | std::uint32_t(list.high[n]) << 16)
                       : list.base + std::int32_t(list.low[n]);
    const double bound = double(list.bounds[n]) * list.unit;
    block[k] = k < count ? bound * bound : std::numeric_limits<double>::infinity();
  }
  const auto& spheres = geometry.spheres;
  const auto& planes = geometry.planes;
  Lanes3 center, normal;
  __m256d radius, offset;
  loadLanes(spheres[ids[0]], spheres[ids[1]], spheres[ids[2]], spheres[ids[3]], center, radius);
  loadLanes(planes[ids[0]], planes[ids[1]], planes[ids[2]], planes[ids[3]], normal, offset);
  _mm256_storeu_pd(block + 4, center.x);
  _mm256_storeu_pd(block + 8, center.y);
  _mm256_storeu_pd(block + 12, center.z);
  _mm256_storeu_pd(block + 16, radius);
  _mm256_storeu_pd(block + 20, normal.x);
  _mm256_storeu_pd(block + 24, normal.y);
  _mm256_storeu_pd(block + 28, normal.z);
  _mm256_storeu_pd(block + 32, offset);
  // The prism bound's lanes wait until a scan needs them (fillEdges): a NaN marks them missing.
  block[84] = std::numeric_limits<double>::quiet_NaN();
}

// Lane k of edge lane set e of a cached block: the unit direction m and the largest of the three corners'
// offsets along it, with the slack that depends on the triangle (see PointBoundLanes::passing).
void setSliverEdgeLane(double* block, int k, int e, const Vec& m, const std::array<Vec, 3>& v) {
  const double offset = std::max({m.dot(v[0]), m.dot(v[1]), m.dot(v[2])});
  double* edge = block + 36 + 16 * e;
  edge[k] = m.x();
  edge[4 + k] = m.y();
  edge[8 + k] = m.z();
  edge[12 + k] = offset + 1e-13 * (block[16 + k] + std::abs(offset));
}

// A sliver's three half-spaces for the prism bound (PointBoundLanes::passingPrism): its plane is zero there,
// so the bound is the largest of m . p - o over the three, each a valid bound on its own for a unit m with
// the triangle in m . x <= o. Along its longest edge both ways (beyond its ends), and across that edge's
// line towards `towards` (the point whose scan lays the block out: the list's next points lie near it).
// Written to lane k of the edge lanes, offsets with the slack of fillEdges; a zero direction (a point on
// the line, a triangle of one point) bounds nothing.
void sliverHalfSpaces(double* block, int k, const std::array<Vec, 3>& v, const Vec& towards) {
  int longest = 0;
  double longest_squared = -1;
  for (int e = 0; e < 3; ++e) {
    const double squared = (v[(e + 1) % 3] - v[e]).squaredNorm();
    if (squared > longest_squared) longest_squared = squared, longest = e;
  }
  const Vec& a = v[longest];
  const Vec u = v[(longest + 1) % 3] - a;
  Vec across = towards - a;
  if (longest_squared > 0) across -= (across.dot(u) / longest_squared) * u;
  const double across_length = across.norm();
  const double u_length = std::sqrt(longest_squared);
  const Vec directions[3] = {u_length > 0 ? Vec(u / u_length) : Vec::Zero(),
                             u_length > 0 ? Vec(-u / u_length) : Vec::Zero(),
                             across_length > 0 ? Vec(across / across_length) : Vec::Zero()};
  for (int e = 0; e < 3; ++e) setSliverEdgeLane(block, k, e, directions[e], v);
}

// The edge lanes of a sliver that has a plane (unit `normal`, accurate to a few ulps: MeshModel::planes):
// each edge's outward normal within that plane, across the edge and that normal, so orthogonal to it up to
// rounding, as the prism bound needs; the plain ab x ac of a sliver is too far off for that. Each offset is
// the largest over the three corners, so that the triangle lies behind the line whatever the rounding of
// the corner opposite a long edge.
void sliverEdgeNormals(double* block, int k, const std::array<Vec, 3>& v, const Vec& normal) {
  for (int e = 0; e < 3; ++e) {
    const Vec m = (v[(e + 1) % 3] - v[e]).cross(normal);
    const double length = m.norm();
    setSliverEdgeLane(block, k, e, length > 0 ? Vec(m / length) : Vec::Zero(), v);
  }
}

// Lays out the prism bound's lanes of a cached block (PointListCache, PointBoundLanes::passingPrism): the
// edges' outward normals within the plane of ab x ac, and for a sliver (kFastSin2, as the kernels), where
// that normal is too inaccurate for the bound's orthogonality, those within its accurate plane
// (sliverEdgeNormals), or without a plane the half-spaces of sliverHalfSpaces about p, the point being
// queried; each offset, and the plane's, with the slack's part that depends on the triangle (see
// PointBoundLanes::passing).
void fillEdges(double* block, const std::int32_t* ids, const MeshModel& geometry, const Vec& p) {
  const auto& corners = geometry.corners;
  const std::array<Vec, 3>* const triangles[4] = {&corners[ids[0]], &corners[ids[1]], &corners[ids[2]],
                                                  &corners[ids[3]]};
  Lanes3 a, b, c;
  loadTriangles(triangles, a, b, c);
  const Lanes3 ab = sub(b, a), ac = sub(c, a);
  const Lanes3 n = cross(ab, ac);
  const __m256d shaped =
      _mm256_cmp_pd(dot(n, n), _mm256_mul_pd(_mm256_mul_pd(_mm256_set1_pd(kFastSin2), dot(ab, ab)), dot(ac, ac)),
                    _CMP_GT_OQ);
  const __m256d radius = _mm256_loadu_pd(block + 16);
  const __m256d unit = _mm256_set1_pd(1e-13);
  const __m256d sign_bit = _mm256_set1_pd(-0.0);
  const Lanes3 from[3] = {a, b, c};
  const Lanes3 along[3] = {ab, sub(c, b), sub(a, c)};
  for (int e = 0; e < 3; ++e) {
    const Lanes3 m = cross(along[e], n);
    const __m256d length = _mm256_sqrt_pd(dot(m, m));
    const __m256d usable = _mm256_and_pd(shaped, _mm256_cmp_pd(length, _mm256_setzero_pd(), _CMP_GT_OQ));
    const Lanes3 unit_m{_mm256_and_pd(_mm256_div_pd(m.x, length), usable),
                        _mm256_and_pd(_mm256_div_pd(m.y, length), usable),
                        _mm256_and_pd(_mm256_div_pd(m.z, length), usable)};
    const __m256d offset = dot(unit_m, from[e]);
    double* edge = block + 36 + 16 * e;
    _mm256_storeu_pd(edge, unit_m.x);
    _mm256_storeu_pd(edge + 4, unit_m.y);
    _mm256_storeu_pd(edge + 8, unit_m.z);
    _mm256_storeu_pd(
        edge + 12,
        _mm256_add_pd(offset, _mm256_mul_pd(unit, _mm256_add_pd(radius, _mm256_andnot_pd(sign_bit, offset)))));
  }
  _mm256_storeu_pd(block + 84,
                   _mm256_mul_pd(unit, _mm256_add_pd(radius, _mm256_andnot_pd(sign_bit, _mm256_loadu_pd(block + 32)))));
  int slivers = ~_mm256_movemask_pd(shaped) & 0xf;
  while (slivers != 0) {
    const int k = __builtin_ctz(unsigned(slivers));
    slivers &= slivers - 1;
    const Vec normal(block[20 + k], block[24 + k], block[28 + k]);
    if (normal.isZero()) {
      // No plane (MeshModel::planes): the height is zero and the half-spaces bound alone.
      sliverHalfSpaces(block, k, *triangles[k], p);
    } else {
      sliverEdgeNormals(block, k, *triangles[k], normal);
    }
  }
}

}  // namespace

void scanPointListCached(const Vec& p, PointListCache& list, const MeshModel& geometry, double& best_squared,
                         int& best_triangle, Vec& closest) {
  const TriangleCorners& corners = geometry.corners;
  PendingTriangleTests tests;
  tests.four = &pointTriangleSquaredDistances4;
  tests.one = &pointTriangleSquaredDistance;
  tests.known_id = list.known_triangle;
  tests.known_squared = list.known_squared;
  tests.known_closest = list.known_closest;
  double best = std::sqrt(best_squared);
  const PointBoundLanes lanes(p);
  const std::uint32_t blocks = (list.source.length + 3) / 4;
  for (std::uint32_t b = 0; b < blocks; ++b) {
    if (b == list.filled) fillBlock(list, geometry, list.filled++);
    double* block = list.lanes.data() + std::size_t(b) * PointListCache::kBlock;
    const std::int32_t* ids = list.ids.data() + 4 * std::size_t(b);
    // The block's entries before the first whose bound reaches the best (as scanPointList).
    const int stop =
        _mm256_movemask_pd(_mm256_cmp_pd(_mm256_loadu_pd(block), _mm256_set1_pd(best_squared), _CMP_GE_OQ));
    const int count = stop ? __builtin_ctz(unsigned(stop)) : 4;
    if (count > 0) {
      int pass;
      const Lanes3 center{_mm256_loadu_pd(block + 4), _mm256_loadu_pd(block + 8), _mm256_loadu_pd(block + 12)};
      if (!std::isnan(block[84])) {
        // Once laid out, the prism bound stands in for the plane's: a valid bound on its own, with the same
        // height and slack, so no lower than the plane's but for rounding. The sphere's still rejects some
        // triangles the prism lets through.
        pass = _mm256_movemask_pd(lanes.nearSphere(center, _mm256_loadu_pd(block + 16), best)) & ((1 << count) - 1);
        if (pass != 0) pass &= lanes.passingPrism(block, best_squared);
      } else {
        const Lanes3 normal{_mm256_loadu_pd(block + 20), _mm256_loadu_pd(block + 24), _mm256_loadu_pd(block + 28)};
        pass = lanes.passing(center, _mm256_loadu_pd(block + 16), normal, _mm256_loadu_pd(block + 32), best) &
               ((1 << count) - 1);
        if (pass != 0) {
          fillEdges(block, ids, geometry, p);
          pass &= lanes.passingPrism(block, best_squared);
        }
      }
      addPassing(pass, p, [&](int k) -> const auto& { return corners[ids[k]]; }, [&](int k) { return ids[k]; }, tests,
                 best_squared, best_triangle, &closest, best);
    }
    if (stop) break;
  }
  tests.run(p, best_squared, best_triangle, &closest);
}

void nearestTriangleBounded(const MeshModel& model, const Vec& p, double& best_squared, int& best_triangle,
                            Vec* closest) {
  const auto& nodes = model.compact_nodes;
  if (nodes.empty()) return;
  // nearestTriangleCompactBounded's box distance with the three axes in lanes: the same sums in the same
  // order, (x^2 + y^2) + z^2, so the same children order and the same walk. (A gap of -0 here may be +0
  // there; squared, both are +0.) The fourth lane, the node's link read as a float, is dropped.
  const __m256d point = _mm256_set_pd(0.0, p.z(), p.y(), p.x());
  const __m256d xyz = _mm256_castsi256_pd(_mm256_set_epi64x(0, -1, -1, -1));
  const auto boxSquared = [&](const CompactBvhNode& node) {
    const __m256d low = _mm256_cvtps_pd(_mm_loadu_ps(node.min));
    const __m256d high = _mm256_cvtps_pd(_mm_loadu_ps(node.max));
    const __m256d zero = _mm256_setzero_pd();
    const __m256d gap = _mm256_add_pd(_mm256_max_pd(_mm256_sub_pd(low, point), zero),
                                      _mm256_max_pd(_mm256_sub_pd(point, high), zero));
    const __m256d squared = _mm256_and_pd(_mm256_mul_pd(gap, gap), xyz);
    const __m128d xy = _mm256_castpd256_pd128(squared);
    const __m128d z = _mm256_extractf128_pd(squared, 1);
    return _mm_cvtsd_f64(_mm_add_sd(_mm_add_sd(xy, _mm_unpackhi_pd(xy, xy)), z));
  };
  struct Pending {
    double bound;
    int node;
  };
  Pending stack[128];
  int top = 0;
  stack[top++] = {boxSquared(nodes[0]), 0};
  double best = std::sqrt(best_squared);
  const PointBoundLanes lanes(p);
  const Eigen::Vector4d* spheres = model.leaf_spheres.data();
  const Eigen::Vector4d* planes = model.leaf_planes.data();
  PendingTriangleTests tests;
  tests.four = &pointTriangleSquaredDistances4;
  tests.one = &pointTriangleSquaredDistance;
  while (top > 0) {
    const Pending pending = stack[--top];
    if (pending.bound > best_squared) continue;
    const CompactBvhNode& node = nodes[pending.node];
    if (node.count > 0) {
      const int end = node.first + node.count;
      for (int i = node.first; i < end; i += 4) {
        // Lanes past the leaf repeat its last triangle and are masked off.
        const int count = std::min(4, end - i);
        const int j1 = i + std::min(1, count - 1), j2 = i + std::min(2, count - 1), j3 = i + std::min(3, count - 1);
        Lanes3 center, normal;
        __m256d radius, offset;
        loadLanes(spheres[i], spheres[j1], spheres[j2], spheres[j3], center, radius);
        loadLanes(planes[i], planes[j1], planes[j2], planes[j3], normal, offset);
        const int pass = lanes.passing(center, radius, normal, offset, best) & ((1 << count) - 1);
        addPassing(pass, p, [&](int k) -> const auto& { return model.corners.in_leaf_order[i + k]; },
                   [&](int k) { return model.bvh.triangle_ids[i + k]; }, tests, best_squared, best_triangle, closest,
                   best);
      }
      // The batch runs before the walk goes on: the nodes' bounds compare with the best.
      if (tests.run(p, best_squared, best_triangle, closest)) best = std::sqrt(best_squared);
      continue;
    }
    const double d_left = boxSquared(nodes[node.first]);
    const double d_right = boxSquared(nodes[node.first + 1]);
    const bool left_first = d_left <= d_right;
    const double d_far = left_first ? d_right : d_left;
    const double d_near = left_first ? d_left : d_right;
    if (d_far <= best_squared) stack[top++] = {d_far, left_first ? node.first + 1 : node.first};
    if (d_near <= best_squared) stack[top++] = {d_near, left_first ? node.first : node.first + 1};
  }
}

}  // namespace cfl::detail::x86_64_v3

#pragma GCC pop_options

#endif  // CFL_X86_64_V3_KERNELS
