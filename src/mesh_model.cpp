#include "cfl/mesh_model.h"

#include "detail/exact_arithmetic.h"

#include <algorithm>
#include <cmath>

#include <Eigen/Geometry>

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
  model.planes.resize(model.corners.size());
  for (std::size_t t = 0; t < model.corners.size(); ++t) {
    const auto& c = model.corners[t];
    const Eigen::Vector3d center = (c[0] + c[1] + c[2]) / 3.0;
    const double radius = std::sqrt(std::max({(c[0] - center).squaredNorm(), (c[1] - center).squaredNorm(),
                                              (c[2] - center).squaredNorm()}));
    model.spheres[t] << center, radius;
    // The query prunes a pair when the plane puts the other triangle beyond the best distance so far: a
    // normal off by an angle a moves that bound by a times the corners' offsets. The plain cross product of
    // a sliver is off by about eps / sin(angle), enough to prune the closest pair of a triangle whose
    // height is 1e-10 of its length; the accurate one is off by a few eps.
    const Eigen::Vector3d normal = detail::accurateNormal(c.data());
    const double length = normal.norm();
    // Thinner than this (height 1e-12 of the longest edge) it gets no plane: its pairs go without that bound.
    const double longest_edge = std::sqrt(std::max({(c[1] - c[0]).squaredNorm(), (c[2] - c[1]).squaredNorm(),
                                                    (c[0] - c[2]).squaredNorm()}));
    if (length > 1e-12 * longest_edge * longest_edge && length > 0) {
      const Eigen::Vector3d unit = normal / length;
      model.planes[t] << unit, unit.dot(c[0]);
    } else {
      model.planes[t].setZero();
    }
  }
  model.bvh = buildBvh(model.mesh, 1);
  model.bounds = boundingBox(model.mesh);
  return model;
}

}  // namespace cfl
