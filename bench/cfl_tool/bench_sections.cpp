#include "bench_sections.h"

#include "tool_support.h"

#include <algorithm>
#include <cmath>
#include <ostream>

namespace cfl::tool {
namespace {

const Eigen::Isometry3d kIdentity = Eigen::Isometry3d::Identity();

struct Row {
  double median_us = 0, p90_us = 0, mean_us = 0, mean_np = 0, mean_nv = 0;
};

Row summarize(const MethodSamples& samples, const std::vector<DistanceResult>* counted) {
  Row r;
  r.median_us = bench::median(samples.micros);
  r.p90_us = bench::percentile(samples.micros, 0.9);
  r.mean_us = mean(samples.micros);
  if (counted != nullptr) {
    std::vector<double> np, nv;
    for (const auto& c : *counted) {
      np.push_back(double(c.counters.triangle_pairs));
      nv.push_back(double(c.counters.voxel_tests));
    }
    r.mean_np = mean(np);
    r.mean_nv = mean(nv);
  }
  return r;
}

// Largest |answer_i - reference_i|; infinite when a value is NaN, so that NaN never passes a check.
double maxDifference(const std::vector<double>& answers, const std::vector<double>& references) {
  double worst = 0;
  for (std::size_t i = 0; i < answers.size() && i < references.size(); ++i) {
    const double d = std::abs(answers[i] - references[i]);
    worst = std::isnan(d) ? INFINITY : std::max(worst, d);
  }
  return worst;
}

// The note under a table when brute force found FCL OBBRSS off on some poses (see Referee).
void noteFclErrors(const Referee& referee, std::size_t poses, double diagonal, std::ostream& out) {
  if (referee.fclErrors() == 0) return;
  out << format("note: FCL OBBRSS was off on %d of %zu poses, by up to %.3g of the diagonal; brute force over all "
                "triangle pairs gave those poses' reference\n",
                referee.fclErrors(), poses, referee.largestFclError() / diagonal);
}

}  // namespace

bool runMovingSection(const SectionContext& c, int frames, double separation, std::uint64_t seed,
                      std::ostream& out) {
  const bench::MovingPoses motion = bench::generateMovingPoses(
      c.cfl_a.geometry.bounds, c.model_b.bounds, separation, frames, seed,
      [&](const Eigen::Isometry3d& X_WB) { return bench::fclDistance(c.obbrss_a, kIdentity, c.obbrss_b, X_WB).distance; });
  const auto& poses = motion.poses;

  // The warm chain, untimed: frame i's hint is frame i-1's answer. Timed warm queries replay these hints,
  // which is what a simulator passing its last result would send.
  std::vector<DistanceOptions> hints(poses.size());
  std::vector<DistanceResult> warm_counted, cold_counted;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    if (i > 0) {
      hints[i].hint_triangle_a = warm_counted.back().triangle_a;
      hints[i].hint_triangle_b = warm_counted.back().triangle_b;
    }
    warm_counted.push_back(computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i], hints[i]));
    cold_counted.push_back(computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i]));
  }
  int reused = 0;  // frames whose answer is the hinted pair
  for (std::size_t i = 1; i < poses.size(); ++i) {
    reused += warm_counted[i].triangle_a == hints[i].hint_triangle_a &&
              warm_counted[i].triangle_b == hints[i].hint_triangle_b;
  }
  // The cached chain, untimed: caches[i] is the cache as frame i left it. A timed query of frame i starts
  // from a copy of caches[i - 1] (the copy reuses the working cache's memory, so it does not allocate), so
  // every repeat sees what a simulator at frame i would; frame 0 starts empty, as the chain did.
  std::vector<DistanceCache> caches(poses.size());
  std::vector<DistanceResult> cached_counted;
  {
    DistanceCache chain;
    for (std::size_t i = 0; i < poses.size(); ++i) {
      cached_counted.push_back(computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i], chain));
      caches[i] = chain;
    }
  }
  const std::int64_t certified_frames = caches.empty() ? 0 : caches.back().reused;
  DistanceCache working;

  const std::vector<IndexedMethod> methods = {
      {"CFL cold", [&](std::size_t i) { return computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i]).distance; }},
      {"CFL warm",
       [&](std::size_t i) { return computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i], hints[i]).distance; }},
      {"OBBRSS",
       [&](std::size_t i) { return bench::fclDistance(c.obbrss_a, kIdentity, c.obbrss_b, poses[i]).distance; }},
      {"CFL cached",
       [&](std::size_t i) {
         if (i == 0) {
           working.reset();
         } else {
           working = caches[i - 1];
         }
         return computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i], working).distance;
       }},
  };
  const std::vector<MethodSamples> samples = timeIndexedMethods(poses.size(), methods, c.repeats, c.clock, c.order);
  const Row cold = summarize(samples[0], &cold_counted);
  const Row warm = summarize(samples[1], &warm_counted);
  const Row obbrss = summarize(samples[2], nullptr);
  const Row cached = summarize(samples[3], &cached_counted);
  const double tolerance = 1e-9 * c.diagonal;
  Referee referee(c.cfl_a.geometry, c.model_b, tolerance);
  std::vector<double> references;
  for (std::size_t i = 0; i < poses.size(); ++i) {
    references.push_back(referee.reference(poses[i], samples[2].distances[i],
                                           {samples[0].distances[i], samples[1].distances[i], samples[3].distances[i]}));
  }
  const double cold_difference = maxDifference(samples[0].distances, references);
  const double warm_difference = maxDifference(samples[1].distances, references);
  const double cached_difference = maxDifference(samples[3].distances, references);

  const double kDegrees = 180 / 3.14159265358979323846;
  out << format("\nmoving objects: %d frames; B orbits A once and turns twice, resting at %g of the diagonal "
                "(median achieved %.4g); per frame B moves %.3g of the diagonal (median; max %.3g) and turns %.3g "
                "degrees\n",
                frames, separation, bench::median(motion.distances) / c.diagonal, motion.median_step / c.diagonal,
                motion.max_step / c.diagonal, motion.rotation_step * kDegrees);
  out << format("warm: each frame passes the previous frame's triangle pair (hint_triangle_a/b); the answer was "
                "that same pair on %d of %d frames\n",
                reused, std::max(frames - 1, 0));
  out << format("cached: each frame passes the DistanceCache the previous frame left; its certificate answered "
                "%lld of %d frames without a search\n",
                static_cast<long long>(certified_frames), frames);
  out << format("%-10s | %8s %8s %8s | %9s %9s | %11s\n", "method", "median", "p90", "mean", "N_p", "N_v",
                "max|d|/diag");
  auto line = [&](const char* name, const Row& r, double difference, bool counted) {
    const bool ok = difference <= tolerance;
    out << format("%-10s | %8.1f %8.1f %8.1f | ", name, r.median_us, r.p90_us, r.mean_us)
        << (counted ? format("%9.1f %9.0f", r.mean_np, r.mean_nv) : format("%9s %9s", "-", "-"))
        << format(" | %11s%s\n", counted ? format("%.2g", difference / c.diagonal).c_str() : "-",
                  ok ? "" : "  <-- MISMATCH");
    return ok;
  };
  bool passed = line("CFL cold", cold, cold_difference, true);
  passed = line("CFL warm", warm, warm_difference, true) && passed;
  passed = line("CFL cached", cached, cached_difference, true) && passed;
  line("OBBRSS", obbrss, 0, false);
  noteFclErrors(referee, poses.size(), c.diagonal, out);
  out << format("microseconds per frame (%s clock). warm/cold speedup %.2fx; OBBRSS/CFL cold %.1fx; OBBRSS/CFL "
                "warm %.1fx; cached/cold speedup %.2fx (of means %.2fx); OBBRSS/CFL cached %.1fx\n",
                c.clock == Clock::kWall ? "wall" : "thread CPU", warm.median_us > 0 ? cold.median_us / warm.median_us : 0,
                cold.median_us > 0 ? obbrss.median_us / cold.median_us : 0,
                warm.median_us > 0 ? obbrss.median_us / warm.median_us : 0,
                cached.median_us > 0 ? cold.median_us / cached.median_us : 0,
                cached.mean_us > 0 ? cold.mean_us / cached.mean_us : 0,
                cached.median_us > 0 ? obbrss.median_us / cached.median_us : 0);
  out.flush();
  return passed;
}

bool runApproximateSection(const SectionContext& c, const std::vector<bench::BandPoses>& bands,
                           const DistanceOptions& options, std::ostream& out) {
  const double tolerance = 1e-9 * c.diagonal;
  out << format("\napproximate queries: rel_err %g, abs_err %g (%.3g of the diagonal). A search step is skipped "
                "only when both allow it (FCL's rule)%s\n",
                options.rel_err, options.abs_err, options.abs_err / c.diagonal,
                options.abs_err == 0 ? "; abs_err = 0 makes the query exact" : "");
  out << format("%-7s %9s | %8s %8s | %8s %8s | %12s | %8s %13s | %8s %8s | %12s\n", "band", "dist/diag",
                "exact", "p90", "approx", "p90", "exact/approx", "OBBRSS", "OBBRSS/approx", "N_p ex", "N_p ap",
                "max(d/true-1)");
  bool passed = true;
  for (const bench::BandPoses& band : bands) {
    const auto& poses = band.poses;
    const std::vector<TimedMethod> methods = {
        {"exact", [&](const Eigen::Isometry3d& X) { return computeDistance(c.cfl_a, kIdentity, c.model_b, X).distance; }},
        {"approx",
         [&](const Eigen::Isometry3d& X) { return computeDistance(c.cfl_a, kIdentity, c.model_b, X, options).distance; }},
        {"OBBRSS",
         [&](const Eigen::Isometry3d& X) { return bench::fclDistance(c.obbrss_a, kIdentity, c.obbrss_b, X).distance; }},
    };
    const std::vector<MethodSamples> samples = timeMethods(poses, methods, c.repeats, c.clock, c.order);
    std::vector<DistanceResult> exact_counted, approx_counted;
    Referee referee(c.cfl_a.geometry, c.model_b, tolerance);
    std::vector<double> references;
    for (std::size_t i = 0; i < poses.size(); ++i) {
      references.push_back(referee.reference(poses[i], samples[2].distances[i], {samples[0].distances[i]}));
    }
    bool ok = maxDifference(samples[0].distances, references) <= tolerance;
    double worst_relative = 0;
    for (std::size_t i = 0; i < poses.size(); ++i) {
      exact_counted.push_back(computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i]));
      approx_counted.push_back(computeDistance(c.cfl_a, kIdentity, c.model_b, poses[i], options));
      const double truth = references[i];
      const double d = samples[1].distances[i];
      const double bound = std::min(truth * (1 + options.rel_err), truth + options.abs_err);
      if (!(d >= truth - tolerance && d <= bound + tolerance)) ok = false;
      if (truth > 0) worst_relative = std::max(worst_relative, d / truth - 1);
    }
    const Row exact = summarize(samples[0], &exact_counted);
    const Row approx = summarize(samples[1], &approx_counted);
    const Row obbrss = summarize(samples[2], nullptr);
    passed = passed && ok;
    out << format("%-7g %9.4g | %8.1f %8.1f | %8.1f %8.1f | %11.2fx | %8.1f %12.1fx | %8.1f %8.1f | %12.3g%s\n",
                  band.band, bench::median(band.distances) / c.diagonal, exact.median_us, exact.p90_us,
                  approx.median_us, approx.p90_us, approx.median_us > 0 ? exact.median_us / approx.median_us : 0,
                  obbrss.median_us, approx.median_us > 0 ? obbrss.median_us / approx.median_us : 0, exact.mean_np,
                  approx.mean_np, worst_relative, ok ? "" : "  <-- MISMATCH");
    noteFclErrors(referee, poses.size(), c.diagonal, out);
    out.flush();
  }
  return passed;
}

}  // namespace cfl::tool
