#include "cfl/mesh_io.h"

#include "cfl/error.h"

#include <Eigen/Geometry>
#include <assimp/Importer.hpp>
#include <assimp/scene.h>

#include <array>
#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
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

// Appends the n - 2 triangles of the polygon `corners` (vertex ids in order) to `out`, consecutively and
// with the polygon's orientation. Done here rather than by aiProcess_Triangulate, which reorders the corners
// of some triangles and trips an assertion (abort) on some malformed files. Convex polygons, degenerate ones
// and those of more than kMaxEarClipping corners are fanned from corner 0; other concave polygons are ear
// clipped in the plane of their Newell normal, falling back to the fan when they are not simple. Either way
// the count, and with it every later triangle id, does not depend on the geometry.
void triangulatePolygon(const std::vector<Eigen::Vector3d>& vertices, const std::vector<int>& corners,
                        std::vector<std::array<int, 3>>* out) {
  constexpr std::size_t kMaxEarClipping = 256;  // ear clipping here is O(n^3)
  const std::size_t n = corners.size();
  const std::size_t first = out->size();
  auto fan = [&] {
    out->resize(first);
    for (std::size_t c = 1; c + 1 < n; ++c) out->push_back({corners[0], corners[c], corners[c + 1]});
  };
  Eigen::Vector3d normal = Eigen::Vector3d::Zero();
  for (std::size_t i = 0; i < n; ++i) {
    normal += vertices[std::size_t(corners[i])].cross(vertices[std::size_t(corners[(i + 1) % n])]);
  }
  if (!(normal.norm() > 0) || !normal.allFinite()) return fan();
  // (u, v, normal) is right-handed, so the polygon winds counter-clockwise in (u, v).
  const Eigen::Vector3d w = normal.normalized();
  const Eigen::Vector3d u = w.unitOrthogonal();
  const Eigen::Vector3d v = w.cross(u);
  std::vector<Eigen::Vector2d> p(n);
  for (std::size_t i = 0; i < n; ++i) {
    const Eigen::Vector3d& q = vertices[std::size_t(corners[i])];
    p[i] = Eigen::Vector2d(q.dot(u), q.dot(v));
  }
  auto turn = [&](std::size_t a, std::size_t b, std::size_t c) {
    const Eigen::Vector2d ab = p[b] - p[a], ac = p[c] - p[a];
    return ab.x() * ac.y() - ab.y() * ac.x();
  };
  bool convex = true;
  for (std::size_t i = 0; i < n && convex; ++i) convex = turn(i, (i + 1) % n, (i + 2) % n) >= 0;
  if (convex || n > kMaxEarClipping) return fan();

  std::vector<std::size_t> left(n);
  for (std::size_t i = 0; i < n; ++i) left[i] = i;
  while (left.size() > 3) {
    const std::size_t m = left.size();
    bool clipped = false;
    for (std::size_t k = 0; k < m && !clipped; ++k) {
      const std::size_t a = left[(k + m - 1) % m], b = left[k], c = left[(k + 1) % m];
      if (!(turn(a, b, c) > 0)) continue;  // reflex or flat corner
      bool blocked = false;
      for (std::size_t j : left) {
        if (j == a || j == b || j == c) continue;
        if (turn(a, b, j) >= 0 && turn(b, c, j) >= 0 && turn(c, a, j) >= 0) {
          blocked = true;
          break;
        }
      }
      if (blocked) continue;
      out->push_back({corners[a], corners[b], corners[c]});
      left.erase(left.begin() + std::ptrdiff_t(k));
      clipped = true;
    }
    if (!clipped) return fan();
  }
  out->push_back({corners[left[0]], corners[left[1]], corners[left[2]]});
}

// An OFF file's header declares its vertex and face counts, and assimp 5.2 allocates for them before reading
// a single vertex: a damaged header of 3.5e11 vertices took 86 s and 21 GB before failing, and a face count
// larger than the file holds loads the faces present without a word. Counts that the file's size cannot hold
// (a vertex takes at least 6 bytes, "0 0 0\n", and a face 8, "3 0 1 2\n") are refused here. Files that do
// not start with a plain OFF header are left to assimp.
void checkOffHeader(const std::string& path, std::int64_t file_size) {
  std::ifstream in(path, std::ios::binary);
  std::string keyword;
  while (in >> keyword && keyword[0] == '#') in.ignore(std::numeric_limits<std::streamsize>::max(), '\n');
  // nOFF puts a dimension before the counts; it and anything unknown are assimp's to judge.
  const bool plain_off = keyword.size() >= 3 && keyword.compare(keyword.size() - 3, 3, "OFF") == 0;
  if (!plain_off || keyword.find('n') != std::string::npos) return;
  long long vertices = 0, faces = 0;
  if (!(in >> vertices >> faces)) return;
  if (vertices < 0 || faces < 0) {
    fail(path, "the OFF header declares " + std::to_string(vertices) + " vertices and " + std::to_string(faces) +
                   " faces");
  }
  if (6.0 * double(vertices) + 8.0 * double(faces) > double(file_size)) {
    fail(path, "the OFF header declares " + std::to_string(vertices) + " vertices and " + std::to_string(faces) +
                   " faces, more than its " + std::to_string(file_size) +
                   " bytes can hold (6 per vertex and 8 per face at least): truncated or damaged");
  }
}

bool hasExtension(const std::string& path, const char* extension) {
  const std::size_t dot = path.find_last_of('.');
  if (dot == std::string::npos) return false;
  std::string suffix = path.substr(dot + 1);
  for (char& c : suffix) c = char(std::tolower(static_cast<unsigned char>(c)));
  return suffix == extension;
}

struct SceneFlattener {
  const aiScene& scene;
  const std::string& path;
  TriangleMesh mesh;
  std::unordered_map<PositionKey, int, PositionHash> vertex_ids;
  std::size_t skipped_faces = 0;  // points and lines
  std::vector<int> polygon_;      // scratch

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
    if (scene.mMeshes == nullptr || scene.mMeshes[mesh_index] == nullptr) {
      fail(path, "mesh " + std::to_string(mesh_index) + " is missing from the scene");
    }
    const aiMesh& m = *scene.mMeshes[mesh_index];
    if ((m.mVertices == nullptr && m.mNumVertices > 0) || (m.mFaces == nullptr && m.mNumFaces > 0)) {
      fail(path, "mesh " + std::to_string(mesh_index) + " has no vertex or face data");
    }
    // The node transform is applied to each vertex as it is first used; a cache keeps that to once per
    // vertex of this instance.
    std::vector<int> ids(m.mNumVertices, -1);
    for (unsigned f = 0; f < m.mNumFaces; ++f) {
      const aiFace& face = m.mFaces[f];
      if (face.mNumIndices < 3 || face.mIndices == nullptr) {
        ++skipped_faces;
        continue;
      }
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
      if (face.mNumIndices == 3) {
        mesh.triangles.push_back({ids[face.mIndices[0]], ids[face.mIndices[1]], ids[face.mIndices[2]]});
        continue;
      }
      polygon_.clear();
      for (unsigned c = 0; c < face.mNumIndices; ++c) polygon_.push_back(ids[face.mIndices[c]]);
      triangulatePolygon(mesh.vertices, polygon_, &mesh.triangles);
    }
  }

  void visit(const aiNode& node, const aiMatrix4x4& X_WParent) {
    const aiMatrix4x4 X_WN = X_WParent * node.mTransformation;
    if (node.mMeshes == nullptr && node.mNumMeshes > 0) {
      fail(path, "node '" + std::string(node.mName.C_Str()) + "' lists " + std::to_string(node.mNumMeshes) +
                     " meshes but holds none (assimp built an incomplete scene from this file)");
    }
    for (unsigned i = 0; i < node.mNumMeshes; ++i) {
      const unsigned mesh_index = node.mMeshes[i];
      if (mesh_index >= scene.mNumMeshes) {
        fail(path, "node '" + std::string(node.mName.C_Str()) + "' refers to mesh " + std::to_string(mesh_index) +
                       " of " + std::to_string(scene.mNumMeshes));
      }
      addMesh(mesh_index, X_WN);
    }
    for (unsigned i = 0; i < node.mNumChildren; ++i) {
      // assimp 5.2's RAW reader leaves a null child for every object after the first: refused, since
      // skipping it would drop part of the mesh without a word.
      if (node.mChildren == nullptr || node.mChildren[i] == nullptr) {
        fail(path, "node '" + std::string(node.mName.C_Str()) + "' lists " + std::to_string(node.mNumChildren) +
                       " children but child " + std::to_string(i) +
                       " is missing (assimp built an incomplete scene from this file)");
      }
      visit(*node.mChildren[i], X_WN);
    }
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
  if (hasExtension(path, "off")) checkOffHeader(path, info.st_size);

  Assimp::Importer importer;
  // No post-processing at all: FindDegenerates, SortByPType and FindInvalidData would drop or move
  // triangles the user's ids refer to, JoinIdenticalVertices is done here on positions alone (after the node
  // transforms), and polygons are triangulated here (see triangulatePolygon).
  const aiScene* scene = importer.ReadFile(path, 0);
  if (scene == nullptr) {
    std::string reason = importer.GetErrorString();
    if (reason.empty()) reason = "unknown assimp error";
    fail(path, "cannot be read as a mesh: " + reason);
  }
  if (scene->mRootNode == nullptr) fail(path, "the file holds no scene graph (no mesh)");

  SceneFlattener flattener{*scene, path, {}, {}, 0, {}};
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
