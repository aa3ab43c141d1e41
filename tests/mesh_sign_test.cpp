// analyzeMeshSign's closure verdicts on crafted meshes, its pseudonormals, and windingNumber against the
// brute-force solid-angle sum.

#include "cfl/cfl_file.h"
#include "cfl/cfl_model.h"
#include "cfl/mesh_sign.h"
#include "cfl/triangle_distance.h"
#include "support/sign_references.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <cstdint>
#include <random>
#include <string>

namespace cfl {
namespace {

using test::NamedMesh;

MeshSign analyze(const TriangleMesh& mesh) { return analyzeMeshSign(makeMeshModel(mesh)); }

TriangleMesh unitCube() { return test::makeBox(Eigen::Vector3d::Zero(), Eigen::Vector3d::Ones()); }

TEST(MeshSign, ClosedMeshesAreClosed) {
  const std::vector<NamedMesh> meshes = {
      {"sphere", test::makeSphere()},
      {"torus", test::makeTorus(1.0, 0.35, 16, 8)},
      {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6)},
      {"cube", unitCube()},
      {"cube soup", test::toSoup(unitCube())},
      {"sphere soup", test::toSoup(test::makeSphere())},
  };
  for (const NamedMesh& named : meshes) {
    SCOPED_TRACE(named.name);
    const MeshSign sign = analyze(named.mesh);
    EXPECT_TRUE(sign.closure.closed) << sign.closure.reason;
    EXPECT_EQ(sign.closure.reason, "");
    EXPECT_EQ(sign.closure.boundary_edges, 0);
    EXPECT_EQ(sign.closure.nonmanifold_edges, 0);
    EXPECT_EQ(sign.closure.inconsistent_edges, 0);
    EXPECT_EQ(sign.closure.degenerate_triangles, 0);
    EXPECT_EQ(sign.closure.intersecting_pairs, 0);
    for (const auto& n : sign.neighbors) {
      for (int e = 0; e < 3; ++e) EXPECT_GE(n[e], 0);
    }
  }
}

TEST(MeshSign, OrientationFollowsTheEnclosedVolume) {
  EXPECT_EQ(analyze(unitCube()).closure.orientation, 1);
  const MeshSign inside_out = analyze(test::flipped(unitCube()));
  EXPECT_TRUE(inside_out.closure.closed);
  EXPECT_EQ(inside_out.closure.orientation, -1);
  // Pseudonormals point outward either way.
  const Eigen::Vector3d corner = Eigen::Vector3d::Ones().normalized();
  EXPECT_NEAR((inside_out.vertex_normals[inside_out.welded_vertex[7]] - corner).norm(), 0, 1e-12);
}

TEST(MeshSign, CubeVertexPseudonormalsPointAlongTheDiagonals) {
  const TriangleMesh cube = unitCube();
  const MeshSign sign = analyze(cube);
  for (int v = 0; v < 8; ++v) {
    const Eigen::Vector3d expected = (cube.vertices[v] - Eigen::Vector3d::Constant(0.5)).normalized();
    EXPECT_NEAR((sign.vertex_normals[sign.welded_vertex[v]] - expected).norm(), 0, 1e-12) << "vertex " << v;
  }
}

TEST(MeshSign, SoupVerticesWeldByPosition) {
  const TriangleMesh soup = test::toSoup(unitCube());
  const MeshSign sign = analyze(soup);
  for (std::size_t v = 0; v < soup.vertices.size(); ++v) {
    EXPECT_EQ(soup.vertices[sign.welded_vertex[v]], soup.vertices[v]);
    EXPECT_LE(sign.welded_vertex[v], int(v));
  }
}

TEST(MeshSign, MissingTriangleLeavesThreeBoundaryEdges) {
  TriangleMesh cube = unitCube();
  cube.triangles.erase(cube.triangles.begin() + 5);
  const MeshSign sign = analyze(cube);
  EXPECT_FALSE(sign.closure.closed);
  EXPECT_EQ(sign.closure.boundary_edges, 3);
  EXPECT_EQ(sign.closure.nonmanifold_edges, 0);
  EXPECT_NE(sign.closure.reason.find("open: 3 boundary edges"), std::string::npos) << sign.closure.reason;
}

TEST(MeshSign, TwoTrianglesShareOneEdgeAndHaveFourBoundaryEdges) {
  TriangleMesh square;
  square.vertices = {{0, 0, 0}, {1, 0, 0}, {1, 1, 0}, {0, 1, 0}};
  square.triangles = {{0, 1, 2}, {0, 2, 3}};
  const MeshSign sign = analyze(square);
  EXPECT_EQ(sign.closure.boundary_edges, 4);
  // The shared edge is edge 2 of triangle 0 (corners 2 and 0) and edge 0 of triangle 1 (corners 0 and 2).
  EXPECT_EQ(sign.neighbors[0][2], 1);
  EXPECT_EQ(sign.neighbors[1][0], 0);
  EXPECT_EQ(sign.neighbors[0][0], -1);
  EXPECT_EQ(sign.closure.inconsistent_edges, 0);
}

TEST(MeshSign, EdgeWithFourTrianglesIsNonManifold) {
  // Two cubes touching along one edge: that edge has four triangles, every other edge two.
  const TriangleMesh a = unitCube();
  const TriangleMesh b = test::makeBox(Eigen::Vector3d(1, 1, 0), Eigen::Vector3d(2, 2, 1));
  const MeshSign sign = analyze(test::merge(a, b));
  EXPECT_FALSE(sign.closure.closed);
  EXPECT_EQ(sign.closure.boundary_edges, 0);
  EXPECT_EQ(sign.closure.nonmanifold_edges, 1);
  EXPECT_EQ(sign.closure.intersecting_pairs, 0);
  EXPECT_EQ(sign.closure.reason.rfind("non-manifold: 1 edge", 0), 0u) << sign.closure.reason;
}

TEST(MeshSign, FinOnAnEdgeIsNonManifoldAndOpen) {
  TriangleMesh cube = unitCube();
  cube.vertices.push_back({0.5, -1, -1});
  cube.triangles.push_back({0, 1, 8});  // on the cube's edge from vertex 0 to vertex 1
  const MeshSign sign = analyze(cube);
  EXPECT_EQ(sign.closure.nonmanifold_edges, 1);
  EXPECT_EQ(sign.closure.boundary_edges, 2);
  EXPECT_EQ(sign.closure.reason.rfind("open: 2 boundary edges", 0), 0u) << sign.closure.reason;
}

TEST(MeshSign, FlippedTriangleIsInconsistent) {
  TriangleMesh cube = unitCube();
  std::swap(cube.triangles[3][1], cube.triangles[3][2]);
  const MeshSign sign = analyze(cube);
  EXPECT_FALSE(sign.closure.closed);
  EXPECT_EQ(sign.closure.boundary_edges, 0);
  EXPECT_EQ(sign.closure.inconsistent_edges, 3);
  EXPECT_EQ(sign.closure.reason.rfind("inconsistently oriented: 3 edges", 0), 0u) << sign.closure.reason;
}

TEST(MeshSign, ZeroAreaTriangleIsDegenerate) {
  // Triangle (a, b, c) of the cube split at the midpoint m of its edge ab, and the sliver (a, b, m) closing
  // the gap against the triangle on the other side of ab: closed and consistent, one zero-area triangle.
  TriangleMesh cube = unitCube();
  const auto t = cube.triangles[0];
  const int a = t[0], b = t[1], c = t[2];
  const int m = int(cube.vertices.size());
  cube.vertices.push_back(0.5 * (cube.vertices[a] + cube.vertices[b]));
  cube.triangles[0] = {a, m, c};
  cube.triangles.push_back({m, b, c});
  cube.triangles.push_back({a, b, m});
  const MeshSign sign = analyze(cube);
  EXPECT_FALSE(sign.closure.closed);
  EXPECT_EQ(sign.closure.boundary_edges, 0);
  EXPECT_EQ(sign.closure.nonmanifold_edges, 0);
  EXPECT_EQ(sign.closure.inconsistent_edges, 0);
  EXPECT_EQ(sign.closure.degenerate_triangles, 1);
  EXPECT_EQ(sign.closure.reason, "degenerate triangle 13 (zero area)");
}

TEST(MeshSign, CrossingBoxesSelfIntersect) {
  const TriangleMesh a = unitCube();
  const TriangleMesh b = test::makeBox(Eigen::Vector3d(0.5, 0.25, 0.25), Eigen::Vector3d(1.5, 0.75, 0.75));
  const MeshSign sign = analyze(test::merge(a, b));
  EXPECT_FALSE(sign.closure.closed);
  EXPECT_EQ(sign.closure.boundary_edges, 0);
  EXPECT_GT(sign.closure.intersecting_pairs, 0);
  EXPECT_EQ(sign.closure.reason.rfind("self-intersecting: triangles ", 0), 0u) << sign.closure.reason;
  EXPECT_NE(sign.closure.reason.find(" cross"), std::string::npos);
}

TEST(MeshSign, ManyCrossingsStopAtTheCap) {
  const TriangleMesh soup = test::makeTriangleSoup(3000, 5, 0.3, 0.3);
  const MeshSign sign = analyze(soup);
  EXPECT_EQ(sign.closure.intersecting_pairs, 1000);
}

// The self-intersection walk prunes node pairs by their boxes (float) and their spheres (double): on a soup
// near the origin and the same soup 1e7 times its size away, where every float box spans the whole soup and
// only the spheres prune, it must find every crossing that a test of all pairs finds.
TEST(MeshSign, SelfIntersectionsMatchAllPairsNearAndFarFromTheOrigin) {
  const TriangleMesh soup = test::makeTriangleSoup(400, 11, 1.0, 0.25);
  for (double offset : {0.0, 1e7}) {
    TriangleMesh moved = soup;
    for (Eigen::Vector3d& v : moved.vertices) v += Eigen::Vector3d(offset, -offset, 0.5 * offset);
    std::int64_t all_pairs = 0;
    for (std::size_t s = 0; s < moved.triangles.size(); ++s) {
      for (std::size_t t = s + 1; t < moved.triangles.size(); ++t) {
        Eigen::Vector3d p[3], q[3];
        for (int k = 0; k < 3; ++k) {
          p[k] = moved.vertices[moved.triangles[s][k]];
          q[k] = moved.vertices[moved.triangles[t][k]];
        }
        all_pairs += trianglesIntersect(p, q);
      }
    }
    ASSERT_GT(all_pairs, 20) << offset;
    ASSERT_LT(all_pairs, 1000) << offset;  // below the count's cap
    EXPECT_EQ(analyze(moved).closure.intersecting_pairs, all_pairs) << offset;
  }
}

TEST(MeshSign, ModelsCarryTheAnalysis) {
  const CflModel model = buildCflModel(test::makeHemisphere(1.0, 6, 16));
  EXPECT_FALSE(model.sign.closure.closed);
  EXPECT_NE(model.sign.closure.reason.find("boundary"), std::string::npos);
  // The winding number's far field is built on first use, once, and shared by copies of the model.
  ASSERT_TRUE(model.sign.winding);
  const CflModel copy = model;
  const WindingField& field = windingField(model.geometry, model.sign);
  EXPECT_EQ(&windingField(copy.geometry, copy.sign), &field);
  ASSERT_EQ(field.dipole_index.size(), model.geometry.bvh.nodes.size());
  std::size_t inner = 0;
  for (std::size_t n = 0; n < model.geometry.bvh.nodes.size(); ++n) {
    if (model.geometry.bvh.nodes[n].isLeaf()) {
      EXPECT_EQ(field.dipole_index[n], -1);
    } else {
      EXPECT_EQ(field.dipole_index[n], int(inner++));
    }
  }
  EXPECT_EQ(field.node_dipoles.size(), inner);
}

TEST(MeshSign, LoadedModelsDeriveTheSameAnalysis) {
  for (const TriangleMesh& mesh : {test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6), test::makeHemisphere(1.0, 6, 16)}) {
    const CflModel built = buildCflModel(mesh);
    const std::vector<unsigned char> bytes = serializeCflModel(built);
    const CflModel loaded = deserializeCflModel(bytes.data(), bytes.size(), "memory");
    EXPECT_EQ(loaded.sign.closure.closed, built.sign.closure.closed);
    EXPECT_EQ(loaded.sign.closure.reason, built.sign.closure.reason);
    EXPECT_EQ(loaded.sign.closure.orientation, built.sign.closure.orientation);
    EXPECT_EQ(loaded.sign.welded_vertex, built.sign.welded_vertex);
    EXPECT_EQ(loaded.sign.neighbors, built.sign.neighbors);
    EXPECT_EQ(loaded.sign.vertex_normals, built.sign.vertex_normals);
    const WindingField& loaded_field = windingField(loaded.geometry, loaded.sign);
    const WindingField& built_field = windingField(built.geometry, built.sign);
    EXPECT_EQ(loaded_field.dipole_index, built_field.dipole_index);
    ASSERT_EQ(loaded_field.node_dipoles.size(), built_field.node_dipoles.size());
    for (std::size_t n = 0; n < built_field.node_dipoles.size(); ++n) {
      EXPECT_EQ(loaded_field.node_dipoles[n].moment, built_field.node_dipoles[n].moment);
      EXPECT_EQ(loaded_field.node_dipoles[n].radius, built_field.node_dipoles[n].radius);
    }
  }
}

// windingNumber against the plain sum over every triangle, at points near and far.
TEST(WindingNumber, MatchesTheBruteForceSum) {
  const std::vector<NamedMesh> meshes = {
      {"sphere", test::makeSphere()},
      {"knot", test::makeTorusKnot(2, 3, 1.0, 0.3, 48, 6)},
      {"hemisphere", test::makeHemisphere(1.0, 6, 16)},
      {"bunny", test::loadBunny()},
  };
  test::Rng rng(7);
  for (const NamedMesh& named : meshes) {
    SCOPED_TRACE(named.name);
    const MeshModel model = makeMeshModel(named.mesh);
    const MeshSign sign = analyzeMeshSign(model);
    const Eigen::Vector3d center = model.bounds.center();
    const Eigen::Vector3d half = 0.5 * model.bounds.size();
    std::uniform_real_distribution<double> unit(-1, 1);
    double worst = 0;
    for (int i = 0; i < 400; ++i) {
      const double spread = i < 300 ? 1.2 : 4.0;
      const Eigen::Vector3d p = center + spread * Eigen::Vector3d(unit(rng) * half.x(), unit(rng) * half.y(),
                                                                  unit(rng) * half.z());
      const double expected = test::referenceWindingNumber(named.mesh, p);
      const double got = windingNumber(model, sign, p);
      worst = std::max(worst, std::abs(got - expected));
    }
    // The far field is an approximation; it must stay well inside the 1/2 that separates inside from outside.
    EXPECT_LT(worst, 0.05);
  }
}

TEST(WindingNumber, IsOneInsideAndZeroOutsideAClosedMesh) {
  const MeshModel model = makeMeshModel(test::makeSphere());
  const MeshSign sign = analyzeMeshSign(model);
  EXPECT_NEAR(windingNumber(model, sign, Eigen::Vector3d(0.1, 0.2, -0.3)), 1.0, 0.05);
  EXPECT_NEAR(windingNumber(model, sign, Eigen::Vector3d(3, 0.2, -0.3)), 0.0, 0.05);
  EXPECT_NEAR(windingNumber(model, sign, Eigen::Vector3d(30, 20, -10)), 0.0, 1e-3);
}

}  // namespace
}  // namespace cfl
