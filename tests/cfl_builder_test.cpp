// Properties of buildCflModel checked against the independent point-mesh reference of test_meshes:
// conservative lists (the paper's central claim), sound lower bounds and corner distances, consistent
// statistics, thread-independent results and a well-behaved progress callback.

#include "cfl/cfl_model.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <set>
#include <string>
#include <thread>
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

// Every voxel whose closed box contains p (1 voxel inside, up to 8 at a grid corner).
std::vector<std::int64_t> voxelsContaining(const VoxelGrid& grid, const Eigen::Vector3d& p) {
  std::vector<std::int64_t> result;
  int base[3];
  for (int axis = 0; axis < 3; ++axis) base[axis] = static_cast<int>(std::floor((p[axis] - grid.origin[axis]) / grid.voxel_size));
  for (int k = base[2] - 1; k <= base[2] + 1; ++k) {
    for (int j = base[1] - 1; j <= base[1] + 1; ++j) {
      for (int i = base[0] - 1; i <= base[0] + 1; ++i) {
        if (i < 0 || j < 0 || k < 0 || i >= grid.dims[0] || j >= grid.dims[1] || k >= grid.dims[2]) continue;
        // The header's definition, origin + voxel_size * [i, i + 1], so that neighbours share their face
        // exactly (voxelBox's min + voxel_size may differ from the next corner by an ulp).
        const Eigen::Vector3d lo = grid.cornerPosition(i, j, k), hi = grid.cornerPosition(i + 1, j + 1, k + 1);
        if ((lo.array() <= p.array()).all() && (p.array() <= hi.array()).all()) {
          result.push_back(grid.voxelIndex(i, j, k));
        }
      }
    }
  }
  return result;
}

// Test points in the grid: uniform, concentrated near the surface at several scales (on it, within a
// voxel, a few voxels away), and exactly on voxel faces, edges and corners.
std::vector<Eigen::Vector3d> samplePoints(const TriangleMesh& mesh, const VoxelGrid& grid, int uniform_count,
                                          int surface_count, int boundary_count, test::Rng& rng) {
  std::vector<Eigen::Vector3d> points;
  const Aabb bounds = grid.bounds();
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
    const double sigma = scales[n % 4] * grid.voxel_size;
    const Eigen::Vector3d p = test::randomPointOnTriangle(mesh, triangle(rng), rng) +
                              sigma * Eigen::Vector3d(gaussian(rng), gaussian(rng), gaussian(rng));
    if (inGrid(p)) points.push_back(p);
  }
  for (int n = 0; n < boundary_count; ++n) {
    const int ijk[3] = {std::uniform_int_distribution<int>(0, grid.dims[0])(rng),
                        std::uniform_int_distribution<int>(0, grid.dims[1])(rng),
                        std::uniform_int_distribution<int>(0, grid.dims[2])(rng)};
    const Eigen::Vector3d corner = grid.cornerPosition(ijk[0], ijk[1], ijk[2]);
    Eigen::Vector3d p = bounds.min + bounds.size().cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
    // Snap 1 (face), 2 (edge) or 3 (corner) coordinates onto grid planes.
    const int snapped = 1 + n % 3;
    for (int axis = 0; axis < snapped; ++axis) p[(axis + n) % 3] = corner[(axis + n) % 3];
    points.push_back(p);
  }
  return points;
}

double listDistance(const CflModel& model, const TriangleMesh& mesh, std::int64_t v, const Eigen::Vector3d& p) {
  double best = std::numeric_limits<double>::infinity();
  for (const std::int32_t* t = model.listBegin(v); t != model.listEnd(v); ++t) {
    const auto& tri = mesh.triangles[*t];
    best = std::min(best, test::referencePointTriangleSquaredDistance(p, mesh.vertices[tri[0]], mesh.vertices[tri[1]],
                                                                       mesh.vertices[tri[2]]));
  }
  return std::sqrt(best);
}

// The list of every voxel containing each sample holds a triangle at the sample's true distance, and the
// voxel's lower bound does not exceed that distance. Returns the number of failures (already reported).
int checkConservative(const CflModel& model, const TriangleMesh& mesh, int samples, std::uint64_t seed,
                      const std::string& label) {
  test::Rng rng(seed);
  const double diagonal = boundingBox(mesh).diagonal();
  const std::vector<Eigen::Vector3d> points = samplePoints(mesh, model.grid, samples, samples, samples / 2, rng);
  int failures = 0;
  for (const Eigen::Vector3d& p : points) {
    const double truth = test::referencePointMeshDistance(mesh, p);
    const std::vector<std::int64_t> voxels = voxelsContaining(model.grid, p);
    if (voxels.empty() && ++failures <= 5) ADD_FAILURE() << label << ": no voxel contains (" << p.transpose() << ")";
    for (std::int64_t v : voxels) {
      // Both sides use the same reference, so a list holding a closest triangle gives exactly `truth`.
      const double from_list = listDistance(model, mesh, v, p);
      if (!(from_list <= truth * (1 + 1e-12) + 1e-15 * diagonal)) {
        if (++failures <= 5) {
          ADD_FAILURE() << label << ": voxel " << v << " list misses the closest triangle of point ("
                        << p.transpose() << "): list distance " << from_list << ", true distance " << truth;
        }
      }
      // Every entry's bound is a lower bound on its triangle's distance from every point of the voxel:
      // the query stops scanning a list at the first bound that reaches its best distance.
      const std::uint8_t* bounds = model.listBoundsBegin(v);
      for (const std::int32_t* t = model.listBegin(v); t != model.listEnd(v); ++t, ++bounds) {
        const auto& tri = mesh.triangles[*t];
        const double distance = std::sqrt(test::referencePointTriangleSquaredDistance(
            p, mesh.vertices[tri[0]], mesh.vertices[tri[1]], mesh.vertices[tri[2]]));
        const double bound = *bounds * model.entryBoundUnit();
        if (!(bound <= distance * (1 + 1e-12) + 1e-15 * diagonal) && ++failures <= 5) {
          ADD_FAILURE() << label << ": voxel " << v << " entry bound " << bound << " of triangle " << *t
                        << " exceeds its distance " << distance << " from (" << p.transpose() << ")";
        }
      }
      if (!(model.voxel_lower_bound[v] <= truth * (1 + 1e-12) + 1e-15 * diagonal)) {
        if (++failures <= 5) {
          ADD_FAILURE() << label << ": voxel " << v << " lower bound " << model.voxel_lower_bound[v]
                        << " exceeds the distance " << truth << " of its point (" << p.transpose() << ")";
        }
      }
    }
  }
  return failures;
}

TEST(CflBuilder, ListsAreConservativeAtSeveralResolutions) {
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {6, 10, 16, 24}) {
      const std::string label = named.name + " resolution " + std::to_string(resolution);
      const CflModel model = buildCflModel(named.mesh, options(resolution));
      EXPECT_EQ(checkConservative(model, named.mesh, 1500, 1000 + resolution, label), 0) << label;
    }
  }
}

// Paper section 3.6. The option is off by default; this test is what decides whether it may be turned on
// for a given kind of mesh: it fails if culling ever drops the closest triangle of a point.
TEST(CflBuilder, TopologyCullingKeepsListsConservative) {
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {6, 10, 16, 24}) {
      const std::string label = named.name + " resolution " + std::to_string(resolution) + " with topology culling";
      const CflModel model = buildCflModel(named.mesh, options(resolution, true));
      EXPECT_TRUE(model.topology_culling) << label;
      EXPECT_EQ(checkConservative(model, named.mesh, 1500, 2000 + resolution, label), 0) << label;
    }
  }
}

// The option exists to shorten lists (paper section 3.6, Table 1): on closed, consistently oriented meshes,
// where every edge has its two planes, it must drop triangles from some voxels. Without this test the
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
  EXPECT_EQ(checkConservative(buildCflModel(bunny, options(12, true)), bunny, 600, 32,
                              "bunny resolution 12 with topology culling"),
            0);
  const TriangleMesh torus = test::makeTorus(1.0, 0.35, 16, 8);
  for (double padding : {1.0, 3.5}) {
    BuildOptions padded = options(10);
    padded.padding = padding;
    const CflModel model = buildCflModel(torus, padded);
    EXPECT_EQ(checkConservative(model, torus, 1000, 41, "torus padding " + std::to_string(padding)), 0);
  }
}

TEST(CflBuilder, CornerDistancesMatchTheReferenceAndNeverExceedIt) {
  test::Rng rng(5);
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {6, 16}) {
      const CflModel model = buildCflModel(named.mesh, options(resolution));
      const VoxelGrid& grid = model.grid;
      const double diagonal = boundingBox(named.mesh).diagonal();
      ASSERT_EQ(static_cast<std::int64_t>(model.corner_distance.size()), grid.cornerCount());
      int failures = 0;
      for (int n = 0; n < 1500; ++n) {
        const int i = std::uniform_int_distribution<int>(0, grid.dims[0])(rng);
        const int j = std::uniform_int_distribution<int>(0, grid.dims[1])(rng);
        const int k = std::uniform_int_distribution<int>(0, grid.dims[2])(rng);
        const double truth = test::referencePointMeshDistance(named.mesh, grid.cornerPosition(i, j, k));
        const double stored = model.corner_distance[grid.cornerIndex(i, j, k)];
        // "Never above": the reference itself carries a few ulps of rounding, hence the 1e-15. A corner on
        // the surface has a distance of pure rounding noise (~1e-17), hence the absolute 1e-15 * diagonal.
        const double noise = 1e-15 * diagonal;
        const bool ok = std::abs(stored - truth) <= 1e-12 * truth + noise && stored <= truth * (1 + 1e-15) + noise;
        if (!ok && ++failures <= 5) {
          ADD_FAILURE() << named.name << " resolution " << resolution << " corner (" << i << ", " << j << ", " << k
                        << "): stored " << stored << ", reference " << truth << ", difference " << stored - truth;
        }
      }
      EXPECT_EQ(failures, 0) << named.name;
    }
  }
}

TEST(CflBuilder, StorageIsWellFormedAndStatisticsMatchIt) {
  for (const NamedMesh& named : testMeshes()) {
    for (int resolution : {6, 13}) {
      SCOPED_TRACE(named.name + " resolution " + std::to_string(resolution));
      const CflModel model = buildCflModel(named.mesh, options(resolution));
      const VoxelGrid& grid = model.grid;
      const std::int64_t voxels = grid.voxelCount();
      const std::int64_t triangles = static_cast<std::int64_t>(named.mesh.triangles.size());
      ASSERT_EQ(static_cast<std::int64_t>(model.voxel_list.size()), voxels);
      ASSERT_EQ(static_cast<std::int64_t>(model.voxel_lower_bound.size()), voxels);
      ASSERT_FALSE(model.list_offsets.empty());
      EXPECT_EQ(model.list_offsets.front(), 0u);
      EXPECT_EQ(model.list_offsets.back(), model.list_triangles.size());
      EXPECT_TRUE(std::is_sorted(model.list_offsets.begin(), model.list_offsets.end()));
      // The model keeps the mesh it was given: triangle ids in the lists refer to the caller's triangles.
      EXPECT_EQ(model.geometry.mesh.triangles, named.mesh.triangles);

      std::int64_t total = 0, longest = 0;
      ASSERT_EQ(model.list_entry_bounds.size(), model.list_triangles.size());
      std::set<std::vector<std::pair<int, std::int32_t>>> distinct;
      for (std::int64_t v = 0; v < voxels; ++v) {
        ASSERT_LT(model.voxel_list[v] + 1, model.list_offsets.size());
        std::vector<std::pair<int, std::int32_t>> list;  // (entry bound, triangle id)
        const std::uint8_t* bounds = model.listBoundsBegin(v);
        for (const std::int32_t* t = model.listBegin(v); t != model.listEnd(v); ++t) list.push_back({*bounds++, *t});
        EXPECT_FALSE(list.empty()) << "voxel " << v << " has an empty list";
        EXPECT_TRUE(std::adjacent_find(list.begin(), list.end(), [](auto a, auto b) { return a >= b; }) == list.end())
            << "voxel " << v << " list is not strictly increasing in (entry bound, id)";
        std::set<std::int32_t> ids;
        for (const auto& [bound, t] : list) {
          EXPECT_GE(t, 0);
          EXPECT_LT(t, triangles);
          EXPECT_TRUE(ids.insert(t).second) << "voxel " << v << " lists triangle " << t << " twice";
        }
        total += static_cast<std::int64_t>(list.size());
        longest = std::max<std::int64_t>(longest, static_cast<std::int64_t>(list.size()));
        distinct.insert(std::move(list));
      }
      const BuildStatistics& stats = model.statistics;
      EXPECT_EQ(stats.resolution, resolution);
      EXPECT_EQ(stats.voxel_count, voxels);
      EXPECT_NEAR(stats.average_list_length, static_cast<double>(total) / voxels, 1e-9 * stats.average_list_length);
      EXPECT_EQ(stats.longest_list, longest);
      EXPECT_EQ(stats.distinct_lists, static_cast<std::int64_t>(distinct.size()));
      EXPECT_GE(static_cast<std::int64_t>(model.list_offsets.size()) - 1, stats.distinct_lists);
      // Every array the model holds, the voxels' and the mesh's: what a user budgets for.
      const auto bytes = [](const auto& array) {
        return static_cast<std::int64_t>(array.size() * sizeof(array[0]));
      };
      const MeshModel& geometry = model.geometry;
      const std::int64_t arrays =
          bytes(model.voxel_list) + bytes(model.list_offsets) + bytes(model.list_triangles) +
          bytes(model.list_entry_bounds) + bytes(model.voxel_lower_bound) + bytes(model.corner_distance) +
          bytes(geometry.mesh.vertices) + bytes(geometry.mesh.triangles) + bytes(geometry.corners) +
          bytes(geometry.spheres) + bytes(geometry.planes) + bytes(geometry.leaf_corners) +
          bytes(geometry.leaf_spheres) + bytes(geometry.leaf_planes) + bytes(geometry.bvh.nodes) +
          bytes(geometry.bvh.triangle_ids);
      EXPECT_EQ(stats.memory_bytes, arrays);
      EXPECT_GE(stats.build_seconds, 0.0);
    }
  }
}

TEST(CflBuilder, GridCoversThePaddedBoxWithTheRequestedResolution) {
  for (const NamedMesh& named : testMeshes()) {
    for (double padding : {1.0, 2.0, 3.0}) {
      SCOPED_TRACE(named.name + " padding " + std::to_string(padding));
      BuildOptions build = options(11);
      build.padding = padding;
      const CflModel model = buildCflModel(named.mesh, build);
      const Aabb mesh_box = boundingBox(named.mesh);
      const Eigen::Vector3d half = 0.5 * padding * mesh_box.size();
      const Aabb grid_box = model.grid.bounds();
      const double slack = 1e-12 * mesh_box.diagonal() * padding;
      EXPECT_TRUE(((grid_box.min.array() - slack) <= (mesh_box.center() - half).array()).all());
      EXPECT_TRUE(((mesh_box.center() + half).array() <= (grid_box.max.array() + slack)).all());
      EXPECT_EQ(*std::max_element(model.grid.dims.begin(), model.grid.dims.end()), 11);
      for (int d : model.grid.dims) EXPECT_GE(d, 1);
      EXPECT_NEAR(model.grid.voxel_size * 11, padding * mesh_box.size().maxCoeff(),
                  1e-9 * padding * mesh_box.size().maxCoeff());
      EXPECT_EQ(model.padding, padding);
    }
  }
}

TEST(CflBuilder, AutomaticResolutionIsUsedWhenZeroAndStaysInRange) {
  for (const NamedMesh& named : testMeshes()) {
    for (double padding : {1.0, 2.0, 3.0, 10.0}) {
      const int automatic = automaticResolution(named.mesh, padding);
      EXPECT_GE(automatic, 8) << named.name;
      EXPECT_LE(automatic, padding <= 2 ? 64 : 96) << named.name << " padding " << padding;
    }
  }
  const TriangleMesh torus = test::makeTorus(1.0, 0.35, 16, 8);
  const CflModel model = buildCflModel(torus, options(0));
  EXPECT_EQ(model.statistics.resolution, automaticResolution(torus, BuildOptions{}.padding));
  EXPECT_EQ(*std::max_element(model.grid.dims.begin(), model.grid.dims.end()), model.statistics.resolution);
}

// A larger padding reaches farther out without coarsening the voxels near the mesh (unless capped): the
// short-range speed must not depend on it.
TEST(CflBuilder, AutomaticVoxelSizeDoesNotDependOnThePaddingBelowTheCap) {
  const TriangleMesh torus = test::makeTorus(1.0, 0.35, 16, 8);
  const double longest = boundingBox(torus).size().maxCoeff();
  const int at_two = automaticResolution(torus, 2.0), at_three = automaticResolution(torus, 3.0);
  ASSERT_LT(at_three, 96);
  const double voxel_two = 2.0 * longest / at_two, voxel_three = 3.0 * longest / at_three;
  // Each resolution is rounded to an integer: the voxel sizes agree to within that rounding.
  EXPECT_NEAR(voxel_three, voxel_two, voxel_two * (1.0 / at_two + 1.0 / at_three));
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

TEST(CflBuilder, ResultDoesNotDependOnThreadCount) {
  for (const NamedMesh& named : {testMeshes()[1], testMeshes()[5], testMeshes()[6]}) {
    BuildOptions one = options(12), two = options(12);
    one.threads = 1;
    two.threads = 2;
    const CflModel a = buildCflModel(named.mesh, one);
    const CflModel b = buildCflModel(named.mesh, two);
    ASSERT_EQ(a.grid.voxelCount(), b.grid.voxelCount());
    for (std::int64_t v = 0; v < a.grid.voxelCount(); ++v) {
      EXPECT_TRUE(std::equal(a.listBegin(v), a.listEnd(v), b.listBegin(v), b.listEnd(v))) << named.name << " voxel " << v;
    }
    EXPECT_EQ(a.voxel_lower_bound, b.voxel_lower_bound) << named.name;
    EXPECT_EQ(a.corner_distance, b.corner_distance) << named.name;
    EXPECT_EQ(a.list_triangles, b.list_triangles) << named.name;
    EXPECT_EQ(a.list_offsets, b.list_offsets) << named.name;
    EXPECT_EQ(a.voxel_list, b.voxel_list) << named.name;
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

TEST(CflBuilder, PointLikeAndFlatMeshesGetAUsableGrid) {
  // A single point-triangle and a flat square: the grid must still have positive voxel size and every
  // list must be conservative.
  TriangleMesh point;
  point.vertices = {Eigen::Vector3d(0.5, -1, 2)};
  point.triangles = {{0, 0, 0}};
  TriangleMesh flat;
  flat.vertices = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(0, 1, 0)};
  flat.triangles = {{0, 1, 2}, {0, 2, 3}};
  for (const TriangleMesh* mesh : {&point, &flat}) {
    const CflModel model = buildCflModel(*mesh, options(6));
    EXPECT_GT(model.grid.voxel_size, 0.0);
    EXPECT_TRUE(std::isfinite(model.grid.voxel_size));
    EXPECT_EQ(checkConservative(model, *mesh, 300, 77, "degenerate extent"), 0);
  }
}

}  // namespace
}  // namespace cfl
