#pragma once
/// @file
/// Fair timing of several distance methods on the same poses, shared by `cfl bench` and `cfl paper`.

#include <Eigen/Geometry>

#include <functional>
#include <string>
#include <vector>

namespace cfl::tool {

/// A distance query under test: B at pose X_WB (A at the identity) -> distance.
struct TimedMethod {
  std::string name;
  std::function<double(const Eigen::Isometry3d& X_WB)> query;
};

/// Per method: for each pose, the median wall time over the repeats (microseconds) and the distance the
/// first repeat returned.
struct MethodSamples {
  std::vector<double> micros;
  std::vector<double> distances;
};

/// Times every method on every pose `repeats` times. Methods are interleaved pose by pose and their order
/// rotates with the pose and the repeat, so drifts in clock speed, cache state or machine load hit all of
/// them alike; every method first runs twice untimed to warm caches. steady_clock, one call per sample.
std::vector<MethodSamples> timeMethods(const std::vector<Eigen::Isometry3d>& poses,
                                       const std::vector<TimedMethod>& methods, int repeats);

/// Mean of `values`; 0 when empty.
double mean(const std::vector<double>& values);

}  // namespace cfl::tool
