// computeDistance and computeCollision on randomized poses against brute force over all triangle pairs
// (cfl::bruteForceDistance; the kernels it uses are tested on their own) and, independently of every
// library kernel, against the point-mesh reference of test_meshes.

#include "cfl/cfl_query.h"
#include "cfl/error.h"
#include "cfl/triangle_distance.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <climits>
#include <cmath>
#include <functional>
#include <initializer_list>
#include <limits>
#include <memory>
#include <random>
#include <sstream>
#include <string>
#include <thread>
#include <vector>

namespace cfl {
namespace {

struct Shape {
  std::string name;
  TriangleMesh mesh;
  MeshModel model;
  CflModel cfl;          // at the resolution asked for (0: adaptive regions)
  CflModel cfl_adaptive; // adaptive regions, what a user gets by default
  double diagonal = 0;
};

std::unique_ptr<Shape> makeShape(const std::string& name, TriangleMesh mesh, int resolution) {
  auto shape = std::make_unique<Shape>();
  shape->name = name;
  shape->mesh = mesh;
  shape->model = makeMeshModel(mesh);
  BuildOptions options;
  options.resolution = resolution;
  shape->cfl = buildCflModel(mesh, options);
  shape->cfl_adaptive = resolution == 0 ? shape->cfl : buildCflModel(std::move(mesh), BuildOptions{});
  shape->diagonal = shape->model.bounds.diagonal();
  return shape;
}

// A large two-triangle ground with a small detailed torus on it, in one mesh: huge triangles next to small
// ones, leaves without lists over the ground, and B's ground triangles meeting many leaves of A.
TriangleMesh makeGroundWithTorus() {
  TriangleMesh mesh = test::makeTorus(0.2, 0.07, 12, 6);
  for (Eigen::Vector3d& v : mesh.vertices) v.z() += 0.08;
  const int first = static_cast<int>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), {{-5, -5, 0}, {5, -5, 0}, {5, 5, 0}, {-5, 5, 0}});
  mesh.triangles.push_back({first, first + 1, first + 2});
  mesh.triangles.push_back({first, first + 2, first + 3});
  return mesh;
}

// Two long wavy layers 0.04 apart, facing each other: the lists near them hold both.
TriangleMesh makeThinSlab() {
  const TriangleMesh sheet = test::makeWavySheet(1.0, 0.05, 10);
  TriangleMesh slab;
  for (int layer = 0; layer < 2; ++layer) {
    const int offset = static_cast<int>(slab.vertices.size());
    for (const Eigen::Vector3d& v : sheet.vertices) slab.vertices.emplace_back(6 * v.x(), v.y(), v.z() + 0.04 * layer);
    for (const auto& t : sheet.triangles) {
      slab.triangles.push_back(layer == 0 ? std::array<int, 3>{t[0] + offset, t[1] + offset, t[2] + offset}
                                          : std::array<int, 3>{t[0] + offset, t[2] + offset, t[1] + offset});
    }
  }
  return slab;
}

// Built once for the whole executable. Small meshes (70-250 triangles) keep brute force affordable over
// a thousand poses; the bunny gets a handful of poses.
const std::vector<std::unique_ptr<Shape>>& shapes() {
  static const std::vector<std::unique_ptr<Shape>> all = [] {
    std::vector<std::unique_ptr<Shape>> v;
    v.push_back(makeShape("torus", test::makeTorus(1.0, 0.35, 10, 5), 12));
    v.push_back(makeShape("knot", test::makeTorusKnot(2, 3, 0.5, 0.3, 30, 4), 12));
    v.push_back(makeShape("soup", test::makeTriangleSoup(100, 99, 0.8, 0.3), 12));
    v.push_back(makeShape("hemisphere", test::makeHemisphere(1.0, 4, 10), 12));
    v.push_back(makeShape("messy", test::makeMessyMesh(10, 6), 12));
    v.push_back(makeShape("wavy_sheet", test::makeWavySheet(1.0, 0.3, 8), 12));
    v.push_back(makeShape("self_intersecting", test::makeSelfIntersectingMesh(10, 5), 12));
    v.push_back(makeShape("ground_torus", makeGroundWithTorus(), 0));
    v.push_back(makeShape("thin_slab", makeThinSlab(), 0));
    return v;
  }();
  return all;
}

const Shape& shape(const std::string& name) {
  for (const auto& s : shapes()) {
    if (s->name == name) return *s;
  }
  throw std::runtime_error("no shape " + name);
}

const Shape& bunny() {
  static const std::unique_ptr<Shape> b = makeShape("bunny", test::loadBunny(), 16);
  return *b;
}

// Collects failures and reports the first few in full, so that a systematic bug does not flood the log.
class Failures {
 public:
  void add(const std::string& message) {
    if (++count_ <= 8) ADD_FAILURE() << message;
  }
  int count() const { return count_; }

 private:
  int count_ = 0;
};

// The corners of triangle t of `model` at pose X (world frame).
void worldTriangle(const MeshModel& model, int t, const Eigen::Isometry3d& X, Eigen::Vector3d out[3]) {
  for (int k = 0; k < 3; ++k) out[k] = X * model.corners[t][k];
}

double pointToTriangle(const Eigen::Vector3d& p, const Eigen::Vector3d tri[3]) {
  return std::sqrt(test::referencePointTriangleSquaredDistance(p, tri[0], tri[1], tri[2]));
}

struct Pose {
  Eigen::Isometry3d X_WA;
  Eigen::Isometry3d X_WB;
  std::string kind;
};

std::string describe(const Pose& pose, const Shape& a, const Shape& b) {
  std::ostringstream out;
  out.precision(17);
  out << a.name << " vs " << b.name << " (" << pose.kind << ")\n  X_WA =\n" << pose.X_WA.matrix() << "\n  X_WB =\n"
      << pose.X_WB.matrix();
  return out.str();
}

// Checks `r` against the brute-force answer `truth`: same distance, points on the named triangles, the
// named pair at that distance, and points mutually closest by the independent point reference.
void checkResult(const DistanceResult& r, const DistanceResult& truth, const Shape& a, const Shape& b, const Pose& pose,
                 const std::string& label, Failures& failures) {
  const double tolerance = 1e-9 * std::max(a.diagonal, b.diagonal);
  std::ostringstream problems;
  problems.precision(17);
  if (!(std::abs(r.distance - truth.distance) <= tolerance)) {
    problems << "  distance " << r.distance << " != brute force " << truth.distance << " (error "
             << r.distance - truth.distance << ")\n";
  }
  const int na = static_cast<int>(a.model.corners.size()), nb = static_cast<int>(b.model.corners.size());
  if (r.triangle_a < 0 || r.triangle_a >= na || r.triangle_b < 0 || r.triangle_b >= nb) {
    problems << "  triangle ids out of range: " << r.triangle_a << ", " << r.triangle_b << "\n";
  } else {
    Eigen::Vector3d ta[3], tb[3];
    worldTriangle(a.model, r.triangle_a, pose.X_WA, ta);
    worldTriangle(b.model, r.triangle_b, pose.X_WB, tb);
    if (!(pointToTriangle(r.point_a, ta) <= tolerance)) {
      problems << "  point_a is " << pointToTriangle(r.point_a, ta) << " off triangle_a " << r.triangle_a << "\n";
    }
    if (!(pointToTriangle(r.point_b, tb) <= tolerance)) {
      problems << "  point_b is " << pointToTriangle(r.point_b, tb) << " off triangle_b " << r.triangle_b << "\n";
    }
    const double pair = std::sqrt(triangleTriangleSquaredDistance(ta, tb));
    if (!(std::abs(pair - r.distance) <= tolerance)) {
      problems << "  the returned pair is at " << pair << ", not at the returned distance " << r.distance << "\n";
    }
  }
  if (r.counters.triangle_pairs < 1) {
    problems << "  counters report " << r.counters.triangle_pairs << " triangle pairs, yet a pair was returned\n";
  }
  if (!(std::abs((r.point_a - r.point_b).norm() - r.distance) <= tolerance)) {
    problems << "  |point_a - point_b| = " << (r.point_a - r.point_b).norm() << " != distance " << r.distance << "\n";
  }
  // Independent of every library kernel: a closest point of A is at exactly the distance from B, and
  // conversely (it is on A, so no closer than the minimum; it is that close to point_b).
  const double a_to_b = test::referencePointMeshDistance(b.mesh, r.point_a, pose.X_WB);
  const double b_to_a = test::referencePointMeshDistance(a.mesh, r.point_b, pose.X_WA);
  if (!(std::abs(a_to_b - truth.distance) <= tolerance) || !(std::abs(b_to_a - truth.distance) <= tolerance)) {
    problems << "  point reference: point_a is " << a_to_b << " from B and point_b " << b_to_a
             << " from A, expected " << truth.distance << "\n";
  }
  if (!problems.str().empty()) failures.add(label + ": " + describe(pose, a, b) + "\n" + problems.str());
}

// Sanity check of the brute-force reference itself with the independent point reference: the distance
// from any vertex of one mesh to the other is an upper bound, and the minimum over vertices is reached
// when a closest pair involves a vertex.
void checkReferenceWithPoints(const DistanceResult& truth, const Shape& a, const Shape& b, const Pose& pose,
                              Failures& failures) {
  const double tolerance = 1e-9 * std::max(a.diagonal, b.diagonal);
  double vertex_bound = std::numeric_limits<double>::infinity();
  for (const auto& t : b.mesh.triangles) {
    for (int k = 0; k < 3; ++k) {
      vertex_bound = std::min(vertex_bound, test::referencePointMeshDistance(a.mesh, pose.X_WB * b.mesh.vertices[t[k]],
                                                                             pose.X_WA));
    }
  }
  if (!(truth.distance <= vertex_bound + tolerance)) {
    std::ostringstream out;
    out << "brute force " << truth.distance << " exceeds the vertex-to-mesh bound " << vertex_bound << " for "
        << describe(pose, a, b);
    failures.add(out.str());
  }
}

// A pose of B relative to A with the given separation, as a fraction of A's diagonal:
// 0 overlaps, a negative fraction means "touching" (closest points brought together exactly).
// `translation_range`: how far from the world origin A may sit (test::randomPose).
Pose makePose(const Shape& a, const Shape& b, double fraction, test::Rng& rng, double translation_range = 2.0) {
  Pose pose;
  pose.X_WA = test::randomPose(rng, translation_range);
  auto distance = [&](const Eigen::Isometry3d& X_WB) { return computeDistance(a.cfl, pose.X_WA, b.model, X_WB).distance; };
  const Eigen::Vector3d center_a = pose.X_WA * a.model.bounds.center();
  if (fraction < 0) {
    pose.X_WB = test::placeAtDistance(distance, center_a, b.model.bounds, 0.02 * a.diagonal, 1e-3 * a.diagonal, rng);
    const DistanceResult apart = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
    pose.X_WB.translation() += apart.point_a - apart.point_b;
    pose.kind = "touching";
  } else {
    const double target = fraction * a.diagonal;
    pose.X_WB = test::placeAtDistance(distance, center_a, b.model.bounds, target, 0.05 * target, rng);
    pose.kind = fraction == 0 ? "overlapping" : "separation " + std::to_string(fraction) + " diagonal";
  }
  return pose;
}

const double kSeparations[] = {0.0, -1.0, 0.005, 0.02, 0.1, 0.5, 3.0};

struct PairCase {
  const char* a;
  const char* b;
};

// Every mesh appears as A and as B, and every mesh meets a differently shaped partner.
const PairCase kPairs[] = {
    {"torus", "knot"},        {"knot", "soup"},        {"soup", "hemisphere"},        {"hemisphere", "messy"},
    {"messy", "wavy_sheet"},  {"wavy_sheet", "torus"}, {"self_intersecting", "knot"}, {"knot", "knot"},
    {"ground_torus", "knot"}, {"thin_slab", "ground_torus"}, {"knot", "thin_slab"},
};

// The bulk of the suite: 8 pairs x 7 separations x 18 = 1008 poses, 4 queries each (both modes, both
// overloads).
constexpr int kPosesPerSeparation = 18;

TEST(ComputeDistance, MatchesBruteForceOnRandomPosesInBothModesAndOverloads) {
  test::Rng rng(2024);
  Failures failures;
  int poses = 0, overlapping = 0;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    for (double fraction : kSeparations) {
      for (int n = 0; n < kPosesPerSeparation; ++n) {
        const Pose pose = makePose(a, b, fraction, rng);
        const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
        ++poses;
        if (truth.distance == 0) ++overlapping;
        if (n % 4 == 0) checkReferenceWithPoints(truth, a, b, pose, failures);
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          const std::string mode_name = mode == QueryMode::kHierarchical ? "hierarchical" : "paper";
          checkResult(computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options), truth, a, b, pose,
                      mode_name + ", B as MeshModel", failures);
          checkResult(computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB, options), truth, a, b, pose,
                      mode_name + ", B as CflModel", failures);
          checkResult(computeDistance(a.cfl_adaptive, pose.X_WA, b.model, pose.X_WB, options), truth, a, b, pose,
                      mode_name + ", adaptive A", failures);
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0) << "of " << poses << " poses";
  // The overlapping and touching poses must really have produced contact, or the suite tests less than it says.
  EXPECT_GE(overlapping, static_cast<int>(std::size(kPairs)) * kPosesPerSeparation) << "too few overlapping poses";
}

// The shapes above reach the adaptive query's special paths, or the test above checks less than it says:
// refined leaves, leaves without a list (their triangles go to A's Bvh) and long lists.
TEST(ComputeDistance, TheAdaptiveShapesReachLeavesWithoutListsAndRefinedLeaves) {
  const BuildStatistics& ground = shape("ground_torus").cfl.statistics;
  const BuildStatistics& slab = shape("thin_slab").cfl.statistics;
  EXPECT_GT(ground.leaves_without_list + slab.leaves_without_list, 0);
  EXPECT_GE(shape("ground_torus").cfl.regions.max_depth, 1);
  EXPECT_GE(shape("thin_slab").cfl.regions.max_depth, 1);
  EXPECT_GT(slab.longest_list, 8);
}

// Sheets facing each other across gaps far narrower than their triangles: where the query bounds B's
// triangles and nodes from grid corners on A's far side, tightest across flat gaps. A bound that overshot
// by a fraction of the gap would drop the closest pair here.
TEST(ComputeDistance, FacingSheetsAcrossNarrowGapsMatchBruteForce) {
  test::Rng rng(4242);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Failures failures;
  int poses = 0;
  for (double amplitude : {0.0, 0.05}) {
    const auto sheet = makeShape(amplitude == 0 ? "flat_sheet" : "gently_wavy_sheet",
                                 test::makeWavySheet(1.0, amplitude, 12), 16);
    for (double gap : {1e-5, 1e-3, 2e-2}) {
      for (int n = 0; n < 12; ++n) {
        // B: the same sheet turned about its normal, tilted by up to a degree, shifted sideways, above A.
        const double tilt = 0.0175 * unit(rng);
        const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilt, Eigen::Vector3d(unit(rng), unit(rng), 0).normalized()) *
                                   Eigen::AngleAxisd(3.2 * unit(rng), Eigen::Vector3d::UnitZ()))
                                      .toRotationMatrix();
        Pose pose{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), "facing sheets"};
        pose.X_WA.linear() = test::randomRotation(rng);
        pose.X_WB.linear() = pose.X_WA.linear() * R;
        const Eigen::Vector3d offset(0.3 * unit(rng), 0.3 * unit(rng), 0);
        pose.X_WB.translation() = pose.X_WA.linear() * offset;
        // Lift B until its lowest point clears A's highest by `gap`, then let brute force say the truth.
        double lowest_b = std::numeric_limits<double>::infinity(), highest_a = -lowest_b;
        for (const auto& v : sheet->mesh.vertices) {
          lowest_b = std::min(lowest_b, (R * v + offset).z());
          highest_a = std::max(highest_a, v.z());
        }
        pose.X_WB.translation() += pose.X_WA.linear() * Eigen::Vector3d(0, 0, highest_a - lowest_b + gap * sheet->diagonal);
        const DistanceResult truth = bruteForceDistance(sheet->model, pose.X_WA, sheet->model, pose.X_WB);
        ++poses;
        checkResult(computeDistance(sheet->cfl, pose.X_WA, sheet->model, pose.X_WB), truth, *sheet, *sheet, pose,
                    sheet->name + " at gap " + std::to_string(gap), failures);
      }
    }
  }
  EXPECT_EQ(failures.count(), 0) << "of " << poses << " poses";
}

TEST(ComputeDistance, MatchesBruteForceOnTheBunny) {
  test::Rng rng(77);
  Failures failures;
  const Shape& a = bunny();
  const Shape& b = shape("torus");
  for (double fraction : kSeparations) {
    {
      // The bunny as A (with CFLs) and as B.
      for (bool bunny_is_a : {true, false}) {
        const Shape& first = bunny_is_a ? a : b;
        const Shape& second = bunny_is_a ? b : a;
        const Pose pose = makePose(first, second, fraction, rng);
        const DistanceResult truth = bruteForceDistance(first.model, pose.X_WA, second.model, pose.X_WB);
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          checkResult(computeDistance(first.cfl, pose.X_WA, second.model, pose.X_WB, options), truth, first, second,
                      pose, "MeshModel B", failures);
          checkResult(computeDistance(first.cfl, pose.X_WA, second.cfl, pose.X_WB, options), truth, first, second,
                      pose, "CflModel B", failures);
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

// RegionTree keeps a list whose ids span 65536 or more "wide" (low and high 16 bits apart). Only meshes
// that large have such lists, so here the bunny's lists are re-encoded wide by hand: the query must decode
// them to the same ids and give the same answers, bit for bit, as from the narrow ones.
TEST(ComputeDistance, WideListsGiveTheSameAnswersAsNarrowOnes) {
  const Shape& a = bunny();
  const Shape& b = shape("torus");
  CflModel wide = a.cfl;
  RegionTree& tree = wide.regions;
  ASSERT_TRUE(tree.list_high_ids.empty());
  const std::vector<std::int32_t> ids = tree.listTriangles();
  tree.list_high_ids.clear();
  for (std::uint32_t list = 0; list < tree.listCount(); ++list) {
    const std::uint32_t base = ~std::uint32_t(tree.list_high_ids.size());
    std::uint16_t* slots = tree.list_entry_ids.data() + tree.listIdsBegin(list);
    slots[0] = std::uint16_t(base & 0xffff);
    slots[1] = std::uint16_t(base >> 16);
    for (std::uint32_t n = 0; n < tree.listLength(list); ++n) {
      const std::int32_t id = ids[tree.list_offsets[list] + n];
      slots[2 + n] = std::uint16_t(id & 0xffff);
      tree.list_high_ids.push_back(std::uint16_t(id >> 16));
    }
  }
  ASSERT_EQ(tree.listTriangles(), ids);
  test::Rng rng(91);
  Failures failures;
  for (double fraction : kSeparations) {
    const Pose pose = makePose(a, b, fraction, rng);
    const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
    for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
      DistanceOptions options;
      options.mode = mode;
      const DistanceResult narrow = computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options);
      const DistanceResult from_wide = computeDistance(wide, pose.X_WA, b.model, pose.X_WB, options);
      EXPECT_EQ(from_wide.distance, narrow.distance) << "separation " << fraction;
      EXPECT_EQ(from_wide.triangle_a, narrow.triangle_a) << "separation " << fraction;
      EXPECT_EQ(from_wide.triangle_b, narrow.triangle_b) << "separation " << fraction;
      checkResult(from_wide, truth, a, b, pose, "wide lists", failures);
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

TEST(ComputeDistance, OverlappingMeshesGiveZeroWithOnePointOnBothTriangles) {
  test::Rng rng(8);
  Failures failures;
  int overlaps = 0;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    for (int n = 0; n < 10; ++n) {
      const Pose pose = makePose(a, b, 0.0, rng);
      const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
      if (truth.distance != 0) continue;
      ++overlaps;
      const double tolerance = 1e-9 * std::max(a.diagonal, b.diagonal);
      for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
        DistanceOptions options;
        options.mode = mode;
        const DistanceResult r = computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options);
        Eigen::Vector3d ta[3], tb[3];
        if (r.triangle_a < 0 || r.triangle_b < 0) {
          failures.add("no triangle pair returned for " + describe(pose, a, b));
          continue;
        }
        worldTriangle(a.model, r.triangle_a, pose.X_WA, ta);
        worldTriangle(b.model, r.triangle_b, pose.X_WB, tb);
        if (!(r.distance <= tolerance && (r.point_a - r.point_b).norm() <= tolerance &&
              pointToTriangle(r.point_a, ta) <= tolerance && pointToTriangle(r.point_a, tb) <= tolerance)) {
          std::ostringstream out;
          out << "overlap: distance " << r.distance << ", |point_a - point_b| " << (r.point_a - r.point_b).norm()
              << ", point_a off triangle_a by " << pointToTriangle(r.point_a, ta) << ", off triangle_b by "
              << pointToTriangle(r.point_a, tb) << " for " << describe(pose, a, b);
          failures.add(out.str());
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
  EXPECT_GE(overlaps, 40);
}

TEST(ComputeDistance, IdenticalMeshesAtIdenticalPosesAreAtZero) {
  test::Rng rng(3);
  for (const auto& s : shapes()) {
    const Eigen::Isometry3d X = test::randomPose(rng, 5.0);
    const double tolerance = 1e-9 * s->diagonal;
    for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
      DistanceOptions options;
      options.mode = mode;
      for (const DistanceResult& r : {computeDistance(s->cfl, X, s->model, X, options),
                                      computeDistance(s->cfl, X, s->cfl, X, options)}) {
        EXPECT_LE(r.distance, tolerance) << s->name;
        EXPECT_LE((r.point_a - r.point_b).norm(), tolerance) << s->name;
        ASSERT_GE(r.triangle_a, 0) << s->name;
        ASSERT_GE(r.triangle_b, 0) << s->name;
        Eigen::Vector3d ta[3], tb[3];
        worldTriangle(s->model, r.triangle_a, X, ta);
        worldTriangle(s->model, r.triangle_b, X, tb);
        EXPECT_LE(pointToTriangle(r.point_a, ta), tolerance) << s->name;
        EXPECT_LE(pointToTriangle(r.point_b, tb), tolerance) << s->name;
      }
    }
  }
}

TEST(ComputeDistance, PosesFarFromTheWorldOriginStayExact) {
  // Both meshes 1e4 diagonals from the world origin: the query must work in A's frame, not lose the
  // distance in the rounding of world coordinates (1e4 * 1e-16 is far below the 1e-9 tolerance).
  test::Rng rng(404);
  Failures failures;
  for (const PairCase& pair : {kPairs[0], kPairs[3], kPairs[6]}) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    for (double fraction : {0.0, 0.005, 0.1}) {
      Pose pose = makePose(a, b, fraction, rng);
      const Eigen::Vector3d offset = 1e4 * a.diagonal * Eigen::Vector3d(0.6, -0.48, 0.64);
      pose.X_WA.translation() += offset;
      pose.X_WB.translation() += offset;
      pose.kind += ", far from the origin";
      const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
      for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
        DistanceOptions options;
        options.mode = mode;
        checkResult(computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options), truth, a, b, pose, "far", failures);
        checkResult(computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB, options), truth, a, b, pose, "far, CflModel B",
                    failures);
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

TEST(ComputeDistance, MeshesInAnyUnitStayExact) {
  // The same shapes in units a million times smaller and larger (a part in metres with micrometre detail,
  // a building in millimetres): no absolute threshold may creep into the bounds or the kernels. FCL 0.7's
  // triangle distance has one (1e-15 on a squared cross product) and misses vertex-face contacts of
  // triangles with edges under about 2e-4 units.
  test::Rng rng(77);
  Failures failures;
  for (const double scale : {1e-6, 1e-3, 1e3, 1e6}) {
    auto scaled = [&](const std::string& name, TriangleMesh mesh) {
      for (auto& v : mesh.vertices) v *= scale;
      return makeShape(name + " x" + std::to_string(scale), std::move(mesh), 12);
    };
    const auto a = scaled("knot", test::makeTorusKnot(2, 3, 0.5, 0.3, 30, 4));
    const auto b = scaled("messy", test::makeMessyMesh(10, 6));
    for (double fraction : {-1.0, 0.005, 0.02, 0.5}) {
      for (int n = 0; n < 3; ++n) {
        const Pose pose = makePose(*a, *b, fraction, rng, 2.0 * scale);
        const DistanceResult truth = bruteForceDistance(a->model, pose.X_WA, b->model, pose.X_WB);
        checkReferenceWithPoints(truth, *a, *b, pose, failures);
        checkResult(computeDistance(a->cfl, pose.X_WA, b->model, pose.X_WB), truth, *a, *b, pose, "scaled", failures);
        checkResult(computeDistance(a->cfl, pose.X_WA, b->cfl, pose.X_WB), truth, *a, *b, pose, "scaled, CflModel B",
                    failures);
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

TEST(ComputeDistance, MeshEntirelyOutsideTheGridIsExact) {
  test::Rng rng(12);
  Failures failures;
  int outside = 0;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    for (double fraction : {0.6, 1.0, 3.0, 50.0}) {
      for (int n = 0; n < 3; ++n) {
        const Pose pose = makePose(a, b, fraction, rng);
        // Only poses where every vertex of B is outside A's grid count for this property.
        const Aabb grid = a.cfl.regions.bounds();
        const Eigen::Isometry3d X_AB = pose.X_WA.inverse() * pose.X_WB;
        bool all_outside = true;
        for (const auto& v : b.mesh.vertices) {
          const Eigen::Vector3d p = X_AB * v;
          if ((grid.min.array() <= p.array()).all() && (p.array() <= grid.max.array()).all()) all_outside = false;
        }
        if (!all_outside) continue;
        ++outside;
        const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          checkResult(computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options), truth, a, b, pose, "outside grid",
                      failures);
          checkResult(computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB, options), truth, a, b, pose,
                      "outside grid, CflModel B", failures);
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
  EXPECT_GE(outside, 40) << "too few poses with B outside the grid";
}

TEST(ComputeDistance, ToleranceGuaranteeHoldsAndTheDistanceIsThatOfTheReturnedPair) {
  test::Rng rng(55);
  Failures failures;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    const double tolerance = 1e-9 * std::max(a.diagonal, b.diagonal);
    for (double fraction : {0.0, 0.005, 0.1, 0.5}) {
      const Pose pose = makePose(a, b, fraction, rng);
      const double truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB).distance;
      for (double rel_err : {0.0, 0.05, 0.5}) {
        for (double abs_err : {0.0, 0.01 * a.diagonal, 0.2 * a.diagonal}) {
          for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
            DistanceOptions options;
            options.mode = mode;
            options.rel_err = rel_err;
            options.abs_err = abs_err;
            for (const DistanceResult& r : {computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options),
                                            computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB, options)}) {
              std::ostringstream problems;
              if (!(r.distance >= truth - tolerance)) problems << " below the true distance;";
              if (!(r.distance <= truth + abs_err + tolerance)) problems << " above true + abs_err;";
              if (!(r.distance <= truth * (1 + rel_err) + tolerance)) problems << " above true * (1 + rel_err);";
              if (r.triangle_a < 0 || r.triangle_b < 0) {
                problems << " no pair returned;";
              } else {
                Eigen::Vector3d ta[3], tb[3];
                worldTriangle(a.model, r.triangle_a, pose.X_WA, ta);
                worldTriangle(b.model, r.triangle_b, pose.X_WB, tb);
                if (!(std::abs(std::sqrt(triangleTriangleSquaredDistance(ta, tb)) - r.distance) <= tolerance)) {
                  problems << " the returned pair is not at the returned distance;";
                }
                if (!(pointToTriangle(r.point_a, ta) <= tolerance && pointToTriangle(r.point_b, tb) <= tolerance &&
                      std::abs((r.point_a - r.point_b).norm() - r.distance) <= tolerance)) {
                  problems << " points inconsistent with the pair;";
                }
              }
              if (!problems.str().empty()) {
                std::ostringstream out;
                out << "rel_err " << rel_err << " abs_err " << abs_err << ": distance " << r.distance << ", true "
                    << truth << ":" << problems.str() << " " << describe(pose, a, b);
                failures.add(out.str());
              }
            }
          }
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

TEST(ComputeDistance, WarmStartHintsNeverChangeTheAnswer) {
  test::Rng rng(66);
  Failures failures;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    const int na = static_cast<int>(a.mesh.triangles.size()), nb = static_cast<int>(b.mesh.triangles.size());
    for (double fraction : {0.0, 0.005, 0.1, 3.0}) {
      const Pose pose = makePose(a, b, fraction, rng);
      const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
      std::uniform_int_distribution<int> random_a(0, na - 1), random_b(0, nb - 1);
      const std::pair<int, int> hints[] = {
          {truth.triangle_a, truth.triangle_b},  // the answer itself
          {random_a(rng), random_b(rng)},        // valid but far from the answer
          {na - 1, nb - 1},                      // last valid ids
          {-1, -1},                              // no hint
          {-5, 3},                               // negative
          {na, 0},                               // one past the end of A
          {0, nb},                               // one past the end of B
          {INT_MAX, INT_MIN},
      };
      for (const auto& [hint_a, hint_b] : hints) {
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          options.hint_triangle_a = hint_a;
          options.hint_triangle_b = hint_b;
          const std::string label = "hint (" + std::to_string(hint_a) + ", " + std::to_string(hint_b) + ")";
          checkResult(computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options), truth, a, b, pose, label,
                      failures);
          checkResult(computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB, options), truth, a, b, pose,
                      label + ", CflModel B", failures);
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

// A broadphase passes the best distance it holds: a pair that cannot beat it comes back empty, one that can
// comes back exact. Bounds just above, at and just below the true distance, and far from it both ways.
TEST(ComputeDistance, UpperBoundFindsExactlyThePairsThatBeatIt) {
  test::Rng rng(67);
  Failures failures;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    for (double fraction : {0.0, 0.005, 0.1, 3.0}) {
      const Pose pose = makePose(a, b, fraction, rng);
      const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
      for (double bound : {truth.distance * 2 + a.diagonal, truth.distance * (1 + 1e-6) + 1e-12, truth.distance,
                           truth.distance * 0.5, 0.0}) {
        for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
          DistanceOptions options;
          options.mode = mode;
          options.upper_bound = bound;
          std::ostringstream label;
          label << "upper bound " << bound << " (truth " << truth.distance << ")";
          const DistanceResult r = computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, options);
          // At a bound equal to the distance, rounding may put the pair on either side: both are right.
          const double slack = 1e-12 * (a.diagonal + b.diagonal);
          const bool empty =
              r.distance == std::numeric_limits<double>::infinity() && r.triangle_a == -1 && r.triangle_b == -1;
          if (!empty) {
            checkResult(r, truth, a, b, pose, label.str(), failures);
            if (!(truth.distance < bound + slack)) failures.add(label.str() + ": a pair at or above the bound");
          } else if (!(truth.distance > bound - slack)) {
            failures.add(a.name + " vs " + b.name + ", " + label.str() + ": no pair, though one beats the bound");
          }
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
  DistanceOptions negative;
  negative.upper_bound = -1;
  const Shape& s = shape(kPairs[0].a);
  EXPECT_THROW(computeDistance(s.cfl, Eigen::Isometry3d::Identity(), s.model, Eigen::Isometry3d::Identity(), negative),
               Error);
}

std::string trialLabel(int trial, const char* parameter, double value) {
  std::ostringstream out;
  out << "trial " << trial << " (" << parameter << " " << value << ")";
  return out.str();
}

// A's triangle 0 is the closest to B's single triangle; triangle 1, a decoy slightly farther, is passed as
// the hint and so sets the first threshold. Both query modes must still find triangle 0's distance: a lower
// bound that errs upwards prunes it and returns the decoy's.
void checkHintedDecoyKeepsTheClosestPair(const TriangleMesh& mesh_a, const TriangleMesh& mesh_b,
                                         const std::string& label, Failures& failures) {
  BuildOptions build;
  build.resolution = 16;
  const CflModel a = buildCflModel(mesh_a, build);
  const MeshModel b = makeMeshModel(mesh_b);
  const Eigen::Isometry3d identity = Eigen::Isometry3d::Identity();
  const DistanceResult truth = bruteForceDistance(a.geometry, identity, b, identity);
  ASSERT_EQ(truth.triangle_a, 0) << label << ": triangle 0 of A must be the closest to B";
  for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
    DistanceOptions options;
    options.mode = mode;
    options.hint_triangle_a = 1;
    options.hint_triangle_b = 0;
    const DistanceResult result = computeDistance(a, identity, b, identity, options);
    if (std::abs(result.distance - truth.distance) > 1e-9 * a.geometry.bounds.diagonal()) {
      std::ostringstream out;
      out.precision(17);
      out << label << ", mode " << int(mode) << ": distance " << result.distance << " on triangle "
          << result.triangle_a << ", brute force " << truth.distance;
      failures.add(out.str());
    }
  }
}

// A sliver's plane bounds its pairs from below only as well as its normal's direction is known. Here the
// closest triangle of A to B is a sliver (height 1e-6 to 1e-12 of its length) and a decoy triangle, tried
// first through the hint, sits 0 to 1e-5 of the gap farther: a normal off by more than that relative
// difference would prune the sliver's pair and return the decoy. With plain double cross products about
// one trial in six did.
TEST(ComputeDistance, SliverPlanesNeverPruneTheClosestPair) {
  test::Rng rng(71);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Failures failures;
  for (int trial = 0; trial < 400; ++trial) {
    const Eigen::Isometry3d X = test::randomPose(rng, 10);
    const double height = std::pow(10.0, -6 - 6 * unit(rng));
    const double gap = 1e-3 * (0.5 + unit(rng));
    const Eigen::Vector3d probe(0.2 + 0.6 * unit(rng), 0.3 * height, gap);
    const Eigen::Vector3d decoy = probe + Eigen::Vector3d(0, gap * (1 + 1e-5 * unit(rng)), 0);
    auto place = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return X * x; };
    TriangleMesh mesh_a;
    mesh_a.vertices = {place({0, 0, 0}), place({1, 0, 0}), place({0.35 + 0.3 * unit(rng), height, 0}),
                       place(decoy), place(decoy + Eigen::Vector3d(0, 0.01, 0.001)),
                       place(decoy + Eigen::Vector3d(0.01, 0.01, 0))};
    mesh_a.triangles = {{0, 1, 2}, {3, 4, 5}};
    TriangleMesh mesh_b;
    mesh_b.vertices = {place(probe), place(probe + Eigen::Vector3d(1e-4, 0, 0)),
                       place(probe + Eigen::Vector3d(0, 0, 1e-4))};
    mesh_b.triangles = {{0, 1, 2}};
    ASSERT_NO_FATAL_FAILURE(checkHintedDecoyKeepsTheClosestPair(
        mesh_a, mesh_b, trialLabel(trial, "height", height), failures));
  }
  EXPECT_EQ(failures.count(), 0);
}

// The pair filter's edge-edge axes are cross products of two edges; between nearly parallel edges the
// rounded product is far from orthogonal to them, so a bound that skipped projecting any corner would prune
// pairs that are closer than the threshold (a version that took an edge's ends as projecting at one value
// failed here, its first three failing trials off by 2e-6 to 6e-6). The closest features are two edges 1e-2
// to 1e-12 rad from parallel, far from the origin, with a decoy 0.1% to 1.1% farther given as the hint.
TEST(ComputeDistance, EdgeAxesNeverPruneTheClosestPair) {
  test::Rng rng(73);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  Failures failures;
  for (int trial = 0; trial < 300; ++trial) {
    const Eigen::Isometry3d X = test::randomPose(rng, 100);
    const double angle = std::pow(10.0, -2 - 10 * unit(rng));
    const double gap = 1e-3 * (0.5 + unit(rng));
    auto place = [&](const Eigen::Vector3d& x) -> Eigen::Vector3d { return X * x; };
    // A's edge along x at z = 0, its triangle below; B's edge at z = gap turned by `angle` about z, its
    // triangle above: the closest points are on the two edges.
    const Eigen::Vector3d along(std::cos(angle), std::sin(angle), 0);
    const Eigen::Vector3d start(0.25 * unit(rng), 0, gap);
    // The decoy's tip lies under B's edge, 0.1% to 1.1% farther from it than A's edge.
    const Eigen::Vector3d decoy = start + 0.95 * along - Eigen::Vector3d(0, 0, gap * (1.001 + 0.01 * unit(rng)));
    TriangleMesh mesh_a;
    mesh_a.vertices = {place({0, 0, 0}), place({1, 0, 0}), place({0.5, 0.3 * unit(rng), -0.5}),
                       place(decoy), place(decoy + Eigen::Vector3d(0.01, 0, -0.01)),
                       place(decoy + Eigen::Vector3d(0, 0.01, -0.01))};
    mesh_a.triangles = {{0, 1, 2}, {3, 4, 5}};
    TriangleMesh mesh_b;
    mesh_b.vertices = {place(start), place(start + along), place(start + Eigen::Vector3d(0.5, 0.3 * unit(rng), 0.5))};
    mesh_b.triangles = {{0, 1, 2}};
    ASSERT_NO_FATAL_FAILURE(checkHintedDecoyKeepsTheClosestPair(
        mesh_a, mesh_b, trialLabel(trial, "angle", angle), failures));
  }
  EXPECT_EQ(failures.count(), 0);
}

TEST(ComputeDistance, ConcurrentQueriesOnSharedModelsGiveTheSequentialAnswers) {
  const Shape& a = shape("knot");
  const Shape& b = shape("messy");
  test::Rng rng(91);
  std::vector<Pose> poses;
  for (int n = 0; n < 40; ++n) poses.push_back(makePose(a, b, kSeparations[n % 7], rng));
  std::vector<DistanceResult> sequential;
  for (const Pose& pose : poses) sequential.push_back(computeDistance(a.cfl, pose.X_WA, b.cfl, pose.X_WB));
  std::vector<DistanceResult> concurrent(poses.size());
  auto work = [&](std::size_t first) {
    for (int repeat = 0; repeat < 5; ++repeat) {
      for (std::size_t i = first; i < poses.size(); i += 2) {
        concurrent[i] = computeDistance(a.cfl, poses[i].X_WA, b.cfl, poses[i].X_WB);
      }
    }
  };
  std::thread t0(work, 0), t1(work, 1);
  t0.join();
  t1.join();
  for (std::size_t i = 0; i < poses.size(); ++i) {
    EXPECT_EQ(concurrent[i].distance, sequential[i].distance) << "pose " << i;
    EXPECT_EQ(concurrent[i].triangle_a, sequential[i].triangle_a) << "pose " << i;
    EXPECT_EQ(concurrent[i].triangle_b, sequential[i].triangle_b) << "pose " << i;
  }
}

TEST(ComputeCollision, AgreesWithBruteForceAndReturnsRealContacts) {
  test::Rng rng(101);
  Failures failures;
  int colliding = 0, separate = 0;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    const double tolerance = 1e-9 * std::max(a.diagonal, b.diagonal);
    for (double fraction : {0.0, 0.0, 0.005, 0.02, 0.5}) {
      for (int n = 0; n < 3; ++n) {
        const Pose pose = makePose(a, b, fraction, rng);
        const double truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB).distance;
        // Within rounding of touching the answer may go either way; every other pose has one right answer.
        if (truth > 0 && truth <= tolerance) continue;
        const bool expected = truth == 0;
        (expected ? colliding : separate)++;
        const bool without_contacts = computeCollision(a.model, pose.X_WA, b.model, pose.X_WB);
        if (without_contacts != expected) {
          failures.add(std::string("collision ") + (without_contacts ? "true" : "false") + " but brute-force distance " +
                       std::to_string(truth) + " for " + describe(pose, a, b));
        }
        for (std::size_t max_contacts : {std::size_t(1), std::size_t(7), std::size_t(100000)}) {
          std::vector<Contact> contacts;
          const bool with_contacts = computeCollision(a.model, pose.X_WA, b.model, pose.X_WB, max_contacts, &contacts);
          std::ostringstream problems;
          if (with_contacts != expected) problems << " wrong answer " << with_contacts << ";";
          if (contacts.size() > max_contacts) problems << " " << contacts.size() << " contacts > max;";
          if (expected != !contacts.empty()) problems << " " << contacts.size() << " contacts;";
          for (const Contact& c : contacts) {
            if (c.triangle_a < 0 || c.triangle_a >= static_cast<int>(a.model.corners.size()) || c.triangle_b < 0 ||
                c.triangle_b >= static_cast<int>(b.model.corners.size())) {
              problems << " contact ids out of range;";
              continue;
            }
            Eigen::Vector3d ta[3], tb[3];
            worldTriangle(a.model, c.triangle_a, pose.X_WA, ta);
            worldTriangle(b.model, c.triangle_b, pose.X_WB, tb);
            const double off_a = pointToTriangle(c.position, ta), off_b = pointToTriangle(c.position, tb);
            if (!(off_a <= tolerance && off_b <= tolerance)) {
              problems << " contact (" << c.triangle_a << ", " << c.triangle_b << ") position is " << off_a
                       << " off A and " << off_b << " off B;";
            }
          }
          if (!problems.str().empty()) {
            failures.add("max_contacts " + std::to_string(max_contacts) + ":" + problems.str() + " " +
                         describe(pose, a, b));
          }
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
  EXPECT_GE(colliding, 40);
  EXPECT_GE(separate, 60);
}

TEST(ComputeCollision, ContactsListEveryIntersectingPairWhenUnbounded) {
  // With room for every contact, the contacts are exactly the intersecting pairs found by testing all
  // pairs with the kernel's predicate (itself tested in triangle_distance_test), each pair once.
  test::Rng rng(202);
  Failures failures;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    for (int n = 0; n < 3; ++n) {
      const Pose pose = makePose(a, b, 0.0, rng);
      std::vector<std::pair<int, int>> expected;
      for (int i = 0; i < static_cast<int>(a.model.corners.size()); ++i) {
        Eigen::Vector3d ta[3];
        worldTriangle(a.model, i, pose.X_WA, ta);
        for (int j = 0; j < static_cast<int>(b.model.corners.size()); ++j) {
          Eigen::Vector3d tb[3];
          worldTriangle(b.model, j, pose.X_WB, tb);
          if (trianglesIntersect(ta, tb)) expected.emplace_back(i, j);
        }
      }
      std::vector<Contact> contacts;
      computeCollision(a.model, pose.X_WA, b.model, pose.X_WB, expected.size() + 1000, &contacts);
      std::vector<std::pair<int, int>> found;
      for (const Contact& c : contacts) found.emplace_back(c.triangle_a, c.triangle_b);
      std::sort(found.begin(), found.end());
      if (found != expected) {
        failures.add("found " + std::to_string(found.size()) + " intersecting pairs, expected " +
                     std::to_string(expected.size()) + " for " + describe(pose, a, b));
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

// A smooth motion of B relative to A, both moving in the world: every frame B turns by `turn` radians
// about a fixed axis through its center and moves by `step` (a fraction of A's diagonal) along a fixed
// direction, while A turns slowly about its own center; `pull` > 0 aims the direction at A's center.
std::vector<Pose> smoothMotion(const Shape& a, const Shape& b, const Pose& start, int frames, double step, double turn,
                               bool pull, test::Rng& rng) {
  std::normal_distribution<double> normal;
  auto randomAxis = [&] { return Eigen::Vector3d(normal(rng), normal(rng), normal(rng)).normalized(); };
  const Eigen::Vector3d axis_b = randomAxis(), axis_a = randomAxis();
  Eigen::Vector3d direction = randomAxis();
  if (pull) {
    direction = (start.X_WA * a.model.bounds.center() - start.X_WB * b.model.bounds.center()).normalized();
  }
  std::vector<Pose> out{start};
  for (int k = 1; k < frames; ++k) {
    Pose next = out.back();
    const Eigen::Vector3d center_b = next.X_WB * b.model.bounds.center();
    next.X_WB.linear() = Eigen::AngleAxisd(turn, axis_b).toRotationMatrix() * next.X_WB.linear();
    next.X_WB.translation() = center_b + step * a.diagonal * direction - next.X_WB.linear() * b.model.bounds.center();
    const Eigen::Vector3d center_a = next.X_WA * a.model.bounds.center();
    next.X_WA.linear() = Eigen::AngleAxisd(0.3 * turn, axis_a).toRotationMatrix() * next.X_WA.linear();
    next.X_WA.translation() = center_a - next.X_WA.linear() * a.model.bounds.center();
    next.kind = start.kind + ", frame " + std::to_string(k);
    out.push_back(next);
  }
  return out;
}

// What makes a certificate sound, checked on points: wherever a point of B can get by moving no more than
// the reach (a distance r), if it is then within level - r of A (a pose whose answer the cache would give
// without a search), some triangle of A closest to it is listed with the point's triangle of B. Points on
// each triangle of B (corners and random ones), each moved in random directions; their closest triangles by
// brute force over A.
void checkCertificateCoversTheReach(const Shape& a, const Shape& b, const Pose& pose, const DistanceCache& cache,
                                    const std::string& label, Failures& failures) {
  test::Rng rng(static_cast<std::uint64_t>(cache.searched) * 7919 + cache.near_pairs.size());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const std::size_t na = a.model.corners.size(), nb = b.model.corners.size();
  std::vector<std::vector<int>> listed(nb);
  for (const auto& [ta, tb] : cache.near_pairs) listed[std::size_t(tb)].push_back(ta);
  std::vector<std::array<Eigen::Vector3d, 3>> world_a(na);
  for (std::size_t i = 0; i < na; ++i) worldTriangle(a.model, int(i), pose.X_WA, world_a[i].data());
  for (std::size_t j = 0; j < nb; ++j) {
    Eigen::Vector3d q[3];
    worldTriangle(b.model, int(j), pose.X_WB, q);
    for (int sample = 0; sample < 6; ++sample) {
      double u = unit(rng), v = unit(rng);
      if (sample < 3) u = sample == 1, v = sample == 2;  // the corners
      if (u + v > 1) u = 1 - u, v = 1 - v;
      const double r = cache.reach * unit(rng);
      const Eigen::Vector3d direction = test::randomRotation(rng).col(0);
      const Eigen::Vector3d moved = q[0] + u * (q[1] - q[0]) + v * (q[2] - q[0]) + r * direction;
      double nearest = std::numeric_limits<double>::infinity();
      std::vector<double> to(na);
      for (std::size_t i = 0; i < na; ++i) {
        to[i] = pointToTriangle(moved, world_a[i].data());
        nearest = std::min(nearest, to[i]);
      }
      if (!(nearest < cache.level - r)) continue;
      bool covered = false;
      for (int ta : listed[j]) covered = covered || to[std::size_t(ta)] <= nearest + 1e-12 * a.diagonal;
      if (!covered) {
        failures.add(label + ": a point of B's triangle " + std::to_string(j) + " moved by " + std::to_string(r) +
                     " is " + std::to_string(nearest) + " from A, within level - r (level " +
                     std::to_string(cache.level) + "), but none of its closest triangles of A is listed with it");
        return;
      }
    }
  }
}

// The certificate a search leaves must give the exact answer at every pose B reaches by moving no point
// more than its reach: the pairs it lists then hold the closest pair even when that pair is another one than
// at the pose searched. Poses around the one searched, B turned about its box's center and shifted by up to
// 1.2 times the reach (past it the query must search again), each answered from a copy of the cache.
void checkCertificate(const Shape& a, const Shape& b, const Pose& pose, const DistanceCache& cache,
                      const std::string& label, Failures& failures) {
  test::Rng rng(static_cast<std::uint64_t>(cache.searched) * 7919 + cache.near_pairs.size());
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const Eigen::Vector3d center = b.model.bounds.center();
  const double radius = 0.5 * b.model.bounds.diagonal();
  for (int sample = 0; sample < 8; ++sample) {
    const double motion = 1.2 * unit(rng) * cache.reach;
    const double turned = unit(rng);
    const Eigen::Vector3d axis = test::randomRotation(rng).col(0);
    const Eigen::Vector3d shift = test::randomRotation(rng).col(0) * (1 - turned) * motion;
    Eigen::Isometry3d step = Eigen::Isometry3d::Identity();
    step.linear() = Eigen::AngleAxisd(radius > 0 ? turned * motion / radius : 0.0, axis).toRotationMatrix();
    step.translation() = center - step.linear() * center + shift;
    Pose moved = pose;
    moved.X_WB = pose.X_WB * step;
    DistanceCache copy = cache;
    const DistanceResult truth = bruteForceDistance(a.model, moved.X_WA, b.model, moved.X_WB);
    checkResult(computeDistance(a.cfl, moved.X_WA, b.model, moved.X_WB, copy), truth, a, b, moved,
                label + ", within the certificate's reach", failures);
  }
}

// Runs `frames` through one cache and checks every answer against brute force, and each certificate a search
// leaves with the two checks above. Returns the frames the certificate answered.
std::int64_t checkCachedFrames(const Shape& a, const Shape& b, const std::vector<Pose>& frames, DistanceCache& cache,
                               const std::string& label, Failures& failures) {
  const std::int64_t reused_before = cache.reused;
  for (const Pose& pose : frames) {
    const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
    const std::int64_t searched_before = cache.searched;
    checkResult(computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, cache), truth, a, b, pose, label, failures);
    if (cache.searched > searched_before && cache.certified) {
      checkCertificateCoversTheReach(a, b, pose, cache, label, failures);
      checkCertificate(a, b, pose, cache, label, failures);
    }
  }
  return cache.reused - reused_before;
}

// A few small triangles of B skimming finely tessellated surfaces of A (a flat plate, a wavy sheet): the
// adaptive regions' lists there are long, and consecutive triangles of B (in the search's order) meet the
// same leaves, or overlapping sets of them, with list prefixes that differ in their lists, their count or
// their lengths. The list scan reuses the previous triangle's merged candidates only when its prefixes are
// the same; reusing them otherwise tests a triangle of B against the wrong triangles of A, and brute force
// disagrees wherever that triangle holds the answer. Through a DistanceCache, every triangle of B counts:
// a scan of the wrong candidates leaves pairs out of the certificate. (A rule comparing the lists but not
// their lengths would pass, and rightly: within a query the threshold only falls, so a list's prefix only
// shortens, and the stale merged set holds the new prefixes' triangles.)
TEST(ComputeDistance, SmallMeshesSkimmingTessellatedSurfacesMatchBruteForce) {
  struct Surface {
    std::unique_ptr<Shape> shape;
    std::function<double(double, double)> height;  // of the face B skims, A's frame
  };
  Surface surfaces[] = {
      {makeShape("tessellated_plate", test::makeThinPlate(1.0, 0.05, 16), 0), [](double, double) { return 0.025; }},
      {makeShape("tessellated_wavy_sheet", test::makeWavySheet(1.0, 0.15, 24), 0),
       [](double x, double y) { return 0.15 * std::sin(x) * std::cos(y); }},
  };
  test::Rng rng(8080);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Failures failures;
  int poses = 0, skims = 0, certified = 0;
  for (const Surface& surface : surfaces) {
    const Shape& a = *surface.shape;
    for (int mesh = 0; mesh < 16; ++mesh) {
      const int triangles = 2 + mesh % 3;
      const auto b =
          mesh % 2 == 0
              ? makeShape("soup of " + std::to_string(triangles),
                          test::makeTriangleSoup(triangles, 500 + mesh, 0.06, 0.04 + 0.01 * (mesh % 4)), 4)
              : makeShape("small sheet", test::makeWavySheet(0.04 + 0.02 * (mesh % 5), 0.01, 2 + mesh % 3), 4);
      for (int n = 0; n < 50; ++n) {
        // B's center above (or below) a random point of the face, at most a few of its quads away.
        Pose pose{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), "skimming " + a.name};
        pose.X_WA.linear() = test::randomRotation(rng);
        const double x = 0.95 * unit(rng), y = 0.95 * unit(rng);
        const Eigen::Vector3d over(x, y, surface.height(x, y) + 0.06 * (unit(rng) + 0.9));
        pose.X_WB.linear() = pose.X_WA.linear() * test::randomRotation(rng);
        pose.X_WB.translation() = pose.X_WA.linear() * over;
        const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b->model, pose.X_WB);
        ++poses;
        ++skims;
        checkResult(computeDistance(a.cfl, pose.X_WA, b->model, pose.X_WB), truth, a, *b, pose, b->name, failures);
        // A small step on, the cache searches with a margin and lists every pair its scans meet within it:
        // the certificate's checks then see every triangle of B's scan, not only the answer's.
        DistanceCache cache;
        checkCachedFrames(a, *b, smoothMotion(a, *b, pose, 2, 2e-4, 1e-3, false, rng), cache, b->name + ", cached",
                          failures);
        certified += cache.certified;
      }
    }
  }
  // A row of copies of one small triangle over the plate, two of its quads apart and at heights a hair
  // apart: their leaves' lists differ in their triangles but often not in their prefixes' lengths, and
  // which copy the search scans first is a toss-up for the bounds, so that the closest copy is often
  // scanned after another one.
  const Shape& plate = *surfaces[0].shape;
  for (int n = 0; n < 1500; ++n) {
    Shape row;
    row.name = "row of copies";
    const Eigen::Matrix3d tilt =
        Eigen::AngleAxisd(0.3 * unit(rng), Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized())
            .toRotationMatrix();
    const Eigen::Vector3d corner(0.8 * unit(rng), 0.8 * unit(rng), 0.025 + 0.02 * (unit(rng) + 1.1));
    const Eigen::Vector3d along = n % 2 == 0 ? Eigen::Vector3d(0.25, 0, 0) : Eigen::Vector3d(0, 0.25, 0);
    for (int copy = 0; copy < 4; ++copy) {
      const Eigen::Vector3d at = corner + (copy - 1.5) * along + Eigen::Vector3d(0, 0, 1e-4 * unit(rng));
      const int first = static_cast<int>(row.mesh.vertices.size());
      for (const Eigen::Vector3d& v : {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(0.05, 0, 0),
                                       Eigen::Vector3d(0, 0.05, 0)}) {
        row.mesh.vertices.push_back(at + tilt * v);
      }
      row.mesh.triangles.push_back({first, first + 1, first + 2});
    }
    row.model = makeMeshModel(row.mesh);
    row.diagonal = row.model.bounds.diagonal();
    Pose pose{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), "row over the plate"};
    pose.X_WA.linear() = test::randomRotation(rng);
    pose.X_WB = pose.X_WA;
    const DistanceResult truth = bruteForceDistance(plate.model, pose.X_WA, row.model, pose.X_WB);
    ++poses;
    checkResult(computeDistance(plate.cfl, pose.X_WA, row.model, pose.X_WB), truth, plate, row, pose, row.name,
                failures);
  }
  EXPECT_EQ(failures.count(), 0) << "of " << poses << " poses";
  // Most second frames must have certified, or the certificate checks above saw little.
  EXPECT_GE(certified, skims / 2) << certified << " of " << skims << " certified";
}

// Two layouts where a voxel's list must keep triangles that nearly tie or that dwarf the voxel: A made of two
// copies of a sheet a hair apart (every voxel near it sees two nearly identical candidates, one of which
// topology culling or the list's bounds could wrongly drop), and A made of tiny triangles among three huge
// ones that cross the whole grid. B is A itself or a hemisphere, at every range, in both query modes.
TEST(ComputeDistance, NearlyCoincidentLayersAndHugeTrianglesAmongTinyOnesMatchBruteForce) {
  std::vector<std::unique_ptr<Shape>> as;
  const TriangleMesh sheet = test::makeWavySheet(1.0, 0.05, 8);
  for (double gap : {1e-7, 1e-3}) {
    TriangleMesh upper = sheet;
    for (Eigen::Vector3d& v : upper.vertices) v.z() += gap;
    std::ostringstream name;
    name << "double_sheet_" << gap << "_apart";
    as.push_back(makeShape(name.str(), test::merge(sheet, upper), 16));
  }
  TriangleMesh huge;
  huge.vertices = {{-1.2, -1.1, -0.9}, {1.3, -0.8, 0.2}, {-0.1, 1.2, 1.1}, {1.1, 1.2, -1.0}, {-1.0, 0.9, 0.3},
                   {0.2, -1.2, 1.0}, {-1.1, -0.2, 1.2}, {1.2, 0.3, 0.9}, {0.1, 0.2, -1.2}};
  huge.triangles = {{0, 1, 2}, {3, 4, 5}, {6, 7, 8}};
  as.push_back(makeShape("huge_among_tiny", test::merge(test::makeTriangleSoup(150, 31, 1.0, 0.02), huge), 16));
  const auto hemisphere = makeShape("hemisphere", test::makeHemisphere(0.6, 4, 10), 12);
  test::Rng rng(3131);
  Failures failures;
  int poses = 0;
  for (const auto& a : as) {
    for (const Shape* b : {a.get(), hemisphere.get()}) {
      for (double fraction : kSeparations) {
        for (int n = 0; n < 6; ++n) {
          const Pose pose = makePose(*a, *b, fraction, rng);
          const DistanceResult truth = bruteForceDistance(a->model, pose.X_WA, b->model, pose.X_WB);
          ++poses;
          for (QueryMode mode : {QueryMode::kHierarchical, QueryMode::kPaper}) {
            DistanceOptions options;
            options.mode = mode;
            checkResult(computeDistance(a->cfl, pose.X_WA, b->model, pose.X_WB, options), truth, *a, *b, pose,
                        mode == QueryMode::kHierarchical ? "hierarchical" : "paper", failures);
          }
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0) << "of " << poses << " poses";
}

// B's triangles span several of A's voxels on each axis: most voxels of a triangle's box miss its plane and
// are skipped, and the query must still match brute force at every range, searched plainly or through a
// certifying cache (whose margin widens what is kept).
TEST(ComputeDistance, TrianglesOfBSpanningManyVoxelsMatchBruteForce) {
  const auto a = makeShape("fine_torus", test::makeTorus(1.0, 0.35, 10, 5), 64);
  const auto b = makeShape("coarse_hemisphere", test::makeHemisphere(1.0, 3, 8), 4);
  test::Rng rng(107);
  Failures failures;
  for (double fraction : {0.0, 0.002, 0.01, 0.03, 0.1}) {
    for (int n = 0; n < 12; ++n) {
      const Pose pose = makePose(*a, *b, fraction, rng);
      const DistanceResult truth = bruteForceDistance(a->model, pose.X_WA, b->model, pose.X_WB);
      checkResult(computeDistance(a->cfl, pose.X_WA, b->model, pose.X_WB), truth, *a, *b, pose, "plain", failures);
    }
    DistanceCache cache;
    const std::vector<Pose> motion = smoothMotion(*a, *b, makePose(*a, *b, fraction, rng), 20, 1e-3, 1e-3, false, rng);
    checkCachedFrames(*a, *b, motion, cache, "cached", failures);
  }
  EXPECT_EQ(failures.count(), 0);
}

// A slab whose top carries a small patch of tiny triangles joined to the slab's corners by fans of long
// slivers: B's slivers leave the lists for A's Bvh, whose walk stops after a budget and goes on as
// triangle-node pairs in the search's heap (Search::testTriangleAtLeaf); every range must match brute force,
// searched plainly or through a certifying cache.
TriangleMesh makeRefinedSlab() {
  TriangleMesh mesh;
  constexpr int kN = 24;
  constexpr double kLo = 4.5, kSize = 1, kTop = 1;
  auto patch = [&](int i, int j) { return (kN + 1) * j + i; };
  for (int j = 0; j <= kN; ++j) {
    for (int i = 0; i <= kN; ++i) {
      const double u = double(i) / kN, v = double(j) / kN;
      mesh.vertices.push_back({kLo + kSize * u, kLo + kSize * v, kTop + 0.05 * std::sin(3 * u) * std::sin(3 * v)});
    }
  }
  for (int j = 0; j < kN; ++j) {
    for (int i = 0; i < kN; ++i) {
      mesh.triangles.push_back({patch(i, j), patch(i + 1, j), patch(i + 1, j + 1)});
      mesh.triangles.push_back({patch(i, j), patch(i + 1, j + 1), patch(i, j + 1)});
    }
  }
  const int top = int(mesh.vertices.size());
  for (const auto& c : {Eigen::Vector2d(0, 0), Eigen::Vector2d(10, 0), Eigen::Vector2d(10, 10), Eigen::Vector2d(0, 10)}) {
    mesh.vertices.push_back({c.x(), c.y(), kTop});
  }
  for (int side = 0; side < 4; ++side) {
    std::vector<int> edge;
    for (int k = 0; k <= kN; ++k) {
      edge.push_back(side == 0 ? patch(k, 0) : side == 1 ? patch(kN, k) : side == 2 ? patch(kN - k, kN) : patch(0, kN - k));
    }
    const int a = top + side, c = top + (side + 1) % 4;
    for (int k = 0; k < kN; ++k) mesh.triangles.push_back({k < kN / 2 ? a : c, edge[k + 1], edge[k]});
    mesh.triangles.push_back({a, c, edge[kN / 2]});
  }
  const int bottom = int(mesh.vertices.size());
  for (const auto& c : {Eigen::Vector2d(0, 0), Eigen::Vector2d(10, 0), Eigen::Vector2d(10, 10), Eigen::Vector2d(0, 10)}) {
    mesh.vertices.push_back({c.x(), c.y(), 0.0});
  }
  mesh.triangles.push_back({bottom, bottom + 3, bottom + 2});
  mesh.triangles.push_back({bottom, bottom + 2, bottom + 1});
  for (int s = 0; s < 4; ++s) {
    const int d0 = bottom + s, d1 = bottom + (s + 1) % 4, t0 = top + s, t1 = top + (s + 1) % 4;
    mesh.triangles.push_back({d0, d1, t1});
    mesh.triangles.push_back({d0, t1, t0});
  }
  return mesh;
}

TEST(ComputeDistance, SliversFannedAroundARefinedPatchMatchBruteForce) {
  const auto a = makeShape("refined_slab", makeRefinedSlab(), 0);
  test::Rng rng(2718);
  Failures failures;
  for (double fraction : kSeparations) {
    for (int n = 0; n < 10; ++n) {
      const Pose pose = makePose(*a, *a, fraction, rng);
      const DistanceResult truth = bruteForceDistance(a->model, pose.X_WA, a->model, pose.X_WB);
      checkResult(computeDistance(a->cfl, pose.X_WA, a->model, pose.X_WB), truth, *a, *a, pose, "plain", failures);
    }
  }
  for (double fraction : {0.0, 0.005, 0.05}) {
    DistanceCache cache;
    const std::vector<Pose> motion = smoothMotion(*a, *a, makePose(*a, *a, fraction, rng), 15, 1e-3, 1e-3, false, rng);
    checkCachedFrames(*a, *a, motion, cache, "cached", failures);
  }
  EXPECT_EQ(failures.count(), 0);
}

// Meshes with triangles about as large as the whole mesh (slivers fanned around a refined patch, a ground
// plane under a small part), each against itself crossing at a steep angle around a shared center: the
// search first descends the node pairs whose oriented boxes overlap (Search::probeForContact). The answer
// must be brute force's, 0 with both points on both returned triangles; and where the meshes are apart
// (pushed out along the normal of the crossing), the pairs that descent tests must not stand in for the
// closest one.
TEST(ComputeDistance, CrossingMeshesWithHugeTrianglesMatchBruteForce) {
  const auto slab = makeShape("refined_slab", makeRefinedSlab(), 0);
  const auto ground = makeShape("ground_with_torus", makeGroundWithTorus(), 0);
  test::Rng rng(31);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Failures failures;
  int overlapping = 0;
  for (const Shape* shape : {slab.get(), ground.get()}) {
    for (int n = 0; n < 24; ++n) {
      Pose pose;
      pose.X_WA = test::randomPose(rng, 2.0);
      const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng), unit(rng), 0.2 * unit(rng)).normalized();
      const double angle = 1.0 + 0.5 * unit(rng);  // radians, steep: the two roots' boxes overlap deeply
      const Eigen::Vector3d center = shape->model.bounds.center();
      Eigen::Isometry3d X_AB = Eigen::Isometry3d::Identity();
      X_AB.linear() = Eigen::AngleAxisd(angle, axis).toRotationMatrix();
      // Every fourth pose pushed off along B's normal so far that the meshes may separate.
      const double push = n % 4 == 3 ? 0.3 * shape->diagonal : 0.0;
      X_AB.translation() = center - X_AB.linear() * center +
                           0.05 * shape->diagonal * Eigen::Vector3d(unit(rng), unit(rng), unit(rng)) +
                           push * (X_AB.linear() * Eigen::Vector3d::UnitZ());
      pose.X_WB = pose.X_WA * X_AB;
      pose.kind = push > 0 ? "crossing, pushed apart" : "crossing";
      const DistanceResult truth = bruteForceDistance(shape->model, pose.X_WA, shape->model, pose.X_WB);
      overlapping += truth.distance == 0;
      checkResult(computeDistance(shape->cfl, pose.X_WA, shape->model, pose.X_WB), truth, *shape, *shape, pose,
                  "plain", failures);
    }
  }
  EXPECT_EQ(failures.count(), 0);
  EXPECT_GE(overlapping, 30);
}

// B nearly level over a large flat part of A, inside A's grid: where the leaves B's nodes meet list only a
// few triangles (the ground's), the node is paired with them and split on its oriented boxes
// (Search::pairWithShortLists). Its triangles nearly tie, so a pair the lists miss, or a bound that
// overshoots, changes the answer. B lies over the ground, past its edges, beside and over the torus, and
// below the ground.
TEST(ComputeDistance, LevelMeshesOverAGroundPlaneMatchBruteForce) {
  const Shape& a = shape("ground_torus");
  const auto sheet = makeShape("level_sheet", test::makeWavySheet(0.6, 0.02, 10), 0);
  const auto small_sheet = makeShape("small_level_sheet", test::makeWavySheet(0.15, 0.005, 6), 0);
  const Shape* level[] = {sheet.get(), small_sheet.get(), &shape("thin_slab")};
  test::Rng rng(2718);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Failures failures;
  int poses = 0;
  for (const Shape* b : level) {
    for (double height : {0.05, 0.2, 0.3, 0.5, 1.0, 2.5, -0.1, -0.4, -1.5}) {
      for (int n = 0; n < 12; ++n) {
        const double tilt = 0.02 * unit(rng);
        const Eigen::Matrix3d R = (Eigen::AngleAxisd(tilt, Eigen::Vector3d(unit(rng), unit(rng), 0).normalized()) *
                                   Eigen::AngleAxisd(3.2 * unit(rng), Eigen::Vector3d::UnitZ()))
                                      .toRotationMatrix();
        // Half the poses over or beside the torus, half anywhere over the ground and a little past its edges.
        const double spread = n % 2 == 0 ? 0.5 : 6.0;
        Pose pose{Eigen::Isometry3d::Identity(), Eigen::Isometry3d::Identity(), "level over the ground"};
        pose.X_WB.linear() = R;
        const Eigen::Vector3d center = b->model.bounds.center();
        const double lowest = height > 0 ? b->model.bounds.min.z() - center.z() : b->model.bounds.max.z() - center.z();
        pose.X_WB.translation() = Eigen::Vector3d(spread * unit(rng), spread * unit(rng), height - lowest) - R * center;
        const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b->model, pose.X_WB);
        if (truth.distance == 0) continue;
        ++poses;
        checkResult(computeDistance(a.cfl, pose.X_WA, b->model, pose.X_WB), truth, a, *b, pose,
                    b->name + " at height " + std::to_string(height), failures);
      }
    }
  }
  EXPECT_EQ(failures.count(), 0) << "of " << poses << " poses";
  EXPECT_GE(poses, 270);
}

// A shape against itself at `count` random poses per gap (fractions of its diagonal), each against brute force.
void expectSelfDistancesMatchBruteForce(const Shape& a, std::initializer_list<double> fractions, int count,
                                        std::uint64_t seed, const std::string& label) {
  test::Rng rng(seed);
  Failures failures;
  for (double fraction : fractions) {
    for (int n = 0; n < count; ++n) {
      const Pose pose = makePose(a, a, fraction, rng);
      const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, a.model, pose.X_WB);
      checkResult(computeDistance(a.cfl, pose.X_WA, a.model, pose.X_WB), truth, a, a, pose, label, failures);
    }
  }
  EXPECT_EQ(failures.count(), 0) << label;
}

// A long, thin, twisted plate, a turbine blade's shape: far apart, the small node pairs of two such blades
// are tested behind one bound shared by all their triangle pairs (Search::testFarBlock), and many of those
// pairs lie within a hair of the closest, so a shared bound that overshot would prune it.
TEST(ComputeDistance, FarApartBladesMatchBruteForce) {
  TriangleMesh blade = test::makeThinPlate(1.0, 0.04, 16);
  for (Eigen::Vector3d& v : blade.vertices) {
    const double along = 6 * v.x(), twist = 0.3 * v.x();
    v = Eigen::Vector3d(along, std::cos(twist) * v.y() - std::sin(twist) * v.z(),
                        std::sin(twist) * v.y() + std::cos(twist) * v.z());
  }
  expectSelfDistancesMatchBruteForce(*makeShape("blade", std::move(blade), 0), {0.02, 0.1, 0.3, 0.5, 1.0, 3.0}, 12,
                                     1618, "far blades");
}

// Thin tubes, a rod bent into a knot and into a ring, against themselves: their Bvh nodes are pieces of the
// tube, needles that node pairs are bounded on as segments swept by disks (MeshModel::node_spine_radii), and
// far apart many of those pairs lie within a hair of the closest, so a radius or a reach across the spine
// taken too small would prune it.
TEST(ComputeDistance, ThinTubesMatchBruteForce) {
  expectSelfDistancesMatchBruteForce(*makeShape("thin knot", test::makeTorusKnot(2, 3, 1.0, 0.02, 120, 4), 0),
                                     {0.005, 0.02, 0.1, 0.3, 0.5, 1.0}, 8, 4711, "thin knot");
  expectSelfDistancesMatchBruteForce(*makeShape("thin ring", test::makeTorus(1.0, 0.01, 160, 5), 0),
                                     {0.005, 0.02, 0.1, 0.3, 0.5, 1.0}, 8, 1147, "thin ring");
}

// The suite's worst case in small: a long flat blade of slivers (a plate 13 times longer than wide,
// triangles 13 times longer than wide, thinner than they are wide), against itself at every band. Far
// apart, its nearly tied node pairs keep the search's heap about a thousand entries deep (the 4-ary heap
// of detail/search_heap.h): any pop out of order ends the search early or prunes the closest pair.
TEST(ComputeDistance, SliverBladeAgainstItselfAtEveryBandMatchesBruteForce) {
  TriangleMesh blade = test::makeThinPlate(1.0, 0.65, 16);
  for (Eigen::Vector3d& v : blade.vertices) {
    const double span = 65 * (v.y() + 1), twist = 0.004 * span;
    const double chord = 5 * v.x();
    v = Eigen::Vector3d(std::cos(twist) * chord - std::sin(twist) * v.z(), span,
                        std::sin(twist) * chord + std::cos(twist) * v.z());
  }
  expectSelfDistancesMatchBruteForce(*makeShape("sliver_blade", std::move(blade), 0), {0.005, 0.02, 0.1, 0.5, 1.0}, 8,
                                     2718, "sliver blade");
}

// A disk triangulated as a fan of slivers around one vertex, as CAD exports cap a cylinder: every sliver's
// sphere spans half the disk, every Bvh node holds the center, and the builder keeps no list (the Bvh
// answers everywhere). The spines' bound (detail/triangle_spine.h) prunes most pairs there, and B's pieces
// over leaves without a list go on as node pairs: at every band, against itself and against a slightly
// domed fan, the answers must equal brute force.
TriangleMesh makeSliverFan(int slivers, double dome, double radius = 20) {
  TriangleMesh mesh;
  mesh.vertices.push_back(Eigen::Vector3d(0, 0, dome));
  for (int k = 0; k < slivers; ++k) {
    const double angle = 2 * M_PI * k / slivers;
    mesh.vertices.push_back(Eigen::Vector3d(radius * std::cos(angle), radius * std::sin(angle), 0));
  }
  for (int k = 0; k < slivers; ++k) mesh.triangles.push_back({0, 1 + k, 1 + (k + 1) % slivers});
  return mesh;
}

TEST(ComputeDistance, SliverFanDisksMatchBruteForce) {
  auto fan = [](int slivers, double dome) { return makeSliverFan(slivers, dome); };
  expectSelfDistancesMatchBruteForce(*makeShape("fan", fan(500, 0), 0), {0, 0.005, 0.02, 0.1, 0.5, 1.0}, 8, 3141,
                                     "flat fan");
  expectSelfDistancesMatchBruteForce(*makeShape("domed fan", fan(400, 0.7), 0), {0.005, 0.02, 0.1, 0.5}, 8, 2718,
                                     "domed fan");
  // Against a compact mesh, either way round: the fan's leaves are needles that stay whole against the
  // torus's larger nodes and split against its smaller ones.
  TriangleMesh small_fan = fan(300, 0.4);
  for (Eigen::Vector3d& v : small_fan.vertices) v *= 0.1;
  const auto torus = makeShape("torus", test::makeTorus(1.0, 0.35, 24, 12), 0);
  const auto disk = makeShape("fan", std::move(small_fan), 0);
  for (const auto& [a, b] : {std::pair{torus.get(), disk.get()}, std::pair{disk.get(), torus.get()}}) {
    test::Rng rng(577);
    Failures failures;
    for (double fraction : {0.0, 0.005, 0.02, 0.1, 0.5, 1.0}) {
      for (int n = 0; n < 8; ++n) {
        const Pose pose = makePose(*a, *b, fraction, rng);
        const DistanceResult truth = bruteForceDistance(a->model, pose.X_WA, b->model, pose.X_WB);
        checkResult(computeDistance(a->cfl, pose.X_WA, b->model, pose.X_WB), truth, *a, *b, pose,
                    a->name + " against " + b->name, failures);
      }
    }
    EXPECT_EQ(failures.count(), 0) << a->name << " against " << b->name;
  }
}

// A fan of slivers (every Bvh node of it reaches from the hub to the rim) crossed by compact meshes, the fan
// as A and as B: the search first descends the node pairs whose oriented boxes overlap, the compact mesh
// split first, testing only the triangle pairs that may touch (Search::probeForContact). The compact mesh's
// center lies in the fan's plane, at the hub, mid-way or past the rim, or off the plane by a little (its
// boxes still cross the fan's, its triangles may not) or by more. Every answer must be brute force's: 0 with
// both points on both returned triangles where they cross, and where they do not, the pairs the descent
// tested must not stand in for the closest.
TEST(ComputeDistance, CompactMeshesCrossingASliverFanMatchBruteForce) {
  std::vector<const Shape*> compact = {&shape("torus"), &shape("knot"), &shape("messy"), &bunny()};
  test::Rng rng(4242);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  Failures failures;
  int overlapping = 0, apart = 0;
  for (const Shape* other : compact) {
    const auto fan = makeShape("fan", makeSliverFan(700, 0.02 * other->diagonal, 0.8 * other->diagonal), 0);
    const int poses = other == &bunny() ? 6 : 16;
    for (int n = 0; n < poses; ++n) {
      const double angle = M_PI * unit(rng);
      const double along = (n % 4 == 0 ? 0.05 : n % 4 == 1 ? 0.5 : n % 4 == 2 ? 0.9 : 1.1) * 0.8 * other->diagonal;
      const double side = unit(rng) < 0 ? -1.0 : 1.0;
      const double off = side * other->diagonal * (n % 3 == 0 ? 0.0 : n % 3 == 1 ? 0.2 * std::abs(unit(rng)) : 0.25 + 0.2 * std::abs(unit(rng)));
      // The compact mesh's box center at (along, angle, off) in the fan's frame, turned at random.
      Eigen::Isometry3d X_FO = Eigen::Isometry3d::Identity();
      X_FO.linear() = test::randomRotation(rng);
      X_FO.translation() = Eigen::Vector3d(along * std::cos(angle), along * std::sin(angle), off) -
                           X_FO.linear() * other->model.bounds.center();
      const Eigen::Isometry3d X_WF = test::randomPose(rng, 2.0);
      for (bool fan_is_a : {true, false}) {
        const Shape& a = fan_is_a ? *fan : *other;
        const Shape& b = fan_is_a ? *other : *fan;
        Pose pose;
        pose.X_WA = fan_is_a ? X_WF : X_WF * X_FO;
        pose.X_WB = fan_is_a ? X_WF * X_FO : X_WF;
        pose.kind = fan_is_a ? "fan as A" : "fan as B";
        const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
        (truth.distance == 0 ? overlapping : apart) += 1;
        checkResult(computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB), truth, a, b, pose,
                    other->name + " crossing a fan", failures);
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
  EXPECT_GE(overlapping, 60);
  EXPECT_GE(apart, 20);
}

// B's Bvh leaves that reach past A's grid go on whole as node pairs with A's Bvh (Search::expand), their
// triangles inside the grid included: flat meshes, slivers among them, at the poses where B straddles the
// grid's boundary must match brute force.
TEST(ComputeDistance, FlatMeshesStraddlingTheGridBoundaryMatchBruteForce) {
  const auto slab = makeShape("refined_slab", makeRefinedSlab(), 0);
  const Shape* flat[] = {slab.get(), &shape("thin_slab"), &shape("ground_torus"), &shape("wavy_sheet")};
  test::Rng rng(3141);
  Failures failures;
  int straddling = 0;
  for (const Shape* a : flat) {
    for (const Shape* b : flat) {
      for (double fraction : {0.4, 0.7, 1.0, 1.5}) {
        for (int n = 0; n < 3; ++n) {
          const Pose pose = makePose(*a, *b, fraction, rng);
          const Aabb grid = a->cfl.regions.bounds();
          const Eigen::Isometry3d X_AB = pose.X_WA.inverse() * pose.X_WB;
          int inside = 0;
          for (const auto& v : b->mesh.vertices) {
            const Eigen::Vector3d p = X_AB * v;
            inside += (grid.min.array() <= p.array()).all() && (p.array() <= grid.max.array()).all();
          }
          if (inside == 0 || inside == int(b->mesh.vertices.size())) continue;
          ++straddling;
          const DistanceResult truth = bruteForceDistance(a->model, pose.X_WA, b->model, pose.X_WB);
          checkResult(computeDistance(a->cfl, pose.X_WA, b->model, pose.X_WB), truth, *a, *b, pose, "straddling",
                      failures);
        }
      }
    }
  }
  EXPECT_EQ(failures.count(), 0);
  EXPECT_GE(straddling, 40) << "too few poses with B across the grid's boundary";
}

TEST(DistanceCache, SlowMotionMatchesBruteForceAndIsMostlyAnsweredByTheCertificate) {
  test::Rng rng(101);
  Failures failures;
  std::int64_t frames = 0, reused = 0;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    // Near and far, in and beyond A's grid.
    for (double fraction : {0.005, 0.03, 0.2, 3.0}) {
      DistanceCache cache;
      // Slow enough for the certificate to last, long enough for the closest pair to change under it.
      const std::vector<Pose> motion = smoothMotion(a, b, makePose(a, b, fraction, rng), 30, 1e-3, 1e-3, false, rng);
      reused += checkCachedFrames(a, b, motion, cache, "slow motion", failures);
      frames += static_cast<std::int64_t>(motion.size());
      EXPECT_EQ(cache.reused + cache.searched, static_cast<std::int64_t>(motion.size()));
    }
  }
  EXPECT_EQ(failures.count(), 0);
  // The first frame of each motion always searches; most of the others should not need to.
  EXPECT_GE(reused, frames / 2) << reused << " of " << frames << " frames answered from the certificate";
}

TEST(DistanceCache, ApproachingThroughContactAndBackStaysExact) {
  test::Rng rng(102);
  Failures failures;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    DistanceCache cache;
    // In steps of 1% of the diagonal from 8% apart into overlap, then straight back out.
    std::vector<Pose> motion = smoothMotion(a, b, makePose(a, b, 0.08, rng), 16, 0.01, 1e-3, true, rng);
    std::vector<Pose> back(motion.rbegin(), motion.rend());
    for (Pose& pose : back) pose.kind += ", returning";
    motion.insert(motion.end(), back.begin(), back.end());
    checkCachedFrames(a, b, motion, cache, "approach", failures);
  }
  EXPECT_EQ(failures.count(), 0);
}

TEST(DistanceCache, SuddenJumpsBetweenSlowStretchesStayExact) {
  test::Rng rng(103);
  Failures failures;
  for (const PairCase& pair : kPairs) {
    const Shape& a = shape(pair.a);
    const Shape& b = shape(pair.b);
    DistanceCache cache;
    // Each stretch starts at a new random pose: the certificate of the last stretch must not be trusted.
    for (double fraction : {0.02, 0.002, 0.1, 0.0, 0.01}) {
      const std::vector<Pose> motion = smoothMotion(a, b, makePose(a, b, fraction, rng), 5, 2e-4, 2e-4, false, rng);
      checkCachedFrames(a, b, motion, cache, "jump", failures);
    }
  }
  EXPECT_EQ(failures.count(), 0);
}

TEST(DistanceCache, OneCacheGivenOtherModelsOrApproximateOptionsStaysCorrect) {
  test::Rng rng(104);
  Failures failures;
  const Shape& a = shape("knot");
  const Shape& other_a = shape("torus");
  const Shape& b = shape("messy");
  const Shape& other_b = shape("soup");
  DistanceCache cache;
  const Pose start = makePose(a, b, 0.01, rng);
  const std::vector<Pose> motion = smoothMotion(a, b, start, 8, 2e-4, 2e-4, false, rng);
  for (std::size_t k = 0; k < motion.size(); ++k) {
    // Alternate the partners at the same poses: a certificate of one pair says nothing about another.
    const Shape& first = k % 3 == 1 ? other_a : a;
    const Shape& second = k % 2 == 1 ? other_b : b;
    const DistanceResult truth = bruteForceDistance(first.model, motion[k].X_WA, second.model, motion[k].X_WB);
    checkResult(computeDistance(first.cfl, motion[k].X_WA, second.model, motion[k].X_WB, cache), truth, first, second,
                motion[k], "alternating models", failures);
  }
  // With a tolerance, the cache steps aside and FCL's guarantee holds.
  const std::int64_t reused = cache.reused;
  DistanceOptions options;
  options.rel_err = 0.2;
  options.abs_err = a.diagonal;
  for (const Pose& pose : motion) {
    const DistanceResult truth = bruteForceDistance(a.model, pose.X_WA, b.model, pose.X_WB);
    const DistanceResult r = computeDistance(a.cfl, pose.X_WA, b.model, pose.X_WB, cache, options);
    EXPECT_LE(r.distance, truth.distance * (1 + options.rel_err) + 1e-9 * a.diagonal);
    EXPECT_GE(r.distance, truth.distance - 1e-9 * a.diagonal);
  }
  EXPECT_EQ(cache.reused, reused);
  EXPECT_EQ(failures.count(), 0);
}

// A certificate must list the pairs B can form anywhere within its margin, including in voxels beyond the
// ones B's triangles touch. Here B is one small horizontal triangle just below a layer of A's voxels (0.01
// voxel), between a sheet of A below (its answer) and a sheet above whose bisector with the lower one lies
// 0.05 voxel inside the next layer. No point of B's own voxels is closest to the upper sheet, so only the
// layer above lists it. B then rises by 0.07 voxel, within the certificate's reach, and the upper sheet becomes
// the closest: a certifying search that skipped the layer above (one that looked only at the voxels B's plane
// crosses) would answer from a certificate without that pair, 0.003 too far.
TEST(DistanceCache, CertificateListsThePairsOfVoxelsOnlyTheMarginReaches) {
  const double h = 0.15;                    // voxel edge: lateral extent 2 + 1 of padding, resolution 20
  const double layer = 3.5 * h;             // the top of B's voxel layer
  const double below = 0.01 * h, bisector = layer + 0.05 * h;
  const double upper = 2 * bisector;        // the lower sheet is at z = 0
  auto sheet = [](TriangleMesh& mesh, double z) {
    const int first = static_cast<int>(mesh.vertices.size());
    for (double x : {-1.0, 1.0}) {
      for (double y : {-1.0, 1.0}) mesh.vertices.emplace_back(x, y, z);
    }
    mesh.triangles.push_back({first, first + 1, first + 3});
    mesh.triangles.push_back({first, first + 3, first + 2});
  };
  TriangleMesh mesh_a;
  sheet(mesh_a, 0.0);
  sheet(mesh_a, upper);
  // A speck in a corner, up at z = 1.2, sets the grid's vertical extent so that a layer of voxels ends at
  // `layer` (15 layers from -0.525: the box grows by 0.5 of its longest extent, 2, on every axis).
  mesh_a.vertices.insert(mesh_a.vertices.end(), {{0.9, 0.9, 1.2}, {1.0, 0.9, 1.2}, {0.9, 1.0, 1.2}});
  mesh_a.triangles.push_back({8, 9, 10});
  BuildOptions options;
  options.resolution = 20;
  options.padding = 1.5;
  const MeshModel model_a = makeMeshModel(mesh_a);
  const CflModel cfl_a = buildCflModel(mesh_a, options);
  ASSERT_EQ(cfl_a.regions.max_depth, 0);
  ASSERT_NEAR(cfl_a.regions.root_size, h, 1e-12);
  ASSERT_NEAR(cfl_a.regions.origin.z() + 7 * h, layer, 1e-12) << "no layer of voxels ends where the test needs one";

  TriangleMesh mesh_b;
  mesh_b.vertices = {{0, 0, 0}, {0.05, 0, 0}, {0, 0.05, 0}};
  mesh_b.triangles = {{0, 1, 2}};
  const MeshModel model_b = makeMeshModel(mesh_b);
  // Inside one column of voxels; the second query's step (0.04 voxel) certifies with a margin of 0.16 voxel.
  auto at = [&](double z) { return Eigen::Isometry3d(Eigen::Translation3d(0.05, 0.05, z)); };
  const double heights[] = {layer - below - 0.04 * h, layer - below, layer - below + 0.07 * h};
  DistanceCache cache;
  const Eigen::Isometry3d X_WA = Eigen::Isometry3d::Identity();
  for (double z : heights) {
    const DistanceResult truth = bruteForceDistance(model_a, X_WA, model_b, at(z));
    const DistanceResult r = computeDistance(cfl_a, X_WA, model_b, at(z), cache);
    EXPECT_NEAR(r.distance, truth.distance, 1e-12) << "B at height " << z;
  }
  // The last query is the one this test is about: it must have come from the certificate.
  EXPECT_EQ(cache.reused, 1) << "the certificate did not answer the last query; the test no longer checks it";
  EXPECT_NEAR(bruteForceDistance(model_a, X_WA, model_b, at(heights[2])).distance, upper - heights[2], 1e-12)
      << "the upper sheet should be the closest after B rises";
}

}  // namespace
}  // namespace cfl
