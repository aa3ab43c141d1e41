// computePenetration against references that do not use it: an exact linear program for convex polytopes
// (the definition's max-min is linear on each face), closed forms for balls and nested boxes, and a dense
// sampling of the surfaces with brute-force distances and winding numbers on non-convex meshes.

#include "cfl/penetration.h"

#include "cfl/error.h"
#include "support/test_meshes.h"

#include <gtest/gtest.h>

#include <cmath>
#include <map>
#include <string>

namespace cfl {
namespace {

using test::Rng;

constexpr double kPi = 3.14159265358979323846;

CflModel build(TriangleMesh mesh) { return buildCflModel(std::move(mesh)); }

// The generalized winding number by direct summation of solid angles (Van Oosterom & Strackee), no
// acceleration: the reference for inside / outside.
double referenceWindingNumber(const TriangleMesh& mesh, const Eigen::Isometry3d& X, const Eigen::Vector3d& p) {
  double total = 0;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = X * mesh.vertices[t[0]] - p, b = X * mesh.vertices[t[1]] - p,
                          c = X * mesh.vertices[t[2]] - p;
    const double la = a.norm(), lb = b.norm(), lc = c.norm();
    const double numerator = a.dot(b.cross(c));
    const double denominator = la * lb * lc + a.dot(b) * lc + b.dot(c) * la + c.dot(a) * lb;
    total += 2 * std::atan2(numerator, denominator);
  }
  return total / (4 * kPi);
}

// Exact depth of the definition for two convex closed meshes: for each triangle F of one and the other body
// S (the intersection of its triangles' half-spaces), max t subject to x in F, x in S, t <= distance from x
// to each face plane of S; for convex S the distance from an inside point to its surface is the least of
// those plane distances, so this is the definition restricted to F. A 3-variable linear program, solved by
// enumerating the vertices of its constraint set (every triple of constraints).
struct Plane {
  Eigen::Vector3d n;  // unit, outward
  double d;           // n . x <= d inside
};

std::vector<Plane> facePlanes(const TriangleMesh& mesh, const Eigen::Isometry3d& X) {
  std::vector<Plane> planes;
  for (const auto& t : mesh.triangles) {
    const Eigen::Vector3d a = X * mesh.vertices[t[0]], b = X * mesh.vertices[t[1]], c = X * mesh.vertices[t[2]];
    const Eigen::Vector3d n = (b - a).cross(c - a).normalized();
    planes.push_back({n, n.dot(a)});
  }
  return planes;
}

double convexFaceDepth(const Eigen::Vector3d f[3], const std::vector<Plane>& solid) {
  // x = f0 + u (f1 - f0) + v (f2 - f0); variables (u, v, t); constraints A z <= b.
  const Eigen::Vector3d e1 = f[1] - f[0], e2 = f[2] - f[0];
  std::vector<Eigen::Vector3d> rows;
  std::vector<double> rhs;
  rows.push_back({-1, 0, 0});
  rhs.push_back(0);
  rows.push_back({0, -1, 0});
  rhs.push_back(0);
  rows.push_back({1, 1, 0});
  rhs.push_back(1);
  for (const Plane& p : solid) {
    rows.push_back({p.n.dot(e1), p.n.dot(e2), 0});  // inside the solid
    rhs.push_back(p.d - p.n.dot(f[0]));
    rows.push_back({p.n.dot(e1), p.n.dot(e2), 1});  // t <= d - n . x
    rhs.push_back(p.d - p.n.dot(f[0]));
  }
  double best = -INFINITY;
  const int m = int(rows.size());
  for (int i = 0; i < m; ++i)
    for (int j = i + 1; j < m; ++j)
      for (int k = j + 1; k < m; ++k) {
        Eigen::Matrix3d A;
        A << rows[i].transpose(), rows[j].transpose(), rows[k].transpose();
        if (std::abs(A.determinant()) < 1e-12) continue;
        const Eigen::Vector3d z = A.inverse() * Eigen::Vector3d(rhs[i], rhs[j], rhs[k]);
        bool feasible = true;
        for (int r = 0; r < m && feasible; ++r) feasible = rows[r].dot(z) <= rhs[r] + 1e-10;
        if (feasible) best = std::max(best, z[2]);
      }
  return best;
}

double referenceConvexDepth(const TriangleMesh& a, const Eigen::Isometry3d& X_WA, const TriangleMesh& b,
                            const Eigen::Isometry3d& X_WB) {
  double depth = 0;
  const std::vector<Plane> planes_a = facePlanes(a, X_WA), planes_b = facePlanes(b, X_WB);
  for (const auto& t : b.triangles) {
    const Eigen::Vector3d f[3] = {X_WB * b.vertices[t[0]], X_WB * b.vertices[t[1]], X_WB * b.vertices[t[2]]};
    depth = std::max(depth, convexFaceDepth(f, planes_a));
  }
  for (const auto& t : a.triangles) {
    const Eigen::Vector3d f[3] = {X_WA * a.vertices[t[0]], X_WA * a.vertices[t[1]], X_WA * a.vertices[t[2]]};
    depth = std::max(depth, convexFaceDepth(f, planes_b));
  }
  return depth;
}

TriangleMesh makeOctahedron(double r) {
  TriangleMesh mesh;
  mesh.vertices = {{r, 0, 0}, {-r, 0, 0}, {0, r, 0}, {0, -r, 0}, {0, 0, r}, {0, 0, -r}};
  // Counterclockwise seen from outside.
  mesh.triangles = {{0, 2, 4}, {2, 1, 4}, {1, 3, 4}, {3, 0, 4}, {2, 0, 5}, {1, 2, 5}, {3, 1, 5}, {0, 3, 5}};
  return mesh;
}

// A unit sphere subdivided from an icosahedron `levels` times (20 * 4^levels triangles, closed).
TriangleMesh makeIcosphere(int levels, double radius = 1.0) {
  const double g = (1 + std::sqrt(5.0)) / 2;
  TriangleMesh mesh;
  mesh.vertices = {{-1, g, 0}, {1, g, 0}, {-1, -g, 0}, {1, -g, 0}, {0, -1, g}, {0, 1, g},
                   {0, -1, -g}, {0, 1, -g}, {g, 0, -1}, {g, 0, 1}, {-g, 0, -1}, {-g, 0, 1}};
  mesh.triangles = {{0, 11, 5}, {0, 5, 1}, {0, 1, 7}, {0, 7, 10}, {0, 10, 11}, {1, 5, 9}, {5, 11, 4},
                    {11, 10, 2}, {10, 7, 6}, {7, 1, 8}, {3, 9, 4}, {3, 4, 2}, {3, 2, 6}, {3, 6, 8},
                    {3, 8, 9}, {4, 9, 5}, {2, 4, 11}, {6, 2, 10}, {8, 6, 7}, {9, 8, 1}};
  for (auto& v : mesh.vertices) v.normalize();
  for (int level = 0; level < levels; ++level) {
    std::map<std::pair<int, int>, int> middle;
    auto mid = [&](int i, int j) {
      const auto key = std::minmax(i, j);
      auto it = middle.find(key);
      if (it != middle.end()) return it->second;
      mesh.vertices.push_back((mesh.vertices[i] + mesh.vertices[j]).normalized());
      return middle[key] = int(mesh.vertices.size()) - 1;
    };
    std::vector<std::array<int, 3>> next;
    for (const auto& t : mesh.triangles) {
      const int ab = mid(t[0], t[1]), bc = mid(t[1], t[2]), ca = mid(t[2], t[0]);
      next.push_back({t[0], ab, ca});
      next.push_back({t[1], bc, ab});
      next.push_back({t[2], ca, bc});
      next.push_back({ab, bc, ca});
    }
    mesh.triangles = next;
  }
  for (auto& v : mesh.vertices) v *= radius;
  return mesh;
}

Eigen::Isometry3d translation(double x, double y, double z) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = Eigen::Vector3d(x, y, z);
  return X;
}

// The witness points say what the depth says: the deepest point lies on its body's surface, inside the
// other body, and `depth` from the other surface, at surface_point.
void expectWitnessesConsistent(const TriangleMesh& ma, const Eigen::Isometry3d& X_WA, const TriangleMesh& mb,
                               const Eigen::Isometry3d& X_WB, const PenetrationResult& r, double tolerance) {
  ASSERT_TRUE(r.deepest_body == 0 || r.deepest_body == 1);
  const TriangleMesh& own = r.deepest_body == 0 ? ma : mb;
  const TriangleMesh& other = r.deepest_body == 0 ? mb : ma;
  const Eigen::Isometry3d& X_own = r.deepest_body == 0 ? X_WA : X_WB;
  const Eigen::Isometry3d& X_other = r.deepest_body == 0 ? X_WB : X_WA;
  EXPECT_LE(test::referencePointMeshDistance(own, r.deepest_point, X_own), tolerance);
  EXPECT_LE(test::referencePointMeshDistance(other, r.surface_point, X_other), tolerance);
  EXPECT_NEAR(test::referencePointMeshDistance(other, r.deepest_point, X_other), r.depth, tolerance);
  EXPECT_NEAR((r.surface_point - r.deepest_point).norm(), r.depth, tolerance);
  if (r.depth > tolerance) EXPECT_GT(std::abs(referenceWindingNumber(other, X_other, r.deepest_point)), 0.5);
  EXPECT_NEAR(r.normal.norm(), 1.0, 1e-9);
  // The reported triangles hold the two points.
  const int own_triangle = r.deepest_body == 0 ? r.triangle_a : r.triangle_b;
  const int other_triangle = r.deepest_body == 0 ? r.triangle_b : r.triangle_a;
  ASSERT_GE(own_triangle, 0);
  ASSERT_GE(other_triangle, 0);
  const auto on = [](const TriangleMesh& m, const Eigen::Isometry3d& X, int t, const Eigen::Vector3d& p) {
    const auto& v = m.triangles[t];
    return std::sqrt(test::referencePointTriangleSquaredDistance(X.inverse() * p, m.vertices[v[0]], m.vertices[v[1]],
                                                                 m.vertices[v[2]]));
  };
  EXPECT_LE(on(own, X_own, own_triangle, r.deepest_point), tolerance);
  EXPECT_LE(on(other, X_other, other_triangle, r.surface_point), tolerance);
}

TEST(Penetration, AxisAlignedBoxesMatchTheExactDefinition) {
  Rng rng(7);
  std::uniform_real_distribution<double> u(0.0, 1.0);
  int overlapping = 0;
  for (int trial = 0; trial < 40; ++trial) {
    Eigen::Vector3d lo_a, hi_a, lo_b, hi_b;
    for (int k = 0; k < 3; ++k) {
      lo_a[k] = u(rng) * 0.5;
      hi_a[k] = lo_a[k] + 0.3 + u(rng);
      lo_b[k] = u(rng);
      hi_b[k] = lo_b[k] + 0.2 + u(rng) * 0.8;
    }
    const TriangleMesh ma = test::makeBox(lo_a, hi_a), mb = test::makeBox(lo_b, hi_b);
    const CflModel a = build(ma), b = build(mb);
    const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
    const PenetrationResult r = computePenetration(a, I, b, I);
    const bool boxes_overlap = (lo_a.array() <= hi_b.array()).all() && (lo_b.array() <= hi_a.array()).all();
    ASSERT_EQ(r.overlapping, boxes_overlap) << "trial " << trial;
    const double expected = boxes_overlap ? referenceConvexDepth(ma, I, mb, I) : 0.0;
    const double tolerance = 1e-4 * std::max(a.geometry.bounds.diagonal(), b.geometry.bounds.diagonal());
    EXPECT_LE(r.depth, expected + 1e-9) << "trial " << trial;
    EXPECT_GE(r.depth_upper, expected - 1e-9) << "trial " << trial;
    EXPECT_LE(r.depth_upper - r.depth, tolerance + 1e-12) << "trial " << trial;
    if (boxes_overlap) {
      ++overlapping;
      expectWitnessesConsistent(ma, I, mb, I, r, 1e-9);
    }
  }
  EXPECT_GE(overlapping, 15);
}

TEST(Penetration, RotatedBoxesAndOctahedraMatchTheExactDefinition) {
  Rng rng(11);
  const std::vector<test::NamedMesh> shapes = {
      {"box", test::makeBox(Eigen::Vector3d(-0.5, -0.3, -0.2), Eigen::Vector3d(0.5, 0.3, 0.2))},
      {"octahedron", makeOctahedron(0.6)},
      {"cube", test::makeBox(Eigen::Vector3d(-0.4, -0.4, -0.4), Eigen::Vector3d(0.4, 0.4, 0.4))}};
  for (const auto& sa : shapes) {
    for (const auto& sb : shapes) {
      const CflModel a = build(sa.mesh), b = build(sb.mesh);
      for (int trial = 0; trial < 12; ++trial) {
        const Eigen::Isometry3d X_WA = test::randomPose(rng, 0.2), X_WB = test::randomPose(rng, 0.5);
        const PenetrationResult r = computePenetration(a, X_WA, b, X_WB);
        const std::string at = sa.name + " / " + sb.name + " trial " + std::to_string(trial);
        if (!r.overlapping) {
          EXPECT_EQ(r.depth, 0) << at;
          continue;
        }
        const double expected = referenceConvexDepth(sa.mesh, X_WA, sb.mesh, X_WB);
        const double tolerance = 1e-4 * std::max(a.geometry.bounds.diagonal(), b.geometry.bounds.diagonal());
        EXPECT_LE(r.depth, expected + 1e-9) << at;
        EXPECT_GE(r.depth_upper, expected - 1e-9) << at;
        EXPECT_LE(r.depth_upper - r.depth, tolerance + 1e-12) << at;
        expectWitnessesConsistent(sa.mesh, X_WA, sb.mesh, X_WB, r, 1e-9);
      }
    }
  }
}

TEST(Penetration, OctahedraAlongAnAxisHaveTheClosedForm) {
  // Octahedra |x| + |y| + |z| <= 1 at 0 and at (s, 0, 0): the deepest point is a vertex, at depth
  // (1 - |s - 1|) / sqrt(3) from the other's faces, for 0 < s < 2.
  const TriangleMesh m = makeOctahedron(1.0);
  const CflModel a = build(m), b = build(m);
  for (double s : {0.3, 0.5, 1.0, 1.5, 1.9}) {
    const PenetrationResult r = computePenetration(a, Eigen::Isometry3d::Identity(), b, translation(s, 0, 0));
    const double expected = (1 - std::abs(s - 1)) / std::sqrt(3.0);
    EXPECT_TRUE(r.overlapping);
    EXPECT_LE(r.depth, expected + 1e-9) << s;
    EXPECT_GE(r.depth_upper, expected - 1e-9) << s;
    EXPECT_NEAR(r.depth, expected, 2e-4 * std::sqrt(12.0)) << s;
  }
}

TEST(Penetration, ABoxWhollyInsideAnotherIsContained) {
  const TriangleMesh outer = test::makeBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1));
  const TriangleMesh inner = test::makeBox(Eigen::Vector3d(0.4, 0.35, 0.45), Eigen::Vector3d(0.6, 0.6, 0.6));
  const CflModel a = build(outer), b = build(inner);
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  // The deepest point of B's surface is the middle of its face z = 0.45, 0.45 from A's face z = 0 (every
  // other face of B has a coordinate within 0.4 of A's faces).
  const PenetrationResult r = computePenetration(a, I, b, I);
  EXPECT_TRUE(r.overlapping);
  EXPECT_EQ(r.contained, 1);
  EXPECT_EQ(r.deepest_body, 1);
  EXPECT_NEAR(r.depth, 0.45, 1e-9);
  EXPECT_NEAR(r.depth, referenceConvexDepth(outer, I, inner, I), 1e-9);
  expectWitnessesConsistent(outer, I, inner, I, r, 1e-9);
  // The other way round.
  const PenetrationResult s = computePenetration(b, I, a, I);
  EXPECT_EQ(s.contained, 2);
  EXPECT_EQ(s.deepest_body, 0);
  EXPECT_NEAR(s.depth, 0.45, 1e-9);
}

TEST(Penetration, TessellatedBallsMatchTheClosedForm) {
  // Unit balls whose centers are s apart. While each center is outside the other ball (s >= 1), the deepest
  // point of either surface is the one nearest the other's center, s - 1 from it, so the depth is 2 - s: the
  // translational depth. Deeper (s < 1) it is 1 - (1 - s) = s, below the translational 2 - s: the definition
  // is a lower bound. The tessellation moves the surfaces inwards by at most its sagitta.
  const TriangleMesh m = makeIcosphere(4);
  const CflModel a = build(m), b = build(m);
  const double sagitta = 0.003;
  for (double s : {0.5, 0.8, 1.2, 1.9}) {
    const PenetrationResult r = computePenetration(a, Eigen::Isometry3d::Identity(), b, translation(0, s, 0));
    const double expected = s >= 1 ? 2 - s : s;
    EXPECT_NEAR(r.depth, expected, 2 * sagitta) << s;
    EXPECT_LE(r.depth, 2 - s + 1e-12) << s;
  }
}

TEST(Penetration, NonConvexMeshesAreNeverShallowerThanASampling) {
  Rng rng(3);
  const std::vector<test::NamedMesh> meshes = {{"torus", test::makeTorus(1.0, 0.35, 24, 12)},
                                               {"knot", test::makeTorusKnot(2, 3, 0.5, 0.15, 64, 6)}};
  for (const auto& ma : meshes) {
    for (const auto& mb : meshes) {
      const CflModel a = build(ma.mesh), b = build(mb.mesh);
      int checked = 0;
      for (int trial = 0; trial < 40 && checked < 4; ++trial) {
        const Eigen::Isometry3d X_WA = Eigen::Isometry3d::Identity(), X_WB = test::randomPose(rng, 0.6);
        const PenetrationResult r = computePenetration(a, X_WA, b, X_WB);
        if (!r.overlapping) continue;
        ++checked;
        const std::string at = ma.name + " / " + mb.name + " trial " + std::to_string(trial);
        // Sample both surfaces densely; keep the deepest sampled point inside the other body.
        double sampled = 0;
        for (int side = 0; side < 2; ++side) {
          const TriangleMesh& skin = side == 0 ? mb.mesh : ma.mesh;
          const TriangleMesh& solid = side == 0 ? ma.mesh : mb.mesh;
          const Eigen::Isometry3d& X_skin = side == 0 ? X_WB : X_WA;
          const Eigen::Isometry3d& X_solid = side == 0 ? X_WA : X_WB;
          const Aabb box = boundingBox(solid);
          for (int t = 0; t < int(skin.triangles.size()); ++t) {
            for (int k = 0; k < 6; ++k) {
              const Eigen::Vector3d p = X_skin * test::randomPointOnTriangle(skin, t, rng);
              const Eigen::Vector3d p_solid = X_solid.inverse() * p;
              if ((p_solid.array() < box.min.array()).any() || (p_solid.array() > box.max.array()).any()) continue;
              const double d = test::referencePointMeshDistance(solid, p, X_solid);
              if (d <= sampled) continue;
              if (std::abs(referenceWindingNumber(solid, X_solid, p)) > 0.5) sampled = d;
            }
          }
        }
        const double tolerance = 1e-4 * std::max(a.geometry.bounds.diagonal(), b.geometry.bounds.diagonal());
        EXPECT_GE(r.depth_upper, sampled) << at;
        EXPECT_GE(r.depth, sampled - tolerance) << at;
        EXPECT_LE(r.depth_upper - r.depth, tolerance + 1e-12) << at;
        expectWitnessesConsistent(ma.mesh, X_WA, mb.mesh, X_WB, r, 1e-9);
      }
      EXPECT_GE(checked, 2) << ma.name << " / " << mb.name;
    }
  }
}

TEST(Penetration, SignedDistanceIsTheDistanceApartAndMinusTheDepthInside) {
  const TriangleMesh m = test::makeTorus(1.0, 0.35, 24, 12);
  const CflModel a = build(m), b = build(m);
  Rng rng(17);
  int apart = 0, overlapping = 0;
  for (int trial = 0; trial < 40; ++trial) {
    const Eigen::Isometry3d X_WA = test::randomPose(rng, 0.3), X_WB = test::randomPose(rng, 1.5);
    const DistanceResult r = computeSignedDistance(a, X_WA, b, X_WB);
    const double unsigned_distance = bruteForceDistance(a.geometry, X_WA, b.geometry, X_WB).distance;
    if (unsigned_distance > 0) {
      ++apart;
      EXPECT_NEAR(r.distance, unsigned_distance, 1e-12) << trial;
      EXPECT_EQ(bodyContainment(a, X_WA, b, X_WB), 0) << trial;  // tori of one size cannot hold each other
    } else {
      ++overlapping;
      const PenetrationResult p = computePenetration(a, X_WA, b, X_WB);
      EXPECT_EQ(r.distance, -p.depth) << trial;
      EXPECT_LT(r.distance, 0) << trial;
      EXPECT_NEAR((r.point_a - r.point_b).norm(), p.depth, 1e-9) << trial;
      EXPECT_LE(test::referencePointMeshDistance(m, r.point_a, X_WA), 1e-9) << trial;
      EXPECT_LE(test::referencePointMeshDistance(m, r.point_b, X_WB), 1e-9) << trial;
    }
  }
  EXPECT_GE(apart, 5);
  EXPECT_GE(overlapping, 5);
  // Nested boxes: the surfaces are apart, the bodies are not.
  const CflModel outer = build(test::makeBox(Eigen::Vector3d(0, 0, 0), Eigen::Vector3d(1, 1, 1)));
  const CflModel inner = build(test::makeBox(Eigen::Vector3d(0.3, 0.3, 0.3), Eigen::Vector3d(0.6, 0.6, 0.6)));
  const Eigen::Isometry3d I = Eigen::Isometry3d::Identity();
  EXPECT_EQ(bodyContainment(outer, I, inner, I), 1);
  EXPECT_EQ(bodyContainment(inner, I, outer, I), 2);
  EXPECT_NEAR(computeSignedDistance(outer, I, inner, I).distance, -0.4, 1e-9);  // inner's faces x, y, z = 0.6
}

TEST(Penetration, SeparatedMeshesHaveNoDepth) {
  const TriangleMesh m = test::makeTorus();
  const CflModel a = build(m), b = build(m);
  const PenetrationResult r = computePenetration(a, Eigen::Isometry3d::Identity(), b, translation(5, 0, 0));
  EXPECT_FALSE(r.overlapping);
  EXPECT_EQ(r.contained, 0);
  EXPECT_EQ(r.depth, 0);
  EXPECT_EQ(r.depth_upper, 0);
}

TEST(Penetration, AnOpenMeshIsRefusedByName) {
  const CflModel open = build(test::makeHemisphere());
  const CflModel closed = build(test::makeTorus());
  try {
    computePenetration(closed, Eigen::Isometry3d::Identity(), open, Eigen::Isometry3d::Identity());
    FAIL() << "an open mesh was accepted";
  } catch (const Error& e) {
    EXPECT_NE(std::string(e.what()).find("mesh B"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("boundary"), std::string::npos) << e.what();
  }
  PenetrationOptions bad;
  bad.tolerance = -1;
  EXPECT_THROW(computePenetration(closed, Eigen::Isometry3d::Identity(), closed, Eigen::Isometry3d::Identity(), bad),
               Error);
}

TEST(Penetration, ACoarseToleranceIsHonoured) {
  const TriangleMesh m = test::makeTorusKnot(2, 3, 0.5, 0.15, 64, 6);
  const CflModel a = build(m), b = build(m);
  const Eigen::Isometry3d X_WB = translation(0.05, 0.02, 0.0);
  for (double tolerance : {1e-2, 1e-3, 1e-5}) {
    PenetrationOptions options;
    options.tolerance = tolerance;
    const PenetrationResult r = computePenetration(a, Eigen::Isometry3d::Identity(), b, X_WB, options);
    EXPECT_TRUE(r.overlapping);
    EXPECT_LE(r.depth_upper - r.depth, tolerance + 1e-12);
    EXPECT_GT(r.depth, 0);
  }
}

}  // namespace
}  // namespace cfl
