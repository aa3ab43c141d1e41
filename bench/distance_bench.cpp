// Google Benchmark suite: exact distance queries of CFL against FCL 0.7 OBBRSS and RSS, per separation band,
// on the poses `cfl bench` uses (same generator, same default seed and count, so the figures agree).
//
// Environment (all optional): CFL_BENCH_MESH_A, CFL_BENCH_MESH_B (default: the bundled bunny, B = A),
// CFL_BENCH_RESOLUTION (0 = automatic), CFL_BENCH_QUERIES (poses per band, 200), CFL_BENCH_SEED (1).
// Each benchmark iteration is one query; iterations cycle through the band's poses. Counters: N_p and N_v
// are the mean triangle pairs and voxel/bounding-volume tests per query (FCL's from its traversal
// statistics). Before timing, every CFL answer is checked against OBBRSS; a mismatch above 1e-9 of the
// diagonal marks the benchmark as failed.
//
// moving/CFL_cold|CFL_warm|CFL_cached|OBBRSS: the smooth orbit of `cfl bench --moving` (CFL_BENCH_FRAMES
// frames, 1000, at CFL_BENCH_SEPARATION of the diagonal, 0.01); iterations step through the frames in
// order, CFL_warm passes the previous iteration's triangle pair as hint_triangle_a/b and CFL_cached one
// DistanceCache, as a simulator would.

#include "cfl/cfl_query.h"
#include "cfl/mesh_io.h"
#include "cfl/query_kernels.h"
#include "fcl_baseline.h"
#include "pose_generator.h"
#include "tool_support.h"

#include <benchmark/benchmark.h>

#include <cmath>
#include <cstdlib>
#include <memory>
#include <string>

namespace {

using cfl::bench::FclBv;
using cfl::bench::FclModel;

std::string envOr(const char* name, const std::string& fallback) {
  const char* v = std::getenv(name);
  return v != nullptr && *v != '\0' ? v : fallback;
}

struct Scene {
  cfl::CflModel cfl_a;
  cfl::MeshModel model_b;
  std::unique_ptr<FclModel> obbrss_a, obbrss_b, rss_a, rss_b;
  double diagonal = 0;
};

struct Moving {
  cfl::bench::MovingPoses motion;
  double max_difference = 0;  // |CFL - OBBRSS| over the frames, cold, warm and cached
};

struct Band {
  cfl::bench::BandPoses poses;
  double max_difference = 0;  // |CFL - OBBRSS| over the poses
  double cfl_np = 0, cfl_nv = 0, fcl_np = 0, fcl_nv = 0;
};

const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();

// A timing of wrong answers means nothing: the run is marked failed instead when the CFL answers checked
// before timing differ from OBBRSS's by more than 1e-9 of the diagonal.
bool skipUnlessExact(benchmark::State& state, const Scene& scene, double max_difference) {
  if (max_difference <= 1e-9 * scene.diagonal) return false;
  state.SkipWithError(("CFL differs from OBBRSS by " + std::to_string(max_difference)).c_str());
  return true;
}

void runQueries(benchmark::State& state, const Scene& scene, const Band& band, const std::string& method) {
  if (skipUnlessExact(state, scene, band.max_difference)) return;
  const auto& poses = band.poses.poses;
  std::size_t i = 0;
  for (auto _ : state) {
    const Eigen::Isometry3d& X_WB = poses[i];
    if (method == "CFL") {
      benchmark::DoNotOptimize(cfl::computeDistance(scene.cfl_a, kIdentity, scene.model_b, X_WB).distance);
    } else if (method == "OBBRSS") {
      benchmark::DoNotOptimize(cfl::bench::fclDistance(*scene.obbrss_a, kIdentity, *scene.obbrss_b, X_WB).distance);
    } else {
      benchmark::DoNotOptimize(cfl::bench::fclDistance(*scene.rss_a, kIdentity, *scene.rss_b, X_WB).distance);
    }
    if (++i == poses.size()) i = 0;
  }
  if (method == "CFL") {
    state.counters["N_p"] = band.cfl_np;
    state.counters["N_v"] = band.cfl_nv;
  } else if (method == "OBBRSS") {
    state.counters["N_p"] = band.fcl_np;
    state.counters["N_v"] = band.fcl_nv;
  }
  state.counters["dist/diag"] = band.poses.target_distance / scene.diagonal;
}

void runMoving(benchmark::State& state, const Scene& scene, const Moving& moving, const std::string& method) {
  if (skipUnlessExact(state, scene, moving.max_difference)) return;
  const auto& poses = moving.motion.poses;
  std::size_t i = 0;
  cfl::DistanceOptions hint;
  cfl::DistanceCache cache;
  for (auto _ : state) {
    if (method == "OBBRSS") {
      benchmark::DoNotOptimize(cfl::bench::fclDistance(*scene.obbrss_a, kIdentity, *scene.obbrss_b, poses[i]).distance);
    } else if (method == "CFL_cached") {
      benchmark::DoNotOptimize(cfl::computeDistance(scene.cfl_a, kIdentity, scene.model_b, poses[i], cache).distance);
    } else {
      const cfl::DistanceResult r = cfl::computeDistance(scene.cfl_a, kIdentity, scene.model_b, poses[i], hint);
      benchmark::DoNotOptimize(r.distance);
      if (method == "CFL_warm") {
        hint.hint_triangle_a = r.triangle_a;
        hint.hint_triangle_b = r.triangle_b;
      }
    }
    if (++i == poses.size()) {
      i = 0;
      hint = {};  // the sequence starts over: the last frame is no neighbour of the first
      cache.reset();
    }
  }
  state.counters["dist/diag"] = moving.motion.target_distance / scene.diagonal;
}

}  // namespace

int main(int argc, char** argv) {
  benchmark::Initialize(&argc, argv);
  if (benchmark::ReportUnrecognizedArguments(argc, argv)) return 1;

  static Scene scene;
  static std::vector<Band> bands;
  static Moving moving;
  try {
    const std::string path_a = envOr("CFL_BENCH_MESH_A", cfl::tool::findDataFile("bunny.obj"));
    const std::string path_b = envOr("CFL_BENCH_MESH_B", path_a);
    cfl::BuildOptions options;
    options.resolution = std::atoi(envOr("CFL_BENCH_RESOLUTION", "0").c_str());
    const int queries = std::max(1, std::atoi(envOr("CFL_BENCH_QUERIES", "200").c_str()));
    const std::uint64_t seed = std::strtoull(envOr("CFL_BENCH_SEED", "1").c_str(), nullptr, 10);

    scene.cfl_a = cfl::buildCflModel(cfl::loadMesh(path_a), options);
    scene.model_b = cfl::makeMeshModel(cfl::loadMesh(path_b));
    scene.obbrss_a = std::make_unique<FclModel>(scene.cfl_a.geometry.mesh, FclBv::kOBBRSS);
    scene.obbrss_b = std::make_unique<FclModel>(scene.model_b.mesh, FclBv::kOBBRSS);
    scene.rss_a = std::make_unique<FclModel>(scene.cfl_a.geometry.mesh, FclBv::kRSS);
    scene.rss_b = std::make_unique<FclModel>(scene.model_b.mesh, FclBv::kRSS);
    scene.diagonal = scene.cfl_a.geometry.bounds.diagonal();
    benchmark::AddCustomContext(
        "mesh_a", path_a + " (" + std::to_string(scene.cfl_a.geometry.mesh.triangles.size()) + " triangles)");
    benchmark::AddCustomContext("mesh_b",
                                path_b + " (" + std::to_string(scene.model_b.mesh.triangles.size()) + " triangles)");
    benchmark::AddCustomContext("cfl_resolution", std::to_string(scene.cfl_a.statistics.resolution));
    benchmark::AddCustomContext("cfl_query_kernels", cfl::queryKernelsName(cfl::activeQueryKernels()));

    for (double value : cfl::bench::defaultBands()) {
      Band band;
      band.poses = cfl::bench::generateBandPoses(
          scene.cfl_a.geometry.bounds, scene.model_b.bounds, value, queries, seed, [](const Eigen::Isometry3d& X) {
            return cfl::bench::fclDistance(*scene.obbrss_a, kIdentity, *scene.obbrss_b, X).distance;
          });
      const double n = double(band.poses.poses.size());
      for (const auto& X : band.poses.poses) {
        const cfl::DistanceResult c = cfl::computeDistance(scene.cfl_a, kIdentity, scene.model_b, X);
        const double f = cfl::bench::fclDistance(*scene.obbrss_a, kIdentity, *scene.obbrss_b, X).distance;
        const double d = std::abs(c.distance - f);
        band.max_difference = std::isnan(d) ? INFINITY : std::max(band.max_difference, d);
        band.cfl_np += double(c.counters.triangle_pairs) / n;
        band.cfl_nv += double(c.counters.voxel_tests) / n;
        const auto counted = cfl::bench::fclCountedDistance(*scene.obbrss_a, kIdentity, *scene.obbrss_b, X);
        band.fcl_np += double(counted.triangle_pairs) / n;
        band.fcl_nv += double(counted.bv_tests) / n;
      }
      bands.push_back(std::move(band));
    }
    const int frames = std::max(1, std::atoi(envOr("CFL_BENCH_FRAMES", "1000").c_str()));
    const double separation = std::atof(envOr("CFL_BENCH_SEPARATION", "0.01").c_str());
    moving.motion = cfl::bench::generateMovingPoses(
        scene.cfl_a.geometry.bounds, scene.model_b.bounds, separation, frames, seed, [](const Eigen::Isometry3d& X) {
          return cfl::bench::fclDistance(*scene.obbrss_a, kIdentity, *scene.obbrss_b, X).distance;
        });
    cfl::DistanceOptions hint;
    cfl::DistanceCache cache;
    for (const auto& X : moving.motion.poses) {
      const double f = cfl::bench::fclDistance(*scene.obbrss_a, kIdentity, *scene.obbrss_b, X).distance;
      const cfl::DistanceResult cold = cfl::computeDistance(scene.cfl_a, kIdentity, scene.model_b, X);
      const cfl::DistanceResult warm = cfl::computeDistance(scene.cfl_a, kIdentity, scene.model_b, X, hint);
      hint.hint_triangle_a = warm.triangle_a;
      hint.hint_triangle_b = warm.triangle_b;
      const cfl::DistanceResult cached = cfl::computeDistance(scene.cfl_a, kIdentity, scene.model_b, X, cache);
      for (double d : {std::abs(cold.distance - f), std::abs(warm.distance - f), std::abs(cached.distance - f)}) {
        moving.max_difference = std::isnan(d) ? INFINITY : std::max(moving.max_difference, d);
      }
    }
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cfl_distance_bench: %s\n", e.what());
    return 1;
  }

  for (const Band& band : bands) {
    for (const char* method : {"CFL", "OBBRSS", "RSS"}) {
      char name[96];
      std::snprintf(name, sizeof name, "distance/band:%g/%s", band.poses.band, method);
      benchmark::RegisterBenchmark(name, [&band, method](benchmark::State& state) {
        runQueries(state, scene, band, method);
      })->Unit(benchmark::kMicrosecond);
    }
  }
  for (const char* method : {"CFL_cold", "CFL_warm", "CFL_cached", "OBBRSS"}) {
    benchmark::RegisterBenchmark((std::string("moving/") + method).c_str(), [method](benchmark::State& state) {
      runMoving(state, scene, moving, method);
    })->Unit(benchmark::kMicrosecond);
  }
  benchmark::RunSpecifiedBenchmarks();
  benchmark::Shutdown();
  return 0;
}
