// Penetration depth of two overlapping closed meshes: cfl::computePenetration next to FCL's collide with
// contacts on BVHModel<OBBRSS> (which gives per-triangle-pair local depths, not the bodies' depth), on the
// same poses in one run:
//
//   cfl_penetration_bench [--poses N] [--repeats R] [--mesh FILE ...]
//
// Each mesh (default data/torus_knot.obj, rock.obj, wuson.obj; meshes that are not closed are skipped with
// the reason) against itself at N overlapping poses (bench/common/pose_generator.h, band 0: B's box center
// pushed from A's along a random direction to half the offset where they stop touching, random rotation).
// Medians of the calling thread's CPU time per query. FCL's columns: the first contact only
// (num_max_contacts 1), and every contact (num_max_contacts 100000, what a caller that wants the deepest
// local depth must ask for).

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/mesh_io.h"
#include "cfl/penetration.h"
#include "measure.h"
#include "pose_generator.h"

#include <fcl/fcl.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <memory>
#include <string>
#include <vector>

#ifndef CFL_DATA_DIR
#define CFL_DATA_DIR "data"
#endif

namespace {

std::shared_ptr<fcl::BVHModel<fcl::OBBRSSd>> fclModel(const cfl::TriangleMesh& mesh) {
  auto model = std::make_shared<fcl::BVHModel<fcl::OBBRSSd>>();
  std::vector<fcl::Vector3d> vertices(mesh.vertices.begin(), mesh.vertices.end());
  std::vector<fcl::Triangle> triangles;
  for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
  model->beginModel();
  model->addSubModel(vertices, triangles);
  model->endModel();
  return model;
}

}  // namespace

int main(int argc, char** argv) try {
  int pose_count = 30, repeats = 3;
  std::vector<std::string> meshes;
  for (int i = 1; i < argc; ++i) {
    const std::string a = argv[i];
    if (i + 1 < argc && a == "--poses") pose_count = std::max(1, std::atoi(argv[++i]));
    else if (i + 1 < argc && a == "--repeats") repeats = std::max(1, std::atoi(argv[++i]));
    else if (i + 1 < argc && a == "--mesh") meshes.push_back(argv[++i]);
    else {
      std::fprintf(stderr, "usage: cfl_penetration_bench [--poses N] [--repeats R] [--mesh FILE ...]\n");
      return a == "--help" ? 0 : 2;
    }
  }
  if (meshes.empty()) {
    const char* dir = std::getenv("CFL_DATA_DIR") ? std::getenv("CFL_DATA_DIR") : CFL_DATA_DIR;
    for (const char* name : {"torus_knot.obj", "rock.obj", "wuson.obj"}) meshes.push_back(std::string(dir) + "/" + name);
  }
  std::printf("Penetration of a closed mesh with itself at %d overlapping poses, median CPU microseconds per query\n",
              pose_count);
  std::printf("%-16s %7s | %12s %14s %12s | %9s %9s | %10s %10s\n", "mesh", "tris", "FCL 1 ct", "FCL all ct",
              "CFL depth", "1ct/CFL", "all/CFL", "depth/diag", "width/diag");
  for (const std::string& path : meshes) {
    const std::string name = path.substr(path.find_last_of('/') + 1);
    const cfl::CflModel model = cfl::buildCflModel(cfl::loadMesh(path));
    if (!model.sign.closure.closed) {
      std::printf("%-16s skipped: not closed (%s)\n", name.c_str(), model.sign.closure.reason.c_str());
      continue;
    }
    const double diagonal = model.geometry.bounds.diagonal();
    const auto fcl_mesh = fclModel(model.geometry.mesh);
    const cfl::bench::BandPoses overlap = cfl::bench::generateBandPoses(
        model.geometry.bounds, model.geometry.bounds, 0.0, pose_count, 20261126,
        [&](const Eigen::Isometry3d& X_WB) {
          return cfl::computeDistance(model, Eigen::Isometry3d::Identity(), model.geometry, X_WB).distance;
        });
    const auto fclCollide = [&](std::size_t contacts) {
      return [&, contacts](const Eigen::Isometry3d& X_WB) {
        fcl::CollisionRequestd request(contacts, true);
        fcl::CollisionResultd result;
        fcl::collide(fcl_mesh.get(), fcl::Transform3d::Identity(), fcl_mesh.get(), fcl::Transform3d(X_WB.matrix()),
                     request, result);
        double deepest = 0;
        for (std::size_t i = 0; i < result.numContacts(); ++i)
          deepest = std::max(deepest, result.getContact(i).penetration_depth);
        return deepest;
      };
    };
    std::vector<double> widths;
    const std::vector<cfl::tool::TimedMethod> methods = {
        {"fcl1", fclCollide(1)},
        {"fclall", fclCollide(100000)},
        {"cfl", [&](const Eigen::Isometry3d& X_WB) {
           const cfl::PenetrationResult r =
               cfl::computePenetration(model, Eigen::Isometry3d::Identity(), model, X_WB);
           return r.depth;
         }}};
    const auto samples = cfl::tool::timeMethods(overlap.poses, methods, repeats, cfl::tool::Clock::kThreadCpu);
    double depth_sum = 0, width_max = 0;
    for (const auto& X_WB : overlap.poses) {
      const cfl::PenetrationResult r = cfl::computePenetration(model, Eigen::Isometry3d::Identity(), model, X_WB);
      depth_sum += r.depth;
      width_max = std::max(width_max, r.depth_upper - r.depth);
    }
    const double t1 = cfl::bench::median(samples[0].micros), tall = cfl::bench::median(samples[1].micros),
                 tc = cfl::bench::median(samples[2].micros);
    std::printf("%-16s %7zu | %12.1f %14.1f %12.1f | %8.2fx %8.2fx | %10.4f %10.2g\n", name.c_str(),
                model.geometry.corners.size(), t1, tall, tc, t1 / tc, tall / tc,
                depth_sum / overlap.poses.size() / diagonal, width_max / diagonal);
  }
  return 0;
} catch (const std::exception& e) {
  std::fprintf(stderr, "cfl_penetration_bench: %s\n", e.what());
  return 1;
}
