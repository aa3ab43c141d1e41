#pragma once
/// @file
/// Fair timing of several distance methods on the same poses, shared by `cfl bench` and `cfl paper`.

#include <Eigen/Geometry>

#include <cstddef>
#include <functional>
#include <string>
#include <vector>

namespace cfl::tool {

/// A distance query under test: B at pose X_WB (A at the identity) -> distance.
struct TimedMethod {
  std::string name;
  std::function<double(const Eigen::Isometry3d& X_WB)> query;
};

/// Per method: for each pose, the median time over the repeats (microseconds, in the Clock asked for) and the distance the
/// first repeat returned.
struct MethodSamples {
  std::vector<double> micros;
  std::vector<double> distances;
};

/// What a sample measures: elapsed wall time (what a caller waits), or the calling thread's CPU time, which
/// leaves out the time the thread waits for a core on a loaded machine. Queries are single-threaded, so on
/// an idle machine the two agree.
enum class Clock { kWall, kThreadCpu };

/// In what order the samples of several methods are taken.
enum class Order {
  /// Pose by pose, the methods in a random order drawn afresh for every pose and repeat (fixed seed): drifts
  /// in clock speed or machine load hit all methods alike, and no method always follows the same other one.
  /// Every query runs right after another method's, in the cache and branch-predictor state that one left:
  /// the harshest setting for a short query that follows a long one.
  kInterleaved,
  /// Method by method: each repeat runs one method on every pose in turn, then the next method (a random
  /// method order drawn afresh for every repeat), as an application that makes many queries of one kind
  /// does. Each method runs in the state its own previous query left.
  kBlocked,
};

/// The clock's own share of a sample: the median of many empty samples (two reads back to back).
/// Reading the thread's CPU clock is a system call, which costs about as much as a short query (a
/// sphere or box against a mesh); timeMethods subtracts this from every sample so that a ratio compares the
/// methods, not the clock. Measured once per clock per process; thread-safe.
double clockOverheadMicros(Clock clock);

/// Times every method on every pose `repeats` times, in `order`; every method first runs twice untimed to
/// warm caches. One query per sample, less clockOverheadMicros (at least 0).
std::vector<MethodSamples> timeMethods(const std::vector<Eigen::Isometry3d>& poses,
                                       const std::vector<TimedMethod>& methods, int repeats,
                                       Clock clock = Clock::kWall, Order order = Order::kInterleaved);

/// A method whose query depends on the pose's position in a sequence (a warm start from the previous
/// frame's answer): `query(i)` answers pose i.
struct IndexedMethod {
  std::string name;
  std::function<double(std::size_t i)> query;
};

/// timeMethods for `count` indexed poses, with the same orders, warm-up and statistics.
std::vector<MethodSamples> timeIndexedMethods(std::size_t count, const std::vector<IndexedMethod>& methods,
                                              int repeats, Clock clock = Clock::kWall,
                                              Order order = Order::kInterleaved);

/// Mean of `values`; 0 when empty.
double mean(const std::vector<double>& values);

}  // namespace cfl::tool
