// The sections of `cfl bench` for the queries other than mesh-mesh distance: points (--points), primitive
// shapes (--shapes) and mesh-mesh penetration (--penetration), each against FCL 0.7 on A's OBBRSS twin in
// the same run. The core's API is timed here (no FCL adapter: the cfl tool does not link it); the same
// queries through unmodified fcl::distance are timed by cfl_shape_bench.

#include "bench_sections.h"

#include "cfl/box_query.h"
#include "cfl/penetration.h"
#include "cfl/point_query.h"
#include "cfl/segment_query.h"
#include "cfl/triangle_distance.h"
#include "point_sets.h"
#include "shape_reference.h"
#include "tool_support.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <ostream>
#include <random>

namespace cfl::tool {
namespace {

const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();

// Distance from p to the nearest triangle of the mesh, over all triangles: the referee where CFL and FCL
// disagree.
double bruteForcePointDistance(const MeshModel& mesh, const Eigen::Vector3d& p) {
  double best = INFINITY;
  for (const auto& c : mesh.corners.in_leaf_order) best = std::min(best, pointTriangleSquaredDistance(p, c[0], c[1], c[2]));
  return std::sqrt(best);
}

Eigen::Isometry3d translation(const Eigen::Vector3d& p) {
  Eigen::Isometry3d X = Eigen::Isometry3d::Identity();
  X.translation() = p;
  return X;
}

struct Shape {
  const char* name;
  bench::FclShape fcl;
};

// The exact CFL distance of `shape` at X_WS to A (at the identity), through the core query for its kind.
double cflShapeDistance(const CflModel& a, const Shape& shape, const Eigen::Isometry3d& X_WS) {
  switch (shape.fcl.kind) {
    case bench::FclShape::Kind::kSphere:
      return computePointDistance(a, kIdentity, X_WS.translation()).distance - shape.fcl.radius;
    case bench::FclShape::Kind::kCapsule: {
      const Eigen::Vector3d half = X_WS.linear().col(2) * (0.5 * shape.fcl.length);
      const Eigen::Vector3d center = X_WS.translation();
      return computeSegmentDistance(a, kIdentity, center - half, center + half).distance - shape.fcl.radius;
    }
    case bench::FclShape::Kind::kBox:
      return computeBoxDistance(a, kIdentity, X_WS, 0.5 * shape.fcl.sides).distance;
  }
  return NAN;
}

}  // namespace

bool runPointSection(const SectionContext& c, int count, std::uint64_t seed, std::ostream& out) {
  const CflModel& a = c.cfl_a;
  const bool closed = a.sign.closure.closed;
  const std::vector<std::pair<const char*, std::vector<Eigen::Vector3d>>> sets = {
      {"near (5%)", bench::nearSurfacePoints(a.geometry.mesh, std::size_t(count), 0.05 * c.diagonal, seed)},
      {"box (2x)", bench::boxPoints(a.geometry.bounds, std::size_t(count), seed + 1)}};
  out << format("\nPoint queries: %d points per set, median microseconds per point (%d repeats); FCL: a sphere of "
                "radius 0 against BVHModel<OBBRSS>; batch: computePointDistances over the whole set on all threads, "
                "median wall time per point over the repeats%s\n",
                count, c.repeats, closed ? "" : "; the mesh is not closed, so no signed column");
  out << format("%-10s | %9s %9s %9s %9s | %10s %10s | %11s\n", "set", "FCL", "CFL", "signed", "batch", "FCL/CFL",
                "FCL/batch", "max|d|/diag");
  bench::FclShape point;
  bool passed = true;
  for (const auto& [name, points] : sets) {
    std::vector<IndexedMethod> methods = {
        {"fcl", [&](std::size_t i) { return bench::fclShapeDistance(point, translation(points[i]), c.obbrss_a, kIdentity); }},
        {"cfl", [&](std::size_t i) { return computePointDistance(a, kIdentity, points[i]).distance; }}};
    if (closed) {
      methods.push_back({"signed", [&](std::size_t i) {
                           return std::abs(computePointDistance(a, kIdentity, points[i], {true}).distance);
                         }});
    }
    const auto samples = timeIndexedMethods(points.size(), methods, c.repeats, c.clock, c.order);
    std::vector<PointDistance> batch(points.size());
    std::vector<double> batch_micros;
    for (int r = 0; r < c.repeats; ++r) {
      const auto start = std::chrono::steady_clock::now();
      computePointDistances(a, kIdentity, points.data(), points.size(), batch.data());
      batch_micros.push_back(std::chrono::duration<double, std::micro>(std::chrono::steady_clock::now() - start).count() /
                             double(points.size()));
    }
    const double batch_us = bench::median(batch_micros);
    // Every CFL answer (single, signed in absolute value, batch) against FCL's; where they differ by more
    // than 1e-9 of the diagonal, brute force decides, and CFL off fails the section.
    double worst = 0;
    for (std::size_t i = 0; i < points.size(); ++i) {
      const double fcl = samples[0].distances[i];
      double reference = fcl;
      for (const double cfl : {samples[1].distances[i], closed ? samples[2].distances[i] : samples[1].distances[i],
                               batch[i].distance}) {
        if (!(std::abs(cfl - reference) <= 1e-9 * c.diagonal) && reference == fcl) {
          reference = bruteForcePointDistance(a.geometry, points[i]);
        }
        worst = std::max(worst, std::isnan(cfl) ? INFINITY : std::abs(cfl - reference));
      }
    }
    const bool ok = worst <= 1e-9 * c.diagonal;
    passed = passed && ok;
    const double t_fcl = bench::median(samples[0].micros), t_cfl = bench::median(samples[1].micros);
    const std::string signed_column = closed ? format("%9.3f", bench::median(samples[2].micros)) : format("%9s", "-");
    out << format("%-10s | %9.3f %9.3f %s %9.3f | %9.1fx %9.1fx | %11.2g%s\n", name, t_fcl, t_cfl,
                  signed_column.c_str(), batch_us, t_fcl / t_cfl, t_fcl / batch_us, worst / c.diagonal,
                  ok ? "" : "  MISMATCH");
  }
  return passed;
}

bool runShapeSection(const SectionContext& c, const std::vector<double>& bands, int poses, std::uint64_t seed,
                     std::ostream& out) {
  const CflModel& a = c.cfl_a;
  const double d = c.diagonal;
  bench::FclShape sphere, capsule, box;
  sphere.radius = 0.02 * d;
  capsule.kind = bench::FclShape::Kind::kCapsule;
  capsule.radius = 0.01 * d;
  capsule.length = 0.05 * d;
  box.kind = bench::FclShape::Kind::kBox;
  box.sides = Eigen::Vector3d(0.03 * d, 0.02 * d, 0.015 * d);
  const Shape shapes[] = {{"sphere", sphere}, {"capsule", capsule}, {"box", box}};
  out << format("\nShapes against A: %d poses per row at exact distances, median microseconds per query (%d "
                "repeats); sizes in diagonals: sphere radius 0.02, capsule radius 0.01 and length 0.05, box 0.03 x "
                "0.02 x 0.015. CFL: the core's point, segment and box queries; FCL: fcl::distance of the shape "
                "against BVHModel<OBBRSS>. Where the two differ by more than 1e-9 of the diagonal (FCL runs GJK to its "
                "own tolerance for capsules and boxes), brute force over every triangle decides: FCL off counts the "
                "poses where CFL equals it and FCL does not; CFL off it fails the section\n",
                poses, c.repeats);
  out << format("%-8s %7s | %10s %10s | %8s | %11s %7s\n", "shape", "band", "FCL", "CFL", "FCL/CFL", "max|d|/diag",
                "FCL off");
  std::mt19937_64 rng(seed);
  bool passed = true;
  for (const Shape& shape : shapes) {
    for (const double band : bands) {
      if (!(band > 0)) continue;  // touching or overlapping shapes have no distance to compare
      std::vector<Eigen::Isometry3d> placed;
      for (int i = 0; i < poses; ++i) placed.push_back(bench::placeShapeOnRay(a.geometry.bounds.center(), d, band * d, rng,
                                                [&](const Eigen::Isometry3d& X) { return cflShapeDistance(a, shape, X); }));
      const std::vector<TimedMethod> methods = {
          {"fcl", [&](const Eigen::Isometry3d& X) { return bench::fclShapeDistance(shape.fcl, X, c.obbrss_a, kIdentity); }},
          {"cfl", [&](const Eigen::Isometry3d& X) { return cflShapeDistance(a, shape, X); }}};
      const auto samples = timeMethods(placed, methods, c.repeats, c.clock, c.order);
      // max|d|/diag: CFL against FCL, or against brute force where the two differ.
      double worst = 0;
      int fcl_off = 0;
      for (int i = 0; i < poses; ++i) {
        const double cfl = samples[1].distances[i];
        double diff = std::abs(samples[0].distances[i] - cfl);
        if (!(diff <= 1e-9 * d)) {
          diff = std::abs(bench::bruteForceShapeDistance(shape.fcl, placed[i], a.geometry.mesh) - cfl);
          fcl_off += diff <= 1e-9 * d;
        }
        worst = std::isnan(diff) ? INFINITY : std::max(worst, diff);
      }
      const bool ok = worst <= 1e-9 * d;
      passed = passed && ok;
      const double t_fcl = bench::median(samples[0].micros), t_cfl = bench::median(samples[1].micros);
      out << format("%-8s %6.1f%% | %10.2f %10.2f | %7.1fx | %11.2g %7d%s\n", shape.name, 100 * band, t_fcl, t_cfl,
                    t_fcl / t_cfl, worst / d, fcl_off, ok ? "" : "  MISMATCH");
    }
  }
  return passed;
}

bool runPenetrationSection(const SectionContext& c, int poses, std::uint64_t seed, std::ostream& out) {
  const CflModel& a = c.cfl_a;
  out << format("\nPenetration of A with itself at %d overlapping poses, median microseconds per query (%d "
                "repeats). CFL: computePenetration, the bodies' depth certified to 1e-4 of the diagonal; FCL: "
                "fcl::collide with contacts, per-triangle-pair local depths, with the first contact only and with "
                "every contact (what a caller wanting the deepest local depth must ask for)\n",
                poses, c.repeats);
  if (!a.sign.closure.closed) {
    out << "skipped: A does not bound a solid (" << a.sign.closure.reason << ")\n";
    return true;
  }
  const bench::BandPoses overlap = bench::generateBandPoses(
      a.geometry.bounds, a.geometry.bounds, 0.0, poses, seed,
      [&](const Eigen::Isometry3d& X_WB) { return computeDistance(a, kIdentity, a.geometry, X_WB).distance; });
  const std::vector<TimedMethod> methods = {
      {"fcl1", [&](const Eigen::Isometry3d& X) { return bench::fclDeepestContact(c.obbrss_a, kIdentity, c.obbrss_a, X, 1); }},
      {"fclall",
       [&](const Eigen::Isometry3d& X) { return bench::fclDeepestContact(c.obbrss_a, kIdentity, c.obbrss_a, X, 100000); }},
      {"cfl", [&](const Eigen::Isometry3d& X) { return computePenetration(a, kIdentity, a, X).depth; }}};
  const auto samples = timeMethods(overlap.poses, methods, c.repeats, c.clock, c.order);
  // The certificate: every interval [depth, depth_upper] no wider than the tolerance, depth positive (the
  // poses overlap), and the deepest point that far from its closest point.
  double depth_sum = 0, widest = 0, witness_error = 0;
  bool ok = true;
  for (const auto& X : overlap.poses) {
    const PenetrationResult r = computePenetration(a, kIdentity, a, X);
    depth_sum += r.depth;
    widest = std::max(widest, r.depth_upper - r.depth);
    witness_error = std::max(witness_error, std::abs((r.deepest_point - r.surface_point).norm() - r.depth));
    ok = ok && r.depth > 0 && r.depth_upper - r.depth <= 1e-4 * c.diagonal * (1 + 1e-9);
  }
  ok = ok && witness_error <= 1e-9 * c.diagonal;
  const double t1 = bench::median(samples[0].micros), tall = bench::median(samples[1].micros),
               tc = bench::median(samples[2].micros);
  out << format("%12s %14s %12s | %9s %9s | %10s %10s\n", "FCL 1 ct", "FCL all ct", "CFL depth", "1ct/CFL", "all/CFL",
                "depth/diag", "width/diag");
  out << format("%12.1f %14.1f %12.1f | %8.2fx %8.2fx | %10.4f %10.2g%s\n", t1, tall, tc, t1 / tc, tall / tc,
                depth_sum / double(overlap.poses.size()) / c.diagonal, widest / c.diagonal,
                ok ? "" : "  FAILED (an interval wider than the tolerance, a zero depth or a witness off)");
  return ok;
}

}  // namespace cfl::tool
