// Structural invariants of buildBvh on several meshes and leaf sizes: the tree is a partition of the
// triangles, every node's box and sphere bound everything below it, and its subtree range lists exactly that.

#include "cfl/bvh.h"
#include "../src/detail/bvh_build.h"
#include "../src/detail/nearest_triangle.h"
#include "support/test_meshes.h"

#include <tbb/task_arena.h>

#include <gtest/gtest.h>

#include <algorithm>
#include <cstring>
#include <random>
#include <sstream>
#include <string>
#include <vector>

namespace cfl {
namespace {

using test::NamedMesh;

// Many tiny triangles among a few huge ones, scattered: the split rule must still bound and partition them.
TriangleMesh unevenSoup() {
  TriangleMesh mesh = test::makeTriangleSoup(600, 7, 1.0, 0.02);
  const TriangleMesh huge = test::makeTriangleSoup(12, 8, 1.0, 3.0);
  const int offset = static_cast<int>(mesh.vertices.size());
  mesh.vertices.insert(mesh.vertices.end(), huge.vertices.begin(), huge.vertices.end());
  for (auto tri : huge.triangles) mesh.triangles.push_back({tri[0] + offset, tri[1] + offset, tri[2] + offset});
  return mesh;
}

std::string scientific(double x) {
  std::ostringstream out;
  out << x;
  return out.str();
}

std::vector<NamedMesh> testMeshes() {
  return {
      {"torus", test::makeTorus()},
      {"knot", test::makeTorusKnot()},
      {"soup", test::makeTriangleSoup(500, 42)},
      {"hemisphere", test::makeHemisphere()},
      {"messy", test::makeMessyMesh()},
      {"self_intersecting", test::makeSelfIntersectingMesh()},
      {"bunny", test::loadBunny()},
      {"refined_slab", test::makeLocallyRefinedSlab(24)},
      {"uneven_soup", unevenSoup()},
  };
}

// Spheres are computed in floating point; a relative slack of 1e-12 of the radius absorbs that rounding,
// while any real bounding error is many orders larger.
bool sphereContains(const BvhNode& node, const Eigen::Vector3d& p) {
  return (p - node.center).norm() <= node.radius * (1 + 1e-12) + 1e-300;
}

bool boxContains(const Aabb& box, const Eigen::Vector3d& p) {
  return (box.min.array() <= p.array()).all() && (p.array() <= box.max.array()).all();
}

bool boxContains(const Aabb& outer, const Aabb& inner) {
  return (outer.min.array() <= inner.min.array()).all() && (inner.max.array() <= outer.max.array()).all();
}

// Checks every invariant of `bvh` over `mesh`.
void checkInvariants(const TriangleMesh& mesh, const Bvh& bvh, int max_leaf_size, const std::string& label) {
  SCOPED_TRACE(label);
  const int n = static_cast<int>(mesh.triangles.size());
  ASSERT_FALSE(bvh.nodes.empty());
  ASSERT_EQ(static_cast<int>(bvh.triangle_ids.size()), n);

  // triangle_ids is a permutation of [0, n).
  std::vector<int> seen_in_ids(n, 0);
  for (int id : bvh.triangle_ids) {
    ASSERT_GE(id, 0);
    ASSERT_LT(id, n);
    ++seen_in_ids[id];
  }
  for (int t = 0; t < n; ++t) EXPECT_EQ(seen_in_ids[t], 1) << "triangle " << t << " in triangle_ids";

  // Walk from the root: every node is reached exactly once, and the leaves cover every slot of
  // triangle_ids exactly once.
  const int node_count = static_cast<int>(bvh.nodes.size());
  std::vector<int> node_visits(node_count, 0);
  std::vector<int> slot_visits(n, 0);
  std::vector<int> stack{0};
  while (!stack.empty()) {
    const int index = stack.back();
    stack.pop_back();
    ASSERT_GE(index, 0);
    ASSERT_LT(index, node_count);
    ASSERT_EQ(++node_visits[index], 1) << "node " << index << " reached twice";
    const BvhNode& node = bvh.nodes[index];
    ASSERT_FALSE(node.box().empty()) << "node " << index;
    if (node.isLeaf()) {
      EXPECT_GE(node.count, 1);
      EXPECT_LE(node.count, max_leaf_size) << "node " << index;
      ASSERT_GE(node.first, 0);
      ASSERT_LE(node.first + node.count, n);
      for (int slot = node.first; slot < node.first + node.count; ++slot) {
        ++slot_visits[slot];
        const auto& tri = mesh.triangles[bvh.triangle_ids[slot]];
        for (int k = 0; k < 3; ++k) {
          const Eigen::Vector3d& v = mesh.vertices[tri[k]];
          EXPECT_TRUE(boxContains(node.box(), v)) << "node " << index << " box misses triangle " << bvh.triangle_ids[slot];
          EXPECT_TRUE(sphereContains(node, v))
              << "node " << index << " sphere misses triangle " << bvh.triangle_ids[slot] << " by "
              << (v - node.center).norm() - node.radius;
        }
      }
    } else {
      ASSERT_GE(node.first, 1);
      ASSERT_LT(node.first + 1, node_count);
      for (int child = node.first; child <= node.first + 1; ++child) {
        EXPECT_TRUE(boxContains(node.box(), bvh.nodes[child].box())) << "node " << index << " child " << child;
        stack.push_back(child);
      }
    }
  }
  for (int i = 0; i < node_count; ++i) EXPECT_EQ(node_visits[i], 1) << "node " << i << " unreachable";
  for (int slot = 0; slot < n; ++slot) EXPECT_EQ(slot_visits[slot], 1) << "slot " << slot << " of triangle_ids";

  // The box and sphere of an inner node bound every triangle below it, not only its children's volumes
  // (a query prunes with the inner node's volume alone).
  std::vector<int> order;  // parents before children
  order.push_back(0);
  for (std::size_t k = 0; k < order.size(); ++k) {
    const BvhNode& node = bvh.nodes[order[k]];
    if (!node.isLeaf()) {
      order.push_back(node.first);
      order.push_back(node.first + 1);
    }
  }
  std::vector<std::vector<int>> below(node_count);
  for (auto it = order.rbegin(); it != order.rend(); ++it) {
    const BvhNode& node = bvh.nodes[*it];
    if (node.isLeaf()) {
      below[*it].assign(bvh.triangle_ids.begin() + node.first, bvh.triangle_ids.begin() + node.first + node.count);
    } else {
      below[*it] = below[node.first];
      below[*it].insert(below[*it].end(), below[node.first + 1].begin(), below[node.first + 1].end());
    }
    // The subtree range is exactly the triangles below (a query tests small subtrees through it alone).
    ASSERT_GE(node.subtree_first, 0) << "node " << *it;
    ASSERT_LE(node.subtree_first + node.subtree_count, n) << "node " << *it;
    EXPECT_EQ(std::vector<int>(bvh.triangle_ids.begin() + node.subtree_first,
                               bvh.triangle_ids.begin() + node.subtree_first + node.subtree_count),
              below[*it])
        << "node " << *it << " subtree range [" << node.subtree_first << ", +" << node.subtree_count << ")";
    for (int t : below[*it]) {
      for (int k = 0; k < 3; ++k) {
        const Eigen::Vector3d& v = mesh.vertices[mesh.triangles[t][k]];
        EXPECT_TRUE(boxContains(node.box(), v)) << "node " << *it << " box misses triangle " << t;
        EXPECT_TRUE(sphereContains(node, v)) << "node " << *it << " sphere misses triangle " << t << " by "
                                             << (v - node.center).norm() - node.radius;
        const Eigen::Vector3d local = node.obb_axes.transpose() * (v - node.obb_center);
        EXPECT_TRUE((local.cwiseAbs().array() <= node.obb_half.array()).all())
            << "node " << *it << " oriented box misses triangle " << t << ": " << local.transpose() << " vs "
            << node.obb_half.transpose();
      }
    }
    // The query's separating-axis bounds assume orthonormal axes.
    EXPECT_TRUE((node.obb_axes.transpose() * node.obb_axes).isIdentity(1e-12)) << "node " << *it;
  }
  EXPECT_EQ(static_cast<int>(below[0].size()), n);
}

TEST(Bvh, InvariantsHoldOnSeveralMeshesAndLeafSizes) {
  for (const NamedMesh& named : testMeshes()) {
    for (int max_leaf_size : {1, 2, 4, 6, 8}) {
      const Bvh bvh = buildBvh(named.mesh, max_leaf_size);
      checkInvariants(named.mesh, bvh, max_leaf_size, named.name + " leaf size " + std::to_string(max_leaf_size));
    }
  }
}

// The query's node bounds lose the node's radius, so spheres should be near the smallest: never larger than
// the sphere about the box's center, and within Jung's theorem (the smallest sphere holding a point set of
// diameter D has radius <= D sqrt(3/8) < 0.6124 D), checked on nodes small enough for all vertex pairs.
TEST(Bvh, SpheresAreNoLargerThanTheBoxCenteredOneAndWithinJungsBound) {
  for (const NamedMesh& named : testMeshes()) {
    SCOPED_TRACE(named.name);
    const Bvh bvh = buildBvh(named.mesh, 1);
    for (std::size_t i = 0; i < bvh.nodes.size(); ++i) {
      const BvhNode& node = bvh.nodes[i];
      std::vector<Eigen::Vector3d> points;
      for (int n = node.subtree_first; n < node.subtree_first + node.subtree_count; ++n) {
        for (int index : named.mesh.triangles[bvh.triangle_ids[n]]) points.push_back(named.mesh.vertices[index]);
      }
      // The vertices' own box: the node's is rounded outward to float, its center shifted by that rounding.
      Aabb box;
      for (const auto& p : points) box.extend(p);
      double box_radius = 0;
      for (const auto& p : points) box_radius = std::max(box_radius, (p - box.center()).norm());
      EXPECT_LE(node.radius, box_radius * (1 + 1e-12)) << "node " << i;
      if (node.subtree_count > 64) continue;
      double diameter = 0;
      for (const auto& p : points) {
        for (const auto& q : points) diameter = std::max(diameter, (p - q).norm());
      }
      EXPECT_LE(node.radius, 0.6124 * diameter * (1 + 1e-12)) << "node " << i;
    }
  }
}

// Node boxes are stored in float, rounded outward: they must still hold every vertex where float rounding
// moves coordinates (far from the origin) and where float has no finite value for them (past 3.4e38, which
// validateMesh allows).
TEST(Bvh, FloatBoxesHoldTheVerticesFarFromTheOriginAndPastFloatRange) {
  for (const double scale : {1.0, 1e30, 1e45, 1e-40}) {
    for (const double offset : {0.0, 1e7, -3.3e38}) {
      TriangleMesh mesh = test::makeTorus();
      for (Eigen::Vector3d& v : mesh.vertices) v = scale * v + Eigen::Vector3d(offset, 0.5 * offset, 0);
      for (int max_leaf_size : {1, 8}) {
        checkInvariants(mesh, buildBvh(mesh, max_leaf_size), max_leaf_size,
                        "scale " + scientific(scale) + " offset " + scientific(offset));
      }
    }
  }
}

// The mesh search's distance from a point to a node's box (nodeBoxSquaredDistance, read from the float
// bounds) against the distance to the point's clamp into the box, at random points inside, beside, past
// the corners of and far from every node of meshes of several scales: a gap too large would prune pairs the
// search must test.
TEST(Bvh, NodeBoxDistanceIsTheDistanceToTheClampedPoint) {
  std::mt19937_64 rng(20261127);
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  int inside = 0, outside = 0;
  for (const double scale : {1.0, 1e-3, 1e6}) {
    TriangleMesh mesh = test::makeTorusKnot();
    for (Eigen::Vector3d& v : mesh.vertices) v *= scale;
    const Bvh bvh = buildBvh(mesh, 4);
    for (const BvhNode& node : bvh.nodes) {
      const Aabb box = node.box();
      const Eigen::Vector3d center = box.center(), half = 0.5 * box.size();
      for (const double reach : {0.5, 1.0, 1.5, 4.0}) {
        const Eigen::Vector3d p =
            center + reach * half.cwiseProduct(Eigen::Vector3d(unit(rng), unit(rng), unit(rng)));
        const Eigen::Vector3d clamped = p.cwiseMax(box.min).cwiseMin(box.max);
        const double expected = (p - clamped).squaredNorm();
        ASSERT_NEAR(detail::nodeBoxSquaredDistance(p, node), expected, 1e-15 * expected)
            << "scale " << scale << " reach " << reach;
        (expected == 0 ? inside : outside) += 1;
      }
    }
  }
  EXPECT_GT(inside, 100);
  EXPECT_GT(outside, 100);
}

// A mesh of ordinary size may hold a few triangles far below its scale (validateMesh bounds only the whole
// mesh's extent): their nodes' scatter would underflow to denormals, on which the eigensolver returns zero
// axes, and their squared extents to zero, which left the oriented boxes without slack for rounding.
TEST(Bvh, OrientedBoxesHoldTrianglesFarBelowTheMeshScale) {
  for (const double tiny : {1e-150, 1e-170, 1e-200, 1e-250}) {
    TriangleMesh mesh = test::makeTorus();
    const TriangleMesh cluster = test::makeTriangleSoup(40, 3, 1.0, 0.3);
    const int offset = static_cast<int>(mesh.vertices.size());
    for (const Eigen::Vector3d& v : cluster.vertices) mesh.vertices.push_back(tiny * v);
    for (auto tri : cluster.triangles) mesh.triangles.push_back({tri[0] + offset, tri[1] + offset, tri[2] + offset});
    ASSERT_NO_THROW(validateMesh(mesh));
    for (int max_leaf_size : {1, 4}) {
      checkInvariants(mesh, buildBvh(mesh, max_leaf_size), max_leaf_size, "tiny " + scientific(tiny));
    }
  }
}

TEST(Bvh, SingleTriangleMeshIsOneLeaf) {
  TriangleMesh mesh;
  mesh.vertices = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 2, 1)};
  mesh.triangles = {{0, 1, 2}};
  for (int max_leaf_size : {1, 4}) {
    const Bvh bvh = buildBvh(mesh, max_leaf_size);
    checkInvariants(mesh, bvh, max_leaf_size, "single triangle");
    ASSERT_EQ(bvh.nodes.size(), 1u);
    EXPECT_TRUE(bvh.nodes[0].isLeaf());
    EXPECT_EQ(bvh.nodes[0].count, 1);
  }
}

TEST(Bvh, IdenticalTrianglesAreSplitIntoBoundedLeaves) {
  // Every centroid equal: a median split must still terminate and respect the leaf size.
  TriangleMesh mesh;
  mesh.vertices = {Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 0, 0), Eigen::Vector3d(0, 1, 0)};
  for (int t = 0; t < 37; ++t) mesh.triangles.push_back({0, 1, 2});
  for (int max_leaf_size : {1, 3}) {
    checkInvariants(mesh, buildBvh(mesh, max_leaf_size), max_leaf_size, "identical triangles");
  }
  TriangleMesh points;
  points.vertices = {Eigen::Vector3d(0.5, -1, 2)};
  for (int t = 0; t < 9; ++t) points.triangles.push_back({0, 0, 0});
  checkInvariants(points, buildBvh(points, 2), 2, "point triangles");
}

// The depth of the leaf holding each triangle of `bvh`, by triangle id.
std::vector<int> leafDepths(const Bvh& bvh) {
  std::vector<int> depth(bvh.triangle_ids.size(), -1);
  std::vector<std::pair<int, int>> stack{{0, 0}};
  while (!stack.empty()) {
    const auto [index, level] = stack.back();
    stack.pop_back();
    const BvhNode& node = bvh.nodes[index];
    if (node.isLeaf()) {
      for (int n = node.first; n < node.first + node.count; ++n) depth[bvh.triangle_ids[n]] = level;
    } else {
      stack.push_back({node.first, level + 1});
      stack.push_back({node.first + 1, level + 1});
    }
  }
  return depth;
}

// Where a few huge triangles lie next to many tiny ones, a split by count pairs them with runs of tiny ones
// all the way down, and a query meets them only below many levels of loose nodes: they must sit near the
// root, and the tiny ones under nodes of their own size.
TEST(Bvh, HugeTrianglesNextToTinyOnesSitNearTheRoot) {
  for (const NamedMesh& named : {NamedMesh{"refined_slab", test::makeLocallyRefinedSlab(60)},
                                 NamedMesh{"uneven_soup", unevenSoup()}}) {
    SCOPED_TRACE(named.name);
    const TriangleMesh& mesh = named.mesh;
    const Bvh bvh = buildBvh(mesh, 6);
    checkInvariants(mesh, bvh, 6, named.name);
    const std::vector<int> depth = leafDepths(bvh);
    const double root_size = bvh.nodes[0].box().diagonal();
    int huge = 0, tiny = 0;
    for (std::size_t t = 0; t < mesh.triangles.size(); ++t) {
      Aabb box;
      for (int index : mesh.triangles[t]) box.extend(mesh.vertices[index]);
      if (box.diagonal() > 0.2 * root_size) {
        ++huge;
        EXPECT_LE(depth[t], 8) << "huge triangle " << t;
      } else if (box.diagonal() < 0.01 * root_size) {
        ++tiny;
      }
    }
    EXPECT_GE(huge, 10);
    EXPECT_GE(tiny, 500);
    // The nodes holding a huge triangle are few: the huge triangles' ancestors, not half the tree.
    std::vector<int> order{0};
    for (std::size_t k = 0; k < order.size(); ++k) {
      const BvhNode& node = bvh.nodes[order[k]];
      bool has_huge = false;
      for (int n = node.subtree_first; n < node.subtree_first + node.subtree_count; ++n) {
        Aabb box;
        for (int index : mesh.triangles[bvh.triangle_ids[n]]) box.extend(mesh.vertices[index]);
        has_huge = has_huge || box.diagonal() > 0.2 * root_size;
      }
      if (!has_huge) continue;
      if (!node.isLeaf()) order.push_back(node.first), order.push_back(node.first + 1);
    }
    EXPECT_LE(order.size(), 3u * huge) << "nodes over huge triangles";
  }
}

// Each triangle's box dwarfs all the smaller ones together, so a surface-area split would peel them off one
// level at a time: the tree must still stay shallow enough for the fixed stacks of the depth-first walks.
TEST(Bvh, NestedTrianglesOfGeometricSizesKeepTheTreeWithinItsDepthBound) {
  TriangleMesh mesh;
  // From 1e100 down to about 1e-94 units: squares stay far from overflow and underflow.
  const int count = 150;
  double size = 1e100;
  for (int k = 0; k < count; ++k, size *= 0.05) {
    const int v = static_cast<int>(mesh.vertices.size());
    mesh.vertices.emplace_back(size, 0, 0);
    mesh.vertices.emplace_back(size, size, 0);
    mesh.vertices.emplace_back(size, 0, size);
    mesh.triangles.push_back({v, v + 1, v + 2});
  }
  for (int leaf_size : {1, 6}) {
    const Bvh bvh = buildBvh(mesh, leaf_size);
    checkInvariants(mesh, bvh, leaf_size, "nested");
    const std::vector<int> depth = leafDepths(bvh);
    EXPECT_LE(*std::max_element(depth.begin(), depth.end()), Bvh::kMaxDepth) << "leaf size " << leaf_size;
  }
}

// Every byte of every node (the padding aside) and the leaf order, compared field by field.
void expectSameBvh(const Bvh& a, const Bvh& b, const std::string& label) {
  SCOPED_TRACE(label);
  ASSERT_EQ(a.triangle_ids, b.triangle_ids);
  ASSERT_EQ(a.nodes.size(), b.nodes.size());
  for (std::size_t i = 0; i < a.nodes.size(); ++i) {
    const BvhNode& x = a.nodes[i];
    const BvhNode& y = b.nodes[i];
    ASSERT_EQ(x.first, y.first) << "node " << i;
    ASSERT_EQ(x.count, y.count) << "node " << i;
    ASSERT_EQ(x.subtree_first, y.subtree_first) << "node " << i;
    ASSERT_EQ(x.subtree_count, y.subtree_count) << "node " << i;
    ASSERT_EQ(std::memcmp(x.box_min, y.box_min, sizeof(x.box_min)), 0) << "node " << i;
    ASSERT_EQ(std::memcmp(x.box_max, y.box_max, sizeof(x.box_max)), 0) << "node " << i;
    ASSERT_EQ(x.center, y.center) << "node " << i;
    ASSERT_EQ(x.radius, y.radius) << "node " << i;
    ASSERT_EQ(x.obb_axes, y.obb_axes) << "node " << i;
    ASSERT_EQ(x.obb_center, y.obb_center) << "node " << i;
    ASSERT_EQ(x.obb_half, y.obb_half) << "node " << i;
  }
}

// The parallel build splices subtrees built apart; it must number and fill the nodes exactly as the
// one-thread build does, whatever the grain and the number of threads, or the models built on the Bvh's
// leaf order would change with the machine.
TEST(Bvh, ParallelBuildEqualsTheOneThreadBuild) {
  std::vector<NamedMesh> meshes = testMeshes();
  meshes.push_back({"big_soup", test::makeTriangleSoup(20000, 11)});
  for (const NamedMesh& named : meshes) {
    for (int max_leaf_size : {1, 6}) {
      const int n = static_cast<int>(named.mesh.triangles.size());
      const Bvh serial = detail::buildBvhWithGrain(named.mesh, max_leaf_size, n + 1);
      checkInvariants(named.mesh, serial, max_leaf_size, named.name + " serial");
      for (int grain : {2, 7, 64, 1000}) {
        for (int threads : {1, 2, 4}) {
          tbb::task_arena arena(threads);
          Bvh parallel;
          arena.execute([&] { parallel = detail::buildBvhWithGrain(named.mesh, max_leaf_size, grain); });
          expectSameBvh(serial, parallel,
                        named.name + " leaf size " + std::to_string(max_leaf_size) + " grain " +
                            std::to_string(grain) + " threads " + std::to_string(threads));
        }
      }
      expectSameBvh(serial, buildBvh(named.mesh, max_leaf_size), named.name + " buildBvh");
    }
  }
}

TEST(Bvh, BuildIsDeterministic) {
  const TriangleMesh mesh = test::makeTriangleSoup(300, 5);
  const Bvh first = buildBvh(mesh, 2);
  const Bvh second = buildBvh(mesh, 2);
  EXPECT_EQ(first.triangle_ids, second.triangle_ids);
  ASSERT_EQ(first.nodes.size(), second.nodes.size());
  for (std::size_t i = 0; i < first.nodes.size(); ++i) {
    EXPECT_EQ(first.nodes[i].first, second.nodes[i].first);
    EXPECT_EQ(first.nodes[i].count, second.nodes[i].count);
    EXPECT_EQ(first.nodes[i].radius, second.nodes[i].radius);
  }
}

}  // namespace
}  // namespace cfl
