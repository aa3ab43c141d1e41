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

}  // namespace cfl::bench
