#pragma once
/// @file
/// Test support for signed distances: closed meshes, mesh edits, and an independent brute-force winding
/// number (no Bvh, no far field) to decide inside and outside.

#include "cfl/mesh.h"

#include <Eigen/Geometry>

#include <cmath>
#include <utility>

namespace cfl::test {

/// A closed UV sphere about the origin, outward: a pole fan at each end and quads between `rings` bands.
inline TriangleMesh makeSphere(double radius = 1.0, int rings = 10, int segments = 20) {
  const double pi = 3.14159265358979323846;
  TriangleMesh mesh;
  mesh.vertices.push_back({0, 0, radius});
  for (int i = 1; i < rings; ++i) {
    const double theta = pi * i / rings;
    for (int j = 0; j < segments; ++j) {
      const double phi = 2 * pi * j / segments;
      mesh.vertices.push_back(radius * Eigen::Vector3d(std::sin(theta) * std::cos(phi), std::sin(theta) * std::sin(phi),
                                                       std::cos(theta)));
    }
  }
  mesh.vertices.push_back({0, 0, -radius});
  const int south = int(mesh.vertices.size()) - 1;
  auto ring = [&](int i, int j) { return 1 + (i - 1) * segments + (j % segments); };
  for (int j = 0; j < segments; ++j) mesh.triangles.push_back({0, ring(1, j), ring(1, j + 1)});
  for (int i = 1; i + 1 < rings; ++i) {
    for (int j = 0; j < segments; ++j) {
      mesh.triangles.push_back({ring(i, j), ring(i + 1, j), ring(i + 1, j + 1)});
      mesh.triangles.push_back({ring(i, j), ring(i + 1, j + 1), ring(i, j + 1)});
    }
  }
  for (int j = 0; j < segments; ++j) mesh.triangles.push_back({south, ring(rings - 1, j + 1), ring(rings - 1, j)});
  return mesh;
}

/// The same triangles with three private vertices each, as an STL file gives them.
inline TriangleMesh toSoup(const TriangleMesh& mesh) {
  TriangleMesh soup;
  for (const auto& t : mesh.triangles) {
    const int base = int(soup.vertices.size());
    for (int k = 0; k < 3; ++k) soup.vertices.push_back(mesh.vertices[t[k]]);
    soup.triangles.push_back({base, base + 1, base + 2});
  }
  return soup;
}

/// Every triangle reversed: the same surface, inside out.
inline TriangleMesh flipped(TriangleMesh mesh) {
  for (auto& t : mesh.triangles) std::swap(t[1], t[2]);
  return mesh;
}

/// Independent reference: the winding number of `mesh` around p, the plain sum of every triangle's solid
/// angle (Van Oosterom & Strackee), written out again here.
inline double referenceWindingNumber(const TriangleMesh& mesh, const Eigen::Vector3d& p) {
  const double pi = 3.14159265358979323846;
  double total = 0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = mesh.vertices[t[0]] - p, b = mesh.vertices[t[1]] - p, c = mesh.vertices[t[2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double numerator = a.dot(b.cross(c));
    if (numerator == 0) continue;
    total += 2 * std::atan2(numerator, la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb);
  }
  return total / (4 * pi);
}

}  // namespace cfl::test
