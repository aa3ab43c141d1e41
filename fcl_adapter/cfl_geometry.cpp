#include "cfl_fcl/cfl_geometry.h"

#include "adapter_internal.h"

#include <cfl/cfl_file.h>

#include <climits>
#include <string>
#include <utility>

namespace cfl_fcl {

namespace {

cfl::TriangleMesh toMesh(const std::vector<fcl::Vector3d>& vertices, const std::vector<fcl::Triangle>& triangles) {
  cfl::TriangleMesh mesh;
  mesh.vertices = vertices;
  mesh.triangles.resize(triangles.size());
  for (std::size_t t = 0; t < triangles.size(); ++t)
    for (int c = 0; c < 3; ++c) {
      const std::size_t id = triangles[t][c];
      if (id >= vertices.size())
        throw cfl::Error("CFLGeometry: triangle " + std::to_string(t) + ": vertex index " + std::to_string(id) +
                         " is out of range [0, " + std::to_string(vertices.size()) + ")");
      if (id > std::size_t(INT_MAX))
        throw cfl::Error("CFLGeometry: triangle " + std::to_string(t) + ": vertex index " + std::to_string(id) +
                         " does not fit an int");
      mesh.triangles[t][c] = int(id);
    }
  return mesh;
}

}  // namespace

CFLGeometry::CFLGeometry(const std::vector<fcl::Vector3d>& vertices, const std::vector<fcl::Triangle>& triangles,
                         const cfl::BuildOptions& options) {
  // Before the expensive build: a program that would bypass the adapter learns it at once.
  detail::checkEntryPoints();
  model_ = std::make_shared<const cfl::CflModel>(cfl::buildCflModel(toMesh(vertices, triangles), options));
  computeLocalAABB();
}

CFLGeometry::CFLGeometry(std::shared_ptr<const cfl::CflModel> model) : model_(std::move(model)) {
  if (model_ == nullptr) throw cfl::Error("CFLGeometry: the shared cfl::CflModel is null");
  detail::checkEntryPoints();
  computeLocalAABB();
}

std::shared_ptr<CFLGeometry> CFLGeometry::load(const std::string& path) {
  detail::checkEntryPoints();
  return std::make_shared<CFLGeometry>(std::make_shared<const cfl::CflModel>(cfl::loadCflModel(path)));
}

void CFLGeometry::computeLocalAABB() {
  const cfl::Aabb& box = model_->geometry.bounds;
  aabb_local = fcl::AABB<double>(box.min, box.max);
  aabb_center = box.center();
  // The broadphase places the object with center and radius (CollisionObject::computeAABB for rotated
  // poses), so the radius must enclose every vertex: half the box diagonal does.
  aabb_radius = 0.5 * box.diagonal();
}

const fcl::BVHModel<fcl::OBBRSSd>& CFLGeometry::shapeProxy() const {
  std::call_once(shape_proxy_once_, [this] {
    const cfl::TriangleMesh& mesh = model_->geometry.mesh;
    std::vector<fcl::Triangle> triangles;
    triangles.reserve(mesh.triangles.size());
    for (const auto& t : mesh.triangles) triangles.emplace_back(t[0], t[1], t[2]);
    auto proxy = std::make_unique<fcl::BVHModel<fcl::OBBRSSd>>();
    if (proxy->beginModel(int(triangles.size()), int(mesh.vertices.size())) != fcl::BVH_OK ||
        proxy->addSubModel(mesh.vertices, triangles) != fcl::BVH_OK || proxy->endModel() != fcl::BVH_OK)
      throw cfl::Error("CFLGeometry: FCL refused to build the BVHModel<OBBRSS> used for primitive shapes");
    shape_proxy_ = std::move(proxy);
  });
  return *shape_proxy_;
}

}  // namespace cfl_fcl
