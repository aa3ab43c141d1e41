// Distance from a solid box to a mesh (box_query.h).

#include "cfl/box_query.h"

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/segment_query.h"

#include <algorithm>
#include <cmath>
#include <sstream>

namespace cfl {
namespace {

// Squared distance from p (box frame) to the solid box [-half, half], and the box's closest point.
double pointBoxSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& half, Eigen::Vector3d* closest) {
  const Eigen::Vector3d q = p.cwiseMax(-half).cwiseMin(half);
  if (closest) *closest = q;
  return (p - q).squaredNorm();
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
  for (const auto& e : kEdges) {
    const double h0 = height[e[0]], h1 = height[e[1]];
    const double gap = h0 > 0 && h1 > 0 ? std::min(h0, h1) : (h0 < 0 && h1 < 0 ? -std::max(h0, h1) : 0.0);
    if (gap * gap >= best.squared) continue;
    // The triangle's bounding sphere: the edge is no closer than its distance to the center minus the radius.
    const Eigen::Vector3d& a = corners[e[0]];
    const Eigen::Vector3d ab = corners[e[1]] - a;
    const double along = std::clamp((sphere_S.head<3>() - a).dot(ab) / ab.squaredNorm(), 0.0, 1.0);
    const double reach = (a + along * ab - sphere_S.head<3>()).norm() - sphere_S.w();
    if (reach > 0 && reach * reach >= best.squared) continue;
    Eigen::Vector3d on_edge, on_triangle;
    const double d = segmentTriangleSquaredDistance(corners[e[0]], corners[e[1]], t[0], t[1], t[2], &on_edge, &on_triangle);
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
  const MeshModel& mesh = model.geometry;
  const Eigen::Isometry3d X_BM = X_WB.inverse() * X_WM;
  Eigen::Vector3d corners[8];
  for (int c = 0; c < 8; ++c)
    corners[c] = Eigen::Vector3d(c & 1 ? half.x() : -half.x(), c & 2 ? half.y() : -half.y(), c & 4 ? half.z() : -half.z());
  Best best{upper_bound * upper_bound};
  const auto& nodes = mesh.bvh.nodes;
  // A node's sphere against the box: its center's distance to the box, minus its radius. (Adding the nodes'
  // axis-aligned boxes against the box's bounds changed nothing measurable in cfl_shape_bench; separating
  // the nodes' oriented boxes from the box along both sets of axes pruned too little for its cost.)
  auto bound = [&](const BvhNode& node) {
    return std::sqrt(pointBoxSquaredDistance(X_BM * node.center, half, nullptr)) - node.radius;
  };
  struct Pending {
    int node;
    double bound;
  };
  Pending stack[128];
  int top = 0;
  if (!nodes.empty()) {
    const double root = bound(nodes[0]);
    if (!(root > 0 && root * root >= best.squared)) stack[top++] = {0, root};
  }
  while (top > 0) {
    const Pending pending = stack[--top];
    if (pending.bound > 0 && pending.bound * pending.bound >= best.squared) continue;
    const BvhNode& node = nodes[pending.node];
    if (node.isLeaf()) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        // A leaf holds several triangles: each is first bounded by its own sphere against the box.
        const Eigen::Vector3d center_B = X_BM * mesh.leaf_spheres[i].head<3>();
        const double reach = std::sqrt(pointBoxSquaredDistance(center_B, half, nullptr)) - mesh.leaf_spheres[i].w();
        if (reach > 0 && reach * reach >= best.squared) continue;
        const auto& c = mesh.leaf_corners[i];
        const Eigen::Vector3d t[3] = {X_BM * c[0], X_BM * c[1], X_BM * c[2]};
        const Eigen::Vector4d& p = mesh.leaf_planes[i];
        Eigen::Vector4d plane_S;
        plane_S.head<3>() = X_BM.linear() * p.head<3>();
        plane_S.w() = plane_S.head<3>().dot(t[0]);
        if (p.head<3>().squaredNorm() == 0) plane_S.setZero();
        Eigen::Vector4d sphere_S;
        sphere_S.head<3>() = center_B;
        sphere_S.w() = mesh.leaf_spheres[i].w();
        testTriangle(t, plane_S, sphere_S, half, corners, mesh.bvh.triangle_ids[i], best);
      }
      if (best.squared == 0) break;
      continue;
    }
    const double left = bound(nodes[node.first]), right = bound(nodes[node.first + 1]);
    const bool left_first = left <= right;
    const Pending near{left_first ? node.first : node.first + 1, left_first ? left : right};
    const Pending far{left_first ? node.first + 1 : node.first, left_first ? right : left};
    if (!(far.bound > 0 && far.bound * far.bound >= best.squared)) stack[top++] = far;
    if (!(near.bound > 0 && near.bound * near.bound >= best.squared)) stack[top++] = near;
  }
  BoxDistance result;
  if (best.triangle < 0) return result;
  result.distance = std::sqrt(best.squared);
  result.triangle = best.triangle;
  result.box_point = X_WB * best.on_box;
  result.mesh_point = X_WB * best.on_triangle;
  return result;
}

}  // namespace cfl
