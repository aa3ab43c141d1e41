#include "commands.h"

#include "cfl/cfl_file.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/mesh_io.h"
#include "cfl/penetration.h"
#include "cfl/point_query.h"
#include "fcl_baseline.h"
#include "point_file.h"
#include "pose_file.h"
#include "referee.h"
#include "tool_args.h"
#include "tool_support.h"

#include <chrono>
#include <cmath>
#include <fstream>
#include <iostream>
#include <memory>

namespace cfl::tool {
namespace {

constexpr const char* kBuildUsage = R"(usage: cfl build MESH [-o OUT.cfl] [--resolution N] [--padding P] [--threads T]

Precomputes the discrete Voronoi regions (cells and their closest feature lists) of MESH (any format
assimp reads: OBJ, STL, PLY, OFF, ...) and prints their statistics. Progress goes to standard error: a bar
on a terminal, plain lines otherwise.

  -o, --output OUT.cfl  also save the model (load it with 'cfl info', 'cfl distance' or cfl::loadCflModel)
  --resolution N        0 (default): adaptive regions; N > 0: a uniform grid of N cells along the longest axis
  --padding P           the regions cover the bounding box grown by (P - 1) / 2 of its longest extent on every
                        side (default 3, >= 1)
  --threads T           build threads; 0 (default) uses every hardware thread
)";

constexpr const char* kInfoUsage = R"(usage: cfl info MESH|FILE.cfl [--resolution N] [--padding P] [--threads T]

Prints the statistics of a saved CFL model, or of the model built from a mesh (same options as 'cfl build').
)";

constexpr const char* kDistanceUsage = R"(usage: cfl distance A B [--poses FILE] [--method cfl|obbrss|both] [--signed] [--resolution N]

Distance between mesh A at the identity and mesh B at each pose of FILE (standard input when FILE is
missing or '-'). A may be a .cfl file written by 'cfl build -o'. Prints CSV to standard output:

  pose,distance,ax,ay,az,bx,by,bz,tri_a,tri_b,micros

pose is the 0-based index of the pose in FILE; (ax,ay,az) and (bx,by,bz) the closest points on A and B in
the world frame; tri_a/tri_b their triangle ids (order of triangles in the file after triangulation); micros
the wall time of that query. With --method both each pose gets a 'cfl' row then an 'obbrss' row and a
trailing 'method' column; where the two differ by more than 1e-9 of the larger bounding-box diagonal, brute
force over all triangle pairs decides, and the run fails (status 1) if CFL is off by more than that (a note
counts the poses where OBBRSS is: FCL 0.7 misses vertex-face contacts of triangles with edges under about
2e-4 units).

Pose file: one pose per line, 12 numbers separated by spaces or commas, the row-major 3x4 matrix [R | t] of
B's pose. '#' starts a comment; blank lines are skipped. A malformed line is an error naming its number.

  --method M      cfl (default), obbrss (FCL 0.7 BVHModel<OBBRSS>) or both
  --signed        signed distance (both meshes must be closed; see 'cfl info'): the distance when apart, minus
                  the penetration depth when the bodies overlap (one inside the other included), with the
                  deepest point and its closest point on the other surface as the two points; cfl only
  --resolution N  when A is a mesh: 0 (default) adaptive regions, N > 0 a uniform grid of N cells
  --threads T     build threads (default: all)
)";

constexpr const char* kSdfUsage = R"(usage: cfl sdf MESH|FILE.cfl [POINTS] [--signed] [--winding] [--threads T]

Exact distance from each point of POINTS (standard input when missing or '-') to the mesh at the identity:
the distance field of the mesh, computed, not sampled. Points: one per line, 'x y z' or 'x,y,z'; '#' starts
a comment. Prints CSV to standard output:

  point,distance,cx,cy,cz,gx,gy,gz,triangle

point is the 0-based index of the point; (cx,cy,cz) its closest point on the mesh, (gx,gy,gz) the unit
gradient of the (signed) distance there, triangle the id of the triangle holding the closest point.

  --signed        negative inside. The mesh must be closed (see 'cfl info'), signs from angle-weighted
                  pseudonormals, exact
  --winding       with --signed: sign by the generalized winding number instead, on any mesh (robust on
                  nearly closed meshes: small holes, cracks)
  --resolution N  when MESH is a mesh: 0 (default) adaptive regions, N > 0 a uniform grid
  --threads T     build and query threads (default: all)
)";

int parseThreads(const ParsedArgs& args) {
  auto t = args.get("threads");
  return t ? int(parseInteger(*t, "--threads", 0, 1024)) : 0;
}

BuildOptions buildOptionsFrom(const ParsedArgs& args) {
  BuildOptions options;
  if (auto r = args.get("resolution")) options.resolution = int(parseInteger(*r, "--resolution", 0, 4096));
  if (auto p = args.get("padding")) options.padding = parseReal(*p, "--padding", 1.0, 1e6);
  options.threads = parseThreads(args);
  return options;
}

const std::vector<OptionSpec> kBuildOptions = {{"output"}, {"resolution"}, {"padding"}, {"threads"}};

// "-o" is the one short option; parseArgs knows only long ones, so it is spelled out here.
std::vector<std::string> expandShortOutput(std::vector<std::string> args) {
  for (auto& a : args) {
    if (a == "-o") a = "--output";
  }
  return args;
}

}  // namespace

int runBuild(const std::vector<std::string>& raw, Streams io) {
  const ParsedArgs args = parseArgs(expandShortOutput(raw), kBuildOptions);
  if (args.has("help")) {
    io.out << kBuildUsage;
    return 0;
  }
  if (args.positionals.size() != 1) throw UsageError("expected one mesh file, got " + std::to_string(args.positionals.size()) + " arguments");
  const std::string& path = args.positionals[0];
  if (isCflFile(path)) throw UsageError("'" + path + "' is already a CFL file; 'cfl build' takes a mesh (see 'cfl info')");
  const CflModel model = obtainCflModel(path, buildOptionsFrom(args), io.err);
  printStatistics(model, io.out);
  if (auto out = args.get("output")) {
    const auto start = std::chrono::steady_clock::now();
    saveCflModel(model, *out);
    io.out << format("saved:               %s (%.3f s)\n", out->c_str(),
                     std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  return 0;
}

int runInfo(const std::vector<std::string>& raw, Streams io) {
  const ParsedArgs args = parseArgs(raw, {{"resolution"}, {"padding"}, {"threads"}});
  if (args.has("help")) {
    io.out << kInfoUsage;
    return 0;
  }
  if (args.positionals.size() != 1) throw UsageError("expected one mesh or .cfl file, got " + std::to_string(args.positionals.size()) + " arguments");
  const std::string& path = args.positionals[0];
  if (isCflFile(path) && (args.has("resolution") || args.has("padding"))) {
    throw UsageError("--resolution and --padding apply to meshes; '" + path + "' is already built");
  }
  const auto start = std::chrono::steady_clock::now();
  const CflModel model = obtainCflModel(path, buildOptionsFrom(args), io.err);
  if (isCflFile(path)) {
    io.out << format("file:                %s (loaded in %.3f s)\n", path.c_str(),
                     std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count());
  }
  printStatistics(model, io.out);
  return 0;
}

int runDistance(const std::vector<std::string>& raw, Streams io) {
  const ParsedArgs args = parseArgs(raw, {{"poses"}, {"method"}, {"resolution"}, {"threads"}, {"signed", false}});
  if (args.has("help")) {
    io.out << kDistanceUsage;
    return 0;
  }
  if (args.positionals.size() != 2) throw UsageError("expected meshes A and B, got " + std::to_string(args.positionals.size()) + " arguments");
  const std::string method = args.get("method").value_or("cfl");
  if (method != "cfl" && method != "obbrss" && method != "both") {
    throw UsageError("--method: expected cfl, obbrss or both, got '" + method + "'");
  }
  const bool signed_distance = args.has("signed");
  if (signed_distance && method != "cfl") {
    throw UsageError("--signed needs --method cfl: FCL 0.7 computes no signed distance between meshes");
  }
  BuildOptions options;
  if (auto r = args.get("resolution")) options.resolution = int(parseInteger(*r, "--resolution", 0, 4096));
  options.threads = parseThreads(args);

  // Poses first: a malformed pose file should fail before an expensive build.
  std::vector<Eigen::Isometry3d> poses;
  const std::string pose_source = args.get("poses").value_or("-");
  if (pose_source == "-") {
    poses = readPoses(io.in, "<stdin>");
  } else {
    std::ifstream file(pose_source);
    if (!file) throw Error(pose_source + ": cannot open the pose file");
    poses = readPoses(file, pose_source);
  }

  const bool use_cfl = method != "obbrss";
  const bool use_fcl = method != "cfl";
  CflModel model_a;
  TriangleMesh mesh_a;
  if (use_cfl) {
    model_a = obtainCflModel(args.positionals[0], options, io.err);
    mesh_a = model_a.geometry.mesh;
  } else {
    mesh_a = readMeshArgument(args.positionals[0]);
  }
  // A signed query needs B's regions too (its inside), so B gets a CFL model of its own.
  CflModel model_b_cfl;
  if (signed_distance) model_b_cfl = obtainCflModel(args.positionals[1], options, io.err);
  MeshModel model_b = signed_distance ? model_b_cfl.geometry : makeMeshModel(readMeshArgument(args.positionals[1]));
  std::unique_ptr<bench::FclModel> fcl_a, fcl_b;
  if (use_fcl) {
    fcl_a = std::make_unique<bench::FclModel>(mesh_a, bench::FclBv::kOBBRSS);
    fcl_b = std::make_unique<bench::FclModel>(model_b.mesh, bench::FclBv::kOBBRSS);
  }
  const double diagonal = std::max(boundingBox(mesh_a).diagonal(), model_b.bounds.diagonal());
  const Eigen::Isometry3d X_WA = Eigen::Isometry3d::Identity();

  io.out << kDistanceCsvHeader << (method == "both" ? ",method" : "") << '\n';
  const double tolerance = 1e-9 * diagonal;
  std::unique_ptr<Referee> referee;
  if (use_cfl && use_fcl) referee = std::make_unique<Referee>(model_a.geometry, model_b, tolerance);
  double worst = 0;  // CFL's largest difference from the reference
  long worst_pose = -1;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    const Eigen::Isometry3d& X_WB = poses[i];
    DistanceRow cfl_row, fcl_row;
    if (use_cfl) {
      const auto start = std::chrono::steady_clock::now();
      const DistanceResult r = signed_distance ? computeSignedDistance(model_a, X_WA, model_b_cfl, X_WB)
                                               : computeDistance(model_a, X_WA, model_b, X_WB);
      const auto stop = std::chrono::steady_clock::now();
      cfl_row = {long(i), r.distance, r.point_a, r.point_b, r.triangle_a, r.triangle_b,
                 std::chrono::duration<double, std::micro>(stop - start).count(), method == "both" ? "cfl" : ""};
      io.out << formatDistanceRow(cfl_row) << '\n';
    }
    if (use_fcl) {
      const auto start = std::chrono::steady_clock::now();
      const bench::FclDistance r = bench::fclDistance(*fcl_a, X_WA, *fcl_b, X_WB);
      const auto stop = std::chrono::steady_clock::now();
      fcl_row = {long(i), r.distance, r.point_a, r.point_b, r.triangle_a, r.triangle_b,
                 std::chrono::duration<double, std::micro>(stop - start).count(), method == "both" ? "obbrss" : ""};
      io.out << formatDistanceRow(fcl_row) << '\n';
    }
    if (referee) {
      const double reference = referee->reference(X_WB, fcl_row.distance, {cfl_row.distance});
      const double difference = std::abs(cfl_row.distance - reference);
      if (!(difference <= worst)) {
        worst = difference;
        worst_pose = long(i);
      }
    }
  }
  io.out.flush();
  if (referee && referee->fclErrors() > 0) {
    io.err << format("cfl distance: note: OBBRSS was off on %d of %zu poses, by up to %.3g (%.3g of the diagonal); "
                     "brute force over all triangle pairs gave those poses' reference\n",
                     referee->fclErrors(), poses.size(), referee->largestFclError(),
                     referee->largestFclError() / diagonal);
  }
  if (referee && worst_pose >= 0 && !(worst <= tolerance)) {
    io.err << format("cfl distance: FAILED: CFL differs from the reference (OBBRSS, or brute force where the two "
                     "disagree) by %.3g (%.3g of the diagonal %g) at pose %ld; allowed: 1e-9 of the diagonal\n",
                     worst, worst / diagonal, diagonal, worst_pose);
    return 1;
  }
  return 0;
}

int runSdf(const std::vector<std::string>& raw, Streams io) {
  const ParsedArgs args = parseArgs(raw, {{"signed", false}, {"winding", false}, {"resolution"}, {"threads"}});
  if (args.has("help")) {
    io.out << kSdfUsage;
    return 0;
  }
  if (args.positionals.empty() || args.positionals.size() > 2) {
    throw UsageError("expected a mesh and a point file, got " + std::to_string(args.positionals.size()) + " arguments");
  }
  if (args.has("winding") && !args.has("signed")) throw UsageError("--winding chooses how --signed signs; add --signed");
  PointQueryOptions query;
  query.signed_distance = args.has("signed");
  query.sign_method = args.has("winding") ? SignMethod::kWindingNumber : SignMethod::kAuto;
  query.threads = parseThreads(args);
  // Points first: a malformed file should fail before an expensive build.
  std::vector<Eigen::Vector3d> points;
  const std::string source = args.positionals.size() == 2 ? args.positionals[1] : "-";
  if (source == "-") {
    points = readPoints(io.in, "<stdin>");
  } else {
    std::ifstream file(source);
    if (!file) throw Error(source + ": cannot open the point file");
    points = readPoints(file, source);
  }
  BuildOptions options;
  if (auto r = args.get("resolution")) options.resolution = int(parseInteger(*r, "--resolution", 0, 4096));
  options.threads = query.threads;
  const CflModel model = obtainCflModel(args.positionals[0], options, io.err);
  std::vector<PointDistance> results(points.size());
  computePointDistances(model, Eigen::Isometry3d::Identity(), points.data(), points.size(), results.data(), query);
  io.out << "point,distance,cx,cy,cz,gx,gy,gz,triangle\n";
  for (std::size_t i = 0; i < results.size(); ++i) {
    const PointDistance& r = results[i];
    io.out << format("%zu,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%.17g,%d\n", i, r.distance, r.closest_point.x(),
                     r.closest_point.y(), r.closest_point.z(), r.gradient.x(), r.gradient.y(), r.gradient.z(),
                     r.triangle);
  }
  return 0;
}

const std::vector<Command>& commands() {
  static const std::vector<Command> list = {
      {"build", "precompute the Voronoi regions of a mesh, print statistics, optionally save them", runBuild},
      {"info", "statistics of a mesh's CFL model or of a saved .cfl file", runInfo},
      {"distance", "distance between two meshes at poses from a file, as CSV (CFL and/or FCL OBBRSS)", runDistance},
      {"sdf", "exact (signed) distance from points of a file to a mesh, with closest points, as CSV", runSdf},
      {"bench", "CFL against FCL OBBRSS and RSS on the same random poses, per separation band", runBench},
      {"paper", "the paper's Tables 1 and 2 on the bundled bunny, next to the published figures", runPaper},
      {"suite", "the benchmark suite of varied meshes and pairs: write it, or run it into one table", runSuite},
  };
  return list;
}

}  // namespace cfl::tool
