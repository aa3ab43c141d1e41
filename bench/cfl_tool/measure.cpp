#include "measure.h"

#include "pose_generator.h"

#include <chrono>
#include <numeric>

namespace cfl::tool {

std::vector<MethodSamples> timeMethods(const std::vector<Eigen::Isometry3d>& poses,
                                       const std::vector<TimedMethod>& methods, int repeats) {
  const std::size_t m = methods.size();
  std::vector<MethodSamples> out(m);
  if (poses.empty() || m == 0) return out;
  repeats = std::max(repeats, 1);
  for (const auto& method : methods) {
    method.query(poses.front());
    method.query(poses.back());
  }
  std::vector<std::vector<double>> times(m);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    for (auto& t : times) t.clear();
    for (int r = 0; r < repeats; ++r) {
      for (std::size_t k = 0; k < m; ++k) {
        const std::size_t j = (i + std::size_t(r) + k) % m;
        const auto start = std::chrono::steady_clock::now();
        const double d = methods[j].query(poses[i]);
        const auto stop = std::chrono::steady_clock::now();
        times[j].push_back(std::chrono::duration<double, std::micro>(stop - start).count());
        if (r == 0) out[j].distances.push_back(d);
      }
    }
    for (std::size_t j = 0; j < m; ++j) out[j].micros.push_back(bench::median(times[j]));
  }
  return out;
}

double mean(const std::vector<double>& values) {
  if (values.empty()) return 0;
  return std::accumulate(values.begin(), values.end(), 0.0) / double(values.size());
}

}  // namespace cfl::tool
