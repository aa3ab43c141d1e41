// Point queries, CFL against Open3D's RaycastingScene (Embree inside), the same points in one run:
//
//   cfl_point_bench [--points N] [--repeats R] [--threads T] [--mesh FILE ...]
//
// For each mesh (default: data/bunny.obj, torus_knot.obj, rock.obj, wuson.obj) and two point sets of N points
// (default 1,000,000): "near", a random surface point moved by up to 5% of the bounding-box diagonal in a
// random direction, and "box", uniform in the bounding box grown to twice its size about its center.
// Unsigned: cfl::computePointDistances against RaycastingScene::ComputeDistance. Signed, on meshes cfl finds
// closed: against ComputeSignedDistance (Open3D signs by ray-crossing parity). Both run on every hardware
// thread, or on --threads T each (Open3D's nthreads, cfl's PointQueryOptions::threads); times are wall-clock
// medians over the repeats, the two interleaved, and beside them the process CPU time of the same calls (all
// threads summed), whose ratio holds when other programs share the cores and the wall clock does not. Open3D
// works in float: the points are floats, given to both exactly, and answers must agree to 1e-6 of the
// diagonal, signs wherever |distance| exceeds that, or, where Open3D's float rounding misses by more, cfl must
// equal a brute force in double over every triangle. Exit 1 when they do not.
//
// Open3D's signs come from casting rays. Where its ray casting finds nothing (checked first: a ray from outside
// the mesh's box towards a vertex must hit), its signs are not compared. That is the case with Debian 12's
// packages: Open3D 0.16 casts every ray with mask 0 and Debian's Embree 3.13.5 is built with ray masks on
// (rtcGetDeviceProperty(RTC_DEVICE_PROPERTY_RAY_MASK_SUPPORTED) is 1), so every ray skips every geometry and
// ComputeSignedDistance returns unsigned distances. The signs of cfl's pseudonormals are then checked against
// cfl's generalized winding number (an independent method: solid angles, no closest feature) on the first
// 20000 points of each set. Build-time columns: RaycastingScene::AddTriangles plus its first query (Embree
// commits the scene lazily) against cfl::buildCflModel.

#include "cfl/cfl_model.h"
#include "cfl/error.h"
#include "cfl/mesh_io.h"
#include "cfl/point_query.h"
#include "cfl/triangle_distance.h"

#include <open3d/core/Tensor.h>
#include <open3d/t/geometry/RaycastingScene.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <ctime>
#include <limits>
#include <random>
#include <string>
#include <vector>

#ifndef CFL_DATA_DIR
#define CFL_DATA_DIR "data"
#endif

namespace {

using Clock = std::chrono::steady_clock;

// CPU time of the whole process (every thread), seconds.
double processCpu() {
  timespec t;
  clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}
namespace o3c = open3d::core;
namespace o3g = open3d::t::geometry;

double seconds(Clock::time_point since) { return std::chrono::duration<double>(Clock::now() - since).count(); }

double median(std::vector<double> v) {
  std::sort(v.begin(), v.end());
  return v.size() % 2 ? v[v.size() / 2] : 0.5 * (v[v.size() / 2 - 1] + v[v.size() / 2]);
}

// Points as floats (what Open3D takes), and the same values as doubles for cfl.
struct PointSet {
  std::string name;
  std::vector<float> xyz;
  std::vector<Eigen::Vector3d> points;
};

PointSet nearPoints(const cfl::TriangleMesh& mesh, std::size_t n, double diagonal, std::mt19937_64& rng) {
  PointSet set{"near (5%)", {}, {}};
  std::vector<double> areas(mesh.triangles.size());
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& v = mesh.triangles[t];
    areas[t] = (mesh.vertices[v[1]] - mesh.vertices[v[0]]).cross(mesh.vertices[v[2]] - mesh.vertices[v[0]]).norm();
  }
  std::discrete_distribution<std::size_t> pick(areas.begin(), areas.end());
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> g(0, 1);
  for (std::size_t i = 0; i < n; ++i) {
    const auto& v = mesh.triangles[pick(rng)];
    double a = u(rng), b = u(rng);
    if (a + b > 1) {
      a = 1 - a;
      b = 1 - b;
    }
    const Eigen::Vector3d on = mesh.vertices[v[0]] + a * (mesh.vertices[v[1]] - mesh.vertices[v[0]]) +
                               b * (mesh.vertices[v[2]] - mesh.vertices[v[0]]);
    const Eigen::Vector3d direction = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    const Eigen::Vector3d p = on + direction * (0.05 * diagonal * u(rng));
    for (int k = 0; k < 3; ++k) set.xyz.push_back(float(p[k]));
  }
  return set;
}

PointSet boxPoints(const cfl::Aabb& box, std::size_t n, std::mt19937_64& rng) {
  PointSet set{"box (2x)", {}, {}};
  std::uniform_real_distribution<double> u(-1, 1);
  const Eigen::Vector3d c = box.center(), h = box.size();  // twice the box: half-extent = its full size / 1
  for (std::size_t i = 0; i < n; ++i)
    for (int k = 0; k < 3; ++k) set.xyz.push_back(float(c[k] + h[k] * u(rng)));
  return set;
}

void finish(PointSet& set) {
  set.points.resize(set.xyz.size() / 3);
  for (std::size_t i = 0; i < set.points.size(); ++i)
    set.points[i] = Eigen::Vector3d(set.xyz[3 * i], set.xyz[3 * i + 1], set.xyz[3 * i + 2]);
}

// How many of the points in `apart` (at most kVerified of them) have cfl's |distance| within 1e-9 of the
// diagonal of the brute force in double over every triangle (its own point-triangle kernel, no regions).
std::size_t countOpen3dErrors(const cfl::TriangleMesh& mesh, const std::vector<Eigen::Vector3d>& points,
                              const std::vector<cfl::PointDistance>& results, const std::vector<std::size_t>& apart,
                              double diagonal) {
  constexpr std::size_t kVerified = 5000;
  std::size_t agree = 0;
  for (std::size_t n = 0; n < std::min(apart.size(), kVerified); ++n) {
    const std::size_t i = apart[n];
    double best = std::numeric_limits<double>::infinity();
    for (const auto& t : mesh.triangles)
      best = std::min(best, cfl::pointTriangleSquaredDistance(points[i], mesh.vertices[t[0]], mesh.vertices[t[1]],
                                                              mesh.vertices[t[2]]));
    if (std::abs(std::sqrt(best) - std::abs(results[i].distance)) <= 1e-9 * diagonal) ++agree;
  }
  return agree;
}

struct Args {
  std::size_t points = 1000000;
  int repeats = 3;
  int threads = 0;  // 0: every hardware thread
  std::vector<std::string> meshes;
};

Args parse(int argc, char** argv) {
  Args args;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    auto value = [&]() -> std::string {
      if (i + 1 >= argc) throw cfl::Error(a + " needs a value");
      return argv[++i];
    };
    if (a == "--points") args.points = std::stoul(value());
    else if (a == "--repeats") args.repeats = std::max(1, std::stoi(value()));
    else if (a == "--threads") args.threads = std::max(0, std::stoi(value()));
    else if (a == "--mesh") args.meshes.push_back(value());
    else if (a == "--help") {
      std::printf("usage: cfl_point_bench [--points N] [--repeats R] [--threads T (0: all)] [--mesh FILE ...]\n");
      std::exit(0);
    } else {
      throw cfl::Error("unknown argument '" + a + "' (see --help)");
    }
  }
  if (args.meshes.empty()) {
    const char* dir = std::getenv("CFL_DATA_DIR") ? std::getenv("CFL_DATA_DIR") : CFL_DATA_DIR;
    for (const char* name : {"bunny.obj", "torus_knot.obj", "rock.obj", "wuson.obj"})
      args.meshes.push_back(std::string(dir) + "/" + name);
  }
  return args;
}

}  // namespace

int main(int argc, char** argv) try {
  const Args args = parse(argc, argv);
  std::mt19937_64 rng(20261126);
  bool failed = false;
  const std::string threads =
      args.threads == 0 ? std::string("all threads") : std::to_string(args.threads) + " thread(s)";
  std::printf("CFL point queries against Open3D RaycastingScene, %zu points per set, median of %d, %s\n",
              args.points, args.repeats, threads.c_str());
  std::printf("%-16s %9s %-10s %-9s | %10s %10s %8s | %10s %10s %8s | %10s %10s %8s | %9s %9s\n", "mesh", "tris",
              "points", "query", "Open3D s", "CFL s", "speedup", "O3D cpu s", "CFL cpu s", "cpu x", "max|d|/diag",
              "sign diff", "O3D off", "O3D bld s", "CFL bld s");
  std::printf(
      "(max|d|/diag: largest difference of |distance| from Open3D's, over the points where it is within 1e-6 of\n"
      " the diagonal; O3D off: points where Open3D is farther off than that and cfl equals the brute force in\n"
      " double to 1e-9 of the diagonal (Open3D's float rounding); sign diff: points farther than 1e-6 of the\n"
      " diagonal from the surface whose sign differs from Open3D's, or from cfl's winding number where Open3D's\n"
      " rays hit nothing)\n");
  for (const std::string& path : args.meshes) {
    const cfl::TriangleMesh mesh = cfl::loadMesh(path);
    auto start = Clock::now();
    const cfl::CflModel model = cfl::buildCflModel(mesh);
    const double cfl_build = seconds(start);
    const double diagonal = model.geometry.bounds.diagonal();
    const bool closed = model.sign.closure.closed;

    o3c::Tensor vertices({std::int64_t(mesh.vertices.size()), 3}, o3c::Float32);
    o3c::Tensor triangles({std::int64_t(mesh.triangles.size()), 3}, o3c::UInt32);
    float* vp = vertices.GetDataPtr<float>();
    for (std::size_t i = 0; i < mesh.vertices.size(); ++i)
      for (int k = 0; k < 3; ++k) vp[3 * i + k] = float(mesh.vertices[i][k]);
    std::uint32_t* tp = triangles.GetDataPtr<std::uint32_t>();
    for (std::size_t i = 0; i < mesh.triangles.size(); ++i)
      for (int k = 0; k < 3; ++k) tp[3 * i + k] = std::uint32_t(mesh.triangles[i][k]);
    start = Clock::now();
    o3g::RaycastingScene scene;
    scene.AddTriangles(vertices, triangles);
    {
      o3c::Tensor one({1, 3}, o3c::Float32);
      one.Fill(0.0f);
      scene.ComputeDistance(one);  // Embree builds its tree on the first query
    }
    const double o3d_build = seconds(start);
    // Does Open3D's ray casting work here? A ray from beyond the box towards a vertex of the mesh hits it.
    bool rays_work = false;
    {
      const Eigen::Vector3d target = mesh.vertices[mesh.triangles[0][0]];
      const Eigen::Vector3d from = model.geometry.bounds.center() + Eigen::Vector3d(2 * diagonal, 0.1 * diagonal, 0);
      const Eigen::Vector3d direction = (target - from).normalized();
      o3c::Tensor ray({1, 6}, o3c::Float32);
      float* r = ray.GetDataPtr<float>();
      for (int k = 0; k < 3; ++k) {
        r[k] = float(from[k]);
        r[3 + k] = float(direction[k]);
      }
      const auto hits = scene.CastRays(ray);
      rays_work = std::isfinite(hits.at("t_hit").GetDataPtr<float>()[0]);
      if (!rays_work)
        std::printf("%-16s Open3D's ray casting hits nothing on this machine: its signs are not compared; cfl's "
                    "signs are checked against cfl's winding number\n",
                    path.substr(path.find_last_of('/') + 1).c_str());
    }

    std::vector<PointSet> sets;
    sets.push_back(nearPoints(mesh, args.points, diagonal, rng));
    sets.push_back(boxPoints(model.geometry.bounds, args.points, rng));
    const std::string name = path.substr(path.find_last_of('/') + 1);
    for (PointSet& set : sets) {
      finish(set);
      o3c::Tensor query({std::int64_t(set.points.size()), 3}, o3c::Float32);
      std::copy(set.xyz.begin(), set.xyz.end(), query.GetDataPtr<float>());
      std::vector<cfl::PointDistance> results(set.points.size());
      for (int signed_query = 0; signed_query < (closed ? 2 : 1); ++signed_query) {
        cfl::PointQueryOptions options;
        options.signed_distance = signed_query == 1;
        options.threads = args.threads;
        std::vector<double> o3d_times, cfl_times, o3d_cpu, cfl_cpu;
        o3c::Tensor o3d_answer;
        for (int r = 0; r < args.repeats; ++r) {
          double cpu = processCpu();
          start = Clock::now();
          o3d_answer = signed_query ? scene.ComputeSignedDistance(query, args.threads)
                                    : scene.ComputeDistance(query, args.threads);
          o3d_times.push_back(seconds(start));
          o3d_cpu.push_back(processCpu() - cpu);
          cpu = processCpu();
          start = Clock::now();
          cfl::computePointDistances(model, Eigen::Isometry3d::Identity(), set.points.data(), set.points.size(),
                                     results.data(), options);
          cfl_times.push_back(seconds(start));
          cfl_cpu.push_back(processCpu() - cpu);
        }
        const float* o3d = o3d_answer.Contiguous().GetDataPtr<float>();
        double worst = 0;
        std::size_t sign_differences = 0;
        std::vector<std::size_t> apart;  // where |distance| differs from Open3D's by more than the tolerance
        for (std::size_t i = 0; i < results.size(); ++i) {
          const double a = results[i].distance, b = o3d[i];
          const double difference = std::abs(std::abs(a) - std::abs(b)) / diagonal;
          if (difference > 1e-6) apart.push_back(i);
          else worst = std::max(worst, difference);
          if (rays_work && signed_query && std::abs(a) > 1e-6 * diagonal && (a < 0) != (b < 0)) ++sign_differences;
        }
        // Open3D's float arithmetic misses by more than the tolerance on some meshes (long slivers): there
        // the brute force in double over every triangle decides. A point where cfl agrees with it (to 1e-9 of
        // the diagonal) counts as Open3D's error; one where it does not, or one beyond kVerified, as cfl's.
        const std::size_t open3d_errors = countOpen3dErrors(mesh, set.points, results, apart, diagonal);
        if (open3d_errors < apart.size()) worst = std::max(worst, 1.0);
        if (!rays_work && signed_query) {
          const std::size_t checked = std::min<std::size_t>(20000, results.size());
          std::vector<cfl::PointDistance> winding(checked);
          cfl::PointQueryOptions by_winding = options;
          by_winding.sign_method = cfl::SignMethod::kWindingNumber;
          cfl::computePointDistances(model, Eigen::Isometry3d::Identity(), set.points.data(), checked, winding.data(),
                                     by_winding);
          for (std::size_t i = 0; i < checked; ++i)
            if (std::abs(results[i].distance) > 1e-6 * diagonal &&
                (results[i].distance < 0) != (winding[i].distance < 0))
              ++sign_differences;
        }
        const double o3d_median = median(o3d_times), cfl_median = median(cfl_times);
        const double o3d_cpu_median = median(o3d_cpu), cfl_cpu_median = median(cfl_cpu);
        std::printf(
            "%-16s %9zu %-10s %-9s | %10.4f %10.4f %7.2fx | %10.4f %10.4f %7.2fx | %10.2g %10zu %8zu | %9.3f %9.3f\n",
            name.c_str(), mesh.triangles.size(), set.name.c_str(), signed_query ? "signed" : "unsigned", o3d_median,
            cfl_median, o3d_median / cfl_median, o3d_cpu_median, cfl_cpu_median, o3d_cpu_median / cfl_cpu_median, worst,
            sign_differences, open3d_errors, o3d_build, cfl_build);
        if (!(worst <= 1e-6) || sign_differences > 0) failed = true;
      }
    }
    if (!closed) std::printf("%-16s not closed (%s): unsigned only\n", name.c_str(), model.sign.closure.reason.c_str());
  }
  if (failed) std::printf("FAILED: an answer differs from Open3D's beyond 1e-6 of the diagonal, or a sign differs\n");
  return failed ? 1 : 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "cfl_point_bench: %s\n", e.what());
  return 1;
}
