// Closure analysis and pseudonormals of a mesh (mesh_sign.h).

#include "cfl/mesh_sign.h"

#include "cfl/triangle_distance.h"
#include "detail/exact_arithmetic.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <sstream>
#include <tuple>
#include <unordered_map>
#include <utility>

namespace cfl {
namespace {

// Welding is by exact position: hashed bit patterns, with -0 folded onto +0 so that the two zeros weld.
struct PositionKey {
  std::uint64_t bits[3];
  bool operator==(const PositionKey& other) const {
    return bits[0] == other.bits[0] && bits[1] == other.bits[1] && bits[2] == other.bits[2];
  }
};

struct PositionHash {
  std::size_t operator()(const PositionKey& key) const {
    std::uint64_t h = 0x9e3779b97f4a7c15ull;
    for (std::uint64_t b : key.bits) {
      h ^= b + 0x9e3779b97f4a7c15ull + (h << 6) + (h >> 2);
      h *= 0xff51afd7ed558ccdull;
    }
    return std::size_t(h ^ (h >> 33));
  }
};

PositionKey keyOf(const Eigen::Vector3d& v) {
  PositionKey key;
  for (int i = 0; i < 3; ++i) {
    const double x = v[i] == 0.0 ? 0.0 : v[i];
    std::memcpy(&key.bits[i], &x, sizeof(double));
  }
  return key;
}

// The first vertex at each position represents it, so the result does not depend on hashing.
std::vector<std::int32_t> weldVertices(const TriangleMesh& mesh) {
  std::vector<std::int32_t> welded(mesh.vertices.size());
  std::unordered_map<PositionKey, std::int32_t, PositionHash> first;
  first.reserve(mesh.vertices.size());
  for (std::size_t v = 0; v < mesh.vertices.size(); ++v) {
    welded[v] = first.emplace(keyOf(mesh.vertices[v]), std::int32_t(v)).first->second;
  }
  return welded;
}

// One directed edge of a triangle, keyed by its welded endpoints in increasing order.
struct EdgeUse {
  std::int32_t low, high;
  std::int32_t triangle;
  std::int8_t edge;     // corners edge and edge + 1 mod 3
  std::int8_t forward;  // 1 when the triangle traverses it from low to high
};

// Self-intersections between triangles that share no welded vertex, by a walk of the Bvh against itself.
// Returns the number found, at most `cap`; `first` receives the first pair.
std::int64_t countSelfIntersections(const MeshModel& model, const std::vector<std::int32_t>& welded,
                                    std::int64_t cap, std::pair<int, int>* first) {
  const auto& nodes = model.bvh.nodes;
  if (nodes.empty()) return 0;
  auto overlap = [](const Aabb& a, const Aabb& b) {
    return (a.min.array() <= b.max.array()).all() && (b.min.array() <= a.max.array()).all();
  };
  auto shareVertex = [&](int s, int t) {
    const auto& a = model.mesh.triangles[s];
    const auto& b = model.mesh.triangles[t];
    for (int i = 0; i < 3; ++i) {
      for (int j = 0; j < 3; ++j) {
        if (welded[a[i]] == welded[b[j]]) return true;
      }
    }
    return false;
  };
  std::int64_t found = 0;
  std::vector<std::pair<int, int>> stack{{0, 0}};
  while (!stack.empty() && found < cap) {
    const auto [i, j] = stack.back();
    stack.pop_back();
    const BvhNode& a = nodes[i];
    const BvhNode& b = nodes[j];
    if (i == j) {
      if (a.isLeaf()) {  // the leaf's own triangles, each pair once
        for (int x = a.first; x < a.first + a.count; ++x) {
          for (int y = x + 1; y < a.first + a.count; ++y) {
            const int s = model.bvh.triangle_ids[x], t = model.bvh.triangle_ids[y];
            if (shareVertex(s, t) || !trianglesIntersect(model.corners[s].data(), model.corners[t].data())) continue;
            if (found == 0) *first = {std::min(s, t), std::max(s, t)};
            if (++found >= cap) return found;
          }
        }
        continue;
      }
      stack.push_back({a.first, a.first + 1});
      stack.push_back({a.first + 1, a.first + 1});
      stack.push_back({a.first, a.first});
      continue;
    }
    // The spheres too: they are in double, while the float boxes lose their use on a mesh far from the
    // origin for its size (at 1e7 times its size, every box spans the whole mesh).
    if (!overlap(a.box(), b.box())) continue;
    const double reach = a.radius + b.radius;
    if ((a.center - b.center).squaredNorm() > reach * reach * (1 + 1e-9)) continue;
    if (a.isLeaf() && b.isLeaf()) {
      for (int x = a.first; x < a.first + a.count; ++x) {
        for (int y = b.first; y < b.first + b.count; ++y) {
          const int s = model.bvh.triangle_ids[x], t = model.bvh.triangle_ids[y];
          if (shareVertex(s, t)) continue;
          if (trianglesIntersect(model.corners[s].data(), model.corners[t].data())) {
            if (found == 0) *first = {std::min(s, t), std::max(s, t)};
            if (++found >= cap) return found;
          }
        }
      }
      continue;
    }
    // Split the node with more triangles (or the one that is not a leaf).
    const bool split_a = !a.isLeaf() && (b.isLeaf() || a.subtree_count >= b.subtree_count);
    if (split_a) {
      stack.push_back({a.first + 1, j});
      stack.push_back({a.first, j});
    } else {
      stack.push_back({i, b.first + 1});
      stack.push_back({i, b.first});
    }
  }
  return found;
}

// The far field of every Bvh node (WindingDipole), children before parents; leaves' too, which their
// parents are made of.
std::vector<WindingDipole> nodeDipoles(const MeshModel& model) {
  const auto& nodes = model.bvh.nodes;
  std::vector<WindingDipole> dipoles(nodes.size());
  std::vector<double> areas(nodes.size(), 0.0);
  // Children always follow their parent in the array (built top-down), so a reverse sweep sees children first.
  for (std::size_t k = nodes.size(); k-- > 0;) {
    const BvhNode& node = nodes[k];
    WindingDipole& d = dipoles[k];
    if (node.isLeaf()) {
      Eigen::Vector3d weighted = Eigen::Vector3d::Zero();
      double area_sum = 0;
      for (int i = node.first; i < node.first + node.count; ++i) {
        const auto& c = model.corners[model.bvh.triangle_ids[i]];
        const Eigen::Vector3d area_vector = 0.5 * detail::accurateNormal(c.data());
        const double area = area_vector.norm();
        d.area_normal += area_vector;
        weighted += area * (c[0] + c[1] + c[2]) / 3.0;
        area_sum += area;
      }
      areas[k] = area_sum;
      d.center = area_sum > 0 ? Eigen::Vector3d(weighted / area_sum) : node.center;
      for (int i = node.first; i < node.first + node.count; ++i) {
        const auto& c = model.corners[model.bvh.triangle_ids[i]];
        const Eigen::Vector3d area_vector = 0.5 * detail::accurateNormal(c.data());
        d.moment += area_vector * ((c[0] + c[1] + c[2]) / 3.0 - d.center).transpose();
        for (const Eigen::Vector3d& v : c) d.radius = std::max(d.radius, (v - d.center).norm());
      }
      continue;
    }
    const WindingDipole& l = dipoles[node.first];
    const WindingDipole& r = dipoles[node.first + 1];
    const double al = areas[node.first], ar = areas[node.first + 1];
    areas[k] = al + ar;
    d.center = areas[k] > 0 ? Eigen::Vector3d((al * l.center + ar * r.center) / areas[k]) : node.center;
    d.area_normal = l.area_normal + r.area_normal;
    // Moments move with their center: sum a n (g - c)^T = M_child + N_child (c_child - c)^T.
    d.moment = l.moment + l.area_normal * (l.center - d.center).transpose() + r.moment +
               r.area_normal * (r.center - d.center).transpose();
    d.radius = std::max((l.center - d.center).norm() + l.radius, (r.center - d.center).norm() + r.radius);
    // The node's own sphere may be tighter than the children's union about this center.
    d.radius = std::min(d.radius, (node.center - d.center).norm() + node.radius);
  }
  return dipoles;
}

}  // namespace

std::int64_t memoryBytes(const MeshSign& sign) {
  // The far field, when built, belongs to whoever asked for a winding number; a model's statistics count what
  // building it costs.
  return std::int64_t(sign.welded_vertex.capacity() * sizeof(std::int32_t) +
                      sign.neighbors.capacity() * sizeof(std::array<std::int32_t, 3>) +
                      sign.vertex_normals.capacity() * sizeof(Eigen::Vector3d));
}

const WindingField& windingField(const MeshModel& model, const MeshSign& sign) {
  static const WindingField none;
  if (!sign.winding) return none;
  WindingFieldCache& cache = *sign.winding;
  std::call_once(cache.once, [&] {
    const std::vector<WindingDipole> all = nodeDipoles(model);
    WindingField& field = cache.field;
    field.dipole_index.assign(all.size(), -1);
    for (std::size_t n = 0; n < all.size(); ++n) {
      if (model.bvh.nodes[n].isLeaf()) continue;
      field.dipole_index[n] = std::int32_t(field.node_dipoles.size());
      field.node_dipoles.push_back(all[n]);
    }
    field.node_dipoles.shrink_to_fit();
  });
  return cache.field;
}

MeshSign analyzeMeshSign(const MeshModel& model) {
  const TriangleMesh& mesh = model.mesh;
  const int triangle_count = int(mesh.triangles.size());
  MeshSign sign;
  MeshClosure& closure = sign.closure;
  sign.welded_vertex = weldVertices(mesh);
  const auto& welded = sign.welded_vertex;

  // Unnormalized normals, accurate in direction however thin the triangle; exactly zero only when the corners
  // are (to twice the working precision) collinear.
  std::vector<Eigen::Vector3d> normals(triangle_count);
  int first_degenerate = -1;
  for (int t = 0; t < triangle_count; ++t) {
    normals[t] = detail::accurateNormal(model.corners[t].data());
    if (normals[t] == Eigen::Vector3d::Zero()) {
      ++closure.degenerate_triangles;
      if (first_degenerate < 0) first_degenerate = t;
    }
  }

  // Edges: sort the directed uses by their welded endpoints; each run of equal endpoints is one edge.
  std::vector<EdgeUse> uses;
  uses.reserve(3 * std::size_t(triangle_count));
  for (int t = 0; t < triangle_count; ++t) {
    for (int e = 0; e < 3; ++e) {
      const std::int32_t a = welded[mesh.triangles[t][e]], b = welded[mesh.triangles[t][(e + 1) % 3]];
      if (a == b) continue;  // a repeated corner: the triangle is degenerate, counted above
      uses.push_back({std::min(a, b), std::max(a, b), t, std::int8_t(e), std::int8_t(a < b)});
    }
  }
  std::sort(uses.begin(), uses.end(), [](const EdgeUse& x, const EdgeUse& y) {
    return std::tie(x.low, x.high, x.triangle, x.edge) < std::tie(y.low, y.high, y.triangle, y.edge);
  });
  sign.neighbors.assign(triangle_count, {-1, -1, -1});
  // The first example of each defect, by triangle id then edge, for the reason.
  const EdgeUse* first_boundary = nullptr;
  const EdgeUse* first_nonmanifold = nullptr;
  std::pair<const EdgeUse*, const EdgeUse*> first_inconsistent{nullptr, nullptr};
  auto earlier = [](const EdgeUse* candidate, const EdgeUse* current) {
    return current == nullptr ||
           std::tie(candidate->triangle, candidate->edge) < std::tie(current->triangle, current->edge);
  };
  for (std::size_t begin = 0; begin < uses.size();) {
    std::size_t end = begin + 1;
    while (end < uses.size() && uses[end].low == uses[begin].low && uses[end].high == uses[begin].high) ++end;
    const std::size_t count = end - begin;
    if (count == 1) {
      ++closure.boundary_edges;
      if (earlier(&uses[begin], first_boundary)) first_boundary = &uses[begin];
    } else if (count >= 3) {
      ++closure.nonmanifold_edges;
      if (earlier(&uses[begin], first_nonmanifold)) first_nonmanifold = &uses[begin];
    } else {
      const EdgeUse& x = uses[begin];
      const EdgeUse& y = uses[begin + 1];
      if (x.forward == y.forward) {
        ++closure.inconsistent_edges;
        if (earlier(&x, first_inconsistent.first)) first_inconsistent = {&x, &y};
      }
      // Neighbors across the edge even when inconsistent: the edge pseudonormal is only used on closed meshes,
      // and the winding number does not read them.
      sign.neighbors[x.triangle][x.edge] = y.triangle;
      sign.neighbors[y.triangle][y.edge] = x.triangle;
    }
    begin = end;
  }

  // Orientation: the signed enclosed volume, about the box center so that far-off meshes lose no digits.
  const Eigen::Vector3d origin = model.bounds.empty() ? Eigen::Vector3d::Zero() : model.bounds.center();
  double volume6 = 0;
  for (int t = 0; t < triangle_count; ++t) {
    const auto& c = model.corners[t];
    volume6 += (c[0] - origin).dot((c[1] - origin).cross(c[2] - origin));
  }
  closure.orientation = volume6 >= 0 ? 1 : -1;

  // Self-intersections: the costliest check, reported on every mesh, capped so that the walk stops early on a
  // mesh that crosses itself a lot.
  std::pair<int, int> first_crossing{-1, -1};
  closure.intersecting_pairs = countSelfIntersections(model, welded, 1000, &first_crossing);

  std::ostringstream reason;
  if (first_boundary != nullptr) {
    const auto& tri = mesh.triangles[first_boundary->triangle];
    reason << "open: " << closure.boundary_edges << " boundary edge" << (closure.boundary_edges == 1 ? "" : "s")
           << " (the first between vertices " << tri[first_boundary->edge] << " and "
           << tri[(first_boundary->edge + 1) % 3] << " of triangle " << first_boundary->triangle << ")";
  } else if (first_nonmanifold != nullptr) {
    const auto& tri = mesh.triangles[first_nonmanifold->triangle];
    reason << "non-manifold: " << closure.nonmanifold_edges << " edge" << (closure.nonmanifold_edges == 1 ? "" : "s")
           << " with three or more triangles (the first between vertices " << tri[first_nonmanifold->edge] << " and "
           << tri[(first_nonmanifold->edge + 1) % 3] << " of triangle " << first_nonmanifold->triangle << ")";
  } else if (first_inconsistent.first != nullptr) {
    reason << "inconsistently oriented: " << closure.inconsistent_edges << " edge"
           << (closure.inconsistent_edges == 1 ? "" : "s")
           << " traversed in the same direction by both triangles (the first: triangles "
           << first_inconsistent.first->triangle << " and " << first_inconsistent.second->triangle << ")";
  } else if (first_degenerate >= 0) {
    reason << "degenerate triangle " << first_degenerate << " (zero area)";
    if (closure.degenerate_triangles > 1) reason << " and " << closure.degenerate_triangles - 1 << " more";
  } else if (closure.intersecting_pairs > 0) {
    reason << "self-intersecting: triangles " << first_crossing.first << " and " << first_crossing.second << " cross";
    if (closure.intersecting_pairs > 1) {
      reason << " (" << closure.intersecting_pairs << (closure.intersecting_pairs >= 1000 ? " or more" : "")
             << " crossing pairs)";
    }
  }
  closure.reason = reason.str();
  closure.closed = closure.reason.empty();

  // Angle-weighted vertex pseudonormals (Baerentzen & Aanaes 2005): each triangle adds its unit normal times
  // its angle at the vertex. Degenerate triangles add nothing (a closed mesh has none).
  sign.vertex_normals.assign(mesh.vertices.size(), Eigen::Vector3d::Zero());
  for (int t = 0; t < triangle_count; ++t) {
    const double length = normals[t].norm();
    if (!(length > 0)) continue;
    const Eigen::Vector3d unit = normals[t] / length;
    const auto& c = model.corners[t];
    for (int k = 0; k < 3; ++k) {
      const Eigen::Vector3d u = c[(k + 1) % 3] - c[k], v = c[(k + 2) % 3] - c[k];
      // atan2 of |u x v| and u . v: accurate for any angle, unlike acos of the normalized dot product.
      const double angle = std::atan2(u.cross(v).norm(), u.dot(v));
      sign.vertex_normals[welded[mesh.triangles[t][k]]] += angle * unit;
    }
  }
  for (Eigen::Vector3d& n : sign.vertex_normals) {
    const double length = n.norm();
    n = length > 0 ? Eigen::Vector3d(closure.orientation * n / length) : Eigen::Vector3d::Zero();
  }

  sign.winding = std::make_shared<WindingFieldCache>();
  return sign;
}

}  // namespace cfl
