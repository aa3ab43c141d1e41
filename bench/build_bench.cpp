// Google Benchmark suite: precompute time of the CFL regions (0: adaptive; N: uniform grid of N cells), next to
// FCL's BVHModel build.
//
// Environment (optional): CFL_BENCH_MESH_A (default: the bundled bunny). Counters per resolution: leaves,
// average CFL length, bytes per triangle and total MB. Wall time (UseRealTime), since the build uses every
// hardware thread. BM_CflBuildDenseKnot builds a generated 100,000-triangle mesh, the size of a fine CAD or
// scanned part, one iteration per run (add --benchmark_repetitions=3 for a median).

#include "cfl/cfl_model.h"
#include "cfl/mesh_io.h"
#include "fcl_baseline.h"
#include "tool_support.h"

#include <Eigen/Geometry>
#include <benchmark/benchmark.h>

#include <cmath>
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

// A closed tube of radius 0.3 around the (2, 3) torus knot, `segments` rings of `tube_segments` vertices:
// 2 * segments * tube_segments triangles, close to equilateral at 1000 x 50, with distant parts of the
// surface close in space (the knot's crossings).
cfl::TriangleMesh makeDenseTorusKnot(int segments, int tube_segments) {
  const double pi = std::acos(-1.0);
  auto curve = [](double t) {
    const double r = 2 + std::cos(3 * t);
    return Eigen::Vector3d(r * std::cos(2 * t), r * std::sin(2 * t), -std::sin(3 * t));
  };
  cfl::TriangleMesh mesh;
  for (int i = 0; i < segments; ++i) {
    const double t = 2 * pi * i / segments;
    const Eigen::Vector3d center = curve(t);
    const Eigen::Vector3d tangent = (curve(t + 1e-4) - curve(t - 1e-4)).normalized();
    // The knot never heads toward the z axis, so its horizontal position is never along the tangent.
    const Eigen::Vector3d binormal = tangent.cross(Eigen::Vector3d(center.x(), center.y(), 0)).normalized();
    const Eigen::Vector3d normal = binormal.cross(tangent);
    for (int j = 0; j < tube_segments; ++j) {
      const double phi = 2 * pi * j / tube_segments;
      mesh.vertices.push_back(center + 0.3 * (std::cos(phi) * normal + std::sin(phi) * binormal));
    }
  }
  auto index = [&](int i, int j) { return (i % segments) * tube_segments + (j % tube_segments); };
  for (int i = 0; i < segments; ++i) {
    for (int j = 0; j < tube_segments; ++j) {
      mesh.triangles.push_back({index(i, j), index(i + 1, j), index(i + 1, j + 1)});
      mesh.triangles.push_back({index(i, j), index(i + 1, j + 1), index(i, j + 1)});
    }
  }
  return mesh;
}

void runBuild(benchmark::State& state, const cfl::TriangleMesh& mesh) {
  cfl::BuildOptions options;
  options.resolution = int(state.range(0));
  cfl::BuildStatistics stats;
  for (auto _ : state) {
    const cfl::CflModel model = cfl::buildCflModel(mesh, options);
    stats = model.statistics;
    benchmark::DoNotOptimize(model.regions.list_entry_ids.data());
  }
  state.counters["triangles"] = double(mesh.triangles.size());
  state.counters["leaves"] = double(stats.voxel_count);
  state.counters["avg_cfl"] = stats.average_list_length;
  state.counters["bytes/triangle"] = double(stats.memory_bytes) / double(mesh.triangles.size());
  state.counters["MB"] = double(stats.memory_bytes) / (1 << 20);
}

void BM_CflBuild(benchmark::State& state) { runBuild(state, benchMesh()); }
BENCHMARK(BM_CflBuild)->Arg(0)->Arg(10)->Arg(15)->Arg(20)->Arg(30)->Arg(32)->Arg(64)
    ->Unit(benchmark::kMillisecond)->UseRealTime();

void BM_FclBuild(benchmark::State& state) {
  const auto bv = state.range(0) == 0 ? cfl::bench::FclBv::kOBBRSS : cfl::bench::FclBv::kRSS;
  state.SetLabel(cfl::bench::fclBvName(bv));
  for (auto _ : state) {
    cfl::bench::FclModel model(benchMesh(), bv);
    benchmark::DoNotOptimize(&model);
  }
}
void BM_CflBuildDenseKnot(benchmark::State& state) {
  static const cfl::TriangleMesh mesh = makeDenseTorusKnot(1000, 50);
  runBuild(state, mesh);
}
BENCHMARK(BM_CflBuildDenseKnot)->Arg(64)->Iterations(1)->Unit(benchmark::kMillisecond)->UseRealTime();

BENCHMARK(BM_FclBuild)->Arg(0)->Arg(1)->Unit(benchmark::kMillisecond)->UseRealTime();

}  // namespace

BENCHMARK_MAIN();
