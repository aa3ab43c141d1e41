// Google Benchmark suite: precompute time of the CFL voxels per resolution, next to FCL's BVHModel build.
//
// Environment (optional): CFL_BENCH_MESH_A (default: the bundled bunny). Counters per resolution: voxels,
// average CFL length, bytes per voxel and total MB. Wall time (UseRealTime), since the build uses every
// hardware thread.

#include "cfl/cfl_model.h"
#include "cfl/mesh_io.h"
#include "fcl_baseline.h"
#include "tool_support.h"

#include <benchmark/benchmark.h>

#include <cstdlib>
#include <string>

namespace {

const cfl::TriangleMesh& benchMesh() {
  static const cfl::TriangleMesh mesh = [] {
    const char* env = std::getenv("CFL_BENCH_MESH_A");
    return cfl::loadMesh(env != nullptr && *env != '\0' ? std::string(env) : cfl::tool::findDataFile("bunny.obj"));
  }();
  return mesh;
}

void BM_CflBuild(benchmark::State& state) {
  cfl::BuildOptions options;
  options.resolution = int(state.range(0));
  cfl::BuildStatistics stats;
  for (auto _ : state) {
    const cfl::CflModel model = cfl::buildCflModel(benchMesh(), options);
    stats = model.statistics;
    benchmark::DoNotOptimize(model.list_triangles.data());
  }
  state.counters["voxels"] = double(stats.voxel_count);
  state.counters["avg_cfl"] = stats.average_list_length;
  state.counters["bytes/voxel"] = stats.voxel_count > 0 ? double(stats.memory_bytes) / double(stats.voxel_count) : 0;
  state.counters["MB"] = double(stats.memory_bytes) / (1 << 20);
}
BENCHMARK(BM_CflBuild)->Arg(10)->Arg(15)->Arg(20)->Arg(30)->Arg(32)->Arg(64)->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FclBuild(benchmark::State& state) {
  const auto bv = state.range(0) == 0 ? cfl::bench::FclBv::kOBBRSS : cfl::bench::FclBv::kRSS;
  state.SetLabel(cfl::bench::fclBvName(bv));
  for (auto _ : state) {
    cfl::bench::FclModel model(benchMesh(), bv);
    benchmark::DoNotOptimize(&model);
  }
}
BENCHMARK(BM_FclBuild)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
