// Distance from a solid box to a mesh (box_query.h).

#include "cfl/box_query.h"

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/segment_query.h"
#include "cfl/triangle_distance.h"
#include "detail/query_kernels.h"

#if defined(__SSE2__)
#include <emmintrin.h>
#endif

#include <algorithm>
#include <array>
#include <cmath>
#include <sstream>

namespace cfl {
namespace {

// Squared distance from p (box frame) to the solid box [-half, half], and the box's closest point. Scalar
// code: it runs for every triangle corner a query screens, and Eigen's 3-vectors cost more here.
inline double pointBoxSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& half, Eigen::Vector3d* closest) {
  double squared = 0;
  for (int k = 0; k < 3; ++k) {
    const double q = std::min(std::max(p[k], -half[k]), half[k]);
    if (closest) (*closest)[k] = q;
    squared += (p[k] - q) * (p[k] - q);
  }
  return squared;
}

// Whether segment [p0, p1] (box frame) meets the solid box: the slab test, closed on both ends.
bool segmentMeetsBox(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& half,
                     Eigen::Vector3d* point) {
  double lo = 0, hi = 1;
  const Eigen::Vector3d d = p1 - p0;
  for (int k = 0; k < 3; ++k) {
    if (d[k] == 0) {
      if (p0[k] < -half[k] || p0[k] > half[k]) return false;
      continue;
    }
    double t0 = (-half[k] - p0[k]) / d[k], t1 = (half[k] - p0[k]) / d[k];
    if (t0 > t1) std::swap(t0, t1);
    lo = std::max(lo, t0);
    hi = std::min(hi, t1);
    if (lo > hi) return false;
  }
  if (point) *point = (p0 + lo * d).cwiseMax(-half).cwiseMin(half);
  return true;
}

// The gaps below are computed from coordinates in the box frame, each within a few roundings of its true
// value; shrunk by far more than that, they stay below the distance they bound.
constexpr double kGapShrink = 1 - 1e-9;

struct Best {
  double squared;
  Eigen::Vector3d on_box = Eigen::Vector3d::Zero(), on_triangle = Eigen::Vector3d::Zero();
  int triangle = -1;
};

// The box's corners (bit k of the index: +half along axis k) and its twelve edges as corner pairs.
constexpr int kEdges[12][2] = {{0, 1}, {2, 3}, {4, 5}, {6, 7}, {0, 2}, {1, 3},
                               {4, 6}, {5, 7}, {0, 4}, {1, 5}, {2, 6}, {3, 7}};

void testTriangle(const Eigen::Vector3d t[3], const Eigen::Vector4d& plane_S, const Eigen::Vector4d& sphere_S,
                  const Eigen::Vector3d& half, const Eigen::Vector3d corners[8], int id, Best& best) {
  // The plane bound: the box reaches plane_S.w() - sum |n_k| half_k short of the triangle's plane.
  const Eigen::Vector3d& n = plane_S.head<3>();
  if (n.squaredNorm() > 0) {
    const double gap = std::abs(plane_S.w()) - n.cwiseAbs().dot(half);
    if (gap > 0 && gap * gap >= best.squared) return;
  }
  Eigen::Vector3d on_box;
  for (int k = 0; k < 3; ++k) {
    const double d = pointBoxSquaredDistance(t[k], half, &on_box);
    if (d < best.squared) best = {d, on_box, t[k], id};
  }
  if (best.triangle == id && best.squared == 0) return;
  // Corner heights over the triangle's plane: an edge with both ends on one side is at least the nearer
  // end's height away.
  double height[8];
  for (int c = 0; c < 8; ++c) height[c] = n.dot(corners[c]) - plane_S.w();
  const Eigen::Vector3d t_min = t[0].cwiseMin(t[1]).cwiseMin(t[2]), t_max = t[0].cwiseMax(t[1]).cwiseMax(t[2]);
  for (const auto& e : kEdges) {
    const double h0 = height[e[0]], h1 = height[e[1]];
    const double gap = h0 > 0 && h1 > 0 ? std::min(h0, h1) : (h0 < 0 && h1 < 0 ? -std::max(h0, h1) : 0.0);
    if (gap * gap >= best.squared) continue;
    // The edge's own box (it is axis-aligned) against the triangle's.
    const Eigen::Vector3d e_min = corners[e[0]].cwiseMin(corners[e[1]]), e_max = corners[e[0]].cwiseMax(corners[e[1]]);
    if ((e_min - t_max).cwiseMax(t_min - e_max).cwiseMax(0.0).squaredNorm() >= best.squared) continue;
    // The triangle's bounding sphere: the edge is no closer than its distance to the center minus the radius.
    const Eigen::Vector3d& a = corners[e[0]];
    const Eigen::Vector3d ab = corners[e[1]] - a;
    const double along = std::clamp((sphere_S.head<3>() - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const double reach = (a + along * ab - sphere_S.head<3>()).norm() - sphere_S.w();
    if (reach > 0 && reach * reach >= best.squared) continue;
    Eigen::Vector3d on_edge, on_triangle;
    const double d =
        segmentTriangleSquaredDistance(corners[e[0]], corners[e[1]], t[0], t[1], t[2], &on_edge, &on_triangle);
    if (d < best.squared) best = {d, on_edge, on_triangle, id};
  }
  if (best.triangle == id && best.squared == 0) return;
  // A triangle edge may pass through the box with its corners outside and no box edge touching it.
  for (int k = 0; k < 3; ++k) {
    Eigen::Vector3d point;
    if (segmentMeetsBox(t[k], t[(k + 1) % 3], half, &point)) {
      best = {0.0, point, point, id};
      return;
    }
  }
}

// The separating-axis gap between the box [-half, half] and triangle t (box frame) along the box's axes,
// the triangle's normal n and the nine box-axis x triangle-edge directions: a lower bound on their distance,
// and <= 0 along all of them exactly when they intersect (up to rounding).
double separatingGap(const Eigen::Vector3d t[3], const Eigen::Vector3d& n, const Eigen::Vector3d& half) {
  const Eigen::Vector3d lo = t[0].cwiseMin(t[1]).cwiseMin(t[2]), hi = t[0].cwiseMax(t[1]).cwiseMax(t[2]);
  double bound = std::sqrt((lo - half).cwiseMax(-half - hi).cwiseMax(0.0).squaredNorm());
  double any = bound;
  auto axisGap = [&](const Eigen::Vector3d& axis) {
    const double p0 = axis.dot(t[0]), p1 = axis.dot(t[1]), p2 = axis.dot(t[2]);
    const double radius = axis.cwiseAbs().dot(half);
    const double gap = std::max(std::min({p0, p1, p2}) - radius, -std::max({p0, p1, p2}) - radius);
    if (!(gap > 0)) return;
    any = 1;
    const double length_squared = axis.squaredNorm();
    if (!(gap * gap > bound * bound * length_squared)) return;
    bound = gap / std::sqrt(length_squared);
  };
  if (n.squaredNorm() > 0) axisGap(n);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d edge = t[(k + 1) % 3] - t[k];
    axisGap(Eigen::Vector3d(0, -edge.z(), edge.y()));
    axisGap(Eigen::Vector3d(edge.z(), 0, -edge.x()));
    axisGap(Eigen::Vector3d(-edge.y(), edge.x(), 0));
  }
  return any > 0 ? bound : 0.0;
}

// testTriangle, faster where the box and triangle are apart: then a closest pair is a triangle corner and
// the box, a box corner and the triangle, or a box edge and a triangle edge (a face's interior against an
// edge or a face is matched by one of these at the same distance), each tested only where its bounds can
// beat the best. Intersecting (every separating gap <= 0), testTriangle finds the common point.
void testTriangleApart(const detail::QueryKernelTable& kernels, const Eigen::Vector3d t[3],
                       const Eigen::Vector4d& plane_S, const Eigen::Vector4d& sphere_S, const Eigen::Vector3d& half,
                       const Eigen::Vector3d corners[8], bool apart, int id, Best& best) {
  Eigen::Vector3d on_box;
  for (int k = 0; k < 3; ++k) {
    const double d = pointBoxSquaredDistance(t[k], half, &on_box);
    if (d < best.squared) best = {d, on_box, t[k], id};
  }
  const Eigen::Vector3d n = (t[1] - t[0]).cross(t[2] - t[0]);
  // Apart along the box's axes or the plane's normal already: the other axes would only tighten a bound.
  if (!apart) {
    const double gap = separatingGap(t, n, half) * kGapShrink;
    if (!(gap > 0)) {
      testTriangle(t, plane_S, sphere_S, half, corners, id, best);
      return;
    }
    if (gap * gap >= best.squared) return;
  }
  // A closest pair's box point p and triangle point q have q - p in the box's normal cone at p, and p - q in
  // the triangle's at q. So a box corner counts only if the triangle reaches past it along all three axes,
  // a box edge only if the triangle reaches past both faces that meet there, and a triangle edge only if
  // the box reaches past the edge's line, away from the triangle. (A corner within rounding of such a
  // border counts.)
  const Eigen::Vector3d lo = t[0].cwiseMin(t[1]).cwiseMin(t[2]), hi = t[0].cwiseMax(t[1]).cwiseMax(t[2]);
  const double slack = 1e-12 * (hi.cwiseAbs().maxCoeff() + lo.cwiseAbs().maxCoeff() + half.maxCoeff());
  int beyond_low = 0, beyond_high = 0;  // bit k: the triangle reaches below -half_k, above +half_k
  for (int k = 0; k < 3; ++k) {
    if (lo[k] <= -half[k] + slack) beyond_low |= 1 << k;
    if (hi[k] >= half[k] - slack) beyond_high |= 1 << k;
  }
  // Bit k of `past(c)`: the triangle reaches past corner c (bit k of c set for +half_k) along axis k.
  auto past = [&](int c) { return (c & beyond_high) | (~c & beyond_low); };
  // Before each exact distance, the gap between the features' axis-aligned boxes (box frame): most features
  // that pass the cone tests are still farther than the best.
  auto boxesApart = [&](const Eigen::Vector3d& min_a, const Eigen::Vector3d& max_a, const Eigen::Vector3d& min_b,
                        const Eigen::Vector3d& max_b) {
    return (min_a - max_b).cwiseMax(min_b - max_a).cwiseMax(0.0).squaredNorm() * kGapShrink >= best.squared;
  };
  for (int c = 0; c < 8; ++c) {
    if (past(c) != 7) continue;
    if (boxesApart(corners[c], corners[c], lo, hi)) continue;
    Eigen::Vector3d q;
    const double d = kernels.point_triangle(corners[c], t[0], t[1], t[2], &q);
    if (d < best.squared) best = {d, corners[c], q, id};
  }
  // Triangle edges the box reaches past (all of them for a degenerate triangle).
  bool edge_counts[3] = {true, true, true};
  if (n.squaredNorm() > 0) {
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d& a = t[k];
      const Eigen::Vector3d outward = (t[(k + 1) % 3] - a).cross(n);
      // Outward from the triangle: the third corner lies on the other side.
      const double sign = outward.dot(t[(k + 2) % 3] - a) > 0 ? -1.0 : 1.0;
      const double reach = outward.cwiseAbs().dot(half) - sign * outward.dot(a);
      edge_counts[k] = reach >= -slack * outward.cwiseAbs().sum();
    }
  }
  // The four box edges along each axis; each needs the triangle past both faces that meet there, and within
  // the box's extent along the edge.
  for (int along = 0; along < 3; ++along) {
    if (lo[along] > half[along] + slack || hi[along] < -half[along] - slack) continue;
    const int i = (along + 1) % 3, j = (along + 2) % 3;
    const int need = 1 << i | 1 << j;
    for (int m = 0; m < 4; ++m) {
      const int c0 = (m & 1) << i | (m >> 1) << j, c1 = c0 | 1 << along;
      if ((past(c0) & need) != need) continue;
      for (int k = 0; k < 3; ++k) {
        if (!edge_counts[k]) continue;
        const Eigen::Vector3d& q0 = t[k];
        const Eigen::Vector3d& q1 = t[(k + 1) % 3];
        if (boxesApart(corners[c0], corners[c1], q0.cwiseMin(q1), q0.cwiseMax(q1))) continue;
        Eigen::Vector3d on_edge, on_triangle;
        const double d = kernels.segment_segment(corners[c0], corners[c1], q0, q1, &on_edge, &on_triangle);
        if (d < best.squared) best = {d, on_edge, on_triangle, id};
      }
    }
  }
}

// The box's pose and shape for the tests of one query; triangles come in frame M.
struct BoxFrame {
  const detail::QueryKernelTable* kernels;
  Eigen::Isometry3d X_BM;
  Eigen::Vector3d half;
  Eigen::Vector3d corners[8];  // frame B
  double rotation[3][3], shift[3];  // X_BM's rotation (row-major) and translation, for sphereReach
#if defined(__SSE2__)
  // The same numbers and +-half, each in both lanes, for the two-lane bounds: set once per query, not
  // broadcast again at every node.
  __m128d rotation2[3][3], shift2[3], half2[3], minus_half2[3];
#endif
};

// The squared distance from point c (frame M) to the box, and the gap from the box to the sphere of center c
// and radius r: the distance from the center to the box, less r. The same operations, in the same order, one
// sphere at a time or two, so that which spheres a query skips does not depend on how many it bounds at once.
inline double boxSquaredDistance(const BoxFrame& box, const double* c) {
  double squared = 0;
  for (int k = 0; k < 3; ++k) {
    const double* row = box.rotation[k];
    const double p = row[0] * c[0] + row[1] * c[1] + row[2] * c[2] + box.shift[k];
    const double d = p - std::min(std::max(p, -box.half[k]), box.half[k]);
    squared += d * d;
  }
  return squared;
}
inline double sphereReach(const BoxFrame& box, const double* c, double r) {
  return std::sqrt(boxSquaredDistance(box, c)) - r;
}

#if defined(__SSE2__)
// The squared distances from the box to points c0 (low lane) and c1 (high lane), frame M: sphereReach's
// operations, in its order, two lanes at once.
inline __m128d boxSquaredDistance2(const BoxFrame& box, const double* c0, const double* c1) {
  const __m128d x = _mm_set_pd(c1[0], c0[0]), y = _mm_set_pd(c1[1], c0[1]), z = _mm_set_pd(c1[2], c0[2]);
  __m128d squared = _mm_setzero_pd();
  for (int k = 0; k < 3; ++k) {
    const __m128d* row = box.rotation2[k];
    const __m128d p = _mm_add_pd(
        _mm_add_pd(_mm_add_pd(_mm_mul_pd(row[0], x), _mm_mul_pd(row[1], y)), _mm_mul_pd(row[2], z)), box.shift2[k]);
    // std::max(p, -h) is p < -h ? -h : p, which _mm_max_pd(-h, p) spells (and std::min likewise).
    const __m128d clamped = _mm_min_pd(box.half2[k], _mm_max_pd(box.minus_half2[k], p));
    const __m128d d = _mm_sub_pd(p, clamped);
    squared = _mm_add_pd(squared, _mm_mul_pd(d, d));
  }
  return squared;
}
#endif

// The squared distances from the box to points c0 and c1 (frame M): out[0] and out[1].
inline void boxSquaredDistance2(const BoxFrame& box, const double* c0, const double* c1, double out[2]) {
#if defined(__SSE2__)
  _mm_storeu_pd(out, boxSquaredDistance2(box, c0, c1));
#else
  out[0] = boxSquaredDistance(box, c0);
  out[1] = boxSquaredDistance(box, c1);
#endif
}

// sphereReach for two spheres: out[0] for (c0, r0), out[1] for (c1, r1). Two lanes share one square root,
// whose latency the walk otherwise waits for at every node.
inline void sphereReach2(const BoxFrame& box, const double* c0, double r0, const double* c1, double r1,
                         double out[2]) {
#if defined(__SSE2__)
  _mm_storeu_pd(out, _mm_sub_pd(_mm_sqrt_pd(boxSquaredDistance2(box, c0, c1)), _mm_set_pd(r1, r0)));
#else
  out[0] = sphereReach(box, c0, r0);
  out[1] = sphereReach(box, c1, r1);
#endif
}

// Triangle `id` (corners, bounding sphere and plane in frame M) against the box, if its sphere, `reach` from
// the box (sphereReach), can beat the best so far.
inline void considerTriangle(const BoxFrame& box, const std::array<Eigen::Vector3d, 3>& c,
                             const Eigen::Vector4d& sphere, double reach, const Eigen::Vector4d& plane, int id,
                             Best& best) {
  if (reach > 0 && reach * reach >= best.squared) return;
  const Eigen::Vector3d t[3] = {box.X_BM * c[0], box.X_BM * c[1], box.X_BM * c[2]};
  // The triangle's box against the box, before anything that costs more.
  const Eigen::Vector3d lo = t[0].cwiseMin(t[1]).cwiseMin(t[2]), hi = t[0].cwiseMax(t[1]).cwiseMax(t[2]);
  const double box_gap = (lo - box.half).cwiseMax(-box.half - hi).cwiseMax(0.0).squaredNorm() * kGapShrink;
  if (box_gap >= best.squared) return;
  Eigen::Vector4d plane_S;
  plane_S.head<3>() = box.X_BM.linear() * plane.head<3>();
  plane_S.w() = plane_S.head<3>().dot(t[0]);
  if (plane.head<3>().squaredNorm() == 0) plane_S.setZero();
  const double plane_gap = std::abs(plane_S.w()) - plane_S.head<3>().cwiseAbs().dot(box.half);
  if (plane_gap > 0 && plane_gap * plane_gap * kGapShrink >= best.squared) return;
  Eigen::Vector4d sphere_S;
  sphere_S.head<3>() = box.X_BM * sphere.head<3>();
  sphere_S.w() = sphere.w();
  // One more separating axis: from the box's point nearest the triangle's sphere center to that center. Where
  // a triangle is tilted against the box's axes and its plane passes near the box, neither bound above is
  // tight, while this one nearly is for any triangle the box sees from outside its sphere. Projections of
  // box-frame coordinates, less a hair of their scale for rounding.
  const Eigen::Vector3d& center = sphere_S.head<3>();
  const Eigen::Vector3d axis = center - center.cwiseMax(-box.half).cwiseMin(box.half);
  const double axis_squared = axis.squaredNorm();
  if (axis_squared > 0) {
    const double scale = std::max(hi.cwiseAbs().maxCoeff(), lo.cwiseAbs().maxCoeff()) + box.half.maxCoeff();
    const double axis_gap = std::min({axis.dot(t[0]), axis.dot(t[1]), axis.dot(t[2])}) -
                            axis.cwiseAbs().dot(box.half) - 1e-12 * axis.cwiseAbs().sum() * scale;
    if (axis_gap > 0 && axis_gap * axis_gap * kGapShrink >= best.squared * axis_squared) return;
  }
  testTriangleApart(*box.kernels, t, plane_S, sphere_S, box.half, box.corners, box_gap > 0 || plane_gap > 0, id, best);
}

// The exact search over the whole mesh through its Bvh, below best.squared.
void searchBvh(const MeshModel& mesh, const BoxFrame& box, Best& best) {
  const auto& nodes = mesh.bvh.nodes;
  // A node's sphere against the box: its center's distance to the box, minus its radius. (Adding the nodes'
  // axis-aligned boxes against the box's bounds changed nothing measurable in cfl_shape_bench; separating
  // the nodes' oriented boxes from the box along both sets of axes pruned too little for its cost.)
  //
  // A node is out of reach when its center is at least its radius plus the best distance from the box:
  // compared in squares, so that no square root of a node's distance stands between it and the choice of
  // the next node (the best distance's root is taken only when a leaf improves it). The walk descends into
  // the nearer child directly and keeps the farther one pending.
  struct Pending {
    int node;
    double squared, radius;  // the squared distance from the node's center to the box, its radius
  };
  Pending stack[Bvh::kMaxDepth + 1];
  int top = 0;
  double best_distance = std::sqrt(best.squared);
  auto outOfReach = [&](double squared, double radius) {
    const double reach = radius + best_distance;
    return squared >= reach * reach;
  };
  if (!nodes.empty()) {
    const double squared = boxSquaredDistance(box, nodes[0].center.data());
    if (!outOfReach(squared, nodes[0].radius)) stack[top++] = {0, squared, nodes[0].radius};
  }
  while (top > 0) {
    const Pending pending = stack[--top];
    if (outOfReach(pending.squared, pending.radius)) continue;
    for (int index = pending.node;;) {
      const BvhNode& node = nodes[index];
      if (node.isLeaf()) {
        // A leaf holds several triangles (a few at a time, kChunk at most): each is first bounded by its own
        // sphere against the box, two at once, and then tested nearest sphere first, so that the best is
        // tight before the farther triangles, whose bounds then dismiss them before their exact tests.
        constexpr int kChunk = 8;
        const int end = node.first + node.count;
        for (int first = node.first; first < end; first += kChunk) {
          const int n = std::min(kChunk, end - first);
          const Eigen::Vector4d* spheres = &mesh.leaf_spheres[std::size_t(first)];
          double reach[kChunk];
          int order[kChunk];
          for (int j = 0; j < n; j += 2) {
            if (j + 1 < n)
              sphereReach2(box, spheres[j].data(), spheres[j].w(), spheres[j + 1].data(), spheres[j + 1].w(),
                           reach + j);
            else
              reach[j] = sphereReach(box, spheres[j].data(), spheres[j].w());
          }
          // Insertion sort by reach; equal reaches keep the leaf's order.
          for (int j = 0; j < n; ++j) {
            int k = j;
            for (; k > 0 && reach[order[k - 1]] > reach[j]; --k) order[k] = order[k - 1];
            order[k] = j;
          }
          for (int k = 0; k < n; ++k) {
            const int j = order[k];
            // The rest reach no nearer: the best only shrinks.
            if (reach[j] > 0 && reach[j] * reach[j] >= best.squared) break;
            const int i = first + j;
            considerTriangle(box, mesh.corners.in_leaf_order[std::size_t(i)], spheres[j], reach[j],
                             mesh.leaf_planes[std::size_t(i)], mesh.bvh.triangle_ids[std::size_t(i)], best);
          }
        }
        if (best.squared == 0) return;
        best_distance = std::sqrt(best.squared);
        break;
      }
      // The children nearer first, by their spheres' reach (a square root each, but only the branch taken
      // waits for it, not the bounds).
      const int left = node.first, right = node.first + 1;
      double squared[2];
      boxSquaredDistance2(box, nodes[left].center.data(), nodes[right].center.data(), squared);
      const double left_radius = nodes[left].radius, right_radius = nodes[right].radius;
      const bool left_first = std::sqrt(squared[0]) - left_radius <= std::sqrt(squared[1]) - right_radius;
      const Pending near = left_first ? Pending{left, squared[0], left_radius} : Pending{right, squared[1], right_radius};
      const Pending far = left_first ? Pending{right, squared[1], right_radius} : Pending{left, squared[0], left_radius};
      if (!outOfReach(far.squared, far.radius)) stack[top++] = far;
      if (outOfReach(near.squared, near.radius)) break;
      index = near.node;
    }
  }
}

}  // namespace

BoxDistance computeBoxDistance(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Isometry3d& X_WB,
                               const Eigen::Vector3d& half, double upper_bound) {
  validatePose(X_WM, "X_WM");
  validatePose(X_WB, "X_WB");
  if (!half.allFinite() || !(half.minCoeff() > 0)) {
    std::ostringstream message;
    message << "computeBoxDistance: half extents must be finite and > 0, got " << half.transpose();
    throw Error(message.str());
  }
  if (!(upper_bound >= 0)) throw Error("computeBoxDistance: upper_bound must be >= 0");
  BoxFrame box;
  box.kernels = &detail::activeQueryKernelTable();
  box.X_BM = X_WB.inverse() * X_WM;
  box.half = half;
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) box.rotation[i][j] = box.X_BM.linear()(i, j);
    box.shift[i] = box.X_BM.translation()[i];
  }
#if defined(__SSE2__)
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) box.rotation2[i][j] = _mm_set1_pd(box.rotation[i][j]);
    box.shift2[i] = _mm_set1_pd(box.shift[i]);
    box.half2[i] = _mm_set1_pd(half[i]);
    box.minus_half2[i] = _mm_set1_pd(-half[i]);
  }
#endif
  for (int c = 0; c < 8; ++c)
    box.corners[c] =
        Eigen::Vector3d(c & 1 ? half.x() : -half.x(), c & 2 ? half.y() : -half.y(), c & 4 ? half.z() : -half.z());
  Best best{upper_bound * upper_bound};
  searchBvh(model.geometry, box, best);
  BoxDistance result;
  if (best.triangle < 0) return result;
  result.distance = std::sqrt(best.squared);
  result.triangle = best.triangle;
  result.box_point = X_WB * best.on_box;
  result.mesh_point = X_WB * best.on_triangle;
  return result;
}

}  // namespace cfl
