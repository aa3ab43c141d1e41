// Per-call cost of the narrow-phase kernels (include/cfl/triangle_distance.h) on random inputs.
//
// Inputs are drawn once (fixed seed) into arrays of kCases and cycled through, so that branch prediction
// sees a realistic mix rather than one configuration repeated. Triangles have unit size; "separated" pairs
// are moved 0.2 to 3 units apart along a random direction and kept only if they do not intersect, "near"
// pairs are within 0.2 (the case a CFL query spends its time in), "intersecting" pairs are random pairs
// that intersect.

#include "cfl/triangle_distance.h"

#include <benchmark/benchmark.h>

#include <array>
#include <random>
#include <vector>

namespace {

using Vec = Eigen::Vector3d;
using Triangle = std::array<Vec, 3>;
constexpr int kCases = 4096;

struct Rng {
  std::mt19937_64 engine{12345};
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(engine); }
  Vec point(double r) { return Vec(uniform(-r, r), uniform(-r, r), uniform(-r, r)); }
  Vec direction() {
    for (;;) {
      const Vec v = point(1.0);
      if (v.squaredNorm() > 1e-2 && v.squaredNorm() <= 1.0) return v.normalized();
    }
  }
  Triangle triangle() { return {point(0.5), point(0.5), point(0.5)}; }
};

enum class PairKind { kSeparated, kNear, kIntersecting };

std::vector<std::pair<Triangle, Triangle>> makePairs(PairKind kind) {
  Rng rng;
  std::vector<std::pair<Triangle, Triangle>> pairs;
  while (static_cast<int>(pairs.size()) < kCases) {
    const Triangle p = rng.triangle();
    Triangle q = rng.triangle();
    if (kind != PairKind::kIntersecting) {
      const Vec shift = rng.direction() * (kind == PairKind::kNear ? rng.uniform(0.0, 0.2) : rng.uniform(0.2, 3.0));
      for (Vec& v : q) v += shift;
    }
    const bool hit = cfl::trianglesIntersect(p.data(), q.data());
    if (hit == (kind == PairKind::kIntersecting)) pairs.emplace_back(p, q);
  }
  return pairs;
}

void BM_PointTriangle(benchmark::State& state) {
  Rng rng;
  std::vector<Triangle> tris(kCases);
  std::vector<Vec> points(kCases);
  for (int i = 0; i < kCases; ++i) {
    tris[i] = rng.triangle();
    points[i] = rng.point(1.5);
  }
  int i = 0;
  for (auto _ : state) {
    Vec c;
    const Triangle& t = tris[i];
    benchmark::DoNotOptimize(cfl::pointTriangleSquaredDistance(points[i], t[0], t[1], t[2], &c));
    benchmark::DoNotOptimize(c);
    i = (i + 1) & (kCases - 1);
  }
}
BENCHMARK(BM_PointTriangle);

void BM_SegmentSegment(benchmark::State& state) {
  Rng rng;
  std::vector<std::array<Vec, 4>> segs(kCases);
  for (auto& s : segs) s = {rng.point(1), rng.point(1), rng.point(1), rng.point(1)};
  int i = 0;
  for (auto _ : state) {
    Vec a, b;
    const auto& s = segs[i];
    benchmark::DoNotOptimize(cfl::segmentSegmentSquaredDistance(s[0], s[1], s[2], s[3], &a, &b));
    benchmark::DoNotOptimize(a);
    i = (i + 1) & (kCases - 1);
  }
}
BENCHMARK(BM_SegmentSegment);

template <PairKind kKind>
void BM_TriangleTriangle(benchmark::State& state) {
  const auto pairs = makePairs(kKind);
  int i = 0;
  for (auto _ : state) {
    Vec a, b;
    benchmark::DoNotOptimize(
        cfl::triangleTriangleSquaredDistance(pairs[i].first.data(), pairs[i].second.data(), &a, &b));
    benchmark::DoNotOptimize(a);
    i = (i + 1) & (kCases - 1);
  }
}
BENCHMARK(BM_TriangleTriangle<PairKind::kSeparated>)->Name("BM_TriangleTriangle/separated");
BENCHMARK(BM_TriangleTriangle<PairKind::kNear>)->Name("BM_TriangleTriangle/near");
BENCHMARK(BM_TriangleTriangle<PairKind::kIntersecting>)->Name("BM_TriangleTriangle/intersecting");

template <PairKind kKind>
void BM_TrianglesIntersect(benchmark::State& state) {
  const auto pairs = makePairs(kKind);
  int i = 0;
  for (auto _ : state) {
    Vec x;
    benchmark::DoNotOptimize(cfl::trianglesIntersect(pairs[i].first.data(), pairs[i].second.data(), &x));
    i = (i + 1) & (kCases - 1);
  }
}
BENCHMARK(BM_TrianglesIntersect<PairKind::kSeparated>)->Name("BM_TrianglesIntersect/separated");
BENCHMARK(BM_TrianglesIntersect<PairKind::kNear>)->Name("BM_TrianglesIntersect/near");
BENCHMARK(BM_TrianglesIntersect<PairKind::kIntersecting>)->Name("BM_TrianglesIntersect/intersecting");

}  // namespace

BENCHMARK_MAIN();
