// bench::generateMovingPoses, the orbit behind `cfl bench --moving` and the moving/ benchmark cases: every
// frame rests at the requested gap (checked by brute force and by the CFL query), the motion is smooth, and a
// seed always gives the same orbit.

#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "pose_generator.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <string>
#include <vector>

namespace cfl {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Small non-convex meshes, so that brute force (the generator's distance here) stays cheap.
struct Pair {
  MeshModel a = makeMeshModel(test::makeTorusKnot(2, 3, 0.5, 0.15, 24, 4));
  MeshModel b = makeMeshModel(test::makeTorus(0.4, 0.12, 8, 4));
  bench::DistanceFunction bruteForce() const {
    return [this](const Eigen::Isometry3d& X_WB) {
      return bruteForceDistance(a, Eigen::Isometry3d::Identity(), b, X_WB).distance;
    };
  }
};

const Pair& pair() {
  static const Pair p;
  return p;
}

double angleBetween(const Eigen::Vector3d& u, const Eigen::Vector3d& v) {
  return std::atan2(u.cross(v).norm(), u.dot(v));
}

TEST(MovingPosesTest, EveryFrameRestsWithinATenthOfAPercentOfTheSeparation) {
  const Pair& p = pair();
  const double separation = 0.02;
  const int frames = 16;
  const bench::MovingPoses motion = bench::generateMovingPoses(p.a.bounds, p.b.bounds, separation, frames, 7, p.bruteForce());
  const double diagonal = p.a.bounds.diagonal();
  const double target = separation * diagonal;
  EXPECT_DOUBLE_EQ(motion.separation, separation);
  EXPECT_DOUBLE_EQ(motion.target_distance, target);
  ASSERT_EQ(motion.poses.size(), std::size_t(frames));
  ASSERT_EQ(motion.distances.size(), std::size_t(frames));

  // The CFL query is an independent check of the brute-force distance the generator was given.
  BuildOptions options;
  options.resolution = 12;
  const CflModel cfl_a = buildCflModel(test::makeTorusKnot(2, 3, 0.5, 0.15, 24, 4), options);
  for (int k = 0; k < frames; ++k) {
    const Eigen::Isometry3d& X_WB = motion.poses[std::size_t(k)];
    EXPECT_TRUE(X_WB.linear().isUnitary(1e-12)) << "frame " << k;
    EXPECT_NEAR(X_WB.linear().determinant(), 1.0, 1e-12) << "frame " << k;
    const double brute = bruteForceDistance(p.a, Eigen::Isometry3d::Identity(), p.b, X_WB).distance;
    EXPECT_EQ(motion.distances[std::size_t(k)], brute) << "frame " << k;
    EXPECT_LE(std::abs(brute - target), 1e-3 * target) << "frame " << k << ": " << brute << " vs " << target;
    const double cfl = computeDistance(cfl_a, Eigen::Isometry3d::Identity(), p.b, X_WB).distance;
    EXPECT_NEAR(cfl, brute, 1e-9 * diagonal) << "frame " << k;
  }
}

TEST(MovingPosesTest, ConsecutiveFramesTurnByTheFixedStepAndMoveSmoothlyAroundA) {
  const Pair& p = pair();
  const int frames = 24;
  const bench::MovingPoses motion = bench::generateMovingPoses(p.a.bounds, p.b.bounds, 0.05, frames, 3, p.bruteForce());
  ASSERT_EQ(motion.poses.size(), std::size_t(frames));
  // Two turns over the orbit: a constant rotation of 4 pi / frames between frames.
  EXPECT_NEAR(motion.rotation_step, 4 * kPi / frames, 1e-15);
  const Eigen::Vector3d center_a = p.a.bounds.center();
  const Eigen::Vector3d center_b = p.b.bounds.center();
  // B comes in from beyond the bounding spheres' contact, so its center never leaves that reach.
  const double reach = 0.5 * (p.a.bounds.diagonal() + p.b.bounds.diagonal()) + 2 * motion.target_distance;
  // The direction to B sweeps one turn in a plane with a wobble of amplitude 0.3 (three times per turn):
  // unnormalized (cos a, sin a, 0.3 sin 3a) has speed <= sqrt(1 + 0.9^2) and length >= 1, so the direction
  // turns by at most that times 2 pi / frames per frame.
  const double max_turn = std::sqrt(1 + 0.9 * 0.9) * 2 * kPi / frames;
  std::vector<double> steps;
  for (int k = 0; k < frames; ++k) {
    const Eigen::Isometry3d& X = motion.poses[std::size_t(k)];
    const Eigen::Vector3d offset = X * center_b - center_a;
    EXPECT_LE(offset.norm(), reach * (1 + 1e-12)) << "frame " << k;
    if (k == 0) continue;
    const Eigen::Isometry3d& previous = motion.poses[std::size_t(k - 1)];
    const double turned = Eigen::AngleAxisd(X.linear() * previous.linear().transpose()).angle();
    EXPECT_NEAR(turned, motion.rotation_step, 1e-9) << "frame " << k;
    const Eigen::Vector3d previous_offset = previous * center_b - center_a;
    EXPECT_LE(angleBetween(previous_offset, offset), max_turn + 1e-12) << "frame " << k;
    steps.push_back((offset - previous_offset).norm());
  }
  // The reported step statistics describe these poses.
  std::sort(steps.begin(), steps.end());
  EXPECT_NEAR(motion.max_step, steps.back(), 1e-12);
  EXPECT_NEAR(motion.median_step, bench::median(steps), 1e-12);
  // Smooth: the typical step is of the order of the orbit's arc per frame, not a jump across A.
  EXPECT_LE(motion.median_step, 2 * reach * max_turn);
}

TEST(MovingPosesTest, TheSameSeedGivesTheSameOrbitAndAnotherSeedAnotherOne) {
  const Pair& p = pair();
  const auto run = [&](std::uint64_t seed) {
    return bench::generateMovingPoses(p.a.bounds, p.b.bounds, 0.05, 6, seed, p.bruteForce());
  };
  const bench::MovingPoses first = run(11), again = run(11), other = run(12);
  ASSERT_EQ(first.poses.size(), again.poses.size());
  for (std::size_t k = 0; k < first.poses.size(); ++k) {
    EXPECT_EQ(first.poses[k].matrix(), again.poses[k].matrix()) << "frame " << k;
    EXPECT_EQ(first.distances[k], again.distances[k]) << "frame " << k;
  }
  EXPECT_EQ(first.median_step, again.median_step);
  EXPECT_NE(first.poses[0].matrix(), other.poses[0].matrix());
}

TEST(MovingPosesTest, BadArgumentsThrowNamingTheValue) {
  const Pair& p = pair();
  const auto message = [&](double separation, int frames) -> std::string {
    try {
      bench::generateMovingPoses(p.a.bounds, p.b.bounds, separation, frames, 1, p.bruteForce());
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  };
  EXPECT_NE(message(0.0, 4).find("separation 0"), std::string::npos) << message(0.0, 4);
  EXPECT_NE(message(-0.5, 4).find("separation -0.5"), std::string::npos) << message(-0.5, 4);
  EXPECT_NE(message(std::nan(""), 4).find("separation"), std::string::npos) << message(std::nan(""), 4);
  EXPECT_NE(message(0.01, 0).find("frame count 0"), std::string::npos) << message(0.01, 0);
  const std::string empty = [&]() -> std::string {
    try {
      bench::generateMovingPoses(Aabb{}, p.b.bounds, 0.01, 4, 1, p.bruteForce());
    } catch (const Error& e) {
      return e.what();
    }
    return "no error";
  }();
  EXPECT_NE(empty.find("empty bounds"), std::string::npos) << empty;
}

}  // namespace
}  // namespace cfl
