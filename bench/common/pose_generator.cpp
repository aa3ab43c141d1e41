#include "pose_generator.h"

#include "cfl/error.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <random>
#include <string>

namespace cfl::bench {
namespace {

std::uint64_t splitMix64(std::uint64_t x) {
  x += 0x9E3779B97F4A7C15ull;
  x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
  x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
  return x ^ (x >> 31);
}

std::uint64_t bandSeed(std::uint64_t seed, double band) {
  std::uint64_t bits;
  std::memcpy(&bits, &band, sizeof bits);
  return splitMix64(splitMix64(seed) ^ bits);
}

// Uniform on SO(3): a normalized 4D Gaussian is a uniform unit quaternion.
Eigen::Matrix3d randomRotation(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Quaterniond q;
  do {
    q = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng));
  } while (q.norm() < 1e-6);
  return q.normalized().toRotationMatrix();
}

Eigen::Vector3d randomDirection(std::mt19937_64& rng) {
  std::normal_distribution<double> normal;
  Eigen::Vector3d u;
  do {
    u = Eigen::Vector3d(normal(rng), normal(rng), normal(rng));
  } while (u.norm() < 1e-6);
  return u.normalized();
}

}  // namespace

std::vector<double> defaultBands() { return {0.0, 0.005, 0.02, 0.1, 0.5}; }

BandPoses generateBandPoses(const Aabb& bounds_a, const Aabb& bounds_b, double band, int count,
                            std::uint64_t seed, const DistanceFunction& distance) {
  if (!std::isfinite(band) || band < 0) throw Error("band " + std::to_string(band) + " must be finite and >= 0");
  if (bounds_a.empty() || bounds_b.empty()) throw Error("pose generator: a mesh has empty bounds");
  const double diagonal = bounds_a.diagonal();
  const double reach = 0.5 * (diagonal + bounds_b.diagonal());  // beyond it the boxes' spheres are apart
  const Eigen::Vector3d center_a = bounds_a.center();
  const Eigen::Vector3d center_b = bounds_b.center();
  // Below this the meshes count as touching: rounding in FCL's triangle distance, not a gap.
  const double touching = 1e-12 * diagonal;

  BandPoses out;
  out.band = band;
  out.target_distance = band * diagonal;
  std::mt19937_64 rng(bandSeed(seed, band));
  int failed_draws = 0;
  while (int(out.poses.size()) < count) {
    const Eigen::Matrix3d R = randomRotation(rng);
    const Eigen::Vector3d u = randomDirection(rng);
    auto poseAt = [&](double s) {
      Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
      X_WB.linear() = R;
      X_WB.translation() = center_a + s * u - R * center_b;
      return X_WB;
    };
    bool found = false;
    Eigen::Isometry3d pose;
    double achieved = 0;
    const double d0 = distance(poseAt(0));
    if (band == 0) {
      if (d0 <= touching) {
        // Largest overlapping offset found so far (lo) and smallest separated one (hi).
        double lo = 0, hi = reach + 0.01 * diagonal;
        for (int i = 0; i < 40 && hi - lo > 1e-6 * diagonal; ++i) {
          const double mid = 0.5 * (lo + hi);
          const double d = distance(poseAt(mid));
          if (d <= touching) {
            lo = mid;
          } else {
            hi = std::max(lo, mid - d);  // 1-Lipschitz: nothing in (mid - d, mid] touches
          }
        }
        for (double fraction : {0.5, 0.25, 0.0}) {
          const Eigen::Isometry3d X = poseAt(fraction * lo);
          const double d = fraction == 0.0 ? d0 : distance(X);
          if (d <= touching) {
            pose = X;
            achieved = d;
            found = true;
            break;
          }
        }
      }
    } else if (d0 < out.target_distance) {
      const double target = out.target_distance;
      // Invariant: distance(lo) <= target <= distance(hi).
      double lo = 0, hi = reach + target;
      for (int i = 0; i < 100; ++i) {
        const double mid = 0.5 * (lo + hi);
        const double d = distance(poseAt(mid));
        if (std::abs(d - target) <= kBandTolerance * target) {
          pose = poseAt(mid);
          achieved = d;
          found = true;
          break;
        }
        if (d < target) {
          lo = std::min(hi, mid + (target - d));
        } else {
          hi = std::max(lo, mid - (d - target));
        }
      }
    }
    if (found) {
      out.poses.push_back(pose);
      out.distances.push_back(achieved);
      failed_draws = 0;
    } else if (++failed_draws >= 100) {
      throw Error("pose generator: 100 random draws in a row could not reach band " + std::to_string(band) +
                  " (distance " + std::to_string(out.target_distance) + ")");
    }
  }
  return out;
}

MovingPoses generateMovingPoses(const Aabb& bounds_a, const Aabb& bounds_b, double separation, int frames,
                                std::uint64_t seed, const DistanceFunction& distance) {
  if (!std::isfinite(separation) || separation <= 0) {
    throw Error("moving poses: separation " + std::to_string(separation) + " must be finite and > 0");
  }
  if (frames < 1) throw Error("moving poses: frame count " + std::to_string(frames) + " must be >= 1");
  if (bounds_a.empty() || bounds_b.empty()) throw Error("moving poses: a mesh has empty bounds");
  const double diagonal = bounds_a.diagonal();
  const double reach = 0.5 * (diagonal + bounds_b.diagonal());
  const Eigen::Vector3d center_a = bounds_a.center();
  const Eigen::Vector3d center_b = bounds_b.center();
  std::mt19937_64 rng(splitMix64(seed ^ 0x6d6f76696e67ull));  // "moving": its own stream, not a band's

  // The orbit's plane (e1, e2) and its normal e3; the rolling axis; B's starting attitude.
  const Eigen::Vector3d e3 = randomDirection(rng);
  const Eigen::Vector3d e1 = e3.unitOrthogonal();
  const Eigen::Vector3d e2 = e3.cross(e1);
  const Eigen::Vector3d roll_axis = randomDirection(rng);
  const Eigen::Matrix3d R0 = randomRotation(rng);
  const double kPi = 3.14159265358979323846;
  const double kTurns = 2;

  MovingPoses out;
  out.separation = separation;
  out.target_distance = separation * diagonal;
  out.rotation_step = 2 * kPi * kTurns / frames;
  const double target = out.target_distance;
  std::vector<double> steps;
  Eigen::Vector3d previous_center = Eigen::Vector3d::Zero();
  for (int k = 0; k < frames; ++k) {
    const double t = double(k) / frames;
    const double angle = 2 * kPi * t;
    const Eigen::Vector3d u =
        (std::cos(angle) * e1 + std::sin(angle) * e2 + 0.3 * std::sin(3 * angle) * e3).normalized();
    const Eigen::Matrix3d R = Eigen::AngleAxisd(2 * kPi * kTurns * t, roll_axis).toRotationMatrix() * R0;
    auto poseAt = [&](double s) {
      Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
      X_WB.linear() = R;
      X_WB.translation() = center_a + s * u - R * center_b;
      return X_WB;
    };
    // From beyond the bounding spheres' contact inward; every step keeps distance >= target.
    double s = reach + 2 * target;
    double d = distance(poseAt(s));
    bool found = false;
    for (int i = 0; i < 10000 && s > 0; ++i) {
      if (std::abs(d - target) <= 1e-3 * target) {
        found = true;
        break;
      }
      s -= std::max(d - target, 1e-4 * target);
      d = distance(poseAt(s));
      if (d < target - 1e-3 * target) break;  // rounding let it step past; the previous step was close
    }
    if (!found) {
      throw Error("moving poses: frame " + std::to_string(k) + " could not reach distance " + std::to_string(target));
    }
    const Eigen::Isometry3d X_WB = poseAt(s);
    const Eigen::Vector3d center = X_WB * center_b;
    if (k > 0) steps.push_back((center - previous_center).norm());
    previous_center = center;
    out.poses.push_back(X_WB);
    out.distances.push_back(d);
  }
  out.median_step = median(steps);
  out.max_step = steps.empty() ? 0 : *std::max_element(steps.begin(), steps.end());
  return out;
}

double percentile(std::vector<double> values, double fraction) {
  if (values.empty()) return 0;
  const std::size_t n = values.size();
  std::size_t rank = std::size_t(std::ceil(fraction * double(n)));
  rank = std::min(n, std::max<std::size_t>(rank, 1));
  std::nth_element(values.begin(), values.begin() + (rank - 1), values.end());
  return values[rank - 1];
}

double median(std::vector<double> values) {
  if (values.empty()) return 0;
  const std::size_t n = values.size();
  std::sort(values.begin(), values.end());
  return n % 2 == 1 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

Eigen::Isometry3d placeShapeOnRay(const Eigen::Vector3d& center, double diagonal, double target,
                                  std::mt19937_64& rng, const DistanceFunction& distance) {
  std::normal_distribution<double> normal;
  const Eigen::Vector3d direction = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = Eigen::Quaterniond(normal(rng), normal(rng), normal(rng), normal(rng)).normalized().toRotationMatrix();
  auto distanceAt = [&](double t) {
    X.translation() = center + t * direction;
    return distance(X);
  };
  double hi = diagonal, lo = hi;
  const double step = 0.02 * diagonal;
  while (lo > 0 && distanceAt(lo) > target) lo -= step;
  lo = std::max(lo, 0.0);
  if (hi - lo < step) lo = hi - step;
  for (int i = 0; i < 60; ++i) {
    const double mid = 0.5 * (lo + hi);
    (distanceAt(mid) > target ? hi : lo) = mid;
  }
  X.translation() = center + hi * direction;
  return X;
}

}  // namespace cfl::bench
