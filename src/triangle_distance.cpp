// Exact point / segment / triangle distance kernels.
//
// Numerical design (why the code looks the way it does):
// - Every distance is computed from differences of nearby inputs (p - a, x0 - y0, ...), never from absolute
//   coordinates, so a configuration far from the origin loses nothing beyond the rounding of its own inputs.
// - Point-triangle uses the triangle normal n and the in-plane inward edge normals m_i = n x e_i instead of the
//   barycentric dot-product formulas (Ericson's va/vb/vc). The region test m_i . (p - v_i) then errs by about
//   eps |p - v_i| in the plane; the dot-product formulas err by eps |p - a|^2 / (size * sin(angle)), which is
//   far worse for points far from small triangles (voxel centres of a coarse grid).
// - The normal of a sliver triangle is ill-conditioned in double: its direction errs by about
//   eps / sin(angle). For angles below 1e-2 rad the normal is recomputed in twice the working precision
//   (error-free transformations), which keeps it accurate down to relative heights of ~1e-14; below that the
//   triangle is treated as the segment it nearly is, which errs by at most its height. The remaining
//   direction error of the normal is tracked (Tri::nerr2) and widens the plane-side and touching tolerances.
// - Segment-segment uses the closed form (Ericson, Real-Time Collision Detection, 5.1.9) when the segments are
//   far from parallel, and the cross-product form of the same line parameter, whose error is second order in
//   the direction error, when they are nearly parallel.
// - Triangle-triangle: min over the 6 vertex-face and 9 edge-edge pairs. The vertex of each triangle nearest
//   the other's plane goes first; a pair is skipped when its plane-distance lower bound is no better than the
//   best so far; the search stops as soon as the best pair is certified optimal (P behind, Q in front of the
//   planes normal to the connecting vector), which for random separated pairs is after ~3 kernel calls.
//   Triangles whose planes do not separate them first get edge-crossing tests (6 at most), so intersecting
//   triangles report distance 0 and a common point; contacts within the touching tolerance (64 eps of the
//   size, plus the normals' direction error) are 0 too. trianglesIntersect runs the same decision code, so
//   the two functions always agree.

#include "cfl/triangle_distance.h"

#include "detail/exact_arithmetic.h"

#include <Eigen/Geometry>

#include <algorithm>
#include <cmath>
#include <limits>

namespace cfl {
namespace {

using Vec = Eigen::Vector3d;

constexpr double kEps = std::numeric_limits<double>::epsilon();
// Below this sin^2 of the corner angle the double normal (direction error ~ 4 eps / sin) is replaced by one
// computed in twice the working precision.
constexpr double kFastSin2 = 1e-4;
// Below this sin^2 the triangle is treated as its three edges, which errs by at most its height, 1e-14 of
// its size; above it the accurate normal errs by about eps^2 / sin << eps in direction.
constexpr double kDegenerateSin2 = 1e-28;
// Segments closer to parallel than this sin^2 use the cross-product form of the line parameter.
constexpr double kNearParallelSin2 = 1e-4;
// Below this sin^2 even the cross-product form is noise; any parameter is within size * sin of optimal.
constexpr double kParallelSin2 = 1e-24;
// Two triangles closer than this fraction of their largest edge are touching: distance 0. Well above the
// rounding of the feature distances (a few eps of the size), far below any tolerance a user can ask for.
constexpr double kTouchRel = 64.0 * kEps;

#if defined(__GNUC__)
#define CFL_HOT_INLINE inline __attribute__((always_inline))
#define CFL_LAMBDA_INLINE __attribute__((always_inline))
#else
#define CFL_HOT_INLINE inline
#define CFL_LAMBDA_INLINE
#endif

inline double clamp01(double x) { return x < 0.0 ? 0.0 : (x > 1.0 ? 1.0 : x); }

// A triangle with the derived quantities every kernel needs. e[i] = v[i+1] - v[i]; m[i] = n x e[i] points into
// the triangle; the normal n = e[k-1] x e[k] for any corner k (same vector, different rounding).
struct Tri {
  const Vec* v;
  Vec e[3];
  double e2[3];
  Vec n;
  double nn;
  double nerr2;  // bound on the squared direction error of n, in radians^2
  bool degenerate;
  bool has_m;  // m is set
  Vec m[3];
};

// Fills everything but m.
inline void initTri(const Vec* v, Tri& t) {
  t.v = v;
  t.has_m = false;
  t.e[0] = v[1] - v[0];
  t.e[1] = v[2] - v[1];
  t.e[2] = v[0] - v[2];
  t.e2[0] = t.e[0].squaredNorm();
  t.e2[1] = t.e[1].squaredNorm();
  t.e2[2] = t.e[2].squaredNorm();
  t.n = t.e[2].cross(t.e[0]);
  t.nn = t.n.squaredNorm();
  // Strict, so that a point triangle (0 > 0) and NaN input take the careful path and end up degenerate.
  const double scale = t.e2[0] * t.e2[2];
  if (t.nn > kFastSin2 * scale) {
    t.nerr2 = -1.0;  // computed by normalError2() when needed
    t.degenerate = false;
  } else {
    t.n = detail::accurateNormal(v);
    t.nn = t.n.squaredNorm();
    t.nerr2 = 16.0 * kEps * kEps;
    const double m2 = std::max({t.e2[0], t.e2[1], t.e2[2]});
    // sin^2 of the largest angle = nn / (product of its two edges), which are the two shortest edges.
    const double short_product = t.e2[0] * t.e2[1] * t.e2[2] / m2;
    t.degenerate = !(t.nn > kDegenerateSin2 * short_product);
  }
}

// Bound on the squared direction error of t.n (radians^2): for the plain cross product, the rounding of the
// edges and of the products relative to |n| = |e0| |e2| sin, i.e. (4 eps (1 + 1/sin))^2 <= 32 eps^2 (1 + 1/sin^2).
inline double normalError2(const Tri& t) {
  return t.nerr2 >= 0.0 ? t.nerr2 : 32.0 * kEps * kEps * (1.0 + t.e2[0] * t.e2[2] / t.nn);
}

inline void initEdgeNormals(Tri& t) {
  if (t.degenerate || t.has_m) return;
  t.has_m = true;
  t.m[0] = t.n.cross(t.e[0]);
  t.m[1] = t.n.cross(t.e[1]);
  t.m[2] = t.n.cross(t.e[2]);
}

// Squared distance from p to segment a + s e, s in [0, 1] (e2 = e.e, may be 0); s and the offset p - closest.
CFL_HOT_INLINE double pointSegment(const Vec& p, const Vec& a, const Vec& e, double e2, double* s_out) {
  const Vec d = p - a;
  double s = e.dot(d);
  if (s <= 0.0) {
    s = 0.0;
  } else if (s >= e2) {
    s = 1.0;
  } else {
    s /= e2;
  }
  *s_out = s;
  return (d - s * e).squaredNorm();
}

// Point-triangle on a prepared triangle (initEdgeNormals done). `in_face` tells whether the closest point is
// interior to the face region (the projection of p lies inside the triangle).
CFL_HOT_INLINE double pointTri(const Tri& t, const Vec& p, Vec* closest, bool* in_face) {
  *in_face = false;
  int mask = 7;
  if (!t.degenerate) {
    const Vec d0 = p - t.v[0];
    const double s0 = t.m[0].dot(d0);
    const double s1 = t.m[1].dot(p - t.v[1]);
    const double s2 = t.m[2].dot(p - t.v[2]);
    if (s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0) {
      const double h = t.n.dot(d0);
      const double k = h / t.nn;
      if (closest) *closest = p - k * t.n;
      *in_face = true;
      return h * k;
    }
    // The closest boundary point lies on an edge whose line separates p from the triangle.
    mask = (s0 < 0.0 ? 1 : 0) | (s1 < 0.0 ? 2 : 0) | (s2 < 0.0 ? 4 : 0);
    if (mask == 0) mask = 7;  // NaN
  }
  double best = std::numeric_limits<double>::infinity();
  int best_i = 0;
  double best_s = 0.0;
  for (int i = 0; i < 3; ++i) {
    if (!(mask & (1 << i))) continue;
    double s;
    const double d2 = pointSegment(p, t.v[i], t.e[i], t.e2[i], &s);
    if (d2 < best || i == best_i) {  // i == best_i keeps NaN results from leaving best_s unset
      best = d2;
      best_i = i;
      best_s = s;
    }
  }
  if (closest) *closest = t.v[best_i] + best_s * t.e[best_i];
  return best;
}

// Squared distance between segments x0 + s dx and y0 + t dy, s, t in [0, 1]; dx2 = dx.dx, dy2 = dy.dy.
CFL_HOT_INLINE double segSeg(const Vec& x0, const Vec& dx, double dx2, const Vec& y0, const Vec& dy, double dy2,
                     double* s_out, double* t_out) {
  const Vec r = x0 - y0;
  const double f = dy.dot(r);
  double s, t;
  if (dx2 <= 0.0) {
    s = 0.0;
    t = dy2 <= 0.0 ? 0.0 : clamp01(f / dy2);
  } else {
    const double c = dx.dot(r);
    if (dy2 <= 0.0) {
      t = 0.0;
      s = clamp01(-c / dx2);
    } else {
      const double b = dx.dot(dy);
      const double scale = dx2 * dy2;
      const double denom = scale - b * b;
      if (denom > kNearParallelSin2 * scale) {
        s = clamp01((b * f - c * dy2) / denom);
      } else {
        // b f - c dy2 = (dx x dy) . (dy x r) and denom = |dx x dy|^2 (Lagrange). In this form an error in the
        // direction of dx x dy rotates the plane through line y in which s is sought, which moves the distance
        // only to second order.
        const Vec cr = dx.cross(dy);
        const double cc = cr.squaredNorm();
        s = cc > kParallelSin2 * scale ? clamp01(cr.dot(dy.cross(r)) / cc) : 0.0;
      }
      t = (b * s + f) / dy2;
      if (t < 0.0) {
        t = 0.0;
        s = clamp01(-c / dx2);
      } else if (t > 1.0) {
        t = 1.0;
        s = clamp01((b - c) / dx2);
      }
    }
  }
  *s_out = s;
  *t_out = t;
  return (r + s * dx - t * dy).squaredNorm();
}

// Whether x (assumed near the plane of t) lies in the closed triangle t (not degenerate, edge normals set).
inline bool insideTri(const Tri& t, const Vec& x) {
  return t.m[0].dot(x - t.v[0]) >= 0.0 && t.m[1].dot(x - t.v[1]) >= 0.0 && t.m[2].dot(x - t.v[2]) >= 0.0;
}

// Finds an edge of a that crosses the closed triangle b; da[i] = b.n . (a.v[i] - b.v[0]).
inline bool edgeCrossesTri(const Tri& a, const double* da, const Tri& b, Vec* point) {
  for (int i = 0; i < 3; ++i) {
    const double d0 = da[i], d1 = da[(i + 1) % 3];
    if ((d0 > 0.0 && d1 > 0.0) || (d0 < 0.0 && d1 < 0.0) || (d0 == 0.0 && d1 == 0.0)) continue;
    // Opposite signs (or one zero): |d0| <= |d0 - d1|, so the crossing stays on the edge.
    const double s = d0 / (d0 - d1);
    const Vec x = a.v[i] + s * a.e[i];
    if (insideTri(b, x)) {
      if (point) *point = x;
      return true;
    }
  }
  return false;
}

// The prepared pair: both triangles, the signed plane distances (unnormalised), and which side is separated.
struct Pair {
  Tri P, Q;
  double dp[3];   // Q.n . (p_i - q_0), valid if !Q.degenerate
  double dq[3];   // P.n . (q_j - p_0), valid if !P.degenerate
  bool sep_p;     // P lies strictly on one side of Q's plane, by more than the touching tolerance
  bool sep_q;
  double touch2;  // squared touching tolerance
  double size2;   // squared longest edge of the two triangles
};

// d[i] = t.n . (x[i] - t.v[0]); returns whether all three x lie strictly on one side of t's plane, each by more
// than the touching tolerance plus what the normal's direction error can move it (|x[i] - t.v[0]| times the direction error).
inline bool planeDistances(const Vec* x, const Tri& t, double touch2, double* d) {
  Vec r[3];
  for (int i = 0; i < 3; ++i) {
    r[i] = x[i] - t.v[0];
    d[i] = t.n.dot(r[i]);
  }
  const bool one_side = (d[0] > 0.0 && d[1] > 0.0 && d[2] > 0.0) || (d[0] < 0.0 && d[1] < 0.0 && d[2] < 0.0);
  if (!one_side) return false;
  const double e2 = t.nerr2;
  for (int i = 0; i < 3; ++i) {
    // (a + b)^2 <= 2 a^2 + 2 b^2
    if (!(d[i] * d[i] > 2.0 * (touch2 + e2 * r[i].squaredNorm()) * t.nn)) return false;
  }
  return true;
}

inline void initPair(const Vec p[3], const Vec q[3], Pair& pr) {
  initTri(p, pr.P);
  initTri(q, pr.Q);
  const double l2 = std::max({pr.P.e2[0], pr.P.e2[1], pr.P.e2[2], pr.Q.e2[0], pr.Q.e2[1], pr.Q.e2[2]});
  // The feature distances of touching triangles err by a few eps of the size plus the normals' direction
  // error times the size.
  pr.P.nerr2 = normalError2(pr.P);
  pr.Q.nerr2 = normalError2(pr.Q);
  // touch = kTouchRel + 4 nerr, squared with (a + b)^2 <= 2 a^2 + 2 b^2.
  pr.touch2 = 2.0 * (kTouchRel * kTouchRel + 16.0 * std::max(pr.P.nerr2, pr.Q.nerr2)) * l2;
  pr.size2 = l2;
  pr.sep_p = !pr.Q.degenerate && planeDistances(p, pr.Q, pr.touch2, pr.dp);
  pr.sep_q = !pr.P.degenerate && planeDistances(q, pr.P, pr.touch2, pr.dq);
}

// Minimum over the 6 vertex-face and 9 edge-edge pairs. Stops as soon as a pair is within `stop2` (pass -1
// to never stop early). Exact for disjoint triangles; for intersecting ones it is only an upper bound.
double featureDistance(Pair& pr, double stop2, Vec* cp, Vec* cq) {
  Tri& P = pr.P;
  Tri& Q = pr.Q;
  const Vec* p = P.v;
  const Vec* q = Q.v;
  // Lower bounds from the planes: a vertex (edge) of P on one side of Q's plane is at least its plane distance
  // from anything in Q.
  double lb_pv[3] = {0, 0, 0}, lb_qv[3] = {0, 0, 0}, lb_pe[3] = {0, 0, 0}, lb_qe[3] = {0, 0, 0};
  if (!Q.degenerate) {
    const double inv = 1.0 / Q.nn;
    for (int i = 0; i < 3; ++i) lb_pv[i] = pr.dp[i] * pr.dp[i] * inv;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      if (pr.dp[i] * pr.dp[j] > 0.0) lb_pe[i] = std::min(lb_pv[i], lb_pv[j]);
    }
  }
  if (!P.degenerate) {
    const double inv = 1.0 / P.nn;
    for (int i = 0; i < 3; ++i) lb_qv[i] = pr.dq[i] * pr.dq[i] * inv;
    for (int i = 0; i < 3; ++i) {
      const int j = (i + 1) % 3;
      if (pr.dq[i] * pr.dq[j] > 0.0) lb_qe[i] = std::min(lb_qv[i], lb_qv[j]);
    }
  }

  double best = std::numeric_limits<double>::infinity();
  Vec bp = p[0], bq = q[0];
  bool done_pv[3] = {false, false, false}, done_qv[3] = {false, false, false};

  // Certificate of optimality for the current pair (bp, bq): with v = bq - bp, all of P behind the plane through
  // bp normal to v and all of Q in front of the parallel plane through bq means nothing is closer than |v|.
  // Checking the six vertices suffices (convexity). The slack admits rounding; it can accept a pair that is
  // at most 2 kTouchRel * size too far.
  const double slack2 = pr.size2 * (kTouchRel * kTouchRel);
  auto optimal = [&]() CFL_LAMBDA_INLINE {
    const Vec v = bq - bp;
    const double limit = slack2 * v.squaredNorm();
    for (int i = 0; i < 3; ++i) {
      const double a = v.dot(p[i] - bp);
      if (a > 0.0 && a * a > limit) return false;
      const double b = v.dot(q[i] - bq);
      if (b < 0.0 && b * b > limit) return false;
    }
    return true;
  };

  // The vertex of each triangle nearest the other's plane first: if a triangle is on one side of the other's
  // plane and that vertex projects into the other, the plane distance is both a lower bound and attained.
  {
    const int k = lb_pv[0] <= lb_pv[1] ? (lb_pv[0] <= lb_pv[2] ? 0 : 2) : (lb_pv[1] <= lb_pv[2] ? 1 : 2);
    Vec c;
    bool face;
    const double d2 = (initEdgeNormals(Q), pointTri(Q, p[k], &c, &face));
    done_pv[k] = true;
    best = d2;
    bp = p[k];
    bq = c;
    if ((face && pr.sep_p) || best <= stop2 || optimal()) goto finish;
  }
  {
    const int k = lb_qv[0] <= lb_qv[1] ? (lb_qv[0] <= lb_qv[2] ? 0 : 2) : (lb_qv[1] <= lb_qv[2] ? 1 : 2);
    Vec c;
    bool face;
    const double d2 = (initEdgeNormals(P), pointTri(P, q[k], &c, &face));
    done_qv[k] = true;
    if (d2 < best) {
      best = d2;
      bp = c;
      bq = q[k];
      if ((face && pr.sep_q) || best <= stop2) goto finish;
    }
    if (optimal()) goto finish;
  }
  for (int i = 0; i < 3; ++i) {
    for (int j = 0; j < 3; ++j) {
      if (std::max(lb_pe[i], lb_qe[j]) >= best) continue;
      double s, t;
      const double d2 = segSeg(p[i], P.e[i], P.e2[i], q[j], Q.e[j], Q.e2[j], &s, &t);
      if (d2 < best) {
        best = d2;
        bp = p[i] + s * P.e[i];
        bq = q[j] + t * Q.e[j];
        if (best <= stop2 || optimal()) goto finish;
      }
    }
  }
  // In exact arithmetic only the vertex nearest the other plane can be a vertex-face optimum (moving from any
  // other vertex towards it lowers the plane distance before leaving the face's prism); the others are kept,
  // behind their lower bounds, for near-ties under rounding and for degenerate partners.
  for (int k = 0; k < 3; ++k) {
    if (!done_pv[k] && lb_pv[k] < best) {
      Vec c;
      bool face;
      const double d2 = (initEdgeNormals(Q), pointTri(Q, p[k], &c, &face));
      if (d2 < best) {
        best = d2;
        bp = p[k];
        bq = c;
        if (best <= stop2) goto finish;
      }
    }
    if (!done_qv[k] && lb_qv[k] < best) {
      Vec c;
      bool face;
      const double d2 = (initEdgeNormals(P), pointTri(P, q[k], &c, &face));
      if (d2 < best) {
        best = d2;
        bp = c;
        bq = q[k];
        if (best <= stop2) goto finish;
      }
    }
  }
finish:
  if (cp) *cp = bp;
  if (cq) *cq = bq;
  return best;
}

// For triangles not separated by a plane: whether they intersect or touch. Shared by
// triangleTriangleSquaredDistance and trianglesIntersect so that both take the same decision. If they do,
// *x is a common point; if not, *d2 is the full feature distance with its closest points (computed here once).
bool intersectOrTouch(Pair& pr, Vec* x, double* d2, Vec* cp, Vec* cq) {
  initEdgeNormals(pr.P);
  initEdgeNormals(pr.Q);
  if (!pr.Q.degenerate && edgeCrossesTri(pr.P, pr.dp, pr.Q, x)) return true;
  if (!pr.P.degenerate && edgeCrossesTri(pr.Q, pr.dq, pr.P, x)) return true;
  // Coplanar overlap, contact within rounding, or degenerate triangles: some feature pair is (nearly) at
  // distance 0. featureDistance only stops early below touch2, so above it *d2 is the exact minimum.
  Vec a, b;
  *d2 = featureDistance(pr, pr.touch2, &a, &b);
  if (*d2 <= pr.touch2) {
    *x = 0.5 * (a + b);
    return true;
  }
  if (cp) *cp = a;
  if (cq) *cq = b;
  return false;
}

}  // namespace

double pointTriangleSquaredDistance(const Vec& p, const Vec& a, const Vec& b, const Vec& c, Vec* closest) {
  // The same computation as pointTri, written for one query: no edge normals are stored, each region test is
  // a triple product n . (e_i x (p - v_i)) = m_i . (p - v_i).
  const Vec ab = b - a, ac = c - a;
  const Vec n = ab.cross(ac);
  const double nn = n.squaredNorm();
  if (nn > kFastSin2 * ab.squaredNorm() * ac.squaredNorm()) {
    const Vec ap = p - a;
    const Vec bc = c - b;
    const double s0 = n.dot(ab.cross(ap));
    const double s1 = n.dot(bc.cross(p - b));
    const double s2 = n.dot(ap.cross(ac));  // (a - c) x (p - c) = ap x ac
    if (s0 >= 0.0 && s1 >= 0.0 && s2 >= 0.0) {
      const double h = n.dot(ap);
      const double k = h / nn;
      if (closest) *closest = p - k * n;
      return h * k;
    }
    // The closest boundary point lies on an edge whose line separates p from the triangle.
    double best = std::numeric_limits<double>::infinity(), t = 0.0;
    const Vec* start = &a;
    const Vec* dir = &ab;
    if (!(s0 >= 0.0)) {
      best = pointSegment(p, a, ab, ab.squaredNorm(), &t);
    }
    if (!(s1 >= 0.0)) {
      double u;
      const double d2 = pointSegment(p, b, bc, bc.squaredNorm(), &u);
      if (!(d2 >= best)) {
        best = d2;
        t = u;
        start = &b;
        dir = &bc;
      }
    }
    if (!(s2 >= 0.0)) {
      // Edge c -> a as a + u (c - a) reversed: the same segment.
      double u;
      const double d2 = pointSegment(p, a, ac, ac.squaredNorm(), &u);
      if (!(d2 >= best)) {
        best = d2;
        t = u;
        start = &a;
        dir = &ac;
      }
    }
    if (closest) *closest = *start + t * *dir;
    return best;
  }
  const Vec v[3] = {a, b, c};
  Tri tri;
  initTri(v, tri);
  initEdgeNormals(tri);
  bool face;
  return pointTri(tri, p, closest, &face);
}

double segmentSegmentSquaredDistance(const Vec& p0, const Vec& p1, const Vec& q0, const Vec& q1, Vec* closest_p,
                                     Vec* closest_q) {
  const Vec dp = p1 - p0;
  const Vec dq = q1 - q0;
  double s, t;
  const double d2 = segSeg(p0, dp, dp.squaredNorm(), q0, dq, dq.squaredNorm(), &s, &t);
  if (closest_p) *closest_p = p0 + s * dp;
  if (closest_q) *closest_q = q0 + t * dq;
  return d2;
}

double triangleTriangleSquaredDistance(const Vec p[3], const Vec q[3], Vec* closest_p, Vec* closest_q) {
  Pair pr;
  initPair(p, q, pr);
  if (pr.sep_p || pr.sep_q) return featureDistance(pr, -1.0, closest_p, closest_q);
  Vec x;
  double d2;
  if (intersectOrTouch(pr, &x, &d2, closest_p, closest_q)) {
    if (closest_p) *closest_p = x;
    if (closest_q) *closest_q = x;
    return 0.0;
  }
  return d2;
}

bool trianglesIntersect(const Vec p[3], const Vec q[3], Vec* point) {
  Pair pr;
  initPair(p, q, pr);
  if (pr.sep_p || pr.sep_q) return false;
  Vec x;
  double d2;
  if (!intersectOrTouch(pr, &x, &d2, nullptr, nullptr)) return false;
  if (point) *point = x;
  return true;
}

}  // namespace cfl
