#include "detail/mesh_assembly.h"

#include <Eigen/Geometry>

#include <array>

namespace cfl::detail {
namespace {

// Done here rather than by aiProcess_Triangulate, which reorders the corners of some triangles and trips an
// assertion (abort) on some malformed files.
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

}  // namespace

std::size_t MeshAssembler::PositionHash::operator()(const PositionKey& k) const {
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

int MeshAssembler::vertexId(const Eigen::Vector3d& p) {
  auto [it, inserted] = ids_.emplace(PositionKey{p.x(), p.y(), p.z()}, int(mesh_.vertices.size()));
  if (inserted) mesh_.vertices.push_back(p);
  return it->second;
}

void MeshAssembler::addPolygon(const std::vector<int>& corners) {
  if (corners.size() == 3) {
    mesh_.triangles.push_back({corners[0], corners[1], corners[2]});
    return;
  }
  triangulatePolygon(mesh_.vertices, corners, &mesh_.triangles);
}

}  // namespace cfl::detail
