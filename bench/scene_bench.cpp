// A planner-like broadphase benchmark: a 4-link arm against a world of 8 meshes of mixed shapes and sizes,
// FCL's DynamicAABBTreeCollisionManager against DynamicAABBTreeCollisionManager with FCL's
// DefaultDistanceFunction, the way a motion planner asks "how far is the robot from everything" at every
// configuration it samples. The identical scene is built twice, once from cfl_fcl::CFLGeometry and once from
// FCL's BVHModel<OBBRSS>, and both are timed on the same configurations in one run, interleaved (measure.h).
//
//   cfl_scene_bench [--poses N] [--repeats R] [--clock wall|cpu] [--seed S] [--model-dir DIR]
//
// Every configuration's minimum distance must agree to 1e-9 of the largest world mesh's diagonal (exit 1
// otherwise). A third column times the CFL scene without the adapter's upper bound (each pair searched to the
// end on a fresh result, as the adapter did before it passed the broadphase's best distance), to show what
// the bound buys.
//
// Why a program of its own and not a `cfl bench` section: the cfl tool deliberately does not link the FCL
// adapter, so that its OBBRSS baseline is libfcl as FCL users run it. Here the adapter is needed, so the
// OBBRSS scene's callback calls libfcl's own fcl::distance (found with dlsym, as in the adapter's tests)
// rather than the adapter's, which would only hand the pair on.
//
// Meshes: data/bunny.obj, wuson.obj, torus_knot.obj and rock.obj (CFL_DATA_DIR, or the environment variable
// of that name), and capsules, a table, a shelf, a bottle and a ring generated below. Units: metres.

#include "cfl/cfl_file.h"
#include "cfl/error.h"
#include "cfl/mesh.h"
#include "cfl/mesh_io.h"
#include "cfl_fcl/cfl_geometry.h"
#include "libfcl_distance.h"
#include "measure.h"
#include "pose_generator.h"
#include "tool_args.h"

#include <fcl/fcl.h>


#include <algorithm>
#include <chrono>
#include <cctype>
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

using cfl::TriangleMesh;
using Transform = fcl::Transform3d;

constexpr double kPi = 3.14159265358979323846;

// ---- Generated meshes -------------------------------------------------------------------------------------

// A closed surface of revolution about the x axis: `profile` holds (x, radius) pairs from one pole (radius 0)
// to the other, swept by `segments` steps.
TriangleMesh revolve(const std::vector<std::pair<double, double>>& profile, int segments) {
  TriangleMesh mesh;
  const int rings = int(profile.size()) - 2;  // Circles between the two poles.
  mesh.vertices.emplace_back(profile.front().first, 0, 0);
  for (int k = 1; k <= rings; ++k)
    for (int s = 0; s < segments; ++s) {
      const double a = 2 * kPi * s / segments;
      mesh.vertices.emplace_back(profile[k].first, profile[k].second * std::cos(a), profile[k].second * std::sin(a));
    }
  mesh.vertices.emplace_back(profile.back().first, 0, 0);
  const int last = int(mesh.vertices.size()) - 1;
  const auto at = [&](int ring, int s) { return 1 + (ring - 1) * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) {
    mesh.triangles.push_back({0, at(1, s + 1), at(1, s)});
    for (int k = 1; k < rings; ++k) {
      mesh.triangles.push_back({at(k, s), at(k, s + 1), at(k + 1, s + 1)});
      mesh.triangles.push_back({at(k, s), at(k + 1, s + 1), at(k + 1, s)});
    }
    mesh.triangles.push_back({last, at(rings, s), at(rings, s + 1)});
  }
  return mesh;
}

// A capsule along +x from 0 to `length` (axis), hemispherical ends of `radius`.
TriangleMesh capsule(double radius, double length, int cap_rings, int body_rings, int segments) {
  std::vector<std::pair<double, double>> profile;
  for (int j = 0; j <= cap_rings; ++j) {
    const double a = kPi / 2 * (1 - double(j) / cap_rings);  // From the pole to the equator.
    profile.emplace_back(-radius * std::sin(a), radius * std::cos(a));
  }
  for (int j = 1; j < body_rings; ++j) profile.emplace_back(length * j / body_rings, radius);
  for (int j = 0; j <= cap_rings; ++j) {
    const double a = kPi / 2 * double(j) / cap_rings;
    profile.emplace_back(length + radius * std::sin(a), radius * std::cos(a));
  }
  return revolve(profile, segments);
}

// A bottle standing on z = 0: a cylinder with a rounded shoulder and a neck.
TriangleMesh bottle(double radius, double height, int segments) {
  std::vector<std::pair<double, double>> profile = {{0, 0}, {0, radius}};
  for (int j = 1; j <= 12; ++j) profile.emplace_back(0.6 * height * j / 12, radius);
  for (int j = 1; j <= 8; ++j) {
    const double a = kPi / 2 * j / 8;
    profile.emplace_back(0.6 * height + 0.2 * height * std::sin(a),
                         0.35 * radius + 0.65 * radius * std::cos(a));
  }
  profile.emplace_back(height, 0.35 * radius);
  profile.emplace_back(height, 0);
  TriangleMesh mesh = revolve(profile, segments);
  for (auto& v : mesh.vertices) v = Eigen::Vector3d(v.y(), v.z(), v.x());  // Axis along z.
  return mesh;
}

// A torus in the xy plane.
TriangleMesh ring(double major, double minor, int major_segments, int minor_segments) {
  TriangleMesh mesh;
  for (int i = 0; i < major_segments; ++i)
    for (int j = 0; j < minor_segments; ++j) {
      const double u = 2 * kPi * i / major_segments, v = 2 * kPi * j / minor_segments;
      const double r = major + minor * std::cos(v);
      mesh.vertices.emplace_back(r * std::cos(u), r * std::sin(u), minor * std::sin(v));
    }
  const auto at = [&](int i, int j) { return (i % major_segments) * minor_segments + (j % minor_segments); };
  for (int i = 0; i < major_segments; ++i)
    for (int j = 0; j < minor_segments; ++j) {
      mesh.triangles.push_back({at(i, j), at(i + 1, j), at(i + 1, j + 1)});
      mesh.triangles.push_back({at(i, j), at(i + 1, j + 1), at(i, j + 1)});
    }
  return mesh;
}

// Closed axis-aligned boxes in one mesh (each box its own 8 vertices), as furniture comes out of CAD.
TriangleMesh boxes(const std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>>& min_max) {
  TriangleMesh mesh;
  // The 12 triangles of a box on corners numbered by bits (x, y, z), wound outwards.
  static const int kFaces[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                                    {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  for (const auto& [lo, hi] : min_max) {
    const int base = int(mesh.vertices.size());
    for (int c = 0; c < 8; ++c)
      mesh.vertices.emplace_back(c & 1 ? hi.x() : lo.x(), c & 2 ? hi.y() : lo.y(), c & 4 ? hi.z() : lo.z());
    for (const auto& f : kFaces) mesh.triangles.push_back({base + f[0], base + f[1], base + f[2]});
  }
  return mesh;
}

TriangleMesh table(double length, double width, double height, double top, double leg) {
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> parts = {
      {Eigen::Vector3d(-length / 2, -width / 2, height - top), Eigen::Vector3d(length / 2, width / 2, height)}};
  for (int corner = 0; corner < 4; ++corner) {
    const double x = corner & 1 ? length / 2 - leg : -length / 2, y = corner & 2 ? width / 2 - leg : -width / 2;
    parts.push_back({Eigen::Vector3d(x, y, 0), Eigen::Vector3d(x + leg, y + leg, height - top)});
  }
  return boxes(parts);
}

TriangleMesh shelf(double width, double depth, double height, double board, int levels) {
  std::vector<std::pair<Eigen::Vector3d, Eigen::Vector3d>> parts = {
      {Eigen::Vector3d(-width / 2, -depth / 2, 0), Eigen::Vector3d(-width / 2 + board, depth / 2, height)},
      {Eigen::Vector3d(width / 2 - board, -depth / 2, 0), Eigen::Vector3d(width / 2, depth / 2, height)},
      {Eigen::Vector3d(-width / 2, depth / 2 - board, 0), Eigen::Vector3d(width / 2, depth / 2, height)}};
  for (int level = 0; level < levels; ++level) {
    const double z = (height - board) * level / (levels - 1);
    parts.push_back({Eigen::Vector3d(-width / 2 + board, -depth / 2, z),
                     Eigen::Vector3d(width / 2 - board, depth / 2 - board, z + board)});
  }
  return boxes(parts);
}

std::string dataPath(const char* file) {
  const char* from_environment = std::getenv("CFL_DATA_DIR");
  return std::string(from_environment ? from_environment : CFL_DATA_DIR) + "/" + file;
}

// `mesh` scaled to a bounding-box diagonal of `diagonal`, moved so that its box is centered on the origin in
// x and y and rests on z = 0 (so that a placement's translation is where it stands).
TriangleMesh standing(TriangleMesh mesh, double diagonal) {
  const cfl::Aabb box = cfl::boundingBox(mesh);
  const double scale = diagonal / box.diagonal();
  const Eigen::Vector3d offset(box.center().x(), box.center().y(), box.min.z());
  for (auto& v : mesh.vertices) v = (v - offset) * scale;
  return mesh;
}

// `mesh` scaled to `diagonal` and centered on the origin (a link mesh, placed by its joint frame).
TriangleMesh centered(TriangleMesh mesh, double diagonal) {
  const cfl::Aabb box = cfl::boundingBox(mesh);
  const double scale = diagonal / box.diagonal();
  for (auto& v : mesh.vertices) v = (v - box.center()) * scale;
  return mesh;
}

// ---- The two scenes -----------------------------------------------------------------------------------------

struct SceneMesh {
  std::string name;
  TriangleMesh mesh;
  std::shared_ptr<fcl::CollisionGeometryd> cfl, obbrss;
  double cfl_build_seconds = 0;
};

// With --model-dir: where built CFL models are kept between runs (empty: always build).
std::string g_model_dir;

std::string modelPath(const std::string& name) {
  std::string file;
  for (char c : name) file += std::isalnum(static_cast<unsigned char>(c)) ? c : '_';
  return g_model_dir + "/" + file + ".cfl";
}

// The model saved for `name` in g_model_dir, when there is one of exactly these triangles (a file from
// another version of the mesh, or one this build cannot read, is rebuilt).
std::shared_ptr<cfl_fcl::CFLGeometry> savedModel(const std::string& name, const TriangleMesh& mesh) {
  if (g_model_dir.empty()) return nullptr;
  try {
    auto model = std::make_shared<const cfl::CflModel>(cfl::loadCflModel(modelPath(name)));
    const auto& corners = model->geometry.corners;
    if (corners.size() != mesh.triangles.size()) return nullptr;
    for (std::size_t t = 0; t < corners.size(); ++t)
      for (int k = 0; k < 3; ++k)
        if (corners[t][k] != mesh.vertices[mesh.triangles[t][k]]) return nullptr;
    return std::make_shared<cfl_fcl::CFLGeometry>(model);
  } catch (const cfl::Error&) {
    return nullptr;
  }
}

SceneMesh makeSceneMesh(const std::string& name, TriangleMesh mesh) {
  SceneMesh m;
  m.name = name;
  m.mesh = std::move(mesh);
  std::vector<fcl::Vector3d> vertices = m.mesh.vertices;
  std::vector<fcl::Triangle> triangles;
  for (const auto& t : m.mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  auto obbrss = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  obbrss->beginModel();
  obbrss->addSubModel(vertices, triangles);
  obbrss->endModel();
  m.obbrss = obbrss;
  if ((m.cfl = savedModel(name, m.mesh))) {
    m.cfl_build_seconds = -1;  // Loaded.
    return m;
  }
  // Default options, as a new user would build it: the resolution is chosen automatically.
  const auto start = std::chrono::steady_clock::now();
  auto geometry = std::make_shared<cfl_fcl::CFLGeometry>(vertices, triangles);
  m.cfl_build_seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
  if (!g_model_dir.empty()) cfl::saveCflModel(geometry->model(), modelPath(name));
  m.cfl = geometry;
  return m;
}

Transform placement(double x, double y, double z, double yaw) {
  Transform X = Transform::Identity();
  X.translation() = fcl::Vector3d(x, y, z);
  X.linear() = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
  return X;
}

// The arm: base yaw and three pitch joints. Link 0 and 1 are capsules from joint to joint, link 2 a hand
// (wuson) and link 3 a held object (bunny) beyond it. Returns the four link poses.
constexpr double kShoulderHeight = 0.75, kUpperArm = 0.4, kForearm = 0.35;
std::vector<Transform> armPoses(const double q[4]) {
  const auto pitch = [](double angle) {
    Transform X = Transform::Identity();
    X.linear() = Eigen::AngleAxisd(angle, Eigen::Vector3d::UnitY()).toRotationMatrix();
    return X;
  };
  const auto shift = [](double x, double z) {
    Transform X = Transform::Identity();
    X.translation() = fcl::Vector3d(x, 0, z);
    return X;
  };
  const Transform shoulder = placement(0, 0, kShoulderHeight, q[0]) * pitch(q[1]);
  const Transform elbow = shoulder * shift(kUpperArm, 0) * pitch(q[2]);
  const Transform wrist = elbow * shift(kForearm, 0) * pitch(q[3]);
  return {shoulder, elbow, wrist * shift(0.08, 0), wrist * shift(0.2, -0.03)};
}

struct Scene {
  std::vector<std::unique_ptr<fcl::CollisionObjectd>> links, world;
  fcl::DynamicAABBTreeCollisionManagerd robot_manager, world_manager;
};

// ---- libfcl's own fcl::distance ----------------------------------------------------------------------------

using cfl::bench::DistanceObjectsFn;
using cfl::bench::libfclDistance;

DistanceObjectsFn g_libfcl_distance = nullptr;

// FCL's DefaultDistanceFunction, calling libfcl's own fcl::distance: what a plain FCL program runs.
bool plainFclDistanceFunction(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data, double& dist) {
  auto* cdata = static_cast<fcl::DefaultDistanceData<double>*>(data);
  if (cdata->done) {
    dist = cdata->result.min_distance;
    return true;
  }
  g_libfcl_distance(o1, o2, cdata->request, cdata->result);
  dist = cdata->result.min_distance;
  return dist <= 0;
}

// DefaultDistanceFunction without the adapter's bound: every pair searched to the end on a fresh result, then
// kept if closer.
bool unboundedDistanceFunction(fcl::CollisionObjectd* o1, fcl::CollisionObjectd* o2, void* data, double& dist) {
  auto* cdata = static_cast<fcl::DefaultDistanceData<double>*>(data);
  if (cdata->done) {
    dist = cdata->result.min_distance;
    return true;
  }
  fcl::DistanceResultd fresh;
  fcl::distance(o1, o2, cdata->request, fresh);
  cdata->result.update(fresh);
  dist = cdata->result.min_distance;
  return dist <= 0;
}

void usage(std::ostream& out) {
  out << "usage: cfl_scene_bench [--poses N] [--repeats R] [--clock wall|cpu] [--seed S] [--model-dir DIR]\n"
         "  A 4-link arm against 8 world meshes, DynamicAABBTree manager against manager with FCL's\n"
         "  DefaultDistanceFunction: CFL geometries (through the FCL adapter) against FCL's BVHModel<OBBRSS>,\n"
         "  interleaved on the same random configurations. Defaults: 200 poses, 5 repeats, cpu clock, seed 1.\n"
         "  --model-dir DIR: keep the built CFL models in DIR (NAME.cfl) and load them on later runs.\n";
}

int run(const std::vector<std::string>& args) {
  using namespace cfl::tool;
  const ParsedArgs parsed = parseArgs(args, {{"poses"}, {"repeats"}, {"clock"}, {"seed"}, {"model-dir"}});
  if (parsed.has("help")) {
    usage(std::cout);
    return 0;
  }
  if (!parsed.positionals.empty()) throw UsageError("unexpected argument '" + parsed.positionals[0] + "'");
  const int poses = int(parseInteger(parsed.get("poses").value_or("200"), "--poses", 1, 1000000));
  const int repeats = int(parseInteger(parsed.get("repeats").value_or("5"), "--repeats", 1, 1000));
  const std::uint64_t seed = std::uint64_t(parseInteger(parsed.get("seed").value_or("1"), "--seed", 0, 1LL << 62));
  const std::string clock_name = parsed.get("clock").value_or("cpu");
  if (clock_name != "cpu" && clock_name != "wall") throw UsageError("--clock must be wall or cpu");
  const Clock clock = clock_name == "cpu" ? Clock::kThreadCpu : Clock::kWall;
  g_libfcl_distance = libfclDistance();
  g_model_dir = parsed.get("model-dir").value_or("");

  // The meshes. Links in their joint frames (capsules start at the joint and run along +x); world meshes
  // standing on z = 0 of their placement.
  std::vector<SceneMesh> links, world;
  links.push_back(makeSceneMesh("upper arm (capsule)", capsule(0.055, kUpperArm, 8, 24, 32)));
  links.push_back(makeSceneMesh("forearm (capsule)", capsule(0.045, kForearm, 8, 20, 28)));
  links.push_back(makeSceneMesh("hand (wuson)", centered(cfl::loadMesh(dataPath("wuson.obj")), 0.16)));
  links.push_back(makeSceneMesh("held object (bunny)", centered(cfl::loadMesh(dataPath("bunny.obj")), 0.12)));
  constexpr double kTableHeight = 0.4;
  world.push_back(makeSceneMesh("table", table(1.0, 0.7, kTableHeight, 0.04, 0.05)));
  world.push_back(makeSceneMesh("shelf", shelf(0.5, 0.3, 1.2, 0.02, 5)));
  world.push_back(makeSceneMesh("rock", standing(cfl::loadMesh(dataPath("rock.obj")), 0.6)));
  world.push_back(makeSceneMesh("bunny", standing(cfl::loadMesh(dataPath("bunny.obj")), 0.25)));
  world.push_back(makeSceneMesh("wuson", standing(cfl::loadMesh(dataPath("wuson.obj")), 0.3)));
  world.push_back(makeSceneMesh("torus knot", standing(cfl::loadMesh(dataPath("torus_knot.obj")), 0.3)));
  world.push_back(makeSceneMesh("bottle", bottle(0.04, 0.28, 32)));
  world.push_back(makeSceneMesh("ring", ring(0.12, 0.025, 64, 16)));
  const std::vector<Transform> world_poses = {
      placement(0.6, 0, 0, 0),                       // table
      placement(-0.35, -0.55, 0, 0.3),               // shelf
      placement(-0.3, 0.6, 0, 1.0),                  // rock, on the floor
      placement(0.45, 0.18, kTableHeight, 2.0),      // bunny, on the table
      placement(0.75, -0.2, kTableHeight, -0.7),     // wuson, on the table
      placement(0.85, 0.2, kTableHeight, 0.4),       // torus knot, on the table
      placement(0.4, -0.2, kTableHeight, 0),         // bottle, on the table
      placement(0.3, 0.5, 0.7, 0) * Transform(Eigen::AngleAxisd(1.2, Eigen::Vector3d::UnitX()))};  // ring, hanging

  Scene cfl_scene, fcl_scene;
  for (Scene* scene : {&cfl_scene, &fcl_scene}) {
    const bool cfl = scene == &cfl_scene;
    for (const SceneMesh& m : links) {
      scene->links.push_back(std::make_unique<fcl::CollisionObjectd>(cfl ? m.cfl : m.obbrss));
      scene->robot_manager.registerObject(scene->links.back().get());
    }
    for (std::size_t k = 0; k < world.size(); ++k) {
      scene->world.push_back(std::make_unique<fcl::CollisionObjectd>(cfl ? world[k].cfl : world[k].obbrss,
                                                                     world_poses[k]));
      scene->world_manager.registerObject(scene->world.back().get());
    }
    scene->robot_manager.setup();
    scene->world_manager.setup();
  }
  double largest_diagonal = 0;
  for (const SceneMesh& m : world) largest_diagonal = std::max(largest_diagonal, cfl::boundingBox(m.mesh).diagonal());

  // Random configurations over the joint ranges: the arm sweeps over the table, the shelf and the rock, from
  // touching them to well clear.
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> yaw(-kPi, kPi), shoulder(-0.9, 0.7), elbow(-1.6, 1.6), wrist(-1.5, 1.5);
  std::vector<std::vector<Transform>> configurations;
  for (int i = 0; i < poses; ++i) {
    const double q[4] = {yaw(rng), shoulder(rng), elbow(rng), wrist(rng)};
    configurations.push_back(armPoses(q));
  }

  // One timed query: move the links, update the robot's tree, and ask for the distance, as a planner does.
  const auto query = [&](Scene& scene, std::size_t i, fcl::DistanceCallBack<double> callback) {
    for (std::size_t k = 0; k < scene.links.size(); ++k) {
      scene.links[k]->setTransform(configurations[i][k]);
      scene.links[k]->computeAABB();
    }
    scene.robot_manager.update();
    fcl::DefaultDistanceData<double> data;
    data.request.enable_nearest_points = true;
    scene.robot_manager.distance(&scene.world_manager, &data, callback);
    return data.result.min_distance;
  };
  const std::vector<IndexedMethod> methods = {
      {"FCL OBBRSS", [&](std::size_t i) { return query(fcl_scene, i, plainFclDistanceFunction); }},
      {"CFL", [&](std::size_t i) { return query(cfl_scene, i, fcl::DefaultDistanceFunction<double>); }},
      {"CFL, no bound", [&](std::size_t i) { return query(cfl_scene, i, unboundedDistanceFunction); }},
  };
  const std::vector<MethodSamples> samples =
      timeIndexedMethods(configurations.size(), methods, repeats, clock, Order::kInterleaved);

  // Exactness, and the overlapping configurations (the pass stops at the first overlap).
  const double tolerance = 1e-9 * largest_diagonal;
  int mismatches = 0, overlapping = 0;
  double worst = 0;
  std::vector<double> separations;
  for (std::size_t i = 0; i < configurations.size(); ++i) {
    const double reference = std::max(samples[0].distances[i], 0.0);
    overlapping += reference == 0;
    separations.push_back(reference);
    for (std::size_t j = 1; j < samples.size(); ++j) {
      const double difference = std::abs(std::max(samples[j].distances[i], 0.0) - reference);
      worst = std::max(worst, difference);
      if (difference > tolerance) {
        ++mismatches;
        std::printf("MISMATCH pose %zu: %s %.17g, FCL OBBRSS %.17g\n", i, methods[j].name.c_str(),
                    samples[j].distances[i], samples[0].distances[i]);
      }
    }
  }

  std::printf("cfl_scene_bench: %d configurations of a 4-link arm, %d repeats, interleaved, %s clock, seed %llu\n",
              poses, repeats, clock_name == "cpu" ? "thread CPU" : "wall", static_cast<unsigned long long>(seed));
  std::printf("%-22s %9s %9s %s\n", "mesh", "triangles", "CFL build", "in");
  for (const auto* group : {&links, &world}) {
    for (const SceneMesh& m : *group) {
      char build[32] = "loaded";
      if (m.cfl_build_seconds >= 0) std::snprintf(build, sizeof build, "%.3f s", m.cfl_build_seconds);
      std::printf("%-22s %9zu %9s %s\n", m.name.c_str(), m.mesh.triangles.size(), build,
                  group == &links ? "link" : "world");
    }
  }
  std::printf("minimum distance over the configurations: median %.4g m, %d of %d overlapping\n\n",
              cfl::bench::median(separations), overlapping, poses);
  std::printf("%-14s | %10s %10s %10s | %s\n", "method", "median us", "p90 us", "mean us", "OBBRSS / method (medians)");
  const double fcl_median = cfl::bench::median(samples[0].micros);
  for (std::size_t j = 0; j < samples.size(); ++j) {
    const double m = cfl::bench::median(samples[j].micros);
    std::printf("%-14s | %10.1f %10.1f %10.1f | %.2fx\n", methods[j].name.c_str(), m,
                cfl::bench::percentile(samples[j].micros, 0.9), mean(samples[j].micros), fcl_median / m);
  }
  // The separated configurations alone: an overlap ends the pass at the first overlapping pair found.
  std::vector<double> separated[2];
  for (std::size_t i = 0; i < configurations.size(); ++i)
    if (separations[i] > 0)
      for (int j = 0; j < 2; ++j) separated[j].push_back(samples[j].micros[i]);
  if (!separated[0].empty())
    std::printf("\n%zu separated configurations alone: median FCL OBBRSS %.1f us, CFL %.1f us: %.2fx\n",
                separated[0].size(), cfl::bench::median(separated[0]), cfl::bench::median(separated[1]),
                cfl::bench::median(separated[0]) / cfl::bench::median(separated[1]));
  // The ratio pose by pose, whose median does not let one method's fast poses pair with the other's slow ones.
  std::vector<double> ratios;
  for (std::size_t i = 0; i < configurations.size(); ++i) ratios.push_back(samples[0].micros[i] / samples[1].micros[i]);
  std::printf("per configuration, OBBRSS time / CFL time: median %.2fx, 10th percentile %.2fx, 90th %.2fx\n",
              cfl::bench::median(ratios), cfl::bench::percentile(ratios, 0.1), cfl::bench::percentile(ratios, 0.9));
  std::printf("exactness: largest |CFL - OBBRSS| %.3g of the largest world diagonal (%.3g m); %d over 1e-9\n",
              worst / largest_diagonal, largest_diagonal, mismatches);
  return mismatches == 0 ? 0 : 1;
}

}  // namespace

int main(int argc, char** argv) {
  try {
    return run(std::vector<std::string>(argv + 1, argv + argc));
  } catch (const cfl::tool::UsageError& e) {
    std::cerr << "cfl_scene_bench: " << e.what() << '\n';
    usage(std::cerr);
    return 2;
  } catch (const std::exception& e) {
    std::cerr << "cfl_scene_bench: error: " << e.what() << '\n';
    return 1;
  }
}
