#include "cfl/segment_query.h"

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/point_query.h"
#include "cfl/triangle_distance.h"

#include <algorithm>
#include <cmath>
#include <queue>
#include <string>

namespace cfl {

double segmentTriangleSquaredDistance(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const Eigen::Vector3d& a,
                                      const Eigen::Vector3d& b, const Eigen::Vector3d& c,
                                      Eigen::Vector3d* closest_segment, Eigen::Vector3d* closest_triangle) {
  // When the segment misses the triangle, a closest pair has a segment end or a triangle edge in it (if both
  // points were interior, the gap would be normal to the segment and to the plane, so sliding along the
  // segment keeps it until an end or an edge is reached). When it crosses the plane inside the triangle,
  // the crossing point is at distance 0 (rounding may leave it a hair outside, hence the point-triangle
  // distance of the crossing rather than a barycentric test).
  Eigen::Vector3d s, t;
  double best = pointTriangleSquaredDistance(p0, a, b, c, &t);
  s = p0;
  Eigen::Vector3d q;
  double d = pointTriangleSquaredDistance(p1, a, b, c, &q);
  if (d < best) {
    best = d;
    s = p1;
    t = q;
  }
  const Eigen::Vector3d* corners[3] = {&a, &b, &c};
  for (int k = 0; k < 3 && best > 0; ++k) {
    Eigen::Vector3d on_segment, on_edge;
    d = segmentSegmentSquaredDistance(p0, p1, *corners[k], *corners[(k + 1) % 3], &on_segment, &on_edge);
    if (d < best) {
      best = d;
      s = on_segment;
      t = on_edge;
    }
  }
  if (best > 0) {
    const Eigen::Vector3d n = (b - a).cross(c - a);
    const double s0 = n.dot(p0 - a), s1 = n.dot(p1 - a);
    if ((s0 > 0 && s1 < 0) || (s0 < 0 && s1 > 0)) {
      const Eigen::Vector3d x = p0 + (s0 / (s0 - s1)) * (p1 - p0);
      d = pointTriangleSquaredDistance(x, a, b, c, &q);
      if (d < best) {
        best = d;
        s = x;
        t = q;
      }
    }
  }
  if (closest_segment) *closest_segment = s;
  if (closest_triangle) *closest_triangle = t;
  return best;
}

namespace {

double pointSegmentSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& ab,
                                   double ab_squared) {
  double t = ab_squared > 0 ? (p - a).dot(ab) / ab_squared : 0.0;
  t = std::clamp(t, 0.0, 1.0);
  return (a + t * ab - p).squaredNorm();
}

// A lower bound on the distance between the segment (a, ab, its box) and everything below a Bvh node: the
// larger of the sphere bound and the box-box gap, both cheap and each tighter in its own cases (spheres on
// round patches, boxes on long thin ones).
double nodeLowerBound(const BvhNode& node, const Eigen::Vector3d& a, const Eigen::Vector3d& ab, double ab_squared,
                      const Aabb& segment_box) {
  const double to_center = std::sqrt(pointSegmentSquaredDistance(node.center, a, ab, ab_squared));
  const double sphere = to_center - node.radius;
  const Eigen::Vector3d gap =
      (node.box().min - segment_box.max).cwiseMax(segment_box.min - node.box().max).cwiseMax(0.0);
  // The nodes' oriented boxes (the gap along each box axis) were tried too: tighter on some meshes, looser
  // per cost on others, no gain overall in cfl_shape_bench.
  return std::max(sphere, gap.norm());
}

// segmentTriangleSquaredDistance for the search, which only needs pairs closer than `best_squared`: each
// candidate pair is tried only where it can be closest. A closest pair (s, q) has q - s in the segment's
// normal cone at s and s - q in the triangle's at q: an end of the segment counts only if the triangle
// reaches behind it along the segment, and an edge of the triangle only if the segment reaches past the
// edge's line, away from the triangle (of a corner's two edges, one always does). `plane` is the triangle's
// (unit normal and offset, zero for a degenerate triangle). Returns true, with the pair, when it found one
// below best_squared.
bool segmentTriangleBelow(const Eigen::Vector3d& p0, const Eigen::Vector3d& p1, const std::array<Eigen::Vector3d, 3>& t,
                          const Eigen::Vector4d& plane, double& best_squared, Eigen::Vector3d& on_segment,
                          Eigen::Vector3d& on_triangle) {
  bool found = false;
  auto offer = [&](double d, const Eigen::Vector3d& s, const Eigen::Vector3d& q) {
    if (!(d < best_squared)) return;
    best_squared = d;
    on_segment = s;
    on_triangle = q;
    found = true;
  };
  const Eigen::Vector3d n = plane.head<3>();
  const bool flat = n.squaredNorm() > 0;
  const double s0 = n.dot(p0) - plane.w(), s1 = n.dot(p1) - plane.w();
  Eigen::Vector3d q;
  // Crossing the plane: the crossing point (0 inside the triangle, a hair off it by rounding).
  if (flat && ((s0 > 0 && s1 < 0) || (s0 < 0 && s1 > 0))) {
    const Eigen::Vector3d x = p0 + (s0 / (s0 - s1)) * (p1 - p0);
    offer(pointTriangleSquaredDistance(x, t[0], t[1], t[2], &q), x, q);
    if (best_squared == 0) return found;
  }
  const Eigen::Vector3d d = p1 - p0;
  const double scale = 1e-12 * (p0.cwiseAbs().maxCoeff() + p1.cwiseAbs().maxCoeff() + t[0].cwiseAbs().maxCoeff() +
                                (t[1] - t[0]).cwiseAbs().maxCoeff() + (t[2] - t[0]).cwiseAbs().maxCoeff());
  const double along[3] = {t[0].dot(d), t[1].dot(d), t[2].dot(d)};
  const double first = std::min({along[0], along[1], along[2]}), last = std::max({along[0], along[1], along[2]});
  const double slack = scale * (std::abs(d.x()) + std::abs(d.y()) + std::abs(d.z()));
  if (!(flat && s0 * s0 >= best_squared) && first <= p0.dot(d) + slack)
    offer(pointTriangleSquaredDistance(p0, t[0], t[1], t[2], &q), p0, q);
  if (!(flat && s1 * s1 >= best_squared) && last >= p1.dot(d) - slack)
    offer(pointTriangleSquaredDistance(p1, t[0], t[1], t[2], &q), p1, q);
  for (int k = 0; k < 3; ++k) {
    const Eigen::Vector3d& a = t[k];
    const Eigen::Vector3d& b = t[(k + 1) % 3];
    if (flat) {
      Eigen::Vector3d outward = (b - a).cross(n);
      if (outward.dot(t[(k + 2) % 3] - a) > 0) outward = -outward;
      const double line = outward.dot(a);
      const double reach = std::max(outward.dot(p0), outward.dot(p1));
      if (reach < line - scale * (std::abs(outward.x()) + std::abs(outward.y()) + std::abs(outward.z()))) continue;
    }
    Eigen::Vector3d on_s, on_edge;
    offer(segmentSegmentSquaredDistance(p0, p1, a, b, &on_s, &on_edge), on_s, on_edge);
  }
  return found;
}

// The unsigned query in frame M: the closest triangle strictly below `bound` (a length), or none.
struct Closest {
  double squared = std::numeric_limits<double>::infinity();
  Eigen::Vector3d on_segment = Eigen::Vector3d::Zero();
  Eigen::Vector3d on_mesh = Eigen::Vector3d::Zero();
  int triangle = -1;
};

Closest closestTriangle(const CflModel& model, const Eigen::Vector3d& a, const Eigen::Vector3d& b, double bound) {
  const MeshModel& mesh = model.geometry;
  Closest best;
  best.squared = bound * bound;
  // No seeding from the regions' lists at the segment's ends: the first descent reaches a close leaf
  // anyway, and the extra triangle tests cost more than the tighter first bound saves (measured with
  // cfl_shape_bench on the knot and the rock).
  const auto& nodes = mesh.bvh.nodes;
  if (nodes.empty()) return best;
  const Eigen::Vector3d ab = b - a;
  const double ab_squared = ab.squaredNorm();
  Aabb segment_box;
  segment_box.extend(a);
  segment_box.extend(b);
  // Depth-first, nearer child first; the tree is at most Bvh::kMaxDepth deep and the search keeps one pending
  // sibling per level, so 128 entries cannot overflow (as in detail/nearest_triangle.h).
  struct Pending {
    int node;
    double bound;
  };
  Pending stack[128];
  int top = 0;
  const double root = nodeLowerBound(nodes[0], a, ab, ab_squared, segment_box);
  if (root * root >= best.squared) return best;
  stack[top++] = {0, root};
  while (top > 0) {
    const Pending pending = stack[--top];
    if (pending.bound * pending.bound >= best.squared) continue;
    const BvhNode& node = nodes[pending.node];
    if (node.isLeaf()) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        // A leaf holds several triangles: each is first bounded by its own sphere.
        const Eigen::Vector4d& sphere = mesh.leaf_spheres[i];
        const double reach = std::sqrt(pointSegmentSquaredDistance(sphere.head<3>(), a, ab, ab_squared)) - sphere[3];
        if (reach > 0 && reach * reach >= best.squared) continue;
        // Both ends on one side of the triangle's plane: the nearer end's plane distance bounds the distance.
        const Eigen::Vector4d& plane = mesh.leaf_planes[i];
        const double s0 = plane.head<3>().dot(a) - plane.w(), s1 = plane.head<3>().dot(b) - plane.w();
        const double gap = s0 > 0 && s1 > 0 ? std::min(s0, s1) : (s0 < 0 && s1 < 0 ? -std::max(s0, s1) : 0.0);
        if (gap * gap >= best.squared) continue;
        if (segmentTriangleBelow(a, b, mesh.corners.in_leaf_order[i], plane, best.squared, best.on_segment,
                                 best.on_mesh))
          best.triangle = mesh.bvh.triangle_ids[i];
      }
      continue;
    }
    const double left = nodeLowerBound(nodes[node.first], a, ab, ab_squared, segment_box);
    const double right = nodeLowerBound(nodes[node.first + 1], a, ab, ab_squared, segment_box);
    const bool left_first = left <= right;
    const Pending near{left_first ? node.first : node.first + 1, left_first ? left : right};
    const Pending far{left_first ? node.first + 1 : node.first, left_first ? right : left};
    if (far.bound * far.bound < best.squared) stack[top++] = far;
    if (near.bound * near.bound < best.squared) stack[top++] = near;
  }
  return best;
}

// The answer in world terms for the pair (on_segment, on_mesh) of triangle t, all in frame M.
SegmentDistance toWorld(const CflModel& model, const Eigen::Isometry3d& X_WM, double squared,
                        const Eigen::Vector3d& on_segment, const Eigen::Vector3d& on_mesh, int t) {
  SegmentDistance result;
  result.distance = std::sqrt(squared);
  result.triangle = t;
  result.segment_point = X_WM * on_segment;
  result.mesh_point = X_WM * on_mesh;
  Eigen::Vector3d direction = on_segment - on_mesh;
  if (!(direction.norm() > 0)) {
    const auto& c = model.geometry.corners[t];
    direction = (c[1] - c[0]).cross(c[2] - c[0]);
  }
  const double length = direction.norm();
  result.direction = length > 0 ? Eigen::Vector3d(X_WM.linear() * direction / length) : Eigen::Vector3d::Zero();
  return result;
}

void validate(const Eigen::Isometry3d& X_WM, const Eigen::Vector3d& p0_W, const Eigen::Vector3d& p1_W, double bound,
              const char* what) {
  validatePose(X_WM, "X_WM");
  if (!p0_W.allFinite() || !p1_W.allFinite()) throw Error(std::string(what) + ": a segment end is not finite");
  if (!(bound >= 0)) throw Error(std::string(what) + ": the bound must be >= 0 (got " + std::to_string(bound) + ")");
}

// The least signed distance along [p0, p1] by branch and bound (see segment_query.h): intervals ordered by
// their lower bound, split at the middle, dropped once they cannot beat the best point by `tolerance`.
SegmentDistance deepestPoint(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d& p0_W,
                             const Eigen::Vector3d& p1_W, double tolerance) {
  PointQueryOptions point_options;
  point_options.signed_distance = true;
  const double length = (p1_W - p0_W).norm();
  struct Sample {
    double t;
    PointDistance f;
  };
  struct Interval {
    Sample lo, hi;
    double bound;
  };
  auto at = [&](double t) {
    return Sample{t, computePointDistance(model, X_WM, p0_W + t * (p1_W - p0_W), point_options)};
  };
  auto point = [&](double t) -> Eigen::Vector3d { return p0_W + t * (p1_W - p0_W); };
  // Two bounds on how low f can go between two samples: the Lipschitz cone (f changes no faster than the
  // point moves) and the surface points already known (a point is no deeper than its distance to any of
  // them; min(|y - q0|, |y - q1|) is largest at an end or where the two distances are equal). The second
  // is quadratic in the interval's length where the first is linear, which matters along flat faces.
  auto bound = [&](const Sample& lo, const Sample& hi) {
    const double span = (hi.t - lo.t) * length;
    const double cone = 0.5 * (lo.f.distance + hi.f.distance - span);
    const Eigen::Vector3d &q0 = lo.f.closest_point, &q1 = hi.f.closest_point;
    auto reach = [&](const Eigen::Vector3d& y) { return std::min((y - q0).norm(), (y - q1).norm()); };
    double farthest = std::max(reach(point(lo.t)), reach(point(hi.t)));
    const Eigen::Vector3d direction = p1_W - p0_W, across = q1 - q0;
    const double slope = direction.dot(across);
    if (slope != 0) {
      const double t = (0.5 * (q0 + q1) - p0_W).dot(across) / slope;
      if (t > lo.t && t < hi.t) farthest = std::max(farthest, reach(point(t)));
    }
    return std::max(cone, -farthest);
  };
  const Sample first = at(0), last = at(1);
  Sample best = last.f.distance < first.f.distance ? last : first;
  auto later = [](const Interval& x, const Interval& y) { return x.bound > y.bound; };
  std::priority_queue<Interval, std::vector<Interval>, decltype(later)> open(later);
  if (length > 0) open.push({first, last, bound(first, last)});
  while (!open.empty()) {
    const Interval interval = open.top();
    if (interval.bound >= best.f.distance - tolerance) break;
    open.pop();
    const Sample middle = at(0.5 * (interval.lo.t + interval.hi.t));
    if (middle.f.distance < best.f.distance) best = middle;
    for (const auto& [lo, hi] : {std::pair{interval.lo, middle}, std::pair{middle, interval.hi}}) {
      const double b = bound(lo, hi);
      if (b < best.f.distance - tolerance) open.push({lo, hi, b});
    }
  }
  SegmentDistance result;
  result.distance = best.f.distance;
  result.segment_point = point(best.t);
  result.mesh_point = best.f.closest_point;
  result.direction = best.f.gradient;
  result.triangle = best.f.triangle;
  return result;
}

}  // namespace

std::size_t findTrianglesNearSegment(const CflModel& model, const Eigen::Isometry3d& X_WM, const Eigen::Vector3d& p0_W,
                                     const Eigen::Vector3d& p1_W, double radius, std::size_t max_count,
                                     std::vector<SegmentDistance>* found) {
  validate(X_WM, p0_W, p1_W, radius, "findTrianglesNearSegment");
  const Eigen::Isometry3d X_MW = X_WM.inverse();
  const Eigen::Vector3d a = X_MW * p0_W, b = X_MW * p1_W;
  const MeshModel& mesh = model.geometry;
  const auto& nodes = mesh.bvh.nodes;
  std::size_t count = 0;
  if (nodes.empty() || max_count == 0) return 0;
  const Eigen::Vector3d ab = b - a;
  const double ab_squared = ab.squaredNorm();
  Aabb segment_box;
  segment_box.extend(a);
  segment_box.extend(b);
  const double radius_squared = radius * radius;
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  while (top > 0) {
    const BvhNode& node = nodes[stack[--top]];
    if (nodeLowerBound(node, a, ab, ab_squared, segment_box) > radius) continue;
    if (node.isLeaf()) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const auto& c = mesh.corners.in_leaf_order[i];
        Eigen::Vector3d s, q;
        const double d = segmentTriangleSquaredDistance(a, b, c[0], c[1], c[2], &s, &q);
        if (!(d <= radius_squared)) continue;
        if (found) found->push_back(toWorld(model, X_WM, d, s, q, mesh.bvh.triangle_ids[i]));
        if (++count == max_count) return count;
      }
      continue;
    }
    stack[top++] = node.first + 1;
    stack[top++] = node.first;
  }
  return count;
}

SegmentDistance computeSegmentDistance(const CflModel& model, const Eigen::Isometry3d& X_WM,
                                       const Eigen::Vector3d& p0_W, const Eigen::Vector3d& p1_W,
                                       const SegmentQueryOptions& options) {
  validate(X_WM, p0_W, p1_W, options.upper_bound, "computeSegmentDistance");
  if (options.signed_distance && !model.sign.closure.closed)
    throw Error("computeSegmentDistance: a signed distance needs a closed mesh; this one is not (" +
                model.sign.closure.reason + ")");
  if (options.signed_distance && !(options.depth_tolerance >= 0))
    throw Error("computeSegmentDistance: depth_tolerance must be >= 0 (got " + std::to_string(options.depth_tolerance) +
                ")");
  const Eigen::Isometry3d X_MW = X_WM.inverse();
  const Eigen::Vector3d a = X_MW * p0_W, b = X_MW * p1_W;
  const Closest closest = closestTriangle(model, a, b, options.upper_bound);
  const SegmentDistance outside = closest.triangle < 0 ? SegmentDistance{}
                                                       : toWorld(model, X_WM, closest.squared, closest.on_segment,
                                                                 closest.on_mesh, closest.triangle);
  if (!options.signed_distance) return outside;
  const double tolerance =
      options.depth_tolerance > 0 ? options.depth_tolerance : 1e-6 * model.geometry.bounds.diagonal();
  // A segment that misses the surface is wholly outside or wholly inside; its first end says which. One
  // that crosses it may come out a rounding error away (the crossing point is computed), so anything
  // within the tolerance counts as touching and goes to the search, which finds no depth if there is none.
  PointQueryOptions point_options;
  point_options.signed_distance = true;
  const bool touching = closest.triangle >= 0 && closest.squared <= tolerance * tolerance;
  if (!touching) {
    const PointDistance end = computePointDistance(model, X_WM, p0_W, point_options);
    if (end.distance > 0) return outside;
  }
  SegmentDistance deepest = deepestPoint(model, X_WM, p0_W, p1_W, tolerance);
  // Touching without reaching in (or reaching in less than the search resolves): the touching point, at 0.
  if (touching && !(deepest.distance < 0)) return outside;
  return deepest;
}

}  // namespace cfl
