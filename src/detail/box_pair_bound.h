#pragma once
// The oriented-box part of the mesh search's lower bound between two Bvh nodes (Search::nodePairLowerBound):
// the scalar reference that the generic build runs and that QueryKernelTable::box_pair_bound matches bit for
// bit. Every sum is spelled out in the order the vector kernel adds its lanes, so that both round alike.

#include <Eigen/Core>

#include <algorithm>
#include <cmath>

namespace cfl::detail {

// A lower bound on the distance between the oriented boxes a and b (points c + axes * s with |s_i| <=
// half_i, one frame), no smaller than `bound`: the separation along the line between their centers (far
// apart, nearly the distance, and it needs no product of the two frames), then, unless that already reaches
// `threshold`, along each box's three axes, where box a reaches half_a[i] along its axis i and box b
// sum_j |cos(i, j)| half_b[j], and the other way round. Returns as soon as the bound reaches `threshold`,
// where the pair is pruned whatever the later axes say.
inline double orientedBoxPairBound(const Eigen::Matrix3d& axes_a, const Eigen::Vector3d& center_a,
                                   const Eigen::Vector3d& half_a, const Eigen::Matrix3d& axes_b,
                                   const Eigen::Vector3d& center_b, const Eigen::Vector3d& half_b, double bound,
                                   double threshold) {
  const double line[3] = {center_b[0] - center_a[0], center_b[1] - center_a[1], center_b[2] - center_a[2]};
  // The line in each box's frame.
  double offset_a[3], offset_b[3];
  for (int i = 0; i < 3; ++i) {
    offset_a[i] = std::abs((axes_a(0, i) * line[0] + axes_a(1, i) * line[1]) + axes_a(2, i) * line[2]);
    offset_b[i] = std::abs((axes_b(0, i) * line[0] + axes_b(1, i) * line[1]) + axes_b(2, i) * line[2]);
  }
  const double length = std::sqrt((line[0] * line[0] + line[1] * line[1]) + line[2] * line[2]);
  if (length > 0) {
    const double reach_a = (half_a[0] * offset_a[0] + half_a[1] * offset_a[1]) + half_a[2] * offset_a[2];
    const double reach_b = (half_b[0] * offset_b[0] + half_b[1] * offset_b[1]) + half_b[2] * offset_b[2];
    bound = std::max(bound, ((length * length - reach_a) - reach_b) / length);
    if (bound >= threshold) return bound;
  }
  double cosines[3][3];  // |axis i of a . axis j of b|
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      cosines[i][j] =
          std::abs((axes_a(0, i) * axes_b(0, j) + axes_a(1, i) * axes_b(1, j)) + axes_a(2, i) * axes_b(2, j));
    }
  }
  for (int i = 0; i < 3; ++i) {
    const double reach_b = (cosines[i][0] * half_b[0] + cosines[i][1] * half_b[1]) + cosines[i][2] * half_b[2];
    const double reach_a = (cosines[0][i] * half_a[0] + cosines[1][i] * half_a[1]) + cosines[2][i] * half_a[2];
    bound = std::max({bound, (offset_a[i] - half_a[i]) - reach_b, (offset_b[i] - half_b[i]) - reach_a});
  }
  return bound;
}

}  // namespace cfl::detail
