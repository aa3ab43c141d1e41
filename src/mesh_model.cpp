#include "cfl/mesh_model.h"

#include <algorithm>
#include <cmath>

namespace cfl {

MeshModel makeMeshModel(TriangleMesh mesh) {
  validateMesh(mesh);
  MeshModel model;
  model.mesh = std::move(mesh);
  model.corners.resize(model.mesh.triangles.size());
  for (std::size_t t = 0; t < model.mesh.triangles.size(); ++t) {
    for (int corner = 0; corner < 3; ++corner) model.corners[t][corner] = model.mesh.vertices[model.mesh.triangles[t][corner]];
  }
  model.spheres.resize(model.corners.size());
  for (std::size_t t = 0; t < model.corners.size(); ++t) {
    const auto& c = model.corners[t];
    const Eigen::Vector3d center = (c[0] + c[1] + c[2]) / 3.0;
    const double radius = std::sqrt(std::max({(c[0] - center).squaredNorm(), (c[1] - center).squaredNorm(),
                                              (c[2] - center).squaredNorm()}));
    model.spheres[t] << center, radius;
  }
  model.bvh = buildBvh(model.mesh, 1);
  model.bounds = boundingBox(model.mesh);
  return model;
}

}  // namespace cfl
