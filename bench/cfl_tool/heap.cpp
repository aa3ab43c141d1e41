#include "heap.h"

#if defined(__GLIBC__)
#include <malloc.h>
#endif

namespace cfl::tool {

std::int64_t liveHeapBytes() {
#if defined(__GLIBC__) && (__GLIBC__ > 2 || (__GLIBC__ == 2 && __GLIBC_MINOR__ >= 33))
  // mallinfo2 sums over all arenas, so blocks the build's worker threads allocated are counted too.
  const struct mallinfo2 info = ::mallinfo2();
  return std::int64_t(info.uordblks) + std::int64_t(info.hblkhd);
#else
  return -1;
#endif
}

}  // namespace cfl::tool
