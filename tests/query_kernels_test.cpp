// The query's builds (query_kernels.h) against each other and against brute force: every build this CPU runs
// must return bit for bit what the generic build returns, for every public query, on randomized poses of
// ordinary and ugly meshes, and the generic answers must match brute force over all triangle pairs.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/query_kernels.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <memory>
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

}  // namespace
}  // namespace cfl
