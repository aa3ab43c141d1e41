// Properties of the distance kernels, checked against references that share no code with them:
// - closed forms that enumerate the KKT candidates of the underlying quadratic program (interior stationary
//   point, then each side of the parameter domain, then the corners), in long double;
// - golden-section searches over convex slices of the parameter domain, which only ever evaluate distances
//   of explicit points to segments (so they cannot share a region-classification bug with the code under
//   test) and do not mind ill-conditioned parametrisations;
// - certificates: returned closest points must lie on their primitives and be sqrt(distance) apart, which
//   proves the returned distance is attained, while the references bound it from above.
//
// Tolerances are relative to the size of the configuration (its largest coordinate extent), as in the
// library's contract; the figures and their reasons are given where they are declared.

#include "cfl/triangle_distance.h"

#include <gtest/gtest.h>

#include <Eigen/Geometry>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <vector>

namespace {

using Vec = Eigen::Vector3d;
using LVec = Eigen::Matrix<long double, 3, 1>;
using Triangle = std::array<Vec, 3>;

LVec toL(const Vec& v) { return v.cast<long double>(); }

// ---------------------------------------------------------------------------------------------------------
// Reference 1: KKT enumeration in long double.

// min |p - (x + t d)|^2 over t in [0, 1].
long double refPointSegment(const LVec& p, const LVec& x, const LVec& d, LVec* closest = nullptr) {
  const long double dd = d.squaredNorm();
  long double t = dd > 0 ? (p - x).dot(d) / dd : 0;
  t = std::clamp<long double>(t, 0, 1);
  const LVec c = x + t * d;
  if (closest) *closest = c;
  return (p - c).squaredNorm();
}

// min |p - (a + u (b - a) + v (c - a))|^2 over u, v >= 0, u + v <= 1: the interior stationary point if it is
// feasible, else the best of the three sides (which include the corners).
long double refPointTriangle(const LVec& p, const LVec& a, const LVec& b, const LVec& c, LVec* closest = nullptr) {
  const LVec e1 = b - a, e2 = c - a, ap = p - a;
  const long double g11 = e1.dot(e1), g12 = e1.dot(e2), g22 = e2.dot(e2);
  const long double r1 = e1.dot(ap), r2 = e2.dot(ap);
  const long double det = g11 * g22 - g12 * g12;
  long double best = std::numeric_limits<long double>::infinity();
  LVec best_c = a;
  if (det > 0) {
    const long double u = (r1 * g22 - r2 * g12) / det, v = (g11 * r2 - g12 * r1) / det;
    if (u >= 0 && v >= 0 && u + v <= 1) {
      best_c = a + u * e1 + v * e2;
      best = (p - best_c).squaredNorm();
    }
  }
  const LVec* starts[3] = {&a, &b, &c};
  const LVec* ends[3] = {&b, &c, &a};
  for (int i = 0; i < 3; ++i) {
    LVec q;
    const long double d2 = refPointSegment(p, *starts[i], *ends[i] - *starts[i], &q);
    if (d2 < best) {
      best = d2;
      best_c = q;
    }
  }
  if (closest) *closest = best_c;
  return best;
}

long double refPointTriangle(const Vec& p, const Triangle& t) {
  return refPointTriangle(toL(p), toL(t[0]), toL(t[1]), toL(t[2]));
}

// min |(p0 + s dp) - (q0 + t dq)|^2 over the unit square: interior stationary point, else the four sides.
long double refSegmentSegment(const Vec& p0, const Vec& p1, const Vec& q0, const Vec& q1) {
  const LVec a = toL(p0), dp = toL(p1) - a, b = toL(q0), dq = toL(q1) - b;
  const long double A = dp.dot(dp), B = dp.dot(dq), C = dq.dot(dq);
  const LVec r = a - b;
  const long double D = dp.dot(r), E = dq.dot(r);
  long double best = std::numeric_limits<long double>::infinity();
  const long double det = A * C - B * B;
  if (det > 0) {
    // Gradient zero: A s - B t + D = 0, -B s + C t - E = 0.
    const long double s = (B * E - C * D) / det, t = (A * E - B * D) / det;
    if (s >= 0 && s <= 1 && t >= 0 && t <= 1) best = (r + s * dp - t * dq).squaredNorm();
  }
  for (int k = 0; k < 2; ++k) {
    best = std::min(best, refPointSegment(a + k * dp, b, dq));  // s fixed at 0 or 1
    best = std::min(best, refPointSegment(b + k * dq, a, dp));  // t fixed at 0 or 1
  }
  return best;
}

// ---------------------------------------------------------------------------------------------------------
// Reference 2: convex slices. The minimum of a jointly convex function over a convex set, restricted to the
// level sets of an affine function, is a convex function of the level (partial minimisation), so it can be
// minimised by golden-section search, which, unlike descent on barycentric coordinates, does not care how badly
// conditioned the parametrisation is (slivers, near-parallel segments). Each slice is then solved exactly
// (point-segment) or by a nested search.

// Minimum of a convex f on [0, 1]. With equal probes the minimum lies between them (convexity), which both
// choices keep.
template <class F>
long double goldenMin(const F& f, int iterations = 90) {
  const long double r = (std::sqrt(5.0L) - 1) / 2;
  long double lo = 0, hi = 1;
  long double x1 = hi - r * (hi - lo), x2 = lo + r * (hi - lo);
  long double f1 = f(x1), f2 = f(x2);
  long double best = std::min({f(0.0L), f(1.0L), f1, f2});
  for (int i = 0; i < iterations; ++i) {
    if (f1 <= f2) {
      hi = x2;
      x2 = x1;
      f2 = f1;
      x1 = hi - r * (hi - lo);
      f1 = f(x1);
      best = std::min(best, f1);
    } else {
      lo = x1;
      x1 = x2;
      f1 = f2;
      x2 = lo + r * (hi - lo);
      f2 = f(x2);
      best = std::min(best, f2);
    }
  }
  return best;
}

// Row s of triangle t: the segment from a + s (b - a) to a + s (c - a); the rows for s in [0, 1] sweep t.
struct Row {
  LVec start, dir;
};
Row row(const Triangle& t, long double s) {
  const LVec a = toL(t[0]);
  const LVec x = a + s * (toL(t[1]) - a), y = a + s * (toL(t[2]) - a);
  return {x, y - x};
}

long double slicedPointTriangle(const Vec& p, const Triangle& t) {
  const LVec lp = toL(p);
  return goldenMin([&](long double s) {
    const Row r = row(t, s);
    return refPointSegment(lp, r.start, r.dir);
  });
}

long double slicedSegmentSegment(const Vec& p0, const Vec& p1, const Vec& q0, const Vec& q1) {
  const LVec a = toL(p0), dp = toL(p1) - a, b = toL(q0), dq = toL(q1) - b;
  return goldenMin([&](long double s) { return refPointSegment(a + s * dp, b, dq); });
}

// Rows of P, points along each row, closed-form distance to Q; and the same with the roles swapped. Both are
// attained values (upper bounds), the smaller is kept.
long double referenceTriangleTriangle(const Triangle& p, const Triangle& q) {
  auto over = [](const Triangle& a, const Triangle& b) {
    const LVec b0 = toL(b[0]), b1 = toL(b[1]), b2 = toL(b[2]);
    return goldenMin(
        [&](long double s) {
          const Row r = row(a, s);
          return goldenMin([&](long double t) { return refPointTriangle(r.start + t * r.dir, b0, b1, b2); }, 62);
        },
        62);
  };
  const long double over_p = over(p, q);
  if (over_p == 0) return 0;
  return std::min(over_p, over(q, p));
}

// ---------------------------------------------------------------------------------------------------------
// Configurations.

class Gen {
 public:
  explicit Gen(unsigned seed) : rng_(seed) {}
  double uniform(double lo, double hi) { return std::uniform_real_distribution<double>(lo, hi)(rng_); }
  Vec point(double r = 1.0) { return Vec(uniform(-r, r), uniform(-r, r), uniform(-r, r)); }
  Vec direction() {
    for (;;) {
      const Vec v = point();
      if (v.squaredNorm() > 1e-2 && v.squaredNorm() <= 1.0) return v.normalized();
    }
  }
  Triangle triangle(double r = 1.0) { return {point(r), point(r), point(r)}; }
  Eigen::Matrix3d rotation() {
    return Eigen::Quaterniond(Eigen::Vector4d(uniform(-1, 1), uniform(-1, 1), uniform(-1, 1), uniform(-1, 1))
                                  .normalized())
        .toRotationMatrix();
  }
  int index(int n) { return std::uniform_int_distribution<int>(0, n - 1)(rng_); }

 private:
  std::mt19937_64 rng_;
};

double extent(const Triangle& p, const Triangle& q) {
  double m = 0;
  for (const auto* t : {&p, &q})
    for (const Vec& v : *t) m = std::max(m, v.cwiseAbs().maxCoeff());
  return std::max(m, 1e-300);
}

Triangle transformed(const Triangle& t, const Eigen::Matrix3d& r, const Vec& o) {
  return {r * t[0] + o, r * t[1] + o, r * t[2] + o};
}

// Accuracy the kernels must reach, relative to the size of the configuration: a few hundred ulps (the
// library promises 1e-9 of the bounding-box diagonal; the kernels do much better).
constexpr double kRel = 1e-12;

// All the checks a triangle pair must pass. `ref2` is the reference squared distance, `size` the scale the
// tolerance is relative to. Returns the distance for further checks.
double checkPair(const Triangle& p, const Triangle& q, double ref2, double size, double rel = kRel) {
  Vec cp, cq;
  const double d2 = cfl::triangleTriangleSquaredDistance(p.data(), q.data(), &cp, &cq);
  const double d = std::sqrt(d2), ref = std::sqrt(ref2);
  const double tol = rel * size;
  EXPECT_GE(d2, 0.0);
  EXPECT_NEAR(d, ref, tol) << "distance disagrees with the reference";
  // The closest points lie on their triangles and realise the distance, so d is attained, not just a bound.
  EXPECT_LE(std::sqrt(static_cast<double>(refPointTriangle(cp, p))), tol) << "closest_p is off triangle P";
  EXPECT_LE(std::sqrt(static_cast<double>(refPointTriangle(cq, q))), tol) << "closest_q is off triangle Q";
  EXPECT_NEAR((cp - cq).norm(), d, tol) << "closest points are not sqrt(distance) apart";
  Vec x;
  const bool hit = cfl::trianglesIntersect(p.data(), q.data(), &x);
  EXPECT_EQ(hit, d2 == 0.0) << "trianglesIntersect disagrees with distance " << d;
  if (d2 == 0.0) {
    EXPECT_EQ(cp, cq) << "intersecting triangles must report one common point";
  }
  if (hit) {
    EXPECT_LE(std::sqrt(static_cast<double>(refPointTriangle(x, p))), tol) << "intersection point off P";
    EXPECT_LE(std::sqrt(static_cast<double>(refPointTriangle(x, q))), tol) << "intersection point off Q";
  }
  // Symmetry: swapping the triangles swaps nothing but the roles.
  const double d2_swapped = cfl::triangleTriangleSquaredDistance(q.data(), p.data());
  EXPECT_NEAR(std::sqrt(d2_swapped), d, tol) << "distance is not symmetric";
  return d;
}

// ---------------------------------------------------------------------------------------------------------
// The references agree with each other (so a failure below points at the code, not at a reference).

TEST(TriangleDistanceReferences, ClosedFormsAndSlicedSearchesAgreeOnWellConditionedInput) {
  Gen g(1);
  for (int k = 0; k < 300; ++k) {
    const Triangle t = g.triangle();
    const Vec p = g.point(2.0);
    const double a = std::sqrt(static_cast<double>(refPointTriangle(p, t)));
    const double b = std::sqrt(static_cast<double>(slicedPointTriangle(p, t)));
    ASSERT_NEAR(a, b, 1e-12) << "case " << k;
    const Vec s0 = g.point(), s1 = g.point(), s2 = g.point(), s3 = g.point();
    const double c = std::sqrt(static_cast<double>(refSegmentSegment(s0, s1, s2, s3)));
    const double d = std::sqrt(static_cast<double>(slicedSegmentSegment(s0, s1, s2, s3)));
    ASSERT_NEAR(c, d, 1e-12) << "case " << k;
  }
}

// ---------------------------------------------------------------------------------------------------------
// Point-triangle.

void checkPointTriangle(const Vec& p, const Triangle& t, double rel = kRel) {
  Vec c;
  const double d2 = cfl::pointTriangleSquaredDistance(p, t[0], t[1], t[2], &c);
  const double size = std::max((p - t[0]).norm(), std::max((t[1] - t[0]).norm(), (t[2] - t[0]).norm()));
  const double tol = rel * std::max(size, 1e-300);
  // Both references are attained values; each is accurate where the other may not be (the closed form's
  // interior solve on slivers), so the smaller one is the reference.
  const double ref =
      std::sqrt(static_cast<double>(std::min(refPointTriangle(p, t), slicedPointTriangle(p, t))));
  EXPECT_NEAR(std::sqrt(d2), ref, tol) << "vs the references";
  EXPECT_LE(std::sqrt(static_cast<double>(refPointTriangle(c, t))), tol) << "closest point off the triangle";
  EXPECT_NEAR((p - c).norm(), std::sqrt(d2), tol) << "closest point does not realise the distance";
}

TEST(PointTriangle, MatchesReferencesOnRandomTrianglesAndPoints) {
  Gen g(2);
  for (int k = 0; k < 2000; ++k) {
    SCOPED_TRACE(k);
    const Triangle t = g.triangle();
    checkPointTriangle(g.point(k % 4 == 0 ? 30.0 : 2.0), t);
  }
}

// Points built from the normal cone of each feature: p = x + (outward direction), so x is the projection of p
// by convex-analysis optimality, with no region test involved.
TEST(PointTriangle, ReturnsTheFeaturePointForPointsInEachVoronoiRegion) {
  Gen g(3);
  for (int k = 0; k < 500; ++k) {
    SCOPED_TRACE(k);
    const Triangle t = g.triangle();
    const Vec n = (t[1] - t[0]).cross(t[2] - t[0]).normalized();
    Vec out[3];  // outward in-plane normal of edge i = (t[i], t[i+1])
    for (int i = 0; i < 3; ++i) {
      const Vec e = t[(i + 1) % 3] - t[i];
      out[i] = e.cross(n).normalized();
      if (out[i].dot(t[(i + 2) % 3] - t[i]) > 0) out[i] = -out[i];
    }
    const double beta = g.uniform(-1, 1);
    Vec x, p;
    switch (k % 3) {
      case 0: {  // face
        const double u = g.uniform(0.01, 0.98), v = g.uniform(0.01, 0.99 - u);
        x = t[0] + u * (t[1] - t[0]) + v * (t[2] - t[0]);
        p = x + beta * n;
        break;
      }
      case 1: {  // edge interior
        const int i = g.index(3);
        x = t[i] + g.uniform(0.01, 0.99) * (t[(i + 1) % 3] - t[i]);
        p = x + g.uniform(0.01, 1) * out[i] + beta * n;
        break;
      }
      default: {  // vertex: its normal cone is spanned by the outward normals of its two edges
        const int i = g.index(3);
        x = t[i];
        p = x + g.uniform(0, 1) * out[i] + g.uniform(0, 1) * out[(i + 2) % 3] + beta * n;
        break;
      }
    }
    Vec c;
    const double d2 = cfl::pointTriangleSquaredDistance(p, t[0], t[1], t[2], &c);
    EXPECT_LE((c - x).norm(), 1e-12) << "closest point is not the feature point";
    EXPECT_NEAR(std::sqrt(d2), (p - x).norm(), 1e-12);
  }
}

TEST(PointTriangle, DegenerateTrianglesAreTheirSegmentOrPoint) {
  Gen g(4);
  for (int k = 0; k < 600; ++k) {
    SCOPED_TRACE(k);
    const Vec a = g.point(), b = g.point();
    Triangle t;
    switch (k % 6) {
      case 0: t = {a, b, a + g.uniform(-0.5, 1.5) * (b - a)}; break;  // collinear, third point on the line
      case 1: t = {a, a, b}; break;                                    // coincident corners
      case 2: t = {a, b, b}; break;
      case 3: t = {a, a, a}; break;  // a point
      case 4: t = {a, b, 0.5 * (a + b)}; break;
      default: {  // slivers: a cap of relative height 1e-7 .. 1e-15 (the ill-conditioned normal)
        const double h = std::pow(10.0, -g.uniform(7, 15));
        const Vec mid = a + g.uniform(0.2, 0.8) * (b - a);
        t = {a, b, mid + h * (b - a).norm() * (b - a).cross(g.direction()).normalized()};
        break;
      }
    }
    if (k % 2) std::swap(t[0], t[2]);
    checkPointTriangle(g.point(2.0), t);
    checkPointTriangle(t[0] + 1e-3 * g.point(), t);  // close to the degenerate triangle
  }
}

TEST(PointTriangle, NeedlesAndCapsOfEveryAspectRatio) {
  Gen g(5);
  for (int k = 0; k < 1000; ++k) {
    SCOPED_TRACE(k);
    const Vec a = g.point(), b = g.point();
    const double h = std::pow(10.0, -g.uniform(0, 14));
    Triangle t;
    if (k % 2) {  // needle: one edge of relative length h
      t = {a, b, b + h * (b - a).norm() * g.direction()};
    } else {  // cap: apex at relative height h over the middle of the long edge
      t = {a, b, 0.5 * (a + b) + h * (b - a).norm() * (b - a).cross(g.direction()).normalized()};
    }
    checkPointTriangle(g.point(2.0), t);
    // Points right above the interior, where the normal's direction matters most.
    checkPointTriangle((t[0] + t[1] + t[2]) / 3 + g.uniform(0.1, 2) * g.direction(), t);
  }
}

TEST(PointTriangle, ScaleAndOffsetDoNotChangeTheRelativeAccuracy) {
  Gen g(6);
  for (int k = 0; k < 300; ++k) {
    SCOPED_TRACE(k);
    Triangle t = g.triangle();
    Vec p = g.point(2.0);
    const double d = std::sqrt(cfl::pointTriangleSquaredDistance(p, t[0], t[1], t[2]));
    // Scaled down: relative accuracy is kept.
    const double s = 1e-6;
    const double ds = std::sqrt(cfl::pointTriangleSquaredDistance(s * p, s * t[0], s * t[1], s * t[2]));
    EXPECT_NEAR(ds, s * d, 1e-12 * s);
    // Scaled down and moved far away: the kernel works on differences, so against the reference evaluated on
    // the same (rounded) doubles it keeps ~1e-12 of the triangle size. Against the unmoved configuration the
    // rounding of the inputs themselves dominates: ulp(1e6) ~ 1.2e-10, i.e. 1e-4 of a 1e-6 triangle.
    const Vec o(1e6, -1e6, 1e6);
    const Triangle to = {s * t[0] + o, s * t[1] + o, s * t[2] + o};
    const Vec po = s * p + o;
    const double dof = std::sqrt(cfl::pointTriangleSquaredDistance(po, to[0], to[1], to[2]));
    // Reference on exact local differences (Sterbenz: nearby doubles subtract exactly).
    const Triangle tl = {to[0] - to[0], to[1] - to[0], to[2] - to[0]};
    const double ref = std::sqrt(static_cast<double>(refPointTriangle(po - to[0], tl)));
    EXPECT_NEAR(dof, ref, 1e-12 * s);
    EXPECT_NEAR(dof, s * d, 4 * std::sqrt(3.0) * 1.2e-10);
  }
}

// ---------------------------------------------------------------------------------------------------------
// Segment-segment.

void checkSegments(const Vec& p0, const Vec& p1, const Vec& q0, const Vec& q1) {
  Vec cp, cq;
  const double d2 = cfl::segmentSegmentSquaredDistance(p0, p1, q0, q1, &cp, &cq);
  double size = 0;
  for (const Vec* v : {&p0, &p1, &q0, &q1}) size = std::max(size, (*v - p0).norm());
  const double tol = kRel * std::max(size, 1e-300);
  const long double ref = std::min(refSegmentSegment(p0, p1, q0, q1), slicedSegmentSegment(p0, p1, q0, q1));
  EXPECT_NEAR(std::sqrt(d2), std::sqrt(static_cast<double>(ref)), tol) << "vs the references";
  EXPECT_LE(std::sqrt(static_cast<double>(refPointSegment(toL(cp), toL(p0), toL(p1) - toL(p0)))), tol);
  EXPECT_LE(std::sqrt(static_cast<double>(refPointSegment(toL(cq), toL(q0), toL(q1) - toL(q0)))), tol);
  EXPECT_NEAR((cp - cq).norm(), std::sqrt(d2), tol);
}

TEST(SegmentSegment, MatchesReferencesOnRandomSegments) {
  Gen g(7);
  for (int k = 0; k < 2000; ++k) {
    SCOPED_TRACE(k);
    checkSegments(g.point(), g.point(), g.point(), g.point());
  }
}

TEST(SegmentSegment, ParallelCollinearNearParallelAndZeroLength) {
  Gen g(8);
  for (int k = 0; k < 1500; ++k) {
    SCOPED_TRACE(k);
    const Vec a = g.point(), d = g.point();
    const Vec off = g.point() * (k % 3 == 0 ? 0.0 : 1.0);  // k % 3 == 0: collinear
    const double s0 = g.uniform(-2, 2), s1 = g.uniform(-2, 2);
    switch (k % 5) {
      case 0:
      case 1:  // parallel or collinear, overlapping or not, same or opposite direction
        checkSegments(a, a + d, a + s0 * d + off, a + s1 * d + off);
        break;
      case 2: {  // nearly parallel, angle 1e-3 .. 1e-15 rad, possibly crossing
        const double angle = std::pow(10.0, -g.uniform(3, 15));
        const Vec e = d + angle * d.norm() * g.direction();
        checkSegments(a, a + d, a + s0 * d + (k % 2 ? off * 1e-6 : off), a + s0 * d + (k % 2 ? off * 1e-6 : off) + e);
        break;
      }
      case 3:  // one zero length
        checkSegments(a, a, g.point(), g.point());
        checkSegments(g.point(), g.point(), a, a);
        break;
      default:  // both zero length
        checkSegments(a, a, a + off, a + off);
        break;
    }
  }
}

// ---------------------------------------------------------------------------------------------------------
// Triangle-triangle.

TEST(TriangleTriangle, MatchesReferenceOnRandomPairsAtManySeparations) {
  Gen g(9);
  int intersecting = 0;
  for (int k = 0; k < 1200; ++k) {
    SCOPED_TRACE(k);
    const double sep = std::array<double, 6>{0.0, 0.05, 0.3, 1.0, 2.0, 10.0}[k % 6];
    const Triangle p = g.triangle();
    Triangle q = g.triangle(g.uniform(0.05, 1.5));
    const Vec shift = sep * g.direction();
    for (Vec& v : q) v += shift;
    const double ref2 = static_cast<double>(referenceTriangleTriangle(p, q));
    if (checkPair(p, q, ref2, extent(p, q)) == 0) ++intersecting;
  }
  EXPECT_GT(intersecting, 60) << "the sample should contain many intersecting pairs";
}

TEST(TriangleTriangle, ParallelPlanesGiveThePlaneGapWhenProjectionsOverlap) {
  Gen g(10);
  for (int k = 0; k < 150; ++k) {
    SCOPED_TRACE(k);
    const Eigen::Matrix3d r = g.rotation();
    const Vec o = g.point();
    auto flat = [&](double z) {
      return Triangle{Vec(g.uniform(-1, 1), g.uniform(-1, 1), z), Vec(g.uniform(-1, 1), g.uniform(-1, 1), z),
                      Vec(g.uniform(-1, 1), g.uniform(-1, 1), z)};
    };
    const double gap = std::pow(10.0, -g.uniform(0, 8));
    const Triangle p = flat(0), q = flat(gap);
    // Axis-aligned (exact planes) and rotated (planes parallel only up to rounding).
    checkPair(p, q, static_cast<double>(referenceTriangleTriangle(p, q)), 1.0);
    const Triangle pr = transformed(p, r, o), qr = transformed(q, r, o);
    checkPair(pr, qr, static_cast<double>(referenceTriangleTriangle(pr, qr)), 2.0);
  }
}

TEST(TriangleTriangle, CoplanarSeparateTouchingAndOverlapping) {
  Gen g(11);
  int overlapping = 0, separate = 0;
  for (int k = 0; k < 300; ++k) {
    SCOPED_TRACE(k);
    const Eigen::Matrix3d r = g.rotation();
    const Vec o = g.point();
    auto flat = [&](double cx) {
      return Triangle{Vec(cx + g.uniform(-1, 1), g.uniform(-1, 1), 0), Vec(cx + g.uniform(-1, 1), g.uniform(-1, 1), 0),
                      Vec(cx + g.uniform(-1, 1), g.uniform(-1, 1), 0)};
    };
    const Triangle p = flat(0);
    Triangle q = flat(g.uniform(0, 3));
    if (k % 4 == 0) {  // touching: a vertex of Q on an edge of P
      const int i = g.index(3);
      q[0] = p[i] + g.uniform(0, 1) * (p[(i + 1) % 3] - p[i]);
    }
    const double d = checkPair(p, q, static_cast<double>(referenceTriangleTriangle(p, q)), 4.0);
    (d == 0 ? overlapping : separate)++;
    if (k % 4 == 0) {
      EXPECT_EQ(d, 0.0) << "touching coplanar triangles must be at distance exactly 0";
    }
    const Triangle pr = transformed(p, r, o), qr = transformed(q, r, o);
    checkPair(pr, qr, static_cast<double>(referenceTriangleTriangle(pr, qr)), 5.0);
  }
  EXPECT_GT(overlapping, 50);
  EXPECT_GT(separate, 50);
}

TEST(TriangleTriangle, TouchingAtAVertexOrAlongAnEdgeIsDistanceZero) {
  Gen g(12);
  for (int k = 0; k < 300; ++k) {
    SCOPED_TRACE(k);
    const Triangle p = g.triangle();
    const Vec n = (p[1] - p[0]).cross(p[2] - p[0]).normalized();
    Triangle q;
    switch (k % 4) {
      case 0:  // shared vertex, Q on one side of P's plane (a mesh fan)
        q = {p[0], p[0] + g.point() + 0.5 * n, p[0] + g.point() + 0.5 * n};
        break;
      case 1:  // shared edge (adjacent mesh triangles, any dihedral angle)
        q = {p[1], p[0], p[0] + g.point() + g.uniform(-1, 1) * n};
        break;
      case 2: {  // Q's vertex on P's interior, Q above
        const double u = g.uniform(0.05, 0.9), v = g.uniform(0.05, 0.95 - u);
        const Vec x = p[0] + u * (p[1] - p[0]) + v * (p[2] - p[0]);
        q = {x, x + g.point() + 1.5 * n, x + g.point() + 1.5 * n};
        break;
      }
      default: {  // crossing edges: Q's edge crosses P's edge, Q otherwise on one side
        const Vec x = p[0] + g.uniform(0.1, 0.9) * (p[1] - p[0]);
        const Vec dir = (p[1] - p[0]).cross(n).normalized() + g.uniform(-0.5, 0.5) * n;
        q = {x - 0.5 * dir, x + 0.7 * dir, x + g.point() + 1.5 * n};
        q[2] = x + 2.0 * (q[2] - x).dot(n) * n + 0.3 * g.point();
        break;
      }
    }
    const double d = checkPair(p, q, static_cast<double>(referenceTriangleTriangle(p, q)), extent(p, q));
    if (k % 4 != 3) {
      EXPECT_EQ(d, 0.0) << "triangles sharing a point must be at distance exactly 0";
    }
  }
}

TEST(TriangleTriangle, PiercingChainLinkPairsIntersectAtACommonPoint) {
  Gen g(13);
  for (int k = 0; k < 500; ++k) {
    SCOPED_TRACE(k);
    // P in the plane z = 0 around the origin, Q in a vertical plane whose edge crosses P's interior, with
    // neither triangle's vertices near the other: only edge-face crossings can find the contact.
    const Triangle p = {Vec(-1, -1, 0), Vec(1.5, -0.8, 0), Vec(-0.5, 1.2, 0)};
    const double x0 = g.uniform(-0.3, 0.3), y0 = g.uniform(-0.3, 0.3);
    const double tilt = g.uniform(-0.5, 0.5);
    const Triangle q0 = {Vec(x0, y0 - 2, 0.3 + tilt), Vec(x0, y0, -g.uniform(0.1, 1)), Vec(x0, y0 + 2, 0.3 - tilt)};
    const Eigen::Matrix3d r = g.rotation();
    const Vec o = g.point();
    for (const auto& pq : {std::make_pair(p, q0), std::make_pair(transformed(p, r, o), transformed(q0, r, o))}) {
      const double d = checkPair(pq.first, pq.second, 0.0, 3.0);
      EXPECT_EQ(d, 0.0);
    }
  }
}

TEST(TriangleTriangle, DegenerateTrianglesOnEitherSide) {
  Gen g(14);
  for (int k = 0; k < 350; ++k) {
    SCOPED_TRACE(k);
    const Vec a = g.point(), b = g.point();
    Triangle deg;
    switch (k % 5) {
      case 0: deg = {a, b, a + g.uniform(0, 1) * (b - a)}; break;
      case 1: deg = {a, a, b}; break;
      case 2: deg = {a, a, a}; break;
      case 3: deg = {a, b, a + g.uniform(-1, 2) * (b - a)}; break;
      default: {
        const double h = std::pow(10.0, -g.uniform(6, 16));
        deg = {a, b, 0.5 * (a + b) + h * (b - a).cross(g.direction())};
        break;
      }
    }
    Triangle other = g.triangle();
    if (k % 7 == 0) {  // a segment-like triangle piercing the other's interior
      const Vec c = (other[0] + other[1] + other[2]) / 3;
      const Vec n = (other[1] - other[0]).cross(other[2] - other[0]).normalized();
      deg = {c - 0.5 * n, c + 0.5 * n, c + g.uniform(-0.5, 0.5) * n};
    }
    const Triangle* pairs[2][2] = {{&deg, &other}, {&other, &deg}};
    for (auto& pq : pairs) {
      checkPair(*pq[0], *pq[1], static_cast<double>(referenceTriangleTriangle(*pq[0], *pq[1])),
                extent(*pq[0], *pq[1]));
    }
    // Both degenerate.
    const Triangle seg = {b, g.point(), b};
    checkPair(deg, seg, static_cast<double>(referenceTriangleTriangle(deg, seg)), extent(deg, seg));
  }
}

TEST(TriangleTriangle, IntersectionTestAgreesWithDistanceUnderRounding) {
  // Configurations at the edge of touching, where floating point decides: the contract is that
  // trianglesIntersect is true exactly when the distance is 0, and a positive distance above the touching
  // tolerance never comes with an intersection.
  Gen g(15);
  for (int k = 0; k < 3000; ++k) {
    SCOPED_TRACE(k);
    const Triangle p = g.triangle();
    Triangle q = g.triangle();
    // Move Q until it just touches P (bisection on the separation along a random direction).
    const Vec dir = g.direction();
    double lo = 0, hi = 8;
    for (int it = 0; it < 60; ++it) {
      const double mid = 0.5 * (lo + hi);
      Triangle qm = q;
      for (Vec& v : qm) v += mid * dir;
      (cfl::trianglesIntersect(p.data(), qm.data()) ? lo : hi) = mid;
    }
    for (double t : {lo, hi, 0.5 * (lo + hi), hi + 1e-12, lo - 1e-12}) {
      Triangle qt = q;
      for (Vec& v : qt) v += t * dir;
      Vec x;
      const bool hit = cfl::trianglesIntersect(p.data(), qt.data(), &x);
      const double d2 = cfl::triangleTriangleSquaredDistance(p.data(), qt.data());
      EXPECT_EQ(hit, d2 == 0.0) << "t " << t << " d2 " << d2;
      if (d2 > 1e-24) {
        EXPECT_FALSE(hit);
      }
    }
  }
}

TEST(TriangleTriangle, ScaleInvarianceAndHonestAccuracyFarFromTheOrigin) {
  Gen g(16);
  for (int k = 0; k < 150; ++k) {
    SCOPED_TRACE(k);
    const Triangle p = g.triangle();
    Triangle q = g.triangle();
    const Vec shift = (k % 3) * 0.3 * g.direction();
    for (Vec& v : q) v += shift;
    const double d = std::sqrt(cfl::triangleTriangleSquaredDistance(p.data(), q.data()));

    // Scaled by 1e-6: everything is relative, so the relative accuracy is unchanged.
    const double s = 1e-6;
    const Triangle ps = transformed(p, s * Eigen::Matrix3d::Identity(), Vec::Zero());
    const Triangle qs = transformed(q, s * Eigen::Matrix3d::Identity(), Vec::Zero());
    const double ds = checkPair(ps, qs, static_cast<double>(referenceTriangleTriangle(ps, qs)), s);
    EXPECT_NEAR(ds, s * d, 1e-12 * s);

    // Scaled by 1e-6 and moved to 1e6. The distance works on differences of nearby inputs, which are exact,
    // so against a reference on the same doubles it keeps 1e-12 of the triangle size. Closest points are
    // absolute coordinates and carry ulp(1e6) ~ 1.2e-10 of rounding (1e-4 of a 1e-6 triangle). Against the
    // configuration before the move, the rounding of the inputs by the move itself (0.5 ulp per coordinate)
    // is what separates the two.
    const Vec o(1e6, 1e6, -1e6);
    const Triangle po = transformed(ps, Eigen::Matrix3d::Identity(), o);
    const Triangle qo = transformed(qs, Eigen::Matrix3d::Identity(), o);
    Vec cp, cq;
    const double d2o = cfl::triangleTriangleSquaredDistance(po.data(), qo.data(), &cp, &cq);
    const Triangle pl = transformed(po, Eigen::Matrix3d::Identity(), -po[0]);  // exact local frame
    const Triangle ql = transformed(qo, Eigen::Matrix3d::Identity(), -po[0]);
    const double ref = std::sqrt(static_cast<double>(referenceTriangleTriangle(pl, ql)));
    EXPECT_NEAR(std::sqrt(d2o), ref, 1e-12 * s);
    EXPECT_NEAR(std::sqrt(d2o), s * d, 2 * std::sqrt(3.0) * 1.2e-10);
    const double ulp = 1.2e-10;
    EXPECT_LE(std::sqrt(static_cast<double>(refPointTriangle(cp - po[0], pl))), 2 * ulp);
    EXPECT_LE(std::sqrt(static_cast<double>(refPointTriangle(cq - po[0], ql))), 2 * ulp);
    EXPECT_EQ(cfl::trianglesIntersect(po.data(), qo.data()), d2o == 0.0);
  }
}

}  // namespace
