// Primitive shapes against large meshes: FCL 0.7's shape-vs-BVHModel<OBBRSS> (libfcl's own fcl::distance)
// against the same call on a cfl_fcl::CFLGeometry, which answers spheres, capsules and boxes from the CFL
// model (fcl_adapter/shape_queries.cpp). Then a robot-like batch: 50 spheres (a link chain's sphere
// approximation) against a scene mesh at many configurations, spheres per second for both.
//
//   cfl_shape_bench [--poses N] [--repeats R] [--clock wall|cpu] [--seed S] [--model-dir DIR]
//                   [--shape sphere|capsule|box|robot]
//
// Poses: for each mesh, shape and range (0.5% and 2% of the mesh's bounding-box diagonal), N poses with a
// random rotation whose exact distance is the range, found by bisection along a random ray towards the
// mesh's center. max|diff|/diag is the largest difference between FCL's and CFL's answers. Where they
// differ by more than 1e-9 of the diagonal (FCL answers capsules and boxes with GJK, which stops at its own
// tolerance), a brute force over every triangle decides: "FCL off" counts the poses where CFL equals it and
// FCL does not, CFL-exact/diag is CFL's largest difference from it, and the program fails if that passes
// 1e-9. Times are the median over poses of the per-pose median over R repeats, interleaved (measure.h), less
// the clock's own cost per sample.
//
// Why a program of its own: it links the FCL adapter, which the cfl tool must not (see scene_bench.cpp).

#include "cfl/error.h"
#include "cfl/mesh.h"
#include "cfl/mesh_io.h"
#include "cfl/sphere_query.h"
#include "cfl_fcl/cfl_geometry.h"
#include "libfcl_distance.h"
#include "measure.h"
#include "pose_generator.h"
#include "shape_reference.h"

#include <fcl/fcl.h>

#include <time.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <iostream>
#include <memory>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#ifndef CFL_DATA_DIR
#define CFL_DATA_DIR "data"
#endif

namespace {

using Transform = fcl::Transform3d;
using cfl::bench::DistanceObjectsFn;
using cfl::bench::libfclDistance;

struct Mesh {
  std::string name;
  cfl::TriangleMesh mesh;
  std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> obbrss;
  std::shared_ptr<cfl_fcl::CFLGeometry> cfl;
  double diagonal = 0;
  Eigen::Vector3d center = Eigen::Vector3d::Zero();
};

Mesh loadScene(const std::string& dir, const std::string& file) {
  Mesh m;
  m.name = file;
  m.mesh = cfl::loadMesh(dir + "/" + file);
  std::vector<fcl::Triangle> triangles;
  for (const auto& t : m.mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  m.obbrss = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  m.obbrss->beginModel();
  m.obbrss->addSubModel(m.mesh.vertices, triangles);
  m.obbrss->endModel();
  m.cfl = std::make_shared<cfl_fcl::CFLGeometry>(m.mesh.vertices, triangles);
  const cfl::Aabb box = cfl::boundingBox(m.mesh);
  m.diagonal = box.diagonal();
  m.center = box.center();
  return m;
}

// A pose of the shape at distance `target` from the mesh (exact: the adapter's answer, which the
// identical-results check then compares with FCL's), along a random ray (bench::placeShapeOnRay).
Transform placeShape(const Mesh& m, const std::shared_ptr<fcl::CollisionGeometryd>& shape, double target,
                     std::mt19937_64& rng) {
  fcl::CollisionObjectd mesh_object(m.cfl, Transform::Identity());
  return cfl::bench::placeShapeOnRay(m.center, m.diagonal, target, rng, [&](const Eigen::Isometry3d& X) {
    fcl::CollisionObjectd shape_object(shape, X);
    fcl::DistanceRequestd request;
    fcl::DistanceResultd result;
    return fcl::distance(&shape_object, &mesh_object, request, result);
  });
}

// The shape as the benches' reference takes it (shape_reference.h).
cfl::bench::FclShape referenceShape(const fcl::CollisionGeometryd& shape) {
  cfl::bench::FclShape out;
  if (const auto* sphere = dynamic_cast<const fcl::Sphered*>(&shape)) {
    out.radius = sphere->radius;
  } else if (const auto* capsule = dynamic_cast<const fcl::Capsuled*>(&shape)) {
    out.kind = cfl::bench::FclShape::Kind::kCapsule;
    out.radius = capsule->radius;
    out.length = capsule->lz;
  } else {
    out.kind = cfl::bench::FclShape::Kind::kBox;
    out.sides = dynamic_cast<const fcl::Boxd&>(shape).side;
  }
  return out;
}

double median(std::vector<double> v) {
  if (v.empty()) return 0;
  std::nth_element(v.begin(), v.begin() + long(v.size() / 2), v.end());
  return v[v.size() / 2];
}

double threadSeconds() {
  timespec t;
  clock_gettime(CLOCK_THREAD_CPUTIME_ID, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

double wallSeconds() {
  timespec t;
  clock_gettime(CLOCK_MONOTONIC, &t);
  return double(t.tv_sec) + 1e-9 * double(t.tv_nsec);
}

}  // namespace

int main(int argc, char** argv) {
  try {
    int poses = 50, repeats = 15;
    std::uint64_t seed = 1;
    std::string clock_name = "cpu";
    std::string only;  // --shape NAME: one shape's rows only (profiling).
    const char* env_dir = std::getenv("CFL_DATA_DIR");
    std::string dir = env_dir != nullptr ? env_dir : CFL_DATA_DIR;
    for (int i = 1; i < argc; ++i) {
      const std::string arg = argv[i];
      auto value = [&]() -> std::string {
        if (i + 1 >= argc) throw cfl::Error(arg + " needs a value");
        return argv[++i];
      };
      if (arg == "--poses") poses = std::stoi(value());
      else if (arg == "--repeats") repeats = std::stoi(value());
      else if (arg == "--seed") seed = std::stoull(value());
      else if (arg == "--clock") clock_name = value();
      else if (arg == "--model-dir") dir = value();
      else if (arg == "--shape") only = value();
      else throw cfl::Error("unknown argument " + arg +
                            " (usage: cfl_shape_bench [--poses N] [--repeats R] [--clock wall|cpu] [--seed S] "
                            "[--model-dir DIR] [--shape sphere|capsule|box|robot])");
    }
    if (clock_name != "cpu" && clock_name != "wall") throw cfl::Error("--clock must be wall or cpu");
    const cfl::tool::Clock clock = clock_name == "cpu" ? cfl::tool::Clock::kThreadCpu : cfl::tool::Clock::kWall;
    const DistanceObjectsFn plain_fcl = libfclDistance();
    std::mt19937_64 rng(seed);

    std::vector<Mesh> meshes;
    for (const char* file : {"torus_knot.obj", "rock.obj"}) meshes.push_back(loadScene(dir, file));

    std::printf("cfl_shape_bench: %d poses x %d repeats per row, %s clock (less its own %.3f us per sample), seed %llu\n",
                poses, repeats, clock_name.c_str(), cfl::tool::clockOverheadMicros(clock),
                static_cast<unsigned long long>(seed));
    std::printf("%-15s %9s %7s %6s %13s %13s %8s %16s %8s %16s\n", "mesh", "triangles", "shape", "range",
                "FCL OBBRSS us", "CFL adapter us", "speedup", "max|diff|/diag", "FCL off", "CFL-exact/diag");
    bool agree = true;
    for (const Mesh& m : meshes) {
      const double d = m.diagonal;
      const std::vector<std::pair<std::string, std::shared_ptr<fcl::CollisionGeometryd>>> shapes = {
          {"sphere", std::make_shared<fcl::Sphered>(0.02 * d)},
          {"capsule", std::make_shared<fcl::Capsuled>(0.01 * d, 0.05 * d)},
          {"box", std::make_shared<fcl::Boxd>(0.03 * d, 0.02 * d, 0.015 * d)}};
      for (const auto& [shape_name, shape] : shapes) {
        if (!only.empty() && shape_name != only) continue;
        for (const double range : {0.005, 0.02}) {
          std::vector<Eigen::Isometry3d> placed;
          for (int i = 0; i < poses; ++i) placed.push_back(Eigen::Isometry3d(placeShape(m, shape, range * d, rng)));
          fcl::CollisionObjectd fcl_mesh(m.obbrss, Transform::Identity()), cfl_mesh(m.cfl, Transform::Identity());
          fcl::DistanceRequestd request(true);
          const std::vector<cfl::tool::TimedMethod> methods = {
              {"fcl",
               [&](const Eigen::Isometry3d& X) {
                 fcl::CollisionObjectd s(shape, Transform(X.matrix()));
                 fcl::DistanceResultd result;
                 return plain_fcl(&s, &fcl_mesh, request, result);
               }},
              {"cfl", [&](const Eigen::Isometry3d& X) {
                 fcl::CollisionObjectd s(shape, Transform(X.matrix()));
                 fcl::DistanceResultd result;
                 return fcl::distance(&s, &cfl_mesh, request, result);
               }}};
          const auto samples = cfl::tool::timeMethods(placed, methods, repeats, clock);
          double worst = 0, worst_cfl = 0;
          int fcl_off = 0;
          for (int i = 0; i < poses; ++i) {
            const double diff = std::abs(samples[0].distances[i] - samples[1].distances[i]) / d;
            worst = std::max(worst, diff);
            if (diff <= 1e-9) continue;
            // They differ: brute force decides which one is off.
            const double exact = cfl::bench::bruteForceShapeDistance(referenceShape(*shape), placed[i], m.mesh);
            const double cfl_error = std::abs(samples[1].distances[i] - exact) / d;
            worst_cfl = std::max(worst_cfl, cfl_error);
            if (cfl_error <= 1e-9) ++fcl_off;
          }
          if (!(worst_cfl <= 1e-9)) agree = false;
          const double t_fcl = median(samples[0].micros), t_cfl = median(samples[1].micros);
          std::printf("%-15s %9zu %7s %5.1f%% %13.2f %13.2f %7.1fx %16.1e %8d %16.1e\n", m.name.c_str(),
                      m.mesh.triangles.size(), shape_name.c_str(), 100 * range, t_fcl, t_cfl, t_fcl / t_cfl, worst,
                      fcl_off, worst_cfl);
        }
      }
    }

    if (!only.empty() && only != "robot") return agree ? 0 : 1;
    // Robot-like batch: 50 spheres along a bent chain (a link chain's sphere approximation, radius 1.5% of
    // the scene's diagonal) placed near the rock at random configurations, each sphere queried on its own as
    // a broadphase's narrow phase does, all of a configuration's spheres sharing one result.
    const Mesh& scene = meshes.back();
    const int spheres = 50, configurations = std::max(20, poses);
    auto ball = std::make_shared<fcl::Sphered>(0.015 * scene.diagonal);
    std::vector<std::vector<Transform>> chains;
    std::normal_distribution<double> normal;
    for (int c = 0; c < configurations; ++c) {
      const Transform start = placeShape(scene, ball, 0.01 * scene.diagonal, rng);
      std::vector<Transform> chain;
      Eigen::Vector3d p = start.translation();
      Eigen::Vector3d heading = Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized();
      for (int k = 0; k < spheres; ++k) {
        Transform tf = Transform::Identity();
        tf.translation() = p;
        chain.push_back(tf);
        // The next sphere a link length on, bending at random but never into the rock: a robot in
        // collision is not what a planner's distance queries mostly see, and there both sides run FCL.
        for (int attempt = 0; attempt < 100; ++attempt) {
          const Eigen::Vector3d next_heading =
              (heading + 0.3 * Eigen::Vector3d(normal(rng), normal(rng), normal(rng))).normalized();
          const Eigen::Vector3d next = p + 0.02 * scene.diagonal * next_heading;
          if (cfl::computePointDistance(scene.cfl->model(), Eigen::Isometry3d::Identity(), next).distance >
                  1.2 * ball->radius ||
              attempt == 99) {
            heading = next_heading;
            p = next;
            break;
          }
        }
      }
      chains.push_back(chain);
    }
    fcl::CollisionObjectd fcl_scene(scene.obbrss, Transform::Identity()), cfl_scene(scene.cfl, Transform::Identity());
    fcl::DistanceRequestd request(true);
    double seconds[3] = {0, 0, 0};
    double worst = 0;
    std::vector<double> least[3];
    // Third: the core's cfl::computeLeastSphereDistance, the same spheres and running bound without FCL's
    // objects and results around each query.
    std::vector<Eigen::Vector3d> centers(spheres);
    std::vector<double> radii(spheres, ball->radius);
    for (int r = 0; r < repeats; ++r) {
      for (int method = 0; method < 3; ++method) {
        const int which = (method + r) % 3;  // Rotate which goes first.
        const double t0 = clock == cfl::tool::Clock::kThreadCpu ? threadSeconds() : wallSeconds();
        std::vector<double> answers;
        for (const auto& chain : chains) {
          double best = INFINITY;
          if (which == 2) {
            for (int k = 0; k < spheres; ++k) centers[k] = chain[k].translation();
            best = cfl::computeLeastSphereDistance(scene.cfl->model(), Eigen::Isometry3d::Identity(), centers.data(),
                                                   radii.data(), centers.size())
                       .distance;
            answers.push_back(best);
            continue;
          }
          // One result for the whole configuration, as a broadphase manager's DefaultDistanceFunction passes
          // it: each sphere needs only beat the best so far, which prunes FCL's traversal and the adapter's
          // query alike.
          fcl::DistanceResultd result;
          for (const Transform& tf : chain) {
            fcl::CollisionObjectd s(ball, tf);
            const double dist = which == 0 ? plain_fcl(&s, &fcl_scene, request, result)
                                           : fcl::distance(&s, &cfl_scene, request, result);
            best = std::min(best, dist);
          }
          answers.push_back(best);
        }
        seconds[which] += (clock == cfl::tool::Clock::kThreadCpu ? threadSeconds() : wallSeconds()) - t0;
        if (r == 0) least[which] = answers;
      }
    }
    for (int c = 0; c < configurations; ++c)
      if (least[0][c] > 0 && least[1][c] > 0 && least[2][c] > 0)
        worst = std::max({worst, std::abs(least[0][c] - least[1][c]) / scene.diagonal,
                          std::abs(least[0][c] - least[2][c]) / scene.diagonal});
    if (!(worst <= 1e-9)) agree = false;
    const double queries = double(repeats) * configurations * spheres;
    std::printf("%-15s %9zu %7s %6s %13.0f %13.0f %7.1fx %16.1e   (spheres per second, %d x %d spheres)\n",
                scene.name.c_str(), scene.mesh.triangles.size(), "robot", "-", queries / seconds[0],
                queries / seconds[1], seconds[0] / seconds[1], worst, configurations, spheres);
    std::printf("%-15s %9zu %7s %6s %13.0f %13.0f %7.1fx %16s   (cfl::computeLeastSphereDistance)\n",
                scene.name.c_str(), scene.mesh.triangles.size(), "batch", "-", queries / seconds[0],
                queries / seconds[2], seconds[0] / seconds[2], "");
    if (!agree) {
      std::printf("FAILED: CFL and FCL disagree beyond the stated bounds\n");
      return 1;
    }
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "cfl_shape_bench: %s\n", e.what());
    return 2;
  }
}
