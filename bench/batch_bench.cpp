// Throughput of the batch distance API against thread count, and the cost of loading a saved model against
// building it (the reason CFL files exist).
//
//   batch_bench --benchmark_filter=Batch      scaling: compare items_per_second of threads:1 and threads:2
//   batch_bench --benchmark_filter=Bunny64    load vs build, bunny at resolution 64
//
// The mesh is the bundled bunny, found through CFL_DATA_DIR (compile definition, overridden by the
// environment variable of the same name).

#include "cfl/batch_query.h"
#include "cfl/cfl_file.h"
#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/mesh_io.h"

#include <benchmark/benchmark.h>

#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <random>
#include <string>
#include <vector>

#ifndef CFL_DATA_DIR
#define CFL_DATA_DIR "data"
#endif

namespace {

using namespace cfl;

std::string dataPath(const char* file) {
  const char* from_environment = std::getenv("CFL_DATA_DIR");
  return std::string(from_environment ? from_environment : CFL_DATA_DIR) + "/" + file;
}

const TriangleMesh& bunny() {
  static const TriangleMesh mesh = loadMesh(dataPath("bunny.obj"));
  return mesh;
}

CflModel buildBunny(int resolution) {
  BuildOptions options;
  options.resolution = resolution;
  return buildCflModel(bunny(), options);
}

// A planning-like batch: one fixed obstacle A, B (the bunny again, as a rigid part) at poses spread from
// overlapping A to a few diagonals away, so query costs vary as they do along sampled trajectories.
struct BatchScene {
  CflModel a;
  MeshModel b;
  Eigen::Isometry3d X_WA = Eigen::Isometry3d::Identity();
  std::vector<Eigen::Isometry3d> poses;
};

const BatchScene& batchScene() {
  static const BatchScene scene = [] {
    BatchScene s;
    s.a = buildBunny(32);
    s.b = makeMeshModel(bunny());
    std::mt19937_64 rng(1);
    std::normal_distribution<double> gaussian;
    std::uniform_real_distribution<double> uniform(0.0, 1.0);
    const double diagonal = s.a.geometry.bounds.diagonal();
    const Eigen::Vector3d center = s.a.geometry.bounds.center();
    for (int i = 0; i < 512; ++i) {
      Eigen::Quaterniond q(gaussian(rng), gaussian(rng), gaussian(rng), gaussian(rng));
      q.normalize();
      Eigen::Vector3d direction(gaussian(rng), gaussian(rng), gaussian(rng));
      direction.normalize();
      Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
      X_WB.linear() = q.toRotationMatrix();
      X_WB.translation() = center + direction * diagonal * 2.0 * uniform(rng) - X_WB.linear() * center;
      s.poses.push_back(X_WB);
    }
    return s;
  }();
  return scene;
}

// Real time, not CPU time: the point is wall-clock speed-up from more threads.
void BM_BatchDistance(benchmark::State& state) {
  const BatchScene& s = batchScene();
  BatchOptions options;
  options.threads = static_cast<int>(state.range(0));
  std::vector<DistanceResult> results(s.poses.size());
  for (auto _ : state) {
    computeDistances(s.a, s.X_WA, s.b, s.poses.data(), s.poses.size(), results.data(), options);
    benchmark::DoNotOptimize(results.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.poses.size()));
  state.counters["threads"] = options.threads;
}
BENCHMARK(BM_BatchDistance)->Arg(1)->Arg(2)->Arg(4)->UseRealTime()->Unit(benchmark::kMillisecond);

// The same queries in a plain loop: the batch with one thread must cost the same.
void BM_SerialDistanceLoop(benchmark::State& state) {
  const BatchScene& s = batchScene();
  std::vector<DistanceResult> results(s.poses.size());
  for (auto _ : state) {
    for (std::size_t i = 0; i < s.poses.size(); ++i) results[i] = computeDistance(s.a, s.X_WA, s.b, s.poses[i]);
    benchmark::DoNotOptimize(results.data());
  }
  state.SetItemsProcessed(state.iterations() * static_cast<std::int64_t>(s.poses.size()));
}
BENCHMARK(BM_SerialDistanceLoop)->UseRealTime()->Unit(benchmark::kMillisecond);

// Build (all hardware threads, as a user would) against load, from memory and from a file.
void BM_Bunny64Build(benchmark::State& state) {
  for (auto _ : state) benchmark::DoNotOptimize(buildBunny(64));
}
BENCHMARK(BM_Bunny64Build)->Iterations(2)->UseRealTime()->Unit(benchmark::kMillisecond);

const std::vector<unsigned char>& bunny64Bytes() {
  static const std::vector<unsigned char> bytes = serializeCflModel(buildBunny(64));
  return bytes;
}

void BM_Bunny64LoadFromMemory(benchmark::State& state) {
  const std::vector<unsigned char>& bytes = bunny64Bytes();
  for (auto _ : state) benchmark::DoNotOptimize(deserializeCflModel(bytes.data(), bytes.size(), "bunny64"));
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(bytes.size()));
}
BENCHMARK(BM_Bunny64LoadFromMemory)->UseRealTime()->Unit(benchmark::kMillisecond);

void BM_Bunny64LoadFromFile(benchmark::State& state) {
  const std::string path = (std::filesystem::temp_directory_path() / "cfl_batch_bench_bunny64.cfl").string();
  saveCflModel(deserializeCflModel(bunny64Bytes().data(), bunny64Bytes().size(), "bunny64"), path);
  for (auto _ : state) benchmark::DoNotOptimize(loadCflModel(path));
  state.SetBytesProcessed(state.iterations() * static_cast<std::int64_t>(std::filesystem::file_size(path)));
  std::filesystem::remove(path);
}
BENCHMARK(BM_Bunny64LoadFromFile)->UseRealTime()->Unit(benchmark::kMillisecond);

void BM_Bunny64Save(benchmark::State& state) {
  const CflModel model = deserializeCflModel(bunny64Bytes().data(), bunny64Bytes().size(), "bunny64");
  const std::string path = (std::filesystem::temp_directory_path() / "cfl_batch_bench_save.cfl").string();
  for (auto _ : state) saveCflModel(model, path);
  std::filesystem::remove(path);
}
BENCHMARK(BM_Bunny64Save)->UseRealTime()->Unit(benchmark::kMillisecond);

}  // namespace
