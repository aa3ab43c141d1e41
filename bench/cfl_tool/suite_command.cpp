// `cfl suite`: `cfl bench`'s measurement over a whole directory of meshes and pairs, summed up in one table
// of OBBRSS/CFL ratios, heap per triangle and build time, worst case first (issue 31).

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/mesh_io.h"
#include "cfl/query_kernels.h"
#include "commands.h"
#include "fcl_baseline.h"
#include "heap.h"
#include "measure.h"
#include "pose_generator.h"
#include "referee.h"
#include "suite_meshes.h"
#include "tool_args.h"
#include "tool_support.h"

#include <spawn.h>
#include <sys/wait.h>
#include <unistd.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <limits>
#include <map>
#include <set>

extern char** environ;

namespace cfl::tool {
namespace {

constexpr const char* kSuiteUsage = R"(usage: cfl suite --generate DIR [--huge]
       cfl suite DIR [--queries N] [--bands LIST] [--cases LIST] [--seed S] [--repeats R]
                 [--clock wall|cpu] [--order interleaved|blocked] [--resolution N] [--threads T]
                 [--plot OUT.png]

--generate writes the benchmark suite into DIR: meshes of the shapes users bring (a long flat blade, a
plate with holes, a ground plane with a small object, an assembly of parts 100x apart in size, thin-legged
and branching figures, a locally refined slab, an open, a non-manifold and a triangle-soup mesh, a
352,800-triangle scan, CAD exports whose planar faces are fans of slivers (a disk, a cylinder, a thin pipe,
a gear), an open terrain, the bundled compact meshes) and DIR/manifest.txt, which lists the cases; --huge adds
a 1,411,200-triangle scan. Deterministic, no network.

Without --generate, runs every case of DIR/manifest.txt ("NAME MESH_A [MESH_B]" per line: A against
itself, or A with its CFL model against B as a plain mesh) as 'cfl bench' does: per band, random poses
set by bisection on FCL OBBRSS distances, CFL and FCL OBBRSS timed interleaved on the same poses, each
CFL answer checked against OBBRSS (brute force where they disagree). Prints one table, worst case first
(sorted by the lowest OBBRSS/CFL ratio at the short-range bands, 0 < band <= 0.02):

  tris A/B         triangles of A and of B (one figure: A against itself)
  band columns     median OBBRSS time / median CFL time on that band's poses (> 1: CFL is faster)
  CFL, OBBRSS B/tri  the live heap that building A's CFL model (mesh copy included) and A's FCL
                   BVHModel<OBBRSS> adds, by glibc's mallinfo2, per triangle of A
  build s          wall time of A's CFL build / of A's OBBRSS build
  max|d|/diag      largest |CFL - reference| / A's bounding-box diagonal; above 1e-9 the row is marked
                   MISMATCH and the exit status is 1

  --generate       write the suite into DIR and stop
  --huge           with --generate: also the 1.4M-triangle case (minutes to build and run)
  --queries N      poses per band (default 40; the whole suite then takes a few minutes on 2 cores)
  --bands LIST     fractions of A's diagonal (default 0,0.005,0.02,0.1,0.5,1; 0 = overlapping)
  --cases LIST     comma-separated case names to run (default: all, in manifest order)
  --seed S, --repeats R, --clock C, --order O, --resolution N, --threads T   as in 'cfl bench'
  --plot OUT.png   also draw the ratios per case and band on a log axis (needs gnuplot)
)";

struct CaseReport {
  std::string name;
  std::size_t triangles_a = 0, triangles_b = 0;
  bool self = true;
  std::vector<double> speedups;  // per band; NaN where the band's poses could not be made
  std::int64_t cfl_heap = 0, obbrss_heap = 0;
  double cfl_build_seconds = 0, obbrss_build_seconds = 0;
  double max_difference = 0;  // / diagonal
  bool exact = true;
  int fcl_errors = 0;
  int unchecked = 0;  // disagreements brute force was too large to settle
  std::vector<std::string> notes;
  double seconds = 0;
  std::string error;  // why the case could not be measured; empty when it was
};

// Brute force costs |A| |B| triangle tests per pose; past this many, a disagreement is left to OBBRSS (and
// counted in a note) rather than stall a run for what is at worst a question about FCL.
constexpr double kBruteForcePairLimit = 2e8;

bool onPath(const std::string& name) {
  const char* path = std::getenv("PATH");
  std::string dirs = path != nullptr ? path : "/usr/bin:/bin";
  for (std::size_t start = 0;;) {
    const std::size_t colon = dirs.find(':', start);
    std::string dir = dirs.substr(start, colon == std::string::npos ? std::string::npos : colon - start);
    if (::access(((dir.empty() ? "." : dir) + "/" + name).c_str(), X_OK) == 0) return true;
    if (colon == std::string::npos) return false;
    start = colon + 1;
  }
}

std::string bandLabel(double band) {
  if (band == 0) return "overlap";
  return format("%g%%", band * 100);
}

// The figure a case is ranked by: its lowest ratio at short range, where CFL is meant to shine; over every
// band when no short-range band was asked for. Infinity (last) when nothing was measured.
double rankingRatio(const CaseReport& r, const std::vector<double>& bands) {
  const bool any_short = std::any_of(bands.begin(), bands.end(), [](double b) { return b > 0 && b <= 0.02; });
  double worst = std::numeric_limits<double>::infinity();
  for (std::size_t i = 0; i < bands.size(); ++i) {
    if (any_short && !(bands[i] > 0 && bands[i] <= 0.02)) continue;
    if (std::isfinite(r.speedups[i])) worst = std::min(worst, r.speedups[i]);
  }
  return worst;
}

std::string ratioCell(double ratio) { return std::isfinite(ratio) ? format("%.2fx", ratio) : "-"; }

std::string perTriangle(std::int64_t bytes, std::size_t triangles) {
  return bytes < 0 || triangles == 0 ? "-" : format("%.0f", double(bytes) / double(triangles));
}

void printTable(const std::vector<CaseReport>& reports, const std::vector<double>& bands, std::ostream& out) {
  std::size_t name_width = 4;
  for (const auto& r : reports) name_width = std::max(name_width, r.name.size());
  const int w = int(name_width);
  const int band_width = 9 * int(bands.size());
  const std::string group = band_width > 24 ? "OBBRSS time / CFL time" : band_width > 11 ? "OBBRSS/CFL" : "ratio";
  out << format("%-*s %15s | %-*s | %17s | %15s |\n", w, "", "", band_width - 1,
                (std::string(std::size_t(std::max(0, (band_width - 1 - int(group.size())) / 2)), ' ') + group).c_str(),
                "heap B/triangle", "build s");
  std::string header = format("%-*s %15s |", w, "case", "tris A/B");
  for (double b : bands) header += format(" %8s", bandLabel(b).c_str());
  header += format(" | %8s %8s | %15s | %11s", "CFL", "OBBRSS", "CFL/OBBRSS", "max|d|/diag");
  out << header << '\n' << std::string(header.size(), '-') << '\n';
  for (const auto& r : reports) {
    const std::string tris = r.self ? format("%zu", r.triangles_a) : format("%zu/%zu", r.triangles_a, r.triangles_b);
    std::string row = format("%-*s %15s |", w, r.name.c_str(), tris.c_str());
    for (double s : r.speedups) row += format(" %8s", ratioCell(s).c_str());
    const bool measured = r.error.empty();
    row += format(" | %8s %8s | %15s | %11s", measured ? perTriangle(r.cfl_heap, r.triangles_a).c_str() : "-",
                  measured ? perTriangle(r.obbrss_heap, r.triangles_a).c_str() : "-",
                  measured ? format("%.2f/%.3f", r.cfl_build_seconds, r.obbrss_build_seconds).c_str() : "-",
                  measured ? format("%.2g", r.max_difference).c_str() : "-");
    if (!r.error.empty()) {
      row += "  <-- ERROR";
    } else if (!r.exact) {
      row += "  <-- MISMATCH";
    }
    out << row << '\n';
  }
}

void writeSuitePlot(const std::string& png, const std::vector<CaseReport>& reports, const std::vector<double>& bands,
                    int queries) {
  const std::string data_path = png + ".dat", script_path = png + ".gp";
  {
    std::ofstream data(data_path);
    data << "case";
    for (double b : bands) data << " \"" << bandLabel(b) << '"';
    data << '\n';
    for (const auto& r : reports) {
      data << '"' << r.name << '"';
      // gnuplot skips a point whose value is "NaN" on a log axis, which is how a missing band should look.
      for (double s : r.speedups) data << ' ' << (std::isfinite(s) && s > 0 ? format("%.6g", s) : "NaN");
      data << '\n';
    }
    if (!data) throw Error(data_path + ": cannot write the plot data");
  }
  {
    const double n = double(bands.size());
    // Tics by hand: xtic() in the plot loop would label every band's point with the case's name.
    std::string tics;
    for (std::size_t i = 0; i < reports.size(); ++i) {
      std::string name;
      for (char ch : reports[i].name) name += ch == '"' || ch == '\\' ? std::string("\\") + ch : std::string(1, ch);
      tics += format("%s\"%s\" %zu", i == 0 ? "" : ", ", name.c_str(), i);
    }
    std::ofstream script(script_path);
    script << "set terminal pngcairo size " << std::max(900, 70 * int(reports.size()) + 200)
           << ",600 enhanced font 'Sans,10'\n"
           << "set output '" << png << "'\n"
           << "set title 'OBBRSS time / CFL time (median of " << queries
           << " poses per band; above 1: CFL faster), worst case first'\n"
           << "set logscale y\nset grid ytics\nset ylabel 'OBBRSS / CFL'\n"
           << "set xtics rotate by -35 noenhanced\nset key outside right top\n"
           << "set xrange [-0.6:" << double(reports.size()) - 0.4 << "]\n"
           << "set datafile missing 'NaN'\n"
           << "set xtics (" << tics << ")\n"
           << "plot for [i=2:" << bands.size() + 1 << "] '" << data_path << "' using ($0 + (i - 2 - " << (n - 1) / 2 << ") * " << 0.7 / n
           << "):i with points pt 7 ps 1.3 title columnhead(i), \\\n"
           << "     1 with lines lt -1 dt 2 title 'OBBRSS = CFL', 10 with lines lc rgb 'gray40' dt 3 title '10x'\n";
    if (!script) throw Error(script_path + ": cannot write the gnuplot script");
  }
  pid_t pid = 0;
  char gnuplot[] = "gnuplot";
  std::vector<char*> argv = {gnuplot, const_cast<char*>(script_path.c_str()), nullptr};
  if (posix_spawnp(&pid, "gnuplot", nullptr, nullptr, argv.data(), environ) != 0) throw Error("could not start gnuplot");
  int status = 0;
  if (waitpid(pid, &status, 0) < 0 || !WIFEXITED(status) || WEXITSTATUS(status) != 0) {
    throw Error("gnuplot failed on " + script_path + " (kept for inspection)");
  }
  std::remove(script_path.c_str());
  std::remove(data_path.c_str());
}

using MeshCache = std::map<std::string, TriangleMesh>;

struct SuiteSettings {
  int queries;
  std::vector<double> bands;
  std::uint64_t seed;
  int repeats;
  Clock clock;
  Order order;
  BuildOptions build;
};

void runCase(const SuiteCase& c, const std::string& dir, const MeshCache& meshes, const SuiteSettings& s,
             std::ostream& log, CaseReport& r) {
  const auto started = std::chrono::steady_clock::now();
  const TriangleMesh& mesh_a = meshes.at(resolveSuitePath(dir, c.mesh_a));
  const TriangleMesh& mesh_b = r.self ? mesh_a : meshes.at(resolveSuitePath(dir, c.mesh_b));
  r.triangles_a = mesh_a.triangles.size();
  r.triangles_b = mesh_b.triangles.size();

  // Inputs exist before each measurement starts; the copy of A that the CFL model keeps is made inside it,
  // as FCL's BVHModel copies A's arrays inside its own.
  // A bar on a terminal; in a log, the lines of a bar per case would bury the per-case summaries.
  const bool terminal = stderrIsTerminal();
  ProgressReporter progress(log, "  building CFL model of " + c.mesh_a, terminal);
  BuildOptions options = s.build;
  if (terminal) options.progress = progress.callback();
  const auto cfl_measured = measureHeap([&] {
    TriangleMesh copy = mesh_a;
    return buildCflModel(std::move(copy), options);
  });
  const CflModel& cfl_a = cfl_measured.first;
  if (terminal) progress.finish(cfl_a.statistics.build_seconds);
  const auto obbrss_measured = measureHeap([&] { return bench::FclModel(mesh_a, bench::FclBv::kOBBRSS); });
  const bench::FclModel& obbrss_a = obbrss_measured.first;
  r.cfl_heap = cfl_measured.second;
  r.obbrss_heap = obbrss_measured.second;
  r.cfl_build_seconds = cfl_a.statistics.build_seconds;
  r.obbrss_build_seconds = obbrss_a.buildSeconds();
  const MeshModel model_b = makeMeshModel(mesh_b);
  const bench::FclModel obbrss_b(mesh_b, bench::FclBv::kOBBRSS);

  const double diagonal = cfl_a.geometry.bounds.diagonal();
  const double tolerance = 1e-9 * diagonal;
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  const bench::DistanceFunction baseline = [&](const Eigen::Isometry3d& X_WB) {
    return bench::fclDistance(obbrss_a, I, obbrss_b, X_WB).distance;
  };
  const std::vector<TimedMethod> methods = {
      {"CFL", [&](const Eigen::Isometry3d& X_WB) { return computeDistance(cfl_a, I, model_b, X_WB).distance; }},
      {"OBBRSS", baseline},
  };
  const bool brute_force_affordable = double(r.triangles_a) * double(r.triangles_b) <= kBruteForcePairLimit;
  Referee referee(cfl_a.geometry, model_b, tolerance);
  for (double band : s.bands) {
    bench::BandPoses poses;
    try {
      poses = bench::generateBandPoses(cfl_a.geometry.bounds, model_b.bounds, band, s.queries, s.seed, baseline);
    } catch (const Error& e) {
      // One unreachable band should not cost the rest of a long run; the table shows "-" and a note why.
      r.speedups.push_back(std::numeric_limits<double>::quiet_NaN());
      r.notes.push_back(format("band %g: no poses (%s)", band, e.what()));
      continue;
    }
    const std::vector<MethodSamples> samples = timeMethods(poses.poses, methods, s.repeats, s.clock, s.order);
    const double cfl_median = bench::median(samples[0].micros);
    r.speedups.push_back(cfl_median > 0 ? bench::median(samples[1].micros) / cfl_median
                                        : std::numeric_limits<double>::quiet_NaN());
    for (std::size_t i = 0; i < poses.poses.size(); ++i) {
      const double cfl = samples[0].distances[i], obbrss = samples[1].distances[i];
      double reference = obbrss;
      if (brute_force_affordable) {
        reference = referee.reference(poses.poses[i], obbrss, {cfl});
      } else if (!(std::abs(cfl - obbrss) <= tolerance)) {
        ++r.unchecked;
      }
      const double difference = std::isnan(cfl) ? INFINITY : std::abs(cfl - reference);
      r.max_difference = std::max(r.max_difference, difference / diagonal);
      if (!(difference <= tolerance)) r.exact = false;
    }
  }
  r.fcl_errors = referee.fclErrors();
  if (r.fcl_errors > 0) {
    r.notes.push_back(format("FCL OBBRSS was off on %d poses, by up to %.3g of the diagonal; brute force gave "
                             "their reference",
                             r.fcl_errors, referee.largestFclError() / diagonal));
  }
  if (r.unchecked > 0) {
    r.notes.push_back(format("%d poses where CFL and OBBRSS disagree were not settled by brute force (%zu x %zu "
                             "triangles is too many); OBBRSS was taken as the reference",
                             r.unchecked, r.triangles_a, r.triangles_b));
  }
  r.seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
}

}  // namespace

int runSuite(const std::vector<std::string>& raw, Streams io) {
  const ParsedArgs args =
      parseArgs(raw, {{"generate", false}, {"huge", false}, {"queries"}, {"bands"}, {"cases"}, {"seed"},
                      {"repeats"}, {"clock"}, {"order"}, {"resolution"}, {"threads"}, {"plot"}});
  if (args.has("help")) {
    io.out << kSuiteUsage;
    return 0;
  }
  if (args.positionals.size() != 1) {
    throw UsageError(args.positionals.empty() ? "expected the suite directory"
                                              : "expected one suite directory, got " + std::to_string(args.positionals.size()));
  }
  const std::string dir = args.positionals[0];
  if (args.has("generate")) {
    for (const char* other : {"queries", "bands", "cases", "seed", "repeats", "clock", "order", "resolution", "threads", "plot"}) {
      if (args.has(other)) throw UsageError(std::string("--") + other + " runs the suite; --generate only writes it");
    }
    generateSuite(dir, args.has("huge"), io.out);
    io.out << "run it: cfl suite " << dir << '\n';
    return 0;
  }
  if (args.has("huge")) throw UsageError("--huge goes with --generate");

  SuiteSettings s;
  s.queries = int(parseInteger(args.get("queries").value_or("40"), "--queries", 1, 1000000));
  s.bands = args.has("bands") ? parseBandList(*args.get("bands"), "--bands") : std::vector<double>{0, 0.005, 0.02, 0.1, 0.5, 1};
  s.seed = std::uint64_t(parseInteger(args.get("seed").value_or("1"), "--seed", 0, INT64_MAX));
  s.repeats = int(parseInteger(args.get("repeats").value_or("3"), "--repeats", 1, 1000));
  const std::string clock_name = args.get("clock").value_or("wall");
  if (clock_name != "wall" && clock_name != "cpu") throw UsageError("--clock: expected wall or cpu, got '" + clock_name + "'");
  s.clock = clock_name == "cpu" ? Clock::kThreadCpu : Clock::kWall;
  const std::string order_name = args.get("order").value_or("interleaved");
  if (order_name != "interleaved" && order_name != "blocked") {
    throw UsageError("--order: expected interleaved or blocked, got '" + order_name + "'");
  }
  s.order = order_name == "blocked" ? Order::kBlocked : Order::kInterleaved;
  s.build.resolution = int(parseInteger(args.get("resolution").value_or("0"), "--resolution", 0, 4096));
  s.build.threads = int(parseInteger(args.get("threads").value_or("0"), "--threads", 0, 1024));
  const auto plot_path = args.get("plot");
  if (plot_path && !onPath("gnuplot")) {
    throw Error("--plot needs gnuplot, which is not in PATH (Debian: apt-get install gnuplot-nox)");
  }

  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec)) {
    throw Error(dir + ": no such suite directory (write one with 'cfl suite --generate " + dir + "')");
  }
  const std::string manifest = resolveSuitePath(dir, kManifestName);
  if (!std::filesystem::exists(manifest, ec)) {
    throw Error(manifest + ": missing (write the suite with 'cfl suite --generate " + dir + "')");
  }
  std::vector<SuiteCase> cases = readManifest(manifest);
  if (auto only = args.get("cases")) {
    std::vector<SuiteCase> chosen;
    std::set<std::string> seen;
    std::size_t start = 0;
    while (start <= only->size()) {
      const std::size_t comma = only->find(',', start);
      const std::string name = only->substr(start, comma == std::string::npos ? std::string::npos : comma - start);
      const auto it = std::find_if(cases.begin(), cases.end(), [&](const SuiteCase& c) { return c.name == name; });
      if (it == cases.end()) {
        std::string known;
        for (const auto& c : cases) known += (known.empty() ? "" : ", ") + c.name;
        throw UsageError("--cases: no case '" + name + "' in " + manifest + " (cases: " + known + ")");
      }
      if (seen.insert(name).second) chosen.push_back(*it);
      if (comma == std::string::npos) break;
      start = comma + 1;
    }
    cases = chosen;
  }
  // Every mesh is read before the first build, so a typo or a broken file fails in seconds, not after
  // minutes of work.
  MeshCache meshes;
  for (const SuiteCase& c : cases) {
    for (const std::string& m : {c.mesh_a, c.mesh_b}) {
      if (m.empty()) continue;
      const std::string p = resolveSuitePath(dir, m);
      if (meshes.count(p) > 0) continue;
      if (!std::filesystem::is_regular_file(p, ec)) {
        throw Error(format("case '%s' (%s:%d): %s: no such mesh file", c.name.c_str(), manifest.c_str(), c.line, p.c_str()));
      }
      try {
        meshes.emplace(p, loadMesh(p));
      } catch (const Error& e) {
        throw Error(format("case '%s' (%s:%d): %s", c.name.c_str(), manifest.c_str(), c.line, e.what()));
      }
    }
  }

  const char* kernels = queryKernelsName(activeQueryKernels());
  io.out << format("cfl suite: %s (%zu case%s), %d poses per band, seed %llu, each timed %d times per method (%s), "
                   "%s time less the clock's own %.3f us per sample; CFL's query kernels: %s\n",
                   manifest.c_str(), cases.size(), cases.size() == 1 ? "" : "s", s.queries, static_cast<unsigned long long>(s.seed), s.repeats,
                   order_name.c_str(), clock_name.c_str(), clockOverheadMicros(s.clock), kernels);
  io.out.flush();
  std::vector<CaseReport> reports;
  for (std::size_t i = 0; i < cases.size(); ++i) {
    io.err << format("[%zu/%zu] %s\n", i + 1, cases.size(), cases[i].name.c_str()) << std::flush;
    CaseReport r;
    r.name = cases[i].name;
    r.self = cases[i].mesh_b.empty();
    try {
      runCase(cases[i], dir, meshes, s, io.err, r);
    } catch (const std::exception& e) {
      // A build the library refuses (say, a grid too large for memory) is a finding of the suite; the other
      // cases still run, and the exit status says it failed.
      r.error = e.what();
      r.exact = false;
      r.speedups.resize(s.bands.size(), std::numeric_limits<double>::quiet_NaN());
      io.err << "  error: " << r.error << '\n';
    }
    reports.push_back(r);
    if (!r.error.empty()) continue;
    io.err << format("  %zu/%zu triangles, CFL built in %.2f s, done in %.1f s; lowest short-range OBBRSS/CFL %s%s\n",
                     r.triangles_a, r.triangles_b, r.cfl_build_seconds, r.seconds,
                     ratioCell(rankingRatio(r, s.bands)).c_str(), r.exact ? "" : "; MISMATCH")
           << std::flush;
  }
  std::stable_sort(reports.begin(), reports.end(), [&](const CaseReport& a, const CaseReport& b) {
    return rankingRatio(a, s.bands) < rankingRatio(b, s.bands);
  });

  io.out << '\n';
  printTable(reports, s.bands, io.out);
  bool passed = true;
  for (const CaseReport& r : reports) {
    passed = passed && r.exact;
    if (!r.error.empty()) io.out << "error: " << r.name << ": " << r.error << '\n';
    for (const std::string& note : r.notes) io.out << "note: " << r.name << ": " << note << '\n';
  }
  if (plot_path) {
    writeSuitePlot(*plot_path, reports, s.bands, s.queries);
    io.out << "wrote " << *plot_path << '\n';
  }
  io.out.flush();
  if (!passed) {
    io.err << "cfl suite: FAILED: a case could not be measured, or a CFL distance differs from the reference by "
              "more than 1e-9 of the diagonal; see the rows marked ERROR or MISMATCH\n";
    return 1;
  }
  return 0;
}

}  // namespace cfl::tool
