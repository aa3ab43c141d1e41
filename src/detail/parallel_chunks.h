#pragma once
// Internal: the one parallel loop of the batch queries (batch_query.cpp, point_query.cpp).

#include "tsan_annotations.h"

#include <tbb/blocked_range.h>
#include <tbb/parallel_for.h>
#include <tbb/partitioner.h>
#include <tbb/task_arena.h>

#include <cstddef>

namespace cfl::detail {

// Calls body(begin, end) on disjoint ranges covering [0, count), on up to `threads` threads (the caller is one
// of them), each range of chunk / 2 to chunk items. A task arena capped at `threads` slots keeps the batch
// from using more threads than asked even when the program runs other TBB work; a parallel_for over
// chunk-sized ranges lets idle threads steal the remaining chunks, so that a few expensive items do not leave
// the other threads idle (simple_partitioner splits down to the grain size and no further: each chunk is a
// unit of stealing). The body must write only what its own items own, so that the result does not depend on
// the schedule. An exception thrown by the body cancels the chunks not yet started and is rethrown here by
// TBB. threads <= 1 runs body(0, count) on the calling thread.
template <typename Body>
void parallelChunks(std::size_t count, int threads, std::size_t chunk, const Body& body) {
  if (threads <= 1) {
    if (count > 0) body(std::size_t(0), count);
    return;
  }
  int before = 0, after = 0;  // Addresses for the TSan annotations only.
  tsanRelease(&before);
  tbb::task_arena arena(threads);
  arena.execute([&] {
    tbb::parallel_for(
        tbb::blocked_range<std::size_t>(0, count, chunk),
        [&](const tbb::blocked_range<std::size_t>& range) {
          tsanAcquire(&before);
          body(range.begin(), range.end());
          tsanRelease(&after);
        },
        tbb::simple_partitioner());
  });
  tsanAcquire(&after);
}

}  // namespace cfl::detail
