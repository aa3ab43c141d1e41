// Writes the generated benchmark meshes of data/ as OBJ: a torus knot tube (a bent pipe or cable: long,
// thin, non-convex, with close non-adjacent parts) and a rock (a displaced icosphere: an irregular,
// bumpy and cratered blob like a rubble or asteroid model). Deterministic: the same arguments write the
// same bytes on every platform that has IEEE doubles and a correctly rounded printf.
//
//   cfl_mesh_generator torus-knot OUT.obj [P Q SEGMENTS SIDES]   (default 3 5 420 12: 10080 triangles)
//   cfl_mesh_generator rock OUT.obj [SEED LEVELS]                 (default 7 5: 20480 triangles)
//
// Triangles are wound counter-clockwise seen from outside. Coordinates are printed with 9 significant
// digits, which survive the float parse of the loaders exactly enough for a benchmark input.

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <utility>
#include <vector>

namespace {

struct Vec {
  double x = 0, y = 0, z = 0;
};
Vec operator+(Vec a, Vec b) { return {a.x + b.x, a.y + b.y, a.z + b.z}; }
Vec operator*(double s, Vec a) { return {s * a.x, s * a.y, s * a.z}; }
double dot(Vec a, Vec b) { return a.x * b.x + a.y * b.y + a.z * b.z; }
Vec cross(Vec a, Vec b) { return {a.y * b.z - a.z * b.y, a.z * b.x - a.x * b.z, a.x * b.y - a.y * b.x}; }
Vec normalized(Vec a) { return (1 / std::sqrt(dot(a, a))) * a; }

constexpr double kPi = 3.14159265358979323846;

struct Mesh {
  std::vector<Vec> vertices;
  std::vector<std::array<int, 3>> triangles;
};

bool writeObj(const Mesh& mesh, const std::string& path, const std::string& comment) {
  FILE* f = std::fopen(path.c_str(), "w");
  if (f == nullptr) return false;
  std::fprintf(f, "# %s\n# %zu vertices, %zu triangles; written by bench/mesh_generator.cpp\n", comment.c_str(),
               mesh.vertices.size(), mesh.triangles.size());
  for (const Vec& v : mesh.vertices) std::fprintf(f, "v %.9g %.9g %.9g\n", v.x, v.y, v.z);
  for (const auto& t : mesh.triangles) std::fprintf(f, "f %d %d %d\n", t[0] + 1, t[1] + 1, t[2] + 1);
  return std::fclose(f) == 0;
}

// The (p, q) torus knot on a torus of radii 2 and 1, swept by a circular tube of radius `tube`. The frame is
// Frenet's, from the analytic first and second derivatives (the knot's curvature never vanishes), so the
// tube closes on itself without a twist seam.
Mesh torusKnot(int p, int q, int segments, int sides, double tube) {
  auto point = [&](double t) {
    const double r = 2 + std::cos(q * t);
    return Vec{r * std::cos(p * t), r * std::sin(p * t), std::sin(q * t)};
  };
  auto first = [&](double t) {
    const double r = 2 + std::cos(q * t), dr = -q * std::sin(q * t);
    return Vec{dr * std::cos(p * t) - p * r * std::sin(p * t), dr * std::sin(p * t) + p * r * std::cos(p * t),
               q * std::cos(q * t)};
  };
  auto second = [&](double t) {
    const double r = 2 + std::cos(q * t), dr = -q * std::sin(q * t), ddr = -q * q * std::cos(q * t);
    return Vec{ddr * std::cos(p * t) - 2 * p * dr * std::sin(p * t) - p * p * r * std::cos(p * t),
               ddr * std::sin(p * t) + 2 * p * dr * std::cos(p * t) - p * p * r * std::sin(p * t),
               -q * q * std::sin(q * t)};
  };
  Mesh mesh;
  for (int i = 0; i < segments; ++i) {
    const double t = 2 * kPi * i / segments;
    const Vec tangent = normalized(first(t));
    const Vec binormal = normalized(cross(first(t), second(t)));
    const Vec normal = cross(binormal, tangent);
    for (int j = 0; j < sides; ++j) {
      const double a = 2 * kPi * j / sides;
      mesh.vertices.push_back(point(t) + tube * (std::cos(a) * normal + std::sin(a) * binormal));
    }
  }
  for (int i = 0; i < segments; ++i) {
    const int i1 = (i + 1) % segments;
    for (int j = 0; j < sides; ++j) {
      const int j1 = (j + 1) % sides;
      const int a = i * sides + j, b = i1 * sides + j, c = i1 * sides + j1, d = i * sides + j1;
      // (normal, binormal) turn positively about the tangent, so this order faces outward.
      mesh.triangles.push_back({a, c, b});
      mesh.triangles.push_back({a, d, c});
    }
  }
  return mesh;
}

// A small deterministic generator (SplitMix64), so the rock does not depend on a library's distributions.
struct Random {
  std::uint64_t state;
  std::uint64_t next() {
    std::uint64_t x = (state += 0x9E3779B97F4A7C15ull);
    x = (x ^ (x >> 30)) * 0xBF58476D1CE4E5B9ull;
    x = (x ^ (x >> 27)) * 0x94D049BB133111EBull;
    return x ^ (x >> 31);
  }
  double uniform() { return double(next() >> 11) * (1.0 / 9007199254740992.0); }  // [0, 1)
  Vec direction() {
    for (;;) {
      const Vec v{2 * uniform() - 1, 2 * uniform() - 1, 2 * uniform() - 1};
      const double n = dot(v, v);
      if (n > 1e-6 && n <= 1) return (1 / std::sqrt(n)) * v;
    }
  }
};

// An icosahedron subdivided `levels` times, vertices on the unit sphere.
Mesh icosphere(int levels) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  Mesh mesh;
  for (Vec v : {Vec{-1, g, 0}, Vec{1, g, 0}, Vec{-1, -g, 0}, Vec{1, -g, 0}, Vec{0, -1, g}, Vec{0, 1, g},
                Vec{0, -1, -g}, Vec{0, 1, -g}, Vec{g, 0, -1}, Vec{g, 0, 1}, Vec{-g, 0, -1}, Vec{-g, 0, 1}}) {
    mesh.vertices.push_back(normalized(v));
  }
  mesh.triangles = {{0, 11, 5}, {0, 5, 1},  {0, 1, 7},   {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                    {11, 10, 2}, {10, 7, 6}, {7, 1, 8},  {3, 9, 4},  {3, 4, 2},   {3, 2, 6}, {3, 6, 8},
                    {3, 8, 9},  {4, 9, 5},  {2, 4, 11},  {6, 2, 10}, {8, 6, 7},   {9, 8, 1}};
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> midpoints;
    auto midpoint = [&](int a, int b) {
      const auto key = std::make_pair(std::min(a, b), std::max(a, b));
      const auto it = midpoints.find(key);
      if (it != midpoints.end()) return it->second;
      mesh.vertices.push_back(normalized(mesh.vertices[a] + mesh.vertices[b]));
      return midpoints[key] = int(mesh.vertices.size()) - 1;
    };
    std::vector<std::array<int, 3>> finer;
    for (const auto& t : mesh.triangles) {
      const int ab = midpoint(t[0], t[1]), bc = midpoint(t[1], t[2]), ca = midpoint(t[2], t[0]);
      finer.push_back({t[0], ab, ca});
      finer.push_back({t[1], bc, ab});
      finer.push_back({t[2], ca, bc});
      finer.push_back({ab, bc, ca});
    }
    mesh.triangles = std::move(finer);
  }
  return mesh;
}

// The rock: each unit-sphere vertex u moves to radius(u) * u, then the whole is stretched along the axes.
// radius = 1 + a sum of random smooth bumps (cosine caps of random centers, widths and signed heights, in
// several octaves: big lobes down to small knobs) - craters (bowls with a raised rim). The radius stays
// positive, so the surface stays star-shaped about the origin and therefore free of self-intersections.
Mesh rock(std::uint64_t seed, int levels) {
  Mesh mesh = icosphere(levels);
  Random random{seed};
  struct Bump {
    Vec center;
    double cos_width, height;
  };
  std::vector<Bump> bumps;
  for (int octave = 0; octave < 5; ++octave) {
    const int count = 6 << octave;  // 6, 12, 24, 48, 96
    const double width = 1.1 / std::pow(1.8, octave);  // cap half-angle, radians
    const double amplitude = 0.3 / std::pow(1.8, octave);
    for (int k = 0; k < count; ++k) {
      const double w = width * (0.6 + 0.8 * random.uniform());
      bumps.push_back({random.direction(), std::cos(w), amplitude * (2 * random.uniform() - 1)});
    }
  }
  struct Crater {
    Vec center;
    double angle, depth;
  };
  std::vector<Crater> craters;
  for (int k = 0; k < 9; ++k)
    craters.push_back({random.direction(), 0.12 + 0.25 * random.uniform(), 0.06 + 0.08 * random.uniform()});
  const Vec stretch{1.35, 1.0, 0.8};

  for (Vec& v : mesh.vertices) {
    double radius = 1;
    for (const Bump& b : bumps) {
      const double c = dot(v, b.center);
      if (c <= b.cos_width) continue;
      const double s = (c - b.cos_width) / (1 - b.cos_width);  // 0 at the cap's edge, 1 at its center
      radius += b.height * s * s * (3 - 2 * s);
    }
    for (const Crater& cr : craters) {
      const double angle = std::acos(std::max(-1.0, std::min(1.0, dot(v, cr.center))));
      const double x = angle / cr.angle;  // 0 at the center, 1 at the rim
      if (x < 1) {
        radius -= cr.depth * (1 - x * x);
      } else if (x < 1.6) {
        const double s = (x - 1) / 0.6;
        radius += 0.35 * cr.depth * std::sin(kPi * s);
      }
    }
    radius = std::max(radius, 0.3);
    v = radius * v;
    v = Vec{stretch.x * v.x, stretch.y * v.y, stretch.z * v.z};
  }
  return mesh;
}

int usage() {
  std::fprintf(stderr,
               "usage: cfl_mesh_generator torus-knot OUT.obj [P Q SEGMENTS SIDES]\n"
               "       cfl_mesh_generator rock OUT.obj [SEED LEVELS]\n");
  return 2;
}

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) return usage();
  const std::string kind = argv[1], out = argv[2];
  auto arg = [&](int i, long fallback) { return argc > i ? std::strtol(argv[i], nullptr, 10) : fallback; };
  Mesh mesh;
  std::string comment;
  if (kind == "torus-knot") {
    const int p = int(arg(3, 3)), q = int(arg(4, 5)), segments = int(arg(5, 420)), sides = int(arg(6, 12));
    if (p < 1 || q < 1 || segments < 3 || sides < 3) return usage();
    mesh = torusKnot(p, q, segments, sides, 0.3);
    comment = "torus knot (" + std::to_string(p) + ", " + std::to_string(q) + "), tube radius 0.3, " +
              std::to_string(segments) + " x " + std::to_string(sides);
  } else if (kind == "rock") {
    const long seed = arg(3, 7), levels = arg(4, 5);
    if (seed < 0 || levels < 0 || levels > 8) return usage();
    mesh = rock(std::uint64_t(seed), int(levels));
    comment = "rock: icosphere level " + std::to_string(levels) + " displaced with seed " + std::to_string(seed);
  } else {
    return usage();
  }
  if (!writeObj(mesh, out, comment)) {
    std::fprintf(stderr, "cfl_mesh_generator: cannot write %s\n", out.c_str());
    return 1;
  }
  std::printf("%s: %zu vertices, %zu triangles\n", out.c_str(), mesh.vertices.size(), mesh.triangles.size());
  return 0;
}
