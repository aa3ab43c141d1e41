// `cfl paper`: Kawachi & Suzuki's Tables 1 and 2, reproduced on the bundled bunny next to the published
// figures.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "commands.h"
#include "fcl_baseline.h"
#include "measure.h"
#include "pose_generator.h"
#include "tool_args.h"
#include "tool_support.h"

#include <cmath>
#include <iostream>

namespace cfl::tool {
namespace {

constexpr const char* kPaperUsage = R"(usage: cfl paper [MESH] [--queries N] [--band F] [--seed S] [--repeats R] [--clock wall|cpu] [--threads T]

Reproduces the paper's two tables (default mesh: the bundled bunny, against itself):

Table 1  CFL voxels at resolutions 10, 15, 20 and 30 (padding 2, as in the paper): voxel count and average
         CFL length, next to the paper's average lengths (29.08, 11.92, 10.90, 6.35). Our resolution counts
         voxels along the longest axis; the other axes get fewer, so our grids have fewer voxels than n^3.
Table 2  Distance queries at the resolution-30 model, CFLs on both meshes as in the paper: mean time, mean
         N_p (triangle pairs tested) and N_v (voxel and bounding-volume tests) for CFL in the paper's mode
         (QueryMode::kPaper), CFL in the default hierarchical mode, and FCL OBBRSS (the PQP-like baseline;
         its N_p/N_v are FCL's own traversal counters num_leaf_tests/num_bv_tests), next to the paper's
         figures (PQP 0.018 s, N_p 105.4, N_v 1781; CFL 0.061 s, N_p 171.6, N_v 7970; 1314-triangle bunny).
         The paper's pose set is not published: we use random poses at a separation of F times the bounding
         box diagonal (default 0.02, short range, where the method is meant to shine).
Every CFL distance is checked against OBBRSS; a difference above 1e-9 of the diagonal fails the run.

  --queries N   poses (default 200)
  --band F      separation as a fraction of the diagonal (default 0.02; 0 = overlapping)
  --seed S      random seed (default 1)
  --repeats R   timed runs per pose and method (default 3)
  --clock C     wall (default) or cpu (the thread's CPU time, steadier on a loaded machine)
  --threads T   CFL build threads (default: all)
)";

struct PaperRow {
  int resolution;
  double average_length;
};
constexpr PaperRow kPaperTable1[] = {{10, 29.08}, {15, 11.92}, {20, 10.90}, {30, 6.35}};

}  // namespace

int runPaper(const std::vector<std::string>& raw, Streams io) {
  const ParsedArgs args = parseArgs(raw, {{"queries"}, {"band"}, {"seed"}, {"repeats"}, {"clock"}, {"threads"}});
  if (args.has("help")) {
    io.out << kPaperUsage;
    return 0;
  }
  if (args.positionals.size() > 1) throw UsageError("expected at most one mesh, got " + std::to_string(args.positionals.size()));
  const int queries = int(parseInteger(args.get("queries").value_or("200"), "--queries", 1, 1000000));
  const double band = parseReal(args.get("band").value_or("0.02"), "--band", 0.0, 100.0);
  const std::uint64_t seed = std::uint64_t(parseInteger(args.get("seed").value_or("1"), "--seed", 0, INT64_MAX));
  const int repeats = int(parseInteger(args.get("repeats").value_or("3"), "--repeats", 1, 1000));
  const std::string clock_name = args.get("clock").value_or("wall");
  if (clock_name != "wall" && clock_name != "cpu") throw UsageError("--clock: expected wall or cpu, got '" + clock_name + "'");
  const Clock clock = clock_name == "cpu" ? Clock::kThreadCpu : Clock::kWall;
  const int threads = int(parseInteger(args.get("threads").value_or("0"), "--threads", 0, 1024));
  const std::string path = args.positionals.empty() ? findDataFile("bunny.obj") : args.positionals[0];
  const TriangleMesh mesh = readMeshArgument(path);

  io.out << format("cfl paper: %s, %zu triangles (the paper's bunny has 1314); CFL's query kernels: %s\n\n",
                   path.c_str(), mesh.triangles.size(), queryKernelsName(activeQueryKernels()));
  io.out << "Table 1: CFL voxels, padding 2\n";
  io.out << format("%-10s %-12s %9s %16s %14s %8s %10s %9s\n", "resolution", "grid", "voxels", "avg CFL (ours)",
                   "avg CFL paper", "longest", "memory MB", "build s");
  io.out.flush();
  CflModel model;
  for (const PaperRow& row : kPaperTable1) {
    BuildOptions options;
    options.resolution = row.resolution;
    options.padding = 2.0;
    options.threads = threads;
    CflModel built = obtainCflModel(path, options, io.err);
    const BuildStatistics& s = built.statistics;
    io.out << format("%-10d %-12s %9lld %16.2f %14.2f %8lld %10.2f %9.3f\n", row.resolution,
                     format("%dx%dx%d", built.regions.root_dims[0], built.regions.root_dims[1], built.regions.root_dims[2]).c_str(),
                     static_cast<long long>(s.voxel_count), s.average_list_length, row.average_length,
                     static_cast<long long>(s.longest_list), double(s.memory_bytes) / (1 << 20), s.build_seconds);
    io.out.flush();
    if (row.resolution == 30) model = std::move(built);
  }

  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  const bench::FclModel obbrss(mesh, bench::FclBv::kOBBRSS);
  const bench::BandPoses poses = bench::generateBandPoses(
      model.geometry.bounds, model.geometry.bounds, band, queries, seed,
      [&](const Eigen::Isometry3d& X_WB) { return bench::fclDistance(obbrss, I, obbrss, X_WB).distance; });
  DistanceOptions paper_mode;
  paper_mode.mode = QueryMode::kPaper;
  // The same model serves as A and B: it is immutable, and the paper measured a bunny against a bunny.
  const std::vector<TimedMethod> methods = {
      {"CFL, paper mode", [&](const Eigen::Isometry3d& X) { return computeDistance(model, I, model, X, paper_mode).distance; }},
      {"CFL, default mode", [&](const Eigen::Isometry3d& X) { return computeDistance(model, I, model, X).distance; }},
      {"FCL OBBRSS", [&](const Eigen::Isometry3d& X) { return bench::fclDistance(obbrss, I, obbrss, X).distance; }},
  };
  const std::vector<MethodSamples> samples = timeMethods(poses.poses, methods, repeats, clock);

  std::vector<double> np[3], nv[3];
  double worst[2] = {0, 0};
  for (std::size_t i = 0; i < poses.poses.size(); ++i) {
    const Eigen::Isometry3d& X = poses.poses[i];
    const DistanceResult paper = computeDistance(model, I, model, X, paper_mode);
    const DistanceResult hierarchical = computeDistance(model, I, model, X);
    const bench::FclCountedDistance fcl = bench::fclCountedDistance(obbrss, I, obbrss, X);
    np[0].push_back(double(paper.counters.triangle_pairs));
    nv[0].push_back(double(paper.counters.voxel_tests));
    np[1].push_back(double(hierarchical.counters.triangle_pairs));
    nv[1].push_back(double(hierarchical.counters.voxel_tests));
    np[2].push_back(double(fcl.triangle_pairs));
    nv[2].push_back(double(fcl.bv_tests));
    for (int m = 0; m < 2; ++m) {
      const double d = std::abs(samples[m].distances[i] - samples[2].distances[i]);
      worst[m] = std::isnan(d) ? INFINITY : std::max(worst[m], d);
    }
  }

  const double diagonal = model.geometry.bounds.diagonal();
  io.out << format("\nTable 2: distance queries, %d random poses at %g of the diagonal apart (median achieved %.4g), "
                   "resolution 30, each timed %d times (%s clock)\n",
                   queries, band, bench::median(poses.distances) / diagonal, repeats, clock_name.c_str());
  io.out << format("%-18s %12s %10s %9s %9s %11s | %-26s\n", "method", "mean time s", "median us", "N_p", "N_v",
                   "vs OBBRSS", "paper (1314 triangles)");
  const char* paper_figures[] = {"CFL  0.061 s  171.6  7970", "(not in the paper)", "PQP  0.018 s  105.4  1781"};
  const double fcl_mean = mean(samples[2].micros);
  for (int m = 0; m < 3; ++m) {
    const double mean_us = mean(samples[m].micros);
    io.out << format("%-18s %12.3g %10.1f %9.1f %9.1f %10.2fx | %s\n", methods[m].name.c_str(), mean_us * 1e-6,
                     bench::median(samples[m].micros), mean(np[m]), mean(nv[m]), mean_us / fcl_mean, paper_figures[m]);
  }
  io.out << format("(vs OBBRSS: mean time relative to FCL OBBRSS; the paper's CFL took %.1fx PQP's time)\n",
                   0.061 / 0.018);
  io.out << format("largest |CFL - OBBRSS| / diagonal: paper mode %.2g, default mode %.2g\n", worst[0] / diagonal,
                   worst[1] / diagonal);
  if (!(worst[0] <= 1e-9 * diagonal && worst[1] <= 1e-9 * diagonal)) {
    io.err << "cfl paper: FAILED: a CFL distance differs from FCL OBBRSS by more than 1e-9 of the diagonal\n";
    return 1;
  }
  return 0;
}

}  // namespace cfl::tool
