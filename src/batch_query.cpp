#include "cfl/batch_query.h"

#include "cfl/error.h"
#include "detail/parallel_chunks.h"

#include <tbb/global_control.h>
#include <tbb/info.h>

#include <algorithm>
#include <string>

namespace cfl {
namespace {

// Runs query(i) for every i in [0, count) on up to options.threads threads in chunks of about
// options.chunk_size poses (detail::parallelChunks). Each query writes only its own result, so the answers do
// not depend on which thread ran which chunk; poses are validated up front, so what a query may throw is
// std::bad_alloc or the like, rethrown in the caller.
template <typename Query>
void runParallel(std::size_t count, const BatchOptions& options, const Query& query) {
  const int threads = batchThreadCount(options.threads, count);
  const std::size_t chunk = options.chunk_size > 0
                                ? static_cast<std::size_t>(options.chunk_size)
                                : std::clamp<std::size_t>(count / (8 * std::size_t(threads)), 1, 64);
  detail::parallelChunks(count, threads, chunk, [&](std::size_t begin, std::size_t end) {
    for (std::size_t i = begin; i != end; ++i) query(i);
  });
}

void validatePoses(const Eigen::Isometry3d& X_WA, const Eigen::Isometry3d* X_WB, std::size_t count,
                   const DistanceResult* results) {
  if (count > 0 && (X_WB == nullptr || results == nullptr)) throw Error("computeDistances: null poses or results");
  validatePose(X_WA, "X_WA");
  std::string name;
  for (std::size_t i = 0; i < count; ++i) {
    name = "X_WB[" + std::to_string(i) + "]";
    validatePose(X_WB[i], name.c_str());
  }
}

template <typename ModelB>
void computeDistancesImpl(const CflModel& a, const Eigen::Isometry3d& X_WA, const ModelB& b,
                          const Eigen::Isometry3d* X_WB, std::size_t count, DistanceResult* results,
                          const BatchOptions& options) {
  validatePoses(X_WA, X_WB, count, results);
  runParallel(count, options,
              [&](std::size_t i) { results[i] = computeDistance(a, X_WA, b, X_WB[i], options.distance); });
}

}  // namespace

int batchThreadCount(int requested, std::size_t count) {
  // TBB's count of the hardware threads this process may run on (it honours CPU affinity masks).
  int threads = requested > 0 ? requested : tbb::info::default_concurrency();
  // No more than TBB will run at once (the hardware threads, unless the program set a tbb::global_control):
  // an arena asking for more gets no more threads, only a warning from TBB on stderr.
  const std::size_t allowed =
      tbb::global_control::active_value(tbb::global_control::max_allowed_parallelism);
  if (allowed < static_cast<std::size_t>(threads)) threads = static_cast<int>(allowed);
  threads = std::max(threads, 1);
  if (count < static_cast<std::size_t>(threads)) threads = static_cast<int>(std::max<std::size_t>(count, 1));
  return threads;
}

void computeDistances(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                      const Eigen::Isometry3d* X_WB, std::size_t count, DistanceResult* results,
                      const BatchOptions& options) {
  computeDistancesImpl(a, X_WA, b, X_WB, count, results, options);
}

void computeDistances(const CflModel& a, const Eigen::Isometry3d& X_WA, const CflModel& b,
                      const Eigen::Isometry3d* X_WB, std::size_t count, DistanceResult* results,
                      const BatchOptions& options) {
  computeDistancesImpl(a, X_WA, b, X_WB, count, results, options);
}

std::vector<DistanceResult> computeDistances(const CflModel& a, const Eigen::Isometry3d& X_WA, const MeshModel& b,
                                             const std::vector<Eigen::Isometry3d>& X_WB,
                                             const BatchOptions& options) {
  std::vector<DistanceResult> results(X_WB.size());
  computeDistances(a, X_WA, b, X_WB.data(), X_WB.size(), results.data(), options);
  return results;
}

}  // namespace cfl
