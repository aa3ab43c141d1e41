// libFuzzer target for the CFL model loader (deserializeCflModel).
//
// Each input is tried twice: as is, which mostly exercises the header checks and the checksums, and with
// both checksums recomputed, so that mutations reach every structural check behind them. Either way the
// loader must throw cfl::Error or return a model that saves to a file it loads again and that answers
// distance queries; anything else (a crash, a sanitizer report, another exception type, a huge allocation
// caught by -rss_limit_mb / -malloc_limit_mb) is a finding.

#include "cfl/cfl_file.h"
#include "cfl/cfl_query.h"
#include "cfl/error.h"

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <sstream>
#include <string>
#include <vector>

namespace {

const cfl::MeshModel& probe() {
  // A small tetrahedron as the other mesh of every query.
  static const cfl::MeshModel model = [] {
    cfl::TriangleMesh mesh;
    mesh.vertices = {{0, 0, 0}, {0.3, 0, 0}, {0, 0.3, 0}, {0, 0, 0.3}};
    mesh.triangles = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
    return cfl::makeMeshModel(mesh);
  }();
  return model;
}

void exercise(const unsigned char* data, std::size_t size) {
  cfl::CflModel model;
  try {
    model = cfl::deserializeCflModel(data, size, "fuzz.cfl");
  } catch (const cfl::Error&) {
    return;
  }
  // A loaded model is valid: it can be saved and loaded again, to the same bytes.
  const std::vector<unsigned char> saved = cfl::serializeCflModel(model);
  const cfl::CflModel again = cfl::deserializeCflModel(saved.data(), saved.size(), "fuzz-resaved.cfl");
  if (cfl::serializeCflModel(again) != saved) std::abort();
  // The stream writer writes those very bytes.
  std::ostringstream stream;
  cfl::writeCflModel(model, stream);
  const std::string streamed = stream.str();
  if (streamed.size() != saved.size() || std::memcmp(streamed.data(), saved.data(), saved.size()) != 0) std::abort();
  // And it can be queried, in both modes, near and far. (A forged list may give a wrong distance, which
  // the checksum exists to prevent; this only checks that nothing breaks.)
  // Valid models may hold coordinates up to kMaxCoordinate, where a pose built from them overflows (those
  // are queried at the origin only: the query rightly refuses a non-finite pose) or puts B beyond
  // kMaxCoordinate from A, which the query refuses with a cfl::Error.
  const Eigen::Vector3d center = 0.5 * model.geometry.bounds.min + 0.5 * model.geometry.bounds.max;
  const double diagonal = model.regions.bounds().diagonal();
  for (cfl::QueryMode mode : {cfl::QueryMode::kHierarchical, cfl::QueryMode::kPaper}) {
    cfl::DistanceOptions options;
    options.mode = mode;
    for (double offset : {0.0, 0.7 * diagonal}) {
      Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
      X_WB.translation() = center + Eigen::Vector3d(offset, 0, 0);
      if (!X_WB.translation().allFinite()) X_WB.translation().setZero();
      cfl::DistanceResult result;
      try {
        result = cfl::computeDistance(model, Eigen::Isometry3d::Identity(), probe(), X_WB, options);
      } catch (const cfl::Error&) {
        if (X_WB.translation().cwiseAbs().maxCoeff() <= cfl::kMaxCoordinate) std::abort();  // refused in range
        continue;
      }
      if (!(result.distance >= 0)) std::abort();
    }
  }
}

}  // namespace

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  exercise(data, size);
  std::vector<unsigned char> resealed(data, data + size);
  cfl::detail::resealCflBuffer(resealed.data(), resealed.size());
  exercise(resealed.data(), resealed.size());
  return 0;
}
