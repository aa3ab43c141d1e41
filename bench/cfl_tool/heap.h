#pragma once
/// @file
/// The live heap a data structure holds, measured the same way for CFL and for FCL: what the allocator
/// reports in use after constructing it, minus before. BuildStatistics::memory_bytes adds up vector sizes
/// and misses capacity slack, allocator overhead and anything not in its sum; the allocator's count has
/// none of those blind spots.

#include <cstdint>
#include <utility>

namespace cfl::tool {

/// Bytes the process holds on the heap right now: glibc's mallinfo2() uordblks (in use in every arena)
/// plus hblkhd (large blocks mmapped one by one). -1 where mallinfo2 is unavailable (not glibc).
std::int64_t liveHeapBytes();

/// Runs `construct` and returns its result together with the heap it left allocated (after - before).
/// Construct inputs before the call, so that only the structure's own memory is counted; temporaries the
/// construction frees again do not count. -1 bytes when liveHeapBytes is unavailable.
template <class F>
auto measureHeap(F&& construct) {
  const std::int64_t before = liveHeapBytes();
  auto value = construct();
  const std::int64_t after = liveHeapBytes();
  return std::make_pair(std::move(value), before < 0 || after < 0 ? std::int64_t(-1) : after - before);
}

}  // namespace cfl::tool
