#include "cfl/batch_query.h"

#include "cfl/error.h"

#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <string>
#include <thread>

namespace cfl {
namespace {

// Runs query(i) for every i in [0, count) on `threads` threads (the caller is one of them), handing out
// chunks from a shared counter so that a few expensive queries do not leave the other threads idle.
template <typename Query>
void runParallel(std::size_t count, const BatchOptions& options, const Query& query) {
  const int threads = batchThreadCount(options.threads, count);
  std::size_t chunk = options.chunk_size > 0 ? static_cast<std::size_t>(options.chunk_size)
                                             : std::clamp<std::size_t>(count / (8 * std::size_t(threads)), 1, 64);
  if (threads <= 1) {
    for (std::size_t i = 0; i < count; ++i) query(i);
    return;
  }

  std::atomic<std::size_t> next{0};
  std::atomic<bool> failed{false};
  std::exception_ptr first_error;
  std::mutex error_mutex;
  const auto work = [&] {
    try {
      while (!failed.load(std::memory_order_relaxed)) {
        const std::size_t begin = next.fetch_add(chunk, std::memory_order_relaxed);
        if (begin >= count) break;
        const std::size_t end = std::min(count, begin + chunk);
        for (std::size_t i = begin; i < end; ++i) query(i);
      }
    } catch (...) {
      // Poses are validated up front, so this is only std::bad_alloc or the like; stop everyone and
      // rethrow it in the caller.
      std::lock_guard<std::mutex> lock(error_mutex);
      if (!first_error) first_error = std::current_exception();
      failed = true;
    }
  };
  std::vector<std::thread> workers;
  workers.reserve(threads - 1);
  for (int t = 1; t < threads; ++t) workers.emplace_back(work);
  work();
  for (std::thread& worker : workers) worker.join();
  if (first_error) std::rethrow_exception(first_error);
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
  runParallel(count, options, [&](std::size_t i) { results[i] = computeDistance(a, X_WA, b, X_WB[i], options.distance); });
}

}  // namespace

int batchThreadCount(int requested, std::size_t count) {
  int threads = requested > 0 ? requested : static_cast<int>(std::thread::hardware_concurrency());
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
