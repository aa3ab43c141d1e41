#include "measure.h"

#include "pose_generator.h"

#include <time.h>

#include <algorithm>
#include <chrono>
#include <numeric>
#include <random>

namespace cfl::tool {

namespace {

double nowMicros(Clock clock) {
  if (clock == Clock::kThreadCpu) {
    timespec t{};
    clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
    return double(t.tv_sec) * 1e6 + double(t.tv_nsec) * 1e-3;
  }
  return std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now().time_since_epoch()).count();
}

}  // namespace

double clockOverheadMicros(Clock clock) {
  auto measure = [](Clock c) {
    std::vector<double> empty(20001);
    for (double& sample : empty) {
      const double start = nowMicros(c);
      sample = nowMicros(c) - start;
    }
    return bench::median(empty);
  };
  static const double wall = measure(Clock::kWall);
  static const double cpu = measure(Clock::kThreadCpu);
  return clock == Clock::kThreadCpu ? cpu : wall;
}

std::vector<MethodSamples> timeIndexedMethods(std::size_t count, const std::vector<IndexedMethod>& methods,
                                              int repeats, Clock clock, Order order) {
  const std::size_t m = methods.size();
  std::vector<MethodSamples> out(m);
  if (count == 0 || m == 0) return out;
  repeats = std::max(repeats, 1);
  for (const auto& method : methods) {
    method.query(0);
    method.query(count - 1);
  }
  // Method j's samples: times[j][slot * repeats + r] for repeat r, where the slot is the pose in blocked
  // order and 0 interleaved, which finishes a pose before the next and keeps only its samples.
  const std::size_t slots = order == Order::kBlocked ? count : 1;
  std::vector<std::vector<double>> times(m, std::vector<double>(slots * std::size_t(repeats)));
  for (auto& samples : out) samples.distances.resize(count);
  const double overhead = clockOverheadMicros(clock);
  auto sample = [&](std::size_t j, std::size_t i, int r) {
    const std::size_t slot = slots == 1 ? 0 : i;
    const double start = nowMicros(clock);
    const double d = methods[j].query(i);
    times[j][slot * repeats + r] = std::max(0.0, nowMicros(clock) - start - overhead);
    if (r == 0) out[j].distances[i] = d;
  };
  auto medianOf = [&](std::size_t j, std::size_t slot) {
    const auto first = times[j].begin() + std::ptrdiff_t(slot * repeats);
    return bench::median(std::vector<double>(first, first + repeats));
  };
  // A fresh random order every time. A rotating order would always run the same method right after the
  // same other one, and a method that follows FCL finds the caches full of FCL's data.
  std::vector<std::size_t> methods_order(m);
  std::iota(methods_order.begin(), methods_order.end(), std::size_t(0));
  std::mt19937 rng(12345);
  if (order == Order::kInterleaved) {
    for (std::size_t i = 0; i < count; ++i) {
      for (int r = 0; r < repeats; ++r) {
        std::shuffle(methods_order.begin(), methods_order.end(), rng);
        for (std::size_t j : methods_order) sample(j, i, r);
      }
      for (std::size_t j = 0; j < m; ++j) out[j].micros.push_back(medianOf(j, 0));
    }
  } else {
    for (int r = 0; r < repeats; ++r) {
      std::shuffle(methods_order.begin(), methods_order.end(), rng);
      for (std::size_t j : methods_order) {
        for (std::size_t i = 0; i < count; ++i) sample(j, i, r);
      }
    }
    for (std::size_t j = 0; j < m; ++j) {
      for (std::size_t i = 0; i < count; ++i) out[j].micros.push_back(medianOf(j, i));
    }
  }
  return out;
}

std::vector<MethodSamples> timeMethods(const std::vector<Eigen::Isometry3d>& poses,
                                       const std::vector<TimedMethod>& methods, int repeats, Clock clock, Order order) {
  std::vector<IndexedMethod> indexed;
  indexed.reserve(methods.size());
  for (const auto& method : methods) {
    indexed.push_back({method.name, [&poses, &method](std::size_t i) { return method.query(poses[i]); }});
  }
  return timeIndexedMethods(poses.size(), indexed, repeats, clock, order);
}

double mean(const std::vector<double>& values) {
  if (values.empty()) return 0;
  return std::accumulate(values.begin(), values.end(), 0.0) / double(values.size());
}

}  // namespace cfl::tool
