#include "support/test_meshes.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>
#include <stdexcept>

namespace cfl::test {
namespace {

constexpr double kPi = 3.14159265358979323846;

// Adds the quad (a, b, c, d) (counter-clockwise seen from outside) as two triangles.
void addQuad(TriangleMesh& mesh, int a, int b, int c, int d) {
  mesh.triangles.push_back({a, b, c});
  mesh.triangles.push_back({a, c, d});
}

// A closed tube: rings of `tube_segments` vertices around the closed curve centers[i] with frames
// (normals[i], binormals[i]); consecutive rings are joined, and the last ring to the first.
TriangleMesh makeClosedTube(const std::vector<Eigen::Vector3d>& centers, const std::vector<Eigen::Vector3d>& normals,
                            const std::vector<Eigen::Vector3d>& binormals, double radius, int tube_segments) {
  TriangleMesh mesh;
  const int n = static_cast<int>(centers.size());
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < tube_segments; ++j) {
      const double phi = 2 * kPi * j / tube_segments;
      mesh.vertices.push_back(centers[i] + radius * (std::cos(phi) * normals[i] + std::sin(phi) * binormals[i]));
    }
  }
  auto index = [&](int i, int j) { return (i % n) * tube_segments + (j % tube_segments); };
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < tube_segments; ++j) {
      addQuad(mesh, index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
    }
  }
  return mesh;
}

double pointSegmentSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a, const Eigen::Vector3d& b) {
  const Eigen::Vector3d ab = b - a;
  const double length2 = ab.squaredNorm();
  double t = 0;
  if (length2 > 0) t = std::clamp((p - a).dot(ab) / length2, 0.0, 1.0);
  return (p - (a + t * ab)).squaredNorm();
}

}  // namespace

TriangleMesh makeTorus(double major_radius, double minor_radius, int major_segments, int minor_segments) {
  std::vector<Eigen::Vector3d> centers, normals, binormals;
  for (int i = 0; i < major_segments; ++i) {
    const double theta = 2 * kPi * i / major_segments;
    const Eigen::Vector3d radial(std::cos(theta), std::sin(theta), 0);
    centers.push_back(major_radius * radial);
    normals.push_back(radial);
    binormals.push_back(Eigen::Vector3d::UnitZ());
  }
  return makeClosedTube(centers, normals, binormals, minor_radius, minor_segments);
}

TriangleMesh makeTorusKnot(int p, int q, double scale, double tube_radius, int segments, int tube_segments) {
  auto curve = [&](double t) -> Eigen::Vector3d {
    const double r = 2 + std::cos(q * t);
    return Eigen::Vector3d(r * std::cos(p * t), r * std::sin(p * t), -std::sin(q * t)) * scale;
  };
  std::vector<Eigen::Vector3d> centers, normals, binormals;
  for (int i = 0; i < segments; ++i) {
    const double t = 2 * kPi * i / segments;
    const double h = 1e-4;
    const Eigen::Vector3d c = curve(t);
    const Eigen::Vector3d tangent = (curve(t + h) - curve(t - h)).normalized();
    // The curve never runs toward the z axis, so the position's horizontal part is never along the tangent.
    const Eigen::Vector3d binormal = tangent.cross(Eigen::Vector3d(c.x(), c.y(), 0)).normalized();
    centers.push_back(c);
    binormals.push_back(binormal);
    normals.push_back(binormal.cross(tangent));
  }
  return makeClosedTube(centers, normals, binormals, tube_radius * scale, tube_segments);
}

TriangleMesh makeTriangleSoup(int triangle_count, std::uint64_t seed, double extent, double triangle_size) {
  Rng rng(seed);
  std::uniform_real_distribution<double> center(-extent, extent);
  std::uniform_real_distribution<double> offset(-triangle_size, triangle_size);
  TriangleMesh mesh;
  for (int t = 0; t < triangle_count; ++t) {
    const Eigen::Vector3d c(center(rng), center(rng), center(rng));
    const int first = static_cast<int>(mesh.vertices.size());
    for (int k = 0; k < 3; ++k) mesh.vertices.push_back(c + Eigen::Vector3d(offset(rng), offset(rng), offset(rng)));
    mesh.triangles.push_back({first, first + 1, first + 2});
  }
  return mesh;
}

TriangleMesh makeHemisphere(double radius, int rings, int segments) {
  TriangleMesh mesh;
  mesh.vertices.push_back(Eigen::Vector3d(0, 0, radius));  // the pole
  for (int r = 1; r <= rings; ++r) {
    const double polar = 0.5 * kPi * r / rings;
    for (int s = 0; s < segments; ++s) {
      const double azimuth = 2 * kPi * s / segments;
      mesh.vertices.push_back(radius * Eigen::Vector3d(std::sin(polar) * std::cos(azimuth),
                                                       std::sin(polar) * std::sin(azimuth), std::cos(polar)));
    }
  }
  auto index = [&](int r, int s) { return 1 + (r - 1) * segments + (s % segments); };
  for (int s = 0; s < segments; ++s) mesh.triangles.push_back({0, index(1, s), index(1, s + 1)});
  for (int r = 1; r < rings; ++r) {
    for (int s = 0; s < segments; ++s) addQuad(mesh, index(r, s), index(r + 1, s), index(r + 1, s + 1), index(r, s + 1));
  }
  return mesh;
}

TriangleMesh makeWavySheet(double size, double amplitude, int n) {
  TriangleMesh mesh;
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) {
      const double x = -size + 2 * size * i / n;
      const double y = -size + 2 * size * j / n;
      mesh.vertices.push_back(Eigen::Vector3d(x, y, amplitude * std::sin(2 * x) * std::cos(2 * y)));
    }
  }
  auto index = [&](int i, int j) { return i + (n + 1) * j; };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) addQuad(mesh, index(i, j), index(i + 1, j), index(i + 1, j + 1), index(i, j + 1));
  }
  return mesh;
}

TriangleMesh makeMessyMesh(int major_segments, int minor_segments) {
  if (major_segments < 8 || minor_segments < 6) throw std::invalid_argument("makeMessyMesh: torus too coarse");
  TriangleMesh mesh = makeTorus(1.0, 0.35, major_segments, minor_segments);
  const int base_triangles = static_cast<int>(mesh.triangles.size());
  auto addVertex = [&](const Eigen::Vector3d& v) {
    mesh.vertices.push_back(v);
    return static_cast<int>(mesh.vertices.size()) - 1;
  };
  // Flipped orientation on some triangles: the soup has no consistent winding.
  for (int t = 0; t < base_triangles; t += 7) std::swap(mesh.triangles[t][1], mesh.triangles[t][2]);
  // Zero-area triangles: a point, a segment with a repeated index, exactly collinear corners (dyadic
  // coordinates, so collinearity survives rounding), and a sliver that is almost but not quite collinear.
  mesh.triangles.push_back({5, 5, 5});
  mesh.triangles.push_back({9, 9, 40});
  const Eigen::Vector3d a(1.5, 0.25, 0.5), d(0.25, 0.5, -0.125);
  const int c0 = addVertex(a), c1 = addVertex(a + d), c3 = addVertex(a + 3 * d);
  mesh.triangles.push_back({c0, c3, c1});
  const int s0 = addVertex(Eigen::Vector3d(-1.6, -0.3, 0.1)), s1 = addVertex(Eigen::Vector3d(-0.4, 1.2, -0.2));
  const int s2 = addVertex(0.5 * (mesh.vertices[s0] + mesh.vertices[s1]) + Eigen::Vector3d(0, 0, 1e-9));
  mesh.triangles.push_back({s0, s1, s2});
  // Duplicates: same indices, permuted indices, and copies on duplicated vertices.
  for (int t = 0; t < 10; ++t) mesh.triangles.push_back(mesh.triangles[t]);
  for (int t = 10; t < 20; ++t) {
    const auto tri = mesh.triangles[t];
    mesh.triangles.push_back({tri[1], tri[2], tri[0]});
    mesh.triangles.push_back({tri[0], tri[2], tri[1]});
  }
  for (int t = 20; t < 30; ++t) {
    const auto tri = mesh.triangles[t];
    const int v0 = addVertex(mesh.vertices[tri[0]]);
    const int v1 = addVertex(mesh.vertices[tri[1]]);
    const int v2 = addVertex(mesh.vertices[tri[2]]);
    mesh.triangles.push_back({v0, v1, v2});
  }
  // Non-manifold edges: two extra wings on a torus edge (4 triangles on it), and a free-standing fan of four
  // triangles on one edge above the hole.
  {
    const auto tri = mesh.triangles[100];
    const Eigen::Vector3d mid = 0.5 * (mesh.vertices[tri[0]] + mesh.vertices[tri[1]]);
    const int w0 = addVertex(mid + Eigen::Vector3d(0, 0, 0.5));
    const int w1 = addVertex(mid + Eigen::Vector3d(0.3, 0.3, -0.4));
    mesh.triangles.push_back({tri[0], tri[1], w0});
    mesh.triangles.push_back({tri[1], tri[0], w1});
  }
  {
    const int e0 = addVertex(Eigen::Vector3d(0, 0, 0.4)), e1 = addVertex(Eigen::Vector3d(0, 0, 1.0));
    for (int k = 0; k < 4; ++k) {
      const double angle = 0.5 * kPi * k + 0.3;
      const int w = addVertex(Eigen::Vector3d(0.45 * std::cos(angle), 0.45 * std::sin(angle), 0.7));
      mesh.triangles.push_back({e0, e1, w});
    }
  }
  // A vertex no triangle uses, far away: it must not count for bounds or distances.
  addVertex(Eigen::Vector3d(100, -100, 100));
  return mesh;
}

TriangleMesh makeThinPlate(double size, double thickness, int n) {
  TriangleMesh mesh;
  for (int face = 0; face < 2; ++face) {  // bottom, then top
    for (int j = 0; j <= n; ++j) {
      for (int i = 0; i <= n; ++i) {
        mesh.vertices.push_back(
            Eigen::Vector3d(-size + 2 * size * i / n, -size + 2 * size * j / n, (face - 0.5) * thickness));
      }
    }
  }
  const int top = (n + 1) * (n + 1);
  auto index = [&](int i, int j) { return i + (n + 1) * j; };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) {
      addQuad(mesh, top + index(i, j), top + index(i + 1, j), top + index(i + 1, j + 1), top + index(i, j + 1));
      addQuad(mesh, index(i, j), index(i, j + 1), index(i + 1, j + 1), index(i + 1, j));
    }
  }
  // The rim, counterclockwise seen from above, so that each strip faces out.
  std::vector<int> rim;
  for (int i = 0; i < n; ++i) rim.push_back(index(i, 0));
  for (int j = 0; j < n; ++j) rim.push_back(index(n, j));
  for (int i = n; i > 0; --i) rim.push_back(index(i, n));
  for (int j = n; j > 0; --j) rim.push_back(index(0, j));
  for (std::size_t k = 0; k < rim.size(); ++k) {
    const int p = rim[k], q = rim[(k + 1) % rim.size()];
    addQuad(mesh, p, q, top + q, top + p);
  }
  return mesh;
}

TriangleMesh makeLocallyRefinedSlab(int n) {
  TriangleMesh mesh;
  auto vertex = [&](const Eigen::Vector3d& p) {
    mesh.vertices.push_back(p);
    return static_cast<int>(mesh.vertices.size()) - 1;
  };
  const int first = static_cast<int>(mesh.vertices.size());
  for (int j = 0; j <= n; ++j) {
    for (int i = 0; i <= n; ++i) vertex(Eigen::Vector3d(4.9 + 0.2 * i / n, 4.9 + 0.2 * j / n, 1.0));
  }
  auto patch = [&](int i, int j) { return first + i + (n + 1) * j; };
  for (int j = 0; j < n; ++j) {
    for (int i = 0; i < n; ++i) addQuad(mesh, patch(i, j), patch(i + 1, j), patch(i + 1, j + 1), patch(i, j + 1));
  }
  const int top[4] = {vertex(Eigen::Vector3d(0, 0, 1)), vertex(Eigen::Vector3d(10, 0, 1)),
                      vertex(Eigen::Vector3d(10, 10, 1)), vertex(Eigen::Vector3d(0, 10, 1))};
  for (int side = 0; side < 4; ++side) {
    // The patch's boundary along this side, from the end near top[side] to the end near the next corner.
    std::vector<int> edge;
    for (int k = 0; k <= n; ++k) {
      edge.push_back(side == 0 ? patch(k, 0) : side == 1 ? patch(n, k) : side == 2 ? patch(n - k, n) : patch(0, n - k));
    }
    const int a = top[side], c = top[(side + 1) % 4];
    for (int k = 0; k < n; ++k) mesh.triangles.push_back({k < n / 2 ? a : c, edge[k + 1], edge[k]});
    mesh.triangles.push_back({a, c, edge[n / 2]});
  }
  const int bottom[4] = {vertex(Eigen::Vector3d(0, 0, 0)), vertex(Eigen::Vector3d(10, 0, 0)),
                         vertex(Eigen::Vector3d(10, 10, 0)), vertex(Eigen::Vector3d(0, 10, 0))};
  addQuad(mesh, bottom[0], bottom[3], bottom[2], bottom[1]);
  for (int s = 0; s < 4; ++s) addQuad(mesh, bottom[s], bottom[(s + 1) % 4], top[(s + 1) % 4], top[s]);
  return mesh;
}

TriangleMesh makeBox(const Eigen::Vector3d& min, const Eigen::Vector3d& max) {
  TriangleMesh mesh;
  for (int k = 0; k < 8; ++k) {
    mesh.vertices.push_back(Eigen::Vector3d((k & 1) ? max.x() : min.x(), (k & 2) ? max.y() : min.y(),
                                            (k & 4) ? max.z() : min.z()));
  }
  addQuad(mesh, 0, 2, 3, 1);  // z = min
  addQuad(mesh, 4, 5, 7, 6);  // z = max
  addQuad(mesh, 0, 1, 5, 4);  // y = min
  addQuad(mesh, 2, 6, 7, 3);  // y = max
  addQuad(mesh, 0, 4, 6, 2);  // x = min
  addQuad(mesh, 1, 3, 7, 5);  // x = max
  return mesh;
}

TriangleMesh merge(const TriangleMesh& a, const TriangleMesh& b) {
  TriangleMesh mesh = a;
  const int offset = static_cast<int>(a.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), b.vertices.begin(), b.vertices.end());
  for (const auto& t : b.triangles) mesh.triangles.push_back({t[0] + offset, t[1] + offset, t[2] + offset});
  return mesh;
}

std::vector<std::pair<std::string, TriangleMesh>> makeFeaturePruningMeshes() {
  return {{"blocks", merge(makeBox(Eigen::Vector3d(-1, -1, -1), Eigen::Vector3d(0, 0, 0)),
                           makeBox(Eigen::Vector3d(0.5, 0.5, 0.5), Eigen::Vector3d(1, 2, 1)))},
          {"messy", makeMessyMesh()},
          {"hemisphere", makeHemisphere()}};
}

TriangleMesh makeSelfIntersectingMesh(int major_segments, int minor_segments) {
  const TriangleMesh torus = makeTorus(1.0, 0.3, major_segments, minor_segments);
  // A second torus, standing up in the xz plane and shifted so that its tube cuts through the first's.
  TriangleMesh linked = torus;
  const Eigen::Matrix3d rotation = Eigen::AngleAxisd(0.5 * kPi, Eigen::Vector3d::UnitX()).toRotationMatrix();
  for (auto& v : linked.vertices) v = rotation * v + Eigen::Vector3d(0.5, 0, 0);
  // A bar that the first torus' tube passes through.
  const TriangleMesh bar = makeBox(Eigen::Vector3d(-1.4, -0.15, -0.6), Eigen::Vector3d(-0.6, 0.15, 0.6));
  return merge(merge(torus, linked), bar);
}

TriangleMesh readObj(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw std::runtime_error("cannot open " + path);
  TriangleMesh mesh;
  std::string line;
  int line_number = 0;
  while (std::getline(in, line)) {
    ++line_number;
    std::istringstream words(line);
    std::string tag;
    if (!(words >> tag)) continue;
    if (tag == "v") {
      Eigen::Vector3d v;
      if (!(words >> v.x() >> v.y() >> v.z())) {
        throw std::runtime_error(path + ":" + std::to_string(line_number) + ": bad vertex");
      }
      mesh.vertices.push_back(v);
    } else if (tag == "f") {
      std::vector<int> polygon;
      std::string word;
      while (words >> word) {
        const int index = std::stoi(word.substr(0, word.find('/')));
        polygon.push_back(index > 0 ? index - 1 : static_cast<int>(mesh.vertices.size()) + index);
      }
      if (polygon.size() < 3) throw std::runtime_error(path + ":" + std::to_string(line_number) + ": bad face");
      for (std::size_t k = 1; k + 1 < polygon.size(); ++k) {
        mesh.triangles.push_back({polygon[0], polygon[k], polygon[k + 1]});
      }
    }
  }
  return mesh;
}

TriangleMesh loadBunny() { return readObj(std::string(CFL_DATA_DIR) + "/bunny.obj"); }

Eigen::Matrix3d randomRotation(Rng& rng) {
  std::normal_distribution<double> gaussian;
  Eigen::Quaterniond q;
  do {
    q = Eigen::Quaterniond(gaussian(rng), gaussian(rng), gaussian(rng), gaussian(rng));
  } while (q.norm() < 1e-6);
  return q.normalized().toRotationMatrix();
}

Eigen::Isometry3d randomPose(Rng& rng, double translation_range) {
  std::uniform_real_distribution<double> uniform(-translation_range, translation_range);
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.linear() = randomRotation(rng);
  X.translation() = Eigen::Vector3d(uniform(rng), uniform(rng), uniform(rng));
  return X;
}

Eigen::Isometry3d placeAtDistance(const std::function<double(const Eigen::Isometry3d& X_WB)>& distance,
                                  const Eigen::Vector3d& center_a, const Aabb& bounds_b, double target,
                                  double tolerance, Rng& rng) {
  std::normal_distribution<double> gaussian;
  Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
  for (int attempt = 0; attempt < 100; ++attempt) {
    X_WB.linear() = randomRotation(rng);
    Eigen::Vector3d direction(gaussian(rng), gaussian(rng), gaussian(rng));
    direction.normalize();
    const Eigen::Vector3d start = center_a - X_WB.linear() * bounds_b.center();
    auto at = [&](double s) {
      Eigen::Isometry3d X = X_WB;
      X.translation() = start + s * direction;
      return X;
    };
    // Concentric shapes usually overlap; try another rotation and direction when they do not.
    if (distance(at(0)) > target) continue;
    if (target == 0) return at(0);
    double lo = 0, hi = bounds_b.diagonal() + target;
    for (int doubling = 0; distance(at(hi)) < target; ++doubling) {
      if (doubling == 60) throw std::runtime_error("placeAtDistance: the distance never reaches the target");
      hi *= 2;
    }
    // Invariant: distance(lo) <= target <= distance(hi); distance is continuous, so a crossing lies between.
    for (int iteration = 0; iteration < 200; ++iteration) {
      const double mid = 0.5 * (lo + hi);
      const double d = distance(at(mid));
      if (std::abs(d - target) <= tolerance) return at(mid);
      (d < target ? lo : hi) = mid;
    }
    return at(hi);
  }
  throw std::runtime_error("placeAtDistance: no overlapping start pose found in 100 attempts");
}

double referencePointTriangleSquaredDistance(const Eigen::Vector3d& p, const Eigen::Vector3d& a,
                                             const Eigen::Vector3d& b, const Eigen::Vector3d& c) {
  // The closest point is either interior (the plane projection, when it falls inside) or on an edge.
  double best = std::min({pointSegmentSquaredDistance(p, a, b), pointSegmentSquaredDistance(p, b, c),
                          pointSegmentSquaredDistance(p, c, a)});
  const Eigen::Vector3d n = (b - a).cross(c - a);
  const double n2 = n.squaredNorm();
  const double scale2 = std::max({(b - a).squaredNorm(), (c - b).squaredNorm(), (a - c).squaredNorm()});
  // Below this area the normal's direction is noise; the edges are then within 1e-12 * edge of the answer.
  if (n2 > 1e-24 * scale2 * scale2) {
    const double height = n.dot(p - a);
    const Eigen::Vector3d q = p - n * (height / n2);
    const bool inside = n.dot((b - a).cross(q - a)) >= 0 && n.dot((c - b).cross(q - b)) >= 0 &&
                        n.dot((a - c).cross(q - c)) >= 0;
    if (inside) best = std::min(best, height * height / n2);
  }
  return best;
}

double referencePointMeshDistance(const TriangleMesh& mesh, const Eigen::Vector3d& p, const Eigen::Isometry3d& X,
                                  int* triangle) {
  // Bring p into the mesh frame instead of moving every vertex: distances are invariant under rigid motion.
  const Eigen::Vector3d p_M = X.inverse() * p;
  double best = std::numeric_limits<double>::infinity();
  for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
    const auto& tri = mesh.triangles[t];
    const double d2 = referencePointTriangleSquaredDistance(p_M, mesh.vertices[tri[0]], mesh.vertices[tri[1]],
                                                            mesh.vertices[tri[2]]);
    if (d2 < best) {
      best = d2;
      if (triangle) *triangle = static_cast<int>(t);
    }
  }
  return std::sqrt(best);
}

Eigen::Vector3d randomPointOnTriangle(const TriangleMesh& mesh, int t, Rng& rng) {
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  double u = uniform(rng), v = uniform(rng);
  if (u + v > 1) {
    u = 1 - u;
    v = 1 - v;
  }
  const auto& tri = mesh.triangles[t];
  const Eigen::Vector3d& a = mesh.vertices[tri[0]];
  return a + u * (mesh.vertices[tri[1]] - a) + v * (mesh.vertices[tri[2]] - a);
}

}  // namespace cfl::test
