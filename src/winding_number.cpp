// The generalized winding number (Jacobson et al. 2013) with the Bvh far field of Barill et al. 2018.

#include "cfl/mesh_sign.h"

#include <Eigen/Geometry>

#include <cmath>

namespace cfl {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Signed solid angle of triangle (a, b, c) seen from p (Van Oosterom & Strackee 1983): positive when p sees
// the triangle's back (the side its counterclockwise normal points away from).
double solidAngle(const Eigen::Vector3d& p, const Eigen::Vector3d& a3, const Eigen::Vector3d& b3,
                  const Eigen::Vector3d& c3) {
  const Eigen::Vector3d a = a3 - p, b = b3 - p, c = c3 - p;
  const double la = a.norm(), lb = b.norm(), lc = c.norm();
  const double det = a.dot(b.cross(c));
  // A flat view (p in the triangle's plane, or a degenerate triangle) subtends nothing; atan2(0, negative)
  // would say 2 pi.
  if (det == 0) return 0;
  const double denominator = la * lb * lc + a.dot(b) * lc + a.dot(c) * lb + b.dot(c) * la;
  return 2 * std::atan2(det, denominator);
}

}  // namespace

double windingNumber(const MeshModel& model, const MeshSign& sign, const Eigen::Vector3d& p_M) {
  const auto& nodes = model.bvh.nodes;
  const WindingField& field = windingField(model, sign);
  if (nodes.empty() || field.dipole_index.size() != nodes.size()) return 0;
  // Depth-first; one pending sibling per level, at most Bvh::kMaxDepth + 1 (see nearestTriangle).
  int stack[128];
  int top = 0;
  stack[top++] = 0;
  double total = 0;
  while (top > 0) {
    const int index = stack[--top];
    const BvhNode& node = nodes[index];
    if (node.isLeaf()) {
      for (int i = node.first; i < node.first + node.count; ++i) {
        const auto& c = model.corners[model.bvh.triangle_ids[i]];
        total += solidAngle(p_M, c[0], c[1], c[2]);
      }
      continue;
    }
    const WindingDipole& d = field.node_dipoles[field.dipole_index[index]];
    const Eigen::Vector3d r = d.center - p_M;
    const double distance_squared = r.squaredNorm();
    if (distance_squared > kWindingFarFactor * kWindingFarFactor * d.radius * d.radius) {
      // Far: the solid angle of area vector dA at x is dA . (x - p) / |x - p|^3 = dA . f(x). To first order in
      // x - center, f(x) = f(center) + J (x - center) with J = (|r|^2 I - 3 r r^T) / |r|^5, and the triangles'
      // first moments are exact at their centroids, so the node subtends N . f + J : M.
      const double inv = 1 / std::sqrt(distance_squared);
      const double inv3 = inv * inv * inv;
      const double inv5 = inv3 * inv * inv;
      double value = d.area_normal.dot(r) * inv3;
      value += inv3 * d.moment.trace() - 3 * inv5 * r.dot(d.moment * r);
      total += value;
      continue;
    }
    stack[top++] = node.first + 1;
    stack[top++] = node.first;
  }
  return total / (4 * kPi);
}

}  // namespace cfl
