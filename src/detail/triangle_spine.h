#pragma once
// A lower bound on the distance between two triangles that stays close for slivers, where bounding spheres,
// boxes and separating axes are loose: each triangle seen as its longest edge (its spine) and the offset of
// its third corner from that edge.

#include "cfl/triangle_distance.h"

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

namespace cfl::detail {

// A triangle's spine, corners `edge` and (edge + 1) % 3, and the offset of its third corner from its
// projection on the spine's line. A longest edge's end angles are at most right, so the third corner
// projects within the spine, and so does every point of the triangle: x = x' + t * offset with x' on the
// spine and t in [0, 1] (projection onto a line is affine).
struct TriangleSpine {
  int edge;
  Eigen::Vector3d offset;
};

// The index of a longest edge of c (the first of equal ones).
inline int longestEdge(const Eigen::Vector3d c[3]) {
  const double l0 = (c[1] - c[0]).squaredNorm(), l1 = (c[2] - c[1]).squaredNorm(), l2 = (c[0] - c[2]).squaredNorm();
  return l0 >= l1 ? (l0 >= l2 ? 0 : 2) : (l1 >= l2 ? 1 : 2);
}

// The spine of c along edge `edge`, which must be a longest edge of c, as computed where c was (a rigid
// motion keeps it one up to rounding, which the bound's slack covers).
inline TriangleSpine triangleSpine(const Eigen::Vector3d c[3], int edge) {
  const Eigen::Vector3d& p = c[edge];
  const Eigen::Vector3d e = c[(edge + 1) % 3] - p;
  const Eigen::Vector3d r = c[(edge + 2) % 3] - p;
  const double length_squared = e.squaredNorm();
  const double t = length_squared > 0 ? r.dot(e) / length_squared : 0;
  return {edge, r - t * e};
}

// A triangle's spine in one byte (MeshModel::spines): its longest edge, plus kSliverSpine where it is a
// sliver, at most a quarter as wide as its spine is long. Past that, the spines' bound rarely beats the
// separating axes it would come before, and the search skips it.
constexpr std::uint8_t kSliverSpine = 4;
inline std::uint8_t spineCode(const Eigen::Vector3d c[3]) {
  const int edge = longestEdge(c);
  const TriangleSpine spine = triangleSpine(c, edge);
  const bool sliver = 16 * spine.offset.squaredNorm() <= (c[(edge + 1) % 3] - c[edge]).squaredNorm();
  return std::uint8_t(edge | (sliver ? kSliverSpine : 0));
}

// A lower bound on the distance between triangles a and b, given their spines, or -infinity where the
// spines meet. The spines' closest points p and q, at distance d along the unit u = (q - p) / d, separate
// the spines (u . (y' - x') >= d for x' on a's spine and y' on b's; closest points of two convex sets), so
// for x in a and y in b, |y - x| >= u . (y - x) >= d + min(0, u . offset_b) - max(0, u . offset_a). Where
// two flat slivers face each other the offsets lie across u and the bound is nearly d, whatever their
// widths; a bound from the widths alone (two capsules) loses both widths whichever way u points. The result
// is lowered by a slack that covers the rounding of the closest points and offsets (a few eps of the
// coordinates and lengths involved). About one segment-segment distance, `segment_distance`: a search
// passes its kernel table's (QueryKernelTable::segment_segment, the same bits in every build).
using SegmentSegmentDistance = double (*)(const Eigen::Vector3d&, const Eigen::Vector3d&, const Eigen::Vector3d&,
                                          const Eigen::Vector3d&, Eigen::Vector3d*, Eigen::Vector3d*);
inline double spineLowerBound(const Eigen::Vector3d a[3], const TriangleSpine& spine_a, const Eigen::Vector3d b[3],
                              const TriangleSpine& spine_b,
                              SegmentSegmentDistance segment_distance = cfl::segmentSegmentSquaredDistance) {
  const Eigen::Vector3d& a0 = a[spine_a.edge];
  const Eigen::Vector3d& a1 = a[(spine_a.edge + 1) % 3];
  const Eigen::Vector3d& b0 = b[spine_b.edge];
  const Eigen::Vector3d& b1 = b[(spine_b.edge + 1) % 3];
  Eigen::Vector3d p, q;
  const double squared = segment_distance(a0, a1, b0, b1, &p, &q);
  if (!(squared > 0)) return -std::numeric_limits<double>::infinity();
  const double d = std::sqrt(squared);
  const Eigen::Vector3d u = (q - p) / d;
  const double slack = 1e-12 * (p.cwiseAbs().sum() + q.cwiseAbs().sum() + (a1 - a0).cwiseAbs().sum() +
                                (b1 - b0).cwiseAbs().sum());
  return d + std::min(0.0, u.dot(spine_b.offset)) - std::max(0.0, u.dot(spine_a.offset)) - slack;
}

// The same bound for two oriented boxes (points c + axes * s with |s_i| <= half_i): each box is its longest
// axis's segment through its center (its spine) swept by the rectangle of its other two half extents, so
// for x in box a and y in box b, u . (y - x) >= d - sum over the other two axes k of half_k |u . axis_k|,
// both boxes' terms. Where the boxes are needles or facing slabs (the Bvh nodes of a disk fanned into
// slivers, every one of them reaching the disk's center) it is nearly the distance; the separating axes
// of the faces and the line between the centers are loose there.
// `radius_a` / `radius_b`: how far the points the box holds may lie from its spine's line (infinity: as far
// as the box's corners). A point's offset from that line is perpendicular to the spine, so its reach along
// u is at most the radius times the part of u across the spine; a box's term is the smaller of the two
// reaches. Round pieces (of a pipe, a rod) then count as the cylinders they nearly are, where the corners of
// their square boxes reach up to 1.4 times as far. The 1e-15 under the root covers the rounding of
// 1 - (u . axis)^2 where u runs nearly along the spine.
inline double boxSpineLowerBound(const Eigen::Matrix3d& axes_a, const Eigen::Vector3d& center_a,
                                 const Eigen::Vector3d& half_a, const Eigen::Matrix3d& axes_b,
                                 const Eigen::Vector3d& center_b, const Eigen::Vector3d& half_b,
                                 SegmentSegmentDistance segment_distance = cfl::segmentSegmentSquaredDistance,
                                 double radius_a = std::numeric_limits<double>::infinity(),
                                 double radius_b = std::numeric_limits<double>::infinity()) {
  int long_a, long_b;
  half_a.maxCoeff(&long_a);
  half_b.maxCoeff(&long_b);
  const Eigen::Vector3d reach_a = half_a[long_a] * axes_a.col(long_a);
  const Eigen::Vector3d reach_b = half_b[long_b] * axes_b.col(long_b);
  Eigen::Vector3d p, q;
  const double squared = segment_distance(center_a - reach_a, center_a + reach_a, center_b - reach_b,
                                          center_b + reach_b, &p, &q);
  if (!(squared > 0)) return -std::numeric_limits<double>::infinity();
  const double d = std::sqrt(squared);
  const Eigen::Vector3d u = (q - p) / d;
  Eigen::Vector3d across_a = half_a, across_b = half_b;
  across_a[long_a] = 0;
  across_b[long_b] = 0;
  const double slack = 1e-12 * (p.cwiseAbs().sum() + q.cwiseAbs().sum() + reach_a.cwiseAbs().sum() +
                                reach_b.cwiseAbs().sum() + half_a.sum() + half_b.sum());
  const Eigen::Vector3d u_a = axes_a.transpose() * u, u_b = axes_b.transpose() * u;
  auto reach = [](const Eigen::Vector3d& across, const Eigen::Vector3d& u_box, int spine, double radius) {
    const double off_spine = std::sqrt(std::max(0.0, 1 - u_box[spine] * u_box[spine]) + 1e-15) * (1 + 1e-12);
    return std::min(across.dot(u_box.cwiseAbs()), radius * off_spine);
  };
  return d - reach(across_a, u_a, long_a, radius_a) - reach(across_b, u_b, long_b, radius_b) - slack;
}

}  // namespace cfl::detail
