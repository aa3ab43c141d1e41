#include "cfl/mesh_io.h"

#include "cfl/error.h"

#include <assimp/Importer.hpp>
#include <assimp/postprocess.h>
#include <assimp/scene.h>

#include <cerrno>
#include <cstring>
#include <fstream>
#include <string>
#include <sys/stat.h>
#include <unordered_map>
#include <vector>

namespace cfl {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& reason) {
  throw Error(path + ": " + reason);
}

// Key for merging vertices with bit-identical positions; -0.0 and 0.0 are the same point.
struct PositionKey {
  double x, y, z;
  bool operator==(const PositionKey& o) const { return x == o.x && y == o.y && z == o.z; }
};

struct PositionHash {
  std::size_t operator()(const PositionKey& k) const {
    auto bits = [](double v) {
      if (v == 0.0) v = 0.0;  // folds -0.0 into +0.0
      std::uint64_t b;
      std::memcpy(&b, &v, sizeof b);
      return b;
    };
    std::uint64_t h = bits(k.x) * 0x9E3779B97F4A7C15ull;
    h ^= bits(k.y) + 0x7F4A7C159E3779B9ull + (h << 6) + (h >> 2);
    h ^= bits(k.z) + 0x94D049BB133111EBull + (h << 6) + (h >> 2);
    return static_cast<std::size_t>(h);
  }
};

struct SceneFlattener {
  const aiScene& scene;
  const std::string& path;
  TriangleMesh mesh;
  std::unordered_map<PositionKey, int, PositionHash> vertex_ids;
  std::size_t skipped_faces = 0;  // points and lines

  int vertexId(const Eigen::Vector3d& p, std::size_t mesh_index, unsigned vertex_index) {
    if (!p.allFinite()) {
      fail(path, "vertex " + std::to_string(vertex_index) + " of mesh " + std::to_string(mesh_index) +
                     " has a non-finite coordinate");
    }
    auto [it, inserted] = vertex_ids.emplace(PositionKey{p.x(), p.y(), p.z()}, int(mesh.vertices.size()));
    if (inserted) mesh.vertices.push_back(p);
    return it->second;
  }

  void addMesh(unsigned mesh_index, const aiMatrix4x4& X_WN) {
    const aiMesh& m = *scene.mMeshes[mesh_index];
    // The node transform is applied to each vertex as it is first used; a cache keeps that to once per
    // vertex of this instance.
    std::vector<int> ids(m.mNumVertices, -1);
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
      const aiFace& face = m.mFaces[f];
      if (face.mNumIndices < 3) {
        ++skipped_faces;
        continue;
      }
      // Triangulate has run, so larger faces only remain if assimp could not split them; fan them so no
      // triangle is lost and ids stay consecutive.
      std::array<int, 3> tri{};
      for (unsigned c = 0; c < face.mNumIndices; ++c) {
        const unsigned v = face.mIndices[c];
        if (v >= m.mNumVertices) {
          fail(path, "face " + std::to_string(f) + " of mesh " + std::to_string(mesh_index) +
                         " refers to vertex " + std::to_string(v) + " of " + std::to_string(m.mNumVertices));
        }
        if (ids[v] < 0) {
          const aiVector3D p = X_WN * m.mVertices[v];
          ids[v] = vertexId(Eigen::Vector3d(p.x, p.y, p.z), mesh_index, v);
        }
      }
      for (unsigned c = 1; c + 1 < face.mNumIndices; ++c) {
        tri = {ids[face.mIndices[0]], ids[face.mIndices[c]], ids[face.mIndices[c + 1]]};
        mesh.triangles.push_back(tri);
      }
    }
  }

  void visit(const aiNode& node, const aiMatrix4x4& X_WParent) {
    const aiMatrix4x4 X_WN = X_WParent * node.mTransformation;
    for (unsigned i = 0; i < node.mNumMeshes; ++i) {
      const unsigned mesh_index = node.mMeshes[i];
      if (mesh_index >= scene.mNumMeshes) {
        fail(path, "node '" + std::string(node.mName.C_Str()) + "' refers to mesh " + std::to_string(mesh_index) +
                       " of " + std::to_string(scene.mNumMeshes));
      }
      addMesh(mesh_index, X_WN);
    }
    for (unsigned i = 0; i < node.mNumChildren; ++i) visit(*node.mChildren[i], X_WN);
  }
};

}  // namespace

TriangleMesh loadMesh(const std::string& path) {
  // Checked here rather than left to assimp, whose messages for these cases are vague.
  struct stat info {};
  if (::stat(path.c_str(), &info) != 0) fail(path, std::string("cannot open: ") + std::strerror(errno));
  if (S_ISDIR(info.st_mode)) fail(path, "is a directory, not a mesh file");
  {
    std::ifstream probe(path, std::ios::binary);
    if (!probe) fail(path, std::string("cannot open for reading: ") + std::strerror(errno));
  }
  if (info.st_size == 0) fail(path, "the file is empty");

  Assimp::Importer importer;
  // Only steps that never remove a triangle: no FindDegenerates, no SortByPType, no
  // JoinIdenticalVertices (merging is done here, on positions alone, after the node transforms), no
  // FindInvalidData. Triangulate splits polygons in place, keeping face order.
  const aiScene* scene = importer.ReadFile(path, aiProcess_Triangulate);
  if (scene == nullptr) {
    std::string reason = importer.GetErrorString();
    if (reason.empty()) reason = "unknown assimp error";
    fail(path, "cannot be read as a mesh: " + reason);
  }
  if (scene->mRootNode == nullptr) fail(path, "the file holds no scene graph (no mesh)");

  SceneFlattener flattener{*scene, path, {}, {}, 0};
  flattener.visit(*scene->mRootNode, aiMatrix4x4());
  if (flattener.mesh.triangles.empty()) {
    std::string reason = "the file holds no triangle (" + std::to_string(scene->mNumMeshes) + " meshes";
    if (flattener.skipped_faces > 0) reason += ", " + std::to_string(flattener.skipped_faces) + " point or line primitives";
    fail(path, reason + ")");
  }
  try {
    validateMesh(flattener.mesh);
  } catch (const Error& e) {
    fail(path, e.what());
  }
  return std::move(flattener.mesh);
}

}  // namespace cfl
