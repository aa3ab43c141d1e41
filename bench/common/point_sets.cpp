#include "point_sets.h"

#include "cfl/error.h"

#include <Eigen/Geometry>

#include <random>

namespace cfl::bench {

std::vector<Eigen::Vector3d> nearSurfacePoints(const TriangleMesh& mesh, std::size_t count, double reach,
                                               std::uint64_t seed) {
  std::vector<double> areas(mesh.triangles.size());
  double total = 0;
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& v = mesh.triangles[t];
    areas[t] = (mesh.vertices[v[1]] - mesh.vertices[v[0]]).cross(mesh.vertices[v[2]] - mesh.vertices[v[0]]).norm();
    total += areas[t];
  }
  if (!(total > 0)) throw Error("near-surface points: the mesh has no triangle of positive area");
  std::mt19937_64 rng(seed);
  std::discrete_distribution<std::size_t> pick(areas.begin(), areas.end());
  std::uniform_real_distribution<double> u(0, 1);
  std::normal_distribution<double> g(0, 1);
  std::vector<Eigen::Vector3d> points;
  points.reserve(count);
  for (std::size_t i = 0; i < count; ++i) {
    const auto& v = mesh.triangles[pick(rng)];
    double a = u(rng), b = u(rng);
    if (a + b > 1) {  // folded back into the triangle: uniform over its area
      a = 1 - a;
      b = 1 - b;
    }
    const Eigen::Vector3d on = mesh.vertices[v[0]] + a * (mesh.vertices[v[1]] - mesh.vertices[v[0]]) +
                               b * (mesh.vertices[v[2]] - mesh.vertices[v[0]]);
    const Eigen::Vector3d direction = Eigen::Vector3d(g(rng), g(rng), g(rng)).normalized();
    points.push_back(on + direction * (reach * u(rng)));
  }
  return points;
}

std::vector<Eigen::Vector3d> boxPoints(const Aabb& box, std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  std::uniform_real_distribution<double> u(-1, 1);
  // Twice the box about its center: half extents equal to the box's full size.
  const Eigen::Vector3d c = box.center(), h = box.size();
  std::vector<Eigen::Vector3d> points;
  points.reserve(count);
  for (std::size_t i = 0; i < count; ++i) points.emplace_back(c.x() + h.x() * u(rng), c.y() + h.y() * u(rng), c.z() + h.z() * u(rng));
  return points;
}

}  // namespace cfl::bench
