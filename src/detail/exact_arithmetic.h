#pragma once
// Internal: error-free transformations (Knuth, Dekker; see Shewchuk 1997) and the triangle normal they make
// accurate. Shared by the distance kernels and by the mesh model's planes, which must agree on how far a
// thin triangle's normal can be trusted.

#include <Eigen/Core>

#include <cmath>

// These rely on IEEE double rounding as written; -ffast-math would reassociate them into wrong answers.
#if defined(__FAST_MATH__)
#error "cfl must be compiled without -ffast-math: its exact queries rely on IEEE double rounding"
#endif

namespace cfl::detail {

// A value as an unevaluated sum hi + lo.
struct TwoDouble {
  double hi, lo;
};

// a - b exactly.
inline TwoDouble twoDiff(double a, double b) {
  const double s = a - b;
  const double bv = s - a;
  const double av = s - bv;
  return {s, (a - av) - (b + bv)};
}

// a b exactly.
inline TwoDouble twoProduct(double a, double b) {
  const double p = a * b;
#ifdef FP_FAST_FMA
  return {p, std::fma(a, b, -p)};
#else
  // Without hardware FMA the compiler cannot contract these products, so Dekker's split is exact.
  constexpr double kSplit = 134217729.0;  // 2^27 + 1
  const double ca = kSplit * a, cb = kSplit * b;
  const double ah = ca - (ca - a), al = a - ah;
  const double bh = cb - (cb - b), bl = b - bh;
  return {p, ((ah * bh - p) + ah * bl + al * bh) + al * bl};
#endif
}

// x y - z w for two-double x, y, z, w, rounded once at the end: about eps^2 of |x y| + |z w| beyond the final
// rounding.
inline double crossTerm(const TwoDouble& x, const TwoDouble& y, const TwoDouble& z, const TwoDouble& w) {
  const TwoDouble p = twoProduct(x.hi, y.hi);
  const TwoDouble q = twoProduct(z.hi, w.hi);
  const double p_lo = p.lo + (x.hi * y.lo + x.lo * y.hi);
  const double q_lo = q.lo + (z.hi * w.lo + z.lo * w.hi);
  const TwoDouble d = twoDiff(p.hi, q.hi);
  return d.hi + (d.lo + (p_lo - q_lo));
}

// (v[1] - v[0]) x (v[2] - v[0]), correct to a few eps in direction however thin the triangle (down to
// relative heights of ~1e-14), wherever it sits: exact edge vectors as two-doubles, products to twice the
// working precision. The plain double cross product errs by about eps / sin(smallest angle) in direction,
// plus eps |corner| / |edge| for a triangle far from the origin.
inline Eigen::Vector3d accurateNormal(const Eigen::Vector3d* v) {
  TwoDouble a[3], b[3];
  for (int i = 0; i < 3; ++i) {
    a[i] = twoDiff(v[1][i], v[0][i]);
    b[i] = twoDiff(v[2][i], v[0][i]);
  }
  return Eigen::Vector3d(crossTerm(a[1], b[2], a[2], b[1]), crossTerm(a[2], b[0], a[0], b[2]),
                         crossTerm(a[0], b[1], a[1], b[0]));
}

}  // namespace cfl::detail
