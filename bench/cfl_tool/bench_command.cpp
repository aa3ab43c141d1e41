// `cfl bench`: CFL against FCL 0.7 BVHModel<OBBRSS> and BVHModel<RSS>, in one process, on the same poses.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "bench_sections.h"
#include "commands.h"
#include "fcl_baseline.h"
#include "heap.h"
#include "measure.h"
#include "pose_generator.h"
#include "referee.h"
#include "tool_args.h"
#include "tool_support.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <iostream>

extern char** environ;

namespace cfl::tool {
namespace {

constexpr const char* kBenchUsage = R"(usage: cfl bench [A [B]] [--queries N] [--bands LIST] [--resolution N] [--seed S]
                 [--repeats R] [--clock wall|cpu] [--order interleaved|blocked] [--threads T]
                 [--json OUT.json] [--plot OUT.png]
                 [--moving FRAMES [--separation F]] [--rel-err E] [--abs-err A]
                 [--points N] [--shapes N] [--penetration N] [--no-table]

Times exact mesh-mesh distance queries of CFL (A's voxels, B as a plain mesh with its Bvh) against FCL 0.7
fcl::distance on BVHModel<OBBRSS> and BVHModel<RSS> (enable_nearest_points = true), in one process, on the
same poses. Without meshes: the bundled bunny against itself; with A only: A against itself.

Poses: per band, N random rotations and directions of B about A; the offset along the direction is set by
bisection so that the FCL OBBRSS distance is the band's fraction of A's bounding-box diagonal (within 1%);
band 0 means overlapping. Every query's CFL distance is checked against OBBRSS, and where the two differ by
more than 1e-9 of the diagonal, against brute force over all triangle pairs, which decides: the run FAILS
(status 1) if CFL is the one off; if OBBRSS is, a note under the table counts those poses (FCL 0.7 ignores
vertex-face contacts of triangles with edges under about 2e-4 units, so meshes that small trip it).

Columns, per band:
  dist/diag        median achieved distance / A's bounding-box diagonal
  CFL, OBBRSS, RSS median and 90th percentile of the microseconds per query (each pose timed R times per
                   method, in --order, less the clock's own cost per sample, measured and printed
                   above the table; the per-pose median enters the statistics)
  OBBRSS/CFL       median OBBRSS time / median CFL time (> 1: CFL is faster)
  CFL N_p, N_v     mean triangle pairs tested and voxel + bounding-volume tests per CFL query
  FCL N_p, N_v     the same for OBBRSS, counted by FCL's own traversal statistics (num_leaf_tests,
                   num_bv_tests) in a separate untimed run of the same traversal
  max|d|/diag      largest |CFL - reference| / diagonal; the reference is OBBRSS's distance, or brute
                   force's where OBBRSS disagrees with CFL

  --queries N      poses per band (default 200)
  --bands LIST     comma-separated fractions of the diagonal (default 0,0.005,0.02,0.1,0.5)
  --resolution N   0 (default): adaptive regions; N > 0: a uniform grid of N cells
  --seed S         random seed (default 1); the same seed gives the same poses here and in the
                   Google Benchmark suite cfl_distance_bench
  --repeats R      timed runs per pose and method (default 3)
  --clock C        wall (default): elapsed time; cpu: the thread's CPU time, steadier on a loaded machine
  --order O        interleaved (default): pose by pose, the methods in a fresh random order, so every query
                   runs right after another method's, in the caches and branch predictor state it left;
                   blocked: each repeat runs one method on all poses, then the next (random method order),
                   as an application making many queries of one kind does
  --threads T      CFL build threads (default: all)
  --json OUT       also write every figure as JSON
  --plot OUT.png   also draw median time per band and method on a log axis (needs gnuplot)

Extra sections, printed after the table only when asked for:
  --moving FRAMES  moving objects: B orbits A once and turns twice over FRAMES frames, resting at a gap of
                   --separation (fraction of A's diagonal, default 0.01; set by sphere tracing on OBBRSS
                   distances). Times per frame: CFL cold (no hint), CFL warm (hint_triangle_a/b = the previous
                   frame's warm answer, the first frame cold), CFL cached (a DistanceCache carried from frame
                   to frame; each timed query starts from the cache the previous frame left) and OBBRSS.
                   Every CFL answer is checked against OBBRSS (1e-9 of the diagonal). Reports medians, p90,
                   means, N_p and the speedups.
  --rel-err E      approximate queries: on each band's poses, CFL with DistanceOptions::rel_err = E and
  --abs-err A      abs_err = A (mesh units; default 0) next to exact CFL and OBBRSS. Pruning follows FCL's
                   rule, which needs BOTH conditions (lb >= best - A and lb * (1 + E) >= best): with A = 0,
                   rel_err alone buys nothing; pass a large A (e.g. the diagonal) to see rel_err's effect
                   alone. Checks true <= d <= min(true * (1 + E), true + A) (+ 1e-9 of the diagonal) with
                   true = OBBRSS's exact distance; FCL 0.7 ignores both for mesh-mesh distance.
  --points N       point queries: N points within 5% of the diagonal of A's surface and N uniform in
                   twice A's box; CFL per point (unsigned; signed too when A is closed) and the whole set
                   through computePointDistances on all threads, against FCL's distance of a sphere of radius
                   0 to A's BVHModel<OBBRSS>. Checked against FCL, brute force deciding (1e-9 of the
                   diagonal). Open3D, the issue's peer for points, is in cfl_point_bench.
  --shapes N       a sphere (radius 0.02 diagonals), a capsule (radius 0.01, length 0.05) and a box (0.03 x
                   0.02 x 0.015) at N poses per positive band (--bands, default 0.005,0.02 here), at exact
                   distances: the core's point, segment and box queries against FCL's fcl::distance of the
                   shape to A's BVHModel<OBBRSS>; where they differ by more than 1e-9 of the diagonal
                   (FCL's GJK tolerance on capsules and boxes), brute force decides ("FCL off" counts FCL's
                   misses; CFL off fails). Through the FCL adapter: cfl_shape_bench.
  --penetration N  A against itself at N overlapping poses: computePenetration (the bodies' depth,
                   certified to 1e-4 of the diagonal) against fcl::collide with contacts (first contact,
                   every contact); checks each interval's width and witness points. Skipped when A is not
                   closed.
  --no-table       skip the per-band table (to run only the sections asked for)
)";

struct BandReport {
  double band = 0;
  double target = 0;
  double achieved_median = 0;
  struct Figures {
    double median_us = 0, p90_us = 0;
    double mean_np = -1, mean_nv = -1;  // -1: not counted
  };
  Figures cfl, obbrss, rss;
  double speedup = 0;
  double max_difference = 0;  // from the reference (Referee)
  int fcl_errors = 0;         // poses where brute force found OBBRSS off
  double largest_fcl_error = 0;
};

std::string findExecutable(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::string dirs = path != nullptr ? path : "/usr/bin:/bin";
  std::size_t start = 0;
  while (start <= dirs.size()) {
    const std::size_t colon = dirs.find(':', start);
    std::string dir = dirs.substr(start, colon == std::string::npos ? std::string::npos : colon - start);
    if (dir.empty()) dir = ".";
    const std::string candidate = dir + "/" + name;
    if (::access(candidate.c_str(), X_OK) == 0) return candidate;
    if (colon == std::string::npos) break;
    start = colon + 1;
  }
  return "";
}

std::string jsonString(const std::string& s) {
  std::string out = "\"";
  for (char c : s) {
    if (c == '"' || c == '\\') {
      out += '\\';
      out += c;
    } else if (static_cast<unsigned char>(c) < 0x20) {
      out += format("\\u%04x", c);
    } else {
      out += c;
    }
  }
  return out + "\"";
}

std::string jsonNumber(double v) { return std::isfinite(v) ? format("%.9g", v) : "null"; }

void writePlot(const std::string& png, const std::vector<BandReport>& bands, const std::string& title) {
  const std::string gnuplot = findExecutable("gnuplot");
  if (gnuplot.empty()) {
    throw Error("--plot needs gnuplot, which is not in PATH (Debian: apt-get install gnuplot-nox)");
  }
  const std::string data_path = png + ".dat";
  const std::string script_path = png + ".gp";
  {
    std::ofstream data(data_path);
    data << "# band cfl_median cfl_p90 obbrss_median obbrss_p90 rss_median rss_p90 (microseconds)\n";
    for (const auto& b : bands) {
      data << format("%g %.6g %.6g %.6g %.6g %.6g %.6g\n", b.band, b.cfl.median_us, b.cfl.p90_us, b.obbrss.median_us,
                     b.obbrss.p90_us, b.rss.median_us, b.rss.p90_us);
    }
    if (!data) throw Error(data_path + ": cannot write the plot data");
  }
  {
    std::ofstream script(script_path);
    script << "set terminal pngcairo size 900,560 enhanced font 'Sans,11'\n"
           << "set output '" << png << "'\n"
           << "set title " << jsonString(title) << "\n"
           << "set logscale y\n"
           << "set ylabel 'microseconds per query (median; bar to p90)'\n"
           << "set xlabel 'separation band (fraction of the bounding-box diagonal; 0 = overlapping)'\n"
           << "set grid ytics mytics\n"
           << "set key top left box opaque\n"
           << "set offsets 0.3, 0.3, 0, 0\n"
           << "plot '" << data_path << "' using ($0-0.1):2:2:3 with yerrorlines lw 2 pt 7 title 'CFL', \\\n"
           << "     '' using ($0):4:4:5:xtic(1) with yerrorlines lw 2 pt 5 title 'FCL OBBRSS', \\\n"
           << "     '' using ($0+0.1):6:6:7 with yerrorlines lw 2 pt 9 title 'FCL RSS'\n";
    if (!script) throw Error(script_path + ": cannot write the gnuplot script");
  }
  pid_t pid = 0;
  std::vector<char*> argv = {const_cast<char*>(gnuplot.c_str()), const_cast<char*>(script_path.c_str()), nullptr};
  if (posix_spawn(&pid, gnuplot.c_str(), nullptr, nullptr, argv.data(), environ) != 0) {
    throw Error("could not start " + gnuplot);
  }
  int status = 0;
  if (waitpid(pid, &status, 0) < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw Error("gnuplot failed on " + script_path + " (kept for inspection)");
  }
  std::remove(script_path.c_str());
  std::remove(data_path.c_str());
}

}  // namespace

int runBench(const std::vector<std::string>& raw, Streams io) {
  const ParsedArgs args = parseArgs(
      raw, {{"queries"}, {"bands"}, {"resolution"}, {"seed"}, {"repeats"}, {"clock"}, {"order"}, {"threads"}, {"json"},
            {"plot"}, {"moving"}, {"separation"}, {"rel-err"}, {"abs-err"}, {"points"}, {"shapes"}, {"penetration"},
            {"no-table", false}});
  if (args.has("help")) {
    io.out << kBenchUsage;
    return 0;
  }
  if (args.positionals.size() > 2) throw UsageError("expected at most two meshes, got " + std::to_string(args.positionals.size()));
  const int queries = int(parseInteger(args.get("queries").value_or("200"), "--queries", 1, 1000000));
  const std::vector<double> bands =
      args.has("bands") ? parseBandList(*args.get("bands"), "--bands") : bench::defaultBands();
  const std::uint64_t seed = std::uint64_t(parseInteger(args.get("seed").value_or("1"), "--seed", 0, INT64_MAX));
  const int repeats = int(parseInteger(args.get("repeats").value_or("3"), "--repeats", 1, 1000));
  const std::string clock_name = args.get("clock").value_or("wall");
  if (clock_name != "wall" && clock_name != "cpu") throw UsageError("--clock: expected wall or cpu, got '" + clock_name + "'");
  const Clock clock = clock_name == "cpu" ? Clock::kThreadCpu : Clock::kWall;
  const std::string order_name = args.get("order").value_or("interleaved");
  if (order_name != "interleaved" && order_name != "blocked") {
    throw UsageError("--order: expected interleaved or blocked, got '" + order_name + "'");
  }
  const Order order = order_name == "blocked" ? Order::kBlocked : Order::kInterleaved;
  BuildOptions options;
  options.resolution = int(parseInteger(args.get("resolution").value_or("0"), "--resolution", 0, 4096));
  options.threads = int(parseInteger(args.get("threads").value_or("0"), "--threads", 0, 1024));
  const int moving_frames = int(parseInteger(args.get("moving").value_or("0"), "--moving", 0, 10000000));
  if (args.has("separation") && moving_frames == 0) throw UsageError("--separation needs --moving FRAMES");
  const double separation = parseReal(args.get("separation").value_or("0.01"), "--separation", 1e-9, 10);
  const bool approximate = args.has("rel-err") || args.has("abs-err");
  DistanceOptions approximate_options;
  approximate_options.rel_err = parseReal(args.get("rel-err").value_or("0"), "--rel-err", 0, 1e9);
  approximate_options.abs_err = parseReal(args.get("abs-err").value_or("0"), "--abs-err", 0, 1e300);
  const int point_count = int(parseInteger(args.get("points").value_or("0"), "--points", 0, 100000000));
  const int shape_poses = int(parseInteger(args.get("shapes").value_or("0"), "--shapes", 0, 1000000));
  const int penetration_poses = int(parseInteger(args.get("penetration").value_or("0"), "--penetration", 0, 1000000));
  const bool table = !args.has("no-table");
  if (!table && moving_frames == 0 && !approximate && point_count == 0 && shape_poses == 0 && penetration_poses == 0) {
    throw UsageError("--no-table leaves nothing to run without --moving, --rel-err/--abs-err, --points, --shapes or --penetration");
  }
  const auto json_path = args.get("json");
  const auto plot_path = args.get("plot");
  if ((json_path || plot_path) && !table) throw UsageError("--json and --plot describe the table; drop --no-table");
  if (plot_path && findExecutable("gnuplot").empty()) {
    throw Error("--plot needs gnuplot, which is not in PATH (Debian: apt-get install gnuplot-nox)");
  }

  const std::string path_a = args.positionals.empty() ? findDataFile("bunny.obj") : args.positionals[0];
  const std::string path_b = args.positionals.size() < 2 ? path_a : args.positionals[1];
  // Before the build: a bad CFL_KERNELS fails here, not after it.
  const char* kernels = queryKernelsName(activeQueryKernels());

  // Each model's heap counts its own copy of the mesh, as FCL's BVHModel copies A's arrays (see heap.h).
  const auto cfl_measured = measureHeap([&] { return obtainCflModel(path_a, options, io.err); });
  const CflModel& cfl_a = cfl_measured.first;
  const TriangleMesh& mesh_a = cfl_a.geometry.mesh;
  auto start = std::chrono::steady_clock::now();
  const MeshModel model_b = makeMeshModel(readMeshArgument(path_b));
  const double model_b_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  const auto obbrss_measured = measureHeap([&] { return bench::FclModel(mesh_a, bench::FclBv::kOBBRSS); });
  const bench::FclModel& obbrss_a = obbrss_measured.first;
  const bench::FclModel obbrss_b(model_b.mesh, bench::FclBv::kOBBRSS);
  const bench::FclModel rss_a(mesh_a, bench::FclBv::kRSS), rss_b(model_b.mesh, bench::FclBv::kRSS);
  const double diagonal = cfl_a.geometry.bounds.diagonal();
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();

  io.out << format("cfl bench: A = %s (%zu triangles), B = %s (%zu triangles), A's diagonal %g\n", path_a.c_str(),
                   mesh_a.triangles.size(), path_b.c_str(), model_b.mesh.triangles.size(), diagonal);
  io.out << format("build: CFL %.3f s (%s regions, %d levels, %lld leaves, avg CFL %.2f, %.1f MB); B's mesh model %.4f s; "
                   "FCL OBBRSS %.4f s; FCL RSS %.4f s (A's structure; B's took %.4f s and %.4f s)\n",
                   cfl_a.statistics.build_seconds, cfl_a.regions.max_depth > 0 ? "adaptive" : "uniform",
                   cfl_a.regions.max_depth + 1, static_cast<long long>(cfl_a.statistics.voxel_count),
                   cfl_a.statistics.average_list_length, double(cfl_a.statistics.memory_bytes) / (1 << 20),
                   model_b_seconds, obbrss_a.buildSeconds(),
                   rss_a.buildSeconds(), obbrss_b.buildSeconds(), rss_b.buildSeconds());
  const double triangles_a = double(mesh_a.triangles.size());
  io.out << format("heap (mallinfo2, what building A's model adds): CFL %.0f bytes per triangle (%.1f MB), "
                   "FCL OBBRSS %.0f bytes per triangle (%.1f MB)\n",
                   double(cfl_measured.second) / triangles_a, double(cfl_measured.second) / (1 << 20),
                   double(obbrss_measured.second) / triangles_a, double(obbrss_measured.second) / (1 << 20));
  // The table and the approximate section time --queries poses per band; the other sections say their own counts.
  if (!table && !approximate) {
    io.out << format("CFL's query kernels: %s\n\n", kernels);
  } else {
    io.out << format("queries: %d poses per band, seed %llu, each timed %d times per method (%s), "
                     "%s microseconds per query (less the clock's own %.3f us per sample); CFL's query kernels: %s\n\n",
                     queries, static_cast<unsigned long long>(seed), repeats,
                     order == Order::kBlocked ? "blocked: each method on all poses in turn" : "interleaved pose by pose",
                     clock == Clock::kWall ? "wall" : "thread CPU", clockOverheadMicros(clock), kernels);
  }
  if (table) {
    io.out << format("%-7s %9s | %8s %8s | %8s %8s | %8s %8s | %10s | %8s %8s | %8s %8s | %11s\n", "band",
                     "dist/diag", "CFL med", "p90", "OBBRSS", "p90", "RSS", "p90", "OBBRSS/CFL", "CFL N_p", "N_v",
                     "FCL N_p", "N_v", "max|d|/diag");
    io.out.flush();
  }

  const bench::DistanceFunction baseline = [&](const Eigen::Isometry3d& X_WB) {
    return bench::fclDistance(obbrss_a, I, obbrss_b, X_WB).distance;
  };
  std::vector<TimedMethod> methods = {
      {"CFL", [&](const Eigen::Isometry3d& X_WB) { return computeDistance(cfl_a, I, model_b, X_WB).distance; }},
      {"OBBRSS", [&](const Eigen::Isometry3d& X_WB) { return bench::fclDistance(obbrss_a, I, obbrss_b, X_WB).distance; }},
      {"RSS", [&](const Eigen::Isometry3d& X_WB) { return bench::fclDistance(rss_a, I, rss_b, X_WB).distance; }},
  };

  std::vector<BandReport> reports;
  std::vector<bench::BandPoses> band_poses;  // kept for the --rel-err section
  bool passed = true;
  for (double band : bands) {
    if (!table && !approximate) break;
    band_poses.push_back(bench::generateBandPoses(cfl_a.geometry.bounds, model_b.bounds, band, queries, seed, baseline));
    const bench::BandPoses& poses = band_poses.back();
    if (!table) continue;
    const std::vector<MethodSamples> samples = timeMethods(poses.poses, methods, repeats, clock, order);
    BandReport r;
    r.band = band;
    r.target = poses.target_distance;
    r.achieved_median = bench::median(poses.distances);
    BandReport::Figures* figures[] = {&r.cfl, &r.obbrss, &r.rss};
    for (int m = 0; m < 3; ++m) {
      figures[m]->median_us = bench::median(samples[m].micros);
      figures[m]->p90_us = bench::percentile(samples[m].micros, 0.9);
    }
    std::vector<double> cfl_np, cfl_nv, fcl_np, fcl_nv;
    Referee referee(cfl_a.geometry, model_b, 1e-9 * diagonal);
    for (std::size_t i = 0; i < poses.poses.size(); ++i) {
      const double cfl = samples[0].distances[i];
      const double reference = referee.reference(poses.poses[i], samples[1].distances[i], {cfl});
      r.max_difference = std::max(r.max_difference, std::abs(cfl - reference));
      if (std::isnan(cfl)) r.max_difference = INFINITY;
      const DistanceResult counted = computeDistance(cfl_a, I, model_b, poses.poses[i]);
      cfl_np.push_back(double(counted.counters.triangle_pairs));
      cfl_nv.push_back(double(counted.counters.voxel_tests));
      const bench::FclCountedDistance fcl = bench::fclCountedDistance(obbrss_a, I, obbrss_b, poses.poses[i]);
      fcl_np.push_back(double(fcl.triangle_pairs));
      fcl_nv.push_back(double(fcl.bv_tests));
    }
    r.cfl.mean_np = mean(cfl_np);
    r.cfl.mean_nv = mean(cfl_nv);
    r.obbrss.mean_np = mean(fcl_np);
    r.obbrss.mean_nv = mean(fcl_nv);
    r.fcl_errors = referee.fclErrors();
    r.largest_fcl_error = referee.largestFclError();
    r.speedup = r.cfl.median_us > 0 ? r.obbrss.median_us / r.cfl.median_us : 0;
    const bool ok = r.max_difference <= 1e-9 * diagonal;
    passed = passed && ok;
    io.out << format("%-7g %9.4g | %8.1f %8.1f | %8.1f %8.1f | %8.1f %8.1f | %9.1fx | %8.1f %8.0f | %8.1f %8.0f | %11.2g%s\n",
                     band, r.achieved_median / diagonal, r.cfl.median_us, r.cfl.p90_us, r.obbrss.median_us,
                     r.obbrss.p90_us, r.rss.median_us, r.rss.p90_us, r.speedup, r.cfl.mean_np, r.cfl.mean_nv,
                     r.obbrss.mean_np, r.obbrss.mean_nv, r.max_difference / diagonal, ok ? "" : "  <-- MISMATCH");
    io.out.flush();
    reports.push_back(r);
  }

  for (const BandReport& r : reports) {
    if (r.fcl_errors == 0) continue;
    io.out << format("note: band %g: FCL OBBRSS was off on %d of %d poses, by up to %.3g of the diagonal; brute "
                     "force over all triangle pairs gave those poses' reference\n",
                     r.band, r.fcl_errors, queries, r.largest_fcl_error / diagonal);
  }

  const SectionContext context{cfl_a, model_b, obbrss_a, obbrss_b, diagonal, repeats, clock, order};
  if (moving_frames > 0) {
    passed = runMovingSection(context, moving_frames, separation, seed, io.out) && passed;
  }
  if (approximate) passed = runApproximateSection(context, band_poses, approximate_options, io.out) && passed;
  if (point_count > 0) passed = runPointSection(context, point_count, seed, io.out) && passed;
  if (shape_poses > 0) {
    const std::vector<double> shape_bands = args.has("bands") ? bands : std::vector<double>{0.005, 0.02};
    passed = runShapeSection(context, shape_bands, shape_poses, seed, io.out) && passed;
  }
  if (penetration_poses > 0) passed = runPenetrationSection(context, penetration_poses, seed, io.out) && passed;

  if (json_path) {
    std::ofstream json(*json_path);
    json << "{\n  \"mesh_a\": " << jsonString(path_a) << ",\n  \"mesh_b\": " << jsonString(path_b)
         << ",\n  \"triangles_a\": " << mesh_a.triangles.size() << ",\n  \"triangles_b\": " << model_b.mesh.triangles.size()
         << ",\n  \"diagonal\": " << jsonNumber(diagonal) << ",\n  \"queries_per_band\": " << queries
         << ",\n  \"repeats\": " << repeats << ",\n  \"clock\": " << jsonString(clock_name) << ",\n  \"order\": " << jsonString(order_name)
         << ",\n  \"query_kernels\": " << jsonString(kernels) << ",\n  \"seed\": " << seed
         << ",\n  \"cfl_model\": {\"resolution\": " << cfl_a.statistics.resolution
         << ", \"voxels\": " << cfl_a.statistics.voxel_count
         << ", \"average_list_length\": " << jsonNumber(cfl_a.statistics.average_list_length)
         << ", \"memory_bytes\": " << cfl_a.statistics.memory_bytes << "},\n  \"build_seconds\": {\"cfl\": "
         << jsonNumber(cfl_a.statistics.build_seconds) << ", \"cfl_mesh_model_b\": " << jsonNumber(model_b_seconds)
         << ", \"fcl_obbrss\": " << jsonNumber(obbrss_a.buildSeconds()) << ", \"fcl_rss\": "
         << jsonNumber(rss_a.buildSeconds()) << "},\n  \"bands\": [\n";
    for (std::size_t i = 0; i < reports.size(); ++i) {
      const BandReport& r = reports[i];
      auto figures = [&](const BandReport::Figures& f) {
        std::string s = "{\"median_us\": " + jsonNumber(f.median_us) + ", \"p90_us\": " + jsonNumber(f.p90_us);
        if (f.mean_np >= 0) s += ", \"mean_np\": " + jsonNumber(f.mean_np) + ", \"mean_nv\": " + jsonNumber(f.mean_nv);
        return s + "}";
      };
      json << "    {\"band\": " << jsonNumber(r.band) << ", \"target_distance\": " << jsonNumber(r.target)
           << ", \"median_distance\": " << jsonNumber(r.achieved_median) << ",\n     \"cfl\": " << figures(r.cfl)
           << ",\n     \"obbrss\": " << figures(r.obbrss) << ",\n     \"rss\": " << figures(r.rss)
           << ",\n     \"speedup_obbrss_over_cfl\": " << jsonNumber(r.speedup)
           << ", \"max_abs_difference\": " << jsonNumber(r.max_difference)
           << ", \"fcl_errors\": " << r.fcl_errors << ", \"largest_fcl_error\": " << jsonNumber(r.largest_fcl_error) << "}"
           << (i + 1 < reports.size() ? ",\n" : "\n");
    }
    json << "  ],\n  \"passed\": " << (passed ? "true" : "false") << "\n}\n";
    if (!json) throw Error(*json_path + ": cannot write the JSON report");
    io.out << "\nwrote " << *json_path << '\n';
  }
  if (plot_path) {
    const std::string title = format("%s vs %s: exact distance query time (%d poses per band)",
                                     path_a.substr(path_a.rfind('/') + 1).c_str(),
                                     path_b.substr(path_b.rfind('/') + 1).c_str(), queries);
    writePlot(*plot_path, reports, title);
    io.out << (json_path ? "" : "\n") << "wrote " << *plot_path << '\n';
  }
  if (!passed) {
    io.err << format("cfl bench: FAILED: a CFL distance differs from the reference (FCL OBBRSS, or brute force where "
                     "the two disagree) by more than 1e-9 of the diagonal (%g), breaks the rel_err/abs_err bound, "
                     "or a section's check failed; see the rows marked MISMATCH or FAILED\n",
                     diagonal);
    return 1;
  }
  return 0;
}

}  // namespace cfl::tool
