// Writes the seed corpus of cfl_file_fuzzer: a few small valid CFL files and broken variants of them
// (truncated, wrong magic, wrong version, flipped byte). Run from the source tree's fuzz/ directory:
//   make_seed_corpus corpus/cfl_file_fuzzer
// The committed corpus was made this way; rerun it after a format change.

#include "cfl/cfl_file.h"
#include "cfl/cfl_model.h"

#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <string>
#include <vector>

namespace {

void write(const std::string& path, const std::vector<unsigned char>& bytes) {
  std::FILE* file = std::fopen(path.c_str(), "wb");
  if (!file || std::fwrite(bytes.data(), 1, bytes.size(), file) != bytes.size()) {
    std::perror(path.c_str());
    std::exit(1);
  }
  std::fclose(file);
}

cfl::TriangleMesh tetrahedron() {
  cfl::TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {0, 1, 0}, {0, 0, 1}};
  mesh.triangles = {{0, 1, 2}, {0, 1, 3}, {0, 2, 3}, {1, 2, 3}};
  return mesh;
}

cfl::TriangleMesh degenerate() {
  // A segment-like sliver, a point triangle and a duplicate: valid geometry the builder must handle.
  cfl::TriangleMesh mesh;
  mesh.vertices = {{0, 0, 0}, {1, 0, 0}, {2, 0, 0}, {0, 1, 0}};
  mesh.triangles = {{0, 1, 2}, {3, 3, 3}, {0, 1, 3}, {1, 0, 3}};
  return mesh;
}

cfl::TriangleMesh rod() {
  // 34 small triangles scattered along a thin rod: the adaptive root grid is a single row of cells (a small
  // file) and the lists are long enough that some cells are refined, so the seed's tree has inner nodes
  // and leaves at several depths. A fixed linear congruential sequence keeps the corpus reproducible.
  cfl::TriangleMesh mesh;
  std::uint32_t state = 12345;
  const auto next = [&state] {
    state = state * 1664525u + 1013904223u;
    return double(state >> 8) / double(1u << 24);
  };
  for (int t = 0; t < 34; ++t) {
    const Eigen::Vector3d center(3 * next(), 0.05 * next(), 0.05 * next());
    const int v = static_cast<int>(mesh.vertices.size());
    for (int corner = 0; corner < 3; ++corner) {
      mesh.vertices.push_back(center + Eigen::Vector3d(0.2 * next() - 0.1, 0.01 * next(), 0.01 * next()));
    }
    mesh.triangles.push_back({v, v + 1, v + 2});
  }
  return mesh;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s OUTPUT_DIRECTORY\n", argv[0]);
    return 2;
  }
  const std::string out = argv[1];
  cfl::BuildOptions options;
  options.threads = 1;
  options.resolution = 2;
  const auto tiny = cfl::serializeCflModel(cfl::buildCflModel(tetrahedron(), options));
  write(out + "/valid_tetrahedron_r2.cfl", tiny);
  options.resolution = 4;
  options.topology_culling = true;
  write(out + "/valid_tetrahedron_r4_culling.cfl", cfl::serializeCflModel(cfl::buildCflModel(tetrahedron(), options)));
  options.resolution = 3;
  options.topology_culling = false;
  options.padding = 1.0;
  write(out + "/valid_degenerate_r3.cfl", cfl::serializeCflModel(cfl::buildCflModel(degenerate(), options)));

  options.resolution = 0;  // adaptive
  options.topology_culling = true;
  options.padding = 1.0;
  cfl::CflModel rod_model = cfl::buildCflModel(rod(), options);
  write(out + "/valid_rod_adaptive.cfl", cfl::serializeCflModel(rod_model));
  // Every third leaf without a list (which the builder makes only for long lists, so not on a tiny mesh):
  // a seed that reaches the loader's and the query's handling of such leaves.
  for (std::size_t leaf = 0; leaf < rod_model.regions.leaf_list.size(); leaf += 3) {
    if (rod_model.regions.leaf_list[leaf] == cfl::RegionTree::kNoList) continue;
    rod_model.regions.leaf_list[leaf] = cfl::RegionTree::kNoList;
    ++rod_model.statistics.leaves_without_list;
  }
  write(out + "/valid_rod_leaves_without_list.cfl", cfl::serializeCflModel(rod_model));

  std::vector<unsigned char> broken(tiny.begin(), tiny.begin() + tiny.size() / 2);
  write(out + "/broken_truncated.cfl", broken);
  broken = tiny;
  broken[0] = 'X';
  write(out + "/broken_magic.cfl", broken);
  broken = tiny;
  broken[12] = 99;
  cfl::detail::resealCflBuffer(broken.data(), broken.size());
  write(out + "/broken_version.cfl", broken);
  broken = tiny;
  broken[broken.size() - 20] ^= 0x40;
  write(out + "/broken_flipped_byte.cfl", broken);
  broken = tiny;
  broken[broken.size() - 20] ^= 0x40;
  cfl::detail::resealCflBuffer(broken.data(), broken.size());
  write(out + "/broken_resealed_statistics.cfl", broken);
  return 0;
}
