// The best-first search's 4-ary heap (src/detail/search_heap.h) against a sorted multiset: every pop must
// return an entry of the smallest key pending, and the entries must come out as they went in.

#include "../src/detail/search_heap.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <limits>
#include <random>
#include <set>
#include <utility>
#include <vector>

namespace {

struct Entry {
  double key;
  int id;
};

// Runs `operations` random pushes and pops (pushes more likely while `growing`), checking each pop against
// the reference. Keys drawn from `distinct_keys` values, so that ties are common when it is small.
void checkAgainstMultiset(std::uint64_t seed, int operations, int distinct_keys) {
  std::mt19937_64 rng(seed);
  std::uniform_int_distribution<int> key_value(0, distinct_keys - 1);
  std::uniform_real_distribution<double> unit(0.0, 1.0);
  std::vector<Entry> heap;
  std::multiset<std::pair<double, int>> reference;
  int next_id = 0;
  for (int step = 0; step < operations; ++step) {
    // Phases of growth and of draining, so that the heap's size crosses every remainder of its four-child
    // groups, up and down, with partial groups at the bottom.
    const bool growing = (step / 3000) % 2 == 0;
    const bool push = reference.empty() || unit(rng) < (growing ? 0.7 : 0.3);
    if (push) {
      // Negative keys too: the search's keys for pieces that may overlap A are negative.
      const Entry entry{double(key_value(rng)) - 0.25 * distinct_keys, next_id++};
      cfl::detail::heapPush(heap, entry);
      reference.insert({entry.key, entry.id});
    } else {
      const double smallest = reference.begin()->first;
      const Entry popped = cfl::detail::heapPop(heap);
      ASSERT_EQ(popped.key, smallest) << "step " << step << ", " << reference.size() << " pending";
      const auto found = reference.find({popped.key, popped.id});
      ASSERT_NE(found, reference.end()) << "popped an entry that was never pushed, or twice";
      reference.erase(found);
    }
    ASSERT_EQ(heap.size(), reference.size());
    if (!heap.empty()) ASSERT_EQ(heap.front().key, reference.begin()->first);
  }
  while (!reference.empty()) {
    const Entry popped = cfl::detail::heapPop(heap);
    ASSERT_EQ(popped.key, reference.begin()->first);
    const auto found = reference.find({popped.key, popped.id});
    ASSERT_NE(found, reference.end());
    reference.erase(found);
  }
  EXPECT_TRUE(heap.empty());
}

TEST(SearchHeap, PopsTheSmallestKeyWithDistinctKeys) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) checkAgainstMultiset(seed, 40000, 1 << 30);
}

TEST(SearchHeap, PopsTheSmallestKeyWithManyTies) {
  for (std::uint64_t seed = 1; seed <= 4; ++seed) checkAgainstMultiset(seed, 40000, 7);
}

TEST(SearchHeap, SortsEverySmallSize) {
  // Every size up to a few levels, each filled in decreasing key order (every push moves to the top) and
  // drained: the pops must come out sorted.
  for (int size = 1; size <= 90; ++size) {
    std::vector<Entry> heap;
    for (int k = size; k > 0; --k) cfl::detail::heapPush(heap, Entry{double(k % 13) + 0.001 * k, k});
    double previous = -std::numeric_limits<double>::infinity();
    for (int k = 0; k < size; ++k) {
      const Entry popped = cfl::detail::heapPop(heap);
      ASSERT_LE(previous, popped.key) << "size " << size << ", pop " << k;
      previous = popped.key;
    }
    ASSERT_TRUE(heap.empty());
  }
}

}  // namespace
