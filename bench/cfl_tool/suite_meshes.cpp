// The meshes of `cfl suite`. Each generator stands for a kind of mesh users bring that the bundled compact
// scans do not: flat, thin, sparse, unevenly detailed, broken or huge. Sizes are in the units a CAD or
// scanning tool would write (tens to hundreds), so absolute tolerances meet realistic magnitudes.

#include "suite_meshes.h"

#include "cfl/error.h"
#include "cfl/mesh.h"
#include "cfl/mesh_io.h"
#include "tool_support.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cerrno>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <map>
#include <optional>
#include <set>
#include <sstream>
#include <cstring>

namespace cfl::tool {
namespace {

using Vec3 = Eigen::Vector3d;
constexpr double kPi = 3.14159265358979323846;

// Collects triangles and merges vertices that land on the same point, so that parts generated separately
// (cells of a plate, pages of a book) share their seams as a modeller's output would.
class MeshBuilder {
 public:
  int vertex(const Vec3& p) {
    // Quantized so that a seam point computed along two routes, which may differ in the last bits, is still
    // one vertex; the step is far below any feature of these meshes.
    const std::array<std::int64_t, 3> key = {std::llround(p.x() * kQuantum), std::llround(p.y() * kQuantum),
                                             std::llround(p.z() * kQuantum)};
    const auto it = index_.find(key);
    if (it != index_.end()) return it->second;
    mesh_.vertices.push_back(p);
    const int id = int(mesh_.vertices.size()) - 1;
    index_.emplace(key, id);
    return id;
  }
  void triangle(int a, int b, int c) { mesh_.triangles.push_back({a, b, c}); }
  void triangle(const Vec3& a, const Vec3& b, const Vec3& c) { triangle(vertex(a), vertex(b), vertex(c)); }
  // a, b, c, d counter-clockwise seen from the side the normal points to.
  void quad(int a, int b, int c, int d) {
    triangle(a, b, c);
    triangle(a, c, d);
  }
  void append(const TriangleMesh& m) {
    for (const auto& t : m.triangles) triangle(m.vertices[t[0]], m.vertices[t[1]], m.vertices[t[2]]);
  }
  TriangleMesh take() { return std::move(mesh_); }

 private:
  static constexpr double kQuantum = double(1 << 24);
  TriangleMesh mesh_;
  std::map<std::array<std::int64_t, 3>, int> index_;
};

using Ring = std::vector<Vec3>;

// Joins consecutive closed rings (all of one size) with quads; outward when each ring runs counter-clockwise
// about the direction from the first ring to the last. An apex closes an end with a fan (a pole or a cap's
// center).
void sweep(MeshBuilder& b, const std::vector<Ring>& rings, std::optional<Vec3> start_apex,
           std::optional<Vec3> end_apex) {
  std::vector<std::vector<int>> ids;
  for (const Ring& r : rings) {
    ids.emplace_back();
    for (const Vec3& p : r) ids.back().push_back(b.vertex(p));
  }
  const std::size_t n = rings.front().size();
  for (std::size_t i = 0; i + 1 < ids.size(); ++i) {
    for (std::size_t k = 0; k < n; ++k) {
      const std::size_t k1 = (k + 1) % n;
      b.quad(ids[i][k], ids[i][k1], ids[i + 1][k1], ids[i + 1][k]);
    }
  }
  if (start_apex) {
    const int c = b.vertex(*start_apex);
    for (std::size_t k = 0; k < n; ++k) b.triangle(c, ids.front()[(k + 1) % n], ids.front()[k]);
  }
  if (end_apex) {
    const int c = b.vertex(*end_apex);
    for (std::size_t k = 0; k < n; ++k) b.triangle(c, ids.back()[k], ids.back()[(k + 1) % n]);
  }
}

Vec3 centroid(const Ring& r) {
  Vec3 c = Vec3::Zero();
  for (const Vec3& p : r) c += p;
  return c / double(r.size());
}

// Two unit vectors completing `axis` to a right-handed frame.
std::pair<Vec3, Vec3> perpendiculars(const Vec3& axis) {
  const Vec3 a = axis.normalized();
  const Vec3 u = a.cross(std::abs(a.x()) < 0.9 ? Vec3::UnitX() : Vec3::UnitY()).normalized();
  return {u, a.cross(u)};
}

Ring circle(const Vec3& center, const Vec3& axis, double radius, int sides, double phase = 0) {
  const auto [u, v] = perpendiculars(axis);
  Ring r;
  for (int k = 0; k < sides; ++k) {
    const double t = phase + 2 * kPi * k / sides;
    r.push_back(center + radius * (std::cos(t) * u + std::sin(t) * v));
  }
  return r;
}

// A closed (capped) cylinder or cone frustum from p0 to p1.
void cylinder(MeshBuilder& b, const Vec3& p0, const Vec3& p1, double r0, double r1, int sides, int segments,
              bool caps = true) {
  const Vec3 axis = p1 - p0;
  std::vector<Ring> rings;
  for (int i = 0; i <= segments; ++i) {
    const double t = double(i) / segments;
    rings.push_back(circle(p0 + t * axis, axis, r0 + t * (r1 - r0), sides));
  }
  if (caps) {
    sweep(b, rings, p0, p1);
  } else {
    sweep(b, rings, std::nullopt, std::nullopt);
  }
}

void ellipsoid(MeshBuilder& b, const Vec3& center, const Vec3& radii, int slices, int stacks) {
  std::vector<Ring> rings;
  for (int i = 1; i < stacks; ++i) {
    const double polar = kPi * i / stacks;  // from the bottom pole
    Ring r;
    for (int k = 0; k < slices; ++k) {
      const double t = 2 * kPi * k / slices;
      r.push_back(center + Vec3(radii.x() * std::sin(polar) * std::cos(t), radii.y() * std::sin(polar) * std::sin(t),
                                -radii.z() * std::cos(polar)));
    }
    rings.push_back(r);
  }
  sweep(b, rings, center - Vec3(0, 0, radii.z()), center + Vec3(0, 0, radii.z()));
}

void box(MeshBuilder& b, const Vec3& lo, const Vec3& hi) {
  auto corner = [&](int i) { return b.vertex(Vec3(i & 1 ? hi.x() : lo.x(), i & 2 ? hi.y() : lo.y(), i & 4 ? hi.z() : lo.z())); };
  const int faces[6][4] = {{0, 2, 3, 1}, {4, 5, 7, 6}, {0, 1, 5, 4}, {2, 6, 7, 3}, {0, 4, 6, 2}, {1, 3, 7, 5}};
  for (const auto& f : faces) b.quad(corner(f[0]), corner(f[1]), corner(f[2]), corner(f[3]));
}

// A small deterministic generator (splitmix64), so the suite is the same bytes everywhere.
class Random {
 public:
  explicit Random(std::uint64_t seed) : state_(seed) {}
  double uniform(double lo, double hi) {
    std::uint64_t z = (state_ += 0x9e3779b97f4a7c15ULL);
    z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
    z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
    z ^= z >> 31;
    return lo + (hi - lo) * double(z >> 11) / double(1ULL << 53);
  }

 private:
  std::uint64_t state_;
};

// ---- the meshes ---------------------------------------------------------------------------------------------

// A turbine blade: an elliptic airfoil 10 wide and 0.65 thick swept 130 along the span, tapering and
// leaning back toward the tip. Long, flat and closed; a uniform grid over its box is flat too.
TriangleMesh blade() {
  MeshBuilder b;
  constexpr int kAround = 80, kSpan = 100;
  std::vector<Ring> rings;
  for (int i = 0; i < kSpan; ++i) {
    const double s = double(i) / (kSpan - 1);
    const double y = 130 * s, half_chord = 5 * (1 - 0.2 * s), half_thickness = 0.325 * (1 - 0.4 * s), lean = 1.5 * s;
    Ring r;
    for (int k = 0; k < kAround; ++k) {
      const double t = 2 * kPi * k / kAround;
      r.push_back(Vec3(lean + half_chord * std::sin(t), y, half_thickness * std::cos(t)));
    }
    rings.push_back(r);
  }
  sweep(b, rings, centroid(rings.front()), centroid(rings.back()));
  return b.take();
}

// A 120 x 72 x 1 plate pierced by a 10 x 6 grid of holes of radius 4, like a sheet-metal part or a
// perforated panel. Each 12 x 12 cell is an annulus between its square and its hole.
TriangleMesh plateWithHoles() {
  MeshBuilder b;
  constexpr int kCellsX = 10, kCellsY = 6, kPerSide = 8, kAround = 4 * kPerSide;
  constexpr double kCell = 12, kHalf = kCell / 2, kRadius = 4, kThickness = 1;
  for (int i = 0; i < kCellsX; ++i) {
    for (int j = 0; j < kCellsY; ++j) {
      const double cx = kCell * i + kHalf, cy = kCell * j + kHalf;
      std::vector<Vec3> square, hole;  // in the plane z = 0, counter-clockwise from the cell's low corner
      for (int k = 0; k < kAround; ++k) {
        const int side = k / kPerSide;
        const double s = -kHalf + kCell * (k % kPerSide) / kPerSide;
        const double x = side == 0 ? s : side == 1 ? kHalf : side == 2 ? -s : -kHalf;
        const double y = side == 0 ? -kHalf : side == 1 ? s : side == 2 ? kHalf : -s;
        square.push_back(Vec3(cx + x, cy + y, 0));
        const double a = std::atan2(y, x);
        hole.push_back(Vec3(cx + kRadius * std::cos(a), cy + kRadius * std::sin(a), 0));
      }
      const Vec3 up(0, 0, kThickness);
      for (int k = 0; k < kAround; ++k) {
        const int k1 = (k + 1) % kAround;
        b.quad(b.vertex(square[k] + up), b.vertex(square[k1] + up), b.vertex(hole[k1] + up), b.vertex(hole[k] + up));
        b.quad(b.vertex(square[k]), b.vertex(hole[k]), b.vertex(hole[k1]), b.vertex(square[k1]));
        b.quad(b.vertex(hole[k]), b.vertex(hole[k] + up), b.vertex(hole[k1] + up), b.vertex(hole[k1]));
      }
    }
  }
  // The outer rim, walked counter-clockwise with the cells' seam points.
  const double width = kCell * kCellsX, height = kCell * kCellsY, step = kCell / kPerSide;
  std::vector<Vec3> rim;
  for (double x = 0; x < width; x += step) rim.push_back(Vec3(x, 0, 0));
  for (double y = 0; y < height; y += step) rim.push_back(Vec3(width, y, 0));
  for (double x = width; x > 0; x -= step) rim.push_back(Vec3(x, height, 0));
  for (double y = height; y > 0; y -= step) rim.push_back(Vec3(0, y, 0));
  const Vec3 up(0, 0, kThickness);
  for (std::size_t k = 0; k < rim.size(); ++k) {
    const Vec3& p = rim[k];
    const Vec3& q = rim[(k + 1) % rim.size()];
    b.quad(b.vertex(p), b.vertex(q), b.vertex(q + up), b.vertex(p + up));
  }
  return b.take();
}

// The bunny standing on a 200 x 200 ground of two triangles, in one mesh: a scene exported whole.
TriangleMesh groundWithBunny(const TriangleMesh& bunny) {
  MeshBuilder b;
  b.append(bunny);
  const Aabb box = boundingBox(bunny);
  const double y = box.min.y(), cx = (box.min.x() + box.max.x()) / 2, cz = (box.min.z() + box.max.z()) / 2;
  const int p00 = b.vertex(Vec3(cx - 100, y, cz - 100)), p10 = b.vertex(Vec3(cx + 100, y, cz - 100));
  const int p11 = b.vertex(Vec3(cx + 100, y, cz + 100)), p01 = b.vertex(Vec3(cx - 100, y, cz + 100));
  b.quad(p00, p01, p11, p10);  // normal +y
  return b.take();
}

// An M1.6-like bolt about 1.5 long: hexagonal head and a shank whose radius ripples like a thread.
void bolt(MeshBuilder& b, const Eigen::Isometry3d& X) {
  std::vector<Ring> head;
  for (double z : {0.0, 0.35}) {
    Ring r;
    for (int k = 0; k < 6; ++k) {
      const double t = 2 * kPi * k / 6;
      r.push_back(X * Vec3(0.5 * std::cos(t), 0.5 * std::sin(t), z));
    }
    head.push_back(r);
  }
  sweep(b, head, centroid(head.front()), centroid(head.back()));
  std::vector<Ring> shank;
  constexpr int kRings = 40;
  for (int i = 0; i <= kRings; ++i) {
    const double z = -1.2 * i / kRings, radius = 0.25 + (i % 2 == 0 ? 0.0 : -0.03);
    Ring r;
    for (int k = 0; k < 12; ++k) {
      const double t = 2 * kPi * k / 12;
      r.push_back(X * Vec3(radius * std::cos(t), radius * std::sin(t), z));
    }
    shank.push_back(r);
  }
  // The shank runs downwards, so its rings are reversed to stay counter-clockwise about that direction.
  for (Ring& r : shank) std::reverse(r.begin(), r.end());
  sweep(b, shank, X * Vec3(0, 0, 0.01), X * Vec3(0, 0, -1.2));
}

TriangleMesh singleBolt() {
  MeshBuilder b;
  bolt(b, Eigen::Isometry3d::Identity());
  return b.take();
}

// A gearbox-like assembly exported as one mesh: a housing 100 across with a flange, a shaft, a bracket
// and 24 bolts of 1.5 on the flange, so that parts differ in size a hundredfold. Parts overlap where they
// are fastened, as in CAD exports that do not merge solids.
TriangleMesh assembly() {
  MeshBuilder b;
  cylinder(b, Vec3(0, 0, 0), Vec3(0, 0, 40), 50, 50, 96, 4);
  cylinder(b, Vec3(0, 0, 40), Vec3(0, 0, 45), 58, 58, 96, 1);
  cylinder(b, Vec3(0, 0, 45), Vec3(0, 0, 90), 4, 4, 24, 6);
  box(b, Vec3(45, -10, 5), Vec3(70, 10, 25));
  for (int i = 0; i < 24; ++i) {
    const double t = 2 * kPi * (i + 0.5) / 24;
    Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
    X.translation() = Vec3(54 * std::cos(t), 54 * std::sin(t), 45);
    X.linear() = Eigen::AngleAxisd(t, Vec3::UnitZ()).toRotationMatrix();
    bolt(b, X);
  }
  return b.take();
}

// A spider: a body, a head and eight legs of three segments 0.12 thick and about 2 long each.
TriangleMesh spider() {
  MeshBuilder b;
  ellipsoid(b, Vec3(0, 0, 1.5), Vec3(1.3, 0.9, 0.7), 32, 16);
  ellipsoid(b, Vec3(1.7, 0, 1.6), Vec3(0.5, 0.5, 0.45), 24, 12);
  for (int side : {-1, 1}) {
    for (int i = 0; i < 4; ++i) {
      const double x = 0.9 - 0.6 * i, spread = 0.6 * (1.5 - i);
      const Vec3 joints[4] = {Vec3(x, side * 0.6, 1.5), Vec3(x + spread, side * 2.2, 2.7),
                              Vec3(x + 1.8 * spread, side * 3.6, 1.2), Vec3(x + 2.2 * spread, side * 4.3, 0)};
      for (int s = 0; s < 3; ++s) cylinder(b, joints[s], joints[s + 1], 0.06, 0.05, 8, 4);
    }
  }
  return b.take();
}

void branch(MeshBuilder& b, const Vec3& base, const Vec3& direction, double length, double radius, int depth,
            Random& random) {
  const Vec3 tip = base + length * direction;
  cylinder(b, base, tip, radius, 0.7 * radius, 6, 2);
  if (depth == 0) return;
  const auto [u, v] = perpendiculars(direction);
  const double turn = random.uniform(0, 2 * kPi);
  for (int c = 0; c < 3; ++c) {
    const double around = turn + 2 * kPi * c / 3, tilt = random.uniform(0.45, 0.8);
    const Vec3 side = std::cos(around) * u + std::sin(around) * v;
    const Vec3 child = (std::cos(tilt) * direction + std::sin(tilt) * side).normalized();
    branch(b, tip, child, length * random.uniform(0.65, 0.8), 0.6 * radius, depth - 1, random);
  }
}

// A tree: a trunk branching three ways five times over, 364 tapered branches down to twigs of radius 0.08.
TriangleMesh tree() {
  MeshBuilder b;
  Random random(31);
  branch(b, Vec3::Zero(), Vec3::UnitZ(), 10, 1, 5, random);
  return b.take();
}

// A 100 x 100 x 10 slab whose top carries a 2 x 2 embossed detail meshed with 20,000 triangles, joined to
// the slab's corners by long fans: tiny triangles next to huge slivers, as CAD tessellators and adaptive
// remeshers leave them.
TriangleMesh locallyRefined() {
  MeshBuilder b;
  constexpr int kN = 100;
  constexpr double kLo = 49, kSize = 2, kTop = 10;
  auto patch = [&](int i, int j) {
    const double u = double(i) / kN, v = double(j) / kN;
    const double bump = std::pow(std::sin(kPi * u) * std::sin(kPi * v), 2) * (1 + 0.5 * std::sin(8 * kPi * u) * std::sin(8 * kPi * v));
    return b.vertex(Vec3(kLo + kSize * u, kLo + kSize * v, kTop + 0.2 * bump));
  };
  for (int i = 0; i < kN; ++i) {
    for (int j = 0; j < kN; ++j) b.quad(patch(i, j), patch(i + 1, j), patch(i + 1, j + 1), patch(i, j + 1));
  }
  const Vec3 corners[4] = {Vec3(0, 0, kTop), Vec3(100, 0, kTop), Vec3(100, 100, kTop), Vec3(0, 100, kTop)};
  for (int side = 0; side < 4; ++side) {
    // The patch's boundary along this side, from the end near corners[side] to the end near the next.
    std::vector<int> edge;
    for (int k = 0; k <= kN; ++k) {
      edge.push_back(side == 0 ? patch(k, 0) : side == 1 ? patch(kN, k) : side == 2 ? patch(kN - k, kN) : patch(0, kN - k));
    }
    const int a = b.vertex(corners[side]), c = b.vertex(corners[(side + 1) % 4]);
    for (int k = 0; k < kN; ++k) b.triangle(k < kN / 2 ? a : c, edge[k + 1], edge[k]);
    b.triangle(a, c, edge[kN / 2]);
  }
  // The slab's other five faces, two triangles each; the top's outer edges have only the corners.
  const int t[4] = {b.vertex(corners[0]), b.vertex(corners[1]), b.vertex(corners[2]), b.vertex(corners[3])};
  const int d[4] = {b.vertex(Vec3(0, 0, 0)), b.vertex(Vec3(100, 0, 0)), b.vertex(Vec3(100, 100, 0)), b.vertex(Vec3(0, 100, 0))};
  b.quad(d[0], d[3], d[2], d[1]);
  for (int s = 0; s < 4; ++s) b.quad(d[s], d[(s + 1) % 4], t[(s + 1) % 4], t[s]);
  return b.take();
}

// A hemispherical bowl of radius 10 open at the rim: a single open sheet with a boundary, as thin-shell
// and surface-only exports are.
TriangleMesh openBowl() {
  MeshBuilder b;
  constexpr int kAround = 96, kStacks = 32;
  std::vector<Ring> rings;
  for (int i = 1; i <= kStacks; ++i) {
    const double polar = 0.5 * kPi * i / kStacks;
    Ring r;
    for (int k = 0; k < kAround; ++k) {
      const double t = 2 * kPi * k / kAround;
      r.push_back(Vec3(10 * std::sin(polar) * std::cos(t), 10 * std::sin(polar) * std::sin(t), 10 - 10 * std::cos(polar)));
    }
    rings.push_back(r);
  }
  sweep(b, rings, Vec3(0, 0, 0), std::nullopt);
  return b.take();
}

// Sixteen pages 15 x 20 fanned about one spine edge (every spine edge has 16 triangles) and a cube that
// touches the spine at one vertex: edge- and vertex-non-manifold, as fins, baffles and careless booleans are.
TriangleMesh nonManifoldFins() {
  MeshBuilder b;
  constexpr int kPages = 16, kAcross = 12, kAlong = 20;
  for (int p = 0; p < kPages; ++p) {
    const double angle = kPi * p / (kPages - 1);
    const Vec3 out(std::cos(angle), 0, std::sin(angle));
    auto at = [&](int i, int j) { return b.vertex(15.0 * i / kAcross * out + Vec3(0, 20.0 * j / kAlong, 0)); };
    for (int i = 0; i < kAcross; ++i) {
      for (int j = 0; j < kAlong; ++j) b.quad(at(i, j), at(i + 1, j), at(i + 1, j + 1), at(i, j + 1));
    }
  }
  box(b, Vec3(-3, -3, -3), Vec3(0, 0, 0));
  return b.take();
}

// A bumpy torus 54 across with 352,800 (or, scaled by 2 in both directions, 1,411,200) triangles: the size
// of a raw scan, with detail everywhere.
TriangleMesh denseScan(int scale) {
  TriangleMesh m;
  const int around = 840 * scale, tube = 210 * scale;
  for (int i = 0; i < around; ++i) {
    const double u = 2 * kPi * i / around;
    for (int j = 0; j < tube; ++j) {
      const double v = 2 * kPi * j / tube;
      const double r = 7 * (1 + 0.06 * std::sin(7 * u + 3 * v) + 0.03 * std::sin(23 * u - 11 * v) +
                            0.015 * std::sin(61 * u + 37 * v));
      m.vertices.push_back(Vec3((20 + r * std::cos(v)) * std::cos(u), (20 + r * std::cos(v)) * std::sin(u), r * std::sin(v)));
    }
  }
  for (int i = 0; i < around; ++i) {
    for (int j = 0; j < tube; ++j) {
      const int a = i * tube + j, b = ((i + 1) % around) * tube + j;
      const int c = ((i + 1) % around) * tube + (j + 1) % tube, d = i * tube + (j + 1) % tube;
      m.triangles.push_back({a, b, c});
      m.triangles.push_back({a, c, d});
    }
  }
  return m;
}

// CAD tessellators (STL exports above all) mesh a planar face bounded by a circle or a profile as a fan of
// slivers from one vertex: long thin triangles all meeting at a point.

// A flat disk of radius 20 meshed as a fan of 3000 slivers about its center: a cylinder's cap alone, open.
TriangleMesh fanDisk() {
  MeshBuilder b;
  const Ring rim = circle(Vec3::Zero(), Vec3::UnitZ(), 20, 3000);
  const int c = b.vertex(Vec3::Zero());
  for (std::size_t k = 0; k < rim.size(); ++k) b.triangle(c, b.vertex(rim[k]), b.vertex(rim[(k + 1) % rim.size()]));
  return b.take();
}

// A closed cylinder of radius 5 and height 40 with 256 segments and 20 rings, caps fanned from their
// centers, as an STL export of a CAD cylinder is.
TriangleMesh cadCylinder() {
  MeshBuilder b;
  cylinder(b, Vec3::Zero(), Vec3(0, 0, 40), 5, 5, 256, 20);
  return b.take();
}

// A closed pipe 300 long of radius 0.5, 16 sides and 400 rings, fan caps: a long thin CAD part.
TriangleMesh longPipe() {
  MeshBuilder b;
  cylinder(b, Vec3::Zero(), Vec3(0, 0, 300), 0.5, 0.5, 16, 399);
  return b.take();
}

// A 60-tooth gear 22 across extruded 2 thick, each face of the profile fanned from the center.
TriangleMesh gear() {
  MeshBuilder b;
  constexpr int kTeeth = 60;
  // Per tooth, (fraction of the pitch, radius): root, flank up, tip, flank down.
  constexpr double kProfile[5][2] = {{0.0, 10}, {0.2, 10}, {0.3, 11}, {0.7, 11}, {0.8, 10}};
  std::vector<Ring> rings(2);
  for (int z = 0; z < 2; ++z) {
    for (int k = 0; k < kTeeth; ++k) {
      for (const auto& [f, r] : kProfile) {
        const double t = 2 * kPi * (k + f) / kTeeth;
        rings[z].push_back(Vec3(r * std::cos(t), r * std::sin(t), 2.0 * z));
      }
    }
  }
  sweep(b, rings, Vec3::Zero(), Vec3(0, 0, 2));
  return b.take();
}

// An open 150 x 150 heightfield 74.5 across, gently wavy with a little noise, as GIS and scanned terrain are.
TriangleMesh terrain() {
  MeshBuilder b;
  constexpr int kN = 150;
  Random random(7);
  std::vector<int> ids;
  for (int i = 0; i < kN; ++i) {
    for (int j = 0; j < kN; ++j) {
      const double x = 0.5 * i, y = 0.5 * j;
      ids.push_back(b.vertex(Vec3(x, y, 2 * std::sin(0.1 * x) * std::cos(0.13 * y) + random.uniform(-0.05, 0.05))));
    }
  }
  for (int i = 0; i + 1 < kN; ++i) {
    for (int j = 0; j + 1 < kN; ++j) {
      b.quad(ids[i * kN + j], ids[(i + 1) * kN + j], ids[(i + 1) * kN + j + 1], ids[i * kN + j + 1]);
    }
  }
  return b.take();
}

// ---- writing ----------------------------------------------------------------------------------------------

void writeObj(const TriangleMesh& mesh, const std::string& path, const std::string& what) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) throw Error(path + ": cannot write (" + std::strerror(errno) + ")");
  std::fprintf(f, "# %s\n# %zu vertices, %zu triangles; written by 'cfl suite --generate'\n", what.c_str(),
               mesh.vertices.size(), mesh.triangles.size());
  // 17 digits: the file holds exactly the generated doubles, so the benchmark sees the generator's geometry.
  for (const Vec3& v : mesh.vertices) std::fprintf(f, "v %.17g %.17g %.17g\n", v.x(), v.y(), v.z());
  for (const auto& t : mesh.triangles) std::fprintf(f, "f %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1);
  if (std::ferror(f) != 0 || std::fclose(f) != 0) throw Error(path + ": write failed");
}

// Binary STL of a triangle soup whose copies of a vertex are not bit-identical: copy k of a vertex moves k
// float steps in x. The loader merges bit-identical positions, so exact copies would come back as an indexed
// mesh; CAD exporters that transform each facet on its own produce such near-copies.
void writeSoupStl(const TriangleMesh& mesh, const std::string& path) {
  std::ofstream out(path, std::ios::binary);
  if (!out) throw Error(path + ": cannot write (" + std::strerror(errno) + ")");
  char header[80] = {};
  std::snprintf(header, sizeof header, "triangle soup written by 'cfl suite --generate'");
  out.write(header, sizeof header);
  const std::uint32_t count = std::uint32_t(mesh.triangles.size());
  out.write(reinterpret_cast<const char*>(&count), 4);
  std::vector<int> copies(mesh.vertices.size(), 0);
  for (const auto& t : mesh.triangles) {
    float record[12] = {};
    for (int c = 0; c < 3; ++c) {
      const Vec3& p = mesh.vertices[t[c]];
      float x = float(p.x());
      for (int k = copies[t[c]]++; k > 0; --k) x = std::nextafter(x, x >= 0 ? 1e30f : -1e30f);
      record[3 + 3 * c] = x;
      record[4 + 3 * c] = float(p.y());
      record[5 + 3 * c] = float(p.z());
    }
    out.write(reinterpret_cast<const char*>(record), sizeof record);
    const std::uint16_t attributes = 0;
    out.write(reinterpret_cast<const char*>(&attributes), 2);
  }
  if (!out.flush()) throw Error(path + ": write failed");
}

struct Entry {
  std::string name, a, b, why;
};

}  // namespace

std::string resolveSuitePath(const std::string& dir, const std::string& path) {
  if (path.empty() || path.front() == '/') return path;
  return (std::filesystem::path(dir) / path).string();
}

void generateSuite(const std::string& dir, bool huge, std::ostream& log) {
  std::error_code ec;
  std::filesystem::create_directories(dir, ec);
  if (ec) throw Error(dir + ": cannot create the suite directory (" + ec.message() + ")");
  auto file = [&](const std::string& name) { return resolveSuitePath(dir, name); };
  auto obj = [&](const std::string& name, const TriangleMesh& mesh, const std::string& what) {
    writeObj(mesh, file(name), what);
    log << format("wrote %-22s %9zu triangles  %s\n", name.c_str(), mesh.triangles.size(), what.c_str());
  };
  for (const char* name : {"bunny.obj", "wuson.obj", "torus_knot.obj", "rock.obj"}) {
    std::filesystem::copy_file(findDataFile(name), file(name), std::filesystem::copy_options::overwrite_existing, ec);
    if (ec) throw Error(file(name) + ": cannot copy the bundled mesh (" + ec.message() + ")");
    log << format("copied %-21s from data/\n", name);
  }
  const TriangleMesh bunny = loadMesh(findDataFile("bunny.obj"));
  obj("blade.obj", blade(), "turbine blade 10 x 130 x 0.65");
  obj("plate_holes.obj", plateWithHoles(), "120 x 72 x 1 plate with 60 holes");
  obj("ground_bunny.obj", groundWithBunny(bunny), "bunny on a 200 x 200 two-triangle ground, one mesh");
  obj("assembly.obj", assembly(), "housing 116 across with 24 bolts of 1.5");
  obj("bolt.obj", singleBolt(), "one bolt of the assembly, 1.5 long");
  obj("spider.obj", spider(), "body and eight thin legs");
  obj("tree.obj", tree(), "trunk branching 3 ways 5 times");
  obj("refined_patch.obj", locallyRefined(), "100 x 100 slab, 2 x 2 patch of tiny triangles fanned to huge ones");
  obj("open_bowl.obj", openBowl(), "open hemispherical sheet");
  obj("nonmanifold_fins.obj", nonManifoldFins(), "16 pages on one spine edge and a cube on one vertex");
  {
    const TriangleMesh rock = loadMesh(file("rock.obj"));
    writeSoupStl(rock, file("soup_rock.stl"));
    log << format("wrote %-22s %9zu triangles  %s\n", "soup_rock.stl", rock.triangles.size(),
                  "rock.obj as a binary STL soup, no vertex shared");
  }
  obj("fan_disk.obj", fanDisk(), "disk of radius 20 as a fan of 3000 slivers, open");
  obj("cad_cylinder.obj", cadCylinder(), "cylinder 10 x 40, 256 segments, fan caps");
  obj("pipe.obj", longPipe(), "pipe 300 long of radius 0.5, fan caps");
  obj("gear.obj", gear(), "60-tooth gear 22 x 2, fan caps");
  obj("terrain.obj", terrain(), "150 x 150 heightfield, open");
  obj("dense_scan.obj", denseScan(1), "bumpy torus, scan-sized");
  if (huge) obj("dense_scan_huge.obj", denseScan(2), "bumpy torus, 1.4M triangles");

  std::vector<Entry> entries = {
      {"bunny", "bunny.obj", "", "the compact scan the project was tuned on, for reference"},
      {"wuson", "wuson.obj", "", "a compact real model (Debian assimp-testmodels)"},
      {"torus_knot", "torus_knot.obj", "", "a thin pipe whose far-apart parts pass close to each other"},
      {"rock", "rock.obj", "", "a bumpy blob; the same shape as soup_rock, welded"},
      {"blade", "blade.obj", "", "long flat part: a uniform grid over its box is flat"},
      {"plate_holes", "plate_holes.obj", "", "thin plate with holes: flat, most of its box empty"},
      {"ground_bunny", "ground_bunny.obj", "", "large ground plane and a small detailed object in one mesh"},
      {"assembly", "assembly.obj", "", "parts differing in size 100x"},
      {"spider", "spider.obj", "", "thin-legged figure"},
      {"tree", "tree.obj", "", "branching figure, thin twigs"},
      {"refined_patch", "refined_patch.obj", "", "locally refined: tiny triangles next to huge slivers"},
      {"open_bowl", "open_bowl.obj", "", "open mesh (a sheet with a boundary)"},
      {"nonmanifold_fins", "nonmanifold_fins.obj", "", "non-manifold edges and vertex"},
      {"soup_rock", "soup_rock.stl", "", "triangle soup as STL files come: no vertex shared"},
      {"dense_scan", "dense_scan.obj", "", "352,800 triangles"},
      {"fan_disk", "fan_disk.obj", "", "CAD cap alone: a disk meshed as a fan of 3000 slivers about one vertex"},
      {"cad_cylinder", "cad_cylinder.obj", "", "cylinder as CAD exports it: caps are fans of slivers"},
      {"pipe", "pipe.obj", "", "long thin pipe (300 x 1) with fan caps"},
      {"gear", "gear.obj", "", "extruded gear, faces fanned from the center across the teeth"},
      {"terrain", "terrain.obj", "", "open heightfield: a wide, gently wavy sheet"},
      {"blade_vs_bunny", "blade.obj", "bunny.obj", "different meshes: long flat part against a compact scan"},
      {"assembly_vs_bolt", "assembly.obj", "bolt.obj", "a part 1/100 the size of the assembly it approaches"},
      {"bolt_vs_assembly", "bolt.obj", "assembly.obj", "the same pair seen from the small part"},
      {"ground_bunny_vs_spider", "ground_bunny.obj", "spider.obj", "a scene against a thin-legged figure"},
      {"fan_disk_vs_bunny", "fan_disk.obj", "bunny.obj", "a fan of slivers against a compact scan"},
      {"cad_cylinder_vs_gear", "cad_cylinder.obj", "gear.obj",
       "a CAD cylinder through a gear (a bolt at its center would sit in the hollow, out of the short bands)"},
      {"pipe_vs_gear", "pipe.obj", "gear.obj", "a long thin pipe against a gear, both with fan caps"},
  };
  // Real meshes the project was not tuned on, read in place from Debian's assimp-testmodels when it is
  // installed (they are not ours to copy): checks that what holds on the procedural shapes holds on models
  // users actually have.
  const std::string models = "/usr/share/assimp/models/";
  const std::string engine = models + "glTF2/2CylinderEngine-glTF-Binary/2CylinderEngine.glb";
  const std::string house = models + "IFC/AC14-FZK-Haus.ifc", human = models + "BLEND/HUMAN.blend";
  const std::string duck = models + "Collada/duck.dae", yxa = models + "BLEND/yxa_1.blend";
  const std::vector<Entry> real = {
      {"real_engine", engine, "", "a real CAD assembly: a two-cylinder engine, parts of many sizes (glTF)"},
      {"real_house", house, "", "a real building model (IFC, the FZK house)"},
      {"real_yxa", yxa, "", "a real detailed Blender model, open (115,712 triangles)"},
      {"real_human", human, "", "a real human figure from Blender"},
      {"real_duck", duck, "", "the COLLADA duck"},
      {"real_engine_vs_duck", engine, duck, "real meshes of different sizes against each other"},
      {"real_house_vs_human", house, human, "a person in a building"},
  };
  bool have_real = true;
  for (const std::string& path : {engine, house, human, duck, yxa}) {
    have_real = have_real && std::filesystem::exists(path);
  }
  if (have_real) {
    entries.insert(entries.end(), real.begin(), real.end());
    log << "listed " << real.size() << " cases of real meshes read in place from " << models << '\n';
  } else {
    log << "left out " << real.size() << " cases of real meshes: 'apt-get install assimp-testmodels' adds them\n";
  }
  if (huge) entries.push_back({"dense_scan_huge", "dense_scan_huge.obj", "", "1,411,200 triangles (--huge only)"});

  const std::string manifest = file(kManifestName);
  std::ofstream out(manifest);
  out << "# The cases of 'cfl suite', written by 'cfl suite --generate'.\n"
         "# NAME MESH_A [MESH_B]: A against itself, or A (with its CFL model) against B; paths relative to this\n"
         "# file. '#' starts a comment. Add your own meshes as further lines.\n";
  for (const Entry& e : entries) {
    out << "\n# " << e.why << '\n' << e.name << ' ' << e.a;
    if (!e.b.empty()) out << ' ' << e.b;
    out << '\n';
  }
  out.flush();
  if (!out) throw Error(manifest + ": cannot write the manifest");
  log << "wrote " << kManifestName << " (" << entries.size() << " cases)\n";
}

std::vector<SuiteCase> readManifest(const std::string& path) {
  std::ifstream in(path);
  if (!in) throw Error(path + ": cannot read the suite manifest (" + std::strerror(errno) + ")");
  std::vector<SuiteCase> cases;
  std::set<std::string> names;
  std::string line;
  for (int number = 1; std::getline(in, line); ++number) {
    const std::size_t hash = line.find('#');
    if (hash != std::string::npos) line.erase(hash);
    std::istringstream words(line);
    std::vector<std::string> w;
    for (std::string word; words >> word;) w.push_back(word);
    if (w.empty()) continue;
    if (w.size() < 2 || w.size() > 3) {
      throw Error(format("%s:%d: expected NAME MESH_A [MESH_B], found %zu word%s", path.c_str(), number, w.size(),
                         w.size() == 1 ? "" : "s"));
    }
    if (!names.insert(w[0]).second) throw Error(format("%s:%d: case '%s' appears twice", path.c_str(), number, w[0].c_str()));
    cases.push_back({w[0], w[1], w.size() == 3 ? w[2] : "", number});
  }
  if (in.bad()) throw Error(path + ": read error");
  if (cases.empty()) throw Error(path + ": the manifest lists no case");
  return cases;
}

}  // namespace cfl::tool
