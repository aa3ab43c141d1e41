// libFuzzer target for the mesh loader's native text readers (cfl::loadMesh): OBJ, and ASCII STL for inputs
// that start with "solid".
//
// loadMesh reads files, so each input is written to a per-process temporary .obj or .stl file first. The loader
// must throw cfl::Error or return a mesh that passes validateMesh (its documented promise); small meshes are
// then pushed through the whole pipeline (CFL build at a coarse resolution and a distance query), where odd
// but valid geometry (degenerate, huge or tiny coordinates) must also end in a result or a cfl::Error.

#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/mesh_io.h"

#include <cmath>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <string>
#include <unistd.h>

namespace {

std::string temporaryPath(const char* extension) {
  static const std::string stem = [] {
    const char* directory = access("/dev/shm", W_OK) == 0 ? "/dev/shm" : "/tmp";
    return std::string(directory) + "/cfl_mesh_fuzz_" + std::to_string(getpid());
  }();
  return stem + extension;
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  const bool stl = size >= 5 && std::memcmp(data, "solid", 5) == 0;
  const std::string path = temporaryPath(stl ? ".stl" : ".obj");
  if (std::FILE* file = std::fopen(path.c_str(), "wb")) {
    if (size > 0) std::fwrite(data, 1, size, file);
    std::fclose(file);
  } else {
    std::abort();
  }
  cfl::TriangleMesh mesh;
  try {
    mesh = cfl::loadMesh(path);
  } catch (const cfl::Error&) {
    std::remove(path.c_str());
    return 0;
  }
  std::remove(path.c_str());
  cfl::validateMesh(mesh);  // promised by loadMesh: throwing here escapes and is reported as a finding
  if (mesh.triangles.size() > 64) return 0;  // keep executions fast; larger meshes only test parsing
  try {
    cfl::BuildOptions options;
    options.resolution = 3;
    options.threads = 1;
    const cfl::CflModel model = cfl::buildCflModel(mesh, options);
    const cfl::MeshModel other = cfl::makeMeshModel(mesh);
    Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
    X_WB.translation().x() = 0.5 * model.geometry.bounds.diagonal();
    const cfl::DistanceResult result = cfl::computeDistance(model, Eigen::Isometry3d::Identity(), other, X_WB);
    if (!(result.distance >= 0) && std::isfinite(model.geometry.bounds.diagonal())) std::abort();
  } catch (const cfl::Error&) {
  }
  return 0;
}
