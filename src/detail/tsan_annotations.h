#pragma once
// Internal: ThreadSanitizer does not see the synchronization inside libtbb.so (not instrumented), so without
// help it takes a caller's writes before a parallel batch and its reads after it as racing with the chunks.
// detail::parallelChunks (parallel_chunks.h), the batches' loop, states with these the order TBB guarantees:
// parallel_for starts every chunk after the call and returns after every chunk. They compile to nothing outside
// TSan builds.

#if defined(__has_feature)
#if __has_feature(thread_sanitizer)
#define CFL_TSAN 1
#endif
#endif
#if defined(__SANITIZE_THREAD__)
#define CFL_TSAN 1
#endif
#ifdef CFL_TSAN
#include <sanitizer/tsan_interface.h>
#endif

namespace cfl::detail {

inline void tsanRelease([[maybe_unused]] void* token) {
#ifdef CFL_TSAN
  __tsan_release(token);
#endif
}
inline void tsanAcquire([[maybe_unused]] void* token) {
#ifdef CFL_TSAN
  __tsan_acquire(token);
#endif
}

}  // namespace cfl::detail
