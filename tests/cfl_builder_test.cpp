// Properties of buildCflModel checked against the independent point-mesh reference of test_meshes:
// conservative lists (the paper's central claim), sound lower bounds and corner distances, a well-formed
// tree whose point location and box walk agree with a plain walk of its nodes, adaptive refinement where it
// pays, consistent statistics, thread-independent results and a well-behaved progress callback.

#include "cfl/cfl_model.h"
#include "cfl/cfl_query.h"
#include "cfl/mesh_model.h"
#include "cfl/query_kernels.h"
#include "../src/detail/builder_test_hooks.h"
#include "support/test_meshes.h"

#include <Eigen/Geometry>
#include <gtest/gtest.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <thread>
#include <tuple>
#include <utility>
#include <vector>

namespace cfl {
namespace {

using test::NamedMesh;

// Small enough for brute force at thousands of points, and covering closed, open, soup and ugly input.
std::vector<NamedMesh> testMeshes() {
  return {
      {"torus", test::makeTorus(1.0, 0.35, 16, 8)},
      {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6)},
      {"soup", test::makeTriangleSoup(200, 17)},
      {"hemisphere", test::makeHemisphere(1.0, 6, 16)},
      {"wavy_sheet", test::makeWavySheet(1.5, 0.4, 12)},
      {"messy", test::makeMessyMesh()},
      {"self_intersecting", test::makeSelfIntersectingMesh()},
  };
}

BuildOptions options(int resolution, bool topology_culling = false) {
  BuildOptions result;
  result.resolution = resolution;
  result.topology_culling = topology_culling;
  return result;
}

// Every leaf of the tree with its box, found by walking the nodes from the root cells: independent of
// RegionTree::locate and forEachLeafInBox, which the tests check against it.
struct LeafBox {
  std::uint32_t leaf;
  Eigen::Vector3d min;
  double size;
  int depth;
};
std::vector<LeafBox> allLeaves(const RegionTree& tree) {
  std::vector<LeafBox> leaves;
  std::vector<std::tuple<std::uint32_t, Eigen::Vector3d, int>> pending;
  for (int k = 0; k < tree.root_dims[2]; ++k) {
    for (int j = 0; j < tree.root_dims[1]; ++j) {
      for (int i = 0; i < tree.root_dims[0]; ++i) {
        pending.emplace_back(std::uint32_t(i + tree.root_dims[0] * (j + tree.root_dims[1] * k)),
                             tree.origin + tree.root_size * Eigen::Vector3d(i, j, k), 0);
      }
    }
  }
  while (!pending.empty()) {
    const auto [node, min, depth] = pending.back();
    pending.pop_back();
    const double size = tree.root_size / double(1 << depth);
    const std::uint32_t value = tree.nodes.at(node);
    if (value & RegionTree::kLeafBit) {
      leaves.push_back({value & ~RegionTree::kLeafBit, min, size, depth});
      continue;
    }
    for (int c = 0; c < 8; ++c) {
      pending.emplace_back(value + c, min + 0.5 * size * Eigen::Vector3d(c & 1, (c >> 1) & 1, c >> 2), depth + 1);
    }
  }
  return leaves;
}

// Every leaf whose closed box contains p (1 inside a leaf, up to 8 at a corner).
std::vector<LeafBox> leavesContaining(const std::vector<LeafBox>& leaves, const Eigen::Vector3d& p) {
  std::vector<LeafBox> result;
  for (const LeafBox& leaf : leaves) {
    const Eigen::Vector3d hi = leaf.min + Eigen::Vector3d::Constant(leaf.size);
    if ((leaf.min.array() <= p.array()).all() && (p.array() <= hi.array()).all()) result.push_back(leaf);
  }
  return result;
}

double finestCell(const RegionTree& tree) { return tree.cellSize(tree.max_depth); }

// Test points in the regions: uniform, concentrated near the surface at several scales (on it, within a
// finest cell, a few cells away), and exactly on leaf faces, edges and corners.
std::vector<Eigen::Vector3d> samplePoints(const TriangleMesh& mesh, const RegionTree& tree,
                                          const std::vector<LeafBox>& leaves, int uniform_count, int surface_count,
                                          int boundary_count, test::Rng& rng) {
  std::vector<Eigen::Vector3d> points;
  const Aabb bounds = tree.bounds();
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::normal_distribution<double> gaussian;
  auto inGrid = [&](const Eigen::Vector3d& p) {
    return (bounds.min.array() <= p.array()).all() && (p.array() <= bounds.max.array()).all();
  };
  for (int n = 0; n < uniform_count; ++n) {
    points.push_back(bounds.min + bounds.size().cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng))));
  }
  std::uniform_int_distribution<int> triangle(0, static_cast<int>(mesh.triangles.size()) - 1);
  const double scales[] = {0.0, 0.01, 0.3, 2.0};
  for (int n = 0; n < surface_count; ++n) {
    const double sigma = scales[n % 4] * finestCell(tree) * (n % 8 < 4 ? 1 : 8);
    const Eigen::Vector3d p = test::randomPointOnTriangle(mesh, triangle(rng), rng) +
                              sigma * Eigen::Vector3d(gaussian(rng), gaussian(rng), gaussian(rng));
    if (inGrid(p)) points.push_back(p);
  }
  std::uniform_int_distribution<std::size_t> pick(0, leaves.size() - 1);
  for (int n = 0; n < boundary_count; ++n) {
    const LeafBox& leaf = leaves[pick(rng)];
    Eigen::Vector3d p = leaf.min + leaf.size * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
    // Snap 1 (face), 2 (edge) or 3 (corner) coordinates onto the leaf's planes.
    const int snapped = 1 + n % 3;
    for (int axis = 0; axis < snapped; ++axis) {
      const int a = (axis + n) % 3;
      p[a] = leaf.min[a] + (unit(rng) < 0.5 ? 0 : leaf.size);
    }
    if (inGrid(p)) points.push_back(p);
  }
  return points;
}

double listDistance(const CflModel& model, const TriangleMesh& mesh, std::uint32_t leaf, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (std::uint32_t n = 0; n < model.regions.leafListLength(leaf); ++n) {
    const auto& tri = mesh.triangles[model.regions.leafListTriangle(leaf, n)];
    best = std::min(best, test::referencePointTriangleSquaredDistance(p, mesh.vertices[tri[0]], mesh.vertices[tri[1]],
                                                                       mesh.vertices[tri[2]]));
  }
  return std::sqrt(best);
}

// The list of every leaf containing each sample holds a triangle at the sample's true distance, the leaf's
// lower bound and entry bounds do not exceed the distances they bound, and locate() finds a leaf that holds
// the point. Returns the number of failures (already reported).
int checkConservative(const CflModel& model, const TriangleMesh& mesh, int samples, std::uint64_t seed,
                      const std::string& label) {
  test::Rng rng(seed);
  const double diagonal = boundingBox(mesh).diagonal();
  const RegionTree& tree = model.regions;
  const std::vector<LeafBox> leaves = allLeaves(tree);
  if (static_cast<std::int64_t>(leaves.size()) != tree.leafCount()) {
    ADD_FAILURE() << label << ": " << leaves.size() << " leaves reachable, " << tree.leafCount() << " stored";
    return 1;
  }
  const std::vector<Eigen::Vector3d> points = samplePoints(mesh, tree, leaves, samples, samples, samples / 2, rng);
  int failures = 0;
  for (const Eigen::Vector3d& p : points) {
    const double truth = test::referencePointMeshDistance(mesh, p);
    const std::vector<LeafBox> containing = leavesContaining(leaves, p);
    if (containing.empty() && ++failures <= 5) ADD_FAILURE() << label << ": no leaf contains (" << p.transpose() << ")";
    // On a face, rounding may put p in either neighbour: the located leaf must hold p within that rounding.
    const RegionCell located = tree.locate(p);
    const double rounding = 1e-12 * (tree.root_size + tree.origin.cwiseAbs().maxCoeff());
    const Eigen::Vector3d located_hi = located.min_corner + Eigen::Vector3d::Constant(located.size);
    if (!((located.min_corner.array() - rounding <= p.array()).all() && (p.array() <= located_hi.array() + rounding).all()) &&
        ++failures <= 5) {
      ADD_FAILURE() << label << ": locate(" << p.transpose() << ") gave leaf " << located.leaf << ", which does not hold it";
    }
    for (const LeafBox& leaf : containing) {
      const std::uint32_t v = leaf.leaf;
      if (!(tree.leaf_lower_bound[v] <= truth * (1 + 1e-12) + 1e-15 * diagonal)) {
        if (++failures <= 5) {
          ADD_FAILURE() << label << ": leaf " << v << " lower bound " << tree.leaf_lower_bound[v]
                        << " exceeds the distance " << truth << " of its point (" << p.transpose() << ")";
        }
      }
      if (!tree.hasList(v)) continue;  // the query takes A's Bvh there
      // Both sides use the same reference, so a list holding a closest triangle gives exactly `truth`.
      const double from_list = listDistance(model, mesh, v, p);
      if (!(from_list <= truth * (1 + 1e-12) + 1e-15 * diagonal)) {
        if (++failures <= 5) {
          ADD_FAILURE() << label << ": leaf " << v << " (depth " << leaf.depth << ") list misses the closest triangle of ("
                        << p.transpose() << "): list distance " << from_list << ", true distance " << truth;
        }
      }
      // Every entry's bound is a lower bound on its triangle's distance from every point of the leaf: the
      // query stops scanning a list at the first bound that reaches its best distance.
      const std::uint8_t* bounds = tree.listBoundsBegin(v);
      for (std::uint32_t n = 0; n < tree.leafListLength(v); ++n, ++bounds) {
        const std::int32_t t = tree.leafListTriangle(v, n);
        const auto& tri = mesh.triangles[t];
        const double distance = std::sqrt(test::referencePointTriangleSquaredDistance(
            p, mesh.vertices[tri[0]], mesh.vertices[tri[1]], mesh.vertices[tri[2]]));
        const double bound = *bounds * tree.entryBoundUnit(leaf.depth);
        if (!(bound <= distance * (1 + 1e-12) + 1e-15 * diagonal) && ++failures <= 5) {
          ADD_FAILURE() << label << ": leaf " << v << " entry bound " << bound << " of triangle " << t
                        << " exceeds its distance " << distance << " from (" << p.transpose() << ")";
        }
      }
    }
  }
  return failures;
}

// Lists whose ids span less than 65536 keep 16-bit ids from a base; wider ones keep the high bits apart.
TEST(RegionTreeLists, NarrowAndWideListsDecodeToTheirIds) {
  RegionTree tree;
  const std::vector<std::int32_t> narrow = {70000, 70001, 135535, 100000};
  const std::vector<std::int32_t> wide = {5, 70000, 1 << 20, 2147483647, 65535};
  const std::vector<std::uint8_t> bounds = {0, 1, 2, 3, 4};
  EXPECT_EQ(tree.appendList(narrow.data(), bounds.data(), std::uint32_t(narrow.size())), 0u);
  EXPECT_EQ(tree.appendList(wide.data(), bounds.data(), std::uint32_t(wide.size())), 1u);
  EXPECT_EQ(tree.appendList(narrow.data() + 1, bounds.data(), 1), 2u);
  ASSERT_EQ(tree.listCount(), 3u);
  EXPECT_EQ(tree.listBase(0), 70000);
  EXPECT_LT(tree.listBase(1), 0);
  EXPECT_EQ(tree.listBase(2), 70001);
  EXPECT_EQ(tree.list_entry_ids.size(), 10u + 2 * 3);
  EXPECT_EQ(tree.list_high_ids.size(), wide.size());
  EXPECT_EQ(tree.list_offsets, (std::vector<std::uint32_t>{0, 4, 9, 10}));
  for (std::uint32_t list = 0; list < 3; ++list) {
    const std::int32_t* expected = list == 0 ? narrow.data() : list == 1 ? wide.data() : narrow.data() + 1;
    ASSERT_EQ(tree.listLength(list), list == 0 ? 4u : list == 1 ? 5u : 1u);
    for (std::uint32_t n = 0; n < tree.listLength(list); ++n) EXPECT_EQ(tree.listTriangle(list, n), expected[n]);
    std::vector<std::int32_t> visited;
    tree.forEachListTriangle(list, tree.listLength(list), [&](std::ptrdiff_t n, std::int32_t id) {
      EXPECT_EQ(n, std::ptrdiff_t(visited.size()));
      visited.push_back(id);
    });
    EXPECT_EQ(visited, std::vector<std::int32_t>(expected, expected + tree.listLength(list)));
  }
  std::vector<std::int32_t> all = narrow;
  all.insert(all.end(), wide.begin(), wide.end());
  all.push_back(narrow[1]);
  EXPECT_EQ(tree.listTriangles(), all);
  EXPECT_EQ(tree.list_entry_bounds.size(), 10u);
}

TEST(CflBuilder, ListsAreConservativeAtSeveralResolutions) {
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {0, 6, 10, 16, 24}) {
      const std::string label = named.name + " resolution " + std::to_string(resolution);
      const CflModel model = buildCflModel(named.mesh, options(resolution));
      EXPECT_EQ(checkConservative(model, named.mesh, 1500, 1000 + resolution, label), 0) << label;
    }
  }
}

// Paper section 3.6: culling must never drop the closest triangle of a point, in uniform and adaptive
// regions alike.
TEST(CflBuilder, TopologyCullingKeepsListsConservative) {
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {0, 6, 10, 16, 24}) {
      const std::string label = named.name + " resolution " + std::to_string(resolution) + " with topology culling";
      const CflModel model = buildCflModel(named.mesh, options(resolution, true));
      EXPECT_TRUE(model.topology_culling) << label;
      EXPECT_EQ(checkConservative(model, named.mesh, 1500, 2000 + resolution, label), 0) << label;
    }
  }
}

// The option exists to shorten lists (paper section 3.6, Table 1): on closed, consistently oriented meshes,
// where every edge has its two planes, it must drop triangles from some cells. Without this test the
// conservativeness test above would also pass for an option that does nothing.
TEST(CflBuilder, TopologyCullingShortensListsOnClosedOrientedMeshes) {
  for (const NamedMesh& named : {testMeshes()[0], testMeshes()[1]}) {
    const CflModel plain = buildCflModel(named.mesh, options(16));
    const CflModel culled = buildCflModel(named.mesh, options(16, true));
    EXPECT_LT(culled.statistics.average_list_length, plain.statistics.average_list_length) << named.name;
  }
}

TEST(CflBuilder, ListsAreConservativeOnTheBunnyAndWithOtherPaddings) {
  const TriangleMesh bunny = test::loadBunny();
  EXPECT_EQ(checkConservative(buildCflModel(bunny, options(12)), bunny, 600, 31, "bunny resolution 12"), 0);
  EXPECT_EQ(checkConservative(buildCflModel(bunny, options(0, true)), bunny, 600, 32,
                              "bunny adaptive with topology culling"),
            0);
  const TriangleMesh torus = test::makeTorus(1.0, 0.35, 16, 8);
  for (double padding : {1.0, 3.5}) {
    for (int resolution : {0, 10}) {
      BuildOptions padded = options(resolution);
      padded.padding = padding;
      const CflModel model = buildCflModel(torus, padded);
      EXPECT_EQ(checkConservative(model, torus, 1000, 41,
                                  "torus padding " + std::to_string(padding) + " resolution " + std::to_string(resolution)),
                0);
    }
  }
}

// A thin plate whose triangles are wider than it is thick: the leaves near it straddle the plate or see
// both faces, and the rules that stop refinement there (list lengths against cell sizes in edges) are the
// ones that must still leave every list complete, with and without topology culling.
TEST(CflBuilder, ListsAreConservativeOnAThinPlate) {
  const TriangleMesh plate = test::makeThinPlate(1.0, 0.05, 12);
  for (bool culling : {false, true}) {
    const std::string label = std::string("thin plate") + (culling ? " with topology culling" : "");
    const CflModel model = buildCflModel(plate, options(0, culling));
    EXPECT_GT(model.regions.max_depth, 0) << label;
    EXPECT_EQ(checkConservative(model, plate, 2000, culling ? 52 : 51, label), 0) << label;
  }
}

// A small turbine blade like the suite's: an elliptic airfoil swept along a span, tapering, and capped. It
// is thinner than its triangles are wide, and its curved faces keep topology culling from removing the
// opposite face, so the cells near it list both faces and their lists stay long where the cells stop
// splitting: the leaves where the split rule and the caps on list lengths decide.
TriangleMesh makeAirfoilBlade(int around = 32, int span = 24, double half_chord = 1.0, double half_thickness = 0.04,
                              double length = 8.0) {
  const double pi = std::acos(-1.0);
  TriangleMesh mesh;
  for (int i = 0; i < span; ++i) {
    const double s = double(i) / (span - 1);
    for (int k = 0; k < around; ++k) {
      const double t = 2 * pi * k / around;
      mesh.vertices.push_back(Eigen::Vector3d(0.2 * s + half_chord * (1 - 0.2 * s) * std::sin(t), length * s,
                                              half_thickness * (1 - 0.4 * s) * std::cos(t)));
    }
  }
  auto ring = [&](int i, int k) { return i * around + k % around; };
  for (int i = 0; i + 1 < span; ++i) {
    for (int k = 0; k < around; ++k) {  // outward: the tangent along the ring, then the span
      mesh.triangles.push_back({ring(i, k), ring(i, k + 1), ring(i + 1, k + 1)});
      mesh.triangles.push_back({ring(i, k), ring(i + 1, k + 1), ring(i + 1, k)});
    }
  }
  const int root = static_cast<int>(mesh.vertices.size());
  mesh.vertices.push_back(Eigen::Vector3d(0, 0, 0));
  mesh.vertices.push_back(Eigen::Vector3d(0.2, length, 0));
  for (int k = 0; k < around; ++k) {
    mesh.triangles.push_back({root, ring(0, k + 1), ring(0, k)});
    mesh.triangles.push_back({root + 1, ring(span - 1, k), ring(span - 1, k + 1)});
  }
  return mesh;
}

TEST(CflBuilder, ListsAreConservativeOnAThinAirfoilBlade) {
  const TriangleMesh blade = makeAirfoilBlade();
  for (bool culling : {false, true}) {
    const std::string label = std::string("airfoil blade") + (culling ? " with topology culling" : "");
    const CflModel model = buildCflModel(blade, options(0, culling));
    // The thin part is what the test is for: some leaves meeting the blade must list the middles of both of
    // its faces (side triangles 2 (i around + k) and the next, ring position k at angle 2 pi k / around from
    // the top).
    int both_faces = 0;
    for (const LeafBox& leaf : allLeaves(model.regions)) {
      if (!model.regions.hasList(leaf.leaf) || model.regions.leaf_lower_bound[leaf.leaf] > 0) continue;
      bool top = false, bottom = false;
      for (std::uint32_t n = 0; n < model.regions.leafListLength(leaf.leaf); ++n) {
        const int t = model.regions.leafListTriangle(leaf.leaf, n);
        if (t >= 2 * 32 * 23) continue;  // a cap
        const int k = (t / 2) % 32;
        top |= k <= 2 || k >= 30;
        bottom |= k >= 14 && k <= 18;
      }
      both_faces += top && bottom;
    }
    EXPECT_GT(both_faces, 0) << label;
    EXPECT_EQ(checkConservative(model, blade, 2500, culling ? 62 : 61, label), 0) << label;
  }
}

// A cell may decide to split before its list is complete (when the split rule holds whatever the rest of the
// list): a shortcut for speed, which must not change the model. Built with and without it, every cell, every
// list, every entry bound and every lower bound must agree; the count proves the shortcut was taken.
TEST(CflBuilder, EarlySplitDecisionsChangeNothing) {
  std::vector<NamedMesh> meshes = testMeshes();
  meshes.push_back({"bunny", test::loadBunny()});
  meshes.push_back({"thin plate", test::makeThinPlate(1.0, 0.05, 12)});
  meshes.push_back({"airfoil blade", makeAirfoilBlade()});
  std::int64_t decisions = 0;
  for (const NamedMesh& named : meshes) {
    for (bool culling : {false, true}) {
      const std::string label = named.name + (culling ? " with topology culling" : "");
      const std::int64_t before = detail::earlySplitDecisionCount();
      const CflModel early = buildCflModel(named.mesh, options(0, culling));
      decisions += detail::earlySplitDecisionCount() - before;
      detail::setEarlySplitDecisions(false);
      const CflModel complete = buildCflModel(named.mesh, options(0, culling));
      detail::setEarlySplitDecisions(true);
      const RegionTree& a = early.regions;
      const RegionTree& b = complete.regions;
      EXPECT_EQ(a.nodes, b.nodes) << label;
      EXPECT_EQ(a.leaf_list, b.leaf_list) << label;
      EXPECT_EQ(a.list_offsets, b.list_offsets) << label;
      EXPECT_EQ(a.list_entry_ids, b.list_entry_ids) << label;
      EXPECT_EQ(a.list_high_ids, b.list_high_ids) << label;
      EXPECT_EQ(a.list_entry_bounds, b.list_entry_bounds) << label;
      EXPECT_EQ(a.leaf_corner_distance, b.leaf_corner_distance) << label;
      // A leaf that stores no list may keep its center's bound, which starts from its parent's: a parent that
      // split early passes down its center's bound instead of its listed one. Either is valid (see
      // LeavesWithoutAListKeepAValidLowerBound); the listed leaves' bounds come from their lists alone.
      ASSERT_EQ(a.leaf_lower_bound.size(), b.leaf_lower_bound.size()) << label;
      int differing = 0;
      for (std::size_t leaf = 0; leaf < a.leaf_list.size(); ++leaf) {
        differing += a.hasList(std::uint32_t(leaf)) && a.leaf_lower_bound[leaf] != b.leaf_lower_bound[leaf];
      }
      EXPECT_EQ(differing, 0) << label;
    }
  }
  EXPECT_GT(decisions, 0);
}

// A far leaf may decide it stores no list before its list is complete, and then keeps a lower bound from
// its center's distance instead of its listed triangles': every such leaf, not just the sampled ones, must
// keep it below the distance of each of its corners and of its center.
TEST(CflBuilder, LeavesWithoutAListKeepAValidLowerBound) {
  const TriangleMesh bunny = test::loadBunny();
  const CflModel model = buildCflModel(bunny, options(0, true));
  const RegionTree& tree = model.regions;
  const double diagonal = boundingBox(bunny).diagonal();
  int without = 0, failures = 0;
  for (const LeafBox& leaf : allLeaves(tree)) {
    if (tree.hasList(leaf.leaf)) continue;
    ++without;
    for (int n = 0; n < 9; ++n) {
      const Eigen::Vector3d p = n == 8 ? Eigen::Vector3d(leaf.min.array() + 0.5 * leaf.size)
                                       : Eigen::Vector3d(leaf.min + leaf.size * Eigen::Vector3d(n & 1, (n >> 1) & 1, n >> 2));
      const double truth = test::referencePointMeshDistance(bunny, p);
      if (!(tree.leaf_lower_bound[leaf.leaf] <= truth * (1 + 1e-12) + 1e-15 * diagonal) && ++failures <= 5) {
        ADD_FAILURE() << "leaf " << leaf.leaf << " lower bound " << tree.leaf_lower_bound[leaf.leaf]
                      << " exceeds the distance " << truth << " of (" << p.transpose() << ")";
      }
    }
  }
  EXPECT_GT(without, 0);
  EXPECT_EQ(failures, 0);
}

// The 16-bit corner distances are lower bounds (rounded down) whose next unit is an upper bound, whatever
// the distance and the unit, and saturate instead of wrapping.
TEST(CflBuilder, CornerDistanceEncodingBracketsTheDistance) {
  test::Rng rng(11);
  std::uniform_real_distribution<double> mantissa(0.5, 1.0);
  std::uniform_int_distribution<int> exponent(-30, 10);
  for (int n = 0; n < 200000; ++n) {
    const double unit = std::ldexp(1.0, exponent(rng));
    const double distance = n % 4 == 0 ? unit * std::floor(mantissa(rng) * 70000)  // exact multiples too
                                       : std::ldexp(mantissa(rng), exponent(rng) + 17);
    const std::uint16_t stored = RegionTree::encodeCornerDistance(distance, unit);
    const double lower = RegionTree::cornerDistanceLower(stored, unit);
    const double upper = RegionTree::cornerDistanceUpper(stored, unit);
    ASSERT_LE(lower, distance) << distance << " in units of " << unit;
    ASSERT_GE(upper, distance) << distance << " in units of " << unit;
    if (stored != RegionTree::kCornerDistanceSaturated) {
      ASSERT_LT(distance, lower + unit) << distance << " in units of " << unit;
    } else {
      ASSERT_GE(distance, 65535 * unit);
    }
  }
  EXPECT_EQ(RegionTree::encodeCornerDistance(std::numeric_limits<double>::infinity(), 1.0),
            RegionTree::kCornerDistanceSaturated);
  EXPECT_EQ(RegionTree::encodeCornerDistance(std::numeric_limits<double>::quiet_NaN(), 1.0), 0);
  EXPECT_EQ(RegionTree::encodeCornerDistance(-1.0, 1.0), 0);
}

TEST(CflBuilder, CornerDistancesMatchTheReferenceAndNeverExceedIt) {
  test::Rng rng(5);
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {0, 6, 16}) {
      const CflModel model = buildCflModel(named.mesh, options(resolution));
      const RegionTree& tree = model.regions;
      const std::vector<LeafBox> leaves = allLeaves(tree);
      ASSERT_EQ(static_cast<std::int64_t>(tree.leaf_corner_distance.size()), tree.leafCount());
      const double diagonal = boundingBox(named.mesh).diagonal();
      int failures = 0;
      std::uniform_int_distribution<std::size_t> pick(0, leaves.size() - 1);
      for (int n = 0; n < 1500; ++n) {
        const LeafBox& leaf = leaves[pick(rng)];
        const int c = n % 8;
        const Eigen::Vector3d corner = leaf.min + leaf.size * Eigen::Vector3d(c & 1, (c >> 1) & 1, c >> 2);
        const double truth = test::referencePointMeshDistance(named.mesh, corner);
        const std::uint16_t stored = tree.leaf_corner_distance[leaf.leaf][c];
        const double unit = tree.cornerDistanceUnit(leaf.size);
        const double lower = RegionTree::cornerDistanceLower(stored, unit);
        const double upper = RegionTree::cornerDistanceUpper(stored, unit);
        // The stored units bracket the truth: the lower bound never above it (the reference carries a few
        // ulps of rounding, and a corner on the surface a distance of pure noise, hence the 1e-15 terms),
        // the upper bound never below it beyond the build's float rounding, which the point query's 1e-6
        // covers. The unit is fine enough for bounds (at most 1/1024 of an edge) and no corner of
        // these meshes saturates.
        const double noise = 1e-15 * diagonal;
        const bool ok = lower <= truth * (1 + 1e-15) + noise && upper >= truth * (1 - 3e-7) - noise &&
                        upper - lower <= leaf.size / 1024 && stored != RegionTree::kCornerDistanceSaturated;
        if (!ok && ++failures <= 5) {
          ADD_FAILURE() << named.name << " resolution " << resolution << " leaf " << leaf.leaf << " corner " << c
                        << ": stored " << stored << " units of " << unit << " (" << lower << " to " << upper
                        << "), reference " << truth;
        }
      }
      EXPECT_EQ(failures, 0) << named.name;
    }
  }
}

TEST(CflBuilder, StorageIsWellFormedAndStatisticsMatchIt) {
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {0, 6, 13}) {
      SCOPED_TRACE(named.name + " resolution " + std::to_string(resolution));
      const CflModel model = buildCflModel(named.mesh, options(resolution));
      const RegionTree& tree = model.regions;
      const std::vector<LeafBox> leaves = allLeaves(tree);
      const std::int64_t leaf_count = tree.leafCount();
      const std::int64_t triangles = static_cast<std::int64_t>(named.mesh.triangles.size());
      ASSERT_EQ(static_cast<std::int64_t>(leaves.size()), leaf_count);
      ASSERT_EQ(static_cast<std::int64_t>(tree.leaf_lower_bound.size()), leaf_count);
      std::set<std::uint32_t> reached;
      int deepest = 0;
      for (const LeafBox& leaf : leaves) {
        EXPECT_TRUE(reached.insert(leaf.leaf).second) << "leaf " << leaf.leaf << " reached twice";
        deepest = std::max(deepest, leaf.depth);
      }
      EXPECT_EQ(deepest, tree.max_depth);
      if (resolution > 0) EXPECT_EQ(tree.max_depth, 0) << "a uniform grid is never refined";
      ASSERT_FALSE(tree.list_offsets.empty());
      EXPECT_EQ(tree.list_offsets.front(), 0u);
      EXPECT_EQ(tree.list_offsets.back(), tree.list_entry_bounds.size());
      // Each list's base in two slots, then an id per entry.
      EXPECT_EQ(tree.list_entry_ids.size(), tree.list_entry_bounds.size() + 2 * tree.listCount());
      // Below 65536 triangles every list is narrow: 16-bit ids from a base.
      if (triangles < 65536) {
        EXPECT_TRUE(tree.list_high_ids.empty());
        for (std::uint32_t list = 0; list < tree.listCount(); ++list) EXPECT_GE(tree.listBase(list), 0);
      }
      EXPECT_TRUE(std::is_sorted(tree.list_offsets.begin(), tree.list_offsets.end()));
      // The model keeps the mesh it was given: triangle ids in the lists refer to the caller's triangles.
      EXPECT_EQ(model.geometry.mesh.triangles, named.mesh.triangles);

      std::int64_t total = 0, longest = 0;
      std::set<std::pair<int, std::vector<std::pair<int, std::int32_t>>>> distinct;
      std::vector<std::int64_t> per_depth(tree.max_depth + 1, 0);
      std::int64_t without_list = 0;
      for (const LeafBox& leaf : leaves) {
        const std::uint32_t v = leaf.leaf;
        ++per_depth[leaf.depth];
        if (!tree.hasList(v)) {
          EXPECT_EQ(resolution, 0) << "a uniform grid keeps every list (the paper's mode scans them)";
          ++without_list;
          continue;
        }
        ASSERT_LT(tree.leaf_list[v] + 1, tree.list_offsets.size());
        std::vector<std::pair<int, std::int32_t>> list;  // (entry bound, triangle id)
        const std::uint8_t* bounds = tree.listBoundsBegin(v);
        for (std::uint32_t n = 0; n < tree.leafListLength(v); ++n) list.push_back({*bounds++, tree.leafListTriangle(v, n)});
        EXPECT_FALSE(list.empty()) << "leaf " << v << " has an empty list";
        EXPECT_TRUE(std::adjacent_find(list.begin(), list.end(), [](auto a, auto b) { return a >= b; }) == list.end())
            << "leaf " << v << " list is not strictly increasing in (entry bound, id)";
        std::set<std::int32_t> ids;
        for (const auto& [bound, t] : list) {
          EXPECT_GE(t, 0);
          EXPECT_LT(t, triangles);
          EXPECT_TRUE(ids.insert(t).second) << "leaf " << v << " lists triangle " << t << " twice";
        }
        total += static_cast<std::int64_t>(list.size());
        longest = std::max<std::int64_t>(longest, static_cast<std::int64_t>(list.size()));
        distinct.insert({leaf.depth, std::move(list)});
      }
      const BuildStatistics& stats = model.statistics;
      EXPECT_EQ(stats.voxel_count, leaf_count);
      EXPECT_EQ(stats.leaves_without_list, without_list);
      EXPECT_EQ(stats.leaves_per_depth, per_depth);
      EXPECT_NEAR(stats.average_list_length, static_cast<double>(total) / (leaf_count - without_list),
                  1e-9 * stats.average_list_length);
      EXPECT_EQ(stats.longest_list, longest);
      // Lists are shared only between leaves of one depth (their bounds' unit is the leaf's edge / 32).
      EXPECT_EQ(stats.distinct_lists, static_cast<std::int64_t>(distinct.size()));
      EXPECT_EQ(static_cast<std::int64_t>(tree.list_offsets.size()) - 1, stats.distinct_lists);
      // Every array the model holds, the regions' and the mesh's, by capacity: what a user budgets for.
      const auto bytes = [](const auto& array) {
        return static_cast<std::int64_t>(array.capacity() * sizeof(array[0]));
      };
      const MeshModel& geometry = model.geometry;
      const std::int64_t arrays =
          bytes(tree.nodes) + bytes(tree.leaf_list) + bytes(tree.leaf_lower_bound) + bytes(tree.leaf_corner_distance) +
          bytes(tree.list_offsets) + bytes(tree.list_entry_ids) + bytes(tree.list_high_ids) +
          bytes(tree.list_entry_bounds) +
          bytes(geometry.mesh.vertices) + bytes(geometry.mesh.triangles) + bytes(geometry.corners.in_leaf_order) +
          bytes(geometry.corners.leaf_position) + bytes(geometry.spheres) + bytes(geometry.planes) +
          bytes(geometry.leaf_spheres) + bytes(geometry.leaf_planes) + bytes(geometry.spines) + bytes(geometry.bvh.nodes) +
          bytes(geometry.compact_nodes) + bytes(geometry.node_spine_radii) +
          bytes(geometry.bvh.triangle_ids) + bytes(model.sign.welded_vertex) + bytes(model.sign.neighbors) +
          bytes(model.sign.vertex_normals);
      EXPECT_EQ(stats.memory_bytes, arrays);
      EXPECT_GE(stats.build_seconds, 0.0);
    }
  }
}

// The regions reach (padding - 1) / 2 of the longest extent past the mesh on every side, however flat or
// long the mesh: a part rotated next to a flat one must still find itself inside.
TEST(CflBuilder, RegionsCoverTheSamePaddingOnEveryAxis) {
  TriangleMesh blade = test::makeWavySheet(1.5, 0.05, 12);
  for (Eigen::Vector3d& v : blade.vertices) v = Eigen::Vector3d(v.x() * 10, v.y() * 0.5, v.z() * 0.2);
  std::vector<NamedMesh> meshes = testMeshes();
  meshes.push_back({"flat long blade", blade});
  for (const NamedMesh& named : meshes) {
    for (double padding : {1.0, 2.0, 3.0}) {
      for (int resolution : {0, 11}) {
        SCOPED_TRACE(named.name + " padding " + std::to_string(padding) + " resolution " + std::to_string(resolution));
        BuildOptions build = options(resolution);
        build.padding = padding;
        const CflModel model = buildCflModel(named.mesh, build);
        const Aabb mesh_box = boundingBox(named.mesh);
        const double margin = 0.5 * (padding - 1) * mesh_box.size().maxCoeff();
        const Aabb box = model.regions.bounds();
        const double slack = 1e-12 * mesh_box.diagonal() * padding;
        EXPECT_TRUE(((box.min.array() - slack) <= (mesh_box.min.array() - margin)).all());
        EXPECT_TRUE(((mesh_box.max.array() + margin) <= (box.max.array() + slack)).all());
        for (int d : model.regions.root_dims) EXPECT_GE(d, 1);
        if (resolution > 0) {
          EXPECT_EQ(*std::max_element(model.regions.root_dims.begin(), model.regions.root_dims.end()), resolution);
        }
        EXPECT_EQ(model.padding, padding);
      }
    }
  }
}

// Adaptive regions are fine near the surface and coarse far from it: leaves that touch the mesh are smaller
// than the leaves far away, and there are far fewer leaves than a uniform grid of the finest edge would have.
TEST(CflBuilder, AdaptiveRegionsAreFineNearTheSurfaceAndCoarseFarAway) {
  for (const NamedMesh& named : {testMeshes()[1], NamedMesh{"bunny", test::loadBunny()}}) {
    SCOPED_TRACE(named.name);
    const CflModel model = buildCflModel(named.mesh, options(0));
    const RegionTree& tree = model.regions;
    EXPECT_GT(tree.max_depth, 0);
    const std::vector<LeafBox> leaves = allLeaves(tree);
    double near_size = 0, far_size = 0;
    int near_count = 0, far_count = 0;
    const double diagonal = boundingBox(named.mesh).diagonal();
    for (const LeafBox& leaf : leaves) {
      const double lower = tree.leaf_lower_bound[leaf.leaf];
      if (lower == 0) near_size += leaf.size, ++near_count;
      if (lower > 0.5 * diagonal) far_size += leaf.size, ++far_count;
    }
    ASSERT_GT(near_count, 0);
    ASSERT_GT(far_count, 0);
    EXPECT_LT(near_size / near_count, far_size / far_count);
    const Eigen::Vector3d cells = tree.bounds().size() / tree.cellSize(tree.max_depth);
    EXPECT_LT(double(tree.leafCount()), 0.25 * cells.prod());
  }
}

// Each leaf's list is short where a split could shorten it: lists longer than the refinement target
// remain only in leaves that reached a stopping rule, so the mean stays near the target.
TEST(CflBuilder, AdaptiveListsAreShorterThanACoarseUniformGrids) {
  const TriangleMesh bunny = test::loadBunny();
  const CflModel adaptive = buildCflModel(bunny, options(0));
  const CflModel coarse = buildCflModel(bunny, options(16));
  EXPECT_LT(adaptive.statistics.average_list_length, coarse.statistics.average_list_length);
}

// RegionTree::forEachLeafInBox visits exactly the leaves whose closed box meets the query box.
TEST(CflBuilder, LeavesInABoxAreExactlyThoseThatMeetIt) {
  test::Rng rng(9);
  for (const NamedMesh& named : {testMeshes()[1], testMeshes()[3]}) {
    const CflModel model = buildCflModel(named.mesh, options(0));
    const RegionTree& tree = model.regions;
    const std::vector<LeafBox> leaves = allLeaves(tree);
    const Aabb box = tree.bounds();
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    for (int n = 0; n < 200; ++n) {
      const Eigen::Vector3d a = box.min + box.size().cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
      const Eigen::Vector3d extent = box.size() * (n % 2 ? 0.02 : 0.2) * unit(rng);
      const Eigen::Vector3d lo = a, hi = (a + extent).cwiseMin(box.max);
      std::set<std::uint32_t> visited, expected;
      tree.forEachLeafInBox(lo, hi, [&](const RegionCell& cell) {
        EXPECT_TRUE(visited.insert(cell.leaf).second) << "leaf " << cell.leaf << " visited twice";
        return true;
      });
      for (const LeafBox& leaf : leaves) {
        const Eigen::Vector3d leaf_hi = leaf.min + Eigen::Vector3d::Constant(leaf.size);
        if ((leaf.min.array() <= hi.array()).all() && (lo.array() <= leaf_hi.array()).all()) expected.insert(leaf.leaf);
      }
      // The traversal may add leaves that touch the box within rounding; it must miss none.
      EXPECT_TRUE(std::includes(visited.begin(), visited.end(), expected.begin(), expected.end())) << named.name;
      EXPECT_LE(visited.size(), expected.size() + expected.size() / 4 + 8) << named.name;
    }
  }
}

// Paper Table 1: finer voxels hold fewer candidate triangles.
TEST(CflBuilder, AverageListLengthDecreasesWithResolutionOnTheBunny) {
  const TriangleMesh bunny = test::loadBunny();
  double previous = std::numeric_limits<double>::infinity();
  for (int resolution : {10, 15, 20, 30}) {
    const CflModel model = buildCflModel(bunny, options(resolution));
    const double average = model.statistics.average_list_length;
    EXPECT_LT(average, previous) << "resolution " << resolution;
    EXPECT_GE(average, 1.0);
    previous = average;
  }
}

// Every cell, list, entry bound, lower bound and corner distance of a and b agree.
void expectSameRegions(const RegionTree& a, const RegionTree& b, const std::string& label) {
  EXPECT_EQ(a.origin, b.origin) << label;
  EXPECT_EQ(a.root_size, b.root_size) << label;
  EXPECT_EQ(a.max_depth, b.max_depth) << label;
  EXPECT_EQ(a.corner_distance_unit, b.corner_distance_unit) << label;
  EXPECT_EQ(a.nodes, b.nodes) << label;
  EXPECT_EQ(a.leaf_list, b.leaf_list) << label;
  EXPECT_EQ(a.leaf_lower_bound, b.leaf_lower_bound) << label;
  EXPECT_EQ(a.leaf_corner_distance, b.leaf_corner_distance) << label;
  EXPECT_EQ(a.list_entry_ids, b.list_entry_ids) << label;
  EXPECT_EQ(a.list_high_ids, b.list_high_ids) << label;
  EXPECT_EQ(a.list_entry_bounds, b.list_entry_bounds) << label;
  EXPECT_EQ(a.list_offsets, b.list_offsets) << label;
}

TEST(CflBuilder, ResultDoesNotDependOnThreadCount) {
  for (const NamedMesh& named : {testMeshes()[1], testMeshes()[5], testMeshes()[6]}) {
    for (int resolution : {0, 12}) {
      BuildOptions one = options(resolution), two = options(resolution);
      one.threads = 1;
      two.threads = 2;
      expectSameRegions(buildCflModel(named.mesh, one).regions, buildCflModel(named.mesh, two).regions, named.name);
    }
  }
}

// The builder runs its point-triangle distances through the active query kernels, four triangles at a time
// in the x86-64-v3 build; the nearest triangles, ties included, and so the model must be the generic
// build's bit for bit.
TEST(CflBuilder, ResultDoesNotDependOnTheQueryKernels) {
  if (!queryKernelsAvailable(QueryKernels::kX86_64_V3)) GTEST_SKIP() << "no x86-64-v3 kernels on this build or CPU";
  const QueryKernels active = activeQueryKernels();
  std::vector<NamedMesh> meshes = testMeshes();
  meshes.push_back({"bunny", test::loadBunny()});
  meshes.push_back({"thin plate", test::makeThinPlate(1.0, 0.05, 12)});
  for (const NamedMesh& named : meshes) {
    for (bool culling : {false, true}) {
      const std::string label = named.name + (culling ? " with topology culling" : "");
      setQueryKernels(QueryKernels::kGeneric);
      const CflModel generic = buildCflModel(named.mesh, options(0, culling));
      setQueryKernels(QueryKernels::kX86_64_V3);
      const CflModel v3 = buildCflModel(named.mesh, options(0, culling));
      expectSameRegions(generic.regions, v3.regions, label);
    }
  }
  setQueryKernels(active);
}

// A memory limit stops refinement: the lists get longer, never wrong.
TEST(CflBuilder, AMemoryLimitCoarsensButKeepsListsConservative) {
  const TriangleMesh knot = test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6);
  BuildOptions limited = options(0);
  limited.memory_limit = 300000;  // above the root cells' floor, below what refinement would take
  const CflModel model = buildCflModel(knot, limited);
  EXPECT_TRUE(model.statistics.coarsened);
  EXPECT_FALSE(buildCflModel(knot, options(0)).statistics.coarsened);
  EXPECT_EQ(checkConservative(model, knot, 500, 51, "knot under a memory limit"), 0);
}

// A closed pipe `length` long of radius `radius` along z, `sides` around and `rings` rings, caps fanned from
// their centers: a long thin part like the suite's pipe, whose cells a few edges away list a whole stretch
// of its circumference.
TriangleMesh makeLongPipe(double length, double radius, int sides, int rings) {
  const double pi = std::acos(-1.0);
  TriangleMesh mesh;
  for (int i = 0; i < rings; ++i) {
    for (int k = 0; k < sides; ++k) {
      const double t = 2 * pi * k / sides;
      mesh.vertices.push_back(Eigen::Vector3d(radius * std::sin(t), radius * std::cos(t), length * i / (rings - 1)));
    }
  }
  auto ring = [&](int i, int k) { return i * sides + k % sides; };
  for (int i = 0; i + 1 < rings; ++i) {
    for (int k = 0; k < sides; ++k) {
      mesh.triangles.push_back({ring(i, k), ring(i, k + 1), ring(i + 1, k + 1)});
      mesh.triangles.push_back({ring(i, k), ring(i + 1, k + 1), ring(i + 1, k)});
    }
  }
  const int bottom = static_cast<int>(mesh.vertices.size());
  mesh.vertices.push_back(Eigen::Vector3d(0, 0, 0));
  mesh.vertices.push_back(Eigen::Vector3d(0, 0, length));
  for (int k = 0; k < sides; ++k) {
    mesh.triangles.push_back({bottom, ring(0, k + 1), ring(0, k)});
    mesh.triangles.push_back({bottom + 1, ring(rings - 1, k), ring(rings - 1, k + 1)});
  }
  return mesh;
}

// Around a long thin pipe the cells a few of their edges away list much of its circumference: unchecked,
// their lists took the model to about three times an FCL OBBRSS hierarchy (556 bytes per triangle). The
// regions' budget keeps it within twice that, by letting the leaves of a cell share one list (farthest
// first) before dropping any, and leaves the lists next to the surface alone. The lists stay conservative,
// their bounds valid for every leaf that shares them, and distances exact.
TEST(CflBuilder, ALongThinPipeStaysWithinTheRegionsBudgetAndExact) {
  const TriangleMesh pipe = makeLongPipe(300.0, 0.5, 16, 400);
  const std::int64_t triangles = std::int64_t(pipe.triangles.size());
  ASSERT_EQ(triangles, 12800);
  const CflModel model = buildCflModel(pipe, options(0, true));
  const BuildStatistics& s = model.statistics;
  EXPECT_LE(double(s.memory_bytes) / double(triangles), 2 * 556.0);
  const RegionTree& tree = model.regions;
  std::int64_t regions_bytes = std::int64_t(tree.nodes.capacity() * sizeof(std::uint32_t) +
                                            tree.leaf_list.capacity() * sizeof(std::uint32_t) +
                                            tree.leaf_lower_bound.capacity() * sizeof(float) +
                                            tree.leaf_corner_distance.capacity() * 16 +
                                            tree.list_offsets.capacity() * sizeof(std::uint32_t) +
                                            tree.list_entry_ids.capacity() * 2 + tree.list_high_ids.capacity() * 2 +
                                            tree.list_entry_bounds.capacity());
  EXPECT_LE(regions_bytes, (std::int64_t(1) << 20) + 688 * triangles);
  // Shared lists, and every leaf that touches the mesh keeps a list of its own.
  std::vector<int> users(tree.listCount(), 0);
  for (std::int64_t leaf = 0; leaf < tree.leafCount(); ++leaf) {
    if (tree.hasList(std::uint32_t(leaf))) ++users[tree.leaf_list[leaf]];
  }
  EXPECT_LT(s.distinct_lists, tree.leafCount() - s.leaves_without_list);
  for (std::int64_t leaf = 0; leaf < tree.leafCount(); ++leaf) {
    if (tree.leaf_lower_bound[leaf] > 0) continue;
    ASSERT_TRUE(tree.hasList(std::uint32_t(leaf))) << "leaf " << leaf << " touches the pipe and has no list";
    EXPECT_EQ(users[tree.leaf_list[leaf]], 1) << "leaf " << leaf << " touches the pipe and shares its list";
  }
  EXPECT_EQ(checkConservative(model, pipe, 1500, 71, "long pipe"), 0);
  // Which lists merge or go does not depend on the workers.
  BuildOptions one_thread = options(0, true);
  one_thread.threads = 1;
  const CflModel serial = buildCflModel(pipe, one_thread);
  EXPECT_EQ(serial.regions.leaf_list, tree.leaf_list);
  EXPECT_EQ(serial.regions.list_offsets, tree.list_offsets);
  EXPECT_EQ(serial.regions.list_entry_ids, tree.list_entry_ids);
  EXPECT_EQ(serial.regions.list_entry_bounds, tree.list_entry_bounds);

  // Against brute force: a small torus at several distances from the pipe, at random places along it and
  // random orientations.
  const TriangleMesh torus = test::makeTorus(1.0, 0.3, 12, 6);
  const MeshModel other = makeMeshModel(torus);
  test::Rng rng(72);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  const double diagonal = boundingBox(pipe).diagonal();
  for (double gap : {0.0, 0.3, 1.5, 4.0, 6.0, 9.0, 20.0, 60.0}) {
    for (int repeat = 0; repeat < 2; ++repeat) {
      const double angle = 2 * std::acos(-1.0) * unit(rng);
      Eigen::Isometry3d X_WB = Eigen::Isometry3d::Identity();
      const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng) - 0.5, unit(rng) - 0.5, unit(rng) - 0.5).normalized();
      X_WB.linear() = Eigen::AngleAxisd(2 * std::acos(-1.0) * unit(rng), axis).toRotationMatrix();
      // The torus reaches 1.3 from its center: its center at 1.8 + gap from the axis is about gap away.
      X_WB.translation() = Eigen::Vector3d((1.8 + gap) * std::cos(angle), (1.8 + gap) * std::sin(angle),
                                           300 * unit(rng));
      const DistanceResult truth = bruteForceDistance(model.geometry, Eigen::Isometry3d::Identity(), other, X_WB);
      const DistanceResult r = computeDistance(model, Eigen::Isometry3d::Identity(), other, X_WB);
      EXPECT_NEAR(r.distance, truth.distance, 1e-9 * diagonal) << "gap " << gap << ", repeat " << repeat;
    }
  }
}

TEST(CflBuilder, ProgressIsReportedOnTheCallingThreadNondecreasingAndEndsAtOne) {
  std::vector<double> fractions;
  bool other_thread = false;
  const std::thread::id caller = std::this_thread::get_id();
  BuildOptions build = options(16);
  build.threads = 2;
  build.progress = [&](double fraction) {
    fractions.push_back(fraction);
    if (std::this_thread::get_id() != caller) other_thread = true;
  };
  buildCflModel(test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6), build);
  ASSERT_FALSE(fractions.empty());
  EXPECT_FALSE(other_thread);
  EXPECT_TRUE(std::is_sorted(fractions.begin(), fractions.end()));
  EXPECT_GE(fractions.front(), 0.0);
  EXPECT_EQ(fractions.back(), 1.0);
  for (double f : fractions) {
    EXPECT_GE(f, 0.0);
    EXPECT_LE(f, 1.0);
  }
}

TEST(CflBuilder, PointLikeAndFlatMeshesGetUsableRegions) {
  // A single point-triangle and a flat square: the grid must still have positive voxel size and every
  // list must be conservative.
  TriangleMesh point;
  point.vertices = {Eigen::Vector3d(0.5, -1, 2)};
  point.triangles = {{0, 0, 0}};
  TriangleMesh flat;
  flat.vertices = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(0, 1, 0)};
  flat.triangles = {{0, 1, 2}, {0, 2, 3}};
  for (const TriangleMesh* mesh : {&point, &flat}) {
    for (int resolution : {0, 6}) {
      const CflModel model = buildCflModel(*mesh, options(resolution));
      EXPECT_GT(model.regions.root_size, 0.0);
      EXPECT_TRUE(std::isfinite(model.regions.root_size));
      EXPECT_EQ(checkConservative(model, *mesh, 300, 77, "degenerate extent"), 0);
    }
  }
}

// Edges shared by many triangles: a book of fins hinged on one edge of a closed torus, and some of the
// torus's faces repeated a dozen times. Culling must stay conservative where such edges stop culling and
// where the fins still cull, and the neighbours it keeps must stay linear in the triangles: every triangle
// of an edge lists all the others, which on many copies of one face is quadratic.
TriangleMesh makeCrowdedEdgeMesh(int fins, int copies) {
  const double kPi = std::acos(-1.0);
  TriangleMesh mesh = test::makeTorus(1.0, 0.35, 16, 8);
  const std::array<int, 3> hinge_face = mesh.triangles[0];
  const Eigen::Vector3d a = mesh.vertices[hinge_face[0]], b = mesh.vertices[hinge_face[1]];
  const Eigen::Vector3d axis = (b - a).normalized();
  const Eigen::Vector3d across = axis.unitOrthogonal();
  for (int f = 0; f < fins; ++f) {
    const Eigen::Vector3d out = Eigen::AngleAxisd(2 * kPi * (f + 0.5) / fins, axis) * across;
    const int tip = int(mesh.vertices.size());
    mesh.vertices.push_back(0.5 * (a + b) + 0.3 * out);
    mesh.triangles.push_back({hinge_face[0], hinge_face[1], tip});
  }
  const std::size_t faces = mesh.triangles.size();
  for (std::size_t t = 0; t < faces; t += 37) {
    for (int k = 0; k < copies; ++k) mesh.triangles.push_back(mesh.triangles[t]);
  }
  return mesh;
}

TEST(CflBuilder, EdgesOfManyTrianglesKeepListsConservative) {
  for (const auto& [fins, copies] : {std::pair{3, 1}, std::pair{6, 2}, std::pair{40, 12}}) {
    const TriangleMesh mesh = makeCrowdedEdgeMesh(fins, copies);
    for (int resolution : {0, 10}) {
      const std::string label = std::to_string(fins) + " fins, " + std::to_string(copies) + " copies, resolution " +
                                std::to_string(resolution);
      const CflModel model = buildCflModel(mesh, options(resolution, true));
      EXPECT_EQ(checkConservative(model, mesh, 1500, 4100 + resolution, label), 0) << label;
    }
  }
}

TEST(CflBuilder, TopologyNeighboursStayLinearOnManyCopiesOfOneFace) {
  const TriangleMesh torus = test::makeTorus(1.0, 0.35, 16, 8);
  const std::int64_t manifold = detail::topologyNeighbourCount(makeMeshModel(torus));
  // A closed manifold mesh: each edge of each triangle has exactly one neighbour.
  EXPECT_EQ(manifold, 3 * std::int64_t(torus.triangles.size()));
  for (int copies : {20, 2000}) {
    TriangleMesh mesh = torus;
    for (int k = 0; k < copies; ++k) mesh.triangles.push_back(torus.triangles[5]);
    const std::int64_t count = detail::topologyNeighbourCount(makeMeshModel(mesh));
    // The copied face's three edges are crowded and keep no neighbours, for its copies, itself and the three
    // torus faces across them; every other edge keeps its one.
    EXPECT_EQ(count, manifold - 6) << copies << " copies";
  }
}

// Far from the origin for its size, the float node boxes round coarser than a ten-thousandth of the mesh, and
// the builder's candidate walk prunes by the nodes' spheres as well: the lists, bounds and point location must
// stay as conservative as near the origin.
TEST(CflBuilder, ListsAreConservativeFarFromTheOrigin) {
  for (const NamedMesh& named : {testMeshes()[1], testMeshes()[2]}) {
    TriangleMesh moved = named.mesh;
    const double size = boundingBox(moved).diagonal();
    for (Eigen::Vector3d& v : moved.vertices) v += Eigen::Vector3d(3e4, -2e4, 1e4) * size;
    for (int resolution : {0, 10}) {
      const std::string label = named.name + " far away, resolution " + std::to_string(resolution);
      const CflModel model = buildCflModel(moved, options(resolution, true));
      EXPECT_EQ(checkConservative(model, moved, 1500, 5100 + resolution, label), 0) << label;
    }
  }
}

}  // namespace
}  // namespace cfl
