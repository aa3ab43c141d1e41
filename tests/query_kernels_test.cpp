// The query's builds (query_kernels.h) against each other and against brute force: every build this CPU runs
// must return bit for bit what the generic build returns, for every public query, on randomized poses of
// ordinary and ugly meshes, and the generic answers must match brute force over all triangle pairs.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "cfl/triangle_distance.h"
#include "support/test_meshes.h"

// The point query's four-triangle kernel is internal: its declaration and whether this library holds it.
#include "../src/detail/query_kernels.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace cfl {
namespace {

constexpr QueryKernels kAllKernels[] = {QueryKernels::kGeneric, QueryKernels::kX86_64_V3};

// Restores the build that ran before the test, whatever the test selects.
class QueryKernelsTest : public ::testing::Test {
 protected:
  void SetUp() override { previous_ = activeQueryKernels(); }
  void TearDown() override { setQueryKernels(previous_); }
  QueryKernels previous_ = QueryKernels::kGeneric;
};

// Bitwise: -0.0 against 0.0 or two NaNs would pass or fail == wrongly; the claim is the same bits.
bool sameBits(double x, double y) { return std::memcmp(&x, &y, sizeof x) == 0; }
bool sameBits(const Eigen::Vector3d& x, const Eigen::Vector3d& y) {
  return sameBits(x[0], y[0]) && sameBits(x[1], y[1]) && sameBits(x[2], y[2]);
}

// Empty when equal; otherwise what differs.
std::string difference(const DistanceResult& x, const DistanceResult& y) {
  std::ostringstream out;
  out.precision(17);
  if (!sameBits(x.distance, y.distance)) out << " distance " << x.distance << " vs " << y.distance;
  if (!sameBits(x.point_a, y.point_a)) {
    out << " point_a (" << x.point_a.transpose() << ") vs (" << y.point_a.transpose() << ")";
  }
  if (!sameBits(x.point_b, y.point_b)) {
    out << " point_b (" << x.point_b.transpose() << ") vs (" << y.point_b.transpose() << ")";
  }
  if (x.triangle_a != y.triangle_a || x.triangle_b != y.triangle_b) {
    out << " pair (" << x.triangle_a << ", " << x.triangle_b << ") vs (" << y.triangle_a << ", " << y.triangle_b << ")";
  }
  if (x.counters.triangle_pairs != y.counters.triangle_pairs || x.counters.voxel_tests != y.counters.voxel_tests) {
    out << " counters " << x.counters.triangle_pairs << "/" << x.counters.voxel_tests << " vs "
        << y.counters.triangle_pairs << "/" << y.counters.voxel_tests;
  }
  return out.str();
}

struct Shape {
  std::string name;
  MeshModel model;
  CflModel cfl;
};

std::unique_ptr<Shape> makeShape(const std::string& name, TriangleMesh mesh, int resolution) {
  auto shape = std::make_unique<Shape>();
  shape->name = name;
  shape->model = makeMeshModel(mesh);
  BuildOptions options;
  options.resolution = resolution;
  shape->cfl = buildCflModel(std::move(mesh), options);
  return shape;
}

const std::vector<std::unique_ptr<Shape>>& shapes() {
  static const std::vector<std::unique_ptr<Shape>> all = [] {
    std::vector<std::unique_ptr<Shape>> v;
    v.push_back(makeShape("knot", test::makeTorusKnot(2, 3, 0.5, 0.3, 30, 4), 12));
    v.push_back(makeShape("soup", test::makeTriangleSoup(100, 7, 0.8, 0.3), 12));
    v.push_back(makeShape("hemisphere", test::makeHemisphere(1.0, 4, 10), 12));
    v.push_back(makeShape("messy", test::makeMessyMesh(10, 6), 12));
    v.push_back(makeShape("self_intersecting", test::makeSelfIntersectingMesh(10, 5), 12));
    // Flat and thin: long lists whose entries mostly pass the spheres, where the x86-64-v3 build filters
    // them four at a time.
    v.push_back(makeShape("plate", test::makeThinPlate(1.0, 0.05, 12), 12));
    // Tiny triangles fanned to huge slivers: the slivers pass the spheres, planes and boxes of most list
    // entries, and the x86-64-v3 build takes their edge axes four at a time too.
    v.push_back(makeShape("refined_slab", test::makeLocallyRefinedSlab(10), 12));
    v.push_back(makeShape("bunny", test::loadBunny(), 24));
    return v;
  }();
  return all;
}

// A pose of B `fraction` of A's diagonal away from A (0: overlapping), A anywhere near the origin.
struct Pose {
  Eigen::Isometry3d X_WA, X_WB;
};
Pose makePose(const Shape& a, const Shape& b, double fraction, test::Rng& rng) {
  Pose pose;
  pose.X_WA = test::randomPose(rng, 2.0);
  const double diagonal = a.model.bounds.diagonal();
  // Placement only shapes the inputs (every assertion is against brute force or the other build), so it may
  // bisect on the fast query.
  auto distance = [&](const Eigen::Isometry3d& X_WB) {
    return computeDistance(a.cfl, pose.X_WA, b.model, X_WB).distance;
  };
  const double target = fraction * diagonal;
  pose.X_WB = test::placeAtDistance(distance, pose.X_WA * a.model.bounds.center(), b.model.bounds, target,
                                    std::max(0.05 * target, 1e-3 * diagonal), rng);
  return pose;
}

// Every query of cfl_query.h under `kernels`, for one pose.
struct Answers {
  DistanceResult mesh, cfl_pair, paper, approximate, brute;
  bool collides = false;
  std::vector<Contact> contacts;
};
Answers answer(QueryKernels kernels, const Shape& a, const Shape& b, const Pose& pose) {
  setQueryKernels(kernels);
  Answers r;
  r.mesh = computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB);
  r.cfl_pair = computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB);
  DistanceOptions paper;
  paper.mode = QueryMode::kPaper;
  r.paper = computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB, paper);
  DistanceOptions approximate;
  approximate.rel_err = 0.05;
  approximate.abs_err = 1.0;
  r.approximate = computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, approximate);
  r.brute = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
  r.collides = computeCollision(a.model, pose.X_WA, b.model, pose.X_WB, 16, &r.contacts);
  return r;
}

TEST_F(QueryKernelsTest, EveryBuildGivesTheGenericBuildsBitsForEveryQuery) {
  if (!queryKernelsAvailable(QueryKernels::kX86_64_V3)) {
    GTEST_SKIP() << "only the generic build runs here (no x86-64-v3 copy, or a CPU without AVX2)";
  }
  const double fractions[] = {0.0, 0.002, 0.01, 0.05, 0.3, 2.0};
  test::Rng rng(20261123);
  int compared = 0;
  for (const auto& a : shapes()) {
    for (const auto& b : shapes()) {
      // The bunny only against itself and one small shape: brute force over its pairs is the slow part.
      if ((a->name == "bunny") != (b->name == "bunny") && a->name != "knot" && b->name != "knot") continue;
      for (double fraction : fractions) {
        const Pose pose = makePose(*a, *b, fraction, rng);
        const std::string where = a->name + " vs " + b->name + " at " + std::to_string(fraction) + " diagonal";
        const Answers generic = answer(QueryKernels::kGeneric, *a, *b, pose);
        const double tolerance = 1e-9 * a->model.bounds.diagonal();
        EXPECT_NEAR(generic.mesh.distance, generic.brute.distance, tolerance) << where;
        for (QueryKernels kernels : kAllKernels) {
          if (kernels == QueryKernels::kGeneric || !queryKernelsAvailable(kernels)) continue;
          const Answers other = answer(kernels, *a, *b, pose);
          const std::string build = std::string(" (") + queryKernelsName(kernels) + "):";
          EXPECT_EQ(difference(generic.mesh, other.mesh), "") << where << build << " computeDistance";
          EXPECT_EQ(difference(generic.cfl_pair, other.cfl_pair), "") << where << build << " CflModel pair";
          EXPECT_EQ(difference(generic.paper, other.paper), "") << where << build << " paper mode";
          EXPECT_EQ(difference(generic.approximate, other.approximate), "") << where << build << " rel_err";
          EXPECT_EQ(difference(generic.brute, other.brute), "") << where << build << " bruteForceDistance";
          EXPECT_EQ(generic.collides, other.collides) << where << build << " computeCollision";
          ASSERT_EQ(generic.contacts.size(), other.contacts.size()) << where << build;
          for (std::size_t i = 0; i < generic.contacts.size(); ++i) {
            EXPECT_EQ(generic.contacts[i].triangle_a, other.contacts[i].triangle_a) << where << build;
            EXPECT_EQ(generic.contacts[i].triangle_b, other.contacts[i].triangle_b) << where << build;
            EXPECT_TRUE(sameBits(generic.contacts[i].position, other.contacts[i].position)) << where << build;
          }
          ++compared;
        }
      }
    }
  }
  EXPECT_GT(compared, 50);
}

// The cached query keeps state between frames (certificate, previous pair): each build carries its own
// cache along the same smooth path and must answer every frame as the generic build does.
TEST_F(QueryKernelsTest, CachedQueriesAlongAPathMatchTheGenericBuildFrameByFrame) {
  if (!queryKernelsAvailable(QueryKernels::kX86_64_V3)) GTEST_SKIP() << "only the generic build runs here";
  const Shape& a = *shapes().back();  // the bunny
  test::Rng rng(7);
  const Pose start = makePose(a, a, 0.01, rng);
  const Eigen::Vector3d axis = Eigen::Vector3d(0.3, -0.5, 0.8).normalized();
  DistanceCache generic_cache, other_cache;
  for (int frame = 0; frame < 200; ++frame) {
    Eigen::Isometry3d X_WB = start.X_WB;
    X_WB.rotate(Eigen::AngleAxisd(2e-4 * frame, axis));
    X_WB.translation() += Eigen::Vector3d(1e-3, -2e-3, 5e-4) * frame;
    setQueryKernels(QueryKernels::kGeneric);
    const DistanceResult generic = computeDistance(a.cfl, start.X_WA, a.model, X_WB, generic_cache);
    setQueryKernels(QueryKernels::kX86_64_V3);
    const DistanceResult other = computeDistance(a.cfl, start.X_WA, a.model, X_WB, other_cache);
    ASSERT_EQ(difference(generic, other), "") << "frame " << frame;
    if (frame % 20 == 0) {
      const DistanceResult brute = bruteForceDistance(a.model, start.X_WA, a.model, X_WB);
      EXPECT_NEAR(generic.distance, brute.distance, 1e-9 * a.model.bounds.diagonal()) << "frame " << frame;
    }
  }
  EXPECT_EQ(generic_cache.reused, other_cache.reused);
  EXPECT_EQ(generic_cache.searched, other_cache.searched);
  EXPECT_GT(generic_cache.reused, 0) << "the path should let the certificate answer some frames";
}

TEST_F(QueryKernelsTest, SelectingABuildMakesItRunOrFailsNamingIt) {
  setQueryKernels(QueryKernels::kGeneric);
  EXPECT_EQ(activeQueryKernels(), QueryKernels::kGeneric);
  EXPECT_TRUE(queryKernelsAvailable(QueryKernels::kGeneric));
  if (queryKernelsAvailable(QueryKernels::kX86_64_V3)) {
    setQueryKernels(QueryKernels::kX86_64_V3);
    EXPECT_EQ(activeQueryKernels(), QueryKernels::kX86_64_V3);
  } else {
    try {
      setQueryKernels(QueryKernels::kX86_64_V3);
      ADD_FAILURE() << "selecting an unavailable build must throw";
    } catch (const Error& e) {
      EXPECT_NE(std::string(e.what()).find("x86-64-v3"), std::string::npos) << e.what();
    }
    EXPECT_EQ(activeQueryKernels(), QueryKernels::kGeneric);
  }
  const QueryKernels before = activeQueryKernels();
  try {
    setQueryKernels(static_cast<QueryKernels>(7));
    ADD_FAILURE() << "a value that names no build must throw";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("value 7"), std::string::npos) << e.what();
  }
  EXPECT_EQ(activeQueryKernels(), before);
  EXPECT_STREQ(queryKernelsName(QueryKernels::kGeneric), "generic");
  EXPECT_STREQ(queryKernelsName(QueryKernels::kX86_64_V3), "x86-64-v3");
}

#if CFL_X86_64_V3_KERNELS
// Triangles the scalar kernel handles apart or where rounding decides the region: zero area (one point, a
// repeated corner), collinear corners, slivers just either side of its fast-path threshold, right angles,
// and coordinates from 1e-300 to 1e300, near and far from the origin; points on corners, on edges, in the
// plane and off it.
std::vector<std::array<Eigen::Vector3d, 3>> kernelTriangles(std::mt19937_64& rng) {
  std::uniform_real_distribution<double> u(-1, 1);
  auto random = [&] { return Eigen::Vector3d(u(rng), u(rng), u(rng)); };
  std::vector<std::array<Eigen::Vector3d, 3>> triangles;
  for (int i = 0; i < 2000; ++i) triangles.push_back({random(), random(), random()});
  const Eigen::Vector3d a = random(), b = random();
  triangles.push_back({a, a, a});
  triangles.push_back({a, a, b});
  triangles.push_back({a, b, b});
  triangles.push_back({a, 0.5 * (a + b), b});
  triangles.push_back({a, b, a + 3.0 * (b - a)});
  for (double height : {1e-1, 1e-2, 1e-3, 1e-8, 1e-14, 1e-20, 0.0}) {
    triangles.push_back({a, b, 0.5 * (a + b) + height * Eigen::Vector3d(0.3, -0.7, 0.2)});
    triangles.push_back({a, b, b + 1e-3 * (b - a) + height * Eigen::Vector3d(1, 0, 0)});
  }
  triangles.push_back({Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0)});
  for (double scale : {1e-300, 1e-150, 1e-10, 1e10, 1e150, 1e300}) {
    for (int i = 0; i < 50; ++i) triangles.push_back({scale * random(), scale * random(), scale * random()});
  }
  for (double offset : {1e6, 1e12}) {
    const Eigen::Vector3d far = offset * Eigen::Vector3d(1, -2, 3);
    for (int i = 0; i < 50; ++i) triangles.push_back({far + random(), far + random(), far + 1e-9 * random()});
  }
  return triangles;
}

TEST(PointTriangleKernels, FourAtOnceGiveTheScalarKernelsBits) {
  if (!queryKernelsAvailable(QueryKernels::kX86_64_V3)) GTEST_SKIP() << "no AVX2 on this CPU";
  std::mt19937_64 rng(32);
  const auto triangles = kernelTriangles(rng);
  std::uniform_real_distribution<double> u(-1, 1);
  std::uniform_int_distribution<std::size_t> pick(0, triangles.size() - 1);
  std::size_t checked = 0;
  for (int round = 0; round < 20000; ++round) {
    const std::array<Eigen::Vector3d, 3>* four[4];
    // Consecutive runs of the list first, so that each triangle meets every lane; then random mixes.
    for (int lane = 0; lane < 4; ++lane)
      four[lane] = &triangles[round < 1000 ? (4 * std::size_t(round) + std::size_t(lane)) % triangles.size() : pick(rng)];
    // A point near the first triangle at its scale: on a corner, on an edge, in it, or off it.
    const auto& t = *four[0];
    const double size = std::max({(t[1] - t[0]).norm(), (t[2] - t[0]).norm(), 1e-300});
    Eigen::Vector3d p;
    switch (round % 5) {
      case 0: p = t[round % 3]; break;
      case 1: p = t[0] + 0.375 * (t[1] - t[0]); break;
      case 2: p = (t[0] + t[1] + t[2]) / 3.0; break;
      default: p = t[0] + 2 * size * Eigen::Vector3d(u(rng), u(rng), u(rng)); break;
    }
    double squared[4];
    Eigen::Vector3d closest[4];
    detail::x86_64_v3::pointTriangleSquaredDistances4(p, four, squared, closest);
    for (int lane = 0; lane < 4; ++lane) {
      const auto& c = *four[lane];
      Eigen::Vector3d q;
      const double d = pointTriangleSquaredDistance(p, c[0], c[1], c[2], &q);
      ASSERT_TRUE(sameBits(d, squared[lane]) && sameBits(q, closest[lane]))
          << "round " << round << " lane " << lane << ": " << d << " vs " << squared[lane] << ", (" << q.transpose()
          << ") vs (" << closest[lane].transpose() << ")";
      ++checked;
    }
  }
  EXPECT_EQ(checked, 80000u);
}

// The mesh search's four-wide list filter (QueryKernelTable::filter_list_candidates) only drops candidates
// its lower bounds put at or beyond the threshold: every triangle of A strictly closer to B's triangle than
// the threshold is kept, in order, and the far ones it drops are what makes it worth calling.
TEST(ListFilterKernel, KeepsEveryCandidateCloserThanTheThreshold) {
  if (!queryKernelsAvailable(QueryKernels::kX86_64_V3)) GTEST_SKIP() << "no AVX2 on this CPU";
  const auto filter_list_candidates = detail::kX86_64_V3QueryKernels.filter_list_candidates;
  ASSERT_NE(filter_list_candidates, nullptr);
  std::mt19937_64 rng(7);
  const std::pair<const char*, TriangleMesh> meshes[] = {
      {"wavy sheet", test::makeWavySheet()},
      {"thin plate", test::makeThinPlate()},
      {"soup", test::makeTriangleSoup(300, 3)}};
  std::size_t kept_total = 0, dropped_total = 0;
  for (const auto& [name, mesh_a] : meshes) {
    const MeshModel a = makeMeshModel(mesh_a);
    TriangleMesh mesh_b = test::makeTorus(0.3, 0.1, 12, 8);
    const Eigen::Isometry3d X_AB = test::randomPose(rng, 0.8);
    for (Eigen::Vector3d& v : mesh_b.vertices) v = X_AB * v;
    const MeshModel b = makeMeshModel(mesh_b);
    std::vector<int> ids(a.corners.size());
    for (std::size_t t = 0; t < ids.size(); ++t) ids[t] = int(t);
    std::vector<int> kept(ids.size());
    for (std::size_t j = 0; j < b.corners.size(); ++j) {
      const auto& c = b.corners[j];
      std::vector<double> distances(ids.size());
      for (std::size_t t = 0; t < ids.size(); ++t) {
        Eigen::Vector3d p, q;
        distances[t] = std::sqrt(triangleTriangleSquaredDistance(a.corners[t].data(), c.data(), &p, &q));
      }
      std::vector<double> sorted = distances;
      std::sort(sorted.begin(), sorted.end());
      // Thresholds that keep a few, some and most candidates.
      for (const double fraction : {0.02, 0.2, 0.7}) {
        const double threshold = sorted[std::size_t(fraction * double(sorted.size()))];
        const Eigen::Vector3d normal = b.planes[j].head<3>();
        const detail::ListFilter filter{a.spheres.data(),
                                        a.planes.data(),
                                        a.corners.in_leaf_order.data(),
                                        a.corners.leaf_position.data(),
                                        c.data(),
                                        b.spheres[j].head<3>(),
                                        b.spheres[j][3],
                                        normal,
                                        normal.dot(c[0]),
                                        c[0].cwiseMin(c[1]).cwiseMin(c[2]),
                                        c[0].cwiseMax(c[1]).cwiseMax(c[2]),
                                        threshold};
        std::size_t near = 0;
        const std::size_t examined = filter_list_candidates(filter, ids.data(), ids.size(), kept.data(), near);
        ASSERT_EQ(examined % 4, 0u);
        ASSERT_LE(examined, ids.size());
        ASSERT_GT(examined + 4, ids.size());
        ASSERT_TRUE(std::is_sorted(kept.begin(), kept.begin() + std::ptrdiff_t(near))) << name;
        std::size_t k = 0;
        for (std::size_t t = 0; t < examined; ++t) {
          const bool is_kept = k < near && kept[k] == int(t);
          k += is_kept;
          ASSERT_TRUE(is_kept || distances[t] >= threshold)
              << name << ": triangle " << t << " at " << distances[t] << " dropped at threshold " << threshold;
          (is_kept ? kept_total : dropped_total) += 1;
        }
        ASSERT_EQ(k, near) << name;
      }
    }
  }
  EXPECT_GT(dropped_total, kept_total) << "the filter should drop most far candidates";
}
#endif


// The search's edge-axes filter only separates pairs at least `threshold` apart (a lower bound, checked
// against the exact distance), and every table answers it the same way. Nearly parallel slivers and
// coplanar patches, where the rounded cross products stray most, are among the pairs.
TEST(EdgeAxesKernel, SeparatesOnlyPairsAtLeastTheThresholdApartInEveryTable) {
  std::vector<const detail::QueryKernelTable*> tables = {&detail::kGenericQueryKernels};
#if CFL_X86_64_V3_KERNELS
  if (queryKernelsAvailable(QueryKernels::kX86_64_V3)) tables.push_back(&detail::kX86_64_V3QueryKernels);
#endif
  std::mt19937_64 rng(11);
  std::uniform_real_distribution<double> unit(-1, 1);
  const auto point = [&] { return Eigen::Vector3d(unit(rng), unit(rng), unit(rng)); };
  int separated = 0, checked = 0;
  for (int trial = 0; trial < 20000; ++trial) {
    Eigen::Vector3d a[3] = {point(), point(), point()};
    Eigen::Vector3d b[3];
    switch (trial % 3) {
      case 0:  // any two triangles
        for (Eigen::Vector3d& v : b) v = point() + Eigen::Vector3d(unit(rng), 0, 0);
        break;
      case 1:  // a sliver nearly parallel to an edge of a, a little apart
        b[0] = a[0] + 0.1 * point();
        b[1] = a[1] + 0.1 * point();
        b[2] = b[0] + 1e-7 * point();
        break;
      default:  // nearly coplanar with a, shifted in its plane
        for (int k = 0; k < 3; ++k) b[k] = a[k] + (a[1] - a[0]) * (0.5 + unit(rng)) + 1e-9 * point();
        break;
    }
    Eigen::Vector3d p, q;
    const double distance = std::sqrt(triangleTriangleSquaredDistance(a, b, &p, &q));
    for (const double threshold : {0.5 * distance, distance, 1.5 * distance + 1e-12}) {
      const int corner_a = int(rng() % 3), corner_b = int(rng() % 3);
      const bool generic = tables[0]->edge_axes_separate(a, b, corner_a, corner_b, threshold);
      for (const detail::QueryKernelTable* table : tables) {
        ASSERT_EQ(table->edge_axes_separate(a, b, corner_a, corner_b, threshold), generic)
            << queryKernelsName(table->kernels) << " differs from generic at trial " << trial;
      }
      ++checked;
      separated += generic;
      ASSERT_TRUE(!generic || distance >= threshold)
          << "trial " << trial << ": separated at " << threshold << " a pair " << distance << " apart";
    }
  }
  EXPECT_GT(separated, checked / 20) << "the edge axes should separate some pairs";
}

}  // namespace
}  // namespace cfl
