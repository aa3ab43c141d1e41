#include "cfl/mesh_io.h"

#include "cfl/error.h"
#include "detail/mesh_assembly.h"
#include "detail/obj_reader.h"
#include "detail/stl_reader.h"

#include <Eigen/Geometry>
#include <assimp/Importer.hpp>
#include <assimp/scene.h>

#include <cctype>
#include <cerrno>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <iterator>
#include <limits>
#include <string>
#include <sys/stat.h>
#include <vector>

namespace cfl {
namespace {

[[noreturn]] void fail(const std::string& path, const std::string& reason) {
  throw Error(path + ": " + reason);
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
  detail::MeshAssembler assembler;
  std::size_t skipped_faces = 0;  // points and lines
  std::vector<int> polygon_;      // scratch

  int vertexId(const Eigen::Vector3d& p, std::size_t mesh_index, unsigned vertex_index) {
    if (!p.allFinite()) {
      fail(path, "vertex " + std::to_string(vertex_index) + " of mesh " + std::to_string(mesh_index) +
                     " has a non-finite coordinate");
    }
    return assembler.vertexId(p);
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
      polygon_.clear();
      for (unsigned c = 0; c < face.mNumIndices; ++c) polygon_.push_back(ids[face.mIndices[c]]);
      assembler.addPolygon(polygon_);
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

// The mesh read from `path`, refused with the path when it holds no triangle or fails validateMesh.
TriangleMesh checked(const std::string& path, TriangleMesh mesh, const std::string& contents) {
  if (mesh.triangles.empty()) fail(path, "the file holds no triangle (" + contents + ")");
  try {
    validateMesh(mesh);
  } catch (const Error& e) {
    fail(path, e.what());
  }
  return mesh;
}

std::string readFile(const std::string& path) {
  std::ifstream in(path, std::ios::binary);
  std::string text((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) fail(path, std::string("read error: ") + std::strerror(errno));
  return text;
}

TriangleMesh loadObj(const std::string& path) {
  std::size_t skipped = 0;
  TriangleMesh mesh = detail::readObj(path, readFile(path), &skipped);
  return checked(path, std::move(mesh), std::to_string(skipped) + " point or line primitives");
}

bool isAsciiStlFile(const std::string& path, std::uint64_t file_size) {
  std::ifstream in(path, std::ios::binary);
  std::string head(256, '\0');
  in.read(head.data(), std::streamsize(head.size()));
  head.resize(std::size_t(in.gcount()));
  return detail::isAsciiStl(head, file_size);
}

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
  if (hasExtension(path, "obj")) return loadObj(path);
  if (hasExtension(path, "stl") && isAsciiStlFile(path, std::uint64_t(info.st_size))) {
    return checked(path, detail::readAsciiStl(path, readFile(path)), "no facet");
  }
  if (hasExtension(path, "off")) checkOffHeader(path, info.st_size);

  Assimp::Importer importer;
  // No post-processing at all: FindDegenerates, SortByPType and FindInvalidData would drop or move
  // triangles the user's ids refer to, JoinIdenticalVertices is done here on positions alone (after the node
  // transforms), and polygons are triangulated here (see MeshAssembler::addPolygon).
  const aiScene* scene = importer.ReadFile(path, 0);
  if (scene == nullptr) {
    std::string reason = importer.GetErrorString();
    if (reason.empty()) reason = "unknown assimp error";
    fail(path, "cannot be read as a mesh: " + reason);
  }
  if (scene->mRootNode == nullptr) fail(path, "the file holds no scene graph (no mesh)");

  SceneFlattener flattener{*scene, path, {}, 0, {}};
  flattener.visit(*scene->mRootNode, aiMatrix4x4());
  std::string contents = std::to_string(scene->mNumMeshes) + " meshes";
  if (flattener.skipped_faces > 0)
    contents += ", " + std::to_string(flattener.skipped_faces) + " point or line primitives";
  return checked(path, flattener.assembler.take(), contents);
}

}  // namespace cfl
