// The C++ side of python/bench/bench_overhead.py: times the calls the Python benchmark times, made directly from
// C++, on the same model files and poses, so that the difference is what the Python binding costs.
//
//   cfl_python_overhead_reference A.cfl B.cfl POSES.f64 SINGLE REPEATS BLOCKS THREADS DISTANCES_OUT
//
// POSES.f64 holds N row-major 4x4 float64 matrices X_WB (A is at the identity). For each of the first
// SINGLE poses, REPEATS consecutive cfl::computeDistance calls are timed together BLOCKS times; the median
// block, divided by REPEATS, is that pose's time per call. Then one cfl::computeDistances over all N poses
// with THREADS threads is timed. Prints one JSON object: {"single_ns": [...], "batch_seconds": s}; writes
// the batch's N distances as float64 to DISTANCES_OUT, so the benchmark can check both sides answered the
// same. Wall time (steady_clock), as the Python side measures.

#include <Eigen/Geometry>
#include <algorithm>
#include <chrono>
#include <cstdio>
#include <cstdlib>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

#include "cfl/batch_query.h"
#include "cfl/cfl_file.h"
#include "cfl/cfl_query.h"

namespace {

double median(std::vector<double> values) {
  std::sort(values.begin(), values.end());
  const std::size_t n = values.size();
  return n % 2 ? values[n / 2] : 0.5 * (values[n / 2 - 1] + values[n / 2]);
}

std::vector<Eigen::Isometry3d> readPoses(const std::string& path) {
  std::ifstream file(path, std::ios::binary);
  std::vector<double> values;
  double value;
  while (file.read(reinterpret_cast<char*>(&value), sizeof value)) values.push_back(value);
  if (values.empty() || values.size() % 16 != 0) {
    std::cerr << path << ": expected a whole number of 4x4 float64 matrices\n";
    std::exit(2);
  }
  std::vector<Eigen::Isometry3d> poses(values.size() / 16);
  for (std::size_t i = 0; i < poses.size(); ++i) {
    poses[i].matrix() = Eigen::Map<const Eigen::Matrix<double, 4, 4, Eigen::RowMajor>>(values.data() + 16 * i);
  }
  return poses;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 9) {
    std::cerr << "usage: " << argv[0] << " A.cfl B.cfl POSES.f64 SINGLE REPEATS BLOCKS THREADS DISTANCES_OUT\n";
    return 2;
  }
  try {
    const cfl::CflModel a = cfl::loadCflModel(argv[1]);
    const cfl::CflModel b = cfl::loadCflModel(argv[2]);
    const std::vector<Eigen::Isometry3d> poses = readPoses(argv[3]);
    const std::size_t single = std::min<std::size_t>(std::stoul(argv[4]), poses.size());
    const int repeats = std::stoi(argv[5]);
    const int blocks = std::stoi(argv[6]);
    const Eigen::Isometry3d X_WA = Eigen::Isometry3d::Identity();
    using Clock = std::chrono::steady_clock;

    // What the Python side's cfl.distance(a, X_WA, b, X_WB) runs: the CflModel-CflModel overload with
    // default options. The sum keeps the calls from being optimized away.
    double sink = 0;
    std::vector<double> single_ns;
    for (std::size_t i = 0; i < single; ++i) {
      std::vector<double> block_ns;
      for (int block = 0; block < blocks; ++block) {
        const auto start = Clock::now();
        for (int r = 0; r < repeats; ++r) sink += cfl::computeDistance(a, X_WA, b, poses[i]).distance;
        block_ns.push_back(std::chrono::duration<double, std::nano>(Clock::now() - start).count() / repeats);
      }
      single_ns.push_back(median(block_ns));
    }

    cfl::BatchOptions options;
    options.threads = std::stoi(argv[7]);
    std::vector<cfl::DistanceResult> results(poses.size());
    const auto start = Clock::now();
    cfl::computeDistances(a, X_WA, b, poses.data(), poses.size(), results.data(), options);
    const double batch_seconds = std::chrono::duration<double>(Clock::now() - start).count();

    std::ofstream out(argv[8], std::ios::binary);
    for (const cfl::DistanceResult& result : results)
      out.write(reinterpret_cast<const char*>(&result.distance), sizeof(double));

    std::printf("{\"single_ns\": [");
    for (std::size_t i = 0; i < single_ns.size(); ++i) std::printf("%s%.1f", i ? ", " : "", single_ns[i]);
    std::printf("], \"batch_seconds\": %.6f, \"sink\": %.17g}\n", batch_seconds, sink);
  } catch (const std::exception& error) {
    std::cerr << error.what() << "\n";
    return 1;
  }
  return 0;
}
