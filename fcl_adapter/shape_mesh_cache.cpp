// The triangles of fcl::Box and fcl::Convex shapes as cfl::MeshModels, cached so that a shape met again costs
// a lookup instead of a rebuild.
//
// Lifetime: a box's triangles depend on its three side lengths only, so boxes are cached by value (two boxes
// of the same size share one entry, and editing `side` just selects another entry). A Convex is cached by
// address, and every lookup compares the cached copy of its vertices and faces with the shape's current
// ones, so a Convex destroyed and another created at the same address is never mistaken for it. Entries are
// shared_ptrs: dropping the cache (it is emptied when it grows past kMaxEntries) never frees one in use.

#include "adapter_internal.h"

#include <cfl/error.h>

#include <fcl/geometry/shape/box.h>
#include <fcl/geometry/shape/convex.h>

#include <array>
#include <map>
#include <mutex>
#include <string>
#include <utility>

namespace cfl_fcl::detail {
namespace {

// Far more shapes than a scene holds; a program creating boxes of ever new sizes stays bounded.
constexpr std::size_t kMaxEntries = 4096;

// Fans of the faces, each triangle turned to face away from the vertices' mean (an interior point of a
// convex polyhedron), so that the mesh is closed and outward whatever order the faces list their vertices.
std::shared_ptr<ShapeMesh> makeShapeMesh(const std::vector<Eigen::Vector3d>& vertices,
                                         const std::vector<std::vector<int>>& faces) {
  cfl::TriangleMesh mesh;
  mesh.vertices = vertices;
  Eigen::Vector3d interior = Eigen::Vector3d::Zero();
  for (const auto& v : vertices) interior += v;
  interior /= double(vertices.size());
  auto shape = std::make_shared<ShapeMesh>();
  for (const auto& face : faces) {
    for (std::size_t k = 1; k + 1 < face.size(); ++k) {
      std::array<int, 3> t{face[0], face[k], face[k + 1]};
      const Eigen::Vector3d &a = vertices[t[0]], &b = vertices[t[1]], &c = vertices[t[2]];
      Eigen::Vector3d n = (b - a).cross(c - a);
      if (n.dot((a + b + c) / 3 - interior) < 0) {
        std::swap(t[1], t[2]);
        n = -n;
      }
      mesh.triangles.push_back(t);
      const double length = n.norm();
      // Degenerate fan triangles bound nothing; the others' planes give the inside test.
      if (length > 0) shape->planes.emplace_back(n.x() / length, n.y() / length, n.z() / length, n.dot(a) / length);
    }
  }
  shape->mesh = std::make_shared<const cfl::MeshModel>(cfl::makeMeshModel(std::move(mesh)));
  return shape;
}

std::shared_ptr<ShapeMesh> boxMesh(const Eigen::Vector3d& side) {
  std::vector<Eigen::Vector3d> vertices;
  for (int i = 0; i < 8; ++i)
    vertices.emplace_back((i & 1 ? 0.5 : -0.5) * side.x(), (i & 2 ? 0.5 : -0.5) * side.y(),
                          (i & 4 ? 0.5 : -0.5) * side.z());
  // The six faces as quads of corner ids (bit 0: +x, bit 1: +y, bit 2: +z); makeShapeMesh orients them.
  const std::vector<std::vector<int>> faces = {{0, 2, 6, 4}, {1, 3, 7, 5}, {0, 1, 5, 4},
                                               {2, 3, 7, 6}, {0, 1, 3, 2}, {4, 5, 7, 6}};
  return makeShapeMesh(vertices, faces);
}

struct ConvexEntry {
  std::vector<Eigen::Vector3d> vertices;
  std::vector<int> faces;
  std::shared_ptr<ShapeMesh> shape;
};

std::mutex cache_mutex;
std::map<std::array<double, 3>, std::shared_ptr<ShapeMesh>> box_cache;
std::map<const void*, ConvexEntry> convex_cache;

}  // namespace

bool ShapeMesh::contains(const Eigen::Vector3d& p_S) const {
  for (const Eigen::Vector4d& plane : planes)
    if (plane.head<3>().dot(p_S) > plane.w()) return false;
  return true;
}

const cfl::CflModel& ShapeMesh::solid() const {
  std::call_once(solid_once, [this] {
    cfl::BuildOptions options;
    options.threads = 1;  // A dozen triangles: threads would cost more than they save.
    solid_model = std::make_unique<cfl::CflModel>(cfl::buildCflModel(mesh->mesh, options));
  });
  return *solid_model;
}

std::shared_ptr<const ShapeMesh> shapeMesh(const fcl::CollisionGeometry<double>& shape) {
  if (shape.getNodeType() == fcl::GEOM_BOX) {
    const auto& box = static_cast<const fcl::Box<double>&>(shape);
    if (!box.side.allFinite() || !(box.side.minCoeff() > 0))
      throw cfl::Error("cfl_fcl: an fcl::Box needs finite positive sides to be measured against a CFL geometry");
    const std::array<double, 3> key{box.side.x(), box.side.y(), box.side.z()};
    std::lock_guard<std::mutex> lock(cache_mutex);
    auto found = box_cache.find(key);
    if (found != box_cache.end()) return found->second;
    if (box_cache.size() >= kMaxEntries) box_cache.clear();
    return box_cache[key] = boxMesh(box.side);
  }
  if (shape.getNodeType() == fcl::GEOM_CONVEX) {
    const auto& convex = static_cast<const fcl::Convex<double>&>(shape);
    const auto& vertices = convex.getVertices();
    const auto& faces = convex.getFaces();
    std::lock_guard<std::mutex> lock(cache_mutex);
    auto found = convex_cache.find(&shape);
    if (found != convex_cache.end() && found->second.vertices == vertices && found->second.faces == faces)
      return found->second.shape;
    // FCL's face list: for each face, its vertex count, then its vertex ids.
    std::vector<std::vector<int>> polygons;
    for (std::size_t i = 0, f = 0; f < std::size_t(convex.getFaceCount()); ++f) {
      if (i >= faces.size()) throw cfl::Error("cfl_fcl: an fcl::Convex lists fewer faces than getFaceCount()");
      const int n = faces[i];
      if (n < 3 || i + 1 + std::size_t(n) > faces.size())
        throw cfl::Error("cfl_fcl: face " + std::to_string(f) + " of an fcl::Convex has a bad vertex count");
      std::vector<int> polygon(faces.begin() + long(i) + 1, faces.begin() + long(i) + 1 + n);
      for (int v : polygon)
        if (v < 0 || std::size_t(v) >= vertices.size())
          throw cfl::Error("cfl_fcl: face " + std::to_string(f) + " of an fcl::Convex names vertex " +
                           std::to_string(v) + " of " + std::to_string(vertices.size()));
      polygons.push_back(std::move(polygon));
      i += 1 + std::size_t(n);
    }
    if (convex_cache.size() >= kMaxEntries) convex_cache.clear();
    ConvexEntry& entry = convex_cache[&shape];
    entry.vertices = vertices;
    entry.faces = faces;
    entry.shape = makeShapeMesh(vertices, polygons);
    return entry.shape;
  }
  return nullptr;
}

}  // namespace cfl_fcl::detail
