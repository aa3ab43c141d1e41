#pragma once
// The best-first search's queue (distance_search.cpp): a 4-ary min-heap on a vector of entries with a
// double `key`, smallest key at index 0. Far from A the search keeps about a thousand node pairs pending,
// and std::pop_heap's binary sift-down took about a fifth of a query's time on the blade, most of it in
// mispredicted branches choosing between two children: four children a level halve the levels, and their
// smallest is chosen without a branch. Entries with equal keys may leave in any order (the search's answer
// does not depend on it).

#include <cstddef>
#include <vector>

namespace cfl::detail {

// Puts `entry` at `hole` or above it: its ancestors with larger keys move down a level each.
template <class Entry>
inline void heapSiftUp(Entry* data, std::size_t hole, const Entry& entry) {
  while (hole > 0) {
    const std::size_t parent = (hole - 1) / 4;
    if (!(entry.key < data[parent].key)) break;
    data[hole] = data[parent];
    hole = parent;
  }
  data[hole] = entry;
}

// Adds `entry`. O(log n).
template <class Entry>
inline void heapPush(std::vector<Entry>& heap, const Entry& entry) {
  heap.push_back(entry);
  heapSiftUp(heap.data(), heap.size() - 1, entry);
}

// Removes and returns the entry of smallest key. The heap must not be empty. O(log n).
// Bottom-up: the hole left at the top moves down to a leaf along the smallest children, without comparing
// with the entry that fills it (the last one, which belongs near the bottom), which then moves up from there,
// rarely more than a level. The smallest of four children is found by index arithmetic, without branches.
template <class Entry>
inline Entry heapPop(std::vector<Entry>& heap) {
  Entry* data = heap.data();
  const Entry top = data[0];
  const Entry last = heap.back();
  heap.pop_back();
  const std::size_t size = heap.size();
  if (size == 0) return top;
  std::size_t hole = 0;
  while (4 * hole + 4 < size) {  // all four children in the heap
    const std::size_t first = 4 * hole + 1;
    const std::size_t left = first + std::size_t(data[first + 1].key < data[first].key);
    const std::size_t right = first + 2 + std::size_t(data[first + 3].key < data[first + 2].key);
    const std::size_t least = left + (right - left) * std::size_t(data[right].key < data[left].key);
    data[hole] = data[least];
    hole = least;
  }
  if (4 * hole + 1 < size) {  // some of them
    std::size_t least = 4 * hole + 1;
    for (std::size_t child = least + 1; child < size && child <= 4 * hole + 4; ++child) {
      if (data[child].key < data[least].key) least = child;
    }
    data[hole] = data[least];
    hole = least;
  }
  heapSiftUp(data, hole, last);
  return top;
}

}  // namespace cfl::detail
